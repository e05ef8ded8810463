//! Running the `froctomap` binary from the command-line tests.
// Each test binary compiles this module and uses a part of it.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Longest a single run may take before the test fails: generous (debug builds on loaded
/// machines), but bounded, so that a command expected to refuse and that starts working
/// instead (a node that serves, a recorder that waits for input) fails the test rather
/// than hanging it.
const RUN_BOUND: Duration = Duration::from_secs(900);

/// Runs the binary built for these tests, with standard input closed, within [`RUN_BOUND`].
pub fn froctomap(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_froctomap"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run froctomap");
    let stdout = drain(child.stdout.take().expect("piped stdout"));
    let stderr = drain(child.stderr.take().expect("piped stderr"));
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for froctomap") {
            break status;
        }
        if started.elapsed() > RUN_BOUND {
            let _ = child.kill();
            let _ = child.wait();
            panic!("froctomap {args:?} still ran after {RUN_BOUND:?}: killed");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Output {
        status,
        stdout: stdout.join().expect("stdout reader"),
        stderr: stderr.join().expect("stderr reader"),
    }
}

/// All of a child's pipe, read on a thread (so that a full pipe never blocks the child).
fn drain(mut pipe: impl std::io::Read + Send + 'static) -> std::thread::JoinHandle<Vec<u8>> {
    std::thread::spawn(move || {
        let mut bytes = Vec::new();
        let _ = pipe.read_to_end(&mut bytes);
        bytes
    })
}

/// Runs it, expecting success; its standard output.
pub fn ok(args: &[&str]) -> String {
    let out = froctomap(args);
    assert!(
        out.status.success(),
        "froctomap {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Runs it, expecting the error exit status 1; its standard error.
pub fn err(args: &[&str]) -> String {
    let out = froctomap(args);
    assert_eq!(out.status.code(), Some(1), "froctomap {args:?} should fail");
    String::from_utf8(out.stderr).unwrap()
}

/// Runs it, expecting any failure (usage errors exit with 2); its standard error.
pub fn fails(args: &[&str]) -> String {
    let out = froctomap(args);
    assert!(!out.status.success(), "froctomap {args:?} succeeded");
    String::from_utf8(out.stderr).unwrap()
}

/// A path as an argument.
pub fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Hidden temporary entries of froctomap in `dir`.
pub fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with(".froct-"))
        .collect()
}

/// `froctomap generate --stream ARGS`, whole.
pub fn generated_stream(args: &[&str]) -> Vec<u8> {
    let output = Command::new(env!("CARGO_BIN_EXE_froctomap"))
        .args(["generate", "--stream"])
        .args(args)
        .stderr(std::process::Stdio::null())
        .output()
        .expect("run froctomap");
    assert!(output.status.success());
    output.stdout
}

/// Lines of a child's output, read on a thread.
pub fn lines(out: impl std::io::Read + Send + 'static) -> mpsc::Receiver<String> {
    let (send, receive) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            if send.send(line).is_err() {
                break;
            }
        }
    });
    receive
}

/// Kills and reaps the children still running when the test ends (a failed assertion
/// must not leave a node or a peer behind).
pub struct Reap(pub Vec<Child>);

impl Drop for Reap {
    fn drop(&mut self) {
        for child in &mut self.0 {
            if matches!(child.try_wait(), Ok(None)) {
                let _ = child.kill();
            }
            let _ = child.wait();
        }
    }
}

/// The next line that satisfies `wanted`, within a minute.
pub fn wait_for(lines: &mpsc::Receiver<String>, wanted: impl Fn(&str) -> bool) -> String {
    loop {
        match lines.recv_timeout(Duration::from_secs(60)) {
            Ok(line) if wanted(&line) => return line,
            Ok(_) => {}
            Err(e) => panic!("no such line: {e}"),
        }
    }
}

/// A ROS domain of the test's own (1..=200), so parallel tests' DDS traffic stays apart.
pub fn random_domain() -> u32 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(11);
    1 + (nanos ^ std::process::id()) % 200
}

/// The samples of a FROctomap file (`info --json`).
pub fn samples(file: &Path) -> u64 {
    let info: serde_json::Value =
        serde_json::from_str(&ok(&["info", s(file), "--json"])).expect("info --json");
    info["time"]["samples"].as_u64().expect("time.samples")
}

/// Sample `i` of `file` retrieves byte-identical to the map file `input`.
pub fn retrieves_as(file: &Path, i: usize, input: &Path) {
    let got = file.with_extension(format!("{i}.bt"));
    let time = format!("index:{i}");
    ok(&["-q", "retrieve", s(file), "--time", &time, "-o", s(&got)]);
    assert!(
        std::fs::read(&got).expect("the retrieved map") == std::fs::read(input).expect("the map"),
        "sample {i} of {} differs from {}",
        file.display(),
        input.display()
    );
    std::fs::remove_file(got).expect("remove the retrieved map");
}
