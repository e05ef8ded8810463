//! The golden files `fixtures/froct/golden-v1.0.froct` (whole toggle lists),
//! `golden-v1.1.froct` (toggle lists in blocks) and `golden-v1.2.froct` (blocks range
//! coded), each written by its version, must stay readable by every later version, with
//! the same content. The files those versions' first release wrote (`golden-v1.0-r0.froct`,
//! `golden-v1.1-r0.froct`, `golden-v1.2-r0.froct`, `golden-v2.0-r0.froct`, fitted by the
//! earlier fit) are kept beside the regenerated ones: a reader must read both back with the
//! same observed states, whatever fit wrote them.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use froctomap_file::{ByteSource, FroctReader, MemorySource, ReadLimits, MAJOR_VERSION};
use std::ops::Range;
use std::path::Path;
use std::sync::{Arc, Mutex};

/// Bytes in memory that record the ranges a reader asks for.
struct RecordingSource {
    bytes: MemorySource<Vec<u8>>,
    reads: Arc<Mutex<Vec<Range<u64>>>>,
}

impl ByteSource for RecordingSource {
    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        self.reads
            .lock()
            .unwrap()
            .push(offset..offset + buf.len() as u64);
        self.bytes.read_exact_at(offset, buf)
    }

    fn size(&self) -> u64 {
        self.bytes.size()
    }

    fn name(&self) -> &Path {
        self.bytes.name()
    }
}

/// The golden files are regenerated only on purpose: `FROCTOMAP_REGENERATE_GOLDEN=1 cargo
/// test -p froctomap-file --test golden`. Otherwise the writer must reproduce each, in its
/// version's layout, byte for byte.
#[test]
fn writer_reproduces_the_golden_files() {
    let dir = tempfile::tempdir().unwrap();
    for (name, toggles) in GOLDENS {
        let fresh = dir.path().join(name);
        write_golden(&fresh, toggles);
        let fresh = std::fs::read(&fresh).unwrap();
        if std::env::var_os("FROCTOMAP_REGENERATE_GOLDEN").is_some() {
            // Atomically, so tests reading the golden file meanwhile never see half of it.
            froctomap_core::write_atomically(&golden_path_of(name), |out| out.write_all(&fresh))
                .unwrap();
        }
        let committed = std::fs::read(golden_path_of(name)).expect("the golden file is committed");
        assert!(
            committed == fresh,
            "the writer's output differs from fixtures/froct/{name}; if the format changed on \
             purpose, bump the version, keep reading the old golden file, and add a new one"
        );
    }
}

/// The golden files written by an earlier release, never regenerated: the fit that wrote
/// them differs from today's, their observed states do not.
const RELEASED_GOLDENS: [&str; 3] = [
    "golden-v1.0-r0.froct",
    "golden-v1.1-r0.froct",
    "golden-v1.2-r0.froct",
];

#[test]
fn golden_files_read_back_every_observed_state() {
    for ((name, toggles), minor) in GOLDENS.into_iter().zip([0u16, 1, 2]) {
        check_golden_read_back(name, toggles, minor);
    }
}

#[test]
fn released_golden_files_read_back_every_observed_state() {
    for (((name, toggles), minor), released) in
        GOLDENS.into_iter().zip([0u16, 1, 2]).zip(RELEASED_GOLDENS)
    {
        assert_ne!(
            std::fs::read(golden_path_of(name)).unwrap(),
            std::fs::read(golden_path_of(released)).unwrap(),
            "{released} must be the earlier release's file, not a copy of {name}"
        );
        check_golden_read_back(released, toggles, minor);
    }
}

fn check_golden_read_back(name: &str, toggles: froctomap_file::ToggleLayout, minor: u16) {
    let reader = FroctReader::open(&golden_path_of(name)).unwrap();
    let header = reader.header();
    assert_eq!(header.version, (MAJOR_VERSION, minor), "{name}");
    assert_eq!(header.toggles, toggles, "{name}");
    assert_eq!(header.axis, golden_axis());
    assert_eq!(header.tile_depth, GOLDEN_TILE_DEPTH);
    assert_eq!(header.metadata["creator"], "froctomap-file tests");
    assert_eq!(reader.tiles().len(), 3);
    let expected = golden_cells();
    let mut decoded = Vec::new();
    for tile in 0..reader.tiles().len() {
        decoded.extend(reader.read_tile(tile).unwrap());
    }
    assert_eq!(decoded.len(), expected.len());
    // Format 1.2 range codes the noisy voxel's exceptions.
    let coded = decoded.iter().any(|c| {
        matches!(
            c.content,
            froctomap_file::CellContent::ConstantExcept { .. }
        )
    });
    assert_eq!(coded, minor == 2, "{name}");
    let axis = golden_axis();
    let truth = |series: &SeriesCell, sample: u32| {
        if axis.is_missing(sample) {
            None
        } else {
            series.observations.state_at(sample)
        }
    };
    for (cell, series) in decoded.iter().zip(&expected) {
        assert_eq!((cell.start, cell.depth), (series.start, series.depth));
        for sample in 0..axis.len() {
            assert_eq!(
                cell.state_at(&axis, reader.model(), sample),
                truth(series, sample),
                "{name}: cell {:?} sample {sample}",
                cell.start
            );
        }
    }
    // The one-sample path (what `retrieve` uses) gives the same states.
    for sample in 0..axis.len() {
        let mut leaves = Vec::new();
        for tile in 0..reader.tiles().len() {
            reader.observed_leaves(tile, sample, &mut leaves).unwrap();
        }
        let expected_leaves: Vec<_> = expected
            .iter()
            .filter_map(|c| truth(c, sample).map(|s| (c.start, s)))
            .collect();
        let got: Vec<_> = leaves.iter().map(|l| (l.start, l.occupancy())).collect();
        assert_eq!(got, expected_leaves, "{name}: sample {sample}");
    }
}

