//! FreMEn on a regular axis: the whole DFT spectrum by real FFT, every bin a candidate.

use super::spectral_line::SpectralLine;
use crate::fit::{
    fit_voxel, pick_distinct, validation_cycles, Candidate, Evaluator, FitSettings, Spectral,
    Usable, CYCLE_TOLERANCE,
};
use crate::model::{read_header_only_parameters, write_parameters_header};
use crate::spectral::options::{
    SpectralOptions, CRITERION, HOLDOUT_FRACTION, MAX_ORDER, MIN_CYCLES, ORDER, SHRINK,
};
use crate::spectral::{self, canonical_sum, SpectralView};
use crate::trig::cos_sin_turns;
use crate::{
    AxisKind, Component, FittedVoxel, ModelConfig, ModelDescriptor, ModelId, ModelOptions,
    OutlierMode, PreparedModel, TemporalError, TemporalModel, TimeAxis, VoxelDescription,
    VoxelObservations,
};
use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use std::sync::{Arc, OnceLock};

/// Registration of [`FremenRegular`].
pub const DESCRIPTOR: ModelDescriptor = ModelDescriptor {
    id: ModelId::FREMEN_REGULAR,
    name: "fremen-regular",
    description: "FreMEn over all DFT bins of a regular time axis (real FFT per voxel)",
    options: &[
        ORDER,
        MAX_ORDER,
        CRITERION,
        MIN_CYCLES,
        HOLDOUT_FRACTION,
        SHRINK,
    ],
    factory: || Box::new(FremenRegular),
};

/// Longest axis the FFT model accepts (samples).
pub const MAX_SAMPLES: u32 = 1 << 26;
/// Longest axis for which the unit-root table is cached (16 bytes per sample); longer axes
/// compute the same values on the fly.
const MAX_ROOT_TABLE: u32 = 1 << 22;

/// FreMEn on a regular axis of `n` samples (gaps allowed): the spectrum of `s_i − mean` over
/// the observed samples at every DFT bin `k` (period `n·step/k`), from one real FFT with
/// unknown samples set to zero, normalised by the observed count. Bins `k ≥ min_cycles·n /
/// coverage` (the voxel's observed samples, first to last plus one, hold `min_cycles` whole
/// cycles, default 2) up to the Nyquist bin `n/2` are candidates; the strongest are kept.
///
/// ```
/// use froctomap_core::{Occupancy::*, Timestamp};
/// use froctomap_temporal::{models::FremenRegular, *};
/// // 8 days of hourly samples: occupied from 9:00 to 17:00.
/// let axis = TimeAxis::regular(Timestamp(0), 3_600_000_000_000, 24 * 8, vec![])?;
/// let mut b = ObservationsBuilder::new();
/// for i in 0..24 * 8 {
///     let hour = i % 24;
///     b.push(i, Some(if (9..17).contains(&hour) { Occupied } else { Free }))?;
/// }
/// let obs = b.finish();
/// let model = FremenRegular.prepare(&axis, &ModelConfig::default().with_option("order", 1))?;
/// let voxel = model.fit(&obs)?;
/// let parameters = SpectralParameters::decode(voxel.parameters())?;
/// assert_eq!(parameters.components[0].frequency, 8); // one cycle per day
/// assert!(model.probability(voxel.parameters(), 13.0 * 3600.0) > 0.5);
/// assert!(model.probability(voxel.parameters(), 1.0 * 3600.0) < 0.5);
/// for (i, s) in obs.iter() {
///     assert_eq!(model.state_at_sample(&voxel, i), s); // lossless
/// }
/// # Ok::<(), TemporalError>(())
/// ```
#[derive(Debug, Clone, Copy, Default)]
pub struct FremenRegular;

impl FremenRegular {
    /// [`TemporalModel::prepare`] returning the concrete type (e.g. to read spectra).
    pub fn prepare_regular(
        &self,
        axis: &TimeAxis,
        config: &ModelConfig,
    ) -> Result<PreparedFremenRegular, TemporalError> {
        let options = SpectralOptions::parse(DESCRIPTOR.name, DESCRIPTOR.options, &config.options)?;
        PreparedFremenRegular::new(axis, &options, config.outliers)
    }
}

