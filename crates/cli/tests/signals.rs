//! Ctrl-C (SIGINT) and SIGTERM during `build` leave no temporary output (`.froct-*.tmp`),
//! no spill directory (`.froct-spill-*`) and no stream spool (`.froct-stream-*`) behind,
//! and the process ends by the signal.
#![cfg(unix)]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use common::temporaries;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

fn froctomap() -> Command {
    Command::new(env!("CARGO_BIN_EXE_froctomap"))
}

/// A generated series of a day every ten minutes (144 snapshots of the FR-079 scan).
fn series(dir: &Path) -> PathBuf {
    let series = dir.join("series");
    let status = froctomap()
        .args(["generate", "--days", "1", "--step", "10min", "-q", "-o"])
        .arg(&series)
        .status()
        .unwrap();
    assert!(status.success());
    series
}

/// Starts a build of `series` into `out` that spills after every snapshot.
fn start_build(series: &Path, out: &Path) -> Child {
    froctomap()
        .args(["build", "-q", "--memory", "0", "-o"])
        .arg(out.join("series.froct"))
        .arg(series)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// Waits until an entry of `dir` is `wanted` (then `true`) or the child ends.
fn wait_for(child: &mut Child, dir: &Path, wanted: fn(&str) -> bool) -> bool {
    loop {
        if temporaries(dir).iter().any(|name| wanted(name)) {
            return true;
        }
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

fn send(child: &Child, signal: &str) {
    let status = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
}

#[test]
fn signals_during_a_build_leave_no_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let series = series(dir.path());
    // (signal, number, what to wait for): the spill directory exists from the start of
    // reading; the temporary output from the start of modelling.
    let spill: fn(&str) -> bool = |name| name.starts_with(".froct-spill-");
    let output: fn(&str) -> bool = |name| name.ends_with(".tmp");
    let cases = [
        ("-TERM", 15, "spill directory", spill),
        ("-INT", 2, "spill directory", spill),
        ("-TERM", 15, "temporary output", output),
        ("-INT", 2, "temporary output", output),
    ];
    for (signal, number, what, wanted) in cases {
        let out = tempfile::tempdir().unwrap();
        // The build may (rarely) finish before the file is seen: then try again.
        let mut caught = false;
        for _ in 0..5 {
            let mut child = start_build(&series, out.path());
            if !wait_for(&mut child, out.path(), wanted) {
                continue;
            }
            send(&child, signal);
            let status = child.wait().unwrap();
            assert_eq!(status.signal(), Some(number), "{signal}: {status:?}");
            caught = true;
            break;
        }
        assert!(caught, "{signal}: never saw the {what} while building");
        assert_eq!(temporaries(out.path()), Vec::<String>::new(), "{signal}");
        assert!(!out.path().join("series.froct").exists());
    }
}

/// Issue 29: `kill -9` cannot be caught, so a build killed while spilling leaves its spill
/// directory; the next build in that directory removes it (it is no longer locked), whether
/// that build spills or not. Three kills, each once the directory exists.
#[test]
fn spill_directories_of_killed_builds_do_not_survive_the_next_build() {
    let dir = tempfile::tempdir().unwrap();
    let series = series(dir.path());
    let spill: fn(&str) -> bool = |name| name.starts_with(".froct-spill-");
    let out = tempfile::tempdir().unwrap();
    let mut killed = 0;
    for attempt in 0..8 {
        if killed == 3 {
            break;
        }
        let mut child = start_build(&series, out.path());
        if !wait_for(&mut child, out.path(), spill) {
            continue;
        }
        child.kill().unwrap(); // SIGKILL
        let status = child.wait().unwrap();
        assert_eq!(status.signal(), Some(9), "{status:?}");
        killed += 1;
        let left = temporaries(out.path());
        assert!(left.iter().any(|n| spill(n)), "attempt {attempt}: {left:?}");
        // The next build: the second time one that stays within its budget (never spills).
        let mut next = froctomap();
        next.args(["build", "-q"]);
        if killed != 2 {
            next.args(["--memory", "0"]);
        }
        let status = next
            .arg("-o")
            .arg(out.path().join("series.froct"))
            .arg(&series)
            .stdout(Stdio::null())
            .status()
            .unwrap();
        assert!(status.success());
        assert_eq!(
            temporaries(out.path()),
            Vec::<String>::new(),
            "attempt {attempt}"
        );
    }
    assert_eq!(killed, 3, "never saw the spill directory while building");
}

/// A build reading a stream on standard input (`-`) holds its spool (`.froct-stream-*`)
/// while it waits for the rest of the stream: SIGTERM and SIGINT then remove it and end
/// the process by the signal; after `kill -9` the next `build -` there removes it.
#[test]
fn the_spool_of_a_stream_goes_on_signals_and_after_kill_9() {
    let generated = froctomap()
        .args(["generate", "--days", "0.125", "--step", "30min", "--stream"])
        .stderr(Stdio::null())
        .output()
        .unwrap();
    assert!(generated.status.success());
    let stream = generated.stdout;
    let spool: fn(&str) -> bool = |name| name.starts_with(".froct-stream-");
    let out = tempfile::tempdir().unwrap();
    let output = out.path().join("f.froct");
    let start = || {
        let mut child = froctomap()
            .args(["build", "-q", "-", "-o"])
            .arg(&output)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Half the stream, the pipe held open: the build waits for the rest.
        let mut stdin = child.stdin.take().unwrap();
        std::io::Write::write_all(&mut stdin, &stream[..stream.len() / 2]).unwrap();
        (child, stdin)
    };
    for (signal, number) in [("-TERM", 15), ("-INT", 2), ("-KILL", 9)] {
        let (mut child, stdin) = start();
        assert!(wait_for(&mut child, out.path(), spool), "{signal}");
        send(&child, signal);
        let status = child.wait().unwrap();
        drop(stdin);
        assert_eq!(status.signal(), Some(number), "{signal}: {status:?}");
        let left = temporaries(out.path());
        if number == 9 {
            assert!(left.iter().any(|n| spool(n)), "{left:?}");
        } else {
            assert_eq!(left, Vec::<String>::new(), "{signal}");
        }
        assert!(!output.exists());
    }
    // The next stream read there removes what the killed build left.
    let mut child = froctomap()
        .args(["build", "-q", "-", "-o"])
        .arg(&output)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    std::io::Write::write_all(&mut stdin, &stream).unwrap();
    drop(stdin);
    assert!(child.wait().unwrap().success());
    assert_eq!(temporaries(out.path()), Vec::<String>::new());
    assert!(output.exists());
}
