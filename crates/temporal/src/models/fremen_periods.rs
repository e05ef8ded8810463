//! FreMEn at a candidate period set, for any time axis (jittered times, missed frames).

use super::spectral_line::SpectralLine;
use crate::fit::{
    fit_voxel, pick_distinct, validation_cycles, Candidate, Evaluator, FitSettings, Spectral,
    Usable, CYCLE_TOLERANCE,
};
use crate::model::{expect_end, read_parameters_header, write_parameters_header};
use crate::spectral::options::{
    SpectralOptions, BASE_PERIOD, CRITERION, HARMONICS, HOLDOUT_FRACTION, MAX_ORDER, MIN_CYCLES,
    ORDER, PERIODS, SHRINK,
};
use crate::spectral::{self, canonical_sum, SpectralView};
use crate::trig::cos_sin_turns;
use crate::varint::{self, Reader};
use crate::{
    Component, FittedVoxel, ModelConfig, ModelDescriptor, ModelId, ModelOptions, OutlierMode,
    PreparedModel, TemporalError, TemporalModel, TimeAxis, VoxelDescription, VoxelObservations,
};
use std::sync::OnceLock;

/// Registration of [`FremenPeriods`].
pub const DESCRIPTOR: ModelDescriptor = ModelDescriptor {
    id: ModelId::FREMEN_PERIODS,
    name: "fremen-periods",
    description: "FreMEn at candidate periods (one week / k plus user periods), any time axis",
    options: &[
        ORDER,
        MAX_ORDER,
        CRITERION,
        PERIODS,
        BASE_PERIOD,
        HARMONICS,
        MIN_CYCLES,
        HOLDOUT_FRACTION,
        SHRINK,
    ],
    factory: || Box::new(FremenPeriods),
};

/// Largest prefix-sum table built for fitting (bytes).
pub const MAX_TABLE_BYTES: u64 = 4 << 30;

/// FreMEn at arbitrary timestamps: `γ_P = (1/N) Σ_observed (s_i − mean)·e^{−j2π·t_i/P}` at
/// each candidate period `P` (seconds), with `t_i` the real time of sample `i`.
///
/// Candidates: `base_period / k` for `k = 1..=harmonics` plus the configured extra periods,
/// deduplicated, longest first, keeping those of which the axis's samples cover `min_cycles`
/// (default 2) whole cycles, counted from the first sample to the last plus one step (each
/// sample stands for its step: `n` samples `s` apart cover `n·s`); per voxel a period is used
/// only when the voxel's observed samples cover `min_cycles` cycles of it the same way. The
/// list is the model's parameter block, so a reader evaluates the same periods.
///
/// Fitting cost: the axis gets prefix sums of `(cos, sin)(2π·t_i/P)` per period (shared by
/// all voxels; `16·K·(n+1)` bytes for `K` periods and `n` samples), so a voxel's spectrum
/// costs two table reads per run boundary and period: sums over all occupied and all free
/// runs give `Σ (s_i − mean)·e^{…} = (1 − mean)·S_occupied − mean·S_free`.
///
/// ```
/// use froctomap_core::{Occupancy::*, Timestamp};
/// use froctomap_temporal::{models::FremenPeriods, *};
/// // Two weeks of jittered, irregular snapshots of a voxel occupied 9:00-17:00 each day.
/// let mut times = Vec::new();
/// let mut t = 0i64;
/// while t < 14 * 86_400 {
///     times.push(Timestamp::from_secs(t));
///     t += 1_000 + (t * 7919) % 1_400; // 1000..2400 s apart
/// }
/// let axis = TimeAxis::explicit(times.clone())?;
/// let mut b = ObservationsBuilder::new();
/// for (i, ts) in times.iter().enumerate() {
///     let hour = (ts.as_secs_f64() / 3600.0) as i64 % 24;
///     b.push(i as u32, Some(if (9..17).contains(&hour) { Occupied } else { Free }))?;
/// }
/// let model = FremenPeriods.prepare(&axis, &ModelConfig::default().with_option("order", 1))?;
/// let voxel = model.fit(&b.finish())?;
/// // The strongest component is the daily one: week / 7.
/// let day = 15.0 * 86_400.0 + 13.0 * 3600.0; // a future day, 13:00
/// assert!(model.probability(voxel.parameters(), day) > 0.5);
/// assert!(model.probability(voxel.parameters(), day + 12.0 * 3600.0) < 0.5);
/// assert_eq!(model.describe(voxel.parameters())?.periodic[0].period_seconds, 86_400.0);
/// # Ok::<(), TemporalError>(())
/// ```
#[derive(Debug, Clone, Copy, Default)]
pub struct FremenPeriods;