impl TemporalModel for FremenRegular {
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
        Ok(Box::new(self.prepare_regular(axis, config)?))
    }

    fn prepare_from_parameters(
        &self,
        axis: &TimeAxis,
        parameters: &[u8],
    ) -> Result<Box<dyn PreparedModel>, TemporalError> {
        let mode = read_header_only_parameters(parameters)?;
        Ok(Box::new(PreparedFremenRegular::new(
            axis,
            &SpectralOptions::default(),
            mode,
        )?))
    }
}

/// [`FremenRegular`] bound to an axis: FFT plan (made on first fit) and unit-root table.
pub struct PreparedFremenRegular {
    axis: TimeAxis,
    n: u32,
    /// `n · step` in seconds: the period of bin 1.
    base_seconds: f64,
    /// `(cos, sin)(2π·r/n)` for `r` in `0..n`, computed with [`cos_sin_turns`].
    roots: Vec<(f64, f64)>,
    fft: OnceLock<Arc<dyn RealToComplex<f64>>>,
    settings: FitSettings,
    min_cycles: f64,
}

impl std::fmt::Debug for PreparedFremenRegular {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PreparedFremenRegular")
            .field("n", &self.n)
            .field("base_seconds", &self.base_seconds)
            .field("settings", &self.settings)
            .finish_non_exhaustive()
    }
}

#[inline]
fn root(n: u32, r: u64) -> (f64, f64) {
    cos_sin_turns(r as f64 / f64::from(n))
}

impl PreparedFremenRegular {
    fn new(
        axis: &TimeAxis,
        config: &SpectralOptions,
        mode: OutlierMode,
    ) -> Result<Self, TemporalError> {
        let (AxisKind::Regular, Some(step_ns)) = (axis.kind(), axis.step_ns()) else {
            return Err(TemporalError::Unsupported {
                model: DESCRIPTOR.name,
                reason: "explicit time axes (use fremen-periods)",
            });
        };
        let n = axis.len();
        if n > MAX_SAMPLES {
            return Err(TemporalError::LimitExceeded {
                what: "samples of a fremen-regular axis",
                value: u64::from(n),
                limit: u64::from(MAX_SAMPLES),
            });
        }
        let roots = if n <= MAX_ROOT_TABLE {
            (0..u64::from(n)).map(|r| root(n, r)).collect()
        } else {
            Vec::new()
        };
        Ok(Self {
            axis: axis.clone(),
            n,
            base_seconds: f64::from(n) * (step_ns as f64 / 1e9),
            roots,
            fft: OnceLock::new(),
            settings: FitSettings {
                order: config.order,
                mode,
                criterion: config.criterion,
                holdout_fraction: config.holdout_fraction,
                shrink: config.shrink,
            },
            min_cycles: config.min_cycles,
        })
    }

    fn plan(&self) -> &Arc<dyn RealToComplex<f64>> {
        self.fft
            .get_or_init(|| RealFftPlanner::<f64>::new().plan_fft_forward(self.n as usize))
    }

    /// Unnormalised DFT `X_k = Σ_observed (s_i − mean)·e^{−j2πki/n}` for `k` in `0..=n/2`.
    fn dft(&self, obs: &VoxelObservations, mean: f64) -> Vec<Complex<f64>> {
        let plan = self.plan();
        let mut input = vec![0.0f64; self.n as usize];
        for run in obs.runs() {
            let value = if run.state.is_occupied() {
                1.0 - mean
            } else {
                -mean
            };
            let start = run.first as usize;
            let end = (run.end() as usize).min(input.len());
            if let Some(slice) = input.get_mut(start..end) {
                slice.fill(value);
            }
        }
        let mut output = plan.make_output_vec();
        let mut scratch = plan.make_scratch_vec();
        if plan
            .process_with_scratch(&mut input, &mut output, &mut scratch)
            .is_err()
        {
            // Only possible with mismatched buffer lengths, which the plan itself made.
            output.clear();
        }
        output
    }

