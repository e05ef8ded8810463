//! Builds from ROS recordings written by independent implementations (PyPI rosbags for ROS 1
//! bags and ROS 2 bags with MCAP storage, mcap-ros2-support for MCAP) of a generated FR-079
//! series: the file built from the recordings gives back, at every message time, exactly the
//! map a build from the same maps as .bt files gives.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_convert::{
    append, build, collect_inputs, evaluate, export, observed_map, resolve_observed, AppendOptions,
    BuildOptions, BuildReport, Context, ExportMode, ExportOptions, RecordedTime, RecordingOptions,
    RecordingProfile, RecordingWriteOptions, SeriesInput, Silent, TimeQuery, TimeSource,
};
use froctomap_core::Timestamp;
use froctomap_file::FroctReader;
use froctomap_formats::{FormatRegistry, ReadOptions};
use froctomap_ros::OCTOMAP_ROS1_MD5;
use froctomap_synth::{write_series, Generator, SeriesSpec, WriteSeriesOptions};
use froctomap_test_support::{geb079, octomap_python, scratch, workspace_root};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn context(time: RecordedTime) -> Context {
    let mut context = Context::with_default_plugins();
    froctomap_ros::register(context.formats_mut()).unwrap();
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
    froctomap_test_support::write_recordings(&spec_path);
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
    build_with_defaults(&plain, &inputs, &from_files);
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
        let collected =
            collect_inputs(&context(RecordedTime::Header), &sources, TimeSource::Auto).unwrap();
        let got: Vec<Timestamp> = collected.iter().map(|i| i.time).collect();
        assert_eq!(got, times, "{sources:?}");
        let out = dir.path().join("recorded.froct");
        // The collected series holds its opened recordings: the context that collected it is
        // gone, and one without the ROS plugin builds it.
        let report = build_with_defaults(&plain, &collected, &out);
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

/// `export --format mcap`, read back by PyPI mcap and mcap-ros2-support: by default (profile
/// ros2) every message of the whole file decodes through its embedded ros2msg schema; one
/// Octomap message per exported time whose data is the body of the `.bt` export of that time,
/// byte for byte, and a PointCloud2 and a MarkerArray (CUBE_LIST per depth) whose voxels are
/// the occupied voxels octomap-python reads from that `.bt`. Profile foxglove adds a
/// foxglove.PointCloud and foxglove.SceneUpdate cubes of the same voxels, in the structure of
/// Foxglove's schemas.
#[test]
fn exported_mcap_holds_the_bt_exports_and_their_occupied_voxels() {
    let dir = scratch();
    let inputs = series(&dir.path().join("maps"));
    let plain = Context::with_default_plugins();
    let froct = dir.path().join("series.froct");
    build_with_defaults(&plain, &inputs, &froct);
    let reader = FroctReader::open(&froct).unwrap();
    let (first, last) = (inputs[0].time, inputs.last().unwrap().time);
    let options = |format: &str, recording| export_options(&inputs, format, recording);
    let bt_dir = dir.path().join("bt");
    let bts = export(
        &plain,
        &reader,
        &bt_dir,
        &options("bt", RecordingWriteOptions::default()),
        &Silent,
    )
    .unwrap();
    let times: Vec<Timestamp> = bts.files.iter().map(|f| f.time).collect();
    let predicted = |t: Timestamp| t < first || t > last;
    assert!(times.iter().any(|&t| predicted(t)) && times.iter().any(|&t| !predicted(t)));
    let bt_json = dir.path().join("bt.json");
    write_time_index(&bts.files, &bt_json);
    let resolution = reader.header().resolution;

    // The defaults, and Foxglove's channels with every option changed.
    let cases = [
        RecordingWriteOptions::default(),
        RecordingWriteOptions::default()
            .with_profile(RecordingProfile::Foxglove)
            .with_frame_id("odom")
            .with_topic_prefix("/robot1")
            .with_threshold(0.2),
    ];
    for write in cases {
        let profile = write.profile;
        let (frame, prefix, threshold) = (
            write.frame_id.as_str(),
            &write.topic_prefix,
            write.threshold,
        );
        let out_dir = dir.path().join(format!("{profile:?}"));
        let mcap = export_mcap(&reader, &out_dir, &options("mcap", write.clone()), &times);

        let data_dir = out_dir.join("data");
        std::fs::create_dir(&data_dir).unwrap();
        let out = run_script("read_exported_mcap.py", &[&mcap, &data_dir, &bt_json]);
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let foxglove = profile == RecordingProfile::Foxglove;
        // MCAP's `ros2` profile promises CDR channels only: a file with JSON channels
        // names no profile.
        assert_eq!(
            report["profile"],
            if foxglove { "" } else { "ros2" },
            "{profile:?}"
        );
        let channels = expected_channels(prefix, foxglove);
        assert_eq!(report["channels"], channels, "{profile:?}");
        // Every message of every channel read (decoded for CDR), one per map.
        let n = times.len();
        let kind_of = |t: Timestamp| map_kind(predicted(t));
        for topic in channels.as_object().unwrap().keys() {
            assert_eq!(report["counts"][topic], n, "{topic}");
        }
        // Each map's kind in an MCAP metadata record.
        let expected: Vec<serde_json::Value> = times
            .iter()
            .map(|&t| serde_json::json!([t.0.to_string(), kind_of(t)]))
            .collect();
        assert_map_kinds(&report["metadata"], &expected);

        let octomaps = report["octomap"].as_array().unwrap();
        let clouds2 = report["cloud2"].as_array().unwrap();
        let markers = report["markers"].as_array().unwrap();
        for (i, file) in bts.files.iter().enumerate() {
            let t = file.time.0;
            let (octomap, cloud2, marker) = (&octomaps[i], &clouds2[i], &markers[i]);
            for message in [octomap, cloud2, marker] {
                assert_eq!(message["log_time"], t);
                assert_eq!(message["stamp_ns"], t);
                assert_eq!(message["frame_id"], frame);
            }
            assert_octomap_message(
                octomap,
                &file.path,
                &data_dir.join(format!("{t}.data")),
                resolution,
            );

            // The voxels octomap-python reads from the .bt (a predicted map holds p > 0.5):
            // the same unless the threshold is lower.
            let compared = !predicted(file.time) || threshold == 0.5;
            assert_eq!(
                cloud2["same_voxels"], compared,
                "points of the cloud at {t}"
            );
            assert_eq!(cloud2["points"], cloud2["distinct_points"]);
            assert!(cloud2["points"].as_u64().unwrap() > 0);
            assert_eq!(
                marker["same_voxels"], compared,
                "cubes of the markers at {t}"
            );
            assert_eq!(marker["markers"], 17);
            assert_eq!(marker["problems"], serde_json::json!([]));
            // Cells, not voxels: coarse cells are one cube.
            assert!(marker["cubes"].as_u64() <= cloud2["points"].as_u64());
            assert_cloud_values(cloud2, predicted(file.time), threshold);
            if foxglove {
                let expected = (&report["cloud"][i], &report["scene"][i]);
                assert_foxglove_map(
                    expected,
                    cloud2,
                    marker,
                    compared,
                    frame,
                    kind_of(file.time),
                );
            }
        }
        if foxglove {
            assert_some_coarse_cubes(&report["scene"]);
        }
    }
}

/// Export options over `inputs`' span and beyond, every 20 minutes, mode auto: retrieved
/// inside the span (instants between snapshots give each snapshot once), predicted 40
/// minutes before and an hour after it.
fn export_options(
    inputs: &[SeriesInput],
    format: &str,
    recording: RecordingWriteOptions,
) -> ExportOptions {
    let minute = 60_000_000_000;
    let (first, last) = (inputs[0].time, inputs[inputs.len() - 1].time);
    ExportOptions {
        from: Timestamp(first.0 - 40 * minute),
        to: Timestamp(last.0 + 60 * minute),
        every_ns: 20 * minute,
        mode: ExportMode::Auto,
        format: format.to_string(),
        backend: None,
        prefix: "map".to_string(),
        overwrite: false,
        recording,
    }
}

/// `reader` exported as `out_dir/maps.mcap` with `options`: a map at each of `times`, and
/// only the finished file left (no temporary beside it).
fn export_mcap(
    reader: &FroctReader,
    out_dir: &Path,
    options: &ExportOptions,
    times: &[Timestamp],
) -> PathBuf {
    std::fs::create_dir(out_dir).unwrap();
    let mcap = out_dir.join("maps.mcap");
    let exported = export(
        &context(RecordedTime::Header),
        reader,
        &mcap,
        options,
        &Silent,
    )
    .unwrap();
    assert!(exported.manifest.is_none());
    let got: Vec<Timestamp> = exported.files.iter().map(|f| f.time).collect();
    assert_eq!(got, times);
    let left: Vec<_> = std::fs::read_dir(out_dir).unwrap().collect();
    assert_eq!(left.len(), 1, "{left:?}");
    mcap
}

/// An exported Octomap message: binary, an OcTree at `resolution`, its data (as the script
/// saved it in `data_path`) the body of the `.bt` export at `bt_path`.
fn assert_octomap_message(
    octomap: &serde_json::Value,
    bt_path: &Path,
    data_path: &Path,
    resolution: f64,
) {
    assert_eq!(octomap["binary"], true);
    assert_eq!(octomap["id"], "OcTree");
    assert_eq!(octomap["resolution"], resolution);
    let bt = std::fs::read(bt_path).unwrap();
    let body_at = bt.windows(6).position(|w| w == b"\ndata\n").unwrap() + 6;
    let data = std::fs::read(data_path).unwrap();
    assert!(
        data == bt[body_at..],
        "data of the message in {}",
        data_path.display()
    );
}

/// "predicted" or "retrieved", as the exported metadata says.
fn map_kind(predicted: bool) -> &'static str {
    if predicted {
        "predicted"
    } else {
        "retrieved"
    }
}

