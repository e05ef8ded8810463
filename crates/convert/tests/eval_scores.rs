//! `eval`'s probabilistic scores (Brier score, log loss, calibration) against a direct
//! computation on the small room: the door's states come from the room's definition, the
//! model's `p` from point queries, the static mean from counting the training frames.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use froctomap_convert::*;
use froctomap_core::VoxelKey;
use froctomap_file::FroctReader;
use froctomap_formats::ReadOptions;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// Three days of hourly frames; the next 14 hours held out.
const FRAMES: u32 = 72;
const HELD_OUT: std::ops::Range<u32> = FRAMES..FRAMES + 14;

fn clipped_log_loss(p: f64, occupied: bool) -> f64 {
    let p = p.clamp(1e-3, 1.0 - 1e-3);
    -if occupied { p.ln() } else { (1.0 - p).ln() }
}

/// `(wrong, brier, log loss)` of `p` per held-out frame and door voxel, directly.
fn direct(
    keys: &[VoxelKey],
    mut p_at: impl FnMut(u32, VoxelKey) -> f64,
    threshold: impl Fn(f64) -> bool,
) -> (u64, f64, f64) {
    let (mut wrong, mut brier, mut loss, mut n) = (0u64, 0.0, 0.0, 0.0);
    for i in HELD_OUT {
        let closed = !door_open_at(time(i));
        for &k in keys {
            let p = p_at(i, k);
            wrong += u64::from(threshold(p) != closed);
            brier += (p - f64::from(u8::from(closed))).powi(2);
            loss += clipped_log_loss(p, closed);
            n += 1.0;
        }
    }
    (wrong, brier / n, loss / n)
}

fn method<'a>(rows: &'a [(String, ErrorRates)], name: &str) -> &'a ErrorRates {
    &rows.iter().find(|(m, _)| m == name).unwrap().1
}

/// The room built from its first `FRAMES` frames, and the frames `truths` as ground truths.
fn room_and_truths(
    context: &Context,
    dir: &std::path::Path,
    truths: impl IntoIterator<Item = u32>,
) -> (FroctReader, Vec<SeriesInput>) {
    let (file, _) = build_room(context, dir, FRAMES);
    let truths_dir = dir.join("truths");
    std::fs::create_dir_all(&truths_dir).unwrap();
    for i in truths {
        write_frame(context, &truths_dir, i, &frame(i));
    }
    let truths = collect_inputs(context, &[truths_dir], TimeSource::Auto).unwrap();
    (context.open_froct(&file).unwrap(), truths)
}

