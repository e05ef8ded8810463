//! Running the `froctomap` binary from the command-line tests.
// Each test binary compiles this module and uses a part of it.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs the binary built for these tests.
pub fn froctomap(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_froctomap"))
        .args(args)
        .output()
        .expect("run froctomap")
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
