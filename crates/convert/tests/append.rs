//! `append` against a full build of the same snapshots, on a small series made from the real
//! FR-079 scan (a door that toggles, a box that comes and goes, a region hidden on every
//! fifth frame): every snapshot of both parts comes back exactly, the tiles are those of the
//! full build, and refused or failed appends leave the file as it was.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use froctomap_convert::*;
use froctomap_core::calendar::iso8601_basic;
use froctomap_core::{Leaf, Occupancy, Snapshot, Timestamp, VoxelKey};
use froctomap_file::FroctReader;
use froctomap_formats::{FormatRegistry, ReadOptions, WriteOptions};
use froctomap_temporal::{ModelConfig, OutlierMode};
use std::path::{Path, PathBuf};

const GEB079: &str = "/usr/share/doc/liboctomap-dev/examples/data/geb079.bt";
const START: i64 = 1_451_865_600;

fn base() -> Snapshot {
    FormatRegistry::with_default_formats()
        .read_file(Path::new(GEB079), ReadOptions::default())
        .unwrap()
        .map
        .snapshot
        .to_max_likelihood()
}

/// Frame `i`: a door block toggling every 3 frames, a box present on frames 4..8 and from
/// 13 on, and a region unknown on every fifth frame.
fn frame(base: &Snapshot, i: u32) -> Snapshot {
    let door_open = (i / 3) % 2 == 0;
    let box_present = (4..8).contains(&i) || i >= 13;
    let door = |k: &VoxelKey| {
        (32700..32712).contains(&k.x)
            && (32760..32762).contains(&k.y)
            && (32768..32790).contains(&k.z)
    };
    let boxed = |k: &VoxelKey| {
        (32800..32806).contains(&k.x)
            && (32750..32756).contains(&k.y)
            && (32768..32774).contains(&k.z)
    };
    let hidden = |k: &VoxelKey| i % 5 == 2 && (32900..33000).contains(&k.x);
    let voxels = base.voxels().filter_map(|(code, state)| {
        let k = code.key();
        if hidden(&k) {
            return None;
        }
        let state = if door(&k) {
            Occupancy::from(!door_open)
        } else if boxed(&k) && box_present {
            Occupancy::Occupied
        } else {
            state
        };
        Some(Leaf::voxel(k, state.log_odds()))
    });
    Snapshot::from_leaves(base.resolution(), voxels.collect())
        .unwrap()
        .canonical()
}

/// A written snapshot of the series.
struct Written {
    path: PathBuf,
    time: Timestamp,
    map: Snapshot,
}

/// Writes frames `frames` into `dir` at the times `time(i)`.
fn write_frames(
    dir: &Path,
    frames: impl Iterator<Item = u32>,
    time: impl Fn(u32) -> Timestamp,
) -> Vec<Written> {
    let base = base();
    let registry = FormatRegistry::with_default_formats();
    std::fs::create_dir_all(dir).unwrap();
    frames
        .map(|i| {
            let t = time(i);
            let path = dir.join(format!("scan_{}.bt", iso8601_basic(t)));
            let map = frame(&base, i);
            registry
                .write_file(&map, &path, WriteOptions::default())
                .unwrap();
            Written { path, time: t, map }
        })
        .collect()
}

fn regular(i: u32) -> Timestamp {
    Timestamp::from_secs(START + i64::from(i) * 600)
}

/// Ten minutes apart with up to a minute of jitter: an explicit axis.
fn jittered(i: u32) -> Timestamp {
    Timestamp::from_secs(START + i64::from(i) * 600 + i64::from(i * 37 % 61))
}

fn inputs(context: &Context, dirs: &[&Path]) -> Vec<SeriesInput> {
    let dirs: Vec<PathBuf> = dirs.iter().map(|d| d.to_path_buf()).collect();
    collect_inputs(context, &dirs, TimeSource::Auto).unwrap()
}

