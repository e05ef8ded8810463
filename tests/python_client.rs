//! A second, separately built OctoMap client reads froctomap's output: the PyPI package
//! `octomap-python` (upstream OctoMap 1.10, statically linked) reports the identical leaf set.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_formats::{FormatRegistry, ReadOptions, WriteOptions};
use froctomap_test_support::{fixtures, geb079, leaf_tuples, python_leaves, scratch};

#[test]
fn octomap_python_reads_our_bt_and_ot_of_geb079_identically() {
    let registry = FormatRegistry::with_default_formats();
    let snapshot = registry
        .read_file(&geb079(), ReadOptions::default())
        .unwrap()
        .map
        .snapshot;
    let expected = leaf_tuples(&snapshot);
    let dir = scratch();
    for ext in ["bt", "ot"] {
        let path = dir.path().join(format!("geb079_ours.{ext}"));
        registry
            .write_file(&snapshot, &path, WriteOptions::default())
            .unwrap();
        let (resolution, leaves) = python_leaves(&path, ext);
        assert_eq!(resolution, 0.08);
        assert_eq!(leaves.len(), expected.len(), ".{ext}");
        assert!(
            leaves == expected,
            ".{ext}: octomap-python sees a different leaf set"
        );
    }
}

#[test]
fn octomap_python_reads_our_log_odds_exactly() {
    // The .ot fixtures carry graded, unclamped log-odds values.
    let registry = FormatRegistry::with_default_formats();
    let dir = scratch();
    for snapshot in [fixtures::few_voxels(), fixtures::coarse_leaves()] {
        let path = dir.path().join("graded.ot");
        registry
            .write_file(&snapshot, &path, WriteOptions::default())
            .unwrap();
        let (_, leaves) = python_leaves(&path, "ot");
        assert_eq!(leaves, leaf_tuples(&snapshot));
    }
}
