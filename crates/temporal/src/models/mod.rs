//! The built-in models. Adding a model: one module here (its [`ModelDescriptor`] with id,
//! name, description and options, a [`TemporalModel`](crate::TemporalModel) and a
//! [`PreparedModel`](crate::PreparedModel) that owns its voxel bytes; see [`markov`] for a
//! small complete one), its `pub mod` line, and one line in [`DEFAULT_MODELS`].

pub mod fremen_periods;
pub mod fremen_regular;
pub mod markov;
pub mod static_mean;

pub use fremen_periods::{FremenPeriods, PreparedFremenPeriods};
pub use fremen_regular::{FremenRegular, PreparedFremenRegular};
pub use static_mean::{PreparedStaticMean, StaticMean};

use crate::ModelDescriptor;

/// Every built-in model, as registered by
/// [`ModelRegistry::with_default_models`](crate::ModelRegistry::with_default_models).
pub const DEFAULT_MODELS: &[ModelDescriptor] = &[
    static_mean::DESCRIPTOR,
    fremen_regular::DESCRIPTOR,
    fremen_periods::DESCRIPTOR,
    markov::DESCRIPTOR,
];

/// One spectral coefficient `γ = (1/N) Σ_observed (s_i − mean)·e^{−j·2π·t_i/P}` of a voxel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectralLine {
    /// The model's frequency index (DFT bin, or index into the period list).
    pub frequency: u32,
    /// Period `P` in seconds (infinite for bin 0).
    pub period_seconds: f64,
    /// Real part of `γ`.
    pub re: f64,
    /// Imaginary part of `γ`.
    pub im: f64,
}

impl SpectralLine {
    /// `|γ|`.
    pub fn magnitude(&self) -> f64 {
        self.re.hypot(self.im)
    }
}
