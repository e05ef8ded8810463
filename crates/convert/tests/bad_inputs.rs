//! Every way a series can be wrong stops the build with a message naming the files (or,
//! with `skip_bad`, leaves them out and lists them).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use froctomap_convert::*;
use froctomap_core::{Leaf, Snapshot, Timestamp, VoxelKey};
use froctomap_formats::WriteOptions;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The context every test hands to the converters.
fn context() -> &'static Context {
    static CONTEXT: OnceLock<Context> = OnceLock::new();
    CONTEXT.get_or_init(Context::with_default_plugins)
}

fn small(resolution: f64, occupied: bool) -> Snapshot {
    let leaves = (0..20u16)
        .map(|i| {
            Leaf::voxel(
                VoxelKey::new(32768 + i, 32768, 32768),
                if occupied && i % 3 == 0 { 3.5 } else { -2.0 },
            )
        })
        .collect();
    Snapshot::from_leaves(resolution, leaves).unwrap()
}

fn write(dir: &Path, name: &str, snapshot: &Snapshot) -> PathBuf {
    let path = dir.join(name);
    context()
        .formats()
        .write_file(snapshot, &path, WriteOptions::default())
        .unwrap();
    path
}

fn series(dir: &Path, n: u32) -> Vec<PathBuf> {
    (0..n)
        .map(|i| {
            write(
                dir,
                &format!("map_{}.bt", 1_451_865_600 + i * 600),
                &small(0.1, i % 2 == 0),
            )
        })
        .collect()
}

fn inputs(dir: &Path) -> Result<Vec<SeriesInput>, ConvertError> {
    collect_inputs(context(), &[dir.to_path_buf()], TimeSource::Auto)
}

fn build_dir(dir: &Path, options: &BuildOptions) -> Result<BuildReport, ConvertError> {
    build(
        context(),
        &inputs(dir)?,
        &dir.join("out").with_extension("froct"),
        options,
        &Silent,
    )
}

#[test]
fn duplicate_times_name_both_files() {
    let dir = tempfile::tempdir().unwrap();
    series(dir.path(), 3);
    let manifest = dir.path().join("manifest.csv");
    std::fs::write(
        &manifest,
        "path,time\nmap_1451865600.bt,1451865600\nmap_1451866200.bt,2016-01-04T00:00:00Z\n",
    )
    .unwrap();
    let err = froctomap_core::error_message(&inputs(dir.path()).unwrap_err());
    assert!(
        err.contains("map_1451865600.bt")
            && err.contains("map_1451866200.bt")
            && err.contains("same time 2016-01-04T00:00:00Z"),
        "{err}"
    );
}

#[test]
fn mixed_resolutions_name_both_files_or_are_skipped() {
    let dir = tempfile::tempdir().unwrap();
    series(dir.path(), 3);
    write(dir.path(), "map_1451867400.bt", &small(0.05, true));
    let err = froctomap_core::error_message(
        &build_dir(dir.path(), &BuildOptions::default()).unwrap_err(),
    );
    assert!(
        err.contains("map_1451867400.bt has resolution 0.05 m")
            && err.contains("map_1451865600.bt has 0.1 m"),
        "{err}"
    );
    assert!(
        !dir.path().join("out.froct").exists(),
        "no output after a failed build"
    );
    let report = build_dir(
        dir.path(),
        &BuildOptions {
            skip_bad: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((report.used, report.skipped.len()), (3, 1));
    assert!(report.skipped[0].path.ends_with("map_1451867400.bt"));
    assert_eq!(report.skipped[0].reason, SkipReason::ResolutionMismatch);
}

#[test]
fn corrupt_inputs_name_the_file_and_problem_or_are_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let files = series(dir.path(), 4);
    let bytes = std::fs::read(&files[2]).unwrap();
    std::fs::write(&files[2], &bytes[..bytes.len() - 2]).unwrap();
    let err = build_dir(dir.path(), &BuildOptions::default()).unwrap_err();
    // Skippable: leaving the file out gets past it (the CLI suggests `--skip-bad`).
    assert!(
        matches!(&err, ConvertError::Snapshot { path, .. } if path == &files[2])
            && err.is_skippable(),
        "{err:?}"
    );
    let err = froctomap_core::error_message(&err);
    assert!(
        err.contains("map_1451866800.bt") && err.contains("truncated"),
        "{err}"
    );
    let report = build_dir(
        dir.path(),
        &BuildOptions {
            skip_bad: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(report.used, 3);
    assert_eq!(report.skipped[0].path, files[2]);
    assert_eq!(report.skipped[0].reason, SkipReason::Malformed);
    assert!(
        report.skipped[0].message.contains("truncated"),
        "{:?}",
        report.skipped
    );
    // The skipped snapshot's time is unknown in the file, not a copy of a neighbour.
    let reader = froctomap_file::FroctReader::open(&dir.path().join("out.froct")).unwrap();
    let err = froctomap_core::error_message(
        &resolve_observed(&reader, TimeQuery::Sample(2)).unwrap_err(),
    );
    assert!(
        err.contains("sample 2") && err.contains("has no snapshot"),
        "{err}"
    );
    assert!(observed_map(&reader, 2).unwrap().is_empty());
    assert!(!observed_map(&reader, 3).unwrap().is_empty());
    // An empty file is named as such.
    std::fs::write(&files[1], b"").unwrap();
    let err = froctomap_core::error_message(
        &build_dir(dir.path(), &BuildOptions::default()).unwrap_err(),
    );
    assert!(
        err.contains("map_1451866200.bt") && err.contains("empty"),
        "{err}"
    );
}

#[test]
fn names_without_times_and_missing_inputs_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "kitchen.bt", &small(0.1, true));
    let err = inputs(dir.path()).unwrap_err();
    assert!(matches!(&err, ConvertError::NoTimes { files } if files.len() == 1));
    let err = err.to_string();
    assert!(
        err.contains("no time in the name")
            && err.contains("kitchen.bt")
            && err.contains("start time and step"),
        "{err}"
    );
    let with_step = collect_inputs(
        context(),
        &[dir.path().join("kitchen.bt")],
        TimeSource::StartStep {
            start: Timestamp::from_secs(1_451_865_600),
            step_ns: 600_000_000_000,
        },
    )
    .unwrap();
    assert_eq!(with_step[0].time, Timestamp::from_secs(1_451_865_600));
    let err = froctomap_core::error_message(
        &collect_inputs(context(), &[dir.path().join("nope")], TimeSource::Auto).unwrap_err(),
    );
    assert!(
        err.contains("nope") && err.contains("no such file"),
        "{err}"
    );
    let err = froctomap_core::error_message(
        &collect_inputs(context(), &[dir.path().join("*.ot")], TimeSource::Auto).unwrap_err(),
    );
    assert!(err.contains("matches no files"), "{err}");
}

#[test]
fn unwritable_output_is_reported_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    series(dir.path(), 2);
    let err = froctomap_core::error_message(
        &build(
            context(),
            &inputs(dir.path()).unwrap(),
            Path::new("/nonexistent-dir/out.froct"),
            &BuildOptions::default(),
            &Silent,
        )
        .unwrap_err(),
    );
    assert!(err.contains("/nonexistent-dir/out.froct"), "{err}");
}

