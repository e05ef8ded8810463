//! The one error type of this crate.

use crate::ModelId;

/// Why a temporal-model operation failed.
///
/// Variants distinguish invalid *arguments* (axis, observations, configuration), *malformed*
/// or truncated encoded bytes, *unsupported* combinations, and *limits* (a resource bound hit,
/// e.g. by hostile input claiming a huge count).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TemporalError {
    /// A time axis that violates its invariants.
    #[error("invalid time axis: {0}")]
    InvalidAxis(&'static str),
    /// Observations that violate their invariants or do not fit the axis.
    #[error("invalid observations: {reason} (sample {sample})")]
    InvalidObservations {
        /// What is wrong.
        reason: &'static str,
        /// The sample index where it was detected.
        sample: u64,
    },
    /// A model configuration value outside its documented range.
    #[error("invalid model configuration: {0}")]
    InvalidConfig(&'static str),
    /// The model cannot work on this kind of time axis.
    #[error("model {model} does not support {reason}")]
    Unsupported {
        /// Name of the model.
        model: &'static str,
        /// What is not supported.
        reason: &'static str,
    },
    /// Encoded bytes ended before the value was complete.
    #[error("truncated {0}")]
    Truncated(&'static str),
    /// Encoded bytes that do not describe a valid value.
    #[error("malformed {0}")]
    Malformed(&'static str),
    /// An encoded parameter version this build does not know.
    #[error("unsupported {what} version {version}")]
    UnsupportedVersion {
        /// Which structure.
        what: &'static str,
        /// The version found.
        version: u8,
    },
    /// A count or size beyond what this implementation accepts.
    #[error("limit exceeded: {what} is {value}, at most {limit} allowed")]
    LimitExceeded {
        /// Which quantity.
        what: &'static str,
        /// Its value.
        value: u64,
        /// The largest accepted value.
        limit: u64,
    },
    /// A model option that is not `key=value` text.
    #[error("model option {0:?} is not KEY=VALUE")]
    MalformedOption(String),
    /// An option the chosen model does not declare.
    #[error("model {model} has no option {key:?}")]
    UnknownOption {
        /// Name of the model.
        model: &'static str,
        /// The key given.
        key: String,
    },
    /// An option value the model does not accept.
    #[error("model {model}: option {key}={value:?} is invalid (expected {expected})")]
    InvalidOption {
        /// Name of the model.
        model: &'static str,
        /// The option's key.
        key: &'static str,
        /// The value given.
        value: String,
        /// What the model accepts.
        expected: &'static str,
    },
    /// No registered model has this id.
    #[error("unknown temporal model id {0}")]
    UnknownModel(ModelId),
    /// A registration clashing with an existing one.
    #[error("temporal model {0} is already registered")]
    DuplicateModel(String),
}
