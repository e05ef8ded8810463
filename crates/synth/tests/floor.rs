//! The entropy floor's exact terms against an independent count on written snapshots: the
//! flips and the partial views are read back from the `.bt` files through the codec and
//! compared with the ground truth, never taken from the generator's internals.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use froctomap_core::{MortonCode, Occupancy, Snapshot, Timestamp, VoxelKey};
use froctomap_formats::{FormatRegistry, ReadOptions};
use froctomap_synth::{write_series, Generator, SeriesSpec, WriteSeriesOptions};
use std::collections::HashMap;

/// Occupied voxels with a free face neighbour and free voxels with an occupied one,
/// voxel by voxel.
fn surface(base: &Snapshot) -> Vec<MortonCode> {
    let states: HashMap<(i32, i32, i32), Occupancy> = base
        .voxels()
        .map(|(c, s)| {
            let k = c.key();
            ((i32::from(k.x), i32::from(k.y), i32::from(k.z)), s)
        })
        .collect();
    let mut out = Vec::new();
    for (&(x, y, z), &state) in &states {
        let neighbours = [
            (x - 1, y, z),
            (x + 1, y, z),
            (x, y - 1, z),
            (x, y + 1, z),
            (x, y, z - 1),
            (x, y, z + 1),
        ];
        let other = !state;
        if neighbours.iter().any(|n| states.get(n) == Some(&other)) {
            out.push(VoxelKey::new(x as u16, y as u16, z as u16).morton());
        }
    }
    out
}

#[test]
fn noise_and_partial_terms_match_the_written_snapshots() {
    let p = 0.004;
    let q = 0.4;
    let spec = SeriesSpec {
        start: Timestamp::from_secs(1_451_894_400), // Monday 08:00 UTC
        count: 12,
        step_secs: 900.0,
        surface_noise: p,
        partial_probability: q,
        partial_extent: 0.3,
        ..SeriesSpec::default()
    };
    let base = common::office();
    let generator = Generator::new(&base, spec, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let formats = FormatRegistry::with_default_formats();
    let manifest = write_series(
        &formats,
        &generator,
        dir.path(),
        &WriteSeriesOptions::default(),
        &|_, _| {},
    )
    .unwrap();
    let candidates = surface(&base);
    let known: Vec<MortonCode> = base.voxels().map(|(c, _)| c).collect();
    // The partial view's box spans 30 % of the known extent on x and y.
    let extent = |axis: fn(&VoxelKey) -> u16| {
        let values = known.iter().map(|c| axis(&c.key()));
        let (lo, hi) = (values.clone().min().unwrap(), values.max().unwrap());
        let extent = f64::from(hi - lo + 1);
        extent - (extent * 0.3).round() + 1.0
    };
    let positions = extent(|k| k.x).log2() + extent(|k| k.y).log2();

    let (mut noise_bits, mut flips_total, mut observed_total, mut partial_bits) =
        (0.0f64, 0u64, 0u64, 0.0f64);
    let mut partial_frames = 0;
    for entry in &manifest.entries {
        let index = entry.index.unwrap();
        let seen = formats
            .read_file(&dir.path().join(&entry.path), ReadOptions::default())
            .unwrap()
            .map
            .snapshot;
        let truth = generator.truth_frame(index).unwrap();
        let hidden = known.iter().any(|&c| seen.state_at(c).is_none());
        partial_frames += usize::from(hidden);
        partial_bits += if hidden {
            -q.log2() + positions
        } else {
            -(1.0 - q).log2()
        };
        let observed: Vec<MortonCode> = candidates
            .iter()
            .copied()
            .filter(|&c| seen.state_at(c).is_some())
            .collect();
        let flips = observed
            .iter()
            .filter(|&&c| seen.state_at(c) != truth.state_at(c))
            .count() as u64;
        // Every observed change against the truth is a flip of a candidate.
        let changed = known
            .iter()
            .filter(|&&c| {
                seen.state_at(c)
                    .is_some_and(|s| Some(s) != truth.state_at(c))
            })
            .count() as u64;
        assert_eq!(
            changed, flips,
            "frame {index}: a change outside the surface"
        );
        let n = observed.len() as u64;
        noise_bits += flips as f64 * -p.log2() + (n - flips) as f64 * -(1.0 - p).log2();
        flips_total += flips;
        observed_total += n;
    }
    assert!(partial_frames > 0 && partial_frames < manifest.entries.len());
    assert!(flips_total > 0);

    let floor = generator.entropy_floor(0..12);
    assert_eq!(floor.frames, 12);
    assert_eq!(floor.noise_flips, flips_total);
    assert_eq!(floor.noise_observed_candidates, observed_total);
    assert!(
        (floor.noise_bits - noise_bits).abs() < 1e-9 * noise_bits,
        "{} vs {noise_bits}",
        floor.noise_bits
    );
    assert!(
        (floor.partial_bits - partial_bits).abs() < 1e-9 * partial_bits,
        "{} vs {partial_bits}",
        floor.partial_bits
    );
    // The expectation is close to the realisation.
    let h = -p * p.log2() - (1.0 - p) * (1.0 - p).log2();
    assert!((floor.noise_expected_bits - observed_total as f64 * h).abs() < 1e-6);
    // Missed frames and jitter are off.
    assert_eq!(floor.timing_bits, 0.0);
    assert!(floor.total_bits() > floor.noise_bits + floor.partial_bits);
}

#[test]
fn a_quiet_series_has_only_schedule_bits_and_more_frames_cost_more() {
    let spec = SeriesSpec {
        count: 144,
        surface_noise: 0.0,
        partial_probability: 0.0,
        ..SeriesSpec::default()
    };
    let generator = Generator::new(&common::office(), spec, None).unwrap();
    let floor = generator.entropy_floor(0..144);
    assert_eq!((floor.noise_bits, floor.partial_bits), (0.0, 0.0));
    assert_eq!(floor.noise_observed_candidates, 0);
    // Monday 00:00 to 08:00 every 10 minutes: nobody is in before 08:00, so the day's
    // draws are not visible yet; a whole day shows them.
    let night = generator.entropy_floor(0..48);
    let day = generator.entropy_floor(0..144);
    assert!(day.schedule_bits() > night.schedule_bits());
    assert!(day.people_bits > 0.0 && day.chair_bits > 0.0);
    // Clamped to the series.
    assert_eq!(generator.entropy_floor(140..1000).frames, 4);
}
