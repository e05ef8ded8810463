//! Decode, encode, decode: whatever the reader accepts, the writers turn into files that read
//! back as the same map (`.ot` leaves bit for bit, `.bt` as the same voxel states), a
//! canonical `.bt` is a fixed point (upstream's pruning is idempotent), and the streaming
//! encoders produce the very bytes of the whole-snapshot ones.
//!
//! Two limits of the file format, found by this target and shared with upstream: the
//! resolution survives only to the 6 significant digits the header prints, so it is compared
//! as printed; and a map that is one root leaf writes as a `.bt` whose root has no child
//! codes, which every reader loads as occupied whatever the leaf's state.
#![no_main]

use froctomap_core::{Occupancy, Snapshot};
use froctomap_octomap_codec::{
    decode, encode_binary, encode_full, format_resolution, BinaryEncoder, FullEncoder, ReadLimits,
};
use libfuzzer_sys::fuzz_target;

const LIMITS: ReadLimits = ReadLimits { max_nodes: 1 << 20 };

fn read(bytes: &[u8]) -> Snapshot {
    let tree = decode(bytes, None, LIMITS).expect("written files read back");
    assert!(
        tree.warnings.is_empty(),
        "written files are canonical: {:?}",
        tree.warnings
    );
    Snapshot::from_leaves(tree.header.resolution, tree.leaves).expect("valid map")
}

fuzz_target!(|data: &[u8]| {
    let Ok(tree) = decode(data, None, LIMITS) else {
        return;
    };
    let Ok(snapshot) = Snapshot::from_leaves(tree.header.resolution, tree.leaves) else {
        return;
    };
    let printed = format_resolution(snapshot.resolution());
    let full = encode_full(&snapshot);
    let from_full = read(&full);
    assert_eq!(format_resolution(from_full.resolution()), printed);
    assert!(
        from_full.leaves() == snapshot.leaves(),
        ".ot round trip changed the leaves"
    );
    let binary = encode_binary(&snapshot);
    let from_binary = read(&binary);
    assert_eq!(format_resolution(from_binary.resolution()), printed);
    // Same voxel states; compared at one resolution, as the printed one may differ.
    let mut leaves = snapshot.leaves().to_vec();
    if let [root] = leaves.as_mut_slice() {
        if root.depth == 0 {
            root.log_odds = Occupancy::Occupied.log_odds();
        }
    }
    let expected = Snapshot::from_leaves(from_binary.resolution(), leaves)
        .expect("valid map")
        .to_max_likelihood();
    assert!(from_binary.same_voxel_states(&expected));
    assert!(
        encode_binary(&from_binary) == binary,
        "canonical .bt is a fixed point"
    );

    let mut bt = BinaryEncoder::new(snapshot.resolution()).expect("valid resolution");
    let mut ot = FullEncoder::new(snapshot.resolution()).expect("valid resolution");
    for leaf in snapshot.leaves() {
        bt.push(*leaf).expect("snapshot leaves are in order");
        ot.push(*leaf).expect("snapshot leaves are in order");
    }
    assert!(bt.finish_to_vec() == binary);
    assert!(ot.finish_to_vec() == full);
});