/// Every snapshot comes back from the file exactly, as the same `.bt` bytes.
fn assert_retrieves(context: &Context, file: &Path, series: &[Written]) {
    let reader = FroctReader::open(file).unwrap();
    let back = file.with_extension("back.bt");
    for written in series {
        let when = resolve_observed(&reader, TimeQuery::Instant(written.time)).unwrap();
        assert!(when.exact);
        let got = observed_map(&reader, when.sample).unwrap();
        assert!(
            got.same_voxel_states(&written.map),
            "{}",
            written.path.display()
        );
        write_map(context, &got, &back, WriteOptions::default()).unwrap();
        assert_eq!(
            std::fs::read(&back).unwrap(),
            std::fs::read(&written.path).unwrap(),
            "{}",
            written.path.display()
        );
    }
    std::fs::remove_file(&back).unwrap();
}

/// The two files have the same axis and the same cells in every tile.
fn assert_same_tiles(appended: &Path, full: &Path) {
    let a = FroctReader::open(appended).unwrap();
    let b = FroctReader::open(full).unwrap();
    assert_eq!(a.header().axis, b.header().axis);
    assert_eq!(a.header().model_parameters, b.header().model_parameters);
    assert_eq!(a.tiles().len(), b.tiles().len());
    for i in 0..a.tiles().len() {
        assert_eq!(a.read_tile(i).unwrap(), b.read_tile(i).unwrap(), "tile {i}");
    }
}

fn file_len(path: &Path) -> u64 {
    std::fs::metadata(path).unwrap().len()
}

/// Builds `first`, appends each of `then` in turn, and compares with a full build.
fn build_then_append(time: fn(u32) -> Timestamp, first: &[u32], then: &[&[u32]]) {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let mut series = write_frames(&dir.path().join("p0"), first.iter().copied(), time);
    let file = dir.path().join("appended.froct");
    build(
        &context,
        &inputs(&context, &[&dir.path().join("p0")]),
        &file,
        &BuildOptions::default(),
        &Silent,
    )
    .unwrap();
    let mut parts = vec![dir.path().join("p0")];
    for (k, part) in then.iter().enumerate() {
        let part_dir = dir.path().join(format!("p{}", k + 1));
        let written = write_frames(&part_dir, part.iter().copied(), time);
        let before = file_len(&file);
        let report = append(
            &context,
            &file,
            &inputs(&context, &[&part_dir]),
            &AppendOptions::default(),
            &Silent,
        )
        .unwrap();
        assert_eq!(report.added, part.len());
        assert_eq!(report.bytes_before, before);
        assert_eq!(report.file_bytes, file_len(&file));
        assert_eq!(report.end, written.last().unwrap().time);
        assert!(report.lossless);
        series.extend(written);
        parts.push(part_dir);
    }
    assert_retrieves(&context, &file, &series);
    let full = dir.path().join("full.froct");
    let all: Vec<&Path> = parts.iter().map(PathBuf::as_path).collect();
    build(
        &context,
        &inputs(&context, &all),
        &full,
        &BuildOptions::default(),
        &Silent,
    )
    .unwrap();
    assert!(
        file_len(&file) as f64 <= 1.1 * file_len(&full) as f64,
        "{} bytes appended, {} built",
        file_len(&file),
        file_len(&full)
    );
    assert_same_tiles(&file, &full);
    let reader = FroctReader::open(&file).unwrap();
    assert_eq!(
        reader.summary()["snapshots_used"].as_u64(),
        Some(series.len() as u64)
    );
}

#[test]
fn appending_the_second_half_of_a_regular_series_gives_the_full_build() {
    // Frame 9 is missing: a gap in the appended part of the grid.
    let second: Vec<u32> = (6..14).filter(|&i| i != 9).collect();
    build_then_append(regular, &(0..6).collect::<Vec<_>>(), &[&second]);
}

#[test]
fn appending_to_an_explicit_axis_with_a_partial_view_at_the_seam() {
    // Frame 7, the last before the seam, hides a region.
    let first: Vec<u32> = (0..8).collect();
    let second: Vec<u32> = (8..14).collect();
    build_then_append(jittered, &first, &[&second]);
}

