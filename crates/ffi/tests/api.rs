//! The safe API over upstream OctoMap, including the upstream quirks it handles on purpose.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_core::{free_log_odds, occupied_log_odds, Leaf, Snapshot, VoxelKey};
use froctomap_octomap_ffi::{LeafRecord, OcTree, OctomapError};

const O: u16 = 32768;

fn eight_children_of(depth: u8, log_odds: f32) -> Vec<Leaf> {
    // The eight depth-`depth` children of the node whose first voxel is the origin key.
    let edge = 1u16 << (16 - depth);
    (0..8u16)
        .map(|i| {
            let key = VoxelKey::new(
                O + (i & 1) * edge,
                O + ((i >> 1) & 1) * edge,
                O + ((i >> 2) & 1) * edge,
            );
            Leaf::containing(key, depth, log_odds)
        })
        .collect()
}

#[test]
fn defaults_and_sizes() {
    let tree = OcTree::new(0.05).unwrap();
    assert_eq!(tree.resolution(), 0.05);
    assert_eq!(tree.tree_depth(), 16);
    assert_eq!((tree.node_count(), tree.leaf_count()), (0, 0));
    let p = tree.occupancy_parameters();
    // Upstream stores them as f32 log-odds, so they come back within float precision.
    let close = |a: f64, b: f64| (a - b).abs() < 1e-6;
    assert!(close(p.occupancy_threshold, 0.5) && close(p.prob_hit, 0.7) && close(p.prob_miss, 0.4));
    assert!(close(p.clamping_min, 0.1192) && close(p.clamping_max, 0.971));
    assert!(OcTree::new(0.0).is_err() && OcTree::new(f64::INFINITY).is_err());
}

#[test]
fn occupancy_parameters_are_validated_and_applied() {
    let mut tree = OcTree::new(0.1).unwrap();
    let mut p = tree.occupancy_parameters();
    p.prob_hit = 0.8;
    tree.set_occupancy_parameters(&p).unwrap();
    assert!((tree.occupancy_parameters().prob_hit - 0.8).abs() < 1e-6);
    p.clamping_min = 1.5;
    assert!(matches!(
        tree.set_occupancy_parameters(&p),
        Err(OctomapError::InvalidArgument(_))
    ));
}

#[test]
fn leaves_round_trip_through_the_library_in_bulk() {
    let leaves = vec![
        Leaf::voxel(VoxelKey::new(O, O, O), 0.7),
        Leaf::containing(VoxelKey::new(100, 200, 300), 10, -1.25),
        Leaf::voxel(VoxelKey::new(65535, 0, 65535), 1e-3),
    ];
    let snapshot = Snapshot::from_leaves(0.2, leaves).unwrap();
    let tree = OcTree::from_snapshot(&snapshot).unwrap();
    assert_eq!(tree.leaf_count(), 3);
    let records = tree.leaf_records().unwrap();
    assert_eq!(records.len(), 3);
    assert!(
        records
            .windows(2)
            .all(|w| w[0].to_leaf().start < w[1].to_leaf().start),
        "Morton order"
    );
    assert_eq!(tree.to_snapshot().unwrap(), snapshot);
    let again = OcTree::from_leaf_records(0.2, &records).unwrap();
    assert_eq!(again.to_snapshot().unwrap(), snapshot);
    // Upstream's own point query sees the same values.
    assert_eq!(tree.search(VoxelKey::new(O, O, O)), Some(0.7));
    // The depth-10 leaf is the 64-voxel cube from key (64, 192, 256).
    assert_eq!(
        tree.search(VoxelKey::new(64 + 63, 192, 256 + 5)),
        Some(-1.25)
    );
    assert_eq!(tree.search(VoxelKey::new(63, 192, 256)), None);
    assert_eq!(tree.search(VoxelKey::new(1, 1, 1)), None);
}

#[test]
fn overlapping_leaves_are_refused_not_crashed_on() {
    let records = [
        LeafRecord {
            x: 0,
            y: 0,
            z: 0,
            depth: 14,
            log_odds: 1.0,
        },
        LeafRecord {
            x: 1,
            y: 1,
            z: 1,
            depth: 16,
            log_odds: 1.0,
        },
    ];
    let err = OcTree::from_leaf_records(0.1, &records).unwrap_err();
    assert!(matches!(err, OctomapError::InvalidMap(_)), "{err}");
    let too_deep = [LeafRecord {
        x: 0,
        y: 0,
        z: 0,
        depth: 17,
        log_odds: 1.0,
    }];
    assert!(OcTree::from_leaf_records(0.1, &too_deep).is_err());
}

