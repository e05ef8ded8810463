//! A fitted voxel: quantised spectral parameters plus its outlier set.

use crate::toggles::Toggles;
use crate::trig::cos_sin_turns;
use crate::varint::{self, Reader};
use crate::TemporalError;

/// Most components a voxel may have (orders are `u8`).
pub const MAX_COMPONENTS: usize = u8::MAX as usize;

/// Scale of the quantised mean and amplitudes: value = q / 65535, so 0 and 1 are exact.
const UNIT_SCALE: f64 = 65535.0;
/// Scale of the quantised phase: φ = 2π · q / 65536.
const PHASE_SCALE: f64 = 65536.0;

/// Quantises a value in `[0, 1]` (clamped) to `u16`, rounding to nearest.
pub(crate) fn quantise_unit(x: f64) -> u16 {
    let q = (x.clamp(0.0, 1.0) * UNIT_SCALE).round();
    // In [0, 65535] after the clamp; NaN becomes 0.
    if q.is_nan() {
        0
    } else {
        q as u16
    }
}

/// Quantises a phase in turns to `u16` (whole turns wrap).
pub(crate) fn quantise_phase(turns: f64) -> u16 {
    let r = turns - turns.floor();
    let q = (r * PHASE_SCALE).round();
    if q.is_nan() || q >= PHASE_SCALE {
        0
    } else {
        q as u16
    }
}

/// One spectral component `A·cos(2π·t/P + φ)` with quantised amplitude and phase.
///
/// Quantisation: `A = amplitude_q / 65535` (FreMEn amplitudes `2|γ|` never exceed 1, since
/// `|γ| ≤ 2μ(1−μ) ≤ 1/2`), error ≤ 7.7e-6; `φ = 2π·phase_q / 65536`, error ≤ 4.8e-5 rad. With
/// the mean's 7.7e-6, `p(t)` moves by at most `7.7e-6 + Σ_c (7.7e-6 + 4.8e-5·A_c)` (≤ 2.9e-4
/// at order 5) from the unquantised fit. Outliers are computed from the quantised values, so
/// lossless reconstruction is exact regardless.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Component {
    /// Model-specific frequency index: the DFT bin for `FremenRegular` (period = axis length /
    /// bin), the index into the parameter period list for `FremenPeriods`.
    pub frequency: u32,
    /// Quantised amplitude.
    pub amplitude_q: u16,
    /// Quantised phase.
    pub phase_q: u16,
}

impl Component {
    /// Amplitude `A` in `[0, 1]`.
    pub fn amplitude(&self) -> f64 {
        f64::from(self.amplitude_q) / UNIT_SCALE
    }

    /// Phase `φ` in turns, `[0, 1)`.
    pub fn phase_turns(&self) -> f64 {
        f64::from(self.phase_q) / PHASE_SCALE
    }
}

/// A component ready for evaluation: `A·cos(θ + φ) = ac·cos θ − as·sin θ`, where `ac, as` are
/// computed deterministically once from the quantised values.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Evaluable {
    pub ac: f64,
    pub as_: f64,
}

impl Evaluable {
    pub fn new(c: &Component) -> Self {
        let a = c.amplitude();
        let (cp, sp) = cos_sin_turns(c.phase_turns());
        Self {
            ac: a * cp,
            as_: a * sp,
        }
    }

    /// Largest magnitude the computed value can take (`|ac·c − as·s| ≤ |ac| + |as|` since the
    /// deterministic cos and sin never exceed 1).
    pub fn bound(&self) -> f64 {
        self.ac.abs() + self.as_.abs()
    }

    #[inline]
    pub fn value(&self, (c, s): (f64, f64)) -> f64 {
        self.ac * c - self.as_ * s
    }
}

/// The fitted model of one voxel: mean, components (strongest first) and outlier toggles.
///
/// The first `m` components are themselves the order-`m` model, and the probability is
/// summed in stored order (`((mean + v₀) + v₁) + …`), which fixes its rounding.
///
/// Equality compares the encoded parameters only, not [`model_errors`](Self::model_errors).
#[derive(Debug, Clone, Default)]
pub struct FittedVoxel {
    mean_q: u16,
    components: Vec<Component>,
    toggles: Toggles,
    model_errors: Option<u64>,
}

impl PartialEq for FittedVoxel {
    fn eq(&self, other: &Self) -> bool {
        self.mean_q == other.mean_q
            && self.components == other.components
            && self.toggles == other.toggles
    }
}

impl FittedVoxel {
    /// A voxel from its parts (for models implemented outside this crate). At most
    /// [`MAX_COMPONENTS`] components are kept.
    pub fn new(mean_q: u16, mut components: Vec<Component>, toggles: Toggles) -> Self {
        components.truncate(MAX_COMPONENTS);
        Self {
            mean_q,
            components,
            toggles,
            model_errors: None,
        }
    }

    /// The same model with another outlier set (for containers that store toggles apart).
    pub fn with_toggles(mut self, toggles: Toggles) -> Self {
        self.toggles = toggles;
        self
    }

    pub(crate) fn with_model_errors(mut self, errors: u64) -> Self {
        self.model_errors = Some(errors);
        self
    }

    /// Quantised mean (`mean = mean_q / 65535`).
    pub fn mean_q(&self) -> u16 {
        self.mean_q
    }

