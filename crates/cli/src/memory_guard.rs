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

/// The value of the first line of a `/proc` file starting with `key`, as its first word.
fn proc_value(path: &str, key: &str, word: usize) -> Option<String> {
    let text = std::fs::read_to_string(path).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    line[key.len()..]
        .split_whitespace()
        .nth(word)
        .map(str::to_string)
}

/// The default `--max-memory`: three quarters of the physical memory (`MemTotal`), or half
/// of the address-space limit (`ulimit -v`, which counts reserved address space as well as
/// resident memory) when that is less; `None` when neither is known.
pub fn default_limit() -> Option<u64> {
    let physical = proc_value("/proc/meminfo", "MemTotal:", 0)
        .and_then(|kib| kib.parse::<u64>().ok())
        .map(|kib| kib * 1024 / 4 * 3);
    let address_space = proc_value("/proc/self/limits", "Max address space", 0)
        .and_then(|soft| soft.parse::<u64>().ok())
        .map(|bytes| bytes / 2);
    match (physical, address_space) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Watches the resident memory of `command` against `limit` bytes (checked at once, then
/// every few milliseconds): past it, removes the temporary files (the output is never
/// written) and exits with status 1 and an error.
/// `default`: the limit is the default one (`auto`), which the error says.
pub fn watch(limit: u64, default: bool, command: &'static str) {
    check(limit, default, command);
    std::thread::spawn(move || loop {
        std::thread::sleep(EVERY);
        check(limit, default, command);
    });
}

fn check(limit: u64, default: bool, command: &str) {
    let Some(resident) = resident_bytes() else {
        return;
    };
    if resident > limit {
        froctomap_core::cleanup::remove_registered();
        let which = if default {
            " (the default: 3/4 of physical memory, or half of `ulimit -v`)"
        } else {
            ""
        };
        eprintln!(
            "error: {command} needed more than --max-memory {} MiB{which} (resident {} MiB); \
             nothing was written",
            limit >> 20,
            resident >> 20
        );
        eprintln!(
            "hint: raise --max-memory SIZE (or `--max-memory none`), or use a deeper \
             --tile-depth so that each tile holds fewer cells (docs/LIMITS.md)"
        );
        std::process::exit(1);
    }
}
