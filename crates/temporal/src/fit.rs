//! The fitting pipeline shared by every spectral model: mean, component choice, order choice,
//! and the outlier set computed from the *quantised* parameters.

use crate::spectral::{
    encoded_len, quantise_phase, quantise_unit, Component, Evaluable, SpectralParameters,
};
use crate::toggles::ToggleBuilder;
use crate::{FittedVoxel, Order, OutlierMode, VoxelObservations};

/// Relative held-out score a higher order must beat the lower ones by to be chosen.
pub(crate) const ORDER_TOLERANCE: f64 = 0.01;

/// Most held-out samples scored when choosing an order by prediction (see `holdout_order`).
pub(crate) const MAX_HOLDOUT_SAMPLES: u64 = 512;

/// Factors the amplitudes may be shrunk by (option `shrink=auto`) when choosing an order by
/// prediction, weakest shrinkage first: amplitudes estimated on the training span overshoot
/// when the behaviour drifts, and the held-out samples say by how much.
pub(crate) const SHRINKS: [f64; 4] = [1.0, 0.8, 0.6, 0.4];

/// Margin below which a bound on `p` is not trusted to decide the threshold (float error of
/// the summation is many orders of magnitude smaller).
const BOUND_MARGIN: f64 = 1e-9;

/// An unquantised spectral component.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Candidate {
    pub frequency: u32,
    /// `A` (= 2|γ| for FreMEn), in `[0, 1]`.
    pub amplitude: f64,
    /// `φ = arg γ`, in turns.
    pub phase_turns: f64,
}

/// Computes `(cos θ_c(i), sin θ_c(i))` of the base angle of each component at a sample,
/// deterministically.
pub(crate) trait Evaluator {
    /// Fills `out[c]` for the first `out.len()` components.
    fn angles(&mut self, sample: u32, out: &mut [(f64, f64)]);
}

/// What a spectral model provides to the shared pipeline.
pub(crate) trait Spectral: Send + Sync {
    type Eval<'a>: Evaluator
    where
        Self: 'a;

    /// An evaluator for these components.
    fn evaluator<'a>(&'a self, components: &[Component]) -> Self::Eval<'a>;

    /// The axis the samples belong to.
    fn time_axis(&self) -> &crate::TimeAxis;

    /// Turns per second of a component's base angle.
    fn rate(&self, component: &Component) -> f64;

    /// Up to `max` strongest usable components of `obs` (mean `mean`), strongest first.
    fn candidates(&self, obs: &VoxelObservations, mean: f64, max: usize) -> Vec<Candidate>;
}

/// Settings the pipeline needs.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FitSettings {
    pub order: Order,
    pub mode: OutlierMode,
    pub criterion: crate::OrderCriterion,
    pub holdout_fraction: f64,
    /// Whether the held-out samples may shrink the amplitudes (option `shrink`).
    pub shrink: bool,
}

fn quantise(cands: &[Candidate]) -> Vec<Component> {
    cands
        .iter()
        .map(|c| Component {
            frequency: c.frequency,
            amplitude_q: quantise_unit(c.amplitude),
            phase_q: quantise_phase(c.phase_turns),
        })
        .filter(|c| c.amplitude_q > 0)
        .collect()
}

/// Fits one voxel with a spectral model.
pub(crate) fn fit_voxel<S: Spectral>(
    model: &S,
    settings: &FitSettings,
    obs: &VoxelObservations,
) -> FittedVoxel {
    let n = obs.observed_count();
    if n == 0 {
        return FittedVoxel::new(&SpectralParameters::default().encode(), Default::default())
            .with_model_errors(0);
    }
    let mean = obs.occupied_count() as f64 / n as f64;
    let mean_q = quantise_unit(mean);
    let max = usize::from(settings.order.max());
    if obs.is_constant().is_some() || max == 0 {
        return finish(
            model,
            mean_q,
            Vec::new(),
            obs,
            OrderChoice::Single(0),
            settings.mode,
        );
    }
    match (settings.order, settings.mode) {
        (Order::Fixed(_), mode) => {
            let comps = quantise(&model.candidates(obs, mean, max));
            finish(model, mean_q, comps, obs, OrderChoice::Single(max), mode)
        }
        (Order::Auto { .. }, OutlierMode::Lossless)
            if settings.criterion == crate::OrderCriterion::SmallestFile =>
        {
            let comps = quantise(&model.candidates(obs, mean, max));
            finish(
                model,
                mean_q,
                comps,
                obs,
                OrderChoice::SmallestEncoding(max),
                OutlierMode::Lossless,
            )
        }
        (Order::Auto { .. }, mode) => {
            let shrinks = if settings.shrink {
                &SHRINKS[..]
            } else {
                &SHRINKS[..1]
            };
            let (m, shrink) = holdout_order(model, obs, max, settings.holdout_fraction, shrinks);
            let mut cands = model.candidates(obs, mean, m);
            for c in &mut cands {
                c.amplitude *= shrink;
            }
            let comps = quantise(&cands);
            finish(model, mean_q, comps, obs, OrderChoice::Single(m), mode)
        }
    }
}

