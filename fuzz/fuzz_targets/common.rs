//! Checks shared by the reader targets: whatever the input, reading returns (never panics,
//! never hangs), and what it accepts is a valid map whose streamed forms agree, and the
//! byte-level comparison with another file accepts the same inputs and finds the changes
//! between the decoded maps.

use froctomap_core::{changes, Leaf, MortonCode, Snapshot};
use froctomap_octomap_codec::{
    decode, diff, encode_binary, encode_full, scan_runs, FileKind, ReadLimits,
};

/// Small enough that a hostile `size` or a deep chain cannot make one input slow.
pub const LIMITS: ReadLimits = ReadLimits { max_nodes: 1 << 20 };

/// Reads `data` as `kind` and checks every invariant the reader promises.
pub fn check_reader(data: &[u8], kind: FileKind) {
    let previous = previous_file(kind);
    let mut found = Vec::new();
    let compared = diff(Some((&previous, None)), data, Some(kind), LIMITS, &mut |c| {
        found.push(c)
    });
    let Ok(tree) = decode(data, Some(kind), LIMITS) else {
        // Rejected: the streaming run reader and the comparison must reject it too.
        assert!(scan_runs(data, Some(kind), LIMITS, &mut |_| {}).is_err());
        assert!(compared.is_err(), "compared what the reader rejects");
        return;
    };
    if tree.leaves.iter().any(|leaf| leaf.log_odds.is_nan()) {
        assert!(compared.is_err(), "compared a NaN leaf");
    } else {
        let (summary, _) = compared.expect("compares what the reader accepts");
        assert_eq!((summary.node_count, summary.data_end), (tree.node_count, tree.data_end));
        let before = decode(&previous, Some(kind), LIMITS).expect("a valid file").leaves;
        assert_eq!(found, changes(&before, &tree.leaves));
    }
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

/// A small valid file to compare inputs with: leaves of several depths near the origin,
/// where small fuzzed trees put theirs.
fn previous_file(kind: FileKind) -> Vec<u8> {
    let leaves = [(0u64, 3u8, 1.0f32), (1 << 39, 4, -1.0), (9 << 36, 5, 2.0), (1 << 45, 1, -2.0)]
        .map(|(start, depth, log_odds)| Leaf {
            start: MortonCode(start),
            depth,
            log_odds,
        });
    let snapshot = Snapshot::from_leaves(0.1, leaves.to_vec()).expect("valid leaves");
    match kind {
        FileKind::Binary => encode_binary(&snapshot),
        FileKind::Full => encode_full(&snapshot),
    }
}
