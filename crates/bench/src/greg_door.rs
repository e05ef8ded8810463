//! Prediction on the one real series in the project: the greg_door recording (a door's
//! state once a minute for 67 days, then 9 held-out test weeks) made into a small OctoMap
//! room, built into a `.froct` and evaluated week by week against the static mean, last
//! seen and a plain FreMEn computed independently in numpy (`scripts/fremen_reference.py`).
//!
//! The room (0.1 m voxels, keys from 32768): a 16 × 16 floor at z = 0; a wall at y = 0,
//! 16 wide and 12 high; in the wall a door panel 4 × 1 × 10 voxels (x 6..10, z 1..11),
//! occupied while the door is closed (state 0 in the data) and free while it is open; the
//! rest of the 16 × 15 × 12 box in front of the wall free. Every map shows the whole room,
//! so the panel's 40 voxels are the only dynamic ones.
//!
//! With `--validate` the test weeks are not read: the file is built from training weeks
//! 1..=6 only (weeks from the first training minute, 2016-01-04 00:00 UTC; week 4 lacks 3
//! days of recording) and scored on the held-back training weeks 7..=10, so that model
//! options can be chosen without looking at the test weeks. `--fit-weeks N` moves the
//! origin (weeks 1..=N fitted, the next up to 4 scored); `--rolling` runs the origins 4, 6
//! and 8 in one go and tabulates whether the targets hold on each.

use anyhow::{bail, Context as _, Result};
use clap::Args;
use froctomap_convert::{build, evaluate, BuildOptions, Context, EvalReport, SeriesInput, Silent};
use froctomap_core::{Leaf, Occupancy, Snapshot, Timestamp, VoxelKey};
use froctomap_file::FroctReader;
use froctomap_formats::{ReadOptions, WriteOptions};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Voxel edge, metres.
const RESOLUTION: f64 = 0.1;
const ORIGIN: u16 = 32768;
const SIDE: u16 = 16;
const HEIGHT: u16 = 12;
/// The FreMEn orders the numpy reference is computed at (the best is k = 4).
const REFERENCE_ORDERS: &str = "0,1,2,3,4,5";
/// The reference order shown beside the model in the table.
const REFERENCE_SHOWN: &str = "fremen k=4";
const WEEK_SECONDS: i64 = 7 * 86_400;
/// `--validate`: training weeks fitted; the later training weeks are the validation weeks.
const FIT_WEEKS: u32 = 6;
/// `--validate`: the held-back training weeks scored (the training data ends with week 10).
#[cfg(test)]
const VALIDATION_WEEKS: std::ops::RangeInclusive<u32> = 7..=10;
/// The last training week recorded.
const LAST_TRAINING_WEEK: u32 = 10;
/// Most held-back weeks scored after a validation origin.
const MAX_SCORED_WEEKS: u32 = 4;
/// `--rolling`: the validation origins (training weeks fitted).
const ROLLING_FIT_WEEKS: [u32; 3] = [4, 6, 8];

/// The training weeks scored when weeks `1..=fit_weeks` are fitted.
fn scored_weeks(fit_weeks: u32) -> std::ops::RangeInclusive<u32> {
    fit_weeks + 1..=(fit_weeks + MAX_SCORED_WEEKS).min(LAST_TRAINING_WEEK)
}