impl FremenPeriods {
    /// [`TemporalModel::prepare`] returning the concrete type (e.g. to read spectra).
    pub fn prepare_periods(
        &self,
        axis: &TimeAxis,
        config: &ModelConfig,
    ) -> Result<PreparedFremenPeriods, TemporalError> {
        let options = SpectralOptions::parse(DESCRIPTOR.name, DESCRIPTOR.options, &config.options)?;
        let mut periods: Vec<f64> = (1..=options.harmonics)
            .map(|k| options.base_period / f64::from(k))
            .chain(options.periods.iter().copied())
            .collect();
        periods.sort_by(|a, b| b.total_cmp(a));
        periods.dedup_by(|b, a| (*a - *b).abs() <= 1e-9 * a.abs());
        // Eligibility on the whole axis: `min_cycles` cycles in the samples' coverage.
        let coverage = axis.coverage_seconds(0, axis.len().saturating_sub(1));
        periods.retain(|p| p * options.min_cycles <= coverage * (1.0 + CYCLE_TOLERANCE));
        Ok(PreparedFremenPeriods::new(
            axis,
            periods,
            &options,
            config.outliers,
        ))
    }
}

impl TemporalModel for FremenPeriods {
    fn descriptor(&self) -> &'static ModelDescriptor {
        &DESCRIPTOR
    }

    fn check_options(&self, options: &ModelOptions) -> Result<(), TemporalError> {
        SpectralOptions::parse(DESCRIPTOR.name, DESCRIPTOR.options, options).map(drop)
    }

    fn prepare(
        &self,
        axis: &TimeAxis,
        config: &ModelConfig,
    ) -> Result<Box<dyn PreparedModel>, TemporalError> {
        Ok(Box::new(self.prepare_periods(axis, config)?))
    }

    fn prepare_from_parameters(
        &self,
        axis: &TimeAxis,
        parameters: &[u8],
    ) -> Result<Box<dyn PreparedModel>, TemporalError> {
        let mut r = Reader::new(parameters);
        let mode = read_parameters_header(&mut r)?;
        let count = r.count("period count", SpectralOptions::MAX_PERIODS as u64, 8)?;
        let mut periods = Vec::with_capacity(count);
        for _ in 0..count {
            let p = r.f64_le("period")?;
            if !(p.is_finite() && p > 0.0) {
                return Err(TemporalError::Malformed("period (not a positive number)"));
            }
            periods.push(p);
        }
        expect_end(&r)?;
        Ok(Box::new(PreparedFremenPeriods::new(
            axis,
            periods,
            &SpectralOptions::default(),
            mode,
        )))
    }
}

/// [`FremenPeriods`] bound to an axis: the period list and (built on first fit) the shared
/// prefix-sum table.
#[derive(Debug)]
pub struct PreparedFremenPeriods {
    axis: TimeAxis,
    periods: Vec<f64>,
    /// `1 / P` per period, the factor the evaluation multiplies times by.
    frequencies: Vec<f64>,
    /// `prefix[i·K + j] = Σ_{l<i} (cos, sin)(2π·t_l/P_j)`.
    prefix: OnceLock<Vec<[f64; 2]>>,
    /// `angles[j·N + i] = (cos, sin)(2π·t_i/P_j)`, computed exactly as the evaluator would
    /// compute them (so lookups are bit-identical): a cache, built on first use when it
    /// fits [`MAX_ANGLE_TABLE_BYTES`].
    angles: OnceLock<Option<Vec<(f64, f64)>>>,
    settings: FitSettings,
    min_cycles: f64,
}

