//! The native Rust codec against the upstream C++ library (through the FFI plugins), which is
//! the oracle: on the real FR-079 scan, every fixture and random trees, both read the same
//! leaves (bit for bit), count the same nodes and warn alike, and both write the same bytes,
//! through `encode_*` and through the streaming encoders. Truncated and mutated files get
//! the same error from both backends.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_core::{Leaf, MortonCode, Snapshot, VoxelKey, TREE_DEPTH};
use froctomap_formats::{Backend, FormatRegistry, ReadOptions, ReadOutcome, WriteOptions};
use froctomap_octomap_codec::{
    decode, encode_binary, encode_full, format_resolution, scan_runs, BinaryEncoder, FileKind,
    FullEncoder, ReadLimits,
};
use froctomap_octomap_ffi::OcTree;
use froctomap_test_support::{fixtures, geb079, leaf_tuples, octomap_fixture, scratch};
use proptest::prelude::*;
use std::path::Path;

fn read_with(backend: Backend, name: &str, bytes: &[u8]) -> Result<ReadOutcome, String> {
    FormatRegistry::with_default_formats()
        .read_bytes(
            Path::new(name),
            bytes,
            ReadOptions {
                backend: Some(backend),
                ..ReadOptions::default()
            },
        )
        // The printed chain, not the outer text alone: a refusal's reason is the cause of
        // the error that names the file, and the backends must agree on it too.
        .map_err(|e| {
            assert_eq!(froctomap_core::said_twice(&e), None, "{e:?}");
            froctomap_core::error_message(&e)
        })
}

/// Reads `bytes` through both backends and requires identical outcomes: the same snapshot
/// (log-odds compared bit for bit), node count and warnings, or the same error message.
/// Returns the native outcome.
fn assert_backends_agree(name: &str, bytes: &[u8]) -> Result<ReadOutcome, String> {
    let native = read_with(Backend::Native, name, bytes);
    let upstream = read_with(Backend::Octomap, name, bytes);
    match (&native, &upstream) {
        (Ok(n), Ok(u)) => {
            assert_eq!(n.format.backend, Backend::Native, "{name}");
            assert_eq!(u.format.backend, Backend::Octomap, "{name}");
            assert_eq!(n.format.name, u.format.name, "{name}");
            assert_eq!(
                n.map.snapshot.resolution().to_bits(),
                u.map.snapshot.resolution().to_bits(),
                "{name}"
            );
            assert!(
                leaf_tuples(&n.map.snapshot) == leaf_tuples(&u.map.snapshot),
                "{name}: the backends read different leaves"
            );
            assert_eq!(n.map.node_count, u.map.node_count, "{name}");
            assert_eq!(n.map.warnings, u.map.warnings, "{name}");
        }
        (Err(n), Err(u)) => assert_eq!(n, u, "{name}: different errors"),
        _ => panic!("{name}: native {native:?} but upstream {upstream:?}"),
    }
    native
}

fn upstream_bt(snapshot: &Snapshot) -> Vec<u8> {
    OcTree::from_snapshot(snapshot)
        .and_then(|mut tree| tree.write_binary())
        .expect("upstream writes .bt")
}

fn upstream_ot(snapshot: &Snapshot) -> Vec<u8> {
    OcTree::from_snapshot(snapshot)
        .and_then(|tree| tree.write_full())
        .expect("upstream writes .ot")
}

fn streamed_bt(snapshot: &Snapshot) -> Vec<u8> {
    let mut encoder = BinaryEncoder::new(snapshot.resolution()).unwrap();
    for leaf in snapshot.leaves() {
        encoder.push(*leaf).unwrap();
    }
    let mut out = Vec::new();
    let nodes = encoder.finish(&mut out).unwrap();
    assert_eq!(
        Some(nodes),
        decode(&out, None, ReadLimits::default())
            .ok()
            .map(|t| t.node_count)
    );
    out
}

fn streamed_ot(snapshot: &Snapshot) -> Vec<u8> {
    let mut encoder = FullEncoder::new(snapshot.resolution()).unwrap();
    for leaf in snapshot.leaves() {
        encoder.push(*leaf).unwrap();
    }
    encoder.finish_to_vec()
}

/// First differing offset, for readable failures on large files.
fn first_difference(a: &[u8], b: &[u8]) -> Option<usize> {
    a.iter()
        .zip(b)
        .position(|(x, y)| x != y)
        .or((a.len() != b.len()).then(|| a.len().min(b.len())))
}

