//! What the benchmark needs from the system: the archive tools, a font, the machine's
//! description, peak memory, and the archive baselines themselves.

use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// The machine a run was measured on.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Machine {
    /// CPU model name (`/proc/cpuinfo`).
    pub cpu: String,
    /// Logical CPUs available to the process.
    pub cpus: usize,
    /// Worker threads of builds, reads and the C++ baseline.
    pub threads: usize,
    /// Total memory, bytes (`/proc/meminfo`).
    pub memory_bytes: u64,
    /// Kernel release.
    pub kernel: String,
    /// `zstd --version`, `xz --version`, `tar --version` (first lines).
    pub tools: Vec<String>,
}

/// An external program and the Debian package that provides it.
#[derive(Clone, Copy, Debug)]
pub struct Tool {
    /// Program name.
    pub program: &'static str,
    /// Debian package.
    pub package: &'static str,
}

/// The archive tools the baselines use.
pub const TOOLS: [Tool; 3] = [
    Tool {
        program: "tar",
        package: "tar",
    },
    Tool {
        program: "zstd",
        package: "zstd",
    },
    Tool {
        program: "xz",
        package: "xz-utils",
    },
];

/// The font the plots are labelled with.
pub const FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Copies `from` to `to`, the error naming `from`.
pub fn copy_file(from: &Path, to: &Path) -> Result<()> {
    std::fs::copy(from, to).with_context(|| format!("copying {}", from.display()))?;
    Ok(())
}

/// Each tool's `--version` first line; an error naming the missing packages otherwise.
pub fn check_tools() -> Result<Vec<String>> {
    let mut versions = Vec::new();
    let mut missing = Vec::new();
    for tool in TOOLS {
        match Command::new(tool.program)
            .arg("--version")
            .stdin(Stdio::null())
            .output()
        {
            Ok(out) if out.status.success() => {
                let text = String::from_utf8_lossy(&out.stdout);
                let text = if text.trim().is_empty() {
                    String::from_utf8_lossy(&out.stderr).into_owned()
                } else {
                    text.into_owned()
                };
                versions.push(
                    text.lines()
                        .next()
                        .unwrap_or(tool.program)
                        .trim_matches(|c: char| c == '*' || c.is_whitespace())
                        .to_string(),
                );
            }
            _ => missing.push(tool),
        }
    }
    if !missing.is_empty() {
        let programs: Vec<&str> = missing.iter().map(|t| t.program).collect();
        let packages: Vec<&str> = missing.iter().map(|t| t.package).collect();
        bail!(
            "the archive baselines need {} (not found or not working): install the Debian package(s) {} \
             (apt-get install {})",
            programs.join(", "),
            packages.join(", "),
            packages.join(" ")
        );
    }
    Ok(versions)
}

/// Reads the plot font; an error naming its package when it is missing.
pub fn load_font(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).with_context(|| {
        format!(
            "cannot read the plot font {} (install the Debian package fonts-dejavu-core)",
            path.display()
        )
    })
}

/// CPU, memory and kernel of this machine, as far as `/proc` tells.
pub fn machine(threads: usize, tools: Vec<String>) -> Machine {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let cpu = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map_or_else(|| "unknown CPU".to_string(), |(_, v)| v.trim().to_string());
    let meminfo = std::fs::read_to_string("/proc/meminfo").unwrap_or_default();
    let memory_bytes = meminfo
        .lines()
        .find(|l| l.starts_with("MemTotal:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kib| kib.parse::<u64>().ok())
        .map_or(0, |kib| kib * 1024);
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease")
        .map_or_else(|_| "unknown".to_string(), |s| s.trim().to_string());
    Machine {
        cpu,
        cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
        threads,
        memory_bytes,
        kernel,
        tools,
    }
}

/// Peak resident memory of this process (`VmHWM`), bytes.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Size and time of `tar` of a directory piped through a compressor.
#[derive(Clone, Copy, Debug)]
pub struct Archive {
    /// Compressed bytes.
    pub bytes: u64,
    /// Wall seconds of the whole pipe.
    pub seconds: f64,
}

/// `tar cf - -C dir --sort=name .` piped through `compressor args`; the compressed stream
/// is counted, not stored.
pub fn tar_through(dir: &Path, compressor: &str, args: &[&str]) -> Result<Archive> {
    let started = Instant::now();
    let mut tar = Command::new("tar")
        .args(["cf", "-", "--sort=name", "-C"])
        .arg(dir)
        .arg(".")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .context("cannot start tar")?;
    let tar_out = tar.stdout.take().context("tar has no stdout")?;
    let mut packer = Command::new(compressor)
        .args(args)
        .stdin(Stdio::from(tar_out))
        .stdout(Stdio::piped())
        .spawn()
        .with_context(|| format!("cannot start {compressor}"))?;
    let mut out = packer
        .stdout
        .take()
        .with_context(|| format!("{compressor} has no stdout"))?;
    let mut buffer = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = out
            .read(&mut buffer)
            .with_context(|| format!("reading {compressor}'s output"))?;
        if n == 0 {
            break;
        }
        bytes += n as u64;
    }
    let tar_status = tar.wait().context("waiting for tar")?;
    let status = packer
        .wait()
        .with_context(|| format!("waiting for {compressor}"))?;
    if !tar_status.success() {
        bail!("tar of {} failed ({tar_status})", dir.display());
    }
    if !status.success() {
        bail!("{compressor} {} failed ({status})", args.join(" "));
    }
    Ok(Archive {
        bytes,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The `froctomap` CLI to time as a process: `explicit`, else `froctomap` beside this
/// executable (where `cargo build --release -p froctomap-cli` puts it).
pub fn find_cli(explicit: Option<&Path>) -> Option<PathBuf> {
    if let Some(path) = explicit {
        return Some(path.to_path_buf());
    }
    let exe = std::env::current_exe().ok()?;
    let candidate = exe.parent()?.join("froctomap");
    candidate.is_file().then_some(candidate)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tar_through_cat_counts_the_archive() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a"), vec![7u8; 5000]).unwrap();
        // `cat` passes tar's output through: a tar archive is a multiple of 512 bytes.
        let archive = tar_through(dir.path(), "cat", &[]).unwrap();
        assert!(archive.bytes >= 5000 + 512, "{}", archive.bytes);
        assert_eq!(archive.bytes % 512, 0);
        assert!(tar_through(dir.path(), "false", &[]).is_err());
    }

    #[test]
    fn missing_font_names_its_package() {
        let err = load_font(Path::new("/nonexistent/font.ttf")).unwrap_err();
        assert!(format!("{err:#}").contains("fonts-dejavu-core"));
    }

    #[test]
    fn machine_is_described() {
        let m = machine(2, vec![]);
        assert!(m.cpus >= 1);
        assert_eq!(m.threads, 2);
    }
}
