//! `eval`: how well a FROctomap file reproduces and predicts ground-truth maps, against the
//! baselines a user would otherwise use.
//!
//! Every ground-truth voxel that the file models is compared, weighted by voxel count (a
//! coarse leaf counts for all its voxels). Errors are reported, as in the FROctomap paper,
//! over *all* voxels, *non-empty* voxels (occupied in the ground truth, or ever occupied in
//! the file's data) and *dynamic* voxels (whose state changed at least once in the file's
//! data). Ground truths inside the file's time span measure reconstruction; those outside it
//! (typically later) measure prediction.
//!
//! Methods compared:
//! * `model`: the temporal model alone, `p(t) > 0.5` (outliers ignored): what FreMEn knows.
//! * `stored`: what the file gives back for that time — the exact state at the last
//!   snapshot at or before it (lossless files reproduce their inputs, so inside the span
//!   this is the retrieval error); outside the span it is not defined.
//! * `static mean`: each voxel's mean occupancy over its observations, `> 0.5`.
//! * `last seen`: each voxel's latest observed state strictly before the time.
//!
//! Beside the thresholded error, every [`Rate`] carries the probabilistic scores the
//! FreMEn literature uses, with the same voxel weights: the Brier score (mean of
//! `(p − s)²`, `s` the true 0/1 state) and the log loss (mean of `−ln p` for occupied and
//! `−ln(1 − p)` for free voxels, `p` clipped to `[ε, 1 − ε]`, [`LOG_LOSS_EPSILON`]). The
//! `p` of each method: the model's `p(t)`; the static mean's mean occupancy; 0 or 1 for
//! `stored` and `last seen`. Cells stored as constant (with or without rare exceptions)
//! have `p` = their usual state for every method. A [`Calibration`] table per method bins
//! `p` over the dynamic voxels (reliability diagram).
//!
//! Sums are kept in fixed point (2⁻³² units) so that they add associatively: the report is
//! the same whatever the order the tiles were tallied in.

use crate::context::Context;
use crate::error::ConvertError;
use crate::inputs::SeriesInput;
use crate::progress::{stop_if_cancelled, Progress};
use froctomap_core::{Occupancy, Snapshot, Timestamp};
use froctomap_file::{Cell, CellContent, FroctReader};
use froctomap_formats::ReadOptions;
use froctomap_temporal::{PreparedModel, TimeAxis};
use rayon::prelude::*;
use serde::Serialize;

/// `p` is clipped to `[ε, 1 − ε]` for the log loss (reported as `log_loss_epsilon`).
pub const LOG_LOSS_EPSILON: f64 = 1e-3;

/// Bins of a [`Calibration`] table: `[0, 0.1)`, `[0.1, 0.2)`, …, `[0.9, 1]`.
pub const CALIBRATION_BINS: usize = 10;

/// Fixed-point scale of the score sums (2³²).
const SCALE: f64 = 4_294_967_296.0;

fn fixed(x: f64) -> u128 {
    // x ∈ [0, −ln ε]: the product fits easily.
    (x * SCALE).round().max(0.0) as u128
}

fn unfixed(x: u128) -> f64 {
    x as f64 / SCALE
}

/// The log loss of probability `p` for the true state `occupied`, `p` clipped to
/// `[ε, 1 − ε]` ([`LOG_LOSS_EPSILON`]).
pub fn log_loss(p: f64, occupied: bool) -> f64 {
    let p = p.clamp(LOG_LOSS_EPSILON, 1.0 - LOG_LOSS_EPSILON);
    -(if occupied { p } else { 1.0 - p }).ln()
}

/// Wrong voxels out of compared voxels, with the probabilistic scores of the same voxels
/// (serialised as `{wrong, total, brier, log_loss}`; the scores are `null` when nothing was
/// compared).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Rate {
    /// Voxels whose state was wrong.
    pub wrong: u64,
    /// Voxels compared.
    pub total: u64,
    /// Σ weight·(p − s)², fixed point.
    squared_error: u128,
    /// Σ weight·log loss, fixed point.
    log_loss: u128,
}

impl Rate {
    /// The error in percent (`None` when nothing was compared).
    pub fn percent(&self) -> Option<f64> {
        (self.total > 0).then(|| 100.0 * self.wrong as f64 / self.total as f64)
    }