    /// The spectrum `γ_k` of `obs` (already checked against the axis) for every bin
    /// `0..=n/2`, from the FFT. `γ_0` is zero up to rounding (the mean is subtracted).
    pub fn spectrum(&self, obs: &VoxelObservations) -> Result<Vec<SpectralLine>, TemporalError> {
        self.axis.check(obs)?;
        let count = obs.observed_count();
        if count == 0 {
            return Ok(Vec::new());
        }
        let mean = obs.occupied_count() as f64 / count as f64;
        let norm = 1.0 / count as f64;
        Ok(self
            .dft(obs, mean)
            .iter()
            .enumerate()
            .map(|(k, x)| SpectralLine {
                frequency: k as u32,
                period_seconds: self.base_seconds / k as f64,
                re: x.re * norm,
                im: x.im * norm,
            })
            .collect())
    }

    /// `(cos, sin)(2π·r/n)`, from the table when cached.
    #[inline]
    fn root_at(&self, r: u64) -> (f64, f64) {
        match self.roots.get(r as usize) {
            Some(v) => *v,
            None => root(self.n, r),
        }
    }

    /// One past the largest valid DFT bin: `n/2 + 1`.
    pub fn frequency_limit(&self) -> u32 {
        self.n / 2 + 1
    }

    /// The lowest bin (a whole number ≥ 1, as f64; NaN or above `n/2` when none) `usable`
    /// on samples `first..=last` (see [`Usable`]): bin k has period n/k samples.
    fn lowest_usable_bin(&self, (first, last): (u32, u32), usable: Usable) -> f64 {
        let n = f64::from(self.n);
        let least = |cycles: f64, samples: f64| {
            (cycles * n / samples * (1.0 - CYCLE_TOLERANCE))
                .ceil()
                .max(1.0)
        };
        match usable {
            // The samples cover their span plus one step (each stands for its step).
            Usable::Eligible => least(self.min_cycles, f64::from(last.saturating_sub(first)) + 1.0),
            Usable::Validation { whole } => least(
                validation_cycles(self.min_cycles),
                f64::from(last.saturating_sub(first)),
            )
            .max(self.lowest_usable_bin(whole, Usable::Eligible)),
        }
    }

    /// Turns per second of bin `k`.
    fn frequency_hz(&self, k: u32) -> f64 {
        f64::from(k) / self.base_seconds
    }
}

/// Base angles `2π·k·i/n` from the root table, advancing `k·i mod n` incrementally along runs.
pub(crate) struct RegularEval<'a> {
    model: &'a PreparedFremenRegular,
    bins: Vec<u64>,
    residues: Vec<u64>,
    last: Option<u32>,
}

impl Evaluator for RegularEval<'_> {
    #[inline]
    fn angles(&mut self, sample: u32, out: &mut [(f64, f64)]) {
        let n = u64::from(self.model.n);
        let sequential = self.last.is_some_and(|l| l.checked_add(1) == Some(sample));
        for ((o, &k), r) in out.iter_mut().zip(&self.bins).zip(self.residues.iter_mut()) {
            if sequential {
                *r += k;
                if *r >= n {
                    *r -= n;
                }
            } else {
                *r = (k * u64::from(sample)) % n;
            }
            *o = self.model.root_at(*r);
        }
        self.last = Some(sample);
    }
}

impl Spectral for PreparedFremenRegular {
    type Eval<'a> = RegularEval<'a>;

