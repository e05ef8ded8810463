//! The fitting pipeline shared by every spectral model: mean, component choice, order choice,
//! and the outlier set computed from the *quantised* parameters.

use crate::spectral::{
    encoded_len, quantise_phase, quantise_unit, Component, Evaluable, SpectralParameters,
};
use crate::toggles::ToggleBuilder;
use crate::{FittedVoxel, Order, OutlierMode, VoxelObservations};

/// Relative held-out score a higher order must beat the lower ones by to be chosen.
pub(crate) const ORDER_TOLERANCE: f64 = 0.01;

/// Highest order chosen by a held-out part that does not span a whole cycle of each of the
/// order's periods; higher orders must be validated on one that does.
pub(crate) const UNVALIDATED_MAX_ORDER: usize = 5;

/// How many standard deviations (of a fair coin's count) a model's held-out decisions that
/// differ from the mean's must be right by, net, for it to cross 0.5 where the mean does not.
pub(crate) const DECISION_Z: f64 = 2.0;

/// Most held-out samples scored when choosing an order by prediction (see `holdout_order`).
pub(crate) const MAX_HOLDOUT_SAMPLES: u64 = 512;

/// Factors the amplitudes may be shrunk by (option `shrink=auto`) when choosing an order by
/// prediction, weakest shrinkage first: amplitudes estimated on the training span overshoot
/// when the behaviour drifts, and the held-out samples say by how much.
pub(crate) const SHRINKS: [f64; 5] = [1.0, 0.8, 0.6, 0.4, 0.2];

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

    /// The longest candidate period (seconds) `usable` on samples `range` (first, last).
    fn longest_usable_period(&self, range: (u32, u32), usable: Usable) -> Option<f64>;

    /// Up to `max` strongest components of `obs` (mean `mean`) among the periods `usable` on
    /// its observed range, strongest first.
    fn candidates(
        &self,
        obs: &VoxelObservations,
        mean: f64,
        max: usize,
        usable: Usable,
    ) -> Vec<Candidate>;
}

/// Cycles of a period that the earlier part of a voxel's samples (the validation fit) must
/// span, first sample to last, for the fit to estimate it there (at most `min-cycles`).
pub(crate) const VALIDATION_MIN_CYCLES: f64 = 1.5;

/// Relative slack when comparing a number of cycles with a span, so that a period that
/// fits exactly (the day on 48 half-hourly samples a day for 2 days) is not lost to rounding.
pub(crate) const CYCLE_TOLERANCE: f64 = 1e-9;

/// Which candidate periods a fit may use: the two roles of `min-cycles`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Usable {
    /// *Eligibility*, for the voxel's own fit: the periods whose `min_cycles` cycles the
    /// samples cover, counted from the first to the last plus one step (each sample stands
    /// for its step: n samples `s` apart cover `n·s`).
    Eligible,
    /// *Validation*, for a fit on the earlier part of a voxel observed from sample
    /// `whole.0` to `whole.1`: the periods eligible on the whole voxel that the earlier
    /// part spans [`VALIDATION_MIN_CYCLES`] times (or `min_cycles`, when less), counted
    /// first to last. So the held-out part never judges a period the final fit may not use,
    /// and a period with exactly two cycles in the whole span (the day on a 2-day series)
    /// is not estimated from the 1.5 days before the held-out part.
    Validation { whole: (u32, u32) },
}

