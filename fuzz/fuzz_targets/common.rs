//! Checks shared by the reader targets: whatever the input, reading returns (never panics,
//! never hangs), and what it accepts is a valid map whose streamed forms agree.

use froctomap_core::Snapshot;
use froctomap_octomap_codec::{decode, scan_runs, FileKind, ReadLimits};

/// Small enough that a hostile `size` or a deep chain cannot make one input slow.
pub const LIMITS: ReadLimits = ReadLimits { max_nodes: 1 << 20 };

/// Reads `data` as `kind` and checks every invariant the reader promises.
pub fn check_reader(data: &[u8], kind: FileKind) {
    let Ok(tree) = decode(data, Some(kind), LIMITS) else {
        // Rejected: the streaming run reader must reject it too.
        assert!(scan_runs(data, Some(kind), LIMITS, &mut |_| {}).is_err());
        return;
    };
    assert!(tree.data_end <= data.len());
    assert!(tree.node_count >= tree.leaves.len() as u64);
    assert!(tree.node_count <= LIMITS.max_nodes);
    // Leaves come sorted, aligned and disjoint: a valid snapshot unless a `.ot` value is NaN.
    let has_nan = tree.leaves.iter().any(|leaf| leaf.log_odds.is_nan());
    assert!(
        !(has_nan && kind == FileKind::Binary),
        ".bt leaves have fixed values"
    );
    let voxels: u64 = tree.leaves.iter().map(|leaf| leaf.voxel_count()).sum();
    match Snapshot::from_leaves(tree.header.resolution, tree.leaves) {
        Ok(snapshot) => assert!(!has_nan && snapshot.stats().occupied_voxels <= voxels),
        Err(error) => assert!(has_nan, "decoded leaves are not a map: {error}"),
    }
    // Runs cover exactly the leaves' voxels.
    let mut covered = 0u64;
    let mut previous_end = 0u64;
    scan_runs(data, Some(kind), LIMITS, &mut |run| {
        assert!(run.start.0 >= previous_end && run.end > run.start.0);
        previous_end = run.end;
        covered += run.len();
    })
    .expect("scan_runs accepts what decode accepts");
    assert_eq!(covered, voxels);
}