    fn evaluator<'a>(&'a self, components: &[Component]) -> RegularEval<'a> {
        let n = u64::from(self.n.max(1));
        RegularEval {
            model: self,
            // Frequencies are validated below n/2 when decoding; reduce anyway so the
            // incremental update stays below n.
            bins: components
                .iter()
                .map(|c| u64::from(c.frequency) % n)
                .collect(),
            residues: vec![0; components.len()],
            last: None,
        }
    }

    fn time_axis(&self) -> &TimeAxis {
        &self.axis
    }

    fn rate(&self, component: &Component) -> f64 {
        self.frequency_hz(component.frequency)
    }

    fn longest_usable_period(&self, range: (u32, u32), usable: Usable) -> Option<f64> {
        let k_min = self.lowest_usable_bin(range, usable);
        if k_min.is_nan() || k_min > f64::from(self.n / 2) {
            return None;
        }
        Some(1.0 / self.frequency_hz(k_min as u32))
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
        let span = f64::from(last - first);
        let nyquist = self.n / 2;
        let k_min = self.lowest_usable_bin((first, last), usable);
        if k_min.is_nan() || k_min > f64::from(nyquist) {
            return Vec::new();
        }
        let k_min = k_min as u32;
        let spectrum = self.dft(obs, mean);
        let offers = spectrum
            .iter()
            .enumerate()
            .skip(k_min as usize)
            .map(|(k, x)| {
                // A = 2|γ| except at Nyquist (n even), whose real line is its own conjugate.
                let weight = if 2 * k == self.n as usize { 1.0 } else { 4.0 };
                (
                    weight * x.norm_sqr(),
                    k as u32,
                    k as f64 / f64::from(self.n),
                )
            })
            .collect();
        let norm = 1.0 / obs.observed_count() as f64;
        // Frequencies in turns per sample: bins are 1/n apart, so only a voxel observed on
        // part of the axis has bins it cannot tell apart.
        pick_distinct(offers, max, span + 1.0, 1.0)
            .into_iter()
            .filter_map(|(key, k)| {
                let x = spectrum.get(k as usize)?;
                Some(Candidate {
                    frequency: k,
                    amplitude: key.sqrt() * norm,
                    phase_turns: x.im.atan2(x.re) / std::f64::consts::TAU,
                })
            })
            .collect()
    }
}

impl PreparedModel for PreparedFremenRegular {
    fn id(&self) -> ModelId {
        ModelId::FREMEN_REGULAR
    }

    fn axis(&self) -> &TimeAxis {
        &self.axis
    }

    fn outlier_mode(&self) -> OutlierMode {
        self.settings.mode
    }

    fn fit(&self, obs: &VoxelObservations) -> Result<FittedVoxel, TemporalError> {
        self.axis.check(obs)?;
        Ok(fit_voxel(self, &self.settings, obs))
    }

    fn parameters_len(&self, bytes: &[u8]) -> Result<usize, TemporalError> {
        spectral::parameters_len(bytes, self.frequency_limit())
    }

    fn probability(&self, parameters: &[u8], seconds_since_axis_start: f64) -> f64 {
        let t = seconds_since_axis_start;
        if !t.is_finite() {
            return SpectralView::new(parameters).mean();
        }
        canonical_sum(parameters, |c| {
            cos_sin_turns(t * self.frequency_hz(c.frequency))
        })
        .clamp(0.0, 1.0)
    }

