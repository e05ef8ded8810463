//! A two-state Markov chain per voxel ("HMM-lite"): the voxel remembers its last observed
//! state and relaxes to its stationary occupancy. Not spectral: it proves that a model owns
//! its voxel bytes, its options and its evaluation.

use crate::model::{read_header_only_parameters, write_parameters_header};
use crate::spectral::{quantise_unit, unit};
use crate::toggles::ToggleBuilder;
use crate::varint::{self, Reader};
use crate::{
    FittedVoxel, ModelConfig, ModelDescriptor, ModelId, OutlierMode, PreparedModel, TemporalError,
    TemporalModel, TimeAxis, VoxelDescription, VoxelObservations,
};

/// Registration of [`Markov`].
pub const DESCRIPTOR: ModelDescriptor = ModelDescriptor {
    id: ModelId(3),
    name: "markov",
    description: "two-state Markov chain: remembers the last observed state, relaxes to the stationary occupancy",
    options: &[],
    factory: || Box::new(Markov),
};

/// The two-state continuous-time Markov chain of a voxel.
///
/// Fitting: the stationary occupancy `π` is the observed mean; the mixing rate `λ = a + b`
/// (`a` free→occupied, `b` occupied→free, per second) comes from the state changes `C`
/// between consecutive observed samples over the observed span `T`: a stationary chain
/// changes state `2·π·(1−π)·λ` times per second, so `λ = C / (2·π·(1−π)·T)` (changes between
/// two samples count once, so fast chains are underestimated).
///
/// Prediction: `p(t) = π` up to the voxel's last observation `t_last`, then
/// `p(t) = π + (s_last − π)·e^{−λ·(t − t_last)}`: the chain remembers its last state and
/// forgets it at rate `λ`. At observed samples `p` is `π` exactly, so the outlier set (and
/// with it lossless reconstruction) depends on no floating-point library.
///
/// Voxel parameters: `u16 LE` `π·65535`, varint `2·last_sample + s_last`, `f32 LE` `λ`
/// (finite, ≥ 0).
///
/// ```
/// use froctomap_core::{Occupancy::*, Timestamp};
/// use froctomap_temporal::{models::markov::Markov, *};
/// // Hourly samples: free for 30 hours, then occupied for the last 10.
/// let axis = TimeAxis::regular(Timestamp(0), 3_600_000_000_000, 40, vec![])?;
/// let obs = VoxelObservations::from_runs([(0, 30, Free), (30, 10, Occupied)])?;
/// let model = Markov.prepare(&axis, &ModelConfig::default())?;
/// let voxel = model.fit(&obs)?;
/// assert!((model.mean(voxel.parameters()) - 0.25).abs() < 1e-4);
/// assert!(model.probability(voxel.parameters(), 40.0 * 3600.0) > 0.9); // just after: occupied
/// assert!((model.probability(voxel.parameters(), 1e9) - 0.25).abs() < 1e-3); // later: π
/// for (i, s) in obs.iter() {
///     assert_eq!(model.state_at_sample(&voxel, i), s); // lossless
/// }
/// # Ok::<(), TemporalError>(())
/// ```
#[derive(Debug, Clone, Copy, Default)]
pub struct Markov;

impl TemporalModel for Markov {
    fn descriptor(&self) -> &'static ModelDescriptor {
        &DESCRIPTOR
    }

    fn prepare(
        &self,
        axis: &TimeAxis,
        config: &ModelConfig,
    ) -> Result<Box<dyn PreparedModel>, TemporalError> {
        self.check_options(&config.options)?;
        Ok(Box::new(PreparedMarkov {
            axis: axis.clone(),
            mode: config.outliers,
        }))
    }

    fn prepare_from_parameters(
        &self,
        axis: &TimeAxis,
        parameters: &[u8],
    ) -> Result<Box<dyn PreparedModel>, TemporalError> {
        let mode = read_header_only_parameters(parameters)?;
        Ok(Box::new(PreparedMarkov {
            axis: axis.clone(),
            mode,
        }))
    }
}

/// [`Markov`] bound to an axis.
#[derive(Debug, Clone)]
pub struct PreparedMarkov {
    axis: TimeAxis,
    mode: OutlierMode,
}

/// One voxel's chain, as stored.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Chain {
    stationary_q: u16,
    last_sample: u32,
    last_occupied: bool,
    rate: f32,
}

