//! The library pipeline on a small series made from the real FR-079 scan: build lossless,
//! then every input comes back exactly; predictions, exports and evaluation work.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use froctomap_convert::*;
use froctomap_core::calendar::iso8601_basic;
use froctomap_core::{Leaf, Occupancy, Snapshot, Timestamp, VoxelKey};
use froctomap_file::FroctReader;
use froctomap_formats::{
    octomap_native, Backend, FormatRegistry, MapFormat, ReadOptions, WriteOptions,
};
use froctomap_temporal::ModelRegistry;
use std::path::{Path, PathBuf};

const GEB079: &str = "/usr/share/doc/liboctomap-dev/examples/data/geb079.bt";

fn base() -> Snapshot {
    FormatRegistry::with_default_formats()
        .read_file(Path::new(GEB079), ReadOptions::default())
        .unwrap()
        .map
        .snapshot
        .to_max_likelihood()
}

/// Frame `i`: a door block toggling every 3 frames, a box present on frames 4..8, and a
/// region unknown on every fifth frame.
fn frame(base: &Snapshot, i: u32) -> Snapshot {
    let door_open = (i / 3) % 2 == 0;
    let box_present = (4..8).contains(&i);
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

fn write_series(dir: &Path, frames: u32) -> Vec<(PathBuf, Timestamp, Snapshot)> {
    let base = base();
    let context = Context::with_default_plugins();
    let registry = context.formats();
    (0..frames)
        .map(|i| {
            // Irregular times: ten minutes apart with up to a minute of jitter.
            let t =
                Timestamp::from_secs(1_451_865_600 + i64::from(i) * 600 + i64::from(i * 37 % 61));
            let path = dir.join(format!("scan_{}.bt", iso8601_basic(t)));
            let snapshot = frame(&base, i);
            registry
                .write_file(&snapshot, &path, WriteOptions::default())
                .unwrap();
            (path, t, snapshot)
        })
        .collect()
}

#[test]
fn lossless_build_gives_back_every_input() {
    let dir = tempfile::tempdir().unwrap();
    let series = write_series(dir.path(), 12);
    let context = Context::with_default_plugins();
    let inputs = collect_inputs(&context, &[dir.path().to_path_buf()], TimeSource::Auto).unwrap();
    assert_eq!(inputs.len(), 12);
    let out = dir.path().join("series.froct");
    let report = build(&context, &inputs, &out, &BuildOptions::default(), &Silent).unwrap();
    assert_eq!(report.used, 12);
    assert!(!report.regular_axis, "jittered times make an explicit axis");
    assert!(
        report.cells.dynamic > 0 && report.cells.unknown_sometimes > 0,
        "{report:?}"
    );
    let reader = FroctReader::open(&out).unwrap();
    for (path, t, truth) in &series {
        let when = resolve_observed(&reader, TimeQuery::Instant(*t)).unwrap();
        assert!(when.exact);
        let got = observed_map(&reader, when.sample).unwrap();
        assert!(got.same_voxel_states(truth), "{}", path.display());
        // Written back, the file is byte-identical to the input.
        let back = dir.path().join("back.bt");
        write_map(&context, &got, &back, WriteOptions::default()).unwrap();
        assert_eq!(
            std::fs::read(&back).unwrap(),
            std::fs::read(path).unwrap(),
            "{}",
            path.display()
        );
        // The tiled writer, straight from the cells' states, writes the same bytes.
        let tiled = dir.path().join("tiled.bt");
        write_observed_map(
            &context,
            &reader,
            when.sample,
            &tiled,
            WriteOptions::default(),
        )
        .unwrap();
        assert_eq!(
            std::fs::read(&tiled).unwrap(),
            std::fs::read(path).unwrap(),
            "tiled: {}",
            path.display()
        );
    }
    // Predictions (inside the span and a week later): the tiled `.bt` equals the `.bt` of
    // the predicted map.
    for t in [
        series[3].1,
        Timestamp::from_secs(series[11].1 .0 / 1_000_000_000 + 7 * 86_400),
    ] {
        let whole = dir.path().join("predicted-whole.bt");
        let tiled = dir.path().join("predicted-tiled.bt");
        write_map(
            &context,
            &predicted_map(&reader, t).unwrap(),
            &whole,
            WriteOptions::default(),
        )
        .unwrap();
        write_predicted_map(&context, &reader, t, &tiled, WriteOptions::default()).unwrap();
        assert_eq!(
            std::fs::read(&whole).unwrap(),
            std::fs::read(&tiled).unwrap()
        );
    }
    println!("{report:#?}");
}

#[test]
fn predictions_exports_and_evaluation() {
    let dir = tempfile::tempdir().unwrap();
    let series = write_series(dir.path(), 9);
    let context = Context::with_default_plugins();
    let registry = context.formats();
    let inputs = collect_inputs(&context, &[dir.path().to_path_buf()], TimeSource::Auto).unwrap();
    let out = dir.path().join("series.froct");
    build(&context, &inputs, &out, &BuildOptions::default(), &Silent).unwrap();
    let reader = FroctReader::open(&out).unwrap();

    // A prediction a day later: every cell present, .ot keeps probabilities, .bt states.
    let later = Timestamp(series[8].1 .0 + 86_400_000_000_000);
    let predicted = predicted_map(&reader, later).unwrap();
    assert!(predicted.leaves().len() > 100_000);
    let ot = dir.path().join("later.ot");
    let bt = dir.path().join("later.bt");
    write_map(&context, &predicted, &ot, WriteOptions::default()).unwrap();
    write_map(&context, &predicted, &bt, WriteOptions::default()).unwrap();
    let read_ot = registry
        .read_file(&ot, ReadOptions::default())
        .unwrap()
        .map
        .snapshot;
    let read_bt = registry
        .read_file(&bt, ReadOptions::default())
        .unwrap()
        .map
        .snapshot;
    assert!(
        read_ot.to_max_likelihood().same_voxel_states(&read_bt),
        "thresholds agree between .ot and .bt"
    );
    let clamping = froctomap_core::free_log_odds()..=froctomap_core::occupied_log_odds();
    assert!(
        read_ot
            .leaves()
            .iter()
            .all(|l| clamping.contains(&l.log_odds)),
        "within OctoMap's clamping range"
    );
    let (free, occupied) = (*clamping.start(), *clamping.end());
    assert!(
        read_ot
            .leaves()
            .iter()
            .any(|l| l.log_odds > free && l.log_odds < occupied),
        "dynamic cells carry intermediate probabilities"
    );

    // Export: maps plus a manifest that `build` reads back.
    let export_dir = dir.path().join("export");
    let options = ExportOptions {
        from: series[0].1,
        to: series[8].1,
        every_ns: 1_200_000_000_000,
        mode: ExportMode::Retrieve,
        format: "bt".into(),
        backend: None,
        prefix: "map".into(),
        overwrite: false,
        recording: Default::default(),
    };
    let report = export(&context, &reader, &export_dir, &options, &Silent).unwrap();
    assert_eq!(report.files.len(), 5);
    for file in &report.files {
        let when = resolve_observed(&reader, TimeQuery::Instant(file.time)).unwrap();
        let expected = &series[when.sample as usize].2;
        let got = registry
            .read_file(&file.path, ReadOptions::default())
            .unwrap()
            .map
            .snapshot;
        assert!(got.same_voxel_states(expected));
    }
    let again = collect_inputs(
        &context,
        std::slice::from_ref(&export_dir),
        TimeSource::Auto,
    )
    .unwrap();
    assert_eq!(again.len(), 5);
    let too_many = ExportOptions {
        every_ns: 1,
        ..options.clone()
    };
    let err = export(&context, &reader, &export_dir, &too_many, &Silent).unwrap_err();
    assert!(
        matches!(err, ConvertError::TooManyMaps { limit, .. } if limit == context.limits().max_exports),
        "{err:?}"
    );

    // Evaluation against the inputs themselves: the stored states are exact.
    let report = evaluate(&context, &reader, &inputs, ReadOptions::default(), &Silent).unwrap();
    assert_eq!((report.inside, report.outside), (9, 0));
    let stored = report
        .reconstruction
        .iter()
        .find(|(m, _)| m == "stored")
        .unwrap()
        .1;
    assert_eq!(stored.all.wrong, 0);
    assert!(stored.all.total > 1_000_000 * 9);
    assert!(stored.dynamic.total > 0);
    let last_seen = report
        .reconstruction
        .iter()
        .find(|(m, _)| m == "last seen")
        .unwrap()
        .1;
    assert!(
        last_seen.dynamic.wrong > 0,
        "the door changes, so persistence is wrong sometimes"
    );
    assert_eq!(report.unmodelled_voxels, 0);
}

/// Builds compared from the bytes (the native differ) and from decoded leaves (the same
/// formats registered without differs; with the `octomap-upstream` feature also the C++
/// library) give the same file contents, whatever the batch size, through a series mixing
/// `.bt` and `.ot`, repeating a file byte for byte, and skipping a broken file followed by an
/// identical copy of it.
#[test]
fn byte_level_and_leaf_level_comparison_build_the_same_cells() {
    let dir = tempfile::tempdir().unwrap();
    let series = write_series(dir.path(), 12);
    let context = Context::with_default_plugins();
    let registry = context.formats();
    let mut truths: Vec<Option<Snapshot>> = series.iter().map(|s| Some(s.2.clone())).collect();
    // Frames 2 and 8 as .ot (the .bt removed), the .bt of frame 9 repeated by frame 10,
    // and frame 5 truncated, then frame 6 a copy of the broken frame 5.
    for i in [2usize, 8] {
        let ot = series[i].0.with_extension("ot");
        registry
            .write_file(&series[i].2, &ot, WriteOptions::default())
            .unwrap();
        std::fs::remove_file(&series[i].0).unwrap();
    }
    std::fs::copy(&series[9].0, &series[10].0).unwrap();
    truths[10] = truths[9].clone();
    let broken = std::fs::read(&series[5].0).unwrap();
    std::fs::write(&series[5].0, &broken[..broken.len() / 2]).unwrap();
    std::fs::write(&series[6].0, &broken[..broken.len() / 2]).unwrap();
    truths[5] = None;
    truths[6] = None;
    let inputs = collect_inputs(&context, &[dir.path().to_path_buf()], TimeSource::Auto).unwrap();
    assert_eq!(inputs.len(), 12);

    let build_with = |context: &Context, backend, batch| {
        let out = dir.path().join(format!("{backend:?}-{batch}.froct"));
        let options = BuildOptions {
            backend: Some(backend),
            batch,
            skip_bad: true,
            ..Default::default()
        };
        let report = build(context, &inputs, &out, &options, &Silent).unwrap();
        assert_eq!((report.used, report.skipped.len()), (10, 2), "{report:?}");
        (report, FroctReader::open(&out).unwrap())
    };
    // The reference decodes every file: the same formats, handed to `build` without their
    // byte-level differs.
    let mut decoding = FormatRegistry::new();
    for format in context.formats().formats() {
        decoding
            .register(MapFormat {
                differ: None,
                ..*format
            })
            .unwrap();
    }
    let decoding = Context::new(decoding, ModelRegistry::with_default_models());
    let (reference, decoded) = build_with(&decoding, Backend::Native, 64);
    // With the C++ backend (no differ either) the cells are the same too.
    #[cfg(feature = "octomap-upstream")]
    {
        let (report, cpp) = build_with(&context, Backend::Octomap, 64);
        assert_eq!(report.cells, reference.cells);
        for tile in 0..cpp.tiles().len() {
            assert_eq!(
                cpp.read_tile(tile).unwrap(),
                decoded.read_tile(tile).unwrap()
            );
        }
    }
    for batch in [1, 3, 64] {
        let (report, native) = build_with(&context, Backend::Native, batch);
        assert_eq!(
            (report.cells, report.toggles, report.changed_voxels),
            (reference.cells, reference.toggles, reference.changed_voxels),
            "batch {batch}"
        );
        assert_eq!(native.tiles().len(), decoded.tiles().len());
        for tile in 0..native.tiles().len() {
            assert_eq!(
                native.read_tile(tile).unwrap(),
                decoded.read_tile(tile).unwrap(),
                "batch {batch}, tile {tile}"
            );
        }
        for (sample, truth) in truths.iter().enumerate() {
            let got = observed_map(&native, sample as u32).unwrap();
            match truth {
                Some(truth) => assert!(got.same_voxel_states(truth), "sample {sample}"),
                None => assert!(got.is_empty(), "skipped sample {sample}"),
            }
        }
    }
}

/// A format the caller registers reaches every path: directories are listed by its
/// extension, `build` reads it, `export` writes it (here the native `.bt` codec under
/// another name and extension).
#[test]
fn a_format_registered_by_the_caller_is_used_by_build_and_export() {
    let dir = tempfile::tempdir().unwrap();
    let renamed = MapFormat {
        name: "tree",
        description: "a program's own name for OctoMap binary",
        extensions: &["tree"],
        ..octomap_native::BINARY
    };
    let mut formats = FormatRegistry::new();
    formats.register(renamed).unwrap();
    let context = Context::new(formats, ModelRegistry::with_default_models());
    let series = write_series(dir.path(), 3);
    let inputs_dir = dir.path().join("renamed");
    std::fs::create_dir(&inputs_dir).unwrap();
    for (path, _, _) in &series {
        let name = path.with_extension("tree");
        std::fs::copy(path, inputs_dir.join(name.file_name().unwrap())).unwrap();
    }
    let inputs = collect_inputs(&context, &[inputs_dir], TimeSource::Auto).unwrap();
    assert_eq!(inputs.len(), 3);
    let out = dir.path().join("renamed.froct");
    let report = build(&context, &inputs, &out, &BuildOptions::default(), &Silent).unwrap();
    assert_eq!(report.used, 3);
    let reader = FroctReader::open(&out).unwrap();
    let export_dir = dir.path().join("exported");
    let options = ExportOptions {
        from: reader.header().axis.start(),
        to: reader.header().axis.start(),
        every_ns: 1,
        mode: ExportMode::Retrieve,
        format: "tree".into(),
        backend: None,
        prefix: "map".into(),
        overwrite: false,
        recording: Default::default(),
    };
    let exported = export(&context, &reader, &export_dir, &options, &Silent).unwrap();
    let file = &exported.files[0].path;
    assert_eq!(file.extension().unwrap(), "tree");
    assert_eq!(
        std::fs::read(file).unwrap(),
        std::fs::read(&series[0].0).unwrap()
    );
    // The default formats do not know the name.
    let default = Context::with_default_plugins();
    let err = export(&default, &reader, &export_dir, &options, &Silent).unwrap_err();
    assert!(
        err.to_string().contains("unknown map format `tree`"),
        "{err}"
    );
}

/// The context's limits bound what a build reads and how many maps an export writes.
#[test]
fn limits_of_the_context_are_enforced() {
    let dir = tempfile::tempdir().unwrap();
    let series = write_series(dir.path(), 2);
    let mut limits = Limits::default();
    limits.max_map_file_bytes = 1000;
    let context = Context::with_default_plugins().with_limits(limits);
    let inputs = collect_inputs(&context, &[dir.path().to_path_buf()], TimeSource::Auto).unwrap();
    let out = dir.path().join("small.froct");
    let err = build(&context, &inputs, &out, &BuildOptions::default(), &Silent).unwrap_err();
    match &err {
        ConvertError::Snapshot { path, source } => {
            assert_eq!(path, &series[0].0);
            assert!(matches!(
                **source,
                SnapshotError::TooLarge { limit: 1000, .. }
            ));
        }
        other => panic!("{other:?}"),
    }
    assert!(
        froctomap_core::error_message(&err).contains("limit of 1000 bytes"),
        "{err}"
    );
}
