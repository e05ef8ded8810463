//! Format 2.0 files (a base and segments) through the binary: `retrieve`, `predict`,
//! `export`, `info` and `compact` against a 1.2 build of the same maps, retrieved maps read
//! by upstream OctoMap's tools and octomap-python, whole-history commands refused until
//! `compact`, and damaged 2.0 files refused with the file named.
//!
//! The segments are written by `froctomap append` (the segment ingest) from the later maps,
//! so each test runs the whole chain: build, convert, append, then read or compact.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_core::{Leaf, Occupancy, Snapshot, VoxelKey};
use froctomap_file::{FroctReader, LivingReader, LivingWriter, ROOT_SLOTS_AT};
use froctomap_formats::{FormatRegistry, WriteOptions};
use froctomap_test_support::{compare_octrees, convert_octree, python_leaves, scratch};
use serde_json::Value;
use std::path::{Path, PathBuf};

mod common;
use common::{err, ok, s};

const START: u32 = 1_451_865_600;
const STEP: u32 = 600;
const CREATED: &str = "2016-02-01T00:00:00Z";

/// A room of 16×16×2 voxels: a wall, a door that opens and closes with a period of four
/// frames, a box that appears from frame 10 on, a chair that comes and goes every third
/// frame, and on odd frames a corner not observed; from frame 12 on (the segments) the
/// sensor also sees a strip behind the wall, never seen before, with a second wall.
fn frame(i: u32) -> Snapshot {
    let mut leaves = Vec::new();
    let width = if i >= 12 { 18 } else { 16 };
    for x in 0..width {
        for y in 0..16u16 {
            for z in 0..2u16 {
                if i % 2 == 1 && x < 4 && y < 4 {
                    continue;
                }
                let wall = x == 15 || x == 17;
                let door = x == 8 && (4..8).contains(&y) && (i / 2) % 2 == 1;
                let new_box = i >= 10 && (2..4).contains(&x) && (10..12).contains(&y);
                let chair = i % 3 == 0 && x == 5 && y == 12 && z == 0;
                let occupied = wall || door || new_box || chair;
                leaves.push(Leaf::voxel(
                    VoxelKey::new(32768 + x, 32768 + y, 32768 + z),
                    if occupied { 3.5 } else { -2.0 },
                ));
            }
        }
    }
    Snapshot::from_leaves(0.1, leaves).unwrap()
}

/// Writes frames into `dir`, named by their times.
fn write_frames(dir: &Path, frames: std::ops::Range<u32>) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir).unwrap();
    let registry = FormatRegistry::with_default_formats();
    frames
        .map(|i| {
            let path = dir.join(format!("room_{}.bt", START + i * STEP));
            registry
                .write_file(&frame(i), &path, WriteOptions::default())
                .unwrap();
            path
        })
        .collect()
}

fn build(dir: &Path, out: &Path) {
    ok(&["build", s(dir), "-o", s(out), "--created", CREATED, "-q"]);
}

/// The series: 24 frames; `full.froct` a 1.2 build of all of them; `base.froct` a 1.2 build
/// of frames 0–11; `living.froct` a copy of it turned by `append --format-version 2.0` into
/// a 2.0 file whose two segments hold 12–17 and 18–23.
struct Living {
    dir: tempfile::TempDir,
    inputs: Vec<PathBuf>,
    full: PathBuf,
    living: PathBuf,
}

fn living_series() -> Living {
    let dir = scratch();
    let root = dir.path();
    let mut inputs = write_frames(&root.join("all"), 0..24);
    inputs.sort();
    for (name, range) in [("base", 0..12), ("seg1", 12..18), ("seg2", 18..24)] {
        write_frames(&root.join(name), range);
    }
    build(&root.join("base"), &root.join("base.froct"));
    let full = root.join("full.froct");
    build(&root.join("all"), &full);
    let living = root.join("living.froct");
    std::fs::copy(root.join("base.froct"), &living).unwrap();
    ok(&[
        "append",
        s(&living),
        s(&root.join("seg1")),
        "--format-version",
        "2.0",
        "-q",
    ]);
    ok(&["append", s(&living), s(&root.join("seg2")), "-q"]);
    Living {
        dir,
        inputs,
        full,
        living,
    }
}

