//! Anomalies on the synthetic room: objects injected into a held-out snapshot are found as
//! the top region, the clean snapshot has nothing as surprising, bad inputs are refused.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use froctomap_convert::*;
use froctomap_core::{Occupancy, Snapshot, Timestamp, VoxelKey};
use std::path::{Path, PathBuf};

/// A week of hourly frames: enough for the daily rhythm to stand out.
const FRAMES: u32 = 168;
/// Day 4 at 10:00: held out, the door is open.
const HELD_OUT: u32 = FRAMES + 10;

fn in_box(k: VoxelKey, lo: [u16; 3], hi: [u16; 3]) -> bool {
    (lo[0]..hi[0]).contains(&(k.x - ORIGIN))
        && (lo[1]..hi[1]).contains(&(k.y - ORIGIN))
        && (lo[2]..hi[2]).contains(&(k.z - ORIGIN))
}

/// The box's metric corners.
fn corners(lo: [u16; 3], hi: [u16; 3]) -> ([f64; 3], [f64; 3]) {
    (
        lo.map(|v| f64::from(v) * RESOLUTION),
        hi.map(|v| f64::from(v) * RESOLUTION),
    )
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-9)
}

struct Room {
    _dir: tempfile::TempDir,
    dir: PathBuf,
    context: Context,
    file: PathBuf,
}

fn room() -> Room {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let (file, _) = build_room(&context, dir.path(), FRAMES);
    Room {
        dir: dir.path().to_path_buf(),
        _dir: dir,
        context,
        file,
    }
}

impl Room {
    fn score(&self, name: &str, map: &Snapshot) -> AnomalyReport {
        let held_out = self.dir.join("held-out");
        std::fs::create_dir_all(&held_out).unwrap();
        let path = write_frame(&self.context, &held_out, HELD_OUT, map);
        let named = held_out.join(name);
        std::fs::rename(&path, &named).unwrap();
        let reader = self.context.open_froct(&self.file).unwrap();
        let snapshot = read_snapshot(&self.context, &reader, &named).unwrap();
        anomalies(
            &reader,
            &snapshot,
            time(HELD_OUT),
            &AnomalyOptions::default(),
        )
        .unwrap()
    }
}

#[test]
fn injected_objects_are_the_top_regions() {
    let room = room();
    let clean = room.score("clean.bt", &frame(HELD_OUT));
    assert!(clean.scored_voxels > 10_000);

    // A 4×4×4 box standing on the floor in free space.
    let (lo, hi) = ([5, 5, 1], [9, 9, 5]);
    let boxed = frame_with(HELD_OUT, |k, s| {
        Some(if in_box(k, lo, hi) {
            Occupancy::Occupied
        } else {
            s
        })
    });
    let report = room.score("box.bt", &boxed);
    let top = &report.regions[0];
    assert_eq!(
        (top.kind, top.voxels),
        (AnomalyKind::Appeared, 64),
        "{report:#?}"
    );
    let (min, max) = corners(lo, hi);
    assert!(close(top.min, min) && close(top.max, max), "{top:?}");
    for region in &clean.regions {
        assert!(region.score < top.score, "clean {region:?} vs box {top:?}");
    }

    // The door closed at 10:00, when it was open every day of the training.
    assert!(door_open_at(time(HELD_OUT)));
    let closed = frame_with(HELD_OUT, |k, s| {
        Some(if is_door(k) { Occupancy::Occupied } else { s })
    });
    let report = room.score("door.bt", &closed);
    let top = &report.regions[0];
    assert_eq!(
        (top.kind, top.voxels),
        (AnomalyKind::Appeared, 6 * 9),
        "{report:#?}"
    );
    let (min, max) = corners([12, 0, 1], [18, 1, 10]);
    assert!(close(top.min, min) && close(top.max, max), "{top:?}");
    for region in &clean.regions {
        assert!(region.score < top.score, "clean {region:?} vs door {top:?}");
    }

    // A hole in a wall vanished, and something outside the room, where nothing was ever
    // seen, appeared (the room's snapshot plus voxels beyond its walls).
    let holed = frame_with(HELD_OUT, |k, s| {
        Some(if in_box(k, [SIDE - 1, 10, 2], [SIDE, 14, 6]) {
            Occupancy::Free
        } else {
            s
        })
    });
    let mut leaves = holed.leaves().to_vec();
    for x in 0..3 {
        for z in 0..3 {
            let k = VoxelKey::new(ORIGIN + 40 + x, ORIGIN + 3, ORIGIN + z);
            leaves.push(froctomap_core::Leaf::voxel(
                k,
                Occupancy::Occupied.log_odds(),
            ));
        }
    }
    let map = Snapshot::from_leaves(RESOLUTION, leaves)
        .unwrap()
        .canonical();
    let report = room.score("hole.bt", &map);
    let kinds: Vec<(AnomalyKind, u64)> =
        report.regions.iter().map(|r| (r.kind, r.voxels)).collect();
    assert!(kinds.contains(&(AnomalyKind::Vanished, 16)), "{kinds:?}");
    assert!(kinds.contains(&(AnomalyKind::Appeared, 9)), "{kinds:?}");
    // The anomalous voxels as a map: exactly the regions' voxels, all occupied.
    let anomalous = report.to_map(RESOLUTION).unwrap();
    let stats = anomalous.stats();
    let total: u64 = report.regions.iter().map(|r| r.voxels).sum();
    assert_eq!((stats.occupied_voxels, stats.free_voxels), (total, 0));
}

