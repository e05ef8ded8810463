//! Iterative append to format 2.0 files (issue 26): a room series built on its first four
//! days, converted to 2.0, then appended map by map and in batches at jittered instants
//! (off the base's hourly grid). Every earlier and every new snapshot read back through
//! `LivingReader::observed_states` must equal the map the format plugin decodes from the
//! input file, and the same snapshot of a plain 1.2 build of all the maps. The new part has
//! what a segment must handle: the door following its daily model (inherited cells), the
//! door opened at night (outliers), a box appearing on the free floor (base cells split),
//! a ceiling never seen before (cells new since the base), a corner hidden at times
//! (masks).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use froctomap_convert::*;
use froctomap_core::calendar::iso8601_basic;
use froctomap_core::{Leaf, Occupancy, Snapshot, Timestamp, VoxelKey};
use froctomap_file::{CellContent, FroctReader, LivingReader, LivingWriter, SegmentContent};
use froctomap_formats::{ReadOptions, WriteOptions};
use std::path::{Path, PathBuf};

/// Frames of the base: four days, hourly (enough cycles for the door's daily period).
const BASE_FRAMES: u32 = 96;
/// Frames in all: a fifth day appended.
const FRAMES: u32 = 120;

/// The instant of frame `i`: hourly on the base's grid, then up to a minute late.
fn instant(i: u32) -> Timestamp {
    let jitter = if i < BASE_FRAMES {
        0
    } else {
        i64::from(i * 37 % 61)
    };
    Timestamp(time(i).0 + jitter * 1_000_000_000)
}

/// Frame `i` of the series (see the module's comment).
fn series_frame(i: u32) -> Snapshot {
    let t = time(i);
    let boxed = |k: VoxelKey| {
        (ORIGIN + 4..ORIGIN + 7).contains(&k.x)
            && (ORIGIN + 5..ORIGIN + 8).contains(&k.y)
            && (ORIGIN + 1..ORIGIN + 3).contains(&k.z)
    };
    let hidden = |k: VoxelKey| i % 5 == 1 && k.x < ORIGIN + 8 && k.y >= ORIGIN + 20;
    let night_visit = i == BASE_FRAMES + 3 || i == BASE_FRAMES + 22;
    let mut leaves: Vec<Leaf> = keys()
        .filter(|&k| !hidden(k))
        .map(|k| {
            let mut s = state(k, t);
            if is_door(k) && night_visit {
                s = Occupancy::Free;
            }
            if boxed(k) && (BASE_FRAMES + 6..BASE_FRAMES + 12).contains(&i) {
                s = Occupancy::Occupied;
            }
            Leaf::voxel(k, s.log_odds())
        })
        .collect();
    if i >= BASE_FRAMES + 4 {
        // A ceiling, first seen in the last day, with a lamp that is on in the evening.
        for x in ORIGIN..ORIGIN + SIDE {
            for y in ORIGIN..ORIGIN + SIDE {
                let lamp = x == ORIGIN + 16 && y == ORIGIN + 16 && i % 24 >= 18;
                let s = if lamp || (u32::from(x) + u32::from(y)) % 2 == 0 {
                    Occupancy::Occupied
                } else {
                    Occupancy::Free
                };
                leaves.push(Leaf::voxel(
                    VoxelKey::new(x, y, ORIGIN + HEIGHT),
                    s.log_odds(),
                ));
            }
        }
    }
    leaves.sort_by_key(|l| l.start);
    Snapshot::from_leaves(RESOLUTION, leaves)
        .unwrap()
        .canonical()
}

/// Writes frames `frames` into `dir`; their paths.
fn write_frames(context: &Context, dir: &Path, frames: std::ops::Range<u32>) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir).unwrap();
    frames
        .map(|i| {
            let path = dir.join(format!("room_{}.bt", iso8601_basic(instant(i))));
            context
                .formats()
                .write_file(&series_frame(i), &path, WriteOptions::default())
                .unwrap();
            path
        })
        .collect()
}

