//! `froctomap anomalies` end to end: an injected box is the top region of the JSON report,
//! `-o` writes its voxels as a `.bt` that upstream OctoMap and octomap-python read, and bad
//! inputs fail with messages naming the file.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_core::{Leaf, Occupancy, Snapshot, VoxelKey};
use froctomap_formats::{FormatRegistry, WriteOptions};
use froctomap_test_support::{convert_octree, python_leaves};
use std::path::{Path, PathBuf};

mod common;
use common::{err, ok, s};

const START: u32 = 1_451_865_600; // 2016-01-04T00:00:00Z
const O: u16 = 32768;

/// A 16×16×6 room at hour `hour`: floor and walls, free inside, a door in the wall y = 0
/// open from 08:00 to 18:00; `extra` voxels occupied on top.
fn room(hour: u32, resolution: f64, extra: &dyn Fn(VoxelKey) -> bool) -> Snapshot {
    let open = (8..18).contains(&(hour % 24));
    let mut leaves = Vec::new();
    for x in 0..16u16 {
        for y in 0..16u16 {
            for z in 0..6u16 {
                let k = VoxelKey::new(O + x, O + y, O + z);
                let door = (6..10).contains(&x) && y == 0 && (1..5).contains(&z);
                let wall = x == 0 || x == 15 || y == 0 || y == 15 || z == 0;
                let occupied = if door { !open } else { wall || extra(k) };
                leaves.push(Leaf::voxel(k, Occupancy::from(occupied).log_odds()));
            }
        }
    }
    Snapshot::from_leaves(resolution, leaves)
        .unwrap()
        .canonical()
}

fn write(map: &Snapshot, path: &Path) -> PathBuf {
    FormatRegistry::with_default_formats()
        .write_file(map, path, WriteOptions::default())
        .unwrap();
    path.to_path_buf()
}

/// A week of hourly rooms built into `room.froct`.
fn built() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("inputs");
    std::fs::create_dir(&inputs).unwrap();
    for hour in 0..168 {
        let path = inputs.join(format!("room_{}.bt", START + hour * 3600));
        write(&room(hour, 0.1, &|_| false), &path);
    }
    let file = dir.path().join("room.froct");
    ok(&["-q", "build", s(&inputs), "-o", s(&file)]);
    (dir, file)
}

/// The box injected on day 8 at 11:00: 3×3×3 voxels in free space, standing on the floor.
fn in_box(k: VoxelKey) -> bool {
    (O + 4..O + 7).contains(&k.x) && (O + 5..O + 8).contains(&k.y) && (O + 1..O + 4).contains(&k.z)
}

#[test]
fn an_injected_box_is_the_top_region_and_its_voxels_are_written() {
    let (dir, file) = built();
    let hour = 168 + 11;
    let snapshot = write(
        &room(hour, 0.1, &in_box),
        &dir.path().join(format!("scan_{}.bt", START + hour * 3600)),
    );
    let out = dir.path().join("anomalies.bt");
    let json: serde_json::Value = serde_json::from_str(&ok(&[
        "-q",
        "anomalies",
        s(&file),
        s(&snapshot),
        "--json",
        "-o",
        s(&out),
    ]))
    .unwrap();
    assert_eq!(json["time"], "2016-01-11T11:00:00Z");
    let regions = json["regions"].as_array().unwrap();
    assert!(!regions.is_empty(), "{json}");
    let top = &regions[0];
    assert_eq!(top["kind"], "appeared");
    assert_eq!(top["voxels"], 27);
    let corner = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_f64().unwrap())
            .collect()
    };
    let near = |a: Vec<f64>, b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9);
    assert!(near(corner(&top["min"]), [0.4, 0.5, 0.1]), "{top}");
    assert!(near(corner(&top["max"]), [0.7, 0.8, 0.4]), "{top}");
    let scores: Vec<f64> = regions
        .iter()
        .map(|r| r["score"].as_f64().unwrap())
        .collect();
    assert!(scores.windows(2).all(|w| w[0] >= w[1]), "{scores:?}");

    // --png: the `render` picture of the map at that time, with the region outlined in red.
    let overlay = dir.path().join("overlay.png");
    let map = dir.path().join("map.png");
    ok(&[
        "-q",
        "anomalies",
        s(&file),
        s(&snapshot),
        "--png",
        s(&overlay),
        "--width",
        "400",
    ]);
    ok(&[
        "-q",
        "render",
        s(&file),
        "--time",
        "2016-01-11T11:00:00Z",
        "-o",
        s(&map),
        "--width",
        "400",
    ]);
    let overlay = image::open(&overlay).unwrap().to_rgb8();
    let map = image::open(&map).unwrap().to_rgb8();
    assert_eq!(overlay.dimensions(), map.dimensions());
    let changed: Vec<[u8; 3]> = overlay
        .pixels()
        .zip(map.pixels())
        .filter(|(a, b)| a != b)
        .map(|(a, _)| a.0)
        .collect();
    assert!(changed.len() >= 20, "{} pixels outlined", changed.len());
    if regions.len() == 1 {
        assert!(
            changed.iter().all(|&p| p == [220, 20, 60]),
            "only red outlines"
        );
    }

    // The clean snapshot of the same hour has nothing as surprising.
    let clean = write(
        &room(hour, 0.1, &|_| false),
        &dir.path().join(format!("clean_{}.bt", START + hour * 3600)),
    );
    let clean_json: serde_json::Value =
        serde_json::from_str(&ok(&["anomalies", s(&file), s(&clean), "--json"])).unwrap();
    for region in clean_json["regions"].as_array().unwrap() {
        assert!(region["score"].as_f64().unwrap() < scores[0], "{region}");
    }

    // The text table, and the anomalous voxels as read by upstream OctoMap and
    // octomap-python: the box's voxels when the box is the only region.
    let table = ok(&["anomalies", s(&file), s(&snapshot)]);
    assert!(
        table.contains("appeared") && table.contains("(0.40, 0.50, 0.10)"),
        "{table}"
    );
    let ot = dir.path().join("anomalies.ot");
    convert_octree(&out, &ot);
    let (resolution, leaves) = python_leaves(&out, "bt");
    assert_eq!(resolution, 0.1);
    let voxels: u64 = leaves
        .iter()
        .map(|l| 1u64 << (3 * (16 - u32::from(l.3))))
        .sum();
    let total: u64 = regions.iter().map(|r| r["voxels"].as_u64().unwrap()).sum();
    assert_eq!(voxels, total);
    if regions.len() == 1 {
        assert!(
            leaves.iter().all(|l| in_box(VoxelKey::new(l.0, l.1, l.2))),
            "{leaves:?}"
        );
    }
}

