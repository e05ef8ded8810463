//! Shared helpers for froctomap's end-to-end tests: where the fixtures and the real data
//! are, how to run upstream OctoMap's tools, and a second, separately built OctoMap client
//! (the PyPI package `octomap-python`, upstream 1.10 linked statically) in a private venv.
//!
//! Helpers panic with a message saying what is missing: a test that cannot reach the
//! upstream tools must fail loudly, never pass by skipping.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

pub mod fixtures;
pub mod living;

use froctomap_core::Snapshot;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

/// The workspace root (the repository checkout).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// `fixtures/` in the repository.
pub fn fixtures_dir() -> PathBuf {
    workspace_root().join("fixtures")
}

/// A file under `fixtures/octomap/`.
pub fn octomap_fixture(name: &str) -> PathBuf {
    fixtures_dir().join("octomap").join(name)
}

/// The shared data folder beside the checkout (`../shared`).
pub fn shared_dir() -> PathBuf {
    workspace_root().join("..").join("shared")
}

/// The real FR-079 corridor scan that ships with Debian's `liboctomap-dev`.
pub fn geb079() -> PathBuf {
    let path = PathBuf::from("/usr/share/doc/liboctomap-dev/examples/data/geb079.bt");
    assert!(
        path.exists(),
        "{} is missing: install liboctomap-dev (scripts/install-deps.sh does)",
        path.display()
    );
    path
}

/// A scratch directory for one test.
pub fn scratch() -> tempfile::TempDir {
    tempfile::tempdir().expect("create a temporary directory")
}

/// Runs an upstream octomap-tools program and returns its output, asserting it started.
pub fn run_upstream(tool: &str, args: &[&Path]) -> Output {
    Command::new(tool).args(args).output().unwrap_or_else(|e| {
        panic!("cannot run `{tool}` ({e}): install octomap-tools (scripts/install-deps.sh does)")
    })
}

