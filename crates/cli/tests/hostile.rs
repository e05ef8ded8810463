//! Hostile inputs and outputs end to end (issue 29): resealed lengths in recordings end in
//! a typed error naming the file within a bounded address space, never an abort.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use std::path::Path;
use std::process::{Command, Output};

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(name)
}

/// Runs the command line in an address space of 4 GB (`ulimit -v`), as the attack did.
fn froctomap_bounded(args: &[&Path]) -> Output {
    let mut command = Command::new("sh");
    command
        .arg("-c")
        .arg("ulimit -v 4000000 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_froctomap"));
    command.args(args).output().expect("run froctomap")
}

/// The MCAP fixture with the first chunk's compression name declaring 0xFFFFFFFF bytes.
fn hostile_mcap() -> Vec<u8> {
    let mut bytes = std::fs::read(fixture("ros/two_maps_zstd.mcap")).unwrap();
    let mut pos = MCAP_MAGIC.len();
    loop {
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        if bytes[pos] == 0x06 {
            let at = pos + 9 + 28;
            bytes[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
            return bytes;
        }
        pos += 9 + len;
    }
}

#[test]
fn build_of_an_mcap_with_a_hostile_length_is_a_typed_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("hostile.mcap");
    std::fs::write(&input, hostile_mcap()).unwrap();
    let output = dir.path().join("out.froct");
    let run = froctomap_bounded(&[Path::new("build"), &input, Path::new("-o"), &output]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("hostile.mcap") && stderr.contains("a string runs past its record"),
        "{stderr}"
    );
    assert!(!output.exists());
}