#[derive(Args)]
pub struct GregDoorArgs {
    /// The greg_door directory (training_data.txt, test_times_W.txt, test_data_W.txt);
    /// by default the one in `shared/` beside the checkout.
    #[arg(long, default_value = "../shared/data/greg_door_2016_min")]
    data: PathBuf,
    /// `full`: all 96,480 training minutes and the 9 test weeks; `ci`: the last 3 weeks of
    /// training and test weeks 1 and 2, every 60th minute. With `--validate`, `full` fits
    /// training weeks 1-6 and scores weeks 7-10; `ci` fits weeks 4-6 and scores week 7.
    #[arg(long, default_value = "full")]
    size: String,
    /// Validation instead of test: fit on training weeks 1-6 only and score on the
    /// held-back training weeks 7-10 as if they were test weeks (the test files are not
    /// read), to choose model options without looking at the test weeks.
    #[arg(long)]
    validate: bool,
    /// With `--validate`: fit training weeks 1..=N (default 6) and score the next up to 4
    /// (at most week 10; N from 1 to 9).
    #[arg(long, value_name = "N", requires = "validate")]
    fit_weeks: Option<u32>,
    /// Rolling-origin validation: `--validate` at fit weeks 4, 6 and 8 (scored on 5-8, 7-10
    /// and 9-10), each run's results in a subdirectory of --out, and a summary table of the
    /// targets on each.
    #[arg(long, conflicts_with_all = ["validate", "fit_weeks"])]
    rolling: bool,
    /// Fail (exit status 1) when a run misses issue 28's targets: every week's thresholded
    /// error at most the static mean's + 0.1 pp, mean Brier at most 0.80× the static
    /// mean's (what CI runs with).
    #[arg(long)]
    require_targets: bool,
    /// Evaluate every n-th test minute (default 10; `ci`: 60).
    #[arg(long)]
    stride: Option<usize>,
    /// Model options for the build (`key=value`, as `froctomap build --option`).
    #[arg(long = "option", value_name = "KEY=VALUE")]
    options: Vec<String>,
    /// Python with numpy for the reference (default target/interop-venv/bin/python, made by
    /// scripts/python-client.sh).
    #[arg(long, default_value = "target/interop-venv/bin/python")]
    python: PathBuf,
    /// Where the room's maps, the file and results.json/results.md go.
    #[arg(long, default_value = "target/greg-door")]
    out: PathBuf,
}

/// One method's scores on one test week (dynamic voxels).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Scores {
    pub error_percent: Option<f64>,
    pub brier: Option<f64>,
    pub log_loss: Option<f64>,
}

/// One test week (or, validating, one held-back training week).
#[derive(Clone, Debug, Default, Serialize)]
pub struct WeekRow {
    /// The test week, or with `--validate` the training week.
    pub week: u32,
    pub maps: usize,
    pub model: Scores,
    pub static_mean: Scores,
    pub last_seen: Scores,
    /// Every order of the numpy reference, and its static mean.
    pub reference: serde_json::Value,
}

/// Means over a run's weeks, and issue 28's criteria.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Summary {
    pub model_brier: f64,
    pub static_brier: f64,
    pub last_seen_brier: f64,
    /// The numpy FreMEn at the order shown in the table.
    pub reference_brier: f64,
    /// Mean Brier, model / static mean (the target is ≤ 0.80).
    pub model_vs_static: f64,
    pub reference_vs_static: f64,
    /// Largest weekly excess of the model's thresholded error over the static mean's,
    /// percentage points (the target is ≤ 0.1).
    pub worst_excess_pp: f64,
    /// Mean Brier over the weeks of every numpy reference order (and its static mean).
    pub reference_orders: Vec<(String, f64)>,
}

/// The whole run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct GregDoorResults {
    /// `test`, or `validation` (`--validate`: training weeks 1-6 fitted, 7-10 scored).
    pub mode: String,
    /// What the file was fitted on, e.g. `training weeks 1-6`.
    pub fitted: String,
    pub size: String,
    pub stride: usize,
    pub training_maps: usize,
    pub options: Vec<String>,
    pub file_bytes: u64,
    pub build_seconds: f64,
    /// The periods the model kept for the door panel, strongest first (seconds).
    pub door_periods: Vec<f64>,
    pub weeks: Vec<WeekRow>,
    pub summary: Summary,
    pub reference_periods_strongest_first: serde_json::Value,
}

fn is_door(k: VoxelKey) -> bool {
    (ORIGIN + 6..ORIGIN + 10).contains(&k.x)
        && k.y == ORIGIN
        && (ORIGIN + 1..ORIGIN + 11).contains(&k.z)
}

