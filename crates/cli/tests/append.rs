//! `froctomap append` through the binary: the summary, retrieval of every snapshot of both
//! parts, and the refusal of snapshots that are not later than the file.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_core::{Leaf, Snapshot, VoxelKey};
use froctomap_formats::{FormatRegistry, WriteOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::{froctomap, ok, s};

/// A room of 16×16 voxels with a wall and a door closed on every other pair of frames; on
/// odd frames a corner is not observed.
fn frame(i: u32) -> Snapshot {
    let mut leaves = Vec::new();
    for x in 0..16u16 {
        for y in 0..16u16 {
            if i % 2 == 1 && x < 4 && y < 4 {
                continue;
            }
            let wall = x == 15;
            let door = x == 8 && (4..8).contains(&y);
            let occupied = wall || (door && (i / 2) % 2 == 1);
            leaves.push(Leaf::voxel(
                VoxelKey::new(32768 + x, 32768 + y, 32768),
                if occupied { 3.5 } else { -2.0 },
            ));
        }
    }
    Snapshot::from_leaves(0.1, leaves).unwrap()
}

fn write_frames(dir: &Path, frames: std::ops::Range<u32>) -> Vec<(PathBuf, u32)> {
    std::fs::create_dir_all(dir).unwrap();
    let registry = FormatRegistry::with_default_formats();
    frames
        .map(|i| {
            let time = 1_451_865_600 + i * 600;
            let path = dir.join(format!("room_{time}.bt"));
            registry
                .write_file(&frame(i), &path, WriteOptions::default())
                .unwrap();
            (path, time)
        })
        .collect()
}

#[test]
fn append_summarises_and_every_snapshot_comes_back() {
    let dir = tempfile::tempdir().unwrap();
    let mut series = write_frames(&dir.path().join("monday"), 0..4);
    let file = dir.path().join("room.froct");
    ok(&["build", s(&dir.path().join("monday")), "-o", s(&file)]);
    let before = std::fs::metadata(&file).unwrap().len();
    series.extend(write_frames(&dir.path().join("tuesday"), 4..9));
    let out = ok(&["append", s(&file), s(&dir.path().join("tuesday"))]);
    assert!(out.contains("appended 5 snapshots"), "{out}");
    assert!(
        out.contains("2016-01-04T00:00:00Z .. 2016-01-04T01:20:00Z (was .. 2016-01-04T00:30:00Z), 9 samples (was 4)"),
        "{out}"
    );
    let after = std::fs::metadata(&file).unwrap().len();
    assert!(out.contains(&format!("(was {before})")), "{out}");
    assert!(after > 0);
    for (path, time) in &series {
        let back = dir.path().join("back.bt");
        ok(&[
            "retrieve",
            s(&file),
            "--time",
            &time.to_string(),
            "-o",
            s(&back),
        ]);
        assert_eq!(
            std::fs::read(&back).unwrap(),
            std::fs::read(path).unwrap(),
            "{}",
            path.display()
        );
    }
    // JSON report.
    series = write_frames(&dir.path().join("wednesday"), 9..10);
    let json = ok(&[
        "append",
        s(&file),
        s(&dir.path().join("wednesday")),
        "--json",
    ]);
    let report: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(report["added"], 1);
    assert_eq!(report["end"], "2016-01-04T01:30:00Z");
    assert_eq!(series.len(), 1);
}

#[test]
fn snapshots_not_later_than_the_file_are_refused_with_a_hint() {
    let dir = tempfile::tempdir().unwrap();
    write_frames(&dir.path().join("a"), 0..4);
    let file = dir.path().join("room.froct");
    ok(&["build", s(&dir.path().join("a")), "-o", s(&file)]);
    let bytes = std::fs::read(&file).unwrap();
    write_frames(&dir.path().join("b"), 2..6);
    let out = froctomap(&["append", s(&file), s(&dir.path().join("b"))]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains("room_1451867400.bt")
            && stderr.contains("is not after the last sample of")
            && stderr.contains("room.froct")
            && stderr.contains("hint: append takes only snapshots later"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&file).unwrap(), bytes);
    let help = ok(&["append", "--help"]);
    assert!(help.contains("refitted on the whole history"), "{help}");
}

/// The bytes of `file` after appending `inputs` to a copy of it.
fn appended_copy(file: &Path, inputs: &Path, copy: &Path) -> Vec<u8> {
    std::fs::copy(file, copy).unwrap();
    let appended = "--appended=2016-02-01T00:00:00Z";
    ok(&["-q", "append", s(copy), s(inputs), appended]);
    std::fs::read(copy).unwrap()
}

#[test]
fn an_append_killed_at_any_moment_leaves_the_old_file_or_the_new_one() {
    let dir = tempfile::tempdir().unwrap();
    let days = |from: &str, days: &str, out: &Path| {
        ok(&[
            "-q",
            "generate",
            "--start",
            from,
            "--days",
            days,
            "--step",
            "1h",
            "-o",
            s(out),
        ]);
    };
    let first = dir.path().join("first");
    let later = dir.path().join("later");
    days("2016-01-04T00:00:00Z", "1", &first);
    days("2016-01-05T00:00:00Z", "1", &later);
    let file = dir.path().join("office.froct");
    ok(&[
        "-q",
        "build",
        s(&first),
        "-o",
        s(&file),
        "--created=2016-01-06T00:00:00Z",
    ]);
    let old = std::fs::read(&file).unwrap();
    let new = appended_copy(&file, &later, &dir.path().join("copy.froct"));
    assert_ne!(old, new);
    for delay_ms in [5, 100, 400, 1500] {
        std::fs::write(&file, &old).unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_froctomap"))
            .args(["-q", "append", s(&file), s(&later)])
            .arg("--appended=2016-02-01T00:00:00Z")
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = child.kill();
        child.wait().unwrap();
        let now = std::fs::read(&file).unwrap();
        assert!(
            now == old || now == new,
            "killed after {delay_ms} ms: a third file"
        );
    }
}

#[test]
fn format_2_0_appends_a_segment_per_call_and_converts_only_when_told() {
    let dir = tempfile::tempdir().unwrap();
    let series = write_frames(&dir.path().join("a"), 0..9);
    let file = dir.path().join("room.froct");
    let part = |name: &str, range: std::ops::Range<usize>| {
        let part = dir.path().join(name);
        std::fs::create_dir_all(&part).unwrap();
        for (path, _) in &series[range] {
            std::fs::rename(path, part.join(path.file_name().unwrap())).unwrap();
        }
        part
    };
    let first = part("first", 0..4);
    ok(&["build", s(&first), "-o", s(&file)]);
    // A 1.x file converted when told, and said so on stderr.
    let out = froctomap(&[
        "append",
        s(&file),
        s(&part("second", 4..6)),
        "--format-version",
        "2.0",
    ]);
    assert!(out.status.success(), "{out:?}");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains("converting") && stderr.contains("format 2.0"),
        "{stderr}"
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(
        stdout.contains("appended 2 snapshots") && stdout.contains("as segment 1"),
        "{stdout}"
    );
    // A 2.0 file gets a segment without being told.
    let json = ok(&["append", s(&file), s(&part("third", 6..9)), "--json"]);
    let report: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        (report["added"].as_u64(), report["segments"].as_u64()),
        (Some(3), Some(2))
    );
    assert_eq!(report["samples"], 9);
    let reader = froctomap_file::LivingReader::open(&file).unwrap();
    assert_eq!(reader.segment_count(), 2);
    let formats = FormatRegistry::with_default_formats();
    for (i, (path, _)) in series.iter().enumerate() {
        let moved = ["first", "second", "third"]
            .iter()
            .map(|d| dir.path().join(d).join(path.file_name().unwrap()))
            .find(|p| p.exists())
            .unwrap();
        let input = formats
            .read_file(&moved, froctomap_formats::ReadOptions::default())
            .unwrap()
            .map
            .snapshot;
        let leaves = reader
            .observed_states(i as u32)
            .unwrap()
            .into_iter()
            .map(|(start, depth, state)| Leaf {
                start,
                depth,
                log_odds: state.log_odds(),
            })
            .collect();
        let got = Snapshot::from_leaves(0.1, leaves).unwrap();
        assert!(got.same_voxel_states(&input), "sample {i}");
    }
    // Plain append on a 1.x file keeps rebuilding it.
    let plain = dir.path().join("plain.froct");
    ok(&["build", s(&first), "-o", s(&plain)]);
    let out = ok(&["append", s(&plain), s(&dir.path().join("second"))]);
    assert!(!out.contains("segment"), "{out}");
    assert!(froctomap_file::FroctReader::open(&plain).is_ok());
}