/// A map's Foxglove messages (`cloud`, `scene`) hold the voxels and cubes of its
/// PointCloud2 and MarkerArray, in `frame`, saying its `kind`.
fn assert_foxglove_map(
    (cloud, scene): (&serde_json::Value, &serde_json::Value),
    cloud2: &serde_json::Value,
    marker: &serde_json::Value,
    compared: bool,
    frame: &str,
    kind: &str,
) {
    assert_eq!(
        cloud["same_voxels"], compared,
        "points of the cloud at {}",
        scene["stamp_ns"]
    );
    assert_eq!(cloud["remainder"], 0);
    assert_eq!(cloud["problems"], serde_json::json!([]), "{cloud}");
    assert_eq!(cloud["points"], cloud2["points"]);
    assert_eq!(scene["problems"], serde_json::json!([]), "{scene}");
    assert_eq!(
        scene["same_voxels"], compared,
        "cubes at {}",
        scene["stamp_ns"]
    );
    assert_eq!(scene["cubes"], marker["cubes"]);
    assert_eq!(scene["stamp_ns"], cloud2["stamp_ns"]);
    assert_eq!(scene["frame_id"], frame);
    assert_eq!(scene["metadata"]["map"], kind);
}

/// The SceneUpdate cubes are sized by their cells: some are coarse.
fn assert_some_coarse_cubes(scenes: &serde_json::Value) {
    // Cubes sized by their cells: some coarse.
    let sizes: Vec<u64> = scenes
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|s| {
            s["sizes"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_u64().unwrap())
        })
        .collect();
    assert!(
        sizes.contains(&1) && sizes.iter().any(|&s| s > 1),
        "{sizes:?}"
    );
}

/// The exported files' paths by their times (ns), as JSON in `path`, for the reading script.
fn write_time_index(files: &[SeriesInput], path: &Path) {
    let mut bt_of = String::from("{");
    for (i, file) in files.iter().enumerate() {
        let sep = if i > 0 { ", " } else { "" };
        bt_of.push_str(&format!(
            "{sep}\"{}\": \"{}\"",
            file.time.0,
            file.path.display()
        ));
    }
    bt_of.push('}');
    std::fs::write(path, bt_of).unwrap();
}

/// The channels of an exported MCAP (topic: encoding and schema), under `prefix`.
fn expected_channels(prefix: &str, foxglove: bool) -> serde_json::Value {
    let mut topics = vec![
        ("/octomap_binary", "cdr", "octomap_msgs/msg/Octomap"),
        (
            "/froctomap/occupied_voxels_pc2",
            "cdr",
            "sensor_msgs/msg/PointCloud2",
        ),
        (
            "/froctomap/occupied_cells_vis_array",
            "cdr",
            "visualization_msgs/msg/MarkerArray",
        ),
    ];
    if foxglove {
        topics.push(("/froctomap/occupied_voxels", "json", "foxglove.PointCloud"));
        topics.push(("/froctomap/occupied_cubes", "json", "foxglove.SceneUpdate"));
    }
    let mut channels = serde_json::json!({});
    for (topic, encoding, schema) in topics {
        channels[format!("{prefix}{topic}")] =
            serde_json::json!({"encoding": encoding, "schema": schema});
    }
    channels
}

/// The `froctomap.map` metadata records say each map's time and kind (`expected`), and only
/// retrieved maps name a sample.
fn assert_map_kinds(metadata: &serde_json::Value, expected: &[serde_json::Value]) {
    let records = metadata.as_array().unwrap();
    for record in records {
        assert_eq!(record["name"], "froctomap.map");
        assert_eq!(
            record.get("sample").is_some(),
            record["map"] == "retrieved",
            "{record}"
        );
    }
    let got: Vec<serde_json::Value> = records
        .iter()
        .map(|m| serde_json::json!([m["time_ns"], m["map"]]))
        .collect();
    assert_eq!(got, expected);
}