#[test]
fn region_queries_read_only_what_they_need() {
    let reads = Arc::new(Mutex::new(Vec::new()));
    let source = RecordingSource {
        bytes: MemorySource::new(std::fs::read(golden_path()).unwrap()),
        reads: Arc::clone(&reads),
    };
    let models = froctomap_temporal::ModelRegistry::with_default_models();
    let reader = FroctReader::from_source(source, ReadLimits::default(), &models).unwrap();
    let take_reads = || std::mem::take(&mut *reads.lock().unwrap());
    assert!(
        !take_reads().is_empty(),
        "opening reads header, footer and index"
    );
    let o = 32768u16;
    let door = froctomap_core::VoxelKey::new(o + 4, o, o);
    // One tile holds the door; the box around it touches no other tile, and a query reads
    // that tile's bytes and nothing else.
    let tiles = reader.tiles_in_box(door, door);
    assert_eq!(tiles.len(), 1);
    assert!(reader.tiles().len() > 1);
    let entry = reader.tiles()[tiles[0]];
    let door_tile = entry.offset..entry.offset + u64::from(entry.stored_len);
    reader.region_states(door, door, 3).unwrap();
    reader.region_probabilities(door, door, 1800.0).unwrap();
    assert_eq!(take_reads(), vec![door_tile.clone(), door_tile]);
    let axis = golden_axis();
    for sample in [3u32, 12, 40] {
        let states = reader.region_states(door, door, sample).unwrap();
        let expected = golden_cells()
            .into_iter()
            .find(|c| c.start == door.morton())
            .unwrap();
        let truth = if axis.is_missing(sample) {
            None
        } else {
            expected.observations.state_at(sample)
        };
        assert_eq!(
            states
                .iter()
                .find(|c| c.start == door.morton())
                .map(|c| c.value),
            truth,
            "sample {sample}"
        );
    }
    // Probabilities exist at any instant, also far in the future, and stay in [0, 1].
    for seconds in [-3600.0, 1800.0, 86_400.0 * 30.0] {
        let p = reader.region_probabilities(door, door, seconds).unwrap();
        assert!(!p.is_empty() && p.iter().all(|c| (0.0..=1.0).contains(&c.value)));
    }
    // A box far away touches nothing and reads nothing.
    take_reads();
    let far = froctomap_core::VoxelKey::new(100, 100, 100);
    assert!(reader.region_states(far, far, 0).unwrap().is_empty());
    assert_eq!(take_reads(), vec![]);
}

/// The format 2.0 golden file: the 1.2 golden file converted, then three segments (regular
/// with a missing sample, jittered explicit instants, regular off the base's grid) appended
/// by the one writer. Regenerated like the others.
const LIVING_GOLDEN: &str = "golden-v2.0.froct";

#[test]
fn writer_reproduces_the_living_golden_file() {
    let dir = tempfile::tempdir().unwrap();
    let fresh = dir.path().join(LIVING_GOLDEN);
    common::living::write_living_golden(&fresh, 3);
    let fresh = std::fs::read(&fresh).unwrap();
    if std::env::var_os("FROCTOMAP_REGENERATE_GOLDEN").is_some() {
        froctomap_core::write_atomically(&golden_path_of(LIVING_GOLDEN), |out| {
            out.write_all(&fresh)
        })
        .unwrap();
    }
    let committed =
        std::fs::read(golden_path_of(LIVING_GOLDEN)).expect("the golden file is committed");
    assert!(
        committed == fresh,
        "the writer's output differs from fixtures/froct/{LIVING_GOLDEN}; if the format \
         changed on purpose, bump the version, keep reading the old golden file, and add a new one"
    );
}

