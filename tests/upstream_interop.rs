//! Interoperability with upstream OctoMap's own tools on the real FR-079 corridor scan:
//! what froctomap writes is byte-identical to what `convert_octree` writes, and upstream's
//! readers accept it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_formats::{FormatRegistry, ReadOptions, WriteOptions};
use froctomap_test_support::{
    compare_octrees, convert_octree, geb079, leaf_tuples, run_upstream, scratch,
};
use std::path::Path;

fn read(path: &Path) -> froctomap_formats::ReadOutcome {
    FormatRegistry::with_default_formats()
        .read_file(path, ReadOptions::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

fn write(snapshot: &froctomap_core::Snapshot, path: &Path) {
    FormatRegistry::with_default_formats()
        .write_file(snapshot, path, WriteOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn geb079_round_trips_byte_identical_to_convert_octree() {
    let dir = scratch();
    let geb = geb079();
    let map = read(&geb).map;
    assert_eq!(
        map.snapshot.leaves().len(),
        428_144,
        "the FR-079 scan has 428,144 leaves"
    );
    assert_eq!(map.node_count, 532_566);

    for ext in ["bt", "ot"] {
        let ours = dir.path().join(format!("ours.{ext}"));
        let theirs = dir.path().join(format!("theirs.{ext}"));
        write(&map.snapshot, &ours);
        convert_octree(&geb, &theirs);
        let (a, b) = (
            std::fs::read(&ours).unwrap(),
            std::fs::read(&theirs).unwrap(),
        );
        assert!(
            a == b,
            ".{ext}: ours {} bytes, convert_octree {} bytes, contents differ",
            a.len(),
            b.len()
        );
        // Leaf sets equal when read back.
        assert_eq!(
            leaf_tuples(&read(&ours).map.snapshot),
            leaf_tuples(&map.snapshot),
            ".{ext}"
        );
    }
    // The .bt written is the very file upstream shipped (it is canonical).
    assert_eq!(
        std::fs::read(dir.path().join("ours.bt")).unwrap(),
        std::fs::read(&geb).unwrap()
    );
}

#[test]
fn compare_octrees_reports_zero_difference_for_our_ot() {
    let dir = scratch();
    let ours = dir.path().join("ours.ot");
    let theirs = dir.path().join("theirs.ot");
    write(&read(&geb079()).map.snapshot, &ours);
    convert_octree(&geb079(), &theirs);
    let report = compare_octrees(&ours, &theirs);
    assert!(report.identical(), "{report:?}");
    assert_eq!(
        report.expanded_leaves,
        Some(1_136_432),
        "{}",
        report.transcript
    );
}

/// The comparison must be able to fail: a map with one voxel changed is reported.
#[test]
fn compare_octrees_detects_a_changed_voxel() {
    let dir = scratch();
    let snapshot = read(&geb079()).map.snapshot;
    let mut leaves = snapshot.leaves().to_vec();
    let target = leaves
        .iter_mut()
        .find(|l| l.depth == 16)
        .expect("a voxel leaf");
    target.log_odds = -target.log_odds;
    let changed = froctomap_core::Snapshot::from_leaves(snapshot.resolution(), leaves).unwrap();
    write(&changed, &dir.path().join("changed.ot"));
    write(&snapshot, &dir.path().join("original.ot"));
    let report = compare_octrees(
        &dir.path().join("changed.ot"),
        &dir.path().join("original.ot"),
    );
    assert!(!report.identical(), "{report:?}");
    assert!(report.kld.is_some_and(|k| k > 0.0), "{}", report.transcript);
}

#[test]
fn strict_upstream_readers_accept_our_bt() {
    let dir = scratch();
    let ours = dir.path().join("ours.bt");
    write(&read(&geb079()).map.snapshot, &ours);
    // edit_octree fails unless readBinary returns true (which also checks the size header).
    let edited = dir.path().join("edited.bt");
    let out = run_upstream("edit_octree", &[Path::new("-o"), &edited, &ours]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read(&edited).unwrap(),
        std::fs::read(&ours).unwrap()
    );
    let converted = dir.path().join("converted.ot");
    convert_octree(&ours, &converted);
    assert_eq!(
        leaf_tuples(&read(&converted).map.snapshot),
        leaf_tuples(&read(&ours).map.snapshot)
    );
}

/// edit_octree is strict about `size`; froctomap is lenient like upstream's loader and says so.
#[test]
fn size_mismatch_is_rejected_by_edit_octree_but_read_by_us_with_a_warning() {
    let dir = scratch();
    let fixture = froctomap_test_support::octomap_fixture("size_mismatch.bt");
    let out = run_upstream(
        "edit_octree",
        &[Path::new("-o"), &dir.path().join("x.bt"), &fixture],
    );
    assert!(!out.status.success());
    let map = read(&fixture).map;
    assert!(!map.snapshot.is_empty());
    assert!(
        map.warnings.iter().any(|w| w.contains("size 1")),
        "{:?}",
        map.warnings
    );
}

/// A `ColorOcTree` written by upstream's library (a small program compiled against it):
/// froctomap reads its occupancy, with a notice, as upstream reads it (`convert_octree`
/// to `.bt` is upstream's occupancy of the same file), and upstream's own rewrite of the
/// file reads back the same.
#[test]
fn color_octrees_written_by_upstream_read_as_upstream_reads_their_occupancy() {
    let dir = scratch();
    let program = dir.path().join("color_tree.cc");
    std::fs::write(
        &program,
        r#"#include <octomap/ColorOcTree.h>
using namespace octomap;
int main(int argc, char** argv) {
  ColorOcTree tree(0.1);
  for (int x = 0; x < 24; ++x)
    for (int y = 0; y < 16; ++y)
      for (int z = 0; z < 2; ++z) {
        point3d p(x * 0.1 + 0.05, y * 0.1 + 0.05, z * 0.1 + 0.05);
        bool occupied = (x / 4 + y / 4 + z) % 3 == 0;
        tree.updateNode(p, occupied);
        if (x % 8 == 0) tree.updateNode(p, !occupied);
        tree.setNodeColor(tree.coordToKey(p), 10 * x, 15 * y, occupied ? 255 : 0);
      }
  tree.updateInnerOccupancy();
  return tree.write(argv[1]) ? 0 : 1;
}
"#,
    )
    .unwrap();
    let binary = dir.path().join("color_tree");
    let flags = std::process::Command::new("pkg-config")
        .args(["--cflags", "--libs", "octomap"])
        .output()
        .expect("pkg-config (liboctomap-dev)");
    let flags = String::from_utf8(flags.stdout).unwrap();
    let compiled = std::process::Command::new("c++")
        .arg(&program)
        .arg("-o")
        .arg(&binary)
        .args(flags.split_whitespace())
        .output()
        .expect("a C++ compiler");
    assert!(
        compiled.status.success(),
        "{}",
        String::from_utf8_lossy(&compiled.stderr)
    );
    let color = dir.path().join("color.ot");
    let ran = std::process::Command::new(&binary)
        .arg(&color)
        .output()
        .unwrap();
    assert!(ran.status.success() && color.exists(), "{ran:?}");
    assert!(std::fs::read(&color)
        .unwrap()
        .windows(14)
        .any(|w| w == b"id ColorOcTree"));

    let ours = read(&color);
    assert!(
        ours.map
            .warnings
            .iter()
            .any(|w| w.contains("`ColorOcTree` read as a plain OcTree")),
        "{:?}",
        ours.map.warnings
    );
    let leaves = ours.map.snapshot.leaves();
    assert!(leaves.len() > 100);
    assert!(leaves.iter().any(|l| l.occupancy().is_occupied()));
    assert!(leaves.iter().any(|l| !l.occupancy().is_occupied()));

    // Upstream's occupancy of the same file.
    let theirs_bt = dir.path().join("theirs.bt");
    convert_octree(&color, &theirs_bt);
    let theirs = read(&theirs_bt).map.snapshot;
    assert!(ours
        .map
        .snapshot
        .to_max_likelihood()
        .same_voxel_states(&theirs));
    // Upstream's rewrite of the colour tree: the same log-odds, leaf for leaf.
    let rewritten = dir.path().join("rewritten.ot");
    convert_octree(&color, &rewritten);
    assert_eq!(
        leaf_tuples(&read(&rewritten).map.snapshot),
        leaf_tuples(&ours.map.snapshot)
    );
}