/// A PointCloud2's `p` and `dynamic` values: a predicted map's p above the threshold,
/// a retrieved map's occupied voxels certain, dynamic and static ones in their colours.
fn assert_cloud_values(cloud2: &serde_json::Value, predicted: bool, threshold: f64) {
    // The same fields in every message, retrieved or predicted.
    assert_eq!(
        cloud2["fields"],
        serde_json::json!([
            ["x", 7],
            ["y", 7],
            ["z", 7],
            ["rgba", 6],
            ["p", 7],
            ["dynamic", 7]
        ])
    );
    let value = &cloud2["values"];
    if predicted {
        let low = value["p"][0].as_f64().unwrap();
        assert!(
            low > threshold && value["p"][1].as_f64().unwrap() <= 1.0,
            "{cloud2}"
        );
        // Below 0.5 too when the threshold is lower: uncertain space drawn.
        assert_eq!(low <= 0.5, threshold < 0.5, "{cloud2}");
        assert_eq!(value["dynamic"], "nan");
    } else {
        // Dynamic and static voxels, each in its own colour, observed occupied.
        assert_eq!(cloud2["colours"], 2, "{cloud2}");
        assert_eq!(value["dynamic"], serde_json::json!([0.0, 1.0]));
        assert_eq!(value["p"], serde_json::json!([1.0, 1.0]));
    }
}

/// A generated series in `dir` (`maps/`), built (`series.froct`, opened) and exported as
/// `.bt` files (`bt/`) at the instants of [`export_options`]: what the recordings exported
/// from the same file are compared with.
fn exported_bts(
    dir: &Path,
) -> (
    Vec<SeriesInput>,
    FroctReader,
    froctomap_convert::ExportReport,
) {
    let inputs = series(&dir.join("maps"));
    let plain = Context::with_default_plugins();
    let froct = dir.join("series.froct");
    build_with_defaults(&plain, &inputs, &froct);
    let reader = FroctReader::open(&froct).unwrap();
    let options = export_options(&inputs, "bt", RecordingWriteOptions::default());
    let bts = export(&plain, &reader, &dir.join("bt"), &options, &Silent).unwrap();
    (inputs, reader, bts)
}

/// `export -o maps.bag`, read back by PyPI rosbags' indexed reader: one
/// `octomap_msgs/Octomap` connection whose MD5 sum is the one rosbags computes from the
/// definition the bag stores, one message per exported time, stamped and logged at it, in
/// order, whose data is the body of the `.bt` export of that time byte for byte; the frame
/// and topic prefix as asked. A profile other than the default is refused, nothing written.
#[test]
fn exported_bag_holds_the_bt_exports_as_octomap_messages() {
    let dir = scratch();
    let (inputs, reader, bts) = exported_bts(dir.path());
    let options = |format: &str, recording| export_options(&inputs, format, recording);
    let context = context(RecordedTime::Header);
    let write = RecordingWriteOptions::default()
        .with_frame_id("odom")
        .with_topic_prefix("/robot1");
    let bag = dir.path().join("maps.bag");
    let exported = export(&context, &reader, &bag, &options("rosbag", write), &Silent).unwrap();
    assert_eq!(exported.files.len(), bts.files.len());

    let data_dir = dir.path().join("data");
    std::fs::create_dir(&data_dir).unwrap();
    let out = run_script("read_exported_bag.py", &[&bag, &data_dir]);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let n = bts.files.len();
    assert_eq!(
        report["connections"],
        serde_json::json!([{"topic": "/robot1/octomap_binary", "type": "octomap_msgs/msg/Octomap",
            "md5": OCTOMAP_ROS1_MD5, "computed_md5": OCTOMAP_ROS1_MD5, "count": n}])
    );
    assert_eq!(report["count"], n);
    let messages = report["messages"].as_array().unwrap();
    assert_eq!(messages.len(), n);
    for (i, (message, file)) in messages.iter().zip(&bts.files).enumerate() {
        let t = file.time.0;
        assert_eq!(message["log_time"], t);
        assert_eq!(message["stamp_ns"], t);
        assert_eq!(message["seq"], i);
        assert_eq!(message["frame_id"], "odom");
        assert_eq!(message["binary"], true);
        assert_eq!(message["id"], "OcTree");
        assert_eq!(message["resolution"], reader.header().resolution);
        let bt = std::fs::read(&file.path).unwrap();
        let body_at = bt.windows(6).position(|w| w == b"\ndata\n").unwrap() + 6;
        let data = std::fs::read(data_dir.join(format!("{t}.data"))).unwrap();
        assert!(data == bt[body_at..], "data of the message at {t}");
    }

    // Foxglove's messages have no place in a ROS 1 bag: refused, naming the option.
    let refused = dir.path().join("foxglove.bag");
    let message = foxglove_refused(&reader, &inputs, "rosbag", &refused);
    assert!(message.contains("profile"), "{message}");
    assert!(!refused.exists());
}

/// The error of an export of `reader` into `output` as `format` with the foxglove profile.
fn foxglove_refused(
    reader: &FroctReader,
    inputs: &[SeriesInput],
    format: &str,
    output: &Path,
) -> String {
    let foxglove = RecordingWriteOptions::default().with_profile(RecordingProfile::Foxglove);
    let options = export_options(inputs, format, foxglove);
    let context = context(RecordedTime::Header);
    chain(&export(&context, reader, output, &options, &Silent).unwrap_err())
}

/// `export --format ros2bag` makes a ROS 2 bag directory `maps_bag/` (metadata.yaml and
/// `maps_bag_0.mcap`) that rosbags' rosbag2 Reader opens: metadata.yaml (parsed on its own
/// too) names the MCAP storage, its one file, every topic with its type, `cdr` and its real
/// message count, the first map's time and the span to the last, no compression; every
/// message of every topic decodes as CDR through the types the MCAP file stores, one octomap
/// message per exported time, stamped and logged at it, whose data is the body of the `.bt`
/// export of that time byte for byte, with the frame and topic prefix asked. Our own reader
/// reads the directory back: a build from it equals the build from the `.bt` export. An
/// existing directory, or a profile a bag cannot hold, is refused, nothing left.
#[test]
fn exported_ros2_bag_directory_holds_the_bt_exports_as_cdr_messages() {
    let dir = scratch();
    let (inputs, reader, bts) = exported_bts(dir.path());
    let options = |format: &str, recording| export_options(&inputs, format, recording);
    let context = context(RecordedTime::Header);
    let write = RecordingWriteOptions::default()
        .with_frame_id("odom")
        .with_topic_prefix("/robot1");
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let bag = out.join("maps_bag");
    let exported = export(&context, &reader, &bag, &options("ros2bag", write), &Silent).unwrap();
    let n = bts.files.len();
    assert_eq!(exported.files.len(), n);
    assert!(exported.manifest.is_none());
    let mut names: Vec<String> = std::fs::read_dir(&bag)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["maps_bag_0.mcap", "metadata.yaml"]);
    let beside: Vec<_> = std::fs::read_dir(&out).unwrap().collect();
    assert_eq!(
        beside.len(),
        1,
        "no temporary directory left beside the bag"
    );

    let data_dir = dir.path().join("data");
    std::fs::create_dir(&data_dir).unwrap();
    let report = run_script("read_exported_ros2bag.py", &[&bag, &data_dir]);
    let report: serde_json::Value = serde_json::from_slice(&report.stdout).unwrap();
    check_exported_ros2_bag(&report, &bts.files, reader.header().resolution, &data_dir);
    let times: Vec<i64> = bts.files.iter().map(|f| f.time.0).collect();

    // Read back by our own reader (a ROS 2 bag directory among the inputs): the same maps.
    let collected = collect_inputs(&context, std::slice::from_ref(&bag), TimeSource::Auto).unwrap();
    let got: Vec<i64> = collected.iter().map(|i| i.time.0).collect();
    assert_eq!(got, times);
    let from_bag = dir.path().join("from_bag.froct");
    let from_bts = dir.path().join("from_bts.froct");
    let plain = Context::with_default_plugins();
    build_with_defaults(&plain, &collected, &from_bag);
    build_with_defaults(&plain, &bts.files, &from_bts);
    let stamps: Vec<Timestamp> = bts.files.iter().map(|f| f.time).collect();
    assert!(observed(&from_bag, &stamps) == observed(&from_bts, &stamps));

    // An existing directory is refused, untouched, nothing written beside it.
    let metadata = std::fs::read(bag.join("metadata.yaml")).unwrap();
    let err = export(
        &context,
        &reader,
        &bag,
        &options("ros2bag", RecordingWriteOptions::default()),
        &Silent,
    )
    .unwrap_err();
    let message = chain(&err);
    assert!(message.contains("already exists"), "{message}");
    assert_eq!(std::fs::read(bag.join("metadata.yaml")).unwrap(), metadata);
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 1);

    // Foxglove's JSON messages have no place in a ROS 2 bag: refused, nothing left.
    let message = foxglove_refused(&reader, &inputs, "ros2bag", &out.join("foxglove_bag"));
    assert!(message.contains("profile"), "{message}");
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 1);
}

