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

use crate::context::Context;
use crate::error::ConvertError;
use crate::inputs::SeriesInput;
use crate::progress::Progress;
use froctomap_core::{Occupancy, Snapshot, Timestamp};
use froctomap_file::{Cell, CellContent, FroctReader};
use froctomap_formats::ReadOptions;
use froctomap_temporal::{PreparedModel, TimeAxis};
use rayon::prelude::*;
use serde::Serialize;

/// Wrong voxels out of compared voxels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Rate {
    /// Voxels whose state was wrong.
    pub wrong: u64,
    /// Voxels compared.
    pub total: u64,
}

impl Rate {
    /// The error in percent (`None` when nothing was compared).
    pub fn percent(&self) -> Option<f64> {
        (self.total > 0).then(|| 100.0 * self.wrong as f64 / self.total as f64)
    }

    fn add(&mut self, wrong: bool, weight: u64) {
        self.total += weight;
        if wrong {
            self.wrong += weight;
        }
    }

    fn merge(&mut self, other: &Rate) {
        self.wrong += other.wrong;
        self.total += other.total;
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
    /// Ground-truth voxels the file has no cell for (never observed in the file's data).
    pub unmodelled_voxels: u64,
}

/// Per method, per set, for one ground truth.
#[derive(Clone, Copy, Default)]
struct Tally {
    methods: [ErrorRates; 4],
    /// Ground-truth voxels a cell covers.
    matched: u64,
    unmodelled: u64,
}

impl Tally {
    fn merge(&mut self, other: &Tally) {
        for (a, b) in self.methods.iter_mut().zip(&other.methods) {
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

fn mean_state(cell: &Cell, model: &dyn PreparedModel) -> Occupancy {
    match &cell.content {
        CellContent::Constant(state) | CellContent::ConstantExcept { state, .. } => *state,
        CellContent::Modelled(voxel) => {
            Occupancy::from_log_odds(if model.mean(voxel.parameters()) > 0.5 {
                1.0
            } else {
                -1.0
            })
        }
    }
}

/// What each method says about one cell at the evaluated time.
struct Verdicts {
    states: [Option<Occupancy>; 4],
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
        CellContent::Constant(state) | CellContent::ConstantExcept { state, .. } => *state,
        CellContent::Modelled(voxel) => model.predicted_state(voxel.parameters(), seconds),
    };
    let at_or_before = axis.last_at_or_before(t);
    let stored = if inside {
        at_or_before
            .and_then(|k| last_observed(cell, axis, k))
            .and_then(|k| cell.state_at(axis, model, k))
    } else {
        None
    };
    let strictly_before = match at_or_before {
        Some(k) if axis.time(k) == Some(t) => k.checked_sub(1),
        other => other,
    };
    let last_seen = strictly_before
        .and_then(|k| last_observed(cell, axis, k))
        .and_then(|k| cell.state_at(axis, model, k));
    Verdicts {
        states: [
            Some(predicted),
            stored,
            Some(mean_state(cell, model)),
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
            let truth_state = leaf.occupancy();
            for (rates, state) in out.methods.iter_mut().zip(v.states) {
                let Some(state) = state else { continue };
                let wrong = state != truth_state;
                rates.all.add(wrong, weight);
                if v.ever_occupied || truth_state.is_occupied() {
                    rates.non_empty.add(wrong, weight);
                }
                if v.dynamic {
                    rates.dynamic.add(wrong, weight);
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
    let name = crate::recording::input_name(truth);
    let bytes = crate::recording::snapshot_bytes(truth, context.limits().max_map_file_bytes)
        .map_err(|e| ConvertError::Snapshot {
            path: name.clone(),
            source: std::sync::Arc::new(e),
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
/// once, one cell at a time, against every truth's leaves inside the tile.
fn tally_group(reader: &FroctReader, truths: &[GroundTruth]) -> Result<Vec<Tally>, ConvertError> {
    let axis = &reader.header().axis;
    let model = reader.model();
    let empty = || vec![Tally::default(); truths.len()];
    let mut tallies = (0..reader.tiles().len())
        .into_par_iter()
        .map(|tile| {
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

/// Compares a file with ground-truth maps (map files of any format of `context`, with their
/// times).
///
/// Memory is a few ground truths and one tile's decoded bytes per thread, whatever the size
/// of the file's map: ground truths are read a group at a time (as many as threads) and the
/// file's tiles are walked cell by cell against each group.
pub fn evaluate(
    context: &Context,
    reader: &FroctReader,
    truths: &[SeriesInput],
    read: ReadOptions<'_>,
    progress: &dyn Progress,
) -> Result<EvalReport, ConvertError> {
    progress.stage("evaluating", truths.len() as u64);
    let group = rayon::current_num_threads().max(1);
    let mut tallies: Vec<(bool, Tally)> = Vec::with_capacity(truths.len());
    for inputs in truths.chunks(group) {
        let loaded = inputs
            .par_iter()
            .map(|truth| read_truth(context, reader, truth, read))
            .collect::<Result<Vec<_>, ConvertError>>()?;
        let group_tallies = tally_group(reader, &loaded)?;
        tallies.extend(loaded.iter().map(|t| t.inside).zip(group_tallies));
        progress.advance(inputs.len() as u64);
    }
    let mut report = EvalReport::default();
    let mut inside_rates = [ErrorRates::default(); 4];
    let mut outside_rates = [ErrorRates::default(); 4];
    for (inside, t) in &tallies {
        let target = if *inside {
            report.inside += 1;
            &mut inside_rates
        } else {
            report.outside += 1;
            &mut outside_rates
        };
        for (sum, r) in target.iter_mut().zip(&t.methods) {
            sum.merge(r);
        }
        report.unmodelled_voxels += t.unmodelled;
    }
    report.reconstruction = METHODS
        .iter()
        .zip(inside_rates)
        .map(|(m, r)| (m.to_string(), r))
        .collect();
    report.prediction = METHODS
        .iter()
        .zip(outside_rates)
        .filter(|(m, _)| **m != "stored")
        .map(|(m, r)| (m.to_string(), r))
        .collect();
    Ok(report)
}
