//! Point queries against maps read back by the codec: a voxel's observed states from
//! `voxel_history` are the input snapshots' states at each sample, and `probabilities` are
//! the predicted map's.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use froctomap_convert::*;
use froctomap_core::{Timestamp, VoxelKey};
use froctomap_formats::ReadOptions;

const FRAMES: u32 = 72;

fn centre(k: VoxelKey) -> [f64; 3] {
    k.center(RESOLUTION)
}

#[test]
fn histories_and_probabilities_agree_with_the_maps() {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let (file, inputs) = build_room(&context, dir.path(), FRAMES);
    let reader = context.open_froct(&file).unwrap();
    let maps: Vec<_> = inputs
        .iter()
        .map(|p| {
            context
                .formats()
                .read_file(p, ReadOptions::default())
                .unwrap()
                .map
                .snapshot
        })
        .collect();

    let door = VoxelKey::new(ORIGIN + 14, ORIGIN, ORIGIN + 5);
    let wall = VoxelKey::new(ORIGIN, ORIGIN + 5, ORIGIN + 5);
    let inside = VoxelKey::new(ORIGIN + 5, ORIGIN + 5, ORIGIN + 5);
    let corner = VoxelKey::new(ORIGIN + 28, ORIGIN + 28, ORIGIN + 5);
    for key in [door, wall, inside, corner] {
        let history = voxel_history(&reader, centre(key), None).unwrap();
        assert_eq!(history.samples.len(), FRAMES as usize);
        assert_eq!(history.cell.key, key);
        for a in 0..3 {
            assert!(history.cell.min[a] <= centre(key)[a] && centre(key)[a] <= history.cell.max[a]);
        }
        let mut unknown = 0;
        for (s, map) in history.samples.iter().zip(&maps) {
            assert_eq!(s.time, time(s.sample));
            assert_eq!(s.state, map.state_at(key.morton()), "{key} at {}", s.sample);
            assert!((0.0..=1.0).contains(&s.p));
            unknown += usize::from(s.state.is_none());
        }
        // The hidden corner is unknown on every seventh frame, and says so.
        let hidden = if key == corner {
            (FRAMES as usize + 3) / 7
        } else {
            0
        };
        assert_eq!(unknown, hidden, "{key}");
        assert_eq!(history.sometimes_unknown, key == corner);
        // Outliers: exactly the observed samples where the state is not the model's.
        let expected: Vec<u32> = history
            .samples
            .iter()
            .filter(|s| s.state.is_some_and(|st| st.is_occupied() != (s.p > 0.5)))
            .map(|s| s.sample)
            .collect();
        let got: Vec<u32> = history.outliers.iter().map(|s| s.sample).collect();
        assert_eq!(got, expected);
    }
    let door_history = voxel_history(&reader, centre(door), None).unwrap();
    assert_eq!(door_history.class, CellClass::Dynamic);
    let description = door_history.model.as_ref().unwrap();
    assert!((0.5..0.7).contains(&description.mean), "{description:?}"); // closed 14 h of 24
    assert!(
        description
            .periodic
            .iter()
            .any(|t| (t.period_seconds - 86_400.0).abs() < 1.0),
        "{description:?}"
    );
    assert_eq!(
        voxel_history(&reader, centre(wall), None).unwrap().class,
        CellClass::StaticOccupied
    );
    assert_eq!(
        voxel_history(&reader, centre(inside), None).unwrap().class,
        CellClass::StaticFree
    );

    // Probabilities: the predicted map's, inside and beyond the span; NaN without a cell.
    let outside_room = VoxelKey::new(ORIGIN + 100, ORIGIN, ORIGIN);
    let points = [
        centre(door),
        centre(wall),
        [1e9, 0.0, 0.0],
        centre(outside_room),
        centre(inside),
    ];
    for t in [
        time(10),
        time(FRAMES + 40),
        Timestamp(time(3).0 + 1_234_567_890),
    ] {
        let p = probabilities(&reader, t, &points).unwrap();
        let predicted = predicted_map(&reader, t).unwrap();
        for (point, p) in points.iter().zip(&p) {
            let code = VoxelKey::from_point(*point, RESOLUTION).map(|k| k.morton());
            match code.and_then(|c| predicted.leaf_at(c)) {
                Some(leaf) => {
                    assert!((0.0..=1.0).contains(p), "{p}");
                    assert_eq!(probability_log_odds(*p), leaf.log_odds, "{point:?}");
                }
                None => assert!(p.is_nan(), "{point:?}: {p}"),
            }
        }
        assert_eq!((p[1], p[4]), (1.0, 0.0));
    }
    // At the samples, the model's p of the history.
    for s in door_history.samples.iter().step_by(5) {
        let p = probabilities(&reader, s.time, &[centre(door)]).unwrap()[0];
        assert!((p - s.p).abs() < 1e-6, "{p} vs {}", s.p);
    }
}