    /// The mean occupancy in `[0, 1]`.
    pub fn mean(&self) -> f64 {
        f64::from(self.mean_q) / UNIT_SCALE
    }

    /// Components, strongest first.
    pub fn components(&self) -> &[Component] {
        &self.components
    }

    /// Number of components.
    pub fn order(&self) -> usize {
        self.components.len()
    }

    /// The outlier set (empty in lossy mode).
    pub fn toggles(&self) -> &Toggles {
        &self.toggles
    }

    /// Observed samples where the thresholded model (without outliers) is wrong, known right
    /// after fitting (`None` for a decoded voxel: use
    /// [`PreparedModel::reconstruction_error`](crate::PreparedModel::reconstruction_error)).
    pub fn model_errors(&self) -> Option<u64> {
        self.model_errors
    }

    /// Appends the common voxel layout:
    ///
    /// | field | encoding |
    /// |---|---|
    /// | `mean_q` | u16 LE |
    /// | `m` (components) | varint, ≤ 255 |
    /// | per component: `frequency` | varint |
    /// | per component: `amplitude_q`, `phase_q` | u16 LE each |
    /// | toggles (lossless only) | [`Toggles::encode`] |
    pub fn encode(&self, with_toggles: bool, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.mean_q.to_le_bytes());
        varint::write_u64(out, self.components.len() as u64);
        for c in &self.components {
            varint::write_u32(out, c.frequency);
            out.extend_from_slice(&c.amplitude_q.to_le_bytes());
            out.extend_from_slice(&c.phase_q.to_le_bytes());
        }
        if with_toggles {
            self.toggles.encode(out);
        }
    }

    /// Bytes [`encode`](Self::encode) produces.
    pub fn encoded_len(&self, with_toggles: bool) -> usize {
        params_len(&self.components)
            + if with_toggles {
                self.toggles.encoded_len()
            } else {
                0
            }
    }

    /// Decodes the common layout; component frequencies must be below `frequency_limit` and
    /// toggles below `sample_limit`. Returns the voxel and the bytes consumed.
    pub fn decode(
        bytes: &[u8],
        frequency_limit: u32,
        sample_limit: u32,
        with_toggles: bool,
    ) -> Result<(Self, usize), TemporalError> {
        let mut r = Reader::new(bytes);
        let mean_q = r.u16_le("voxel mean")?;
        let m = r.count("component count", MAX_COMPONENTS as u64, 5)?;
        let mut components = Vec::with_capacity(m);
        for _ in 0..m {
            let frequency = r.u32()?;
            if frequency >= frequency_limit {
                return Err(TemporalError::Malformed("component frequency out of range"));
            }
            let amplitude_q = r.u16_le("component")?;
            let phase_q = r.u16_le("component")?;
            components.push(Component {
                frequency,
                amplitude_q,
                phase_q,
            });
        }
        let toggles = if with_toggles {
            Toggles::read(&mut r, sample_limit)?
        } else {
            Toggles::empty()
        };
        Ok((
            Self {
                mean_q,
                components,
                toggles,
                model_errors: None,
            },
            r.position(),
        ))
    }
}

/// Encoded bytes of the mean and the given components.
pub(crate) fn params_len(components: &[Component]) -> usize {
    2 + varint::encoded_len(components.len() as u64)
        + components
            .iter()
            .map(|c| varint::encoded_len(u64::from(c.frequency)) + 4)
            .sum::<usize>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_bounds() {
        assert_eq!(quantise_unit(0.0), 0);
        assert_eq!(quantise_unit(1.0), u16::MAX);
        assert_eq!(quantise_unit(2.0), u16::MAX);
        assert_eq!(quantise_unit(f64::NAN), 0);
        for k in 0..1000 {
            let x = k as f64 / 999.0;
            let back = f64::from(quantise_unit(x)) / UNIT_SCALE;
            assert!((back - x).abs() <= 0.5 / UNIT_SCALE + 1e-15);
            let turns = x * 3.0 - 1.0;
            let q = f64::from(quantise_phase(turns)) / PHASE_SCALE;
            let d = (q - (turns - turns.floor())).abs();
            assert!(d.min(1.0 - d) <= 0.5 / PHASE_SCALE + 1e-15);
        }
    }

    #[test]
    fn encode_decode_and_limits() {
        let v = FittedVoxel::new(
            1234,
            vec![Component {
                frequency: 300,
                amplitude_q: 5,
                phase_q: 65535,
            }],
            Toggles::new(vec![1, 200]).unwrap(),
        );
        for with_toggles in [true, false] {
            let mut out = Vec::new();
            v.encode(with_toggles, &mut out);
            assert_eq!(out.len(), v.encoded_len(with_toggles));
            let (d, used) = FittedVoxel::decode(&out, 301, 201, with_toggles).unwrap();
            assert_eq!(used, out.len());
            assert_eq!(d.components(), v.components());
            assert_eq!(d.toggles().is_empty(), !with_toggles);
            assert!(FittedVoxel::decode(&out, 300, 201, with_toggles).is_err());
            for cut in 0..out.len() {
                assert!(FittedVoxel::decode(&out[..cut], 301, 201, with_toggles).is_err());
            }
        }
    }
}
