//! The real base map: elements find doorways and floor in the FR-079 corridor scan, doors
//! follow the real door series, and frames are quick to make.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use froctomap_core::Occupancy;
use froctomap_synth::{DoorDriver, ElementKind, Generator, SeriesSpec};

#[test]
fn geb079_series_with_real_doors() {
    let base = common::geb079();
    let raw = common::raw_door_states(&common::door_file());
    let spec = SeriesSpec {
        door_file: Some(common::door_file()),
        surface_noise: 0.0,
        partial_probability: 0.0,
        ..SeriesSpec::with_duration(14.0, 600.0)
    };
    let generator = Generator::new(&base, spec, None).unwrap();
    assert!(
        generator.warnings().is_empty(),
        "{:?}",
        generator.warnings()
    );
    let summary = generator.change_summary();
    for kind in &summary.kinds {
        assert_eq!(kind.placed, kind.requested, "{kind:?}");
    }
    let elements = generator.elements();
    // Everything stands in the scanned building: inside the corridor's bounds, at floor
    // level (the floor of geb079 is at about 0 m), and on base free space.
    for e in &elements {
        for &v in &e.voxels {
            assert_eq!(
                base.state_at(v),
                Some(Occupancy::Free),
                "{} {}",
                e.kind,
                e.index
            );
            let [x, y, z] = v.key().center(0.08);
            assert!(
                (-8.0..31.0).contains(&x) && (-7.6..7.5).contains(&y),
                "{x} {y}"
            );
            assert!((-0.1..2.2).contains(&z), "{} {} at z {z}", e.kind, e.index);
        }
    }
    // Real doors: open in the recording <=> slab free, for frames at recorded minutes.
    let door0 = elements
        .iter()
        .find(|e| e.door_driver == Some(DoorDriver::Real { offset_weeks: 0 }))
        .unwrap();
    let mut seen = [false; 2];
    for f in generator.frames().step_by(97) {
        let Some(&open) = raw.get(&(f.time.0.div_euclid(60_000_000_000) * 60)) else {
            continue;
        };
        let frame = generator.frame(f.index).unwrap();
        let want = Occupancy::from(!open);
        assert!(door0
            .voxels
            .iter()
            .all(|&v| frame.state_at(v) == Some(want)));
        seen[usize::from(open)] = true;
    }
    assert_eq!(seen, [true, true], "both door states seen");
    // Partial views and noise on: a frame still differs from the base only where elements,
    // noise and the unobserved region are.
    let noisy = Generator::new(
        &base,
        SeriesSpec {
            surface_noise: 0.001,
            partial_probability: 0.5,
            ..generator.spec().clone()
        },
        None,
    )
    .unwrap();
    let (frame, stats) = noisy.frame_with_stats(60).unwrap();
    assert_eq!(frame.resolution(), 0.08);
    assert!(stats.noise > 50 && stats.noise < 1000, "{stats:?}");
    let elements_now: u64 = ElementKind::ALL.iter().map(|&k| stats.of(k)).sum();
    assert!(elements_now > 0);
}