/// What rosbags read from the ROS 2 bag exported from the maps `files` (the `.bt` export)
/// with frame `odom` and topic prefix `/robot1` (`read_exported_ros2bag.py`'s report): the
/// metadata, the connections and every message as the test above says.
fn check_exported_ros2_bag(
    report: &serde_json::Value,
    files: &[SeriesInput],
    resolution: f64,
    data_dir: &Path,
) {
    let n = files.len();
    let times: Vec<i64> = files.iter().map(|f| f.time.0).collect();
    let (first, last) = (times[0], times[n - 1]);
    let topics = [
        ("/robot1/octomap_binary", "octomap_msgs/msg/Octomap"),
        (
            "/robot1/froctomap/occupied_voxels_pc2",
            "sensor_msgs/msg/PointCloud2",
        ),
        (
            "/robot1/froctomap/occupied_cells_vis_array",
            "visualization_msgs/msg/MarkerArray",
        ),
    ];
    let topic_counts: Vec<serde_json::Value> = topics
        .iter()
        .map(|(name, type_name)| {
            serde_json::json!({"topic_metadata": {"name": name, "type": type_name,
                "serialization_format": "cdr", "offered_qos_profiles": "",
                "type_description_hash": ""}, "message_count": n})
        })
        .collect();
    let span = serde_json::json!({"nanoseconds": last - first});
    let start = serde_json::json!({"nanoseconds_since_epoch": first});
    assert_eq!(
        report["metadata"],
        serde_json::json!({"rosbag2_bagfile_information": {
            "version": 8, "storage_identifier": "mcap", "duration": span,
            "starting_time": start, "message_count": 3 * n,
            "topics_with_message_count": topic_counts,
            "compression_format": "", "compression_mode": "",
            "relative_file_paths": ["maps_bag_0.mcap"],
            "files": [{"path": "maps_bag_0.mcap", "starting_time": start, "duration": span,
                "message_count": 3 * n}],
            "custom_data": {}, "ros_distro": ""}})
    );
    assert_eq!(report["start_time"], first);
    assert_eq!(report["end_time"], last + 1);
    assert_eq!(report["message_count"], 3 * n);
    assert_eq!(report["compression"], serde_json::json!([null, null]));
    for (topic, type_name) in topics {
        assert!(
            report["connections"]
                .as_array()
                .unwrap()
                .contains(&serde_json::json!({"topic": topic, "type": type_name,
                    "format": "cdr", "count": n})),
            "{topic}: {}",
            report["connections"]
        );
        assert_eq!(report["decoded"][topic], n, "{topic}");
    }
    let octomaps = report["octomaps"].as_array().unwrap();
    assert_eq!(octomaps.len(), n);
    for (message, file) in octomaps.iter().zip(files) {
        let t = file.time.0;
        assert_eq!(message["topic"], "/robot1/octomap_binary");
        assert_eq!(message["log_time"], t);
        assert_eq!(message["stamp_ns"], t);
        assert_eq!(message["frame_id"], "odom");
        assert_eq!(message["binary"], true);
        assert_eq!(message["id"], "OcTree");
        assert_eq!(message["resolution"], resolution);
        let bt = std::fs::read(&file.path).unwrap();
        let body_at = bt.windows(6).position(|w| w == b"\ndata\n").unwrap() + 6;
        let data = std::fs::read(data_dir.join(format!("{t}.data"))).unwrap();
        assert!(data == bt[body_at..], "data of the message at {t}");
    }
}

