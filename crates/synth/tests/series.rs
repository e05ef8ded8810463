//! Writing a series through the format registry and reading it back.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use froctomap_core::calendar::iso8601_basic;
use froctomap_core::{Occupancy, Timestamp};
use froctomap_formats::{FormatRegistry, ReadOptions};
use froctomap_synth::{
    write_series, Generator, SeriesManifest, SeriesSpec, SynthError, WriteSeriesOptions,
    MANIFEST_NAME,
};
use std::sync::atomic::{AtomicU64, Ordering};

fn formats() -> FormatRegistry {
    FormatRegistry::with_default_formats()
}

#[test]
fn twenty_frames_round_trip_through_the_registry() {
    let spec = SeriesSpec {
        start: Timestamp::from_secs(1_451_894_400), // Monday 08:00 UTC, people about
        count: 24,
        step_secs: 900.0,
        jitter_secs: 30.0,
        missed_frames: 0.15,
        surface_noise: 0.005,
        partial_probability: 0.2,
        door_file: Some(common::door_file()),
        ..SeriesSpec::default()
    };
    let generator = Generator::new(&common::office(), spec, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("series");
    let calls = AtomicU64::new(0);
    let options = WriteSeriesOptions {
        threads: 2,
        ..WriteSeriesOptions::default()
    };
    let manifest = write_series(&formats(), &generator, &out, &options, &|done, total| {
        calls.fetch_add(1, Ordering::Relaxed);
        assert!(done <= total);
    })
    .unwrap();
    let present: Vec<_> = generator.frames().collect();
    assert!(
        present.len() < 24 && present.len() >= 15,
        "{}",
        present.len()
    );
    assert_eq!(manifest.entries.len(), present.len());
    assert!(calls.load(Ordering::Relaxed) >= 1);

    let registry = FormatRegistry::with_default_formats();
    let mut total = 0;
    for (entry, frame) in manifest.entries.iter().zip(&present) {
        assert_eq!(entry.index, Some(frame.index));
        assert_eq!(entry.time, frame.time);
        assert_eq!(
            entry.path.to_str().unwrap(),
            format!("frame_{}.bt", iso8601_basic(frame.time))
        );
        let path = out.join(&entry.path);
        assert_eq!(std::fs::metadata(&path).unwrap().len(), entry.bytes);
        total += entry.bytes;
        let read = registry.read_file(&path, ReadOptions::default()).unwrap();
        assert_eq!(read.format.name, "bt");
        let expected = generator.frame(frame.index).unwrap();
        assert!(
            read.map.snapshot.same_voxel_states(&expected),
            "{} differs from frame {}",
            entry.path.display(),
            frame.index
        );
    }
    assert_eq!(total, manifest.total_bytes);
    // Something dynamic really is in the files: people at 08:00-14:00 on a Monday.
    assert!(manifest.changes.people > 0 && manifest.changes.noise > 0);

    // The manifest on disk says the same, in the agreed format.
    let text = std::fs::read_to_string(out.join(MANIFEST_NAME)).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("path,time"));
    let first = lines.next().unwrap();
    let (name, secs) = first.split_once(',').unwrap();
    assert_eq!(name, manifest.entries[0].path.to_str().unwrap());
    let secs: f64 = secs.parse().unwrap();
    assert!((secs - manifest.entries[0].time.as_secs_f64()).abs() < 1e-6);
    let read_back = SeriesManifest::read(&out.join(MANIFEST_NAME)).unwrap();
    assert_eq!(read_back.dir, out);
    let pairs = |m: &SeriesManifest| -> Vec<_> {
        m.entries.iter().map(|e| (e.path.clone(), e.time)).collect()
    };
    assert_eq!(pairs(&read_back), pairs(&manifest));
    // No temporary files left behind.
    let files = std::fs::read_dir(&out).unwrap().count();
    assert_eq!(files, present.len() + 1);
}

#[test]
fn bad_options_fail_before_writing() {
    let generator = Generator::new(
        &common::office(),
        SeriesSpec {
            count: 3,
            ..SeriesSpec::default()
        },
        None,
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let bad_pattern = WriteSeriesOptions {
        file_pattern: "frame.bt".into(),
        ..WriteSeriesOptions::default()
    };
    assert!(matches!(
        write_series(&formats(), &generator, dir.path(), &bad_pattern, &|_, _| {}),
        Err(SynthError::InvalidPattern { .. })
    ));
    let bad_format = WriteSeriesOptions {
        format: "png".into(),
        ..WriteSeriesOptions::default()
    };
    let err =
        write_series(&formats(), &generator, dir.path(), &bad_format, &|_, _| {}).unwrap_err();
    assert!(
        err.to_string().contains("unknown map format `png`"),
        "{err}"
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // `ot` works too and keeps the states.
    let ot = WriteSeriesOptions {
        format: "ot".into(),
        file_pattern: "{index}.{ext}".into(),
        threads: 1,
    };
    let manifest = write_series(&formats(), &generator, dir.path(), &ot, &|_, _| {}).unwrap();
    assert_eq!(manifest.entries[2].path.to_str(), Some("2.ot"));
    let read = FormatRegistry::with_default_formats()
        .read_file(&dir.path().join("2.ot"), ReadOptions::default())
        .unwrap();
    assert!(read
        .map
        .snapshot
        .same_voxel_states(&generator.frame(2).unwrap()));
    let occupied = read.map.snapshot.stats().occupied_voxels;
    assert!(
        occupied > 0
            && read
                .map
                .snapshot
                .state_at(read.map.snapshot.leaves()[0].start)
                .is_some()
    );
    let _ = Occupancy::Free;
}