/// The room with the door closed or open.
fn room(closed: bool) -> Result<Snapshot> {
    let mut leaves = Vec::new();
    for x in ORIGIN..ORIGIN + SIDE {
        for y in ORIGIN..ORIGIN + SIDE {
            for z in ORIGIN..ORIGIN + HEIGHT {
                let k = VoxelKey::new(x, y, z);
                let occupied = if is_door(k) {
                    closed
                } else {
                    z == ORIGIN || y == ORIGIN
                };
                leaves.push(Leaf::voxel(k, Occupancy::from(occupied).log_odds()));
            }
        }
    }
    Ok(Snapshot::from_leaves(RESOLUTION, leaves)?.canonical())
}

/// `(unix seconds, state)` pairs of a two-column file, or two one-column files.
fn read_pairs(times: &Path, states: Option<&Path>) -> Result<Vec<(i64, u8)>> {
    let text =
        |p: &Path| std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()));
    let parse = |p: &Path, line: usize, field: Option<&str>| -> Result<i64> {
        field
            .and_then(|f| f.trim().parse::<f64>().ok())
            .filter(|v| v.is_finite())
            .map(|v| v as i64)
            .with_context(|| format!("{}:{}: not a number", p.display(), line + 1))
    };
    let first = text(times)?;
    let mut out = Vec::new();
    match states {
        None => {
            for (i, line) in first
                .lines()
                .enumerate()
                .filter(|(_, l)| !l.trim().is_empty())
            {
                let mut fields = line.split_whitespace();
                let t = parse(times, i, fields.next())?;
                let s = parse(times, i, fields.next())?;
                out.push((t, u8::from(s != 0)));
            }
        }
        Some(states_path) => {
            let second = text(states_path)?;
            let t = first.lines().filter(|l| !l.trim().is_empty());
            let s = second.lines().filter(|l| !l.trim().is_empty());
            for (i, (t, s)) in t.zip(s).enumerate() {
                out.push((
                    parse(times, i, Some(t))?,
                    u8::from(parse(states_path, i, Some(s))? != 0),
                ));
            }
        }
    }
    if out.is_empty() {
        bail!("{}: no samples", times.display());
    }
    Ok(out)
}

fn inputs(pairs: &[(i64, u8)], closed: &Path, open: &Path) -> Vec<SeriesInput> {
    pairs
        .iter()
        .map(|&(t, state)| {
            SeriesInput::new(
                if state == 0 { closed } else { open }.to_path_buf(),
                Timestamp::from_secs(t),
            )
        })
        .collect()
}

fn scores(report: &EvalReport, method: &str) -> Scores {
    report
        .prediction
        .iter()
        .find(|(m, _)| m == method)
        .map(|(_, r)| Scores {
            error_percent: r.dynamic.percent(),
            brier: r.dynamic.brier(),
            log_loss: r.dynamic.log_loss(),
        })
        .unwrap_or_default()
}

