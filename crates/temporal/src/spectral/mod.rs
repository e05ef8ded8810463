//! What the FreMEn-family models share: quantised components, their voxel parameter layout
//! (mean + components), evaluation straight from those bytes, and their options.

pub mod options;

use crate::trig::cos_sin_turns;
use crate::varint::{self, Reader};
use crate::{PeriodicTerm, TemporalError, VoxelDescription};

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

/// The value of a quantised unit.
pub(crate) fn unit(q: u16) -> f64 {
    f64::from(q) / UNIT_SCALE
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
        unit(self.amplitude_q)
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

/// The parameters of a FreMEn-family voxel, decoded (for inspection and tests; evaluation
/// reads the bytes directly).
///
/// | field | encoding |
/// |---|---|
/// | `mean_q` | u16 LE, `μ = q / 65535` |
/// | `m` (components) | varint, ≤ 255 |
/// | per component: `frequency` | varint (below the model's frequency limit) |
/// | per component: `amplitude_q`, `phase_q` | u16 LE each |
///
/// ```
/// use froctomap_temporal::spectral::{Component, SpectralParameters};
/// let p = SpectralParameters { mean_q: 1234, components: vec![Component { frequency: 7, amplitude_q: 5, phase_q: 9 }] };
/// let bytes = p.encode();
/// assert_eq!(bytes, [0xd2, 0x04, 1, 7, 5, 0, 9, 0]);
/// assert_eq!(SpectralParameters::decode(&bytes)?, p);
/// # Ok::<(), froctomap_temporal::TemporalError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SpectralParameters {
    /// Quantised mean.
    pub mean_q: u16,
    /// Components, strongest first: the first `m'` are the order-`m'` model.
    pub components: Vec<Component>,
}

impl SpectralParameters {
    /// The mean occupancy in `[0, 1]`.
    pub fn mean(&self) -> f64 {
        unit(self.mean_q)
    }

    /// The encoded bytes.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(encoded_len(&self.components));
        out.extend_from_slice(&self.mean_q.to_le_bytes());
        varint::write_u64(&mut out, self.components.len() as u64);
        for c in &self.components {
            varint::write_u32(&mut out, c.frequency);
            out.extend_from_slice(&c.amplitude_q.to_le_bytes());
            out.extend_from_slice(&c.phase_q.to_le_bytes());
        }
        out
    }

    /// Decodes exactly `bytes` (frequencies are not checked against a model).
    pub fn decode(bytes: &[u8]) -> Result<Self, TemporalError> {
        if parameters_len(bytes, u32::MAX)? != bytes.len() {
            return Err(TemporalError::Malformed(
                "spectral parameters (trailing bytes)",
            ));
        }
        let view = SpectralView::new(bytes);
        Ok(Self {
            mean_q: view.mean_q,
            components: view.components().collect(),
        })
    }
}

/// Encoded bytes of the mean and the given components.
pub(crate) fn encoded_len(components: &[Component]) -> usize {
    2 + varint::encoded_len(components.len() as u64)
        + components
            .iter()
            .map(|c| varint::encoded_len(u64::from(c.frequency)) + 4)
            .sum::<usize>()
}

/// Validates the parameters at the start of `bytes` (frequencies below `frequency_limit`)
/// and returns their length, without allocating.
pub(crate) fn parameters_len(bytes: &[u8], frequency_limit: u32) -> Result<usize, TemporalError> {
    let mut r = Reader::new(bytes);
    r.u16_le("voxel mean")?;
    let m = r.count("component count", MAX_COMPONENTS as u64, 5)?;
    for _ in 0..m {
        if r.u32()? >= frequency_limit {
            return Err(TemporalError::Malformed("component frequency out of range"));
        }
        r.u16_le("component")?;
        r.u16_le("component")?;
    }
    Ok(r.position())
}

/// Reads parameters in place. Bytes are expected to be validated by [`parameters_len`];
/// malformed ones end the component list early instead of panicking.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SpectralView<'a> {
    pub mean_q: u16,
    count: usize,
    rest: &'a [u8],
}