/// Largest per-sample angle table kept (64 MiB: 24 periods × 175,000 samples).
const MAX_ANGLE_TABLE_BYTES: u64 = 64 << 20;

impl PreparedFremenPeriods {
    fn new(
        axis: &TimeAxis,
        periods: Vec<f64>,
        config: &SpectralOptions,
        mode: OutlierMode,
    ) -> Self {
        Self {
            axis: axis.clone(),
            frequencies: periods.iter().map(|p| 1.0 / p).collect(),
            periods,
            prefix: OnceLock::new(),
            angles: OnceLock::new(),
            settings: FitSettings {
                order: config.order,
                mode,
                criterion: config.criterion,
                holdout_fraction: config.holdout_fraction,
                shrink: config.shrink,
            },
            min_cycles: config.min_cycles,
        }
    }

    /// The candidate periods in seconds, longest first; component frequencies index this list.
    pub fn periods(&self) -> &[f64] {
        &self.periods
    }

    fn table(&self) -> Result<&[[f64; 2]], TemporalError> {
        let k = self.periods.len() as u64;
        let bytes = (u64::from(self.axis.len()) + 1) * k * 16;
        if bytes > MAX_TABLE_BYTES {
            return Err(TemporalError::LimitExceeded {
                what: "fremen-periods table bytes",
                value: bytes,
                limit: MAX_TABLE_BYTES,
            });
        }
        Ok(self.prefix.get_or_init(|| {
            let k = self.periods.len();
            let n = self.axis.len();
            let mut table = Vec::with_capacity((n as usize + 1) * k);
            table.extend(std::iter::repeat_n([0.0, 0.0], k));
            for i in 0..n {
                let t = self.axis.sample_seconds(i);
                let base = i as usize * k;
                for (j, f) in self.frequencies.iter().enumerate() {
                    let (c, s) = cos_sin_turns(t * f);
                    let prev = table.get(base + j).copied().unwrap_or([0.0, 0.0]);
                    table.push([prev[0] + c, prev[1] + s]);
                }
            }
            table
        }))
    }

    /// Unnormalised `X_j = Σ_observed (s_i − mean)·e^{−j2π·t_i/P_j}` for every period.
    fn sums(&self, obs: &VoxelObservations, mean: f64) -> Result<Vec<[f64; 2]>, TemporalError> {
        let table = self.table()?;
        let k = self.periods.len();
        let mut occupied = vec![[0.0f64; 2]; k];
        let mut free = vec![[0.0f64; 2]; k];
        for run in obs.runs() {
            let (Some(a), Some(b)) = (
                table.get(run.first as usize * k..(run.first as usize + 1) * k),
                table.get(run.end() as usize * k..(run.end() as usize + 1) * k),
            ) else {
                continue; // unreachable: observations are checked against the axis
            };
            let acc = if run.state.is_occupied() {
                &mut occupied
            } else {
                &mut free
            };
            for ((s, pa), pb) in acc.iter_mut().zip(a).zip(b) {
                s[0] += pb[0] - pa[0];
                s[1] += pb[1] - pa[1];
            }
        }
        Ok(occupied
            .iter()
            .zip(&free)
            .map(|(o, f)| {
                let re = (1.0 - mean) * o[0] - mean * f[0];
                let im = (1.0 - mean) * o[1] - mean * f[1];
                [re, -im] // e^{−jθ} = cos θ − j sin θ
            })
            .collect())
    }

    /// The spectrum `γ_j` of `obs` at every period of [`periods`](Self::periods).
    pub fn spectrum(&self, obs: &VoxelObservations) -> Result<Vec<SpectralLine>, TemporalError> {
        self.axis.check(obs)?;
        let count = obs.observed_count();
        if count == 0 {
            return Ok(Vec::new());
        }
        let mean = obs.occupied_count() as f64 / count as f64;
        let norm = 1.0 / count as f64;
        Ok(self
            .sums(obs, mean)?
            .iter()
            .enumerate()
            .map(|(j, x)| SpectralLine {
                frequency: j as u32,
                period_seconds: self.periods.get(j).copied().unwrap_or(f64::NAN),
                re: x[0] * norm,
                im: x[1] * norm,
            })
            .collect())
    }