/// Cycles the earlier part must span in a validation fit, for a model requiring `min_cycles`.
pub(crate) fn validation_cycles(min_cycles: f64) -> f64 {
    VALIDATION_MIN_CYCLES.min(min_cycles)
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
            let comps = quantise(&model.candidates(obs, mean, max, Usable::Eligible));
            finish(model, mean_q, comps, obs, OrderChoice::Single(max), mode)
        }
        (Order::Auto { .. }, OutlierMode::Lossless)
            if settings.criterion == crate::OrderCriterion::SmallestFile =>
        {
            let comps = quantise(&model.candidates(obs, mean, max, Usable::Eligible));
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
            let mut cands = model.candidates(obs, mean, m, Usable::Eligible);
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
    let Some(whole) = obs.observed_range() else {
        return (0, 1.0);
    };
    let fraction = holdout_fraction(model, obs, fraction);
    let train_count = ((1.0 - fraction) * n as f64).ceil() as u64;
    let split = obs.sample_after_observed(train_count.min(n));
    let train = obs.truncated(split);
    let test_count = n - train.observed_count();
    if train.observed_count() == 0 || test_count == 0 || train.is_constant().is_some() {
        return (0, 1.0);
    }
    let train_mean = train.occupied_count() as f64 / train.observed_count() as f64;
    let comps = quantise(&model.candidates(&train, train_mean, max, Usable::Validation { whole }));
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
    // Per order and factor: samples whose decision differs from the mean's.
    let mut differs = vec![vec![0u64; shrinks.len()]; comps.len() + 1];
    let mean_decision = mean > 0.5;
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
            for (m, ((errs, wrongs), diffs)) in sq_err
                .iter_mut()
                .zip(&mut wrong)
                .zip(&mut differs)
                .enumerate()
            {
                for (((err, w), diff), shrink) in errs
                    .iter_mut()
                    .zip(wrongs.iter_mut())
                    .zip(diffs.iter_mut())
                    .zip(shrinks)
                {
                    let p = (mean + shrink * periodic).clamp(0.0, 1.0);
                    let d = p - target;
                    *err += d * d;
                    *w += u64::from((p > 0.5) != run.state.is_occupied());
                    *diff += u64::from((p > 0.5) != mean_decision);
                }
                if let (Some(e), Some(a)) = (evaluables.get(m), angles.get(m)) {
                    periodic += e.value(*a);
                }
            }
            i += stride;
        }
    }
    // A shrinkage is validated only on a held-out part that spans a whole cycle of every
    // period of the order: a shorter one cannot tell a period that drifts from one that was
    // seen in part (a day's first half held out on a two-day series), and a shrinkage it
    // chose would soften what the samples cannot judge.
    let axis = model.time_axis();
    let last = obs.observed_range().map_or(split, |(_, last)| last);
    let holdout_span =
        axis.sample_seconds(last) - axis.sample_seconds(split) + axis.mean_step_seconds();
    let covered: Vec<bool> = (0..=comps.len())
        .map(|m| {
            comps
                .get(..m)
                .unwrap_or(&comps)
                .iter()
                .all(|c| model.rate(c) * holdout_span >= 1.0)
        })
        .collect();
    let mean_wrong = wrong.first().and_then(|w| w.first()).copied().unwrap_or(0);
    // Which (order, factor) pairs may be chosen. On a covering held-out part, any factor,
    // provided the decisions (p > 0.5) that differ from the mean's are right significantly
    // more often than wrong: a sign test, `gain ≥ DECISION_Z·√changed`, so a model whose
    // threshold crossings are a coin flip on the held-out part is shrunk (or cut) until it
    // no longer crosses there. Otherwise the unshrunk order alone, up to
    // UNVALIDATED_MAX_ORDER.
    let admissible = |m: usize, s: usize| -> bool {
        let cell = |table: &[Vec<u64>]| table.get(m).and_then(|r| r.get(s)).copied();
        if m == 0 {
            return s == 0;
        }
        if !covered.get(m).copied().unwrap_or(false) {
            return s == 0 && m <= UNVALIDATED_MAX_ORDER;
        }
        let (Some(w), Some(changed)) = (cell(&wrong), cell(&differs)) else {
            return false;
        };
        let gain = mean_wrong as f64 - w as f64;
        changed == 0 || gain >= DECISION_Z * (changed as f64).sqrt()
    };
    // The lowest order, then the weakest shrinkage, within 1 % of the best admissible score:
    // a component must earn its place, so noise-like voxels (whose spurious components fit
    // the held-out samples by chance) keep the mean alone instead of paying for components
    // that do not predict.
    let best = sq_err
        .iter()
        .enumerate()
        .flat_map(|(m, errs)| {
            errs.iter()
                .enumerate()
                .filter(move |&(s, _)| admissible(m, s))
                .map(|(_, &e)| e)
        })
        .fold(f64::INFINITY, f64::min);
    let good = |e: f64| e <= best * (1.0 + ORDER_TOLERANCE) + f64::EPSILON;
    sq_err
        .iter()
        .enumerate()
        .find_map(|(m, errs)| {
            let s = errs
                .iter()
                .enumerate()
                .position(|(s, &e)| good(e) && admissible(m, s))?;
            let shrink = shrinks.get(s).copied()?;
            Some((m, if m == 0 { 1.0 } else { shrink }))
        })
        .unwrap_or((0, 1.0))
}

/// Largest part of a voxel's samples held out to validate its order and shrinkage.
pub(crate) const MAX_HOLDOUT_FRACTION: f64 = 0.5;