fn retrieved(file: &Path, sample: u32, out: &Path) -> Vec<u8> {
    ok(&[
        "retrieve",
        s(file),
        "--time",
        &format!("index:{sample}"),
        "-o",
        s(out),
        "-q",
    ]);
    std::fs::read(out).unwrap()
}

fn info(file: &Path) -> Value {
    serde_json::from_str(&ok(&["info", s(file), "--json"])).unwrap()
}

/// `info --json` without what differs between equal maps in different containers: the
/// file's name, its metadata, version, sizes and the ratios computed from them.
fn content(mut info: Value) -> Value {
    let object = info.as_object_mut().unwrap();
    for key in [
        "file",
        "metadata",
        "version",
        "size",
        "ratio_vs_inputs",
        "ratio_vs_raw_states",
        "input_files",
        "input_bytes",
        "living",
    ] {
        object.remove(key);
    }
    info
}

#[test]
fn every_map_of_a_living_file_retrieves_as_a_build_of_the_same_maps() {
    let series = living_series();
    let out = series.dir.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    let reader = LivingReader::open(&series.living).unwrap();
    assert_eq!((reader.segment_count(), reader.sample_count()), (2, 24));
    // The segments store what differs from the base's predictions (patch tiles).
    let patches = (0..2)
        .flat_map(|k| (0..reader.segment_tiles(k).len()).map(move |t| (k, t)))
        .filter(|&(k, t)| reader.is_patch_tile(k, t))
        .count();
    assert!(patches > 0, "no patch tile");
    for sample in 0..24 {
        let from_living = retrieved(&series.living, sample, &out.join("living.bt"));
        let from_full = retrieved(&series.full, sample, &out.join("full.bt"));
        assert!(from_living == from_full, "sample {sample} differs");
        // The generated inputs are canonical: the retrieval is the input itself.
        assert!(
            from_living == std::fs::read(&series.inputs[sample as usize]).unwrap(),
            "sample {sample} is not its input"
        );
    }
    // Retrieval by time takes the map at or before it, across the base/segment seam.
    let between = format!("{}", START + 14 * STEP + STEP / 2);
    ok(&[
        "retrieve",
        s(&series.living),
        "--time",
        &between,
        "-o",
        s(&out.join("between.bt")),
        "-q",
    ]);
    assert_eq!(
        std::fs::read(out.join("between.bt")).unwrap(),
        std::fs::read(&series.inputs[14]).unwrap()
    );

    // Upstream OctoMap and octomap-python read what the living file gives, leaf for leaf
    // as they read the input, in the base and in each segment.
    for sample in [3u32, 13, 22] {
        let bt = out.join(format!("living-{sample}.bt"));
        retrieved(&series.living, sample, &bt);
        let input = &series.inputs[sample as usize];
        let (ot, input_ot) = (out.join(format!("{sample}.ot")), out.join("input.ot"));
        convert_octree(&bt, &ot);
        convert_octree(input, &input_ot);
        let comparison = compare_octrees(&input_ot, &ot);
        assert!(comparison.identical(), "{}", comparison.transcript);
        assert_eq!(python_leaves(&bt, "bt"), python_leaves(input, "bt"));
    }
}

#[test]
fn info_predict_and_export_read_living_files() {
    let series = living_series();
    let out = series.dir.path().join("out");
    info_shows_the_segments(&series);
    predict_reads_base_and_segments(&series, &out);
    export_retrieves_the_inputs(&series, &out);
    export_to_mcap_matches_the_bt_export(&series, &out);
    export_past_the_span_predicts(&series, &out);
}