#[test]
fn the_hour_matters() {
    // The same closed door at 03:00, when it was closed every night, is no anomaly.
    let room = room();
    let night = FRAMES + 3;
    assert!(!door_open_at(time(night)));
    let reader = room.context.open_froct(&room.file).unwrap();
    let report = anomalies(
        &reader,
        &frame(night),
        time(night),
        &AnomalyOptions::default(),
    )
    .unwrap();
    assert!(report.regions.is_empty(), "{report:#?}");
    // Opened at night, it is.
    let opened = frame_with(night, |k, s| {
        Some(if is_door(k) { Occupancy::Free } else { s })
    });
    let report = anomalies(&reader, &opened, time(night), &AnomalyOptions::default()).unwrap();
    assert_eq!(report.regions.len(), 1, "{report:#?}");
    assert_eq!(report.regions[0].kind, AnomalyKind::Vanished);

    // The baselines cannot tell: the door is as often closed as open on average, and it
    // was closed in the last snapshot (23:00); both see the day's closed door at 10:00
    // as nothing new. Against the last seen map the open door at 10:00 is a change.
    let day = FRAMES + 10;
    let closed = frame_with(day, |k, s| {
        Some(if is_door(k) { Occupancy::Occupied } else { s })
    });
    for expectation in [
        Expectation::Model,
        Expectation::StaticMean,
        Expectation::LastSeen,
    ] {
        let mut options = AnomalyOptions::default();
        options.expectation = expectation;
        let found = anomalies(&reader, &closed, time(day), &options).unwrap();
        assert_eq!(
            found.regions.len(),
            usize::from(expectation == Expectation::Model),
            "{expectation:?}: {found:#?}"
        );
        let open = anomalies(&reader, &frame(day), time(day), &options).unwrap();
        assert_eq!(
            open.regions.len(),
            usize::from(expectation == Expectation::LastSeen),
            "{expectation:?}: {open:#?}"
        );
    }
}

#[test]
fn bad_inputs_are_refused_naming_the_file() {
    let room = room();
    let reader = room.context.open_froct(&room.file).unwrap();
    let dir = room.dir.join("bad");
    std::fs::create_dir_all(&dir).unwrap();

    // Another resolution.
    let coarse = Snapshot::from_leaves(
        0.2,
        vec![froctomap_core::Leaf::voxel(
            VoxelKey::new(ORIGIN, ORIGIN, ORIGIN),
            1.0,
        )],
    )
    .unwrap();
    let path = dir.join("coarse.bt");
    room.context
        .formats()
        .write_file(&coarse, &path, Default::default())
        .unwrap();
    let err = read_snapshot(&room.context, &reader, &path).unwrap_err();
    assert!(
        matches!(err, ConvertError::SnapshotResolution { .. }),
        "{err}"
    );
    let text = err.to_string();
    assert!(
        text.contains("coarse.bt") && text.contains("0.2") && text.contains("room.froct"),
        "{text}"
    );
    let err = anomalies(&reader, &coarse, time(HELD_OUT), &AnomalyOptions::default()).unwrap_err();
    assert!(
        matches!(err, ConvertError::SnapshotResolution { .. }),
        "{err}"
    );

    // Unreadable: garbage, empty, missing, a directory.
    let garbage = dir.join("garbage.bt");
    std::fs::write(&garbage, b"# Octomap OcTree binary file\nnonsense").unwrap();
    let empty = dir.join("empty.bt");
    std::fs::write(&empty, b"").unwrap();
    for path in [garbage, empty, dir.join("missing.bt"), dir.clone()] {
        let err = read_snapshot(&room.context, &reader, &path).unwrap_err();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let err = froctomap_core::error_message(&err);
        assert!(err.contains(&name), "{}: {err}", path.display());
    }

    // A time before the file, or outside what froctomap accepts.
    let map = frame(HELD_OUT);
    let before = Timestamp(time(0).0 - 1);
    let err = anomalies(&reader, &map, before, &AnomalyOptions::default()).unwrap_err();
    assert!(
        matches!(err, ConvertError::AnomalyTimeBeforeFile { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("room.froct"), "{err}");
    let err = anomalies(
        &reader,
        &map,
        Timestamp(i64::MAX),
        &AnomalyOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(err, ConvertError::BadTime(_)), "{err}");

    // Options out of range.
    let mut options = AnomalyOptions::default();
    options.error_rate = 0.0;
    let err = anomalies(&reader, &map, time(HELD_OUT), &options).unwrap_err();
    assert!(
        matches!(err, ConvertError::BadAnomalyOption { .. }),
        "{err}"
    );
    assert!(Path::new(&room.file).exists());
}