/// Every writer produces exactly upstream's bytes for `snapshot`; returns them (`.bt`, `.ot`).
fn assert_writers_agree(what: &str, snapshot: &Snapshot) -> (Vec<u8>, Vec<u8>) {
    let (bt, ot) = (upstream_bt(snapshot), upstream_ot(snapshot));
    for (writer, ours, theirs) in [
        ("encode_binary", encode_binary(snapshot), &bt),
        ("BinaryEncoder", streamed_bt(snapshot), &bt),
        ("encode_full", encode_full(snapshot), &ot),
        ("FullEncoder", streamed_ot(snapshot), &ot),
    ] {
        assert!(
            ours == *theirs,
            "{what}: {writer} differs from upstream at byte {:?} ({} vs {} bytes)",
            first_difference(&ours, theirs),
            ours.len(),
            theirs.len()
        );
    }
    // And through the registry, on disk.
    let dir = scratch();
    let registry = FormatRegistry::with_default_formats();
    for (ext, expected) in [("bt", &bt), ("ot", &ot)] {
        let path = dir.path().join(format!("native.{ext}"));
        let written = registry
            .write_file(snapshot, &path, WriteOptions::default())
            .unwrap();
        assert_eq!(written.backend, Backend::Native);
        assert!(std::fs::read(&path).unwrap() == *expected, "{what}: .{ext}");
    }
    (bt, ot)
}

#[test]
fn geb079_reads_and_writes_identically() {
    let bytes = std::fs::read(geb079()).unwrap();
    let read = assert_backends_agree("geb079.bt", &bytes).unwrap();
    assert_eq!(read.map.snapshot.leaves().len(), 428_144);
    let (bt, ot) = assert_writers_agree("geb079", &read.map.snapshot);
    assert!(
        bt == bytes,
        "geb079.bt is canonical: rewriting it changes nothing"
    );
    let from_ot = assert_backends_agree("geb079.ot", &ot).unwrap();
    assert_eq!(from_ot.map.snapshot, read.map.snapshot);
}

#[test]
fn every_fixture_reads_and_writes_identically() {
    for file in fixtures::generate() {
        let bytes = std::fs::read(octomap_fixture(file.name)).unwrap();
        let read = assert_backends_agree(file.name, &bytes).unwrap();
        assert_eq!(
            read.map.snapshot,
            fixtures::expected_snapshot(file.name),
            "{}",
            file.name
        );
        assert_writers_agree(file.name, &read.map.snapshot);
    }
    // The fixtures' source maps, with their graded log-odds, too.
    assert_writers_agree("few_voxels", &fixtures::few_voxels());
    assert_writers_agree("coarse_leaves", &fixtures::coarse_leaves());
}

#[test]
fn every_truncation_of_every_small_fixture_fails_alike_in_both_backends() {
    for name in [
        "few_voxels.bt",
        "few_voxels.ot",
        "coarse_leaves.bt",
        "coarse_leaves.ot",
        "crlf_comments.bt",
        "legacy_headerless.bt",
        "size_mismatch.bt",
    ] {
        let bytes = std::fs::read(octomap_fixture(name)).unwrap();
        for len in 0..bytes.len() {
            let err = assert_backends_agree(name, &bytes[..len])
                .err()
                .unwrap_or_else(|| panic!("{name} cut to {len} bytes was accepted"));
            assert!(err.starts_with(&format!("{name}: ")), "{err}");
        }
    }
}

// ---------------------------------------------------------------------------------------
// Random trees
// ---------------------------------------------------------------------------------------

/// A small deterministic generator (xorshift64*), so one proptest seed is one tree.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn chance(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }
}

/// Values that make the writers' corner cases likely: states on both sides of 0 (and ±0),
/// the clamping bounds, extremes whose maximum is `-FLT_MAX` or infinite, and a random one.
fn random_value(rng: &mut Rng) -> f32 {
    const PALETTE: [f32; 11] = [
        -2.0,
        3.5,
        0.0,
        -0.0,
        -0.4,
        0.85,
        f32::MIN_POSITIVE,
        -f32::MAX,
        f32::NEG_INFINITY,
        f32::INFINITY,
        1e-30,
    ];
    if rng.chance(80) {
        PALETTE[rng.below(PALETTE.len() as u64) as usize]
    } else {
        // Any finite or infinite non-NaN value.
        let value = f32::from_bits(rng.next() as u32);
        if value.is_nan() {
            -1.25
        } else {
            value
        }
    }
}