#[test]
fn times_outside_a_sensible_range_are_refused() {
    for bad in [
        "1e12",
        "-1",
        "99999999999",
        "2300-01-01T00:00:00Z",
        "next tuesday",
    ] {
        assert!(bad.parse::<TimeQuery>().is_err(), "{bad}");
    }
    let err = froctomap_core::error_message(&"99999999999".parse::<TimeQuery>().unwrap_err());
    assert!(
        err.contains("outside the supported range 1970-01-01 .. 2200-01-01"),
        "{err}"
    );
    let dir = tempfile::tempdir().unwrap();
    series(dir.path(), 3);
    build_dir(dir.path(), &BuildOptions::default()).unwrap();
    let reader = froctomap_file::FroctReader::open(&dir.path().join("out.froct")).unwrap();
    let before = froctomap_core::error_message(
        &resolve_observed(&reader, "2015-01-01T00:00:00Z".parse().unwrap()).unwrap_err(),
    );
    assert!(
        before.contains("before the first snapshot")
            && before.contains("2016-01-04T00:00:00Z .. 2016-01-04T00:20:00Z"),
        "{before}"
    );
    let beyond = froctomap_core::error_message(
        &resolve_observed(&reader, "index:3".parse().unwrap()).unwrap_err(),
    );
    assert!(beyond.contains("beyond the 3 samples"), "{beyond}");
}

#[test]
fn unknown_model_and_incompatible_axis_are_refused_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    series(dir.path(), 3);
    let err = froctomap_core::error_message(
        &build_dir(
            dir.path(),
            &BuildOptions {
                model: "magic".into(),
                ..Default::default()
            },
        )
        .unwrap_err(),
    );
    assert!(
        err.contains("unknown model `magic`") && err.contains("fremen-periods"),
        "{err}"
    );
    // Irregular times cannot use the FFT model.
    write(dir.path(), "map_1451867437.bt", &small(0.1, true));
    let err = build_dir(
        dir.path(),
        &BuildOptions {
            model: "fremen-regular".into(),
            ..Default::default()
        },
    )
    .unwrap_err();
    let err = froctomap_core::error_message(&err);
    assert!(err.contains("fremen-regular"), "{err}");
}

/// Issue 16 item 5: an 18-byte legacy `.bt` (a root with eight leaf children) would be
/// split into 2^30 cells at tile depth 10: the build stops before accumulating it, naming
/// the file, and a coarser tiling takes it.
#[test]
fn coarse_leaves_that_would_make_billions_of_cells_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("map_1451865600.bt");
    let mut legacy = Vec::new();
    legacy.extend(3i32.to_le_bytes());
    legacy.extend(0.1f64.to_le_bytes());
    legacy.extend(9u32.to_le_bytes());
    // The root's children, two bits each: every one a leaf.
    legacy.extend([0x55, 0x55]);
    assert_eq!(legacy.len(), 18);
    std::fs::write(&path, &legacy).unwrap();
    let options = BuildOptions::default();
    assert_eq!(options.tile_depth, 10);
    match build_dir(dir.path(), &options) {
        Err(ConvertError::Snapshot {
            path: refused,
            source,
        }) => {
            assert_eq!(refused, path);
            match *source {
                SnapshotError::TooManyTiles { tile_depth, limit } => {
                    assert_eq!(tile_depth, 10);
                    assert_eq!(limit, context().limits().max_snapshot_tiles);
                }
                ref other => panic!("{other:?}"),
            }
        }
        other => panic!("{other:?}"),
    }
    // Not a file --skip-bad can leave out: it was read as the series' latest map.
    let skipping = BuildOptions {
        skip_bad: true,
        ..BuildOptions::default()
    };
    let err = build_dir(dir.path(), &skipping).unwrap_err();
    assert!(!err.is_skippable(), "{err}");
    // Tiles of depth 2 hold it in 8 × 8 cells.
    let coarse = BuildOptions {
        tile_depth: 2,
        ..BuildOptions::default()
    };
    let report = build_dir(dir.path(), &coarse).unwrap();
    assert_eq!(report.used, 1);
}