    /// Whether a period (seconds) is `usable` on samples `first..=last` (see [`Usable`]).
    fn is_usable(&self, period: f64, (first, last): (u32, u32), usable: Usable) -> bool {
        let fits = |cycles: f64, seconds: f64| period * cycles <= seconds * (1.0 + CYCLE_TOLERANCE);
        match usable {
            Usable::Eligible => fits(self.min_cycles, self.axis.coverage_seconds(first, last)),
            Usable::Validation { whole } => {
                let span = self.axis.sample_seconds(last) - self.axis.sample_seconds(first);
                fits(validation_cycles(self.min_cycles), span)
                    && self.is_usable(period, whole, Usable::Eligible)
            }
        }
    }

    fn frequency(&self, index: u32) -> f64 {
        self.frequencies.get(index as usize).copied().unwrap_or(0.0)
    }

    /// The per-sample angle cache, if it fits.
    fn angle_table(&self) -> Option<&[(f64, f64)]> {
        self.angles
            .get_or_init(|| {
                let n = self.axis.len() as usize;
                let bytes = (n as u64) * (self.frequencies.len() as u64) * 16;
                (bytes <= MAX_ANGLE_TABLE_BYTES).then(|| {
                    let mut table = Vec::with_capacity(n * self.frequencies.len());
                    for f in &self.frequencies {
                        for i in 0..n {
                            table.push(angle(&self.axis, *f, i as u32));
                        }
                    }
                    table
                })
            })
            .as_deref()
    }
}

/// The base angle `2π·t_i·f` of a sample: the one computation both the table and direct
/// evaluation use, so they agree bit for bit.
#[inline]
fn angle(axis: &TimeAxis, frequency: f64, sample: u32) -> (f64, f64) {
    cos_sin_turns(axis.sample_seconds(sample) * frequency)
}

/// The angle table and the row offset of each component's period in it.
type CachedRows<'a> = (&'a [(f64, f64)], Vec<usize>);

/// Base angles `2π·t_i/P` per sample, from the cached table or computed with
/// [`cos_sin_turns`].
pub(crate) struct PeriodsEval<'a> {
    axis: &'a TimeAxis,
    frequencies: Vec<f64>,
    /// The cached table and, per component, the offset of its period's row.
    table: Option<CachedRows<'a>>,
}

impl Evaluator for PeriodsEval<'_> {
    #[inline]
    fn angles(&mut self, sample: u32, out: &mut [(f64, f64)]) {
        match &self.table {
            // Samples beyond the axis (extrapolated) are not in the table.
            Some((table, rows)) if sample < self.axis.len() => {
                for ((o, row), f) in out.iter_mut().zip(rows).zip(&self.frequencies) {
                    *o = match table.get(row + sample as usize) {
                        Some(&cached) => cached,
                        None => angle(self.axis, *f, sample),
                    };
                }
            }
            _ => {
                for (o, f) in out.iter_mut().zip(&self.frequencies) {
                    *o = angle(self.axis, *f, sample);
                }
            }
        }
    }
}

impl Spectral for PreparedFremenPeriods {
    type Eval<'a> = PeriodsEval<'a>;