#[test]
fn bad_inputs_fail_naming_the_file() {
    let (dir, file) = built();
    let d = dir.path();
    let t = START + 200 * 3600;

    let coarse = write(
        &room(10, 0.2, &|_| false),
        &d.join(format!("coarse_{t}.bt")),
    );
    let e = err(&["anomalies", s(&file), s(&coarse)]);
    assert!(
        e.contains("coarse_") && e.contains("0.2 m") && e.contains("hint:"),
        "{e}"
    );

    let garbage = d.join(format!("garbage_{t}.bt"));
    std::fs::write(&garbage, b"# Octomap OcTree binary file\nres 0.1\ndata\n").unwrap();
    let e = err(&["anomalies", s(&file), s(&garbage)]);
    assert!(e.contains("garbage_"), "{e}");
    let e = err(&["anomalies", s(&file), s(&d.join("missing_1451865600.bt"))]);
    assert!(e.contains("missing_1451865600.bt"), "{e}");

    // No time anywhere, and a time before the file.
    let unnamed = write(&room(10, 0.1, &|_| false), &d.join("scan.bt"));
    let e = err(&["anomalies", s(&file), s(&unnamed)]);
    assert!(e.contains("scan.bt") && e.contains("--time"), "{e}");
    let e = err(&[
        "anomalies",
        s(&file),
        s(&unnamed),
        "--time",
        "2015-12-31T00:00:00Z",
    ]);
    assert!(
        e.contains("room.froct") && e.contains("before the file's first snapshot"),
        "{e}"
    );
    ok(&[
        "anomalies",
        s(&file),
        s(&unnamed),
        "--time",
        "2016-01-11T10:00:00Z",
    ]);
    // A manifest beside the snapshot that lists it gives its time.
    let listed = d.join("listed");
    std::fs::create_dir(&listed).unwrap();
    let scan = write(&room(10, 0.1, &|_| false), &listed.join("scan.bt"));
    std::fs::write(
        listed.join("manifest.csv"),
        "path,time\nscan.bt,2016-01-11T10:00:00Z\n",
    )
    .unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&ok(&["anomalies", s(&file), s(&scan), "--json"])).unwrap();
    assert_eq!(json["time"], "2016-01-11T10:00:00Z");

    // The output may not be an input; thresholds are checked.
    let e = err(&[
        "anomalies",
        s(&file),
        s(&unnamed),
        "--time",
        "1452506400",
        "-o",
        s(&unnamed),
    ]);
    assert!(e.contains("destroy"), "{e}");
    let before = std::fs::read(&unnamed).unwrap();
    assert_eq!(before, std::fs::read(&unnamed).unwrap());
    let e = err(&[
        "anomalies",
        s(&file),
        s(&unnamed),
        "--time",
        "1452506400",
        "--error-rate",
        "0.7",
    ]);
    assert!(e.contains("error rate"), "{e}");
}
