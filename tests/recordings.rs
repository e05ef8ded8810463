//! Builds from ROS recordings written by independent implementations (PyPI rosbags for ROS 1
//! bags and ROS 2 bags with MCAP storage, mcap-ros2-support for MCAP) of a generated FR-079
//! series: the file built from the recordings gives back, at every message time, exactly the
//! map a build from the same maps as .bt files gives.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_convert::{
    build, collect_inputs, observed_map, resolve_observed, BuildOptions, Context, RecordedTime,
    RecordingOptions, SeriesInput, Silent, TimeQuery, TimeSource,
};
use froctomap_core::Timestamp;
use froctomap_file::FroctReader;
use froctomap_formats::{FormatRegistry, ReadOptions};
use froctomap_synth::{write_series, Generator, SeriesSpec, WriteSeriesOptions};
use froctomap_test_support::{geb079, octomap_python, scratch, workspace_root};
use std::path::{Path, PathBuf};
use std::process::Command;

fn context(time: RecordedTime) -> Context {
    let mut context = Context::with_default_plugins();
    froctomap_ros::register(&mut context);
    context.with_recording_options(RecordingOptions::new(None, time))
}

/// A short generated series as .bt files with times in their names.
fn series(dir: &Path) -> Vec<SeriesInput> {
    let formats = FormatRegistry::with_default_formats();
    let base = formats
        .read_file(&geb079(), ReadOptions::default())
        .unwrap()
        .map
        .snapshot
        .to_max_likelihood();
    let spec = SeriesSpec {
        seed: 5,
        start: Timestamp::from_secs(1_451_894_400),
        partial_probability: 0.3,
        ..SeriesSpec::with_duration(0.125, 1800.0)
    };
    let generator = Generator::new(&base, spec, None).unwrap();
    let options = WriteSeriesOptions {
        format: "bt".into(),
        file_pattern: "frame_{time}.{ext}".into(),
        threads: 0,
    };
    write_series(&formats, &generator, dir, &options, &|_, _| {}).unwrap();
    collect_inputs(
        &Context::with_default_plugins(),
        &[dir.to_path_buf()],
        TimeSource::Auto,
    )
    .unwrap()
}

/// Writes recordings with the Python writers: `(kind, path, compression, inputs)`.
fn write_recordings(dir: &Path, recordings: &[(&str, PathBuf, &str, Vec<&SeriesInput>)]) {
    let mut spec = String::from("{\"recordings\": [");
    for (i, (kind, path, compression, inputs)) in recordings.iter().enumerate() {
        let messages: Vec<String> = inputs
            .iter()
            .map(|input| {
                format!(
                    "{{\"topic\": \"/octomap_binary\", \"map\": \"{}\", \"stamp_ns\": {}, \"log_ns\": {}}}",
                    input.path.display(),
                    input.time.0,
                    input.time.0 + 1_000_000_000
                )
            })
            .collect();
        spec.push_str(&format!(
            "{}{{\"kind\": \"{kind}\", \"path\": \"{}\", \"compression\": \"{compression}\", \"messages\": [{}]}}",
            if i > 0 { ", " } else { "" },
            path.display(),
            messages.join(", ")
        ));
    }
    spec.push_str("]}");
    let spec_path = dir.join("spec.json");
    std::fs::write(&spec_path, spec).unwrap();
    let out = Command::new(octomap_python())
        .arg(workspace_root().join("tests/scripts/write_recordings.py"))
        .arg(&spec_path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The leaves of the map observed at each time.
fn observed(froct: &Path, times: &[Timestamp]) -> Vec<Vec<froctomap_core::Leaf>> {
    let reader = FroctReader::open(froct).unwrap();
    times
        .iter()
        .map(|&t| {
            let when = resolve_observed(&reader, TimeQuery::Instant(t)).unwrap();
            assert!(when.exact);
            observed_map(&reader, when.sample)
                .unwrap()
                .leaves()
                .to_vec()
        })
        .collect()
}

#[test]
fn builds_from_bags_and_mcap_equal_the_build_from_bt_files() {
    let dir = scratch();
    let maps = dir.path().join("maps");
    let inputs = series(&maps);
    assert!(inputs.len() >= 5, "{}", inputs.len());
    let times: Vec<Timestamp> = inputs.iter().map(|i| i.time).collect();
    let plain = Context::with_default_plugins();
    let from_files = dir.path().join("files.froct");
    build(
        &plain,
        &inputs,
        &from_files,
        &BuildOptions::default(),
        &Silent,
    )
    .unwrap();
    let expected = observed(&from_files, &times);
    // Even frames in a ROS 1 bag (lz4), odd ones in an MCAP file: merged in time order.
    let even: Vec<&SeriesInput> = inputs.iter().step_by(2).collect();
    let odd: Vec<&SeriesInput> = inputs.iter().skip(1).step_by(2).collect();
    let bag = dir.path().join("even.bag");
    let mcap = dir.path().join("odd.mcap");
    let ros2 = dir.path().join("all_ros2");
    let bz2 = dir.path().join("all_bz2.bag");
    write_recordings(
        dir.path(),
        &[
            ("ros1", bag.clone(), "lz4", even),
            ("mcap", mcap.clone(), "zstd", odd),
            ("ros2bag", ros2.clone(), "none", inputs.iter().collect()),
            ("ros1", bz2.clone(), "bz2", inputs.iter().collect()),
        ],
    );
    for sources in [vec![bag.clone(), mcap.clone()], vec![ros2], vec![bz2]] {
        let context = context(RecordedTime::Header);
        let collected = collect_inputs(&context, &sources, TimeSource::Auto).unwrap();
        let got: Vec<Timestamp> = collected.iter().map(|i| i.time).collect();
        assert_eq!(got, times, "{sources:?}");
        let out = dir.path().join("recorded.froct");
        let report = build(
            &context,
            &collected,
            &out,
            &BuildOptions::default(),
            &Silent,
        )
        .unwrap();
        assert_eq!(report.used, inputs.len());
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert!(observed(&out, &times) == expected, "{sources:?}");
    }

    // Log times: one second after each stamp.
    let context = context(RecordedTime::Log);
    let collected = collect_inputs(&context, &[bag, mcap], TimeSource::Auto).unwrap();
    let logged: Vec<Timestamp> = collected.iter().map(|i| i.time).collect();
    let shifted: Vec<Timestamp> = times
        .iter()
        .map(|t| Timestamp(t.0 + 1_000_000_000))
        .collect();
    assert_eq!(logged, shifted);
}