#[test]
fn appending_twice() {
    let parts: [&[u32]; 2] = [&[4, 5, 6, 7], &[8, 9, 10, 11, 12]];
    build_then_append(regular, &[0, 1, 2, 3], &parts);
}

#[test]
fn times_off_the_file_grid_renumber_its_samples() {
    // The first part every 20 minutes, then every 10: the grid becomes finer.
    let time = |i: u32| {
        if i < 5 {
            regular(2 * i)
        } else {
            regular(i + 5)
        }
    };
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let mut series = write_frames(&dir.path().join("a"), 0..5, time);
    let file = dir.path().join("x.froct");
    let first = inputs(&context, &[&dir.path().join("a")]);
    build(&context, &first, &file, &BuildOptions::default(), &Silent).unwrap();
    series.extend(write_frames(&dir.path().join("b"), 5..9, time));
    let later = inputs(&context, &[&dir.path().join("b")]);
    append(&context, &file, &later, &AppendOptions::default(), &Silent).unwrap();
    assert_retrieves(&context, &file, &series);
    let reader = FroctReader::open(&file).unwrap();
    assert_eq!(reader.header().axis.step_ns(), Some(600_000_000_000));
    let full = dir.path().join("full.froct");
    let all = inputs(&context, &[&dir.path().join("a"), &dir.path().join("b")]);
    build(&context, &all, &full, &BuildOptions::default(), &Silent).unwrap();
    assert_same_tiles(&file, &full);
}

/// The bytes of every file in `dir`, by name.
fn snapshot_dir(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files: Vec<(PathBuf, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p, bytes)
        })
        .collect();
    files.sort();
    files
}

#[test]
fn overlapping_other_resolution_and_broken_inputs_leave_the_file_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let first = dir.path().join("first");
    write_frames(&first, 0..4, regular);
    let file = dir.path().join("kept.froct");
    build(
        &context,
        &inputs(&context, &[&first]),
        &file,
        &BuildOptions::default(),
        &Silent,
    )
    .unwrap();
    let before = snapshot_dir(dir.path());

    // A snapshot at the file's last time, and one before it.
    for (name, frames) in [("same", 3..5), ("earlier", 1..2)] {
        let part = dir.path().join(name);
        let written = write_frames(&part, frames, regular);
        match append(
            &context,
            &file,
            &inputs(&context, &[&part]),
            &AppendOptions::default(),
            &Silent,
        ) {
            Err(ConvertError::AppendOverlap {
                file: named,
                last,
                input,
                ..
            }) => {
                assert_eq!(named, file);
                assert_eq!(last, regular(3));
                assert!(written.iter().any(|w| w.path == input));
                let message = ConvertError::AppendOverlap {
                    file: named,
                    last,
                    input,
                    time: last,
                }
                .to_string();
                assert!(message.contains("kept.froct"), "{message}");
            }
            other => panic!("{name}: {other:?}"),
        }
    }

    // Another resolution.
    let coarse = dir.path().join("coarse");
    std::fs::create_dir_all(&coarse).unwrap();
    let map = Snapshot::from_leaves(
        0.2,
        vec![Leaf::voxel(VoxelKey::new(32768, 32768, 32768), 1.0)],
    )
    .unwrap();
    let coarse_path = coarse.join(format!("scan_{}.bt", iso8601_basic(regular(5))));
    context
        .formats()
        .write_file(&map, &coarse_path, WriteOptions::default())
        .unwrap();
    match append(
        &context,
        &file,
        &inputs(&context, &[&coarse]),
        &AppendOptions::default(),
        &Silent,
    ) {
        Err(error @ ConvertError::MixedResolution { .. }) => {
            let message = error.to_string();
            assert!(
                message.contains("kept.froct") && message.contains("0.2"),
                "{message}"
            );
        }
        other => panic!("{other:?}"),
    }

    // A good snapshot then a broken one: nothing is written.
    let broken = dir.path().join("broken");
    write_frames(&broken, 4..5, regular);
    let bad = broken.join(format!("scan_{}.bt", iso8601_basic(regular(5))));
    let mut bytes =
        std::fs::read(broken.join(format!("scan_{}.bt", iso8601_basic(regular(4))))).unwrap();
    let half = bytes.len() / 2;
    bytes.truncate(half);
    std::fs::write(&bad, bytes).unwrap();
    let result = append(
        &context,
        &file,
        &inputs(&context, &[&broken]),
        &AppendOptions::default(),
        &Silent,
    );
    assert!(result.is_err(), "{result:?}");

    // No temporary file left beside it, and the file is byte-identical.
    assert_eq!(snapshot_dir(dir.path()), before);
}