impl Chain {
    fn encode(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.stationary_q.to_le_bytes());
        varint::write_u64(
            out,
            u64::from(self.last_sample) << 1 | u64::from(self.last_occupied),
        );
        out.extend_from_slice(&self.rate.to_le_bytes());
    }

    /// Reads and validates a chain whose last sample must be below `sample_limit`.
    fn read(r: &mut Reader<'_>, sample_limit: u32) -> Result<Self, TemporalError> {
        let stationary_q = r.u16_le("markov voxel")?;
        let last = r.u64()?;
        let last_sample = u32::try_from(last >> 1)
            .ok()
            .filter(|&s| s < sample_limit)
            .ok_or(TemporalError::Malformed(
                "markov last sample beyond the axis",
            ))?;
        let rate = f32::from_le_bytes(r.array::<4>("markov voxel")?);
        if !(rate.is_finite() && rate >= 0.0) {
            return Err(TemporalError::Malformed("markov rate (not a finite rate)"));
        }
        Ok(Self {
            stationary_q,
            last_sample,
            last_occupied: last & 1 == 1,
            rate,
        })
    }

    /// Reads bytes that passed [`Chain::read`]; others give an empty chain.
    fn view(parameters: &[u8]) -> Self {
        Self::read(&mut Reader::new(parameters), u32::MAX).unwrap_or(Self {
            stationary_q: 0,
            last_sample: 0,
            last_occupied: false,
            rate: 0.0,
        })
    }

    fn stationary(&self) -> f64 {
        unit(self.stationary_q)
    }
}

impl PreparedMarkov {
    /// `p` at `seconds` given the time of the last observation.
    fn relaxed(&self, chain: &Chain, seconds: f64) -> f64 {
        let pi = chain.stationary();
        let since = seconds - self.axis.sample_seconds(chain.last_sample);
        // A non-finite time gives the mean, as for every model.
        if !since.is_finite() || since <= 0.0 {
            return pi;
        }
        let last = f64::from(u8::from(chain.last_occupied));
        let memory = match chain.rate {
            0.0 => 1.0,
            rate => (-f64::from(rate) * since).exp(),
        };
        (pi + (last - pi) * memory).clamp(0.0, 1.0)
    }
}

impl PreparedModel for PreparedMarkov {
    fn id(&self) -> ModelId {
        DESCRIPTOR.id
    }

    fn axis(&self) -> &TimeAxis {
        &self.axis
    }

    fn outlier_mode(&self) -> OutlierMode {
        self.mode
    }

    fn fit(&self, obs: &VoxelObservations) -> Result<FittedVoxel, TemporalError> {
        self.axis.check(obs)?;
        let mut out = Vec::with_capacity(12);
        let Some((first, last)) = obs.observed_range() else {
            Chain::view(&[]).encode(&mut out);
            return Ok(FittedVoxel::new(&out, Default::default()).with_model_errors(0));
        };
        let pi = obs.occupied_count() as f64 / obs.observed_count() as f64;
        let changes = obs
            .runs()
            .windows(2)
            .filter(|w| matches!(w, [a, b] if a.state != b.state))
            .count() as f64;
        let span = self.axis.sample_seconds(last) - self.axis.sample_seconds(first);
        let rate = changes / (2.0 * pi * (1.0 - pi) * span);
        let chain = Chain {
            stationary_q: quantise_unit(pi),
            last_sample: last,
            last_occupied: obs.state_at(last).is_some_and(|s| s.is_occupied()),
            rate: if rate.is_finite() { rate as f32 } else { 0.0 },
        };
        chain.encode(&mut out);
        // p is π at every observed sample: the outliers are where the state is not π's side.
        let predicted = chain.stationary() > 0.5;
        let mut toggles = ToggleBuilder::new(self.mode == OutlierMode::Lossless);
        for run in obs.runs() {
            toggles.push_run(run.first, run.len, predicted != run.state.is_occupied());
        }
        let errors = toggles.disagreements();
        Ok(FittedVoxel::new(&out, toggles.finish()).with_model_errors(errors))
    }

    fn parameters_len(&self, bytes: &[u8]) -> Result<usize, TemporalError> {
        let mut r = Reader::new(bytes);
        Chain::read(&mut r, self.axis.len().max(1))?;
        Ok(r.position())
    }

    fn probability(&self, parameters: &[u8], seconds_since_axis_start: f64) -> f64 {
        self.relaxed(&Chain::view(parameters), seconds_since_axis_start)
    }

    fn probability_at_sample(&self, parameters: &[u8], sample: u32) -> f64 {
        let chain = Chain::view(parameters);
        if sample <= chain.last_sample {
            // Every observed sample: exact, no libm.
            chain.stationary()
        } else {
            self.relaxed(&chain, self.axis.sample_seconds(sample))
        }
    }

    fn mean(&self, parameters: &[u8]) -> f64 {
        Chain::view(parameters).stationary()
    }