/// A random tree below a random node: leaves at every depth, complete sibling groups of one
/// state (prunable, often several levels up), partial groups, and coarse leaves in complete
/// groups that only merge if deeper levels merged first (upstream's prune stops otherwise).
fn random_tree(seed: u64, max_leaves: usize) -> Snapshot {
    let mut rng = Rng(seed | 1);
    let top_depth = rng.below(14) as u8;
    let top_start = MortonCode(rng.next() & (MortonCode::END - 1)).node_start(top_depth);
    // How eagerly subtrees stop early: low values make deep trees with voxel leaves.
    let leaf_bias = rng.below(60);
    let mut leaves = Vec::new();
    let mut stack = vec![(top_start.0, top_depth, None::<f32>)];
    while let Some((start, depth, inherited)) = stack.pop() {
        let value = inherited.unwrap_or_else(|| random_value(&mut rng));
        let becomes_leaf = depth == TREE_DEPTH
            || (depth > top_depth && rng.chance(leaf_bias + u64::from(depth) * 2))
            || leaves.len() + stack.len() >= max_leaves;
        if becomes_leaf {
            leaves.push(Leaf {
                start: MortonCode(start),
                depth,
                log_odds: value,
            });
            continue;
        }
        // Children share their parent's value (so groups can merge) or draw their own.
        let uniform = rng.chance(55);
        let complete = rng.chance(60);
        let child_size = froctomap_core::voxels_per_node(depth + 1);
        for child in (0..8u64).rev() {
            if complete || rng.chance(60) {
                let inherited = if uniform { Some(value) } else { None };
                stack.push((start + child * child_size, depth + 1, inherited));
            }
        }
    }
    Snapshot::from_leaves(0.05, leaves).expect("generated leaves form a tree")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(160))]

    #[test]
    fn random_trees_write_identically(seed in any::<u64>(), size in 1usize..1500) {
        let snapshot = random_tree(seed, size);
        let (bt, ot) = assert_writers_agree(&format!("seed {seed}"), &snapshot);
        // And what upstream wrote reads back alike through both backends.
        let from_bt = assert_backends_agree("random.bt", &bt).unwrap();
        prop_assert!(from_bt.map.snapshot.same_voxel_states(&snapshot.to_max_likelihood()));
        let from_ot = assert_backends_agree("random.ot", &ot).unwrap();
        prop_assert_eq!(leaf_tuples(&from_ot.map.snapshot), leaf_tuples(&snapshot));
    }

    #[test]
    fn unpruned_bt_of_random_trees_reads_identically(seed in any::<u64>(), size in 1usize..1500) {
        // writeBinaryConst keeps the leaves as they are, including non-canonical splits.
        let snapshot = random_tree(seed, size);
        let bytes = OcTree::from_snapshot(&snapshot).unwrap().write_binary_unchanged().unwrap();
        let read = assert_backends_agree("unpruned.bt", &bytes).unwrap();
        prop_assert_eq!(read.map.snapshot.leaves().len(), snapshot.leaves().len());
    }

    #[test]
    fn resolutions_are_printed_as_upstream_prints_them(
        mantissa in 1.0f64..10.0,
        exponent in -9i32..9,
        digits in 0usize..9,
    ) {
        // Short decimals (what people pick) and full-precision values, across magnitudes.
        let value = mantissa * 10f64.powi(exponent);
        let short: f64 = format!("{:.*e}", digits, value).parse().unwrap();
        for resolution in [value, short] {
            assert_same_header(resolution);
        }
    }

    #[test]
    fn mutated_files_fail_or_read_alike(
        which in 0usize..4,
        flips in proptest::collection::vec((any::<proptest::sample::Index>(), any::<u8>()), 1..4),
    ) {
        let name = ["few_voxels.bt", "few_voxels.ot", "coarse_leaves.bt", "coarse_leaves.ot"][which];
        let mut bytes = std::fs::read(octomap_fixture(name)).unwrap();
        for (index, value) in flips {
            let at = index.index(bytes.len());
            bytes[at] = value;
        }
        let _ = assert_backends_agree(name, &bytes);
    }
}

fn assert_same_header(resolution: f64) {
    let empty = Snapshot::empty(resolution).unwrap();
    let ours = encode_binary(&empty);
    let theirs = upstream_bt(&empty);
    assert!(
        ours == theirs,
        "res {resolution:e}: ours {:?}, upstream {:?}",
        String::from_utf8_lossy(&ours),
        String::from_utf8_lossy(&theirs)
    );
    assert_eq!(encode_full(&empty), upstream_ot(&empty), "{resolution:e}");
}