fn inputs_of(context: &Context, paths: &[PathBuf]) -> Vec<SeriesInput> {
    collect_inputs(context, paths, TimeSource::Auto).unwrap()
}

/// The map the format plugin decodes from an input file.
fn decoded(context: &Context, path: &Path) -> Snapshot {
    context
        .formats()
        .read_file(path, ReadOptions::default())
        .unwrap()
        .map
        .snapshot
}

/// A 2.0 file's observed map at a global sample, as a snapshot.
fn living_snapshot(reader: &LivingReader, sample: u32) -> Snapshot {
    let leaves = reader
        .observed_states(sample)
        .unwrap()
        .into_iter()
        .map(|(start, depth, state)| Leaf {
            start,
            depth,
            log_odds: state.log_odds(),
        })
        .collect();
    Snapshot::from_leaves(RESOLUTION, leaves).unwrap()
}

/// Every snapshot the file holds equals the decoded input and the full build's snapshot.
fn assert_every_snapshot(context: &Context, file: &Path, frames: &[PathBuf], full: &FroctReader) {
    let reader = LivingReader::open(file).unwrap();
    assert_eq!(
        reader.sample_count() as usize,
        frames.len(),
        "{}",
        file.display()
    );
    for (i, path) in frames.iter().enumerate() {
        let sample = i as u32;
        assert_eq!(reader.sample_time(sample), Some(instant(sample)));
        let got = living_snapshot(&reader, sample);
        assert!(
            got.same_voxel_states(&decoded(context, path)),
            "sample {sample} ({}) differs from its input",
            path.display()
        );
        assert!(
            got.same_voxel_states(&observed_map(full, sample).unwrap()),
            "sample {sample} differs from the full build's"
        );
    }
}

struct Series {
    _dir: tempfile::TempDir,
    frames: Vec<PathBuf>,
    base: PathBuf,
    full: PathBuf,
}

/// The frames, the 1.2 build of the first four days and the 1.2 build of all five.
fn series(model: &str) -> Series {
    let context = Context::with_default_plugins();
    let dir = tempfile::tempdir().unwrap();
    let frames = write_frames(&context, &dir.path().join("maps"), 0..FRAMES);
    let options = BuildOptions {
        model: model.to_string(),
        ..BuildOptions::default()
    };
    let base = dir.path().join("base.froct");
    let inputs = inputs_of(&context, &frames[..BASE_FRAMES as usize]);
    build(&context, &inputs, &base, &options, &Silent).unwrap();
    let full = dir.path().join("full.froct");
    build(
        &context,
        &inputs_of(&context, &frames),
        &full,
        &options,
        &Silent,
    )
    .unwrap();
    Series {
        _dir: dir,
        frames,
        base,
        full,
    }
}

/// Writes frames `0..frames` into `dir` and builds `dir/room.froct` (format 1.2) from the
/// first `built`; the frames' paths and the file.
fn room_built(context: &Context, dir: &Path, frames: u32, built: usize) -> (Vec<PathBuf>, PathBuf) {
    let paths = write_frames(context, dir, 0..frames);
    let file = dir.join("room.froct");
    let inputs = inputs_of(context, &paths[..built]);
    build(context, &inputs, &file, &BuildOptions::default(), &Silent).unwrap();
    (paths, file)
}