    fn is_constant(&self, parameters: &[u8]) -> bool {
        let chain = Chain::view(parameters);
        match chain.stationary_q {
            0 => !chain.last_occupied,
            u16::MAX => chain.last_occupied,
            _ => false,
        }
    }

    fn describe(&self, parameters: &[u8]) -> Result<VoxelDescription, TemporalError> {
        self.parameters_len(parameters)?;
        Ok(VoxelDescription {
            mean: self.mean(parameters),
            periodic: Vec::new(),
        })
    }

    fn encode_parameters(&self) -> Vec<u8> {
        let mut out = Vec::new();
        write_parameters_header(&mut out, self.mode);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::{Occupancy, Timestamp};

    fn prepared(n: u32) -> Box<dyn PreparedModel> {
        let axis = TimeAxis::regular(Timestamp(0), 60_000_000_000, n, vec![]).unwrap();
        Markov.prepare(&axis, &ModelConfig::default()).unwrap()
    }

    #[test]
    fn remembers_the_last_state_then_relaxes_to_the_stationary_occupancy() {
        // A door that is open a fifth of the time, in 20-minute bouts every 100 minutes,
        // last seen open.
        let model = prepared(1000);
        let runs = (0..10u32).flat_map(|k| {
            [
                (k * 100, 80, Occupancy::Free),
                (k * 100 + 80, 20, Occupancy::Occupied),
            ]
        });
        let obs = VoxelObservations::from_runs(runs).unwrap();
        let voxel = model.fit(&obs).unwrap();
        let p = voxel.parameters();
        assert!((model.mean(p) - 0.2).abs() < 1e-4);
        assert!(!model.is_constant(p));
        let end = 1000.0 * 60.0;
        assert!(
            model.probability(p, end + 60.0) > 0.9,
            "just after: still open"
        );
        assert!((model.probability(p, end + 30.0 * 86_400.0) - 0.2).abs() < 1e-3);
        assert!(model.probability_at_sample(p, 1000 + 1) > 0.9);
        // Within the observed span p is π: the threshold says free, the toggles say the rest.
        assert_eq!(model.probability_at_sample(p, 90), model.mean(p));
        assert_eq!(voxel.model_errors(), Some(200));
        for (i, s) in obs.iter() {
            assert_eq!(model.state_at_sample(&voxel, i), s);
        }
        // Rate: 20 changes over 999 minutes, π(1−π) = 0.16.
        let rate = 19.0 / (2.0 * 0.16 * 999.0 * 60.0);
        let chain = Chain::view(p);
        assert!((f64::from(chain.rate) - rate).abs() < 1e-6 * rate);
    }

    #[test]
    fn constant_voxels_are_constant_and_empty_voxels_encode() {
        let model = prepared(10);
        let obs = VoxelObservations::from_runs([(2, 5, Occupancy::Occupied)]).unwrap();
        let voxel = model.fit(&obs).unwrap();
        assert!(model.is_constant(voxel.parameters()));
        assert_eq!(model.probability(voxel.parameters(), 1e9), 1.0);
        let empty = model.fit(&VoxelObservations::default()).unwrap();
        assert_eq!(
            model.parameters_len(empty.parameters()),
            Ok(empty.parameters().len())
        );
        assert_eq!(model.probability(empty.parameters(), 3.0), 0.0);
    }

    #[test]
    fn hostile_parameters_are_rejected() {
        let model = prepared(10);
        let good = Chain {
            stationary_q: 7,
            last_sample: 9,
            last_occupied: true,
            rate: 0.5,
        };
        let mut bytes = Vec::new();
        good.encode(&mut bytes);
        assert_eq!(model.parameters_len(&bytes), Ok(bytes.len()));
        for cut in 0..bytes.len() {
            assert!(model.parameters_len(&bytes[..cut]).is_err());
        }
        for bad in [
            Chain {
                last_sample: 10,
                ..good
            },
            Chain {
                rate: f32::NAN,
                ..good
            },
            Chain {
                rate: f32::INFINITY,
                ..good
            },
            Chain { rate: -1.0, ..good },
        ] {
            let mut bytes = Vec::new();
            bad.encode(&mut bytes);
            assert!(model.parameters_len(&bytes).is_err(), "{bad:?}");
            assert!(model.describe(&bytes).is_err());
        }
        // A last sample beyond u32 is rejected, not truncated.
        let mut huge = vec![0, 0];
        varint::write_u64(&mut huge, u64::MAX);
        huge.extend_from_slice(&0f32.to_le_bytes());
        assert!(model.parameters_len(&huge).is_err());
    }
}