    /// The Brier score: the voxel-weighted mean of `(p − s)²` (`None` when nothing was
    /// compared).
    pub fn brier(&self) -> Option<f64> {
        (self.total > 0).then(|| unfixed(self.squared_error) / self.total as f64)
    }

    /// The voxel-weighted mean log loss, `p` clipped to `[ε, 1 − ε]` ([`LOG_LOSS_EPSILON`]).
    pub fn log_loss(&self) -> Option<f64> {
        (self.total > 0).then(|| unfixed(self.log_loss) / self.total as f64)
    }

    /// Adds `weight` voxels for which a method said `state` with probability `p`, when the
    /// truth was `truth`.
    fn add(&mut self, verdict: Verdict, truth: bool, weight: u64) {
        self.total += weight;
        if verdict.occupied != truth {
            self.wrong += weight;
        }
        let s = if truth { 1.0 } else { 0.0 };
        let w = u128::from(weight);
        self.squared_error += fixed((verdict.p - s).powi(2)) * w;
        self.log_loss += fixed(log_loss(verdict.p, truth)) * w;
    }

    fn merge(&mut self, other: &Rate) {
        self.wrong += other.wrong;
        self.total += other.total;
        self.squared_error += other.squared_error;
        self.log_loss += other.log_loss;
    }
}

impl Serialize for Rate {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut out = serializer.serialize_struct("Rate", 4)?;
        out.serialize_field("wrong", &self.wrong)?;
        out.serialize_field("total", &self.total)?;
        out.serialize_field("brier", &self.brier())?;
        out.serialize_field("log_loss", &self.log_loss())?;
        out.end()
    }
}

/// One bin of a [`Calibration`] table.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CalibrationBin {
    /// Lowest `p` of the bin.
    pub lower: f64,
    /// Highest `p` (exclusive, except for the last bin).
    pub upper: f64,
    /// Voxels whose `p` fell in the bin.
    pub voxels: u64,
    /// Their mean `p` (`None` for an empty bin).
    pub mean_p: Option<f64>,
    /// The fraction of them that was occupied (`None` for an empty bin).
    pub occupied_fraction: Option<f64>,
}

/// A method's reliability over the dynamic voxels: how often voxels given `p` were occupied,
/// per bin of `p` ([`CALIBRATION_BINS`] equal bins). A calibrated method has
/// `occupied_fraction ≈ mean_p` in every bin.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Calibration {
    bins: [BinSum; CALIBRATION_BINS],
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct BinSum {
    voxels: u64,
    occupied: u64,
    /// Σ weight·p, fixed point.
    p_sum: u128,
}

impl Calibration {
    fn add(&mut self, p: f64, truth: bool, weight: u64) {
        let bin = ((p * CALIBRATION_BINS as f64) as usize).min(CALIBRATION_BINS - 1);
        if let Some(b) = self.bins.get_mut(bin) {
            b.voxels += weight;
            b.occupied += if truth { weight } else { 0 };
            b.p_sum += fixed(p) * u128::from(weight);
        }
    }

    fn merge(&mut self, other: &Calibration) {
        for (a, b) in self.bins.iter_mut().zip(&other.bins) {
            a.voxels += b.voxels;
            a.occupied += b.occupied;
            a.p_sum += b.p_sum;
        }
    }

    /// The bins, lowest `p` first.
    pub fn bins(&self) -> Vec<CalibrationBin> {
        let width = 1.0 / CALIBRATION_BINS as f64;
        self.bins
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let n = (b.voxels > 0).then_some(b.voxels as f64);
                CalibrationBin {
                    lower: i as f64 * width,
                    upper: (i + 1) as f64 * width,
                    voxels: b.voxels,
                    mean_p: n.map(|n| unfixed(b.p_sum) / n),
                    occupied_fraction: n.map(|n| b.occupied as f64 / n),
                }
            })
            .collect()
    }
}

impl Serialize for Calibration {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        self.bins().serialize(serializer)
    }
}

/// Errors over the three voxel sets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ErrorRates {
    /// All compared voxels.
    pub all: Rate,
    /// Voxels occupied in the truth or ever occupied in the data.
    pub non_empty: Rate,
    /// Voxels that changed state in the data.
    pub dynamic: Rate,
}