    fn evaluator<'a>(&'a self, components: &[Component]) -> PeriodsEval<'a> {
        let n = self.axis.len() as usize;
        PeriodsEval {
            axis: &self.axis,
            frequencies: components
                .iter()
                .map(|c| self.frequency(c.frequency))
                .collect(),
            table: self.angle_table().map(|table| {
                let rows = components
                    .iter()
                    .map(|c| c.frequency as usize * n)
                    .collect();
                (table, rows)
            }),
        }
    }

    fn time_axis(&self) -> &TimeAxis {
        &self.axis
    }

    fn rate(&self, component: &Component) -> f64 {
        self.frequency(component.frequency)
    }

    fn longest_usable_period(&self, range: (u32, u32), usable: Usable) -> Option<f64> {
        self.periods
            .iter()
            .copied()
            .find(|&p| self.is_usable(p, range, usable))
    }

    fn candidates(
        &self,
        obs: &VoxelObservations,
        mean: f64,
        max: usize,
        usable: Usable,
    ) -> Vec<Candidate> {
        let Some((first, last)) = obs.observed_range() else {
            return Vec::new();
        };
        let span = self.axis.sample_seconds(last) - self.axis.sample_seconds(first);
        let Ok(sums) = self.sums(obs, mean) else {
            return Vec::new();
        };
        let offers = sums
            .iter()
            .zip(&self.periods)
            .enumerate()
            .filter(|(_, (_, p))| self.is_usable(**p, (first, last), usable))
            .map(|(j, (x, p))| (4.0 * (x[0] * x[0] + x[1] * x[1]), j as u32, 1.0 / p))
            .collect();
        // The samples cover their span plus one step (each stands for its step).
        let step = self.axis.mean_step_seconds();
        let norm = 1.0 / obs.observed_count() as f64;
        pick_distinct(offers, max, span + step, step)
            .into_iter()
            .filter_map(|(key, j)| {
                let x = sums.get(j as usize)?;
                Some(Candidate {
                    frequency: j,
                    amplitude: key.sqrt() * norm,
                    phase_turns: x[1].atan2(x[0]) / std::f64::consts::TAU,
                })
            })
            .collect()
    }
}

impl PreparedModel for PreparedFremenPeriods {
    fn id(&self) -> ModelId {
        ModelId::FREMEN_PERIODS
    }

    fn axis(&self) -> &TimeAxis {
        &self.axis
    }

    fn outlier_mode(&self) -> OutlierMode {
        self.settings.mode
    }

    fn fit(&self, obs: &VoxelObservations) -> Result<FittedVoxel, TemporalError> {
        self.axis.check(obs)?;
        if obs.is_constant().is_none() && self.settings.order.max() > 0 {
            self.table()?; // surface the table-size limit as an error, not an empty fit
        }
        Ok(fit_voxel(self, &self.settings, obs))
    }

    fn parameters_len(&self, bytes: &[u8]) -> Result<usize, TemporalError> {
        spectral::parameters_len(bytes, self.periods.len() as u32)
    }

    fn probability(&self, parameters: &[u8], seconds_since_axis_start: f64) -> f64 {
        let t = seconds_since_axis_start;
        if !t.is_finite() {
            return SpectralView::new(parameters).mean();
        }
        canonical_sum(parameters, |c| {
            cos_sin_turns(t * self.frequency(c.frequency))
        })
        .clamp(0.0, 1.0)
    }

    fn probability_at_sample(&self, parameters: &[u8], sample: u32) -> f64 {
        // Exactly the evaluator's computation for this sample.
        let t = self.axis.sample_seconds(sample);
        canonical_sum(parameters, |c| {
            cos_sin_turns(t * self.frequency(c.frequency))
        })
        .clamp(0.0, 1.0)
    }

    fn mean(&self, parameters: &[u8]) -> f64 {
        SpectralView::new(parameters).mean()
    }

    fn is_constant(&self, parameters: &[u8]) -> bool {
        SpectralView::new(parameters).is_empty()
    }

    fn describe(&self, parameters: &[u8]) -> Result<VoxelDescription, TemporalError> {
        spectral::describe(parameters, self.periods.len() as u32, |j| {
            self.periods.get(j as usize).copied()
        })
    }