/// A format 2.0 file with a patch tile (FORMAT.md §10.6), which readers of the first 2.0
/// release refuse: `common::living::write_patch_golden`. Regenerated like the others.
const PATCH_GOLDEN: &str = "golden-v2.0-patch.froct";

#[test]
fn writer_reproduces_the_patch_golden_file() {
    let dir = tempfile::tempdir().unwrap();
    let fresh = dir.path().join(PATCH_GOLDEN);
    common::living::write_patch_golden(&fresh);
    let fresh = std::fs::read(&fresh).unwrap();
    if std::env::var_os("FROCTOMAP_REGENERATE_GOLDEN").is_some() {
        froctomap_core::write_atomically(&golden_path_of(PATCH_GOLDEN), |out| {
            out.write_all(&fresh)
        })
        .unwrap();
    }
    let committed =
        std::fs::read(golden_path_of(PATCH_GOLDEN)).expect("the golden file is committed");
    assert!(
        committed == fresh,
        "the writer's output differs from fixtures/froct/{PATCH_GOLDEN}; if the format \
         changed on purpose, bump the version, keep reading the old golden file, and add a new one"
    );
    let reader = froctomap_file::LivingReader::open(&golden_path_of(PATCH_GOLDEN)).unwrap();
    assert!(reader.is_patch_tile(0, 0));
}

/// A format 2.0 file with a patch tile whose remainder several masks observe (FORMAT.md
/// §10.7), which readers before that section refuse: `common::living::write_remainder_golden`.
/// Regenerated like the others.
const REMAINDER_GOLDEN: &str = "golden-v2.0-remainder.froct";

#[test]
fn writer_reproduces_the_remainder_golden_file() {
    let dir = tempfile::tempdir().unwrap();
    let fresh = dir.path().join(REMAINDER_GOLDEN);
    common::living::write_remainder_golden(&fresh);
    let fresh = std::fs::read(&fresh).unwrap();
    if std::env::var_os("FROCTOMAP_REGENERATE_GOLDEN").is_some() {
        froctomap_core::write_atomically(&golden_path_of(REMAINDER_GOLDEN), |out| {
            out.write_all(&fresh)
        })
        .unwrap();
    }
    let committed =
        std::fs::read(golden_path_of(REMAINDER_GOLDEN)).expect("the golden file is committed");
    assert!(
        committed == fresh,
        "the writer's output differs from fixtures/froct/{REMAINDER_GOLDEN}; if the format \
         changed on purpose, bump the version, keep reading the old golden file, and add a new one"
    );
    let reader = froctomap_file::LivingReader::open(&golden_path_of(REMAINDER_GOLDEN)).unwrap();
    assert_eq!(
        reader.remainder(0, 0).unwrap().map(|r| r.runs.len()),
        Some(2)
    );
    // The patch golden file, written before remainder runs, reads with one mask throughout.
    let reader = froctomap_file::LivingReader::open(&golden_path_of(PATCH_GOLDEN)).unwrap();
    assert!(reader
        .remainder(0, 0)
        .unwrap()
        .is_some_and(|r| r.runs.is_empty()));
}

/// The format 2.0 golden file the first 2.0 release wrote, never regenerated.
const RELEASED_LIVING_GOLDEN: &str = "golden-v2.0-r0.froct";

#[test]
fn living_golden_file_reads_back_every_observed_state() {
    check_living_golden_read_back(LIVING_GOLDEN);
}

#[test]
fn released_living_golden_file_reads_back_every_observed_state() {
    assert_ne!(
        std::fs::read(golden_path_of(LIVING_GOLDEN)).unwrap(),
        std::fs::read(golden_path_of(RELEASED_LIVING_GOLDEN)).unwrap(),
        "{RELEASED_LIVING_GOLDEN} must be the earlier release's file"
    );
    check_living_golden_read_back(RELEASED_LIVING_GOLDEN);
}

fn check_living_golden_read_back(name: &str) {
    let reader = froctomap_file::LivingReader::open(&golden_path_of(name)).unwrap();
    assert_eq!(
        reader.header().version,
        (froctomap_file::LIVING_MAJOR_VERSION, 0)
    );
    assert_eq!(reader.header().axis, golden_axis());
    assert_eq!(reader.segment_count(), 3);
    let plans: Vec<_> = common::living::golden_segment_axes()
        .iter()
        .enumerate()
        .map(|(k, axis)| common::living::golden_segment(k as u64, axis))
        .collect();
    let expected = common::living::expected_maps(&plans);
    assert_eq!(reader.sample_count() as usize, expected.len());
    for (sample, map) in expected.iter().enumerate() {
        assert_eq!(
            &reader.observed_states(sample as u32).unwrap(),
            map,
            "{name}: sample {sample}"
        );
    }
}