impl ErrorRates {
    fn merge(&mut self, other: &ErrorRates) {
        self.all.merge(&other.all);
        self.non_empty.merge(&other.non_empty);
        self.dynamic.merge(&other.dynamic);
    }
}

/// The methods compared, in report order.
pub const METHODS: [&str; 4] = ["model", "stored", "static mean", "last seen"];

/// The result of an evaluation.
#[derive(Clone, Debug, Default, Serialize)]
pub struct EvalReport {
    /// Ground truths within the file's time span.
    pub inside: usize,
    /// Ground truths outside it.
    pub outside: usize,
    /// Per method (see [`METHODS`]): errors inside the span.
    pub reconstruction: Vec<(String, ErrorRates)>,
    /// Per method: errors outside the span (`stored` is absent).
    pub prediction: Vec<(String, ErrorRates)>,
    /// Per method: reliability of `p` on the dynamic voxels inside the span.
    pub reconstruction_calibration: Vec<(String, Calibration)>,
    /// Per method: reliability of `p` on the dynamic voxels outside the span.
    pub prediction_calibration: Vec<(String, Calibration)>,
    /// The `ε` of the log loss ([`LOG_LOSS_EPSILON`]).
    pub log_loss_epsilon: f64,
    /// Ground-truth voxels the file has no cell for (never observed in the file's data).
    pub unmodelled_voxels: u64,
}

/// Per method, per set, for one ground truth.
#[derive(Clone, Copy, Default)]
struct Tally {
    methods: [ErrorRates; 4],
    calibration: [Calibration; 4],
    /// Ground-truth voxels a cell covers.
    matched: u64,
    unmodelled: u64,
}

impl Tally {
    fn merge(&mut self, other: &Tally) {
        for (a, b) in self.methods.iter_mut().zip(&other.methods) {
            a.merge(b);
        }
        for (a, b) in self.calibration.iter_mut().zip(&other.calibration) {
            a.merge(b);
        }
        self.matched += other.matched;
    }
}

/// The latest sample `≤ k` at which the cell was observed.
fn last_observed(cell: &Cell, axis: &TimeAxis, mut k: u32) -> Option<u32> {
    loop {
        if cell.is_observed(axis, k) {
            return Some(k);
        }
        if let Some(mask) = cell.mask.as_ref().filter(|m| !m.parity_at(k)) {
            // Jump over the whole unobserved stretch of the mask.
            let toggles = mask.as_slice();
            let before = toggles.partition_point(|&p| p <= k);
            k = toggles.get(before.checked_sub(1)?)?.checked_sub(1)?;
        } else {
            k = k.checked_sub(1)?;
        }
    }
}

/// What one method says about a cell: its state and its probability of occupancy.
#[derive(Clone, Copy, Debug)]
struct Verdict {
    occupied: bool,
    p: f64,
}

impl Verdict {
    fn state(state: Occupancy) -> Self {
        Self::certain(state.is_occupied())
    }

    fn certain(occupied: bool) -> Self {
        Self {
            occupied,
            p: if occupied { 1.0 } else { 0.0 },
        }
    }

    fn probability(p: f64) -> Self {
        Self {
            occupied: p > 0.5,
            p,
        }
    }
}

fn mean_verdict(cell: &Cell, model: &dyn PreparedModel) -> Verdict {
    match &cell.content {
        CellContent::Constant(state) | CellContent::ConstantExcept { state, .. } => {
            Verdict::state(*state)
        }
        CellContent::Modelled(voxel) => Verdict::probability(model.mean(voxel.parameters())),
    }
}

/// What each method says about one cell at the evaluated time.
struct Verdicts {
    states: [Option<Verdict>; 4],
    dynamic: bool,
    ever_occupied: bool,
}