/// The order (≤ `max`) and amplitude factor (one of `shrinks`, the first being 1) whose fit
/// on the earlier observed samples best predicts the later ones (smallest Brier score);
/// order 0 when there is nothing to hold out or learn from.
fn holdout_order<S: Spectral>(
    model: &S,
    obs: &VoxelObservations,
    max: usize,
    fraction: f64,
    shrinks: &[f64],
) -> (usize, f64) {
    let n = obs.observed_count();
    let train_count = ((1.0 - fraction) * n as f64).ceil() as u64;
    let split = obs.sample_after_observed(train_count.min(n));
    let train = obs.truncated(split);
    let test_count = n - train.observed_count();
    if train.observed_count() == 0 || test_count == 0 || train.is_constant().is_some() {
        return (0, 1.0);
    }
    let train_mean = train.occupied_count() as f64 / train.observed_count() as f64;
    let comps = quantise(&model.candidates(&train, train_mean, max));
    if comps.is_empty() {
        return (0, 1.0);
    }
    let mean = f64::from(quantise_unit(train_mean)) / 65535.0;
    let evaluables: Vec<Evaluable> = comps.iter().map(Evaluable::new).collect();
    let mut eval = model.evaluator(&comps);
    let mut angles = vec![(0.0, 0.0); comps.len()];
    // Per order m, per factor s: squared error, and samples on the wrong side of 0.5.
    let mut sq_err = vec![vec![0.0f64; shrinks.len()]; comps.len() + 1];
    let mut wrong = vec![vec![0u64; shrinks.len()]; comps.len() + 1];
    // Scoring every held-out sample costs (samples × orders) evaluations per voxel; an
    // evenly spaced subset ranks the orders as well and bounds the cost on long series.
    let stride = test_count.div_ceil(MAX_HOLDOUT_SAMPLES).max(1);
    let mut seen = 0u64;
    for run in obs.runs() {
        let target = if run.state.is_occupied() { 1.0 } else { 0.0 };
        let start = u64::from(run.first.max(split));
        let end = run.end();
        if start >= end {
            continue;
        }
        let mut i = start + (stride - seen % stride) % stride;
        seen += end - start;
        while i < end {
            let sample = i as u32;
            eval.angles(sample, &mut angles);
            let mut periodic = 0.0;
            for (m, (errs, wrongs)) in sq_err.iter_mut().zip(&mut wrong).enumerate() {
                for ((err, w), shrink) in errs.iter_mut().zip(wrongs.iter_mut()).zip(shrinks) {
                    let p = (mean + shrink * periodic).clamp(0.0, 1.0);
                    let d = p - target;
                    *err += d * d;
                    *w += u64::from((p > 0.5) != run.state.is_occupied());
                }
                if let (Some(e), Some(a)) = (evaluables.get(m), angles.get(m)) {
                    periodic += e.value(*a);
                }
            }
            i += stride;
        }
    }
    // The lowest order, then the weakest shrinkage, within 1 % of the best score: a
    // component must earn its place, so noise-like voxels (whose spurious components fit
    // the held-out samples by chance) keep the mean alone instead of paying for components
    // that do not predict. A shrinkage must not put more held-out samples on the wrong
    // side of 0.5 than the unshrunk order does: it may soften p, not the decisions.
    let best = sq_err
        .iter()
        .flatten()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let good = |e: f64| e <= best * (1.0 + ORDER_TOLERANCE) + f64::EPSILON;
    sq_err
        .iter()
        .zip(&wrong)
        .enumerate()
        .find_map(|(m, (errs, wrongs))| {
            let unshrunk = wrongs.first().copied().unwrap_or(0);
            let s = errs
                .iter()
                .zip(wrongs)
                .position(|(&e, &w)| good(e) && w <= unshrunk)?;
            let shrink = shrinks.get(s).copied()?;
            Some((m, if m == 0 { 1.0 } else { shrink }))
        })
        .unwrap_or((0, 1.0))
}

#[derive(Debug, Clone, Copy)]
enum OrderChoice {
    /// Exactly this order (or all components when fewer).
    Single(usize),
    /// The order in `0..=max` with the smallest encoded voxel.
    SmallestEncoding(usize),
}

