//! The modules of every crate form a DAG: `scripts/module_cycles.py` builds each crate's
//! module graph from its `use`, `crate::`, `super::` and `self::` paths and fails on a loop
//! (docs/ARCHITECTURE.md). The checker's own tests run first, so a checker that stopped
//! seeing edges cannot pass this quietly.
#![allow(clippy::panic)] // tests fail by panicking

use froctomap_test_support::workspace_root;
use std::process::Command;

/// Any Python 3 does (the checker uses the standard library only): `$FROCTOMAP_PYTHON` when
/// set, else `python3`.
fn python() -> std::ffi::OsString {
    std::env::var_os("FROCTOMAP_PYTHON").unwrap_or_else(|| "python3".into())
}

fn run(script: &str) -> (bool, String) {
    let output = Command::new(python())
        .arg(workspace_root().join("scripts").join(script))
        .current_dir(workspace_root())
        .output()
        .unwrap_or_else(|e| panic!("run {script} with {:?}: {e}", python()));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    (output.status.success(), text)
}

#[test]
fn the_loop_checker_passes_its_own_tests() {
    let (ok, text) = run("module_cycles_test.py");
    assert!(ok, "scripts/module_cycles_test.py failed:\n{text}");
}

#[test]
fn no_crate_has_an_import_loop() {
    let (ok, text) = run("module_cycles.py");
    assert!(ok, "import loops between modules:\n{text}");
    assert!(text.contains("no import loops"), "{text}");
}