/// Appends `frames` to the 2.0 file as one segment.
fn append_part(context: &Context, file: &Path, frames: &[PathBuf]) -> AppendReport {
    let mut writer = LivingWriter::open(file).unwrap();
    append_segment(
        context,
        &mut writer,
        &inputs_of(context, frames),
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap()
}

/// Counts of the segment cells by kind: inherited, constant, constant with exceptions, and
/// cells finer than 1 voxel's tile depth (any).
fn segment_kinds(reader: &LivingReader) -> [usize; 3] {
    let mut kinds = [0; 3];
    for k in 0..reader.segment_count() {
        for tile in 0..reader.segment_tiles(k).len() {
            for cell in reader.read_segment_tile(k, tile).unwrap() {
                kinds[match cell.content {
                    SegmentContent::Inherited { .. } => 0,
                    SegmentContent::Constant(_) => 1,
                    SegmentContent::ConstantExcept { .. } => 2,
                }] += 1;
            }
        }
    }
    kinds
}

#[test]
fn appended_segments_retrieve_every_snapshot_as_a_full_build_does() {
    let context = Context::with_default_plugins();
    let series = series("fremen-periods");
    let full = FroctReader::open(&series.full).unwrap();
    let file = series.base.with_file_name("living.froct");
    LivingWriter::convert(&series.base, &file).unwrap();
    let b = BASE_FRAMES as usize;
    // One map, a batch, then map by map, then a last batch.
    let parts = [
        b..b + 1,
        b + 1..b + 8,
        b + 8..b + 9,
        b + 9..b + 10,
        b + 10..FRAMES as usize,
    ];
    for part in parts.clone() {
        let end = part.end;
        let report = append_part(&context, &file, &series.frames[part.clone()]);
        assert_eq!(report.added, part.len());
        assert_eq!(report.samples as usize, end);
        assert_eq!(report.end, instant(end as u32 - 1));
        assert_every_snapshot(&context, &file, &series.frames[..end], &full);
    }
    let reader = LivingReader::open(&file).unwrap();
    assert_eq!(reader.segment_count(), parts.len());
    let [inherited, constant, exceptions] = segment_kinds(&reader);
    // The door follows its model in most segments, is opened at night in some, the lamp
    // and the box are new or changing: each kind of cell is exercised.
    assert!(inherited > 0, "no inherited cell");
    assert!(constant > 0 && exceptions > 0, "{constant} {exceptions}");
    // Segments store what differs from the base: patch tiles occur, and the hidden corner
    // gives some base cells of a patch tile another remainder mask than the rest, or none
    // (FORMAT.md §10.7).
    assert!(patch_tiles(&reader) > 0, "no patch tile");
    let regional = (0..reader.segment_count())
        .flat_map(|k| (0..reader.segment_tiles(k).len()).map(move |t| (k, t)))
        .filter_map(|(k, t)| reader.remainder(k, t).unwrap())
        .filter(|r| !r.runs.is_empty())
        .count();
    assert!(regional > 0, "no patch tile with remainder runs");
}

#[test]
fn markov_cells_are_never_inherited() {
    let context = Context::with_default_plugins();
    let series = series("markov");
    let full = FroctReader::open(&series.full).unwrap();
    let file = series.base.with_file_name("living.froct");
    LivingWriter::convert(&series.base, &file).unwrap();
    let b = BASE_FRAMES as usize;
    append_part(&context, &file, &series.frames[b..b + 12]);
    append_part(&context, &file, &series.frames[b + 12..]);
    assert_every_snapshot(&context, &file, &series.frames, &full);
    let reader = LivingReader::open(&file).unwrap();
    let [_, _, exceptions] = segment_kinds(&reader);
    assert!(exceptions > 0);
    // Inherited cells (stored, or what patch tiles leave to the base) lie in constant base
    // cells only: a markov cell's p(t) is not the same on every platform.
    let mut inherited = 0;
    for k in 0..reader.segment_count() {
        for tile in 0..reader.segment_tiles(k).len() {
            let cells = reader.read_segment_tile(k, tile).unwrap();
            let code = reader.segment_tiles(k)[tile].code;
            let base = reader
                .base()
                .tile_containing(code)
                .map_or_else(Vec::new, |t| reader.base().read_tile(t).unwrap());
            for cell in cells {
                if let SegmentContent::Inherited { .. } = cell.content {
                    inherited += 1;
                    let holder = base
                        .iter()
                        .find(|b| b.start <= cell.start && cell.start.0 < b.end())
                        .expect("an inherited cell lies in a base cell");
                    assert!(
                        !matches!(holder.content, CellContent::Modelled(_)),
                        "cell {:#x} of segment {k} inherits a markov model",
                        cell.start.0
                    );
                }
            }
        }
    }
    assert!(inherited > 0, "no patch tile");
}

/// How many tiles of `reader`'s segments are patch tiles.
fn patch_tiles(reader: &LivingReader) -> usize {
    (0..reader.segment_count())
        .map(|k| {
            (0..reader.segment_tiles(k).len())
                .filter(|&t| reader.is_patch_tile(k, t))
                .count()
        })
        .sum()
}

#[test]
fn fremen_regular_files_are_refused_naming_fremen_periods() {
    let context = Context::with_default_plugins();
    let dir = tempfile::tempdir().unwrap();
    let frames = write_frames(&context, dir.path(), 0..4);
    let base = dir.path().join("regular.froct");
    let options = BuildOptions {
        model: "fremen-regular".to_string(),
        ..BuildOptions::default()
    };
    build(
        &context,
        &inputs_of(&context, &frames[..3]),
        &base,
        &options,
        &Silent,
    )
    .unwrap();
    LivingWriter::convert(&base, &base).unwrap();
    let before = std::fs::read(&base).unwrap();
    let mut writer = LivingWriter::open(&base).unwrap();
    let error = append_segment(
        &context,
        &mut writer,
        &inputs_of(&context, &frames[3..]),
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap_err();
    assert!(
        matches!(error, ConvertError::ModelCannotGrow { .. }),
        "{error}"
    );
    let message = error.to_string();
    assert!(
        message.contains("fremen-periods") && message.contains("regular.froct"),
        "{message}"
    );
    drop(writer);
    assert_eq!(std::fs::read(&base).unwrap(), before);
}

#[test]
fn a_bad_map_commits_nothing() {
    let context = Context::with_default_plugins();
    let dir = tempfile::tempdir().unwrap();
    let (mut frames, file) = room_built(&context, dir.path(), 6, 3);
    LivingWriter::convert(&file, &file).unwrap();
    append_part(&context, &file, &frames[3..4]);
    let before = std::fs::read(&file).unwrap();
    // The last map of the batch is damaged: nothing of the batch may be committed.
    let bad = dir
        .path()
        .join(format!("room_{}.bt", iso8601_basic(instant(9))));
    let mut bytes = std::fs::read(&frames[5]).unwrap();
    bytes.truncate(bytes.len() / 2);
    std::fs::write(&bad, bytes).unwrap();
    frames[5] = bad.clone();
    let mut writer = LivingWriter::open(&file).unwrap();
    let error = append_segment(
        &context,
        &mut writer,
        &inputs_of(&context, &frames[4..]),
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap_err();
    assert!(
        froctomap_core::error_message(&error).contains(&*bad.to_string_lossy()),
        "{error}"
    );
    drop(writer);
    assert_eq!(std::fs::read(&file).unwrap(), before);
    let reader = LivingReader::open(&file).unwrap();
    assert_eq!((reader.segment_count(), reader.sample_count()), (1, 4));
}

#[test]
fn a_reader_open_across_an_append_keeps_its_view_until_refresh() {
    let context = Context::with_default_plugins();
    let dir = tempfile::tempdir().unwrap();
    let (frames, file) = room_built(&context, dir.path(), 8, 4);
    LivingWriter::convert(&file, &file).unwrap();
    append_part(&context, &file, &frames[4..6]);
    let mut reader = LivingReader::open(&file).unwrap();
    let earlier: Vec<Snapshot> = (0..6).map(|s| living_snapshot(&reader, s)).collect();
    append_part(&context, &file, &frames[6..]);
    // The view taken before the append: the same samples, the same maps, nothing new.
    assert_eq!((reader.sample_count(), reader.segment_count()), (6, 1));
    for (s, map) in earlier.iter().enumerate() {
        assert!(living_snapshot(&reader, s as u32).same_voxel_states(map));
    }
    assert!(reader.observed_states(6).unwrap().is_empty());
    assert!(reader.refresh().unwrap());
    assert_eq!((reader.sample_count(), reader.segment_count()), (8, 2));
    for (s, path) in frames.iter().enumerate() {
        assert!(living_snapshot(&reader, s as u32).same_voxel_states(&decoded(&context, path)));
    }
}

#[test]
fn appending_as_2_0_converts_a_1_x_file_only_once_the_segment_is_committed() {
    let context = Context::with_default_plugins();
    let dir = tempfile::tempdir().unwrap();
    let (frames, file) = room_built(&context, dir.path(), 6, 3);
    assert!(!is_living_file(&file).unwrap());
    let before = std::fs::read(&file).unwrap();
    // Overlapping inputs: refused, the 1.x file untouched, no file left beside it.
    let error = append_living(
        &context,
        &file,
        &inputs_of(&context, &frames[2..]),
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap_err();
    assert!(
        matches!(error, ConvertError::AppendOverlap { .. }),
        "{error}"
    );
    assert_eq!(std::fs::read(&file).unwrap(), before);
    let (report, converted) = append_living(
        &context,
        &file,
        &inputs_of(&context, &frames[3..5]),
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap();
    assert!(converted && is_living_file(&file).unwrap());
    assert_eq!(
        (report.samples_before, report.samples, report.segments),
        (3, 5, Some(1))
    );
    let (_, converted) = append_living(
        &context,
        &file,
        &inputs_of(&context, &frames[5..]),
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap();
    assert!(!converted);
    let reader = LivingReader::open(&file).unwrap();
    assert_eq!(reader.segment_count(), 2);
    for (s, path) in frames.iter().enumerate() {
        assert!(living_snapshot(&reader, s as u32).same_voxel_states(&decoded(&context, path)));
    }
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(names.is_empty(), "left beside the file: {names:?}");
}

#[test]
fn a_map_skipped_as_bad_is_a_missing_sample_of_the_segment() {
    let context = Context::with_default_plugins();
    let dir = tempfile::tempdir().unwrap();
    let (frames, file) = room_built(&context, dir.path(), 7, 3);
    LivingWriter::convert(&file, &file).unwrap();
    // The second of the four new maps is damaged.
    let bad = frames[4].clone();
    let bytes = std::fs::read(&bad).unwrap();
    std::fs::write(&bad, &bytes[..bytes.len() / 3]).unwrap();
    let mut writer = LivingWriter::open(&file).unwrap();
    let options = AppendOptions {
        skip_bad: true,
        ..AppendOptions::default()
    };
    let report = append_segment(
        &context,
        &mut writer,
        &inputs_of(&context, &frames[3..]),
        &options,
        &Silent,
    )
    .unwrap();
    drop(writer);
    assert_eq!((report.added, report.skipped.len()), (3, 1));
    assert_eq!(report.skipped[0].path, bad);
    assert_eq!(report.skipped[0].code(), "malformed");
    let reader = LivingReader::open(&file).unwrap();
    assert_eq!(reader.sample_count(), 7);
    assert!(reader.is_missing(4));
    assert!(reader.observed_states(4).unwrap().is_empty());
    for (s, path) in frames.iter().enumerate().filter(|(s, _)| *s != 4) {
        assert!(
            living_snapshot(&reader, s as u32).same_voxel_states(&decoded(&context, path)),
            "sample {s}"
        );
    }
}

/// The tiles of a 1.x file (their bytes, from the first tile to the end of the last), its
/// axis and its model parameters: what a compaction must share with a build.
fn tiles_and_model(file: &Path) -> (Vec<u8>, String, Vec<u8>) {
    let reader = FroctReader::open(file).unwrap();
    let bytes = std::fs::read(file).unwrap();
    let tiles = reader.tiles();
    let (first, last) = (tiles.first().unwrap(), tiles.last().unwrap());
    let range = first.offset as usize..(last.offset + u64::from(last.stored_len)) as usize;
    let header = reader.header();
    (
        bytes[range].to_vec(),
        format!("{:?}", header.axis),
        header.model_parameters.clone(),
    )
}

/// The 1.2 series (fremen-periods) built once for the property test below.
fn shared_series() -> &'static Series {
    static SERIES: std::sync::OnceLock<Series> = std::sync::OnceLock::new();
    SERIES.get_or_init(|| series("fremen-periods"))
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 6, ..Default::default() })]

    /// Whatever the split of the last day into segments (map by map, batches, one
    /// segment), `compact` merges the base's and the segments' histories into the tiles
    /// and model a 1.2 build of all the maps from their files has, byte for byte.
    #[test]
    fn compacting_any_split_into_segments_gives_the_build(
        cuts in proptest::collection::btree_set(BASE_FRAMES + 1..FRAMES, 0..6)
    ) {
        let context = Context::with_default_plugins();
        let series = shared_series();
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("living.froct");
        LivingWriter::convert(&series.base, &file).unwrap();
        let mut start = BASE_FRAMES as usize;
        for end in cuts.iter().map(|&c| c as usize).chain([FRAMES as usize]) {
            append_part(&context, &file, &series.frames[start..end]);
            start = end;
        }
        let flat = dir.path().join("compacted.froct");
        let options = CompactOptions {
            format: CompactFormat::Flat(None),
            ..CompactOptions::default()
        };
        let report = compact(&context, &file, Some(&flat), &options, &Silent).unwrap();
        proptest::prop_assert_eq!(report.segments_before, cuts.len() + 1);
        proptest::prop_assert_eq!(report.maps, FRAMES as usize);
        let (tiles, axis, model) = tiles_and_model(&flat);
        let (built_tiles, built_axis, built_model) = tiles_and_model(&series.full);
        proptest::prop_assert_eq!(axis, built_axis);
        proptest::prop_assert!(model == built_model, "model parameters differ");
        proptest::prop_assert!(tiles == built_tiles, "tiles differ from the build's");
    }
}

/// A context whose files hold at most 8 segments, and the room of `frames` frames built from
/// its first 24 (as [`room_built`]).
fn room_under_a_segment_limit_of_8(dir: &Path, frames: u32) -> (Context, Vec<PathBuf>, PathBuf) {
    let mut limits = Limits::default();
    limits.froct.max_segments = 8;
    let context = Context::with_default_plugins().with_limits(limits);
    let (paths, file) = room_built(&context, dir, frames, 24);
    (context, paths, file)
}

/// Each sample of `reader` retrieves its input, `paths` in order.
fn assert_snapshots_are_the_inputs(context: &Context, reader: &LivingReader, paths: &[PathBuf]) {
    for (i, path) in paths.iter().enumerate() {
        let got = living_snapshot(reader, i as u32);
        assert!(
            got.same_voxel_states(&decoded(context, path)),
            "sample {i} differs from its input"
        );
    }
}

/// One map per commit never reaches the segment limit: a compaction is due once the
/// segments reach a quarter of it, though neither the size nor the span rule is (the
/// base holds a day, the 12 maps add half of one). With a limit of 8 segments, 12
/// one-map commits stopped at the ninth before that rule.
#[test]
fn one_map_commits_compact_before_the_segment_limit() {
    let dir = tempfile::tempdir().unwrap();
    let (context, paths, file) = room_under_a_segment_limit_of_8(dir.path(), 36);
    let options = RecordOptions {
        commit_every: CommitEvery::Maps(1),
        ..RecordOptions::default()
    };
    let mut recorder = Recorder::open(&context, &file, options).unwrap();
    let mut most_segments = 0;
    for input in inputs_of(&context, &paths[24..]) {
        recorder.take_file(input).unwrap();
        let reader = LivingReader::open(&file).unwrap();
        most_segments = most_segments.max(reader.segment_count());
    }
    let summary = recorder.finish().unwrap();
    assert_eq!(summary.committed_maps, 12);
    assert_eq!(summary.compactions, 6, "{summary:?}");
    assert_eq!(
        most_segments, 1,
        "compacted at the second segment each time"
    );
    let reader = LivingReader::open(&file).unwrap();
    assert_eq!(reader.segment_count(), 0);
    assert_eq!(reader.sample_count(), 36);
    assert_snapshots_are_the_inputs(&context, &reader, &paths);
}

/// The shared series' base as a 2.0 file in `dir`.
fn living_of_the_shared_base(dir: &Path) -> PathBuf {
    let file = dir.join("living.froct");
    LivingWriter::convert(&shared_series().base, &file).unwrap();
    file
}

/// A build of all the shared series' frames (fremen-periods) with tiles of `depth`, in `dir`.
fn series_built_at_depth(context: &Context, dir: &Path, depth: u8) -> PathBuf {
    let built = dir.join("built.froct");
    let options = BuildOptions {
        model: "fremen-periods".to_string(),
        tile_depth: depth,
        ..BuildOptions::default()
    };
    let inputs = inputs_of(context, &shared_series().frames);
    build(context, &inputs, &built, &options, &Silent).unwrap();
    built
}

/// `file` has the axis, model parameters and tiles of `built`, byte for byte.
fn assert_same_tiles_and_model(file: &Path, built: &Path) {
    let (tiles, axis, model) = tiles_and_model(file);
    let (built_tiles, built_axis, built_model) = tiles_and_model(built);
    assert_eq!(axis, built_axis);
    assert!(model == built_model, "model parameters differ");
    assert!(tiles == built_tiles, "tiles differ from the build's");
}

/// The largest tile's history a build measured, in its summary.
fn largest_tile_history(file: &Path) -> u64 {
    FroctReader::open(file).unwrap().summary()["largest_tile_history_bytes"]
        .as_u64()
        .unwrap()
}

/// A compaction whose largest tile's history (as the base's build measured it, grown with
/// the maps since) passes the tile budget writes tiles as many levels deeper as bring it
/// under, one level at a time, and the result is a build at that depth; at the budget, or
/// with none, the file keeps its depth.
#[test]
fn a_tile_budget_deepens_the_tiles_as_the_history_grows() {
    let context = Context::with_default_plugins();
    let series = shared_series();
    let dir = tempfile::tempdir().unwrap();
    let file = living_of_the_shared_base(dir.path());
    append_part(&context, &file, &series.frames[BASE_FRAMES as usize..]);
    let measured = largest_tile_history(&series.base);
    assert!(measured > 0);
    let grown = measured * u64::from(FRAMES) / u64::from(BASE_FRAMES);
    let compacted = |name: &str, tile_budget: Option<u64>| {
        let output = dir.path().join(name);
        let options = CompactOptions {
            format: CompactFormat::Flat(None),
            tile_budget,
            ..CompactOptions::default()
        };
        let report = compact(&context, &file, Some(&output), &options, &Silent).unwrap();
        assert_eq!(report.tile_depth_before, 10);
        let depth = FroctReader::open(&output).unwrap().header().tile_depth;
        assert_eq!(report.tile_depth, depth, "{name}");
        (output, depth)
    };
    assert_eq!(compacted("kept.froct", None).1, 10);
    let (at_budget, depth) = compacted("at.froct", Some(grown));
    assert_eq!(depth, 10);
    let (deeper, depth) = compacted("past.froct", Some(grown - 1));
    assert_eq!(depth, 11);
    // One level at a time, however far past.
    assert_eq!(compacted("far-past.froct", Some(1)).1, 11);

    let built = series_built_at_depth(&context, dir.path(), 11);
    assert_same_tiles_and_model(&deeper, &built);
    // What the next compaction reads: each result measured its own largest tile.
    let (whole, smaller) = (
        largest_tile_history(&at_budget),
        largest_tile_history(&deeper),
    );
    assert!(
        0 < smaller && smaller <= whole,
        "{smaller} B at depth 11, {whole} B at 10"
    );
    assert_eq!(smaller, largest_tile_history(&built));
}

/// A recording's compactions deepen the tiles as the budget asks and keep every snapshot:
/// with a budget of one byte, each compaction goes one level deeper, in place or in the
/// background (whose result takes the maps committed meanwhile as segments of its deeper
/// tiles).
#[test]
fn a_recording_compacts_into_deeper_tiles_past_its_tile_budget() {
    for compact in [Compaction::AfterCommit, Compaction::Background] {
        let dir = tempfile::tempdir().unwrap();
        let (context, paths, file) = room_under_a_segment_limit_of_8(dir.path(), 30);
        let options = RecordOptions {
            commit_every: CommitEvery::Maps(1),
            tile_budget: Some(1),
            compact,
            ..RecordOptions::default()
        };
        let depths = std::cell::RefCell::new(Vec::new());
        let mut recorder = Recorder::open(&context, &file, options).unwrap();
        recorder.on_event(|event| {
            if let RecordEvent::Compacted(report) = event {
                depths
                    .borrow_mut()
                    .push((report.tile_depth_before, report.tile_depth));
            }
        });
        for input in inputs_of(&context, &paths[24..]) {
            recorder.take_file(input).unwrap();
        }
        recorder.finish().unwrap();
        let depths = depths.into_inner();
        if compact == Compaction::AfterCommit {
            assert_eq!(depths, [(10, 11), (11, 12), (12, 13)]);
        }
        assert!(!depths.is_empty(), "{compact:?}");
        for (k, &(before, after)) in depths.iter().enumerate() {
            assert_eq!((before, after), (10 + k as u8, 11 + k as u8), "{depths:?}");
        }
        let reader = LivingReader::open(&file).unwrap();
        let last = depths.last().unwrap().1;
        assert_eq!(reader.base().header().tile_depth, last, "{compact:?}");
        assert_snapshots_are_the_inputs(&context, &reader, &paths);
    }
}

/// `compact` into smaller tiles than the file's gives the tiles and model of a build at
/// that depth, byte for byte; larger tiles are refused, naming the file.
#[test]
fn compacting_into_smaller_tiles_gives_the_build_at_that_depth() {
    let context = Context::with_default_plugins();
    let series = shared_series();
    let dir = tempfile::tempdir().unwrap();
    let file = living_of_the_shared_base(dir.path());
    let split = BASE_FRAMES as usize + 7;
    append_part(&context, &file, &series.frames[BASE_FRAMES as usize..split]);
    append_part(&context, &file, &series.frames[split..]);
    let deeper = dir.path().join("deeper.froct");
    let options = CompactOptions {
        format: CompactFormat::Flat(None),
        tile_depth: Some(15),
        ..CompactOptions::default()
    };
    compact(&context, &file, Some(&deeper), &options, &Silent).unwrap();
    let built = series_built_at_depth(&context, dir.path(), 15);
    let reader = FroctReader::open(&deeper).unwrap();
    assert_eq!(reader.header().tile_depth, 15);
    let file_tiles = FroctReader::open(&series.full).unwrap().tiles().len();
    assert!(
        reader.tiles().len() > file_tiles,
        "{file_tiles} tiles before"
    );
    assert_same_tiles_and_model(&deeper, &built);
    let codes = |r: &FroctReader| r.tiles().iter().map(|t| t.code).collect::<Vec<_>>();
    assert_eq!(codes(&reader), codes(&FroctReader::open(&built).unwrap()));

    let coarser = CompactOptions {
        tile_depth: Some(9),
        ..options
    };
    let err = compact(
        &context,
        &file,
        Some(&dir.path().join("c.froct")),
        &coarser,
        &Silent,
    )
    .unwrap_err();
    assert!(matches!(err, ConvertError::CoarserTiles { .. }), "{err}");
    assert!(err.to_string().contains("living.froct"), "{err}");
    assert!(!dir.path().join("c.froct").exists());
}