    /// Header, then `varint K` and the `K` periods as f64 LE seconds.
    fn encode_parameters(&self) -> Vec<u8> {
        let mut out = Vec::new();
        write_parameters_header(&mut out, self.settings.mode);
        varint::write_u64(&mut out, self.periods.len() as u64);
        for p in &self.periods {
            out.extend_from_slice(&p.to_le_bytes());
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::Usable;
    use froctomap_core::Timestamp;

    #[test]
    fn period_set_is_deduplicated_sorted_and_spanned() {
        // 3 weeks of hourly samples.
        let axis = TimeAxis::regular(Timestamp(0), 3_600_000_000_000, 21 * 24, vec![]).unwrap();
        let config = ModelConfig::default().with_option("periods", "86400,18000,1e9");
        let model = FremenPeriods.prepare_periods(&axis, &config).unwrap();
        let p = model.periods();
        assert!(p.windows(2).all(|w| w[0] > w[1]));
        assert_eq!(p.iter().filter(|&&x| x == 86_400.0).count(), 1); // week/7 == 1 day
        assert!(p.contains(&18_000.0));
        assert!(!p.contains(&1e9));
        // The samples cover 504 hours: one week (168 h) fits 3 times, so it is kept.
        assert_eq!(p.first(), Some(&604_800.0));
        assert_eq!(p.len(), 48 + 1); // the default 48 harmonics and 5 h

        let params = model.encode_parameters();
        let back = FremenPeriods
            .prepare_from_parameters(&axis, &params)
            .unwrap();
        assert_eq!(back.encode_parameters(), params);
    }

    #[test]
    fn eligibility_counts_two_cycles_in_coverage_and_validation_one_and_a_half_in_span() {
        // 2 days of half-hourly samples: 96 samples cover 48 h (the last one stands for the
        // half hour after it), so the day has exactly two cycles and is a candidate; 28 h
        // (week / 6) is not, nor is the day on one sample less.
        let step = 1_800_000_000_000;
        let axis = TimeAxis::regular(Timestamp(0), step, 96, vec![]).unwrap();
        let model = FremenPeriods
            .prepare_periods(&axis, &ModelConfig::default())
            .unwrap();
        assert_eq!(model.periods().first(), Some(&86_400.0));
        let longest = |range, usable| model.longest_usable_period(range, usable);
        assert_eq!(longest((0, 95), Usable::Eligible), Some(86_400.0));
        assert_eq!(longest((1, 95), Usable::Eligible), Some(604_800.0 / 8.0));
        // A validation fit on the first 72 samples (35.5 h first to last) keeps periods with
        // 1.5 cycles there: 21 h, not the day (36 h needed).
        let whole = (0, 95);
        let validation = Usable::Validation { whole };
        assert_eq!(longest((0, 71), validation), Some(604_800.0 / 8.0));
        // With min-cycles 1.5 the axis keeps 28 h; validation on the whole range would
        // offer it, but not when the voxel itself covers less than 42 h.
        let model = FremenPeriods
            .prepare_periods(
                &axis,
                &ModelConfig::default().with_option("min-cycles", 1.5),
            )
            .unwrap();
        assert_eq!(model.periods().first(), Some(&(604_800.0 / 6.0)));
        assert_eq!(
            model.longest_usable_period((0, 95), validation),
            Some(604_800.0 / 6.0)
        );
        assert_eq!(
            model.longest_usable_period((0, 95), Usable::Validation { whole: (0, 80) }),
            Some(86_400.0)
        );
        let shorter = TimeAxis::regular(Timestamp(0), step, 95, vec![]).unwrap();
        let model = FremenPeriods
            .prepare_periods(&shorter, &ModelConfig::default())
            .unwrap();
        assert_eq!(model.periods().first(), Some(&(604_800.0 / 8.0)));
    }

    #[test]
    fn table_limit_is_an_error() {
        let axis = TimeAxis::regular(Timestamp(0), 1_000_000_000, u32::MAX, vec![]).unwrap();
        let model = FremenPeriods
            .prepare_periods(&axis, &ModelConfig::default())
            .unwrap();
        let obs = crate::VoxelObservations::from_runs([
            (0, 1, froctomap_core::Occupancy::Free),
            (5, 1, froctomap_core::Occupancy::Occupied),
        ])
        .unwrap();
        assert!(matches!(
            model.fit(&obs),
            Err(TemporalError::LimitExceeded { .. })
        ));
    }
}