fn verdicts(
    cell: &Cell,
    axis: &TimeAxis,
    model: &dyn PreparedModel,
    t: Timestamp,
    inside: bool,
) -> Verdicts {
    let seconds = t.secs_since(axis.start());
    let predicted = match &cell.content {
        CellContent::Constant(state) | CellContent::ConstantExcept { state, .. } => {
            Verdict::state(*state)
        }
        CellContent::Modelled(voxel) => {
            Verdict::probability(model.probability(voxel.parameters(), seconds))
        }
    };
    let at_or_before = axis.last_at_or_before(t);
    let stored = if inside {
        at_or_before
            .and_then(|k| last_observed(cell, axis, k))
            .and_then(|k| cell.state_at(axis, model, k))
            .map(Verdict::state)
    } else {
        None
    };
    let strictly_before = match at_or_before {
        Some(k) if axis.time(k) == Some(t) => k.checked_sub(1),
        other => other,
    };
    let last_seen = strictly_before
        .and_then(|k| last_observed(cell, axis, k))
        .and_then(|k| cell.state_at(axis, model, k))
        .map(Verdict::state);
    Verdicts {
        states: [
            Some(predicted),
            stored,
            Some(mean_verdict(cell, model)),
            last_seen,
        ],
        dynamic: !matches!(cell.content, CellContent::Constant(_)),
        ever_occupied: !matches!(cell.content, CellContent::Constant(Occupancy::Free)),
    }
}

/// Tallies the overlaps of one cell with the leaves of a ground truth, from `next` on
/// (both lists sorted and disjoint), advancing `next` past the leaves the cell ends.
fn tally_cell(
    cell: &Cell,
    truth: &GroundTruth,
    next: &mut usize,
    axis: &TimeAxis,
    model: &dyn PreparedModel,
    out: &mut Tally,
) {
    let leaves = truth.snapshot.leaves();
    let mut verdict: Option<Verdicts> = None;
    while let Some(leaf) = leaves.get(*next) {
        if leaf.start.0 >= cell.end() {
            break;
        }
        let start = leaf.start.0.max(cell.start.0);
        let end = leaf.end().min(cell.end());
        if start < end {
            let v = verdict
                .get_or_insert_with(|| verdicts(cell, axis, model, truth.time, truth.inside));
            let weight = end - start;
            out.matched += weight;
            let truth = leaf.occupancy().is_occupied();
            for ((rates, calibration), verdict) in out
                .methods
                .iter_mut()
                .zip(&mut out.calibration)
                .zip(v.states)
            {
                let Some(verdict) = verdict else { continue };
                rates.all.add(verdict, truth, weight);
                if v.ever_occupied || truth {
                    rates.non_empty.add(verdict, truth, weight);
                }
                if v.dynamic {
                    rates.dynamic.add(verdict, truth, weight);
                    calibration.add(verdict.p, truth, weight);
                }
            }
        }
        if leaf.end() <= cell.end() {
            *next += 1;
        } else {
            break;
        }
    }
}

/// A ground-truth map and where its time lies.
struct GroundTruth {
    snapshot: Snapshot,
    time: Timestamp,
    inside: bool,
}

/// Reads a ground truth and checks its resolution against the file's.
fn read_truth(
    context: &Context,
    reader: &FroctReader,
    truth: &SeriesInput,
    read: ReadOptions<'_>,
) -> Result<GroundTruth, ConvertError> {
    let resolution = reader.header().resolution;
    let axis = &reader.header().axis;
    // A file, or a map of a recording the inputs were collected from (named
    // `recording/topic@time`).
    let name = crate::inputs::input_name(truth);
    let bytes =
        crate::inputs::snapshot_bytes(truth, context.limits().max_map_file_bytes).map_err(|e| {
            ConvertError::Snapshot {
                path: name.clone(),
                source: std::sync::Arc::new(e),
            }
        })?;
    let snapshot = context
        .formats()
        .read_bytes(&name, &bytes, read)
        .map_err(ConvertError::Read)?
        .map
        .snapshot;
    if snapshot.resolution() != resolution {
        return Err(ConvertError::MixedResolution {
            first: reader.path().to_path_buf(),
            first_resolution: resolution,
            second: name,
            second_resolution: snapshot.resolution(),
        });
    }
    Ok(GroundTruth {
        snapshot,
        time: truth.time,
        inside: truth.time >= axis.start() && truth.time <= axis.end(),
    })
}