/// Recordings written by rosbags and mcap-ros2-support, then damaged here: each problem is an
/// error naming the recording (and the topic and message time where there is one), or, for a
/// message whose data is not a map, a map left out and listed with `skip_bad`.
#[test]
fn damaged_recordings_are_refused_or_skipped_with_their_bag_topic_and_time() {
    let dir = scratch();
    let fixtures = workspace_root().join("fixtures/octomap");
    let good = [
        fixtures.join("few_voxels.bt"),
        fixtures.join("coarse_leaves.bt"),
    ];
    // A map whose body is not an OctoMap tree (every node claims children past the leaves).
    let raw = std::fs::read(&good[0]).unwrap();
    let at = raw.windows(6).position(|w| w == b"\ndata\n").unwrap() + 6;
    let mut not_a_map = raw[..at].to_vec();
    not_a_map.extend_from_slice(&[0xff; 40]);
    let bad = dir.path().join("not_a_map.bt");
    std::fs::write(&bad, not_a_map).unwrap();
    let second = 1_000_000_000;
    let t0 = 1_700_000_000 * second;
    let input = |path: &Path, t: i64| SeriesInput::new(path.to_path_buf(), Timestamp(t));
    let three = [
        input(&good[0], t0),
        input(&bad, t0 + 60 * second),
        input(&good[1], t0 + 120 * second),
    ];
    let same = [input(&good[0], t0), input(&good[1], t0)];
    let path = |name: &str| dir.path().join(name);
    write_recordings(
        dir.path(),
        &[
            (
                "ros1",
                path("not_a_map.bag"),
                "none",
                three.iter().collect(),
            ),
            (
                "mcap",
                path("not_a_map.mcap"),
                "zstd",
                three.iter().collect(),
            ),
            ("ros1", path("same.bag"), "none", same.iter().collect()),
            ("ros1", path("lz4.bag"), "lz4", same[..1].iter().collect()),
        ],
    );
    let context = || context(RecordedTime::Header);
    let out = path("out.froct");
    for name in ["not_a_map.bag", "not_a_map.mcap"] {
        let context = context();
        let inputs = collect_inputs(&context, &[path(name)], TimeSource::Auto).unwrap();
        let err =
            chain(&build(&context, &inputs, &out, &BuildOptions::default(), &Silent).unwrap_err());
        // The message is named by its log time (one second after its stamp here).
        for part in [
            name,
            "/octomap_binary",
            "2023-11-14T22:14:21Z",
            "not an OctoMap tree",
        ] {
            assert!(err.contains(part), "{name}: {err}");
        }
        let options = BuildOptions {
            skip_bad: true,
            ..BuildOptions::default()
        };
        let report = build(&context, &inputs, &out, &options, &Silent).unwrap();
        assert_eq!(report.used, 2, "{name}");
        assert_eq!(report.skipped.len(), 1, "{name}");
        assert_eq!(report.skipped[0].code(), "damaged-recording", "{name}");
        assert!(
            report.skipped[0].message.contains("2023-11-14T22:14:21Z"),
            "{:?}",
            report.skipped
        );
    }

    // Two maps of one time.
    let err =
        chain(&collect_inputs(&context(), &[path("same.bag")], TimeSource::Auto).unwrap_err());
    for part in [
        "same.bag",
        "/octomap_binary",
        "2023-11-14T22:13:20Z",
        "same time",
    ] {
        assert!(err.contains(part), "{err}");
    }

    // Compression this reader does not know, and a damaged lz4 chunk.
    let bag = std::fs::read(path("lz4.bag")).unwrap();
    let field = bag
        .windows(15)
        .position(|w| w == b"compression=lz4")
        .unwrap();
    let mut unknown = bag.clone();
    unknown[field + 12..field + 15].copy_from_slice(b"xz4");
    std::fs::write(path("unknown.bag"), unknown).unwrap();
    let err =
        chain(&collect_inputs(&context(), &[path("unknown.bag")], TimeSource::Auto).unwrap_err());
    assert!(
        err.contains("unknown.bag") && err.contains("`xz4` is not supported"),
        "{err}"
    );
    let mut damaged = bag.clone();
    for byte in &mut damaged[field + 80..field + 140] {
        *byte ^= 0x5a;
    }
    std::fs::write(path("damaged.bag"), damaged).unwrap();
    let err =
        chain(&collect_inputs(&context(), &[path("damaged.bag")], TimeSource::Auto).unwrap_err());
    assert!(err.contains("damaged.bag"), "{err}");
    // Cut anywhere: an error naming the bag, never a panic.
    for end in (0..bag.len()).step_by(97) {
        std::fs::write(path("cut.bag"), &bag[..end]).unwrap();
        if let Err(err) = collect_inputs(&context(), &[path("cut.bag")], TimeSource::Auto) {
            let err = chain(&err);
            assert!(err.contains("cut.bag"), "cut at {end}: {err}");
        }
    }
}

/// Maps stamped out of their recording order are taken in time order, with a warning.
#[test]
fn maps_stamped_out_of_recording_order_are_sorted_with_a_warning() {
    let dir = scratch();
    let fixtures = workspace_root().join("fixtures/octomap");
    let t0 = 1_700_000_000_000_000_000;
    let minute = 60_000_000_000;
    // Logged in this order (log time = stamp + 1 s), stamped later then earlier.
    let late = SeriesInput::new(fixtures.join("few_voxels.bt"), Timestamp(t0 + minute));
    let early = SeriesInput::new(
        fixtures.join("coarse_leaves.bt"),
        Timestamp(t0 - 2 * minute),
    );
    let bag = dir.path().join("unordered.bag");
    write_recordings(
        dir.path(),
        &[("ros1", bag.clone(), "none", vec![&late, &early])],
    );
    let context = context(RecordedTime::Header);
    let collected = froctomap_convert::collect_inputs_explained(
        &context,
        &[bag],
        TimeSource::Auto,
        &Default::default(),
    )
    .unwrap();
    let times: Vec<Timestamp> = collected.series.iter().map(|i| i.time).collect();
    assert_eq!(times, [early.time, late.time]);
    let warnings: Vec<String> = collected.warnings.iter().map(|w| w.to_string()).collect();
    assert!(
        warnings.iter().any(|w| w.contains("stamped earlier")),
        "{warnings:?}"
    );
}