#[test]
fn ranges_and_points_outside_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let (file, _) = build_room(&context, dir.path(), 12);
    let reader = context.open_froct(&file).unwrap();
    let door = centre(VoxelKey::new(ORIGIN + 14, ORIGIN, ORIGIN + 5));

    let some = voxel_history(&reader, door, Some((time(3), Timestamp(time(6).0 + 1)))).unwrap();
    let samples: Vec<u32> = some.samples.iter().map(|s| s.sample).collect();
    assert_eq!(samples, [3, 4, 5, 6]);

    let err = voxel_history(&reader, door, Some((time(20), time(30)))).unwrap_err();
    assert!(
        matches!(err, ConvertError::RangeOutsideAxis { .. }),
        "{err}"
    );
    let text = err.to_string();
    assert!(
        text.contains("room.froct") && text.contains("2016-01-04"),
        "{text}"
    );
    let err = voxel_history(&reader, door, Some((time(6), time(3)))).unwrap_err();
    assert!(matches!(err, ConvertError::EmptyRange { .. }), "{err}");

    for point in [[50.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0], [1e12, 0.0, 0.0]] {
        let err = voxel_history(&reader, point, None).unwrap_err();
        assert!(matches!(err, ConvertError::PointOutsideMap { .. }), "{err}");
        let text = err.to_string();
        assert!(
            text.contains("room.froct") && text.contains("span"),
            "{text}"
        );
    }
}

#[test]
fn series_probabilities_of_a_living_file_follow_its_predicted_map() {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let (built, paths) = build_room(&context, dir.path(), 24);
    // A 1.x file: exactly `probabilities`.
    let flat = context.open_series(&built).unwrap();
    let points: Vec<[f64; 3]> = keys().map(centre).chain([[1e9, 0.0, 0.0]]).collect();
    let t = time(30);
    let bits = |p: Vec<f64>| p.into_iter().map(f64::to_bits).collect::<Vec<_>>();
    assert_eq!(
        bits(series_probabilities(&flat, t, &points).unwrap()),
        bits(probabilities(flat.whole_history().unwrap(), t, &points).unwrap())
    );

    // A 2.0 file with segments: recorded 12 maps at a time.
    let living = dir.path().join("living.froct");
    let options = RecordOptions {
        commit_every: CommitEvery::Maps(12),
        // Kept in segments: what this test reads.
        compact: froctomap_convert::Compaction::Off,
        ..RecordOptions::default()
    };
    let mut recorder = Recorder::open(&context, &living, options).unwrap();
    for input in collect_inputs(&context, &paths, TimeSource::Auto).unwrap() {
        recorder.take_file(input).unwrap();
    }
    recorder.finish().unwrap();
    let reader = context.open_series(&living).unwrap();
    assert!(reader.segment_count() > 0);
    let p = series_probabilities(&reader, t, &points).unwrap();
    let predicted = predicted_map(&reader, t).unwrap();
    for (point, p) in points.iter().zip(&p) {
        let leaf = VoxelKey::from_point(*point, RESOLUTION).and_then(|k| {
            let code = k.morton();
            predicted
                .leaves()
                .iter()
                .find(|l| l.start <= code && code.0 < l.end())
        });
        match leaf {
            Some(leaf) => assert_eq!(*p > 0.5, leaf.log_odds > 0.0, "{point:?}: p {p}"),
            None => assert!(p.is_nan(), "{point:?}: p {p} where no cell is"),
        }
    }
    assert!(p[..p.len() - 1].iter().all(|p| p.is_finite()));
}