#[test]
fn resolution_formatting_matches_upstream_on_chosen_values() {
    // Rounding carries (999999.5 → 1e+06), ties (exact binary halves round to even, as glibc
    // does), the fixed/exponent boundaries at 1e-4 and 1e6, and typical map resolutions.
    for resolution in [
        0.08,
        0.1,
        0.05,
        0.025,
        0.2,
        1.0,
        1e-5,
        1e-4,
        0.0001234565,
        123456.7,
        999999.4,
        999999.5,
        1e6,
        1234565.0,
        1234575.0,
        2.5,
        0.125,
        1.0 / 3.0,
        f64::MIN_POSITIVE,
        f64::MAX,
        5e-324,
    ] {
        assert_same_header(resolution);
        assert!(!format_resolution(resolution).is_empty());
    }
}

/// Eight leaves filling `parent`'s eight children, all of one value.
fn group(parent: Leaf, value: f32) -> Vec<Leaf> {
    let size = froctomap_core::voxels_per_node(parent.depth + 1);
    (0..8)
        .map(|i| Leaf {
            start: MortonCode(parent.start.0 + i * size),
            depth: parent.depth + 1,
            log_odds: value,
        })
        .collect()
}

/// Leaves filling `parent` so that pruning merges something at every depth from 15 up to
/// `parent.depth`: children 1–7 are leaves, child 0 is filled the same way, down to eight
/// voxels.
fn cascade(parent: Leaf, value: f32) -> Vec<Leaf> {
    let mut children = group(parent, value);
    if parent.depth + 1 == TREE_DEPTH {
        return children;
    }
    let first = children.remove(0);
    let mut leaves = cascade(first, value);
    leaves.extend(children);
    leaves
}

/// Upstream's prune stops at the first depth where nothing merged, and never merges into
/// the root; the writer must reproduce both, not do a full prune.
#[test]
fn prune_quirks_are_reproduced() {
    let node = |x: u16, depth: u8| Leaf::containing(VoxelKey::new(x, 0, 0), depth, 0.0);
    let leaves_after_write = |mut leaves: Vec<Leaf>| -> Vec<u8> {
        leaves.sort_by_key(|l| l.start);
        let snapshot = Snapshot::from_leaves(0.1, leaves).unwrap();
        let (bt, _) = assert_writers_agree("quirk", &snapshot);
        let mut depths: Vec<u8> = decode(&bt, Some(FileKind::Binary), ReadLimits::default())
            .unwrap()
            .leaves
            .iter()
            .map(|l| l.depth)
            .collect();
        depths.sort_unstable();
        depths
    };
    // Eight equal depth-14 leaves alone: nothing merges at depth 15, so nothing at all.
    assert_eq!(leaves_after_write(group(node(0, 13), 1.0)), [14; 8]);
    // The same eight beside a subtree that merges at depths 15 and 14: now they merge too.
    let mut leaves = group(node(0, 13), 1.0);
    leaves.extend(cascade(node(256, 14), -1.0));
    assert_eq!(leaves_after_write(leaves), [13, 14]);
    // A merge at depth 15 but none at 14 stops the prune before eight equal depth-13 leaves.
    let mut leaves = group(node(0, 12), 2.0);
    leaves.extend(group(node(256, 15), 2.0));
    assert_eq!(
        leaves_after_write(leaves),
        [13, 13, 13, 13, 13, 13, 13, 13, 15]
    );
    // Every depth merges down to depth 1, leaving eight equal depth-1 leaves: the root
    // never absorbs them, whether the merging subtree comes first or last.
    for which in [0, 7] {
        let mut leaves = group(node(0, 0), 3.0);
        let merging = leaves.remove(which);
        leaves.extend(cascade(merging, 3.0));
        assert_eq!(leaves_after_write(leaves), [1; 8]);
    }
}