/// `append` takes a recording like .bt files, and `evaluate` takes one as ground truth: the
/// same results as with the recorded maps as .bt files.
#[test]
fn append_and_eval_take_recordings() {
    let dir = scratch();
    let inputs = series(&dir.path().join("maps"));
    let (early, late) = inputs.split_at(inputs.len() / 2);
    let mcap = dir.path().join("late.mcap");
    write_recordings(
        dir.path(),
        &[("mcap", mcap.clone(), "zstd", late.iter().collect())],
    );
    let plain = Context::with_default_plugins();
    let from_files = dir.path().join("files.froct");
    build_with_defaults(&plain, early, &from_files);
    let from_recording = dir.path().join("recording.froct");
    std::fs::copy(&from_files, &from_recording).unwrap();

    // Evaluated against the later maps: from the recording as from the files.
    let eval = |context: &Context, truths: &[SeriesInput]| {
        let reader = FroctReader::open(&from_files).unwrap();
        let report = evaluate(context, &reader, truths, ReadOptions::default(), &Silent).unwrap();
        serde_json::to_value(report).unwrap()
    };
    let context = context(RecordedTime::Header);
    let recorded = collect_inputs(&context, &[mcap], TimeSource::Auto).unwrap();
    assert_eq!(recorded.len(), late.len());
    let expected = eval(&plain, late);
    assert_eq!(expected["outside"], late.len());
    assert_eq!(eval(&context, &recorded), expected);

    // Appended: the file of the recording equals the one of the files, map for map.
    append(
        &plain,
        &from_files,
        late,
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap();
    append(
        &context,
        &from_recording,
        &recorded,
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap();
    let times: Vec<Timestamp> = inputs.iter().map(|i| i.time).collect();
    assert!(observed(&from_recording, &times) == observed(&from_files, &times));
}

/// `build` with default options, which must succeed.
fn build_with_defaults(context: &Context, inputs: &[SeriesInput], out: &Path) -> BuildReport {
    build(context, inputs, out, &BuildOptions::default(), &Silent).unwrap()
}

/// Where `needle` occurs in `haystack`.
fn positions(haystack: &[u8], needle: &[u8]) -> Vec<usize> {
    haystack
        .windows(needle.len())
        .enumerate()
        .filter(|(_, w)| *w == needle)
        .map(|(i, _)| i)
        .collect()
}

/// `inputs` as a ROS 1 bag (rosbags, lz4) `bag.bag` and an MCAP file (mcap-ros2-support, zstd)
/// `mcap.mcap` in `dir`, one chunk per map, each logged a second after its stamp.
fn write_one_chunk_per_map(inputs: &[SeriesInput], dir: &Path) {
    let second = 1_000_000_000;
    let mut spec = String::from("{\"recordings\": [");
    for (i, (kind, name, compression)) in
        [("ros1", "bag.bag", "lz4"), ("mcap", "mcap.mcap", "zstd")]
            .iter()
            .enumerate()
    {
        let messages: Vec<String> = inputs
            .iter()
            .map(|m| {
                format!(
                    "{{\"topic\": \"/octomap_binary\", \"map\": \"{}\", \"stamp_ns\": {}, \"log_ns\": {}}}",
                    m.path.display(),
                    m.time.0,
                    m.time.0 + second
                )
            })
            .collect();
        spec.push_str(&format!(
            "{}{{\"kind\": \"{kind}\", \"path\": \"{}\", \"compression\": \"{compression}\", \"chunk_bytes\": 1, \"messages\": [{}]}}",
            if i > 0 { ", " } else { "" },
            dir.join(name).display(),
            messages.join(", ")
        ));
    }
    spec.push_str("]}");
    let spec_path = dir.join("spec.json");
    std::fs::write(&spec_path, spec).unwrap();
    froctomap_test_support::write_recordings(&spec_path);
}

/// `bytes` with those of `range` after `at` inverted.
fn damaged(bytes: &[u8], at: usize, range: std::ops::Range<usize>) -> Vec<u8> {
    let mut bytes = bytes.to_vec();
    for b in &mut bytes[at + range.start..at + range.end] {
        *b ^= 0xff;
    }
    bytes
}

/// The default plugins and the ROS ones, times from the header stamps, damaged parts of
/// recordings left out with `skip_bad`.
fn header_time_context(skip_bad: bool) -> Context {
    let mut context = Context::with_default_plugins();
    froctomap_ros::register(context.formats_mut()).unwrap();
    context.with_recording_options(
        RecordingOptions::new(None, RecordedTime::Header).with_skip_bad(skip_bad),
    )
}

/// The inputs of one recording, as `build` collects them.
fn collect_one(
    context: &Context,
    file: &Path,
) -> Result<froctomap_convert::CollectedInputs, froctomap_convert::ConvertError> {
    froctomap_convert::collect_inputs_explained(
        context,
        &[file.to_path_buf()],
        TimeSource::Auto,
        &Default::default(),
    )
}

/// Recordings of four maps, one chunk each, written by rosbags (ROS 1, lz4) and
/// mcap-ros2-support (zstd), then damaged here: a chunk whose compressed data is not lz4 or
/// zstd, one whose CRC fails, and files cut inside their third chunk (no index, no summary).
/// A damaged chunk is an error naming the recording, topic and times, or with `skip_bad`
/// is left out and listed; a cut file gives its complete chunks, with a warning saying what
/// was lost. What is read builds, map for map, what the same `.bt` files build.
#[test]
fn damaged_chunks_are_skipped_and_cut_recordings_read_up_to_the_cut() {
    let dir = scratch();
    let fixtures = workspace_root().join("fixtures/octomap");
    let second = 1_000_000_000;
    let t0 = 1_700_000_000 * second;
    let inputs: Vec<SeriesInput> = (0..4)
        .map(|k| {
            SeriesInput::new(
                fixtures.join(["few_voxels.bt", "coarse_leaves.bt"][k % 2]),
                Timestamp(t0 + 60 * second * k as i64),
            )
        })
        .collect();
    let path = |name: &str| dir.path().join(name);
    write_one_chunk_per_map(&inputs, dir.path());

    let bag = std::fs::read(path("bag.bag")).unwrap();
    let mcap = std::fs::read(path("mcap.mcap")).unwrap();
    // The compressed data of each chunk starts with its frame's magic number.
    let lz4_frames = positions(&bag, &[0x04, 0x22, 0x4d, 0x18]);
    let zstd_frames = positions(&mcap, &[0x28, 0xb5, 0x2f, 0xfd]);
    assert!(
        lz4_frames.len() >= 4 && zstd_frames.len() >= 4,
        "{lz4_frames:?} {zstd_frames:?}"
    );
    // The chunk of the second map: the second frame, or the third when the first chunk holds
    // only connection records (find it by the map it holds).
    // The message logged at t0 + 61 s (the second map), in ISO 8601.
    let second_map = "2023-11-14T22:14:21Z";
    let cases: Vec<(&str, Vec<u8>, &str)> = lz4_frames
        .iter()
        .map(|&at| ("lz4.bag", damaged(&bag, at, 0..4), "lz4"))
        .chain(
            zstd_frames
                .iter()
                .map(|&at| ("zstd.mcap", damaged(&mcap, at, 0..4), "zstd")),
        )
        .chain(
            // The CRC (u32) lies before the compression name (u32 length, "zstd").
            positions(&mcap, b"\x04\x00\x00\x00zstd")
                .iter()
                .map(|&at| ("crc.mcap", damaged(&mcap, at - 4, 0..4), "CRC")),
        )
        .collect();
    // The build from the .bt files of `kept` (indexes into `inputs`), and its maps.
    let from_bt = |kept: &[usize], name: &str| {
        let files: Vec<SeriesInput> = kept.iter().map(|&k| inputs[k].clone()).collect();
        let out = path(&format!("{name}-bt.froct"));
        build_with_defaults(&Context::with_default_plugins(), &files, &out);
        let times: Vec<Timestamp> = files.iter().map(|i| i.time).collect();
        (observed(&out, &times), times)
    };
    let mut seen = Vec::new();
    for (name, bytes, problem) in &cases {
        std::fs::write(path(name), bytes).unwrap();
        let strict = collect_one(&header_time_context(false), &path(name));
        let context = header_time_context(true);
        let lenient = collect_one(&context, &path(name)).unwrap();
        if lenient.series.len() == inputs.len() {
            // A frame of a chunk without maps (the connections only): nothing of ours lost.
            assert!(lenient.skipped.is_empty() || strict.is_err(), "{name}");
            continue;
        }
        let err = chain(&strict.unwrap_err());
        assert_eq!(lenient.skipped.len(), 1, "{name}: {:?}", lenient.skipped);
        assert_eq!(lenient.skipped[0].code(), "damaged-recording", "{name}");
        let listed = &lenient.skipped[0].message;
        for text in [&err, listed] {
            for part in [name, "/octomap_binary", "chunk at byte", problem] {
                assert!(text.contains(part), "{name}: {text}");
            }
        }
        // Which map was lost: the one whose time the message names.
        let lost = (0..4)
            .find(|&k| !lenient.series.iter().any(|i| i.time == inputs[k].time))
            .unwrap();
        let logged = froctomap_core::calendar::iso8601(Timestamp(inputs[lost].time.0 + second));
        assert!(err.contains(&logged), "{name}: {err}");
        if lost == 1 {
            assert!(err.contains(second_map));
        }
        seen.push((name.to_string(), lost));
        // The rest builds what their .bt files build.
        let out = path(&format!("{name}.froct"));
        build_with_defaults(&context, &lenient.series, &out);
        let kept: Vec<usize> = (0..4).filter(|&k| k != lost).collect();
        let (expected, times) = from_bt(&kept, name);
        assert!(observed(&out, &times) == expected, "{name}");
    }
    for name in ["lz4.bag", "zstd.mcap", "crc.mcap"] {
        assert!(
            seen.iter().filter(|(n, _)| n == name).count() == 4,
            "{name}: each map's chunk damaged once: {seen:?}"
        );
    }

    // Cut inside the chunk of the third map: no index or summary; the two maps before read.
    for (name, bytes, frames, fix) in [
        ("cut.bag", &bag, &lz4_frames, "rosbag reindex"),
        ("cut.mcap", &mcap, &zstd_frames, "mcap recover"),
    ] {
        // The frame holding the third map: the third of the frames that hold maps.
        let map_frames: Vec<usize> = frames
            .iter()
            .copied()
            .filter(|&at| {
                std::fs::write(path("probe"), damaged(bytes, at, 0..4)).unwrap();
                collect_one(&header_time_context(true), &path("probe"))
                    .unwrap()
                    .series
                    .len()
                    < 4
            })
            .collect();
        assert_eq!(map_frames.len(), 4, "{name}");
        let cut = &bytes[..map_frames[2] + 10];
        std::fs::write(path(name), cut).unwrap();
        let context = header_time_context(false);
        let collected = collect_one(&context, &path(name)).unwrap();
        let times: Vec<Timestamp> = collected.series.iter().map(|i| i.time).collect();
        assert_eq!(times, [inputs[0].time, inputs[1].time], "{name}");
        let warnings: Vec<String> = collected.warnings.iter().map(|w| w.to_string()).collect();
        assert!(
            warnings
                .iter()
                .any(|w| w.contains(name) && w.contains(fix) && w.contains("bytes are not read")),
            "{name}: {warnings:?}"
        );
        let out = path(&format!("{name}.froct"));
        build_with_defaults(&context, &collected.series, &out);
        let (expected, times) = from_bt(&[0, 1], name);
        assert!(observed(&out, &times) == expected, "{name}");
    }
}

/// The bytes of the map observed at each time, as `retrieve` writes them (`.bt`).
fn retrieved_bytes(context: &Context, froct: &Path, times: &[Timestamp]) -> Vec<Vec<u8>> {
    let reader = FroctReader::open(froct).unwrap();
    let dir = scratch();
    times
        .iter()
        .map(|&t| {
            let when = resolve_observed(&reader, TimeQuery::Instant(t)).unwrap();
            assert!(when.exact);
            let out = dir.path().join(format!("{}.bt", t.0));
            froctomap_convert::write_observed_map(
                context,
                &reader,
                when.sample,
                &out,
                Default::default(),
            )
            .unwrap();
            std::fs::read(&out).unwrap()
        })
        .collect()
}

/// ROS 2 bags with sqlite3 storage written by rosbags, uncompressed and with both of
/// rosbag2's zstd compression modes (per message, per file): each builds a file from which
/// every map retrieves byte for byte as the input `.bt` file, at its header stamp (or, with
/// `--time-source log`, at its log time); `append` takes one too.
#[test]
fn sqlite3_ros2_bags_build_and_retrieve_their_maps_byte_for_byte() {
    let dir = scratch();
    let inputs = series(&dir.path().join("maps"));
    let times: Vec<Timestamp> = inputs.iter().map(|i| i.time).collect();
    let expected: Vec<Vec<u8>> = inputs
        .iter()
        .map(|i| std::fs::read(&i.path).unwrap())
        .collect();
    let bag = |mode: &str| dir.path().join(format!("sqlite_{mode}"));
    write_recordings(
        dir.path(),
        &["none", "message", "file"]
            .map(|mode| ("ros2sqlite", bag(mode), mode, inputs.iter().collect())),
    );
    // What rosbags wrote: a .db3 (a .db3.zstd for file compression) beside metadata.yaml.
    assert!(bag("none").join("sqlite_none.db3").is_file());
    assert!(bag("file").join("sqlite_file.db3.zstd").is_file());
    let spool = dir.path().join("spool");
    std::fs::create_dir(&spool).unwrap();
    for mode in ["none", "message", "file"] {
        let context = context(RecordedTime::Header);
        let context = context.with_recording_options(
            RecordingOptions::new(None, RecordedTime::Header).with_spool_dir(Some(spool.clone())),
        );
        let collected = collect_inputs(&context, &[bag(mode)], TimeSource::Auto).unwrap();
        let got: Vec<Timestamp> = collected.iter().map(|i| i.time).collect();
        assert_eq!(got, times, "{mode}");
        let out = dir.path().join(format!("{mode}.froct"));
        let report = build_with_defaults(&context, &collected, &out);
        assert_eq!(report.used, inputs.len(), "{mode}");
        assert!(report.warnings.is_empty(), "{mode}: {:?}", report.warnings);
        drop(collected);
        // The decompressed database is gone with the recording.
        assert_eq!(std::fs::read_dir(&spool).unwrap().count(), 0, "{mode}");
        let retrieved = retrieved_bytes(&context, &out, &times);
        for (k, (got, want)) in retrieved.iter().zip(&expected).enumerate() {
            assert!(got == want, "{mode}: map {k} differs from its input");
        }
    }
    // Log times (one second after each stamp), and append.
    let context = context(RecordedTime::Log);
    let logged = collect_inputs(&context, &[bag("message")], TimeSource::Auto).unwrap();
    let shifted: Vec<Timestamp> = times
        .iter()
        .map(|t| Timestamp(t.0 + 1_000_000_000))
        .collect();
    assert_eq!(logged.iter().map(|i| i.time).collect::<Vec<_>>(), shifted);
    let (early, late) = inputs.split_at(inputs.len() / 2);
    let appended = dir.path().join("appended.froct");
    build_with_defaults(&Context::with_default_plugins(), early, &appended);
    let context = self::context(RecordedTime::Header).with_recording_options(
        RecordingOptions::new(None, RecordedTime::Header).with_skip_bad(false),
    );
    let recorded: Vec<SeriesInput> = collect_inputs(&context, &[bag("file")], TimeSource::Auto)
        .unwrap()
        .into_iter()
        .skip(early.len())
        .collect();
    assert_eq!(recorded.len(), late.len());
    append(
        &context,
        &appended,
        &recorded,
        &AppendOptions::default(),
        &Silent,
    )
    .unwrap();
    let retrieved = retrieved_bytes(&context, &appended, &times);
    assert!(retrieved == expected, "appended from the bag");
}

/// Hostile sqlite3 storage (made by Python's sqlite3, or rosbags' file cut or changed here):
/// each is a typed error naming the database file, never a panic, a hang or a large
/// allocation.
#[test]
fn hostile_sqlite3_bags_are_refused_naming_the_file() {
    let dir = scratch();
    let t0 = 1_700_000_000_000_000_000;
    let inputs = fixture_maps(t0);
    let good = dir.path().join("good");
    let message = dir.path().join("message");
    let file = dir.path().join("file");
    write_recordings(
        dir.path(),
        &[
            ("ros2sqlite", good.clone(), "none", inputs.iter().collect()),
            (
                "ros2sqlite",
                message.clone(),
                "message",
                inputs.iter().collect(),
            ),
            ("ros2sqlite", file.clone(), "file", inputs.iter().collect()),
        ],
    );
    let db = good.join("good.db3");
    let hostile = dir.path().join("hostile");
    std::fs::create_dir(&hostile).unwrap();
    let out = run_script("hostile_sqlite.py", &[&db, &hostile]);
    let declared: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let context = context(RecordedTime::Header);
    // Opened and every map read: the first error.
    let read_all = |bag: &Path| -> Result<usize, String> {
        let collected = collect_inputs(&context, &[bag.to_path_buf()], TimeSource::Auto)
            .map_err(|e| chain(&e))?;
        let out = bag.with_extension("froct");
        build(
            &context,
            &collected,
            &out,
            &BuildOptions::default(),
            &Silent,
        )
        .map_err(|e| chain(&e))?;
        Ok(collected.len())
    };
    assert_eq!(read_all(&good), Ok(3));
    for (case, expect) in [
        ("no_messages", "no table `messages`"),
        ("no_data", "no column `data`"),
        ("view", "no table `messages`"),
        ("huge_blob", "good.db3"),
        ("not_sqlite", "not a database"),
    ] {
        let err = read_all(&hostile.join(case)).unwrap_err();
        assert!(
            err.contains("good.db3") && err.contains(expect),
            "{case}: {err}"
        );
        if case == "huge_blob" {
            // Refused for what it claims, before anything of that size is allocated.
            let claimed = declared["huge_declared"].as_u64().unwrap();
            assert!(
                err.contains(&claimed.to_string()) || err.contains("malformed"),
                "{case}: {err}"
            );
        }
    }
    // Cut anywhere (the plain and the zstd-compressed database): an error naming the file,
    // or the maps before the cut.
    for (bag, name) in [(&good, "good.db3"), (&file, "file.db3.zstd")] {
        let bytes = std::fs::read(bag.join(name)).unwrap();
        let cut = dir.path().join(format!("cut_{name}"));
        std::fs::create_dir(&cut).unwrap();
        std::fs::copy(bag.join("metadata.yaml"), cut.join("metadata.yaml")).unwrap();
        for end in (0..bytes.len()).step_by(bytes.len() / 40 + 1) {
            std::fs::write(cut.join(name), &bytes[..end]).unwrap();
            if let Err(err) = read_all(&cut) {
                assert!(err.contains(name), "cut at {end}: {err}");
            }
        }
    }
    // A compression this reader does not read: named with its mode and format.
    let metadata = std::fs::read_to_string(message.join("metadata.yaml")).unwrap();
    assert!(metadata.contains("compression_format: zstd"), "{metadata}");
    std::fs::write(
        message.join("metadata.yaml"),
        metadata.replace("compression_format: zstd", "compression_format: lz4"),
    )
    .unwrap();
    let err = read_all(&message).unwrap_err();
    assert!(
        err.contains("message") && err.contains("`lz4`") && err.contains("is not read"),
        "{err}"
    );
}

/// Runs a script of `tests/scripts` with the interop Python, which must succeed: its
/// standard output.
fn run_script(script: &str, args: &[&Path]) -> Output {
    let out = Command::new(octomap_python())
        .arg(workspace_root().join("tests/scripts").join(script))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{script}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// An error and its causes, one text, as the front ends print it (a refusal's reason is the
/// cause of the error that names the file). Not checked with `said_twice`: rusqlite's errors
/// repeat their own causes, which the printed line shows once.
fn chain(error: &(dyn std::error::Error + 'static)) -> String {
    froctomap_core::error_message(error)
}

/// `info` on every kind of recording (ROS 1 bag, MCAP file, ROS 2 bag directories with MCAP
/// and sqlite3 storage, compressed per file): its topics, types, message counts and log-time
/// spans are what rosbags (bags) and mcap (MCAP files) read from the same file.
#[test]
fn info_on_recordings_lists_what_rosbags_and_mcap_read() {
    let dir = scratch();
    let fixtures = workspace_root().join("fixtures/octomap");
    let t0 = 1_700_000_000_000_000_000;
    let inputs = fixture_maps(t0);
    let path = |name: &str| dir.path().join(name);
    let recordings = [
        ("ros1", path("run.bag"), "lz4", "rosbag"),
        ("mcap", path("run.mcap"), "zstd", "mcap"),
        ("ros2bag", path("mcap_bag"), "none", "ros2bag"),
        ("ros2sqlite", path("sqlite_bag"), "file", "ros2bag"),
    ];
    write_recordings(
        dir.path(),
        &recordings
            .clone()
            .map(|(kind, path, compression, _)| (kind, path, compression, inputs.iter().collect())),
    );
    let context = context(RecordedTime::Header);
    for (_, path, _, format) in &recordings {
        let info = froctomap_convert::describe_recording(&context, path)
            .unwrap()
            .unwrap();
        assert_eq!(info.format, *format);
        let out = run_script("recording_info.py", &[path]);
        let expected: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let expected = expected.as_object().unwrap();
        assert_eq!(info.topics.len(), expected.len(), "{path:?}: {info:?}");
        for topic in &info.topics {
            let want = &expected[&topic.topic];
            // rosbags names ROS 1 types as ROS 2 ones (`octomap_msgs/msg/Octomap`).
            let ros2_name = |name: &str| name.replace("/msg/", "/");
            assert_eq!(
                ros2_name(&topic.type_name),
                ros2_name(want["type"].as_str().unwrap()),
                "{path:?}"
            );
            assert_eq!(
                topic.messages,
                want["messages"].as_u64().unwrap(),
                "{path:?}"
            );
            assert_eq!(topic.first_ns, want["first"].as_i64(), "{path:?}");
            assert_eq!(topic.last_ns, want["last"].as_i64(), "{path:?}");
        }
        // The maps' topic: three messages, logged a second after each stamp.
        let maps = info
            .topics
            .iter()
            .find(|t| t.topic == "/octomap_binary")
            .unwrap();
        assert_eq!(maps.messages, 3);
        assert_eq!(maps.first_ns, Some(t0 + 1_000_000_000));
        assert_eq!(info.messages, 4, "{path:?}");
        assert_eq!(info.duration_s, Some(120.0));
    }
    // A map file is not a recording.
    let map = fixtures.join("few_voxels.bt");
    assert!(froctomap_convert::describe_recording(&context, &map)
        .unwrap()
        .is_none());
}

/// Three fixture maps a minute apart from `t0`.
fn fixture_maps(t0: i64) -> Vec<SeriesInput> {
    let fixtures = workspace_root().join("fixtures/octomap");
    (0..3)
        .map(|k| {
            SeriesInput::new(
                fixtures.join(["few_voxels.bt", "coarse_leaves.bt"][k % 2]),
                Timestamp(t0 + 60_000_000_000 * k as i64),
            )
        })
        .collect()
}