impl<'a> SpectralView<'a> {
    #[inline]
    pub fn new(bytes: &'a [u8]) -> Self {
        let mean_q = match bytes {
            [a, b, ..] => u16::from_le_bytes([*a, *b]),
            _ => 0,
        };
        let after_mean = bytes.get(2..).unwrap_or(&[]);
        let (count, used) = varint::read_u64(after_mean).unwrap_or((0, 0));
        Self {
            mean_q,
            count: count.min(MAX_COMPONENTS as u64) as usize,
            rest: after_mean.get(used..).unwrap_or(&[]),
        }
    }

    pub fn mean(&self) -> f64 {
        unit(self.mean_q)
    }

    /// Whether there are no components (`p` is the mean at all times).
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    #[inline]
    pub fn components(&self) -> impl Iterator<Item = Component> + 'a {
        let mut rest = self.rest;
        (0..self.count).map_while(move |_| {
            let (frequency, used) = varint::read_u32(rest).ok()?;
            let c = match rest.get(used..used + 4)? {
                [a0, a1, p0, p1] => Component {
                    frequency,
                    amplitude_q: u16::from_le_bytes([*a0, *a1]),
                    phase_q: u16::from_le_bytes([*p0, *p1]),
                },
                _ => return None,
            };
            rest = rest.get(used + 4..)?;
            Some(c)
        })
    }
}

/// The canonical probability (unclamped) of parameter bytes: `((mean + v₀) + v₁) + …` with
/// `v_c = ac·cos θ_c − as·sin θ_c`, where `angle(c)` gives `(cos θ_c, sin θ_c)`. Summing in
/// stored order fixes the rounding, so encoder and decoder agree bit for bit.
#[inline]
pub(crate) fn canonical_sum(
    parameters: &[u8],
    mut angle: impl FnMut(&Component) -> (f64, f64),
) -> f64 {
    let view = SpectralView::new(parameters);
    let mut p = view.mean();
    for c in view.components() {
        p += Evaluable::new(&c).value(angle(&c));
    }
    p
}

/// The description of parameter bytes, with each component's period from `period_seconds`.
pub(crate) fn describe(
    parameters: &[u8],
    frequency_limit: u32,
    period_seconds: impl Fn(u32) -> Option<f64>,
) -> Result<VoxelDescription, TemporalError> {
    parameters_len(parameters, frequency_limit)?;
    let view = SpectralView::new(parameters);
    Ok(VoxelDescription {
        mean: view.mean(),
        periodic: view
            .components()
            .map(|c| PeriodicTerm {
                period_seconds: period_seconds(c.frequency).unwrap_or(f64::NAN),
                amplitude: c.amplitude(),
                phase_turns: c.phase_turns(),
            })
            .collect(),
    })
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
            let back = unit(quantise_unit(x));
            assert!((back - x).abs() <= 0.5 / UNIT_SCALE + 1e-15);
            let turns = x * 3.0 - 1.0;
            let q = f64::from(quantise_phase(turns)) / PHASE_SCALE;
            let d = (q - (turns - turns.floor())).abs();
            assert!(d.min(1.0 - d) <= 0.5 / PHASE_SCALE + 1e-15);
        }
    }

    #[test]
    fn encode_decode_and_limits() {
        let p = SpectralParameters {
            mean_q: 1234,
            components: vec![
                Component {
                    frequency: 300,
                    amplitude_q: 5,
                    phase_q: 65535,
                },
                Component {
                    frequency: 2,
                    amplitude_q: 7,
                    phase_q: 1,
                },
            ],
        };
        let out = p.encode();
        assert_eq!(out.len(), encoded_len(&p.components));
        assert_eq!(parameters_len(&out, 301), Ok(out.len()));
        assert!(parameters_len(&out, 300).is_err());
        let view = SpectralView::new(&out);
        assert_eq!(view.components().collect::<Vec<_>>(), p.components);
        for cut in 0..out.len() {
            assert!(parameters_len(&out[..cut], 301).is_err());
            // A view of damaged bytes yields fewer components, never a panic.
            assert!(SpectralView::new(&out[..cut]).components().count() < 2);
        }
    }
}
