//! No output path replaces anything but a regular file (issue 29): every verb that writes
//! writes into a FIFO or /dev/null (leaving it a FIFO, a device), `-o -` is standard output,
//! and a write leaves no temporary file behind, even after a writer was killed with SIGKILL.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_core::{Leaf, Snapshot, VoxelKey};
use froctomap_formats::{FormatRegistry, WriteOptions};
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::{froctomap, ok, s};

const T0: u32 = 1_451_865_600;

/// A room whose door opens and closes.
fn frame(i: u32) -> Snapshot {
    let mut leaves = Vec::new();
    for x in 0..8u16 {
        for y in 0..8u16 {
            let occupied = x == 7 || (x == 4 && y < 3 && i % 2 == 1);
            leaves.push(Leaf::voxel(
                VoxelKey::new(32768 + x, 32768 + y, 32768),
                if occupied { 3.5 } else { -2.0 },
            ));
        }
    }
    Snapshot::from_leaves(0.1, leaves).unwrap()
}

fn write_frames(dir: &Path, frames: std::ops::Range<u32>) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir).unwrap();
    let registry = FormatRegistry::with_default_formats();
    frames
        .map(|i| {
            let path = dir.join(format!("room_{}.bt", T0 + i * 600));
            registry
                .write_file(&frame(i), &path, WriteOptions::default())
                .unwrap();
            path
        })
        .collect()
}

fn mkfifo(path: &Path) {
    assert!(Command::new("mkfifo").arg(path).status().unwrap().success());
}