/// `info` shows the base and the two segments.
fn info_shows_the_segments(series: &Living) {
    let living = info(&series.living);
    assert_eq!(living["version"], "2.0");
    assert_eq!(living["time"]["samples"], 24);
    assert_eq!(living["time"]["kind"], "segmented");
    let segments = living["living"]["segments"].as_array().unwrap();
    let samples: Vec<(u64, u64)> = segments
        .iter()
        .map(|s| {
            (
                s["first_sample"].as_u64().unwrap(),
                s["samples"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(samples, [(12, 6), (18, 6)]);
    assert_eq!(
        living["living"]["committed_len"].as_u64().unwrap(),
        std::fs::metadata(&series.living).unwrap().len()
    );
    let text = ok(&["info", s(&series.living)]);
    assert!(text.contains("FROctomap 2.0"), "{text}");
    assert!(text.contains("2 segment(s) of 6, 6 samples"), "{text}");
}

/// A prediction: every base cell by its model, as in the base's own 1.x file; space
/// only the segments saw (the strip behind the wall) by the newest segment's state.
/// Upstream reads it.
fn predict_reads_base_and_segments(series: &Living, out: &Path) {
    let later = format!("{}", START + 40 * STEP);
    let predicted = out.join("predicted.bt");
    std::fs::create_dir_all(out).unwrap();
    ok(&[
        "predict",
        s(&series.living),
        "--time",
        &later,
        "-o",
        s(&predicted),
        "-q",
    ]);
    convert_octree(&predicted, &out.join("predicted.ot"));
    let map = FormatRegistry::with_default_formats()
        .read_file(&predicted, Default::default())
        .unwrap()
        .map
        .snapshot;
    let base = FroctReader::open(&series.dir.path().join("base.froct")).unwrap();
    let seconds = f64::from(40 * STEP);
    let behind = VoxelKey::new(32768 + 17, 32768 + 3, 32768);
    assert_eq!(map.state_at(behind.morton()), Some(Occupancy::Occupied));
    let beside = VoxelKey::new(32768 + 16, 32768 + 3, 32768);
    assert_eq!(map.state_at(beside.morton()), Some(Occupancy::Free));
    let wall = VoxelKey::new(32768 + 15, 32768, 32768);
    let base_wall = base
        .region_probabilities(wall, wall, seconds)
        .unwrap()
        .first()
        .map(|c| c.value > 0.5);
    assert_eq!(
        map.state_at(wall.morton()).map(|o| o.is_occupied()),
        base_wall
    );
    // .ot carries p(t) of the base cells: the door's voxel (modelled in the base) has the
    // log-odds the base's own file predicts, per octomap-python.
    let (living_ot, base_ot) = (out.join("p.ot"), out.join("base-p.ot"));
    let base_file = series.dir.path().join("base.froct");
    for (file, ot) in [(&series.living, &living_ot), (&base_file, &base_ot)] {
        ok(&["predict", s(file), "--time", &later, "-o", s(ot), "-q"]);
    }
    let door = |ot: &Path| {
        python_leaves(ot, "ot")
            .1
            .into_iter()
            .find(|&(x, y, z, depth, _)| (x, y, z, depth) == (32768 + 8, 32768 + 5, 32768, 16))
            .expect("the door voxel is a leaf")
    };
    assert_eq!(door(&living_ot), door(&base_ot));
}

/// Export in both modes: retrieved maps are the inputs.
fn export_retrieves_the_inputs(series: &Living, out: &Path) {
    let exported = out.join("export");
    ok(&[
        "export",
        s(&series.living),
        "--from",
        &format!("{START}"),
        "--to",
        &format!("{}", START + 30 * STEP),
        "--every",
        "10min",
        "--mode",
        "auto",
        "-o",
        s(&exported),
        "-q",
    ]);
    for (i, input) in series.inputs.iter().enumerate() {
        let name = format!(
            "map_{}.bt",
            froctomap_core::calendar::iso8601_basic(froctomap_core::Timestamp::from_secs(
                i64::from(START + i as u32 * STEP)
            ))
        );
        assert_eq!(
            std::fs::read(exported.join(&name)).unwrap(),
            std::fs::read(input).unwrap(),
            "{name}"
        );
    }
}

/// One MCAP recording of the same maps (occupied voxels from the states: the segments'
/// cells have no models to shade them by), read by the PyPI mcap readers: each message's
/// map is the .bt export's, each point cloud its occupied voxels per octomap-python.
fn export_to_mcap_matches_the_bt_export(series: &Living, out: &Path) {
    let exported = out.join("export");
    let mcap = out.join("maps.mcap");
    ok(&[
        "export",
        s(&series.living),
        "--from",
        &format!("{START}"),
        "--to",
        &format!("{}", START + 30 * STEP),
        "--every",
        "10min",
        "--mode",
        "auto",
        "-o",
        s(&mcap),
        "-q",
    ]);
    let name = |i: u32| {
        exported.join(format!(
            "map_{}.bt",
            froctomap_core::calendar::iso8601_basic(froctomap_core::Timestamp::from_secs(
                i64::from(START + i * STEP)
            ))
        ))
    };
    let bt_of: serde_json::Map<String, Value> = (0..=30)
        .map(|i| {
            let t = i64::from(START + i * STEP) * 1_000_000_000;
            (t.to_string(), Value::from(s(&name(i))))
        })
        .collect();
    let bt_json = out.join("bt.json");
    std::fs::write(&bt_json, Value::Object(bt_of).to_string()).unwrap();
    let data_dir = out.join("mcap-data");
    std::fs::create_dir_all(&data_dir).unwrap();
    let read = std::process::Command::new(froctomap_test_support::octomap_python())
        .arg(froctomap_test_support::workspace_root().join("tests/scripts/read_exported_mcap.py"))
        .args([&mcap, &data_dir, &bt_json])
        .output()
        .unwrap();
    assert!(
        read.status.success(),
        "{}",
        String::from_utf8_lossy(&read.stderr)
    );
    let report: Value = serde_json::from_slice(&read.stdout).unwrap();
    // The default (`ros2`) profile's point cloud: `sensor_msgs/PointCloud2` in CDR.
    let clouds = report["cloud2"].as_array().unwrap();
    assert_eq!(clouds.len(), 31);
    for cloud in clouds {
        assert_eq!(cloud["same_voxels"], true, "{cloud}");
    }
    for i in 0..=30u32 {
        let t = i64::from(START + i * STEP) * 1_000_000_000;
        let bt = std::fs::read(name(i)).unwrap();
        let body_at = bt.windows(6).position(|w| w == b"\ndata\n").unwrap() + 6;
        let data = std::fs::read(data_dir.join(format!("{t}.data"))).unwrap();
        assert!(data == bt[body_at..], "map {i}");
    }
}

/// Past the span: predicted maps, as `predict` writes them.
fn export_past_the_span_predicts(series: &Living, out: &Path) {
    let exported = out.join("export");
    let last = exported.join(format!(
        "map_{}.bt",
        froctomap_core::calendar::iso8601_basic(froctomap_core::Timestamp::from_secs(i64::from(
            START + 30 * STEP
        )))
    ));
    let direct = out.join("direct.bt");
    ok(&[
        "predict",
        s(&series.living),
        "--time",
        &format!("{}", START + 30 * STEP),
        "-o",
        s(&direct),
        "-q",
    ]);
    assert_eq!(std::fs::read(last).unwrap(), std::fs::read(direct).unwrap());
}

/// `compact --lossy -o` writes what `build --lossy` of the same maps writes (the models
/// without the outlier set); in place it is refused, naming the file, which is left whole.
#[test]
fn a_lossy_compaction_is_a_lossy_build_and_never_in_place() {
    let series = living_series();
    let root = series.dir.path();
    let built = root.join("lossy-build.froct");
    let compacted = root.join("lossy.froct");
    let lossy = ["--lossy", "--created", CREATED, "-q", "-o"];
    ok(&[&["build", s(&root.join("all"))], &lossy[..], &[s(&built)]].concat());
    ok(&[
        &["compact", s(&series.living)],
        &lossy[..],
        &[s(&compacted)],
    ]
    .concat());
    let compacted_info = info(&compacted);
    assert_eq!(compacted_info["outliers"], "lossy", "{compacted_info}");
    assert_eq!(content(compacted_info), content(info(&built)));
    let out = root.join("out-lossy");
    std::fs::create_dir_all(&out).unwrap();
    for sample in 0..24 {
        assert!(
            retrieved(&compacted, sample, &out.join("a.bt"))
                == retrieved(&built, sample, &out.join("b.bt")),
            "sample {sample}"
        );
    }
    let before = std::fs::read(&series.living).unwrap();
    let message = err(&["compact", s(&series.living), "--lossy"]);
    assert!(
        message.contains(s(&series.living)) && message.contains("-o"),
        "{message}"
    );
    assert_eq!(std::fs::read(&series.living).unwrap(), before);
}

/// `compact --tile-depth` into smaller tiles writes what `build --tile-depth` of the same
/// maps writes; larger tiles than the file's are refused, naming the file.
#[test]
fn compacting_into_smaller_tiles_is_a_build_in_them() {
    let series = living_series();
    let root = series.dir.path();
    let built = root.join("small-tiles-build.froct");
    let compacted = root.join("small-tiles.froct");
    let common = ["--tile-depth", "14", "--created", CREATED, "-q", "-o"];
    ok(&[&["build", s(&root.join("all"))], &common[..], &[s(&built)]].concat());
    ok(&[
        &["compact", s(&series.living)],
        &common[..],
        &[s(&compacted)],
    ]
    .concat());
    let compacted_info = info(&compacted);
    assert_eq!(compacted_info["tile_depth"], 14, "{compacted_info}");
    assert_eq!(content(compacted_info), content(info(&built)));
    let out = root.join("out-small-tiles");
    std::fs::create_dir_all(&out).unwrap();
    for sample in [0, 11, 12, 23] {
        assert!(
            retrieved(&compacted, sample, &out.join("a.bt"))
                == retrieved(&series.full, sample, &out.join("b.bt")),
            "sample {sample}"
        );
    }
    let message = err(&["compact", s(&series.living), "--tile-depth", "9"]);
    assert!(
        message.contains(s(&series.living)) && message.contains("tile depth 9"),
        "{message}"
    );
}

#[test]
fn compact_equals_a_build_of_the_same_maps() {
    let series = living_series();
    let root = series.dir.path();
    // Whole-history commands refuse a file with segments, naming it and the cure.
    let message = err(&["history", s(&series.living), "--at", "0.5,0.5,0.05"]);
    assert!(
        message.contains(s(&series.living))
            && message.contains("2 segment(s)")
            && message.contains("froctomap compact"),
        "{message}"
    );

    let flat = root.join("compact-1.2.froct");
    let report: Value = serde_json::from_str(&ok(&[
        "compact",
        s(&series.living),
        "-o",
        s(&flat),
        "--format-version",
        "1.2",
        "--created",
        CREATED,
        "--json",
        "-q",
    ]))
    .unwrap();
    assert_eq!(report["segments_before"], 2);
    assert_eq!(report["version"], "1.2");
    let compacted = info(&flat);
    assert_eq!(content(compacted.clone()), content(info(&series.full)));
    // Every map counted, but the segments' input bytes are not recorded: no ratio claimed
    // from the base's inputs alone.
    assert_eq!(compacted["input_files"], 24);
    assert!(compacted["input_bytes"].is_null(), "{compacted}");
    assert!(compacted["ratio_vs_inputs"].is_null(), "{compacted}");
    // Before compaction, the ratio is the base's against the base's inputs.
    let before = info(&series.living);
    let base_len = before["living"]["base_len"].as_f64().unwrap();
    let ratio = before["input_bytes"].as_f64().unwrap() / base_len;
    assert!(
        (before["ratio_vs_inputs"].as_f64().unwrap() - ratio).abs() < 1e-9,
        "{before}"
    );

    // In place, as 2.0 without segments (the default), under the writer lock: refused
    // while another writer holds it, and the file left as it was.
    let copy = root.join("copy.froct");
    std::fs::copy(&series.living, &copy).unwrap();
    let writer = LivingWriter::open(&copy).unwrap();
    let message = err(&["compact", s(&copy)]);
    assert!(
        message.contains(s(&copy)) && message.contains("lock"),
        "{message}"
    );
    drop(writer);
    assert_eq!(
        std::fs::read(&copy).unwrap(),
        std::fs::read(&series.living).unwrap()
    );
    ok(&["compact", s(&copy), "--created", CREATED, "-q"]);
    let compacted = info(&copy);
    assert_eq!(compacted["version"], "2.0");
    assert_eq!(compacted["living"]["segments"].as_array().unwrap().len(), 0);
    assert_eq!(content(compacted), content(info(&series.full)));
    let out = root.join("out");
    std::fs::create_dir_all(&out).unwrap();
    for sample in 0..24 {
        assert!(
            retrieved(&copy, sample, &out.join("a.bt"))
                == retrieved(&series.full, sample, &out.join("b.bt")),
            "sample {sample}"
        );
    }
    // The tiles are the build's: apart from the header (metadata) and the root slots, the
    // 2.0 file and the 1.2 file of the compaction hold the same bytes.
    let (two, one) = (std::fs::read(&copy).unwrap(), std::fs::read(&flat).unwrap());
    let tiles = |bytes: &[u8], reader: &FroctReader| {
        let t = reader.tiles();
        let (a, b) = (
            t[0].offset as usize,
            (t.last().unwrap().offset + u64::from(t.last().unwrap().stored_len)) as usize,
        );
        bytes[a..b].to_vec()
    };
    let living = LivingReader::open(&copy).unwrap();
    assert!(tiles(&two, living.base()) == tiles(&one, &FroctReader::open(&flat).unwrap()));
    // With no segment left, the whole-history commands work.
    ok(&["history", s(&copy), "--at", "0.85,0.45,0.05", "--json"]);
    // And a 2.0 file without segments reads as its base everywhere.
    let fresh = root.join("fresh.froct");
    LivingWriter::convert(&series.full, &fresh).unwrap();
    let history = |file: &Path| {
        let text = ok(&["history", s(file), "--at", "0.85,0.45,0.05", "--json"]);
        let mut story: Value = serde_json::from_str(&text).unwrap();
        story.as_object_mut().unwrap().remove("file");
        story
    };
    assert_eq!(history(&fresh), history(&series.full));
}

#[test]
fn damaged_living_files_are_refused_naming_the_file() {
    let series = living_series();
    let bytes = std::fs::read(&series.living).unwrap();
    let root = series.dir.path();
    let out = root.join("out.bt");
    let retrieve = |file: &Path| err(&["retrieve", s(file), "--time", "last", "-o", s(&out)]);

    // Cut inside the last segment: the root says more is committed than the file holds.
    let truncated = root.join("truncated.froct");
    std::fs::write(&truncated, &bytes[..bytes.len() - 10]).unwrap();
    for message in [
        retrieve(&truncated),
        err(&["info", s(&truncated)]),
        err(&["compact", s(&truncated), "-o", s(&root.join("c.froct"))]),
    ] {
        assert!(
            message.contains(s(&truncated)) && message.contains("truncated"),
            "{message}"
        );
    }
    assert!(!root.join("c.froct").exists());

    // Resealed roots (checksums recomputed): a segment count beyond the limit, and one
    // that does not match the chain of records.
    let current = {
        let slot = |k: usize| {
            let at = ROOT_SLOTS_AT as usize + 64 * k;
            u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap())
        };
        usize::from(slot(1) > slot(0))
    };
    for (what, count) in [("limit", u32::MAX), ("chain", 1)] {
        let mut hostile = bytes.clone();
        let at = ROOT_SLOTS_AT as usize + 64 * current;
        hostile[at + 32..at + 36].copy_from_slice(&count.to_le_bytes());
        let crc = crc32c::crc32c(&hostile[at..at + 60]);
        hostile[at + 60..at + 64].copy_from_slice(&crc.to_le_bytes());
        let path = root.join(format!("resealed-{what}.froct"));
        std::fs::write(&path, &hostile).unwrap();
        for message in [retrieve(&path), err(&["info", s(&path)])] {
            assert!(message.contains(s(&path)), "{what}: {message}");
            assert!(!message.contains("panicked"), "{what}: {message}");
        }
    }
}