/// Computes the outlier set (and disagreement count) for the chosen order(s) from the
/// quantised components, and assembles the voxel.
fn finish<S: Spectral>(
    model: &S,
    mean_q: u16,
    mut comps: Vec<Component>,
    obs: &VoxelObservations,
    choice: OrderChoice,
    mode: OutlierMode,
) -> FittedVoxel {
    let (lo, hi) = match choice {
        OrderChoice::Single(m) => (m.min(comps.len()), m.min(comps.len())),
        OrderChoice::SmallestEncoding(max) => (0, max.min(comps.len())),
    };
    comps.truncate(hi);
    let mean = f64::from(mean_q) / 65535.0;
    let evaluables: Vec<Evaluable> = comps.iter().map(Evaluable::new).collect();

    // Orders whose |p − mean| bound keeps p on one side of 0.5 predict a constant state and
    // need no per-sample evaluation.
    let mut constant = Vec::with_capacity(hi + 1);
    let mut bound = 0.0;
    for m in 0..=hi {
        let state = if m == 0 {
            Some(mean > 0.5)
        } else if mean + bound < 0.5 - BOUND_MARGIN {
            Some(false)
        } else if mean - bound > 0.5 + BOUND_MARGIN {
            Some(true)
        } else {
            None
        };
        constant.push(state);
        if let Some(e) = evaluables.get(m) {
            bound += e.bound();
        }
    }
    let evaluated = (lo..=hi)
        .rev()
        .find(|&m| constant.get(m).copied().flatten().is_none())
        .unwrap_or(0);

    // |dp/dt| ≤ Σ 2π·rate·bound: a sample whose p is d away from 0.5 decides the threshold
    // for every sample within d/slope seconds after it, so those need no evaluation. This
    // only skips work: the decision is the one each skipped sample's own p would give.
    let mut slopes = Vec::with_capacity(hi + 1);
    let mut slope = 0.0;
    for m in 0..=hi {
        slopes.push(slope);
        if let (Some(e), Some(c)) = (evaluables.get(m), comps.get(m)) {
            slope += std::f64::consts::TAU * model.rate(c).abs() * e.bound();
        }
    }
    let axis = model.time_axis();

    let keep = mode == OutlierMode::Lossless;
    let mut trackers: Vec<ToggleBuilder> = (lo..=hi).map(|_| ToggleBuilder::new(keep)).collect();
    let mut eval = model.evaluator(&comps);
    let mut angles = vec![(0.0, 0.0); evaluated];
    let mut predicted = vec![false; evaluated + 1];
    // The last evaluated sample and how far (ns) its decisions are guaranteed to hold.
    let mut anchor: Option<(u32, i64)> = None;
    for run in obs.runs() {
        let occupied = run.state.is_occupied();
        for (m, tracker) in (lo..=hi).zip(trackers.iter_mut()) {
            if let Some(Some(predicted)) = constant.get(m) {
                tracker.push_run(run.first, run.len, *predicted != occupied);
            }
        }
        if evaluated == 0 {
            continue;
        }
        let mut i = u64::from(run.first);
        while i < run.end() {
            let sample = i as u32;
            let covered = anchor.map_or(0, |(a, limit)| {
                axis.samples_within(a, sample, run.end(), limit)
            });
            if covered > 0 {
                for m in lo..=evaluated {
                    if constant.get(m) == Some(&None) {
                        if let (Some(tracker), Some(&pred)) =
                            (trackers.get_mut(m - lo), predicted.get(m))
                        {
                            tracker.push_run(sample, covered, pred != occupied);
                        }
                    }
                }
                i += u64::from(covered);
                continue;
            }
            eval.angles(sample, &mut angles);
            let mut p = mean;
            let mut horizon = f64::INFINITY;
            for m in 0..=evaluated {
                if m >= lo && constant.get(m) == Some(&None) {
                    if let Some(slot) = predicted.get_mut(m) {
                        *slot = p > 0.5;
                    }
                    let distance = (p - 0.5).abs() - BOUND_MARGIN;
                    let slope = slopes.get(m).copied().unwrap_or(f64::INFINITY);
                    let h = if distance > 0.0 {
                        distance / slope * (1.0 - 1e-6)
                    } else {
                        0.0
                    };
                    horizon = horizon.min(h);
                }
                if let (Some(e), Some(a)) = (evaluables.get(m), angles.get(m)) {
                    p += e.value(*a);
                }
            }
            // Covers at least the anchor itself (limit ≥ 0), so the loop advances.
            let limit = (horizon * 1e9).floor().clamp(0.0, i64::MAX as f64) as i64;
            anchor = Some((sample, limit));
        }
    }

    let mut best = 0;
    let mut best_size = usize::MAX;
    for (k, tracker) in trackers.iter().enumerate() {
        let m = lo + k;
        let size = encoded_len(comps.get(..m).unwrap_or(&comps)) + tracker.encoded_len();
        if size < best_size {
            best_size = size;
            best = k;
        }
    }
    let m = lo + best;
    let tracker = trackers.swap_remove(best);
    let errors = tracker.disagreements();
    comps.truncate(m);
    let parameters = SpectralParameters {
        mean_q,
        components: comps,
    };
    FittedVoxel::new(&parameters.encode(), tracker.finish()).with_model_errors(errors)
}

