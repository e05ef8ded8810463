//! Frames are a pure function of (spec, base, index): deterministic, random-access, valid,
//! on a strictly increasing time axis with the requested gaps and jitter.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use froctomap_core::Timestamp;
use froctomap_synth::{Generator, SeriesSpec, SynthError};

fn spec(seed: u64) -> SeriesSpec {
    SeriesSpec {
        seed,
        count: 60,
        step_secs: 1800.0,
        start: Timestamp::from_secs(1_451_890_800), // Monday 07:00 UTC
        surface_noise: 0.01,
        partial_probability: 0.2,
        ..SeriesSpec::default()
    }
}

#[test]
fn same_seed_same_frames_other_seed_other_frames() {
    let base = common::office();
    let a = Generator::new(&base, spec(5), None).unwrap();
    let b = Generator::new(&base, spec(5), None).unwrap();
    let c = Generator::new(&base, spec(6), None).unwrap();
    assert_eq!(a.elements(), b.elements());
    assert_ne!(a.elements(), c.elements());
    let mut differing = 0;
    for i in (0..60).step_by(7) {
        let fa = a.frame(i).unwrap();
        assert_eq!(fa, b.frame(i).unwrap(), "frame {i}");
        if !fa.same_voxel_states(&c.frame(i).unwrap()) {
            differing += 1;
        }
    }
    assert!(
        differing >= 8,
        "only {differing} frames differ between seeds"
    );
}

#[test]
fn random_access_equals_sequential_and_frames_are_valid() {
    let base = common::office();
    let generator = Generator::new(&base, spec(11), None).unwrap();
    let sequential: Vec<_> = generator
        .frames()
        .map(|f| (f.index, generator.frame(f.index).unwrap()))
        .collect();
    assert_eq!(sequential.len(), 60);
    // Backwards, from a fresh generator: nothing depends on what was generated before.
    let fresh = Generator::new(&base, spec(11), None).unwrap();
    for (index, frame) in sequential.iter().rev() {
        assert_eq!(&fresh.frame(*index).unwrap(), frame);
    }
    let base_stats = base.stats();
    let base_known = base_stats.free_voxels + base_stats.occupied_voxels;
    for (index, frame) in &sequential {
        assert_eq!(frame.resolution(), base.resolution());
        // A valid snapshot: rebuilding it from its leaves passes every check.
        let rebuilt =
            froctomap_core::Snapshot::from_leaves(frame.resolution(), frame.leaves().to_vec())
                .unwrap();
        assert_eq!(&rebuilt, frame);
        let stats = frame.stats();
        let known = stats.free_voxels + stats.occupied_voxels;
        if generator.unobserved_region(*index).is_none() {
            assert_eq!(known, base_known, "frame {index} changed the known space");
        } else {
            assert!(known < base_known, "partial frame {index} hides nothing");
        }
    }
    assert!(matches!(
        generator.frame(60),
        Err(SynthError::FrameOutOfRange {
            index: 60,
            count: 60
        })
    ));
}

#[test]
fn missed_frames_are_absent_and_jitter_stays_in_bounds() {
    let base = common::office();
    let spec = SeriesSpec {
        count: 2000,
        step_secs: 60.0,
        jitter_secs: 20.0,
        missed_frames: 0.25,
        doors: 0,
        people: 1,
        chairs: 0,
        objects: 0,
        machines: 0,
        ..SeriesSpec::default()
    };
    let generator = Generator::new(&base, spec.clone(), None).unwrap();
    let frames: Vec<_> = generator.frames().collect();
    let missed = 2000 - frames.len();
    assert!((400..600).contains(&missed), "{missed} of 2000 missed");
    assert!(frames
        .windows(2)
        .all(|w| w[0].time < w[1].time && w[0].index < w[1].index));
    let mut jittered = 0;
    for f in &frames {
        let grid = spec.start.0 + 60_000_000_000 * f.index as i64;
        let offset = f.time.0 - grid;
        assert!(
            offset.abs() <= 20_000_000_000,
            "frame {} off by {offset} ns",
            f.index
        );
        jittered += usize::from(offset != 0);
    }
    assert!(jittered > frames.len() * 9 / 10);
    let present: std::collections::HashSet<u64> = frames.iter().map(|f| f.index).collect();
    let mut checked = 0;
    for index in (0..2000).filter(|i| !present.contains(i)).take(5) {
        assert!(generator.is_missed(index));
        assert!(matches!(
            generator.frame(index),
            Err(SynthError::MissedFrame { .. })
        ));
        // The world still has a state then.
        generator.truth_frame(index).unwrap();
        checked += 1;
    }
    assert_eq!(checked, 5);
    // A regular grid without jitter hits the grid exactly.
    let regular = Generator::new(
        &base,
        SeriesSpec {
            count: 10,
            ..SeriesSpec::default()
        },
        None,
    )
    .unwrap();
    let times: Vec<i64> = regular.frames().map(|f| f.time.0).collect();
    let expected: Vec<i64> = (0..10)
        .map(|i| 1_451_865_600_000_000_000 + i * 600_000_000_000)
        .collect();
    assert_eq!(times, expected);
}

/// A run resumed from a time (`generate --from`) makes exactly the maps, bytes and times
/// that a run from the start makes from that time on, with jitter and missed frames, from
/// times on a frame, between frames and before the series.
#[test]
fn a_run_resumed_from_a_time_continues_the_same_series() {
    use froctomap_formats::FormatRegistry;
    let base = common::office();
    let spec = SeriesSpec {
        jitter_secs: 600.0,
        missed_frames: 0.2,
        ..spec(13)
    };
    let formats = FormatRegistry::with_default_formats();
    let encoded = |generator: &Generator| {
        let mut maps = Vec::new();
        froctomap_synth::encode_series(
            &formats,
            generator,
            "bt",
            0,
            &|_, _| {},
            &mut |frame, bytes, _| {
                maps.push((frame.index, frame.time, bytes));
                Ok(())
            },
        )
        .unwrap();
        maps
    };
    let whole = encoded(&Generator::new(&base, spec.clone(), None).unwrap());
    assert!(
        whole.len() < 60 && whole.len() > 30,
        "{} frames",
        whole.len()
    );
    let on_a_frame = whole[whole.len() / 2].1;
    let between_frames = Timestamp(whole[whole.len() / 3].1 .0 + 1);
    let before = Timestamp(spec.start.0 - 3_600_000_000_000);
    for from in [on_a_frame, between_frames, before, whole[0].1] {
        let resumed = encoded(
            &Generator::new(&base, spec.clone(), None)
                .unwrap()
                .with_frames_from(from),
        );
        let expected: Vec<_> = whole.iter().filter(|m| m.1 >= from).cloned().collect();
        assert!(!expected.is_empty());
        assert_eq!(resumed.len(), expected.len(), "from {from:?}");
        assert!(resumed == expected, "from {from:?}: other maps");
    }
    let after = Timestamp(whole[whole.len() - 1].1 .0 + 1);
    let none = Generator::new(&base, spec, None)
        .unwrap()
        .with_frames_from(after);
    assert_eq!(none.frames().count(), 0);
}