/// `convert_octree input output`, asserting success.
pub fn convert_octree(input: &Path, output: &Path) {
    let out = run_upstream("convert_octree", &[input, output]);
    assert!(
        out.status.success() && output.exists(),
        "convert_octree {} {} failed: {}{}",
        input.display(),
        output.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// What `compare_octrees` reported.
#[derive(Debug)]
pub struct Comparison {
    /// Process exit code.
    pub exit_code: Option<i32>,
    /// The `KLD:` value, if printed.
    pub kld: Option<f64>,
    /// The `Expanded num. leafs:` value, if printed.
    pub expanded_leaves: Option<u64>,
    /// Lines starting with `ERROR` or `WARNING`.
    pub complaints: Vec<String>,
    /// Everything it printed.
    pub transcript: String,
}

impl Comparison {
    /// `true` only when the tool ran to the end, found every leaf and measured zero divergence.
    pub fn identical(&self) -> bool {
        self.exit_code == Some(0) && self.kld == Some(0.0) && self.complaints.is_empty()
    }
}

/// `compare_octrees a.ot b.ot` (which only reads `.ot`), with its report parsed: its exit
/// code alone proves nothing, as it exits 0 even when leaves are missing.
pub fn compare_octrees(a: &Path, b: &Path) -> Comparison {
    let out = run_upstream("compare_octrees", &[a, b]);
    let transcript = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let value_after = |label: &str| {
        transcript.lines().find_map(|line| {
            line.trim()
                .strip_prefix(label)
                .map(|v| v.trim().to_string())
        })
    };
    Comparison {
        exit_code: out.status.code(),
        kld: value_after("KLD:").and_then(|v| v.parse().ok()),
        expanded_leaves: value_after("Expanded num. leafs:").and_then(|v| v.parse().ok()),
        complaints: transcript
            .lines()
            .filter(|l| l.contains("ERROR") || l.contains("WARNING"))
            .map(str::to_string)
            .collect(),
        transcript,
    }
}

/// A leaf as every client can report it: minimum-corner key, depth, log-odds bits.
pub type LeafTuple = (u16, u16, u16, u8, u32);

/// The leaves of a snapshot as sorted tuples (log-odds compared bit for bit).
pub fn leaf_tuples(snapshot: &Snapshot) -> Vec<LeafTuple> {
    let mut tuples: Vec<LeafTuple> = snapshot
        .leaves()
        .iter()
        .map(|leaf| {
            let key = leaf.min_key();
            (key.x, key.y, key.z, leaf.depth, leaf.log_odds.to_bits())
        })
        .collect();
    tuples.sort_unstable();
    tuples
}

/// The Python interpreter of a venv that has `octomap-python` installed.
///
/// Uses `$FROCTOMAP_PYTHON` when set (the test script sets it); otherwise creates the venv
/// under `target/interop-venv` on first use.
pub fn octomap_python() -> PathBuf {
    static PYTHON: OnceLock<PathBuf> = OnceLock::new();
    PYTHON
        .get_or_init(|| {
            if let Some(python) = std::env::var_os("FROCTOMAP_PYTHON") {
                return PathBuf::from(python);
            }
            let venv = workspace_root().join("target").join("interop-venv");
            let python = venv.join("bin").join("python");
            if !python_has_octomap(&python) {
                let status =
                    Command::new(workspace_root().join("scripts").join("python-client.sh"))
                        .arg(&venv)
                        .status()
                        .expect("run scripts/python-client.sh");
                assert!(
                    status.success(),
                    "scripts/python-client.sh failed to set up {}",
                    venv.display()
                );
            }
            assert!(
                python_has_octomap(&python),
                "{} cannot import octomap",
                python.display()
            );
            python
        })
        .clone()
}

/// Runs `tests/scripts/write_recordings.py SPEC` (the ROS recordings written by PyPI
/// rosbags and mcap-ros2-support), asserting it succeeded.
pub fn write_recordings(spec: &Path) {
    let out = Command::new(octomap_python())
        .arg(workspace_root().join("tests/scripts/write_recordings.py"))
        .arg(spec)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "write_recordings.py {}: {}",
        spec.display(),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn python_has_octomap(python: &Path) -> bool {
    Command::new(python)
        // The recording tests' writers and the ROS 2 peer's DDS too (scripts/python-client.sh
        // installs them all).
        .args([
            "-c",
            "import octomap, rosbags, mcap, mcap_ros2, cyclonedds.domain",
        ])
        .output()
        .is_ok_and(|o| o.status.success())
}

const PYTHON_LEAF_DUMP: &str = r#"
import sys, octomap
path, kind = sys.argv[1].encode(), sys.argv[2]
if kind == "bt":
    tree = octomap.OcTree(0.1)
    if not tree.readBinary(path):
        sys.exit("readBinary failed")
else:
    tree = octomap.OcTree.read(path)
    if tree is None:
        sys.exit("read failed")
out = ["res %r" % tree.getResolution()]
for leaf in tree.begin_leafs():
    k = leaf.getIndexKey()
    out.append("%d %d %d %d %r" % (k[0], k[1], k[2], leaf.getDepth(), leaf.getValue()))
sys.stdout.write("\n".join(out) + "\n")
"#;

/// Leaves of a `.bt` (`kind = "bt"`) or `.ot` file as read by `octomap-python`, with the
/// resolution it reports.
pub fn python_leaves(path: &Path, kind: &str) -> (f64, Vec<LeafTuple>) {
    let out = Command::new(octomap_python())
        .args(["-c", PYTHON_LEAF_DUMP])
        .arg(path)
        .arg(kind)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "octomap-python could not read {}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("utf-8 output");
    let mut lines = text.lines();
    let resolution: f64 = lines
        .next()
        .and_then(|l| l.strip_prefix("res "))
        .and_then(|v| v.parse().ok())
        .expect("resolution line");
    let mut leaves: Vec<LeafTuple> = lines
        .map(|line| {
            let f: Vec<&str> = line.split_whitespace().collect();
            let value: f64 = f[4].parse().expect("log-odds");
            (
                f[0].parse().expect("x"),
                f[1].parse().expect("y"),
                f[2].parse().expect("z"),
                f[3].parse().expect("depth"),
                // Python prints the float32 widened to double: narrowing is exact.
                (value as f32).to_bits(),
            )
        })
        .collect();
    leaves.sort_unstable();
    (resolution, leaves)
}