/// Keeps the `max` largest by `key` (strongest first; ties to the lower frequency).
pub(crate) struct TopK {
    max: usize,
    items: Vec<(f64, u32)>,
}

impl TopK {
    pub fn new(max: usize) -> Self {
        Self {
            max,
            items: Vec::with_capacity(max + 1),
        }
    }

    /// Offers frequency `frequency` with strength `key`.
    #[inline]
    pub fn offer(&mut self, key: f64, frequency: u32) {
        if self.max == 0 || key.is_nan() || key <= 0.0 {
            return;
        }
        if self.items.len() == self.max {
            match self.items.last() {
                Some(&(k, _)) if key > k => {}
                _ => return,
            }
            self.items.pop();
        }
        let pos = self.items.partition_point(|&(k, _)| k >= key);
        self.items.insert(pos, (key, frequency));
    }

    /// The kept `(key, frequency)` pairs, strongest first.
    pub fn into_sorted(self) -> Vec<(f64, u32)> {
        self.items
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::FremenPeriods;
    use crate::{ModelConfig, ObservationsBuilder, SpectralParameters, TemporalModel, TimeAxis};
    use froctomap_core::{Occupancy, Timestamp};

    /// Occupied 09:00-17:00 every day for three weeks, then on every other day only: the
    /// daily rhythm weakens in the held-out week.
    #[test]
    fn shrink_auto_softens_amplitudes_that_overshoot_the_held_out_part() {
        let n = 4 * 7 * 24;
        let axis = TimeAxis::regular(Timestamp(0), 3_600_000_000_000, n, vec![]).unwrap();
        let mut b = ObservationsBuilder::new();
        for i in 0..n {
            let (day, hour) = (i / 24, i % 24);
            let active = day < 21 || day % 2 == 0;
            b.push(i, Some(Occupancy::from(active && (9..17).contains(&hour))))
                .unwrap();
        }
        let obs = b.finish();
        let components = |options: &[(&str, &str)]| {
            let mut config = ModelConfig::default();
            for (k, v) in options {
                config = config.with_option(k, v);
            }
            let model = FremenPeriods.prepare(&axis, &config).unwrap();
            let voxel = model.fit(&obs).unwrap();
            SpectralParameters::decode(voxel.parameters())
                .unwrap()
                .components
        };
        // Unshrunk, no component predicts the weaker held-out week well enough: the mean alone.
        assert!(components(&[("shrink", "off")]).is_empty());
        // Shrunk, the daily rhythm validates: the same components as a fixed order gives,
        // with every amplitude scaled by one factor of the grid below 1.
        let auto = components(&[("shrink", "auto")]);
        assert!(!auto.is_empty());
        let order = auto.len().to_string();
        let fixed = components(&[("order", order.as_str())]);
        let mut ratios = Vec::new();
        for (a, b) in fixed.iter().zip(&auto) {
            assert_eq!((a.frequency, a.phase_q), (b.frequency, b.phase_q));
            ratios.push(f64::from(b.amplitude_q) / f64::from(a.amplitude_q));
        }
        let factor = ratios[0];
        assert!(
            factor < 0.9 && SHRINKS.iter().any(|s| (s - factor).abs() < 1e-3),
            "{ratios:?}"
        );
        assert!(
            ratios.iter().all(|r| (r - factor).abs() < 1e-3),
            "{ratios:?}"
        );
    }

    #[test]
    fn top_k_keeps_strongest_in_order() {
        let mut t = TopK::new(3);
        for (k, f) in [
            (1.0, 1),
            (5.0, 2),
            (3.0, 3),
            (5.0, 4),
            (0.5, 5),
            (4.0, 6),
            (0.0, 7),
        ] {
            t.offer(k, f);
        }
        assert_eq!(t.into_sorted(), vec![(5.0, 2), (5.0, 4), (4.0, 6)]);
        let mut none = TopK::new(0);
        none.offer(1.0, 1);
        assert!(none.into_sorted().is_empty());
    }
}