/// The tallies of a group of ground truths: the file's tiles in parallel, each walked
/// once, one cell at a time, against every truth's leaves inside the tile; `progress`
/// advances by the group's size per tile.
fn tally_group(
    reader: &FroctReader,
    truths: &[GroundTruth],
    progress: &dyn Progress,
) -> Result<Vec<Tally>, ConvertError> {
    let axis = &reader.header().axis;
    let model = reader.model();
    let empty = || vec![Tally::default(); truths.len()];
    let mut tallies = (0..reader.tiles().len())
        .into_par_iter()
        .map(|tile| {
            stop_if_cancelled(progress)?;
            let code = reader.tiles()[tile].code.0;
            let mut out = empty();
            // Each truth's first leaf reaching into the tile (a coarse leaf may span tiles).
            let mut next: Vec<usize> = truths
                .iter()
                .map(|t| t.snapshot.leaves().partition_point(|l| l.end() <= code))
                .collect();
            reader.visit_cells(tile, |cell| {
                for ((truth, next), out) in truths.iter().zip(&mut next).zip(&mut out) {
                    tally_cell(&cell, truth, next, axis, model, out);
                }
            })?;
            progress.advance(truths.len() as u64);
            Ok::<_, ConvertError>(out)
        })
        .try_reduce(empty, |mut a, b| {
            for (a, b) in a.iter_mut().zip(&b) {
                a.merge(b);
            }
            Ok(a)
        })?;
    for (tally, truth) in tallies.iter_mut().zip(truths) {
        let known = truth
            .snapshot
            .leaves()
            .iter()
            .fold(0u64, |sum, l| sum.saturating_add(l.voxel_count()));
        tally.unmodelled = known.saturating_sub(tally.matched);
    }
    Ok(tallies)
}

/// Per method of [`METHODS`], named; `stored` left out unless `keep_stored`.
fn named<T: Copy>(values: &[T; 4], keep_stored: bool) -> Vec<(String, T)> {
    METHODS
        .iter()
        .zip(values.iter().copied())
        .filter(|(m, _)| keep_stored || **m != "stored")
        .map(|(m, r)| (m.to_string(), r))
        .collect()
}

/// Compares a file with ground-truth maps (map files of any format of `context`, with their
/// times).
///
/// Ground truths are read a group at a time and the file's tiles are walked cell by cell
/// against each group. Each walk decodes the whole file, which on a long history costs far
/// more than comparing one more map, so a group is as many truths as fit in
/// [`Limits::eval_group_bytes`](crate::Limits) of leaves (at least as many as threads).
/// Memory is that group and one tile's decoded bytes per thread, whatever the size of the
/// file.
pub fn evaluate(
    context: &Context,
    reader: &FroctReader,
    truths: &[SeriesInput],
    read: ReadOptions<'_>,
    progress: &dyn Progress,
) -> Result<EvalReport, ConvertError> {
    // Counted in maps × tiles: a walk of the file for many maps is long.
    let tiles = reader.tiles().len() as u64;
    progress.stage("evaluating", (truths.len() as u64).saturating_mul(tiles));
    let threads = rayon::current_num_threads().max(1);
    let mut tallies: Vec<(bool, Tally)> = Vec::with_capacity(truths.len());
    let mut rest = truths;
    while !rest.is_empty() {
        let mut loaded: Vec<GroundTruth> = Vec::new();
        let mut leaf_bytes = 0usize;
        while !rest.is_empty()
            && (loaded.is_empty() || leaf_bytes < context.limits().eval_group_bytes)
        {
            let (inputs, tail) = rest.split_at(threads.min(rest.len()));
            rest = tail;
            let read_now = inputs
                .par_iter()
                .map(|truth| read_truth(context, reader, truth, read))
                .collect::<Result<Vec<_>, ConvertError>>()?;
            leaf_bytes = read_now.iter().fold(leaf_bytes, |sum, t| {
                sum.saturating_add(std::mem::size_of_val(t.snapshot.leaves()))
            });
            loaded.extend(read_now);
        }
        let group_tallies = tally_group(reader, &loaded, progress)?;
        tallies.extend(loaded.iter().map(|t| t.inside).zip(group_tallies));
    }
    let mut report = EvalReport {
        log_loss_epsilon: LOG_LOSS_EPSILON,
        ..EvalReport::default()
    };
    let mut inside = Tally::default();
    let mut outside = Tally::default();
    for (is_inside, t) in &tallies {
        if *is_inside {
            report.inside += 1;
            inside.merge(t);
        } else {
            report.outside += 1;
            outside.merge(t);
        }
        report.unmodelled_voxels += t.unmodelled;
    }
    report.reconstruction = named(&inside.methods, true);
    report.prediction = named(&outside.methods, false);
    report.reconstruction_calibration = named(&inside.calibration, true);
    report.prediction_calibration = named(&outside.calibration, false);
    Ok(report)
}
