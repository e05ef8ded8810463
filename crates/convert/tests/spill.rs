//! Bounded-memory builds: a build forced to spill its histories to disk (a budget of zero
//! bytes spills after every snapshot) writes the same bytes as one that keeps everything in
//! memory, and leaves no spill data behind, also when it fails half-way.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use froctomap_convert::*;
use froctomap_core::{Leaf, Snapshot, Timestamp, VoxelKey};
use froctomap_formats::WriteOptions;
use proptest::prelude::*;
use std::path::{Path, PathBuf};

/// A leaf per slot of 8 voxels along x: `None` leaves the slot unknown in that frame (a
/// partial view), else `(depth, occupied)`; shallow depths make coarse leaves that cover
/// the slots after them (those are then left out).
type Frame = Vec<Option<(u8, bool)>>;

fn snapshot(frame: &Frame) -> Snapshot {
    let mut leaves: Vec<Leaf> = Vec::new();
    for (slot, leaf) in frame.iter().enumerate() {
        let Some((depth, occupied)) = *leaf else {
            continue;
        };
        let key = VoxelKey::new(32768 + 8 * slot as u16, 32768, 32768 + (slot % 3) as u16);
        let leaf = Leaf::containing(key, depth, if occupied { 2.0 } else { -2.0 });
        if leaves
            .iter()
            .all(|o| o.end() <= leaf.start.0 || leaf.end() <= o.start.0)
        {
            leaves.push(leaf);
        }
    }
    Snapshot::from_leaves(0.1, leaves).unwrap()
}

/// Writes the frames as .bt files one second apart, skipping the seconds in `missing`, and
/// returns the series.
fn write_series(dir: &Path, frames: &[Frame], missing: &[u32]) -> Vec<SeriesInput> {
    let context = Context::with_default_plugins();
    let mut inputs = Vec::new();
    let mut second = 0u32;
    for (i, frame) in frames.iter().enumerate() {
        while missing.contains(&second) {
            second += 1;
        }
        let path = dir.join(format!("frame_{i:03}.bt"));
        context
            .formats()
            .write_file(&snapshot(frame), &path, WriteOptions::default())
            .unwrap();
        inputs.push(SeriesInput::new(
            path,
            Timestamp::from_secs(1_451_865_600 + i64::from(second)),
        ));
        second += 1;
    }
    inputs
}

fn options(tile_depth: u8, memory: u64, tmp_dir: &Path) -> BuildOptions {
    BuildOptions {
        tile_depth,
        memory,
        tmp_dir: Some(tmp_dir.to_path_buf()),
        time: Some(Timestamp::from_secs(1_700_000_000)),
        ..BuildOptions::default()
    }
}

fn entries(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    found.sort();
    found
}

/// Builds `inputs` twice, in memory and spilling after every snapshot, and checks the files
/// are the same bytes and no spill data is left.
fn same_bytes_when_spilling(inputs: &[SeriesInput], tile_depth: u8) -> Result<(), TestCaseError> {
    let out = tempfile::tempdir().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let kept_path = out.path().join("kept.froct");
    let spilled_path = out.path().join("spilled.froct");
    let kept = build(
        &context,
        inputs,
        &kept_path,
        &options(tile_depth, u64::MAX, tmp.path()),
        &Silent,
    )
    .unwrap();
    prop_assert_eq!(kept.spilled_bytes, 0);
    let spilled = build(
        &context,
        inputs,
        &spilled_path,
        &options(tile_depth, 0, tmp.path()),
        &Silent,
    )
    .unwrap();
    if kept.cells.total() > 0 {
        // (Bytes only where some run had closed: a series that never changes spills none.)
        prop_assert!(spilled.spills > 0);
    }
    prop_assert!(
        std::fs::read(&kept_path).unwrap() == std::fs::read(&spilled_path).unwrap(),
        "tile depth {}: the spilled build differs",
        tile_depth
    );
    prop_assert_eq!(entries(tmp.path()), Vec::<PathBuf>::new());
    prop_assert_eq!(entries(out.path()), vec![kept_path, spilled_path]);
    Ok(())
}

fn frame_strategy() -> impl Strategy<Value = Frame> {
    proptest::collection::vec(
        proptest::option::weighted(0.8, (13u8..=16, proptest::bool::weighted(0.3))),
        12,
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Partial views (slots unknown in some frames), missing samples, coarse and fine
    /// leaves, several tile depths: spilling never changes a byte.
    #[test]
    fn a_build_forced_to_spill_writes_the_same_bytes(
        first in frame_strategy(),
        // Each later frame changes a few slots of the one before (state, depth, known).
        edits in proptest::collection::vec(
            proptest::collection::vec((0usize..12, proptest::option::weighted(0.75, (13u8..=16, any::<bool>()))), 0..4),
            1..14,
        ),
        missing in proptest::collection::vec(1u32..20, 0..3),
        tile_depth in prop_oneof![Just(12u8), Just(14), Just(15)],
    ) {
        let mut frames = vec![first];
        for edit in edits {
            let mut next = frames[frames.len() - 1].clone();
            for (slot, leaf) in edit {
                next[slot] = leaf;
            }
            frames.push(next);
        }
        let dir = tempfile::tempdir().unwrap();
        let inputs = write_series(dir.path(), &frames, &missing);
        same_bytes_when_spilling(&inputs, tile_depth)?;
    }
}

#[test]
fn a_failed_build_leaves_no_spill_data_and_no_output() {
    // A slot that toggles every frame, and a partial view every third frame.
    let frames: Vec<Frame> = (0..30)
        .map(|i| {
            (0..12)
                .map(|slot| match slot {
                    0 => Some((16, i % 2 == 0)),
                    5 if i % 3 == 1 => None,
                    _ => Some((14, slot % 4 == 0)),
                })
                .collect()
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let inputs = write_series(dir.path(), &frames, &[]);
    // Frame 20 keeps its header but loses the end of its tree: the header check passes, and
    // the build fails only when it reaches the frame, after spilling the ones before.
    let damaged = &inputs[20].path;
    let bytes = std::fs::read(damaged).unwrap();
    std::fs::write(damaged, &bytes[..bytes.len() - 8]).unwrap();
    let out = tempfile::tempdir().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let output = out.path().join("series.froct");
    let failed = build(
        &context,
        &inputs,
        &output,
        &options(14, 0, tmp.path()),
        &Silent,
    );
    assert!(failed.is_err(), "{failed:?}");
    assert_eq!(
        entries(tmp.path()),
        Vec::<PathBuf>::new(),
        "spill data left"
    );
    assert_eq!(entries(out.path()), Vec::<PathBuf>::new(), "output left");
    // Without --tmp-dir the spill data goes beside the output, and goes away as well.
    let mut beside = options(14, 0, tmp.path());
    beside.tmp_dir = None;
    assert!(
        build(&context, &inputs[..20], &output, &beside, &Silent)
            .unwrap()
            .spilled_bytes
            > 0
    );
    assert_eq!(entries(out.path()), vec![output]);
}