/// The part of `obs`'s observed samples held out: half of them when a validation fit on the
/// first half may still use the longest period the whole voxel may use ([`Usable`]), so that
/// the held-out part holds as many cycles of every period as it can without the fit losing
/// one; else `fraction` (the option).
fn holdout_fraction<S: Spectral>(model: &S, obs: &VoxelObservations, fraction: f64) -> f64 {
    let Some((first, last)) = obs.observed_range() else {
        return fraction;
    };
    let n = obs.observed_count();
    let half = ((1.0 - MAX_HOLDOUT_FRACTION) * n as f64).ceil() as u64;
    let split = obs.sample_after_observed(half.min(n));
    let fit_last = split.saturating_sub(1).max(first);
    match (
        model.longest_usable_period((first, last), Usable::Eligible),
        model.longest_usable_period(
            (first, fit_last),
            Usable::Validation {
                whole: (first, last),
            },
        ),
    ) {
        (Some(whole), Some(fit)) if fit >= whole => fraction.max(MAX_HOLDOUT_FRACTION),
        _ => fraction,
    }
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

/// Whether two frequencies (turns per unit of time) cannot be told apart on samples spanning
/// `span` taken every `step` (units of time): they are closer than the span's resolution
/// `1/span`, or one is the other's alias on the sampling grid (`f_a ∓ f_b` within `1/span`
/// of a multiple of the sampling rate `1/step`). Such a pair fits the training span by
/// cancelling or reinforcing each other in ways the samples cannot check, and its beat
/// extrapolates into the future as a pattern nobody observed.
pub(crate) fn aliases(f_a: f64, f_b: f64, span: f64, step: f64) -> bool {
    if span.is_nan() || span <= 0.0 {
        return true;
    }
    // Frequencies exactly 1/span apart (neighbouring DFT bins) are resolvable.
    let resolution = (1.0 - 1e-9) / span;
    let rate = if step > 0.0 {
        1.0 / step
    } else {
        f64::INFINITY
    };
    let off_grid = |x: f64| {
        if rate.is_finite() {
            (x - rate * (x / rate).round()).abs()
        } else {
            x.abs()
        }
    };
    off_grid(f_a - f_b) < resolution || (f_a + f_b > resolution && off_grid(f_a + f_b) < resolution)
}

/// The strongest `max` of `offers` (`(strength, frequency index, frequency)`), strongest
/// first (ties to the lower index), skipping every offer that [`aliases`] one already
/// picked on `span` and `step`: no two chosen periods alias each other.
pub(crate) fn pick_distinct(
    mut offers: Vec<(f64, u32, f64)>,
    max: usize,
    span: f64,
    step: f64,
) -> Vec<(f64, u32)> {
    offers.retain(|&(key, _, _)| key > 0.0);
    offers.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut picked: Vec<(f64, u32, f64)> = Vec::with_capacity(max);
    for offer in offers {
        if picked.len() == max {
            break;
        }
        if picked.iter().all(|p| !aliases(p.2, offer.2, span, step)) {
            picked.push(offer);
        }
    }
    picked.into_iter().map(|(key, j, _)| (key, j)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::FremenPeriods;
    use crate::{ModelConfig, ObservationsBuilder, SpectralParameters, TemporalModel, TimeAxis};
    use froctomap_core::{Occupancy, Timestamp};

    /// Occupied 09:00-17:00 every day for three weeks, then on every other day only: the
    /// daily rhythm weakens in the held-out half. Unshrunk, the daily component puts p above
    /// 0.5 every working hour, right on half the held-out days and wrong on the others: a
    /// coin flip, which the decision test rejects.
    #[test]
    fn shrink_auto_softens_amplitudes_that_overshoot_the_held_out_part() {
        let n = 6 * 7 * 24;
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
        // Unshrunk, every order crosses 0.5 on a coin flip: the mean alone.
        assert!(components(&[("shrink", "off")]).is_empty());
        // Shrunk, the daily rhythm validates below 0.5: the same components as a fixed
        // order gives, with every amplitude scaled by one factor of the grid below 1, and p
        // never above 0.5 in the held-out half.
        let auto = components(&[("shrink", "auto")]);
        let model = FremenPeriods
            .prepare(&axis, &ModelConfig::default())
            .unwrap();
        let voxel = model.fit(&obs).unwrap();
        assert!((n / 2..n).all(|i| model.probability_at_sample(voxel.parameters(), i) <= 0.5));
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

    /// The periods a voxel's fit keeps, in hours, strongest first.
    fn kept_hours(
        axis: &TimeAxis,
        obs: &crate::VoxelObservations,
        options: &[(&str, &str)],
    ) -> Vec<f64> {
        let mut config = ModelConfig::default();
        for (k, v) in options {
            config = config.with_option(k, v);
        }
        let model = FremenPeriods.prepare(axis, &config).unwrap();
        let voxel = model.fit(obs).unwrap();
        model
            .describe(voxel.parameters())
            .unwrap()
            .periodic
            .iter()
            .map(|t| t.period_seconds / 3600.0)
            .collect()
    }

    /// A 6-hour rhythm (occupied the first 2 hours of every 6) with a deterministic
    /// pseudo-random 10 % of flipped samples, every 10 minutes for three weeks: the planted
    /// period is the strongest one kept, and the model predicts it a week later.
    #[test]
    fn a_planted_period_is_found_and_predicted() {
        let n = 3 * 7 * 144;
        let axis = TimeAxis::regular(Timestamp(0), 600_000_000_000, n, vec![]).unwrap();
        let mut b = ObservationsBuilder::new();
        let mut rng = 12345u64;
        for i in 0..n {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let flip = (rng >> 33) % 10 == 0;
            b.push(i, Some(Occupancy::from(((i % 36) < 12) ^ flip)))
                .unwrap();
        }
        let obs = b.finish();
        let hours = kept_hours(&axis, &obs, &[]);
        assert_eq!(hours.first(), Some(&6.0), "{hours:?}");
        let model = FremenPeriods
            .prepare(&axis, &ModelConfig::default())
            .unwrap();
        let voxel = model.fit(&obs).unwrap();
        let week = 7.0 * 86_400.0 * 4.0; // four weeks from the start: a week past the end
        assert!(model.probability(voxel.parameters(), week + 3600.0) > 0.5);
        assert!(model.probability(voxel.parameters(), week + 4.0 * 3600.0) < 0.5);
    }

    /// Two days of 30-minute samples of a voxel occupied 08:00-18:00 with a lunch break:
    /// the 1-day rhythm's shape has energy at 28 h, 24 h and 21 h (one week / 6, 7, 8),
    /// which two days cannot tell apart. At any order, no two kept periods alias each other.
    #[test]
    fn two_aliasing_periods_are_never_both_chosen() {
        let n = 96;
        let step = 1800.0;
        let axis = TimeAxis::regular(Timestamp(0), 1_800_000_000_000, n, vec![]).unwrap();
        let mut b = ObservationsBuilder::new();
        for i in 0..n {
            let hour = (i % 48) / 2;
            b.push(
                i,
                Some(Occupancy::from((8..18).contains(&hour) && hour != 12)),
            )
            .unwrap();
        }
        let obs = b.finish();
        let span = (f64::from(n) - 1.0) * step + step;
        for order in ["3", "5", "8"] {
            let hours = kept_hours(&axis, &obs, &[("order", order)]);
            assert!(hours.contains(&24.0), "{hours:?}");
            for (i, a) in hours.iter().enumerate() {
                for b in &hours[i + 1..] {
                    let (fa, fb) = (1.0 / (a * 3600.0), 1.0 / (b * 3600.0));
                    assert!(!aliases(fa, fb, span, step), "{a} h and {b} h in {hours:?}");
                }
            }
            assert!(
                !hours.contains(&21.0) && !hours.contains(&28.0),
                "{hours:?}"
            );
        }
    }

    #[test]
    fn pick_distinct_never_keeps_two_aliasing_periods() {
        // One day of 10-minute samples (frequencies in turns per hour).
        let (span, step) = (24.0, 1.0 / 6.0);
        // 24 h and 21 h cannot be told apart in one day; 12 h can.
        assert!(aliases(1.0 / 24.0, 1.0 / 21.0, span, step));
        assert!(!aliases(1.0 / 24.0, 1.0 / 12.0, span, step));
        // 6 per hour is the sampling rate: 1/(10 min + ε) aliases a very slow period.
        assert!(aliases(
            6.0 - 1.0 / 30.0,
            1.0 / 30.0 + 1.0 / 200.0,
            span,
            step
        ));
        assert!(aliases(6.0 - 1.0 / 30.0, 1.0 / 30.0, span, step)); // f_a + f_b = rate
        let offers = vec![
            (5.0, 0, 1.0 / 24.0),
            (4.0, 1, 1.0 / 21.0), // aliases the stronger 24 h
            (3.0, 2, 1.0 / 12.0),
            (3.0, 3, 1.0 / 11.0), // aliases 12 h
            (2.0, 4, 1.0 / 8.0),
            (0.0, 5, 1.0 / 6.0), // no strength
        ];
        assert_eq!(
            pick_distinct(offers.clone(), 5, span, step),
            [(5.0, 0), (3.0, 2), (2.0, 4)]
        );
        assert_eq!(
            pick_distinct(offers.clone(), 2, span, step),
            [(5.0, 0), (3.0, 2)]
        );
        // Over a long span every one is resolvable: the strongest five with strength.
        let long = pick_distinct(offers, 9, 1000.0, step);
        assert_eq!(
            long.iter().map(|o| o.1).collect::<Vec<_>>(),
            [0, 1, 2, 3, 4]
        );
    }
}