/// Edge trees: empty, a root without children (free or occupied: upstream writes a `.bt`
/// root without child codes, which reads back occupied either way), single voxels at the
/// corners of the key space, and one coarse leaf at every depth.
#[test]
fn edge_trees_read_and_write_identically() {
    let root = |log_odds: f32| Leaf {
        start: MortonCode(0),
        depth: 0,
        log_odds,
    };
    let mut maps = vec![
        vec![],
        vec![root(-2.0)],
        vec![root(3.5)],
        vec![root(-0.0)],
        vec![Leaf::voxel(VoxelKey::new(0, 0, 0), 1.0)],
        vec![Leaf::voxel(
            VoxelKey::new(u16::MAX, u16::MAX, u16::MAX),
            -1.0,
        )],
    ];
    for depth in 1..=TREE_DEPTH {
        maps.push(vec![Leaf::containing(
            VoxelKey::new(40000, 9, 65000),
            depth,
            0.5,
        )]);
    }
    for leaves in maps {
        let snapshot = Snapshot::from_leaves(0.2, leaves).unwrap();
        let (bt, ot) = assert_writers_agree("edge tree", &snapshot);
        let from_bt = assert_backends_agree("edge.bt", &bt).unwrap();
        let from_ot = assert_backends_agree("edge.ot", &ot).unwrap();
        assert_eq!(from_ot.map.snapshot, snapshot);
        if let [leaf] = snapshot.leaves() {
            if leaf.depth == 0 {
                assert!(from_bt.map.snapshot.leaves()[0].occupancy().is_occupied());
                continue;
            }
        }
        assert!(from_bt
            .map
            .snapshot
            .same_voxel_states(&snapshot.to_max_likelihood()));
    }
}

/// Hostile structure is refused by both backends alike, before anything large happens.
#[test]
fn deep_chains_and_node_floods_fail_alike() {
    let header = |size: usize| {
        format!("# Octomap OcTree binary file\nid OcTree\nsize {size}\nres 0.1\ndata\n")
            .into_bytes()
    };
    let mut deep = header(1_000_001);
    deep.extend(std::iter::repeat_n([0b11u8, 0], 1_000_000).flatten());
    let err = assert_backends_agree("deep.bt", &deep).unwrap_err();
    assert!(err.contains("depth 16"), "{err}");
    // Every inner node has eight inner children down to depth 15, whose eight voxels are
    // occupied: 8^16 leaves claimed, cut off after 200 kB. Refused as truncated, in time.
    fn claim_everything(depth: u8, out: &mut Vec<u8>) {
        if out.len() >= 200_000 {
            return;
        }
        if depth == 15 {
            out.extend([0xAA, 0xAA]);
            return;
        }
        out.extend([0xFF, 0xFF]);
        for _ in 0..8 {
            claim_everything(depth + 1, out);
        }
    }
    let mut flood = header(4_000_000_000);
    claim_everything(0, &mut flood);
    let err = assert_backends_agree("flood.bt", &flood).unwrap_err();
    assert!(err.contains("truncated"), "{err}");
    // With a node limit below what the prefix holds, the limit is what stops it.
    let limited = froctomap_octomap_codec::decode(&flood, None, ReadLimits { max_nodes: 50_000 });
    assert!(
        matches!(
            limited,
            Err(froctomap_octomap_codec::CodecError::TooManyNodes { limit: 50_000 })
        ),
        "{limited:?}"
    );
    assert!(matches!(
        OcTree::read_binary_with_limits(&flood, ReadLimits { max_nodes: 50_000 }),
        Err(froctomap_octomap_ffi::OctomapError::Malformed(
            froctomap_octomap_codec::CodecError::TooManyNodes { .. }
        ))
    ));
}

/// Runs of the native scan agree with the voxel states upstream reports.
#[test]
fn voxel_runs_cover_the_same_voxels_as_upstream_leaves() {
    let bytes = std::fs::read(geb079()).unwrap();
    let upstream = OcTree::read_binary(&bytes)
        .unwrap()
        .tree
        .to_snapshot()
        .unwrap();
    let mut runs = Vec::new();
    scan_runs(&bytes, None, ReadLimits::default(), &mut |run| {
        runs.push(run)
    })
    .unwrap();
    let covered: u64 = runs.iter().map(|r| r.len()).sum();
    let stats = upstream.stats();
    assert_eq!(covered, stats.occupied_voxels + stats.free_voxels);
    assert!(runs.len() < upstream.leaves().len());
    for pair in runs.windows(2) {
        assert!(pair[0].end < pair[1].start.0 || pair[0].state != pair[1].state);
    }
    for run in runs.iter().step_by(97) {
        assert_eq!(upstream.state_at(run.start), Some(run.state));
        assert_eq!(upstream.state_at(MortonCode(run.end - 1)), Some(run.state));
    }
}
