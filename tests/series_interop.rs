//! The whole pipeline on a generated series made from the real FR-079 scan (doors, people,
//! objects and machines on schedules, sensor noise, partially observed frames, jittered
//! times), checked through upstream OctoMap: every input comes back with the identical leaf
//! set, and predicted and exported maps are read by `convert_octree` and `octomap-python`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_convert::{
    build, collect_inputs, export, observed_map, predicted_map, resolve_observed, write_map,
    BuildOptions, Context, ExportMode, ExportOptions, Silent, TimeQuery, TimeSource,
};
use froctomap_core::Timestamp;
use froctomap_file::FroctReader;
use froctomap_formats::{FormatRegistry, ReadOptions, WriteOptions};
use froctomap_octomap_ffi::OcTree;
use froctomap_synth::{write_series, Generator, SeriesSpec, WriteSeriesOptions};
use froctomap_test_support::{convert_octree, geb079, leaf_tuples, python_leaves, scratch};
use std::path::Path;

fn upstream_leaves(path: &Path) -> Vec<froctomap_test_support::LeafTuple> {
    let loaded = OcTree::read(&std::fs::read(path).unwrap()).unwrap();
    leaf_tuples(&loaded.tree.to_snapshot().unwrap())
}

#[test]
fn generated_series_round_trips_and_outputs_are_read_by_upstream_clients() {
    let dir = scratch();
    let series_dir = dir.path().join("series");
    let formats = FormatRegistry::with_default_formats();
    let base = formats
        .read_file(&geb079(), ReadOptions::default())
        .unwrap()
        .map
        .snapshot
        .to_max_likelihood();
    // One working day every 40 minutes, irregular times, one in three frames partial.
    let spec = SeriesSpec {
        seed: 11,
        start: Timestamp::from_secs(1_451_894_400), // Monday 08:00 UTC
        jitter_secs: 90.0,
        partial_probability: 0.35,
        surface_noise: 0.002,
        ..SeriesSpec::with_duration(0.5, 2400.0)
    };
    let generator = Generator::new(&base, spec, None).unwrap();
    let options = WriteSeriesOptions {
        format: "bt".into(),
        file_pattern: "frame_{time}.{ext}".into(),
        threads: 0,
    };
    write_series(&formats, &generator, &series_dir, &options, &|_, _| {}).unwrap();

    let context = Context::with_default_plugins();
    let inputs = collect_inputs(
        &context,
        std::slice::from_ref(&series_dir),
        TimeSource::Auto,
    )
    .unwrap();
    assert_eq!(inputs.len(), 18);
    let froct = dir.path().join("series.froct");
    let report = build(&context, &inputs, &froct, &BuildOptions::default(), &Silent).unwrap();
    assert!(!report.regular_axis, "jittered times");
    assert!(
        report.cells.dynamic > 1000 && report.cells.unknown_sometimes > 1000,
        "{report:?}"
    );
    let reader = FroctReader::open(&froct).unwrap();

    // Every input time: the retrieved .bt has the input's leaf set as upstream reads both.
    for input in &inputs {
        let when = resolve_observed(&reader, TimeQuery::Instant(input.time)).unwrap();
        assert!(when.exact);
        let out = dir.path().join("retrieved.bt");
        write_map(
            &context,
            &observed_map(&reader, when.sample).unwrap(),
            &out,
            WriteOptions::default(),
        )
        .unwrap();
        assert!(
            upstream_leaves(&out) == upstream_leaves(&input.path),
            "{}",
            input.path.display()
        );
    }

    // Predictions (past and future) in both formats: read by convert_octree and python.
    let last = inputs.last().unwrap().time;
    for (name, t) in [
        ("within", inputs[5].time),
        ("tomorrow", Timestamp(last.0 + 86_400_000_000_000)),
    ] {
        let predicted = predicted_map(&reader, t).unwrap();
        for ext in ["bt", "ot"] {
            let path = dir.path().join(format!("{name}.{ext}"));
            write_map(&context, &predicted, &path, WriteOptions::default()).unwrap();
            convert_octree(&path, &dir.path().join(format!("{name}_upstream.ot")));
            let (resolution, leaves) = python_leaves(&path, ext);
            assert_eq!(resolution, 0.08);
            assert!(
                leaves == upstream_leaves(&path),
                "{name}.{ext}: octomap-python sees other leaves"
            );
        }
    }

    // Export: complete files plus a manifest; every file is read by both clients.
    let export_dir = dir.path().join("export");
    let exported = export(
        &context,
        &reader,
        &export_dir,
        &ExportOptions {
            from: inputs[0].time,
            to: last,
            every_ns: 4 * 3_600_000_000_000,
            mode: ExportMode::Predict,
            format: "bt".into(),
            backend: None,
            prefix: "map".into(),
            overwrite: false,
            recording: Default::default(),
        },
        &Silent,
    )
    .unwrap();
    assert_eq!(exported.files.len(), 3);
    for file in &exported.files {
        convert_octree(&file.path, &dir.path().join("exported_upstream.ot"));
        let (_, leaves) = python_leaves(&file.path, "bt");
        assert!(leaves == upstream_leaves(&file.path));
    }
    let manifest = std::fs::read_to_string(exported.manifest.as_ref().unwrap()).unwrap();
    assert_eq!(manifest.lines().count(), 4, "{manifest}");
}