    fn probability_at_sample(&self, parameters: &[u8], sample: u32) -> f64 {
        let n = u64::from(self.n.max(1));
        // The same residue the incremental evaluator reaches, so the same table entry.
        canonical_sum(parameters, |c| {
            let r = (u64::from(c.frequency) % n) * u64::from(sample) % n;
            self.root_at(r)
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
        spectral::describe(parameters, self.frequency_limit(), |k| {
            (k > 0).then(|| self.base_seconds / f64::from(k))
        })
    }

    fn encode_parameters(&self) -> Vec<u8> {
        let mut out = Vec::new();
        write_parameters_header(&mut out, self.settings.mode);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::Usable;
    use crate::{ObservationsBuilder, SpectralParameters};
    use froctomap_core::{Occupancy, Timestamp};

    fn prepared(n: u32, order: u8) -> PreparedFremenRegular {
        let axis = TimeAxis::regular(Timestamp(0), 1_000_000_000, n, vec![]).unwrap();
        FremenRegular
            .prepare_regular(&axis, &ModelConfig::default().with_option("order", order))
            .unwrap()
    }

    #[test]
    fn nyquist_line_counts_once() {
        let model = prepared(64, 1);
        let mut b = ObservationsBuilder::new();
        for i in 0..64 {
            b.push(i, Some(Occupancy::from(i % 2 == 0))).unwrap();
        }
        let voxel = model.fit(&b.finish()).unwrap();
        let components = SpectralParameters::decode(voxel.parameters())
            .unwrap()
            .components;
        assert_eq!(components[0].frequency, 32);
        assert!((components[0].amplitude() - 0.5).abs() < 1e-4);
        assert!(model.probability_at_sample(voxel.parameters(), 10) > 0.999);
        assert!(model.probability_at_sample(voxel.parameters(), 11) < 0.001);
        assert_eq!(voxel.model_errors(), Some(0));
    }

    #[test]
    fn short_observed_span_excludes_long_periods() {
        // A voxel seen only during samples 100..160 of 1000: its 60 samples cover 60, so
        // periods above 30 samples (bins below 34) are not usable with min_cycles 2.
        let model = prepared(1000, 3);
        let mut b = ObservationsBuilder::new();
        for i in 100..160 {
            b.push(i, Some(Occupancy::from(i < 130))).unwrap();
        }
        let voxel = model.fit(&b.finish()).unwrap();
        let components = SpectralParameters::decode(voxel.parameters())
            .unwrap()
            .components;
        assert!(!components.is_empty());
        for c in components {
            assert!(
                1000.0 / f64::from(c.frequency) * 2.0 <= 60.0,
                "bin {}",
                c.frequency
            );
        }
    }

    #[test]
    fn eligibility_counts_coverage_and_validation_needs_one_and_a_half_cycles_of_eligible_bins() {
        // 96 samples: bin 2 (48 samples) has exactly two cycles in their coverage; bin 1
        // has one. Usable::Validation on the first 72 (71 samples first to last): bins of
        // 1.5 cycles, k ≥ 1.5·96/71 → k ≥ 3, and never a bin not eligible on the whole.
        let model = prepared(96, 3);
        let longest = |range, usable| {
            model
                .longest_usable_period(range, usable)
                .map(|p: f64| p.round())
        };
        assert_eq!(longest((0, 95), Usable::Eligible), Some(48.0));
        assert_eq!(longest((1, 95), Usable::Eligible), Some(32.0)); // 95 cover < 96
        let validation = Usable::Validation { whole: (0, 95) };
        assert_eq!(longest((0, 71), validation), Some(32.0));
        assert_eq!(longest((0, 95), validation), Some(48.0)); // 1.5 · 48 ≤ 95
                                                              // The whole voxel decides eligibility: seen over 60 samples, no bin below 4.
        let validation = Usable::Validation { whole: (0, 59) };
        assert_eq!(longest((0, 95), validation), Some(24.0));
        // Validation never needs more cycles than eligibility asks for.
        let axis = TimeAxis::regular(Timestamp(0), 1_000_000_000, 96, vec![]).unwrap();
        let one = FremenRegular
            .prepare_regular(&axis, &ModelConfig::default().with_option("min-cycles", 1))
            .unwrap();
        let validation = Usable::Validation { whole: (0, 95) };
        assert_eq!(
            one.longest_usable_period((0, 48), validation)
                .map(f64::round),
            Some(48.0)
        );
    }

    #[test]
    fn sample_and_time_evaluation_agree() {
        let model = prepared(500, 4);
        let mut b = ObservationsBuilder::new();
        for i in 0..500u32 {
            b.push(i, Some(Occupancy::from((i * i) % 7 < 3))).unwrap();
        }
        let voxel = model.fit(&b.finish()).unwrap();
        for i in (0..500).step_by(7) {
            let a = model.probability_at_sample(voxel.parameters(), i);
            let b = model.probability(voxel.parameters(), f64::from(i));
            assert!((a - b).abs() < 1e-9);
        }
    }
}
