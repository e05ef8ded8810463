//! The built-in models. Adding a model: one module here (its [`ModelDescriptor`] with id,
//! name, description and options, a [`TemporalModel`](crate::TemporalModel) and a
//! [`PreparedModel`](crate::PreparedModel) that owns its voxel bytes; see [`markov`] for a
//! small complete one), its `pub mod` line, and one line in [`DEFAULT_MODELS`].

pub mod fremen_periods;
pub mod fremen_regular;
pub mod markov;
mod spectral_line;
pub mod static_mean;

pub use fremen_periods::{FremenPeriods, PreparedFremenPeriods};
pub use fremen_regular::{FremenRegular, PreparedFremenRegular};
pub use spectral_line::SpectralLine;
pub use static_mean::{PreparedStaticMean, StaticMean};

use crate::ModelDescriptor;

/// The name of the model a build uses unless told otherwise (`--model`, Python's `model=`).
pub const DEFAULT_MODEL: &str = fremen_periods::DESCRIPTOR.name;

/// Every built-in model, as registered by
/// [`ModelRegistry::with_default_models`](crate::ModelRegistry::with_default_models).
pub const DEFAULT_MODELS: &[ModelDescriptor] = &[
    static_mean::DESCRIPTOR,
    fremen_regular::DESCRIPTOR,
    fremen_periods::DESCRIPTOR,
    markov::DESCRIPTOR,
];
