//! `--max-memory`: a bound on the resident memory of a whole build or append (reading,
//! accumulating, fitting), enforced by a thread that samples the process's resident set
//! and ends the command with an error naming the limit before the system's allocator
//! fails (an allocation failure aborts the process without a word about what to change).

use std::time::Duration;

/// How often the resident set is sampled.
const EVERY: Duration = Duration::from_millis(20);

/// This process's resident memory in bytes (Linux `VmRSS`), if known.
pub fn resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Watches the resident memory of `command` against `limit` bytes (checked at once, then
/// every few milliseconds): past it, removes the temporary files (the output is never
/// written) and exits with status 1 and an error.
pub fn watch(limit: u64, command: &'static str) {
    check(limit, command);
    std::thread::spawn(move || loop {
        std::thread::sleep(EVERY);
        check(limit, command);
    });
}

fn check(limit: u64, command: &str) {
    let Some(resident) = resident_bytes() else {
        return;
    };
    if resident > limit {
        froctomap_core::cleanup::remove_registered();
        eprintln!(
            "error: {command} needed more than --max-memory {} MiB (resident {} MiB); \
             nothing was written",
            limit >> 20,
            resident >> 20
        );
        eprintln!(
            "hint: raise --max-memory (or leave it out), or use a deeper --tile-depth \
             so that each tile holds fewer cells (docs/LIMITS.md)"
        );
        std::process::exit(1);
    }
}