/// Runs the numpy reference; its JSON.
fn reference(
    args: &GregDoorArgs,
    weeks: &[u32],
    stride: usize,
    train_from: Option<i64>,
    validate_until: Option<i64>,
) -> Result<serde_json::Value> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/fremen_reference.py");
    let weeks: Vec<String> = weeks.iter().map(u32::to_string).collect();
    let mut command = Command::new(&args.python);
    command
        .arg(&script)
        .arg(&args.data)
        .arg("--weeks")
        .arg(weeks.join(","))
        .arg("--stride")
        .arg(stride.to_string())
        .arg("--orders")
        .arg(REFERENCE_ORDERS)
        .arg("--eps")
        .arg(froctomap_convert::LOG_LOSS_EPSILON.to_string());
    if let Some(t) = train_from {
        command.arg("--train-from").arg(t.to_string());
    }
    if let Some(t) = validate_until {
        command.arg("--validate-until").arg(t.to_string());
    }
    let output = command.output().with_context(|| {
        format!(
            "running the numpy reference with {} (make it with scripts/python-client.sh target/interop-venv)",
            args.python.display()
        )
    })?;
    if !output.status.success() {
        bail!(
            "the numpy reference failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    Ok(serde_json::from_slice(&output.stdout)?)
}

fn cell(x: Option<f64>, digits: usize) -> String {
    x.map_or_else(|| "-".into(), |v| format!("{v:.digits$}"))
}

fn reference_scores(value: &serde_json::Value, method: &str) -> Scores {
    let get = |k: &str| {
        value
            .get(method)
            .and_then(|m| m.get(k))
            .and_then(serde_json::Value::as_f64)
    };
    Scores {
        error_percent: get("error_percent"),
        brier: get("brier"),
        log_loss: get("log_loss"),
    }
}

/// Removes from `training` the samples at or after `until` and returns them (`--validate`).
fn hold_back(training: &mut Vec<(i64, u8)>, until: i64) -> Vec<(i64, u8)> {
    let later = training
        .iter()
        .filter(|&&(t, _)| t >= until)
        .copied()
        .collect();
    training.retain(|&(t, _)| t < until);
    later
}

/// The samples of training week `week` (1-based, weeks from `start`).
fn training_week(samples: &[(i64, u8)], start: i64, week: u32) -> Vec<(i64, u8)> {
    let from = start + i64::from(week.saturating_sub(1)) * WEEK_SECONDS;
    let to = from + WEEK_SECONDS;
    samples
        .iter()
        .filter(|&&(t, _)| (from..to).contains(&t))
        .copied()
        .collect()
}

/// Mean Brier scores over `weeks` and the largest weekly error excess.
pub fn summarise(weeks: &[WeekRow]) -> Summary {
    let n = weeks.len().max(1) as f64;
    let mean = |f: &dyn Fn(&WeekRow) -> Option<f64>| {
        weeks.iter().map(|w| f(w).unwrap_or(f64::NAN)).sum::<f64>() / n
    };
    let model_brier = mean(&|w| w.model.brier);
    let static_brier = mean(&|w| w.static_mean.brier);
    let reference_brier = mean(&|w| reference_scores(&w.reference, REFERENCE_SHOWN).brier);
    let worst_excess_pp = weeks
        .iter()
        .filter_map(|w| Some(w.model.error_percent? - w.static_mean.error_percent?))
        .fold(f64::NEG_INFINITY, f64::max);
    let mut orders: Vec<String> = weeks
        .first()
        .and_then(|w| w.reference.as_object())
        .map(|o| o.keys().cloned().collect())
        .unwrap_or_default();
    orders.sort();
    let reference_orders = orders
        .into_iter()
        .map(|k| {
            let b = mean(&|w| reference_scores(&w.reference, &k).brier);
            (k, b)
        })
        .collect();
    Summary {
        model_brier,
        static_brier,
        last_seen_brier: mean(&|w| w.last_seen.brier),
        reference_brier,
        model_vs_static: model_brier / static_brier,
        reference_vs_static: reference_brier / static_brier,
        worst_excess_pp,
        reference_orders,
    }
}

/// Whether a run meets issue 28's targets (every week's error ≤ static mean + 0.1 pp, mean
/// Brier ≤ 0.80× the static mean's).
fn targets_met(summary: &Summary) -> bool {
    summary.worst_excess_pp <= 0.1 + 1e-9 && summary.model_vs_static <= 0.80
}

/// With `--require-targets`, an error naming the runs that miss the targets.
fn check_targets(args: &GregDoorArgs, runs: &[&GregDoorResults]) -> Result<()> {
    let missed: Vec<String> = runs
        .iter()
        .filter(|r| !targets_met(&r.summary))
        .map(|r| {
            format!(
                "{} ({}): model / static mean {:.3}, worst excess {:+.2} pp",
                r.mode, r.fitted, r.summary.model_vs_static, r.summary.worst_excess_pp
            )
        })
        .collect();
    if args.require_targets && !missed.is_empty() {
        bail!("issue 28's targets missed: {}", missed.join("; "));
    }
    Ok(())
}

/// The markdown table of a run.
pub fn markdown(results: &GregDoorResults) -> String {
    let validating = results.mode == "validation";
    let mut out = String::new();
    let _ = writeln!(
        out,
        "greg_door room, {}, size {}, {} training maps ({}) fitted, every {}th {} minute, options [{}]; file {} bytes, built in {:.1} s; door periods kept (h): {}\n",
        if validating {
            format!(
                "VALIDATION (scored on training weeks {}; test weeks not read)",
                results.weeks.iter().map(|w| w.week.to_string()).collect::<Vec<_>>().join(", ")
            )
        } else {
            "test".into()
        },
        results.size,
        results.training_maps,
        results.fitted,
        results.stride,
        if validating { "held-back" } else { "test" },
        results.options.join(", "),
        results.file_bytes,
        results.build_seconds,
        results
            .door_periods
            .iter()
            .map(|p| format!("{:.1}", p / 3600.0))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        out,
        "Dynamic voxels (the door panel). Error = thresholded at 0.5, %; Brier; log loss (ε = {}).\n",
        froctomap_convert::LOG_LOSS_EPSILON
    );
    let _ = writeln!(out, "| {} | maps | model error | static | last seen | FreMEn k=4 (numpy) | model Brier | static | last seen | FreMEn k=4 | model log loss | static | last seen | FreMEn k=4 |",
        if validating { "training week" } else { "week" });
    let _ = writeln!(out, "| ---: | ---: |{}", " ---: |".repeat(12));
    for w in &results.weeks {
        let fremen = reference_scores(&w.reference, REFERENCE_SHOWN);
        let rows = [&w.model, &w.static_mean, &w.last_seen, &fremen];
        let _ = write!(out, "| {} | {} |", w.week, w.maps);
        for s in rows {
            let _ = write!(out, " {} |", cell(s.error_percent, 2));
        }
        for s in rows {
            let _ = write!(out, " {} |", cell(s.brier, 4));
        }
        for s in rows {
            let _ = write!(out, " {} |", cell(s.log_loss, 3));
        }
        let _ = writeln!(out);
    }
    let s = &results.summary;
    let _ = writeln!(
        out,
        "\nMean Brier over the weeks: model {:.4}, static mean {:.4}, last seen {:.4}, FreMEn k=4 {:.4}; model / static mean = {:.3}, FreMEn k=4 / static mean = {:.3}.",
        s.model_brier,
        s.static_brier,
        s.last_seen_brier,
        s.reference_brier,
        s.model_vs_static,
        s.reference_vs_static
    );
    let _ = writeln!(
        out,
        "Largest weekly excess of the model's error over the static mean's: {:+.2} percentage points.",
        s.worst_excess_pp
    );
    // Issue 28's targets, judged on this run.
    let verdict = |met: bool| if met { "met" } else { "not met" };
    let _ = writeln!(
        out,
        "Targets: every week's error ≤ static mean + 0.1 pp: {}; mean Brier ≤ 0.80× the static mean's: {} ({:.3}×).",
        verdict(s.worst_excess_pp <= 0.1 + 1e-9),
        verdict(s.model_vs_static <= 0.80),
        s.model_vs_static
    );
    let means: Vec<String> = s
        .reference_orders
        .iter()
        .map(|(k, b)| format!("{k}: {b:.4}"))
        .collect();
    let _ = writeln!(
        out,
        "Numpy reference, mean Brier per order: {}.",
        means.join(", ")
    );
    out
}

/// The markdown summary of a rolling-origin validation: one row per origin.
pub fn rolling_markdown(runs: &[GregDoorResults]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "greg_door room, ROLLING-ORIGIN VALIDATION (test weeks not read), size {}: mean Brier over each origin's scored weeks relative to the static mean's, and the largest weekly excess of the thresholded error over the static mean's.\n",
        runs.first().map_or("", |r| r.size.as_str())
    );
    let _ = writeln!(out, "| fitted | scored training weeks | model / static | FreMEn k=4 / static | best FreMEn / static | worst excess (pp) | targets (≤ 0.80×, ≤ +0.1 pp) | door periods (h) |");
    let _ = writeln!(out, "| --- | --- | ---: | ---: | ---: | ---: | --- | --- |");
    for r in runs {
        let s = &r.summary;
        let best = s
            .reference_orders
            .iter()
            .filter(|(k, _)| k.starts_with("fremen"))
            .map(|(_, b)| b / s.static_brier)
            .fold(f64::INFINITY, f64::min);
        let met = targets_met(s);
        let _ = writeln!(
            out,
            "| {} | {} | {:.3} | {:.3} | {:.3} | {:+.2} | {} | {} |",
            r.fitted,
            r.weeks
                .iter()
                .map(|w| w.week.to_string())
                .collect::<Vec<_>>()
                .join(", "),
            s.model_vs_static,
            s.reference_vs_static,
            best,
            s.worst_excess_pp,
            if met { "met" } else { "not met" },
            r.door_periods
                .iter()
                .map(|p| format!("{:.1}", p / 3600.0))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    out
}

pub fn greg_door_command(args: &GregDoorArgs) -> Result<()> {
    if !args.rolling {
        let fit_weeks = args.validate.then_some(args.fit_weeks.unwrap_or(FIT_WEEKS));
        let results = run(args, fit_weeks, &args.out)?;
        write_results(&args.out, &markdown(&results), &results)?;
        return check_targets(args, &[&results]);
    }
    let mut runs = Vec::new();
    for fit_weeks in ROLLING_FIT_WEEKS {
        let out = args.out.join(format!("fit-weeks-{fit_weeks}"));
        let results = run(args, Some(fit_weeks), &out)?;
        write_results(&out, &markdown(&results), &results)?;
        runs.push(results);
    }
    write_results(&args.out, &rolling_markdown(&runs), &runs)?;
    check_targets(args, &runs.iter().collect::<Vec<_>>())
}

/// Prints `md` and writes it and `results` as results.md and results.json in `out`.
fn write_results(out: &Path, md: &str, results: &impl Serialize) -> Result<()> {
    println!("{md}");
    std::fs::write(out.join("results.md"), md)?;
    std::fs::write(
        out.join("results.json"),
        serde_json::to_string_pretty(results)?,
    )?;
    Ok(())
}

/// One run: the test weeks, or with `fit_weeks` the validation on training weeks
/// `1..=fit_weeks` scored on the next ones; its files in `out`.
fn run(args: &GregDoorArgs, fit_weeks: Option<u32>, out: &Path) -> Result<GregDoorResults> {
    if let Some(n) = fit_weeks {
        if !(1..LAST_TRAINING_WEEK).contains(&n) {
            bail!("--fit-weeks {n}: expected 1 to {}", LAST_TRAINING_WEEK - 1);
        }
    }
    let validate = fit_weeks.is_some();
    let (weeks, default_stride, train_days): (Vec<u32>, usize, Option<i64>) =
        match (args.size.as_str(), fit_weeks) {
            ("full", None) => ((1..=9).collect(), 10, None),
            ("ci", None) => (vec![1, 2], 60, Some(21)),
            ("full", Some(n)) => (scored_weeks(n).collect(), 10, None),
            ("ci", Some(n)) => (vec![n + 1], 60, Some(21)),
            (other, _) => bail!("--size {other}: expected `full` or `ci`"),
        };
    let stride = args.stride.unwrap_or(default_stride).max(1);
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let context = Context::with_default_plugins();
    let (closed, open) = write_rooms(&context, out)?;

    let training_path = args.data.join("training_data.txt");
    let mut training = read_pairs(&training_path, None)?;
    let start = training.first().map_or(0, |&(t, _)| t);
    // Validating: the training samples from week fit_weeks + 1 on are held back.
    let validate_until = fit_weeks.map(|n| start + i64::from(n) * WEEK_SECONDS);
    let held_back = match validate_until {
        Some(until) => hold_back(&mut training, until),
        None => Vec::new(),
    };
    if training.is_empty() {
        bail!("{}: no training samples to fit", training_path.display());
    }
    let train_from =
        train_days.and_then(|days| training.last().map(|&(t, _)| t - days * 86_400 + 60));
    if let Some(from) = train_from {
        training.retain(|&(t, _)| t >= from);
    }
    eprintln!("greg-door: building from {} maps", training.len());
    let file = out.join("greg_door.froct");
    let mut config = froctomap_temporal::ModelConfig::default();
    for option in &args.options {
        config.options.set_assignment(option)?;
    }
    let options = BuildOptions {
        config,
        time: Some(Timestamp::from_secs(0)),
        ..BuildOptions::default()
    };
    let started = Instant::now();
    build(
        &context,
        &inputs(&training, &closed, &open),
        &file,
        &options,
        &Silent,
    )?;
    let build_seconds = started.elapsed().as_secs_f64();
    let reader = FroctReader::open(&file)?;
    let door_centre = VoxelKey::new(ORIGIN + 7, ORIGIN, ORIGIN + 5).center(RESOLUTION);
    let door_periods = froctomap_convert::voxel_history(&reader, door_centre, None)?
        .model
        .map(|m| m.periodic.iter().map(|t| t.period_seconds).collect())
        .unwrap_or_default();

    eprintln!("greg-door: numpy reference");
    let reference = reference(args, &weeks, stride, train_from, validate_until)?;
    let mut rows = Vec::new();
    for &week in &weeks {
        let pairs = if validate {
            held_back_week(&held_back, start, week, &training_path)?
        } else {
            test_week(args, week)?
        };
        let truths: Vec<SeriesInput> = inputs(&pairs, &closed, &open)
            .into_iter()
            .step_by(stride)
            .collect();
        let report = evaluate(&context, &reader, &truths, ReadOptions::default(), &Silent)?;
        if report.inside > 0 {
            bail!(
                "week {week}: {} maps inside the training span",
                report.inside
            );
        }
        eprintln!("greg-door: week {week} evaluated ({} maps)", truths.len());
        let row = WeekRow {
            week,
            maps: truths.len(),
            model: scores(&report, "model"),
            static_mean: scores(&report, "static mean"),
            last_seen: scores(&report, "last seen"),
            reference: reference["weeks"][week.to_string()].clone(),
        };
        check_same_samples(&row)?;
        rows.push(row);
    }
    Ok(GregDoorResults {
        mode: if validate { "validation" } else { "test" }.into(),
        fitted: fitted(fit_weeks, train_days),
        size: args.size.clone(),
        stride,
        training_maps: training.len(),
        options: args.options.clone(),
        file_bytes: std::fs::metadata(&file)?.len(),
        build_seconds,
        door_periods,
        summary: summarise(&rows),
        weeks: rows,
        reference_periods_strongest_first: reference["strongest_first"].clone(),
    })
}

/// The room with the door closed and open, written as door-closed.bt and door-open.bt
/// in `out`: every sample is one of the two.
fn write_rooms(context: &Context, out: &Path) -> Result<(PathBuf, PathBuf)> {
    let closed = out.join("door-closed.bt");
    let open = out.join("door-open.bt");
    for (path, is_closed) in [(&closed, true), (&open, false)] {
        context
            .formats()
            .write_file(&room(is_closed)?, path, WriteOptions::default())?;
    }
    Ok((closed, open))
}

/// The held-back training samples of `week` (validating), which must not be empty.
fn held_back_week(
    held_back: &[(i64, u8)],
    start: i64,
    week: u32,
    training_path: &Path,
) -> Result<Vec<(i64, u8)>> {
    let pairs = training_week(held_back, start, week);
    if pairs.is_empty() {
        bail!(
            "{}: no samples in training week {week}",
            training_path.display()
        );
    }
    Ok(pairs)
}

/// The samples of test week `week`.
fn test_week(args: &GregDoorArgs, week: u32) -> Result<Vec<(i64, u8)>> {
    read_pairs(
        &args.data.join(format!("test_times_{week}.txt")),
        Some(&args.data.join(format!("test_data_{week}.txt"))),
    )
}

/// Checks that the numpy reference scored the same samples as froctomap in `row`.
fn check_same_samples(row: &WeekRow) -> Result<()> {
    // The numpy reference splits and strides the samples on its own: its static mean
    // scoring as froctomap's (up to the 16-bit quantised mean) shows both scored the
    // same samples against the same training mean.
    let week = row.week;
    let ours = row.static_mean.brier;
    let theirs = reference_scores(&row.reference, "static mean").brier;
    match (ours, theirs) {
        (Some(a), Some(b)) if (a - b).abs() <= 1e-4 * a.abs().max(1e-3) => Ok(()),
        _ => bail!(
            "week {week}: the static mean's Brier score is {ours:?} here and {theirs:?} in the numpy reference: the two did not score the same samples"
        ),
    }
}

/// What the model was fitted on, in words.
fn fitted(fit_weeks: Option<u32>, train_days: Option<i64>) -> String {
    match (fit_weeks, train_days) {
        (None, None) => "all training weeks".into(),
        (None, Some(days)) => format!("the last {days} training days"),
        (Some(n), None) => format!("training weeks 1-{n}"),
        (Some(n), Some(days)) => format!("the {days} days before training week {}", n + 1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ten weeks of minutes with three days missing in week 4, as in greg_door's training
    /// file: the fit keeps weeks 1-6 only, and weeks 7-10 are whole weeks of held-back
    /// minutes that together are exactly the held-back samples.
    #[test]
    fn validation_fits_six_weeks_and_scores_the_next_four() {
        let start = 1_451_865_600;
        let gap = start + 22 * 86_400..start + 25 * 86_400;
        let mut training: Vec<(i64, u8)> = (0..10 * WEEK_SECONDS / 60)
            .map(|i| (start + 60 * i, u8::from(i % 7 == 0)))
            .filter(|(t, _)| !gap.contains(t))
            .collect();
        let all = training.clone();
        let until = start + i64::from(FIT_WEEKS) * WEEK_SECONDS;
        let held_back = hold_back(&mut training, until);
        assert_eq!(training.len(), 6 * 7 * 1440 - 3 * 1440);
        assert!(training.iter().all(|&(t, _)| t < until));
        let mut weeks = Vec::new();
        assert_eq!(scored_weeks(FIT_WEEKS), VALIDATION_WEEKS);
        for week in VALIDATION_WEEKS {
            let samples = training_week(&held_back, start, week);
            assert_eq!(samples.len(), 7 * 1440, "week {week}");
            assert_eq!(
                samples.first().map(|s| s.0),
                Some(start + i64::from(week - 1) * WEEK_SECONDS)
            );
            weeks.extend(samples);
        }
        assert_eq!(weeks, held_back);
        assert_eq!([training, held_back].concat(), all);
        assert!(training_week(&all, start, 11).is_empty());
        // The rolling origins score the weeks after them, never past the last.
        assert_eq!(scored_weeks(4), 5..=8);
        assert_eq!(scored_weeks(8), 9..=10);
        assert!(scored_weeks(ROLLING_FIT_WEEKS[2]).all(|w| w <= LAST_TRAINING_WEEK));
    }
}