#[test]
fn a_childless_root_is_a_leaf_covering_everything() {
    let snapshot =
        Snapshot::from_leaves(0.1, vec![Leaf::containing(VoxelKey::new(0, 0, 0), 0, -0.5)])
            .unwrap();
    let tree = OcTree::from_snapshot(&snapshot).unwrap();
    assert_eq!((tree.node_count(), tree.leaf_count()), (1, 1));
    assert_eq!(tree.search(VoxelKey::new(12345, 0, 65535)), Some(-0.5));
    let read = OcTree::read_full(&tree.write_full().unwrap()).unwrap();
    assert_eq!(read.tree.to_snapshot().unwrap(), snapshot);
    let mut expandable = tree.try_clone().unwrap();
    assert!(matches!(
        expandable.expand(1_000_000),
        Err(OctomapError::InvalidArgument(_))
    ));
}

#[test]
fn write_binary_mutates_like_upstream_and_the_unchanged_variant_does_not() {
    let mut leaves = eight_children_of(16, 0.4);
    leaves.push(Leaf::voxel(VoxelKey::new(1000, 1000, 1000), -0.3));
    let snapshot = Snapshot::from_leaves(0.1, leaves).unwrap();
    let mut tree = OcTree::from_snapshot(&snapshot).unwrap();
    let unchanged = tree.write_binary_unchanged().unwrap();
    assert_eq!(
        tree.to_snapshot().unwrap(),
        snapshot,
        "writeBinaryConst leaves the tree alone"
    );
    let written = tree.write_binary().unwrap();
    let after = tree.to_snapshot().unwrap();
    // Maximum likelihood, then the eight equal siblings pruned into one depth-15 leaf.
    assert_eq!(after.leaves().len(), 2);
    assert!(after
        .leaves()
        .iter()
        .any(|l| l.depth == 15 && l.log_odds == occupied_log_odds()));
    assert!(after
        .leaves()
        .iter()
        .any(|l| l.depth == 16 && l.log_odds == free_log_odds()));
    assert!(written.len() < unchanged.len());
    // Both describe the same voxel states.
    let a = OcTree::read_binary(&written)
        .unwrap()
        .tree
        .to_snapshot()
        .unwrap();
    let b = OcTree::read_binary(&unchanged)
        .unwrap()
        .tree
        .to_snapshot()
        .unwrap();
    assert!(a.same_voxel_states(&b));
}

/// Upstream `prune()` works bottom-up and stops at the first level where nothing merged, so
/// eight equal depth-14 leaves stay split when no depth-16 siblings merge first.
#[test]
fn prune_stops_at_the_first_level_without_merges() {
    let snapshot = Snapshot::from_leaves(0.1, eight_children_of(14, 3.5)).unwrap();
    let mut tree = OcTree::from_snapshot(&snapshot).unwrap();
    tree.prune().unwrap();
    assert_eq!(
        tree.leaf_count(),
        8,
        "not merged: level 15 had nothing to prune"
    );
    // When a merge happens at every level on the way up, pruning continues: eight voxels
    // merge into a depth-15 leaf, completing eight equal depth-15 leaves, which merge into a
    // depth-14 leaf beside seven more, which merge into one depth-13 leaf.
    let mut leaves: Vec<Leaf> = eight_children_of(14, 3.5).into_iter().skip(1).collect();
    leaves.extend(eight_children_of(15, 3.5).into_iter().skip(1));
    leaves.extend(eight_children_of(16, 3.5));
    let mut tree = OcTree::from_snapshot(&Snapshot::from_leaves(0.1, leaves).unwrap()).unwrap();
    assert_eq!(tree.leaf_count(), 7 + 7 + 8);
    tree.prune().unwrap();
    let pruned = tree.to_snapshot().unwrap();
    assert_eq!(pruned.leaves().len(), 1);
    assert_eq!(pruned.leaves()[0].depth, 13);
}

#[test]
fn to_max_likelihood_and_inner_update() {
    let snapshot = Snapshot::from_leaves(
        0.1,
        vec![
            Leaf::voxel(VoxelKey::new(5, 5, 5), 0.1),
            Leaf::voxel(VoxelKey::new(9, 9, 9), -0.1),
        ],
    )
    .unwrap();
    let mut tree = OcTree::from_snapshot(&snapshot).unwrap();
    tree.to_max_likelihood().unwrap();
    tree.update_inner_occupancy().unwrap();
    let values: Vec<f32> = tree
        .to_snapshot()
        .unwrap()
        .leaves()
        .iter()
        .map(|l| l.log_odds)
        .collect();
    assert_eq!(values, vec![occupied_log_odds(), free_log_odds()]);
}

#[test]
fn trees_move_between_threads() {
    let tree =
        OcTree::from_snapshot(&Snapshot::from_leaves(0.1, eight_children_of(16, 1.0)).unwrap())
            .unwrap();
    let count = std::thread::spawn(move || tree.leaf_count())
        .join()
        .unwrap();
    assert_eq!(count, 8);
}

#[test]
fn library_errors_carry_the_library_explanation() {
    // The .ot reader is handed a .bt: the Rust check names the problem before upstream runs.
    let bt = b"# Octomap OcTree binary file\nid OcTree\nsize 1\nres 0.1\ndata\n\0\0";
    let err = OcTree::read_full(bt).unwrap_err().to_string();
    assert!(err.contains("this is a .bt file"), "{err}");
}