#[test]
fn brier_and_log_loss_match_a_direct_computation() {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let (reader, truths) = room_and_truths(&context, dir.path(), HELD_OUT);
    let report = evaluate(&context, &reader, &truths, ReadOptions::default(), &Silent).unwrap();
    assert_eq!((report.inside, report.outside), (0, HELD_OUT.len()));
    assert_eq!(report.log_loss_epsilon, 1e-3);

    let door: Vec<VoxelKey> = keys().filter(|&k| is_door(k)).collect();
    let voxels = (door.len() * HELD_OUT.len()) as u64;
    let close = |a: Option<f64>, b: f64, tolerance: f64, what: &str| {
        let a = a.unwrap();
        assert!((a - b).abs() <= tolerance, "{what}: {a} vs {b}");
    };

    // The model: p(t) from point queries.
    let model = method(&report.prediction, "model");
    let (wrong, brier, loss) = direct(
        &door,
        |i, k| probabilities(&reader, time(i), &[k.center(RESOLUTION)]).unwrap()[0],
        |p| p > 0.5,
    );
    assert_eq!((model.dynamic.wrong, model.dynamic.total), (wrong, voxels));
    close(model.dynamic.brier(), brier, 1e-9, "model Brier");
    close(model.dynamic.log_loss(), loss, 1e-9, "model log loss");
    assert!(brier > 0.0);
    // Every other voxel is static and predicted exactly: p = s adds no squared error, and
    // −ln(1 − ε) of log loss per voxel.
    let all = model.all.total as f64;
    close(
        model.all.brier(),
        brier * voxels as f64 / all,
        1e-9,
        "model Brier, all",
    );
    close(
        model.all.log_loss(),
        (loss * voxels as f64 + (all - voxels as f64) * -(1.0f64 - 1e-3).ln()) / all,
        1e-9,
        "model log loss, all",
    );

    // The static mean: the fraction of training frames the door was closed (stored to 1/65535).
    let closed = (0..FRAMES).filter(|&i| !door_open_at(time(i))).count();
    let mean = closed as f64 / f64::from(FRAMES);
    let static_mean = method(&report.prediction, "static mean");
    let (wrong, brier, loss) = direct(&door, |_, _| mean, |p| p > 0.5);
    assert_eq!(static_mean.dynamic.wrong, wrong);
    close(
        static_mean.dynamic.brier(),
        brier,
        1e-4,
        "static mean Brier",
    );
    close(
        static_mean.dynamic.log_loss(),
        loss,
        1e-4,
        "static mean log loss",
    );

    // Last seen: the state of the last training frame, as 0 or 1.
    let last = f64::from(u8::from(!door_open_at(time(FRAMES - 1))));
    let last_seen = method(&report.prediction, "last seen");
    let (wrong, brier, loss) = direct(&door, |_, _| last, |p| p > 0.5);
    assert_eq!(last_seen.dynamic.wrong, wrong);
    close(last_seen.dynamic.brier(), brier, 1e-12, "last seen Brier");
    close(
        last_seen.dynamic.log_loss(),
        loss,
        1e-9,
        "last seen log loss",
    );
    // A 0/1 method's Brier score is its error rate.
    close(
        last_seen.dynamic.brier(),
        wrong as f64 / voxels as f64,
        1e-12,
        "Brier of 0/1",
    );

    // Calibration of the static mean: every door voxel in the bin of the mean.
    let (_, calibration) = report
        .prediction_calibration
        .iter()
        .find(|(m, _)| m == "static mean")
        .unwrap();
    let bins = calibration.bins();
    assert_eq!(bins.len(), CALIBRATION_BINS);
    let bin = &bins[(mean * 10.0) as usize];
    assert_eq!(bin.voxels, voxels);
    close(bin.mean_p, mean, 1e-4, "bin mean");
    let closed_held_out = HELD_OUT.filter(|&i| !door_open_at(time(i))).count();
    close(
        bin.occupied_fraction,
        closed_held_out as f64 / HELD_OUT.len() as f64,
        1e-12,
        "occupied fraction",
    );
    assert_eq!(bins.iter().map(|b| b.voxels).sum::<u64>(), voxels);

    // JSON: every {wrong, total} object carries brier and log_loss.
    let json = serde_json::to_value(&report).unwrap();
    let mut objects = 0;
    for (_, rates) in json["prediction"]
        .as_array()
        .unwrap()
        .iter()
        .map(|row| (row[0].clone(), row[1].clone()))
    {
        for set in ["all", "non_empty", "dynamic"] {
            let rate = &rates[set];
            assert!(rate["wrong"].is_u64() && rate["total"].is_u64(), "{rate}");
            assert!(
                rate["brier"].is_f64() && rate["log_loss"].is_f64(),
                "{rate}"
            );
            objects += 1;
        }
    }
    assert_eq!(objects, 9);
    assert_eq!(json["log_loss_epsilon"], 1e-3);
}

/// Ground truths are compared a group at a time, one walk of the file each: a group of one
/// (no leaf budget, one thread) and one group of all of them give the same report.
#[test]
fn the_report_does_not_depend_on_how_truths_are_grouped() {
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    // Some inside the span (reconstruction), the held-out hours after it (prediction).
    let (reader, truths) =
        room_and_truths(&context, dir.path(), (0..FRAMES).step_by(5).chain(HELD_OUT));
    let report = |context: &Context, threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let report = pool
            .install(|| evaluate(context, &reader, &truths, ReadOptions::default(), &Silent))
            .unwrap();
        serde_json::to_value(&report).unwrap()
    };
    let one_group = report(&context, 2);
    let mut limits = Limits::default();
    limits.eval_group_bytes = 0;
    let one_each = Context::with_default_plugins().with_limits(limits);
    let one_each = report(&one_each, 1);
    assert_eq!(one_group["inside"], 15);
    assert_eq!(one_group["outside"], HELD_OUT.len());
    assert_eq!(one_group, one_each);

    // Progress is counted in maps × tiles, and a cancellation is heard within a walk.
    let counted = Counted::default();
    evaluate(&context, &reader, &truths, ReadOptions::default(), &counted).unwrap();
    let total = (truths.len() * reader.tiles().len()) as u64;
    assert_eq!(
        counted.stages.lock().unwrap().as_slice(),
        [("evaluating".to_string(), total)]
    );
    assert_eq!(counted.done.load(Ordering::Relaxed), total);
    let cancelled = Counted {
        cancel: true,
        ..Counted::default()
    };
    let result = evaluate(
        &context,
        &reader,
        &truths,
        ReadOptions::default(),
        &cancelled,
    );
    assert!(matches!(result, Err(ConvertError::Cancelled)), "{result:?}");
}

#[derive(Default)]
struct Counted {
    stages: Mutex<Vec<(String, u64)>>,
    done: AtomicU64,
    cancel: bool,
}

impl Progress for Counted {
    fn stage(&self, name: &str, total: u64) {
        self.stages.lock().unwrap().push((name.to_string(), total));
    }
    fn advance(&self, units: u64) {
        self.done.fetch_add(units, Ordering::Relaxed);
    }
    fn cancelled(&self) -> bool {
        self.cancel
    }
}