#[test]
fn a_lossy_file_continues_from_its_reconstruction() {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let lossy = BuildOptions {
        config: ModelConfig::default().with_outliers(OutlierMode::Lossy),
        ..BuildOptions::default()
    };
    let first_dir = dir.path().join("first");
    let first = write_frames(&first_dir, 0..6, regular);
    let file = dir.path().join("lossy.froct");
    build(
        &context,
        &inputs(&context, &[&first_dir]),
        &file,
        &lossy,
        &Silent,
    )
    .unwrap();

    // What the lossy file knows of its past: its reconstructed maps, written as snapshots.
    let known = dir.path().join("known");
    std::fs::create_dir_all(&known).unwrap();
    let reader = FroctReader::open(&file).unwrap();
    for written in &first {
        let when = resolve_observed(&reader, TimeQuery::Instant(written.time)).unwrap();
        let map = observed_map(&reader, when.sample).unwrap();
        // Unknown stays unknown even in a lossy file.
        let observed = |m: &Snapshot| m.voxels().map(|(code, _)| code).collect::<Vec<_>>();
        assert_eq!(observed(&map), observed(&written.map));
        let name = written.path.file_name().unwrap();
        write_map(&context, &map, &known.join(name), WriteOptions::default()).unwrap();
    }
    drop(reader);

    let second_dir = dir.path().join("second");
    write_frames(&second_dir, 6..12, regular);
    let report = append(
        &context,
        &file,
        &inputs(&context, &[&second_dir]),
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap();
    assert!(!report.lossless);
    assert_eq!(
        FroctReader::open(&file).unwrap().model().outlier_mode(),
        OutlierMode::Lossy
    );
    // The same as a lossy build of the reconstructed past and the new snapshots.
    let full = dir.path().join("full.froct");
    let all = inputs(&context, &[&known, &second_dir]);
    build(&context, &all, &full, &lossy, &Silent).unwrap();
    assert_same_tiles(&file, &full);
}

#[test]
fn broken_snapshots_left_out_become_missing_samples_as_in_a_build() {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let first = dir.path().join("first");
    let mut series = write_frames(&first, 0..4, regular);
    let file = dir.path().join("skipping.froct");
    let skip = BuildOptions {
        skip_bad: true,
        ..BuildOptions::default()
    };
    build(
        &context,
        &inputs(&context, &[&first]),
        &file,
        &skip,
        &Silent,
    )
    .unwrap();
    let later = dir.path().join("later");
    series.extend(write_frames(&later, [4, 5, 7].into_iter(), regular));
    let broken = later.join(format!("scan_{}.bt", iso8601_basic(regular(6))));
    std::fs::write(&broken, b"# Octomap OcTree binary file\nid OcTree\n").unwrap();
    let options = AppendOptions {
        skip_bad: true,
        ..AppendOptions::default()
    };
    let report = append(
        &context,
        &file,
        &inputs(&context, &[&later]),
        &options,
        &Silent,
    )
    .unwrap();
    assert_eq!(report.added, 3);
    assert_eq!(report.skipped.len(), 1);
    assert_eq!(report.skipped[0].path, broken);
    assert_eq!(report.skipped[0].reason, SkipReason::Malformed);
    assert_retrieves(&context, &file, &series);
    let reader = FroctReader::open(&file).unwrap();
    assert_eq!(reader.header().axis.missing(), &[6]);
    let full = dir.path().join("full.froct");
    build(
        &context,
        &inputs(&context, &[&first, &later]),
        &full,
        &skip,
        &Silent,
    )
    .unwrap();
    assert_same_tiles(&file, &full);
}