/// The files in `dir` (names).
fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Runs `args` (with `OUT` replaced by `out`) while a thread reads the FIFO `out`; returns
/// whether the command succeeded and what the FIFO received.
fn run_into_fifo(args: &[&str], out: &Path) -> (bool, Vec<u8>) {
    let reader = {
        let out = out.to_path_buf();
        std::thread::spawn(move || std::fs::read(out).unwrap())
    };
    let args: Vec<&str> = args
        .iter()
        .map(|&a| if a == "OUT" { s(out) } else { a })
        .collect();
    let run = froctomap(&args);
    // A command that failed before opening the FIFO leaves the reader waiting: release it.
    if !reader.is_finished() {
        drop(std::fs::OpenOptions::new().write(true).open(out));
    }
    let received = reader.join().unwrap();
    assert!(
        run.status.success() || received.is_empty(),
        "{args:?} failed after writing: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    (run.status.success(), received)
}

#[test]
fn no_verb_replaces_a_fifo_or_a_device() {
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps");
    let frames = write_frames(&maps, 0..6);
    let file = dir.path().join("room.froct");
    ok(&["-q", "build", s(&maps), "-o", s(&file)]);
    let (from, to) = (format!("{T0}"), format!("{}", T0 + 1800));
    let verbs: Vec<Vec<&str>> = vec![
        vec!["build", s(&maps), "-o", "OUT"],
        vec![
            "retrieve",
            s(&file),
            "--time",
            "index:1",
            "-o",
            "OUT",
            "--format",
            "bt",
        ],
        vec![
            "predict",
            s(&file),
            "--time",
            "index:1",
            "-o",
            "OUT",
            "--format",
            "ot",
        ],
        vec![
            "export",
            s(&file),
            "--from",
            &from,
            "--to",
            &to,
            "--every",
            "10min",
            "-o",
            "OUT",
            "--format",
            "mcap",
        ],
        vec!["render", s(&file), "--time", "index:1", "-o", "OUT"],
        vec!["history", s(&file), "--at", "0.05,0.05,0.05", "-o", "OUT"],
        vec!["anomalies", s(&file), s(&frames[3]), "--png", "OUT"],
        vec!["convert", s(&frames[0]), "OUT", "--format", "ot"],
    ];
    let pipes = dir.path().join("pipes");
    std::fs::create_dir(&pipes).unwrap();
    let fifo = pipes.join("out");
    mkfifo(&fifo);
    for verb in &verbs {
        let (succeeded, received) = run_into_fifo(verb, &fifo);
        assert!(succeeded, "{verb:?} into a FIFO");
        assert!(!received.is_empty(), "{verb:?} wrote nothing into the FIFO");
        assert!(
            std::fs::metadata(&fifo).unwrap().file_type().is_fifo(),
            "{verb:?}"
        );
        assert_eq!(
            names(&pipes),
            ["out"],
            "{verb:?} left a file beside the FIFO"
        );
        // /dev/null: written into, never replaced.
        let args: Vec<&str> = verb
            .iter()
            .map(|&a| if a == "OUT" { "/dev/null" } else { a })
            .collect();
        ok(&args);
        assert!(std::fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device());
    }
    // A directory or a socket is refused, and left as it was.
    let socket = pipes.join("socket");
    let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
    let run = froctomap(&[
        "retrieve",
        s(&file),
        "--time",
        "index:1",
        "-o",
        s(&socket),
        "--format",
        "bt",
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("a socket"), "{stderr}");
    assert!(std::fs::metadata(&socket).unwrap().file_type().is_socket());
}

#[test]
fn dash_is_standard_output_and_reports_go_to_standard_error() {
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps");
    write_frames(&maps, 0..4);
    let file = dir.path().join("room.froct");
    ok(&["-q", "build", s(&maps), "-o", s(&file)]);
    let regular = dir.path().join("then.bt");
    ok(&["retrieve", s(&file), "--time", "index:2", "-o", s(&regular)]);
    let run = froctomap(&[
        "retrieve",
        s(&file),
        "--time",
        "index:2",
        "-o",
        "-",
        "--format",
        "bt",
    ]);
    assert!(run.status.success());
    assert_eq!(
        run.stdout,
        std::fs::read(&regular).unwrap(),
        "the map alone on stdout"
    );
    assert!(
        String::from_utf8_lossy(&run.stderr).contains("leaves"),
        "the report on stderr"
    );
    assert!(!dir.path().join("-").exists());
}

/// `kill -9` at arbitrary instants of `build` over a bounded number of trials: the next
/// write removes whatever temporary files the killed ones left, and leaves none itself.
#[test]
fn temporary_files_of_killed_writers_do_not_survive_the_next_write() {
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps");
    write_frames(&maps, 0..12);
    let outputs = dir.path().join("out");
    std::fs::create_dir(&outputs).unwrap();
    let file = outputs.join("room.froct");
    let mut left_behind = 0;
    for trial in 0..12u64 {
        let mut child = Command::new(env!("CARGO_BIN_EXE_froctomap"))
            .args(["-q", "build", s(&maps), "-o", s(&file)])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        // Spread over the build's run, by polling rather than by a clock: kill once the
        // temporary file exists (from the second trial on, some time after), or at the end.
        for _ in 0..trial * 3 {
            if child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::yield_now();
            let _ = names(&outputs);
        }
        let _ = child.kill(); // SIGKILL
        child.wait().unwrap();
        left_behind += names(&outputs)
            .iter()
            .filter(|n| n.ends_with(".tmp"))
            .count();
        // The next write of an output in that directory.
        ok(&["-q", "build", s(&maps), "-o", s(&file)]);
        assert_eq!(names(&outputs), ["room.froct"], "trial {trial}");
    }
    // The property was exercised: some killed build left a temporary file.
    println!("{left_behind} temporary files left by killed builds were removed");
}

/// `compact` reads its FILE before anything else: a FIFO there is refused before it is
/// opened (opening a FIFO for reading waits for a writer that never comes), in place and
/// with `-o`.
#[test]
fn compact_refuses_a_fifo_without_opening_it() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("series.froct");
    mkfifo(&fifo);
    let out = dir.path().join("out.froct");
    for args in [
        vec!["compact", s(&fifo)],
        vec!["compact", s(&fifo), "-o", s(&out)],
    ] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_froctomap"))
            .args(&args)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Generous: a refusal takes milliseconds; only a hang reaches the deadline.
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
        let status = loop {
            if let Some(status) = child.try_wait().unwrap() {
                break status;
            }
            if std::time::Instant::now() > deadline {
                child.kill().unwrap();
                child.wait().unwrap();
                panic!("froctomap {args:?} never returned: it opened the FIFO");
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        };
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
        assert_eq!(status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains(s(&fifo)) && stderr.to_lowercase().contains("fifo"),
            "{args:?}: {stderr}"
        );
        assert!(std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo());
        assert!(!out.exists());
    }
}
