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
