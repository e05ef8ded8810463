//! The plugin interface: model ids, configuration, and the two traits every model implements.

use crate::varint::Reader;
use crate::{
    FittedVoxel, ModelId, ModelOptions, OptionDescriptor, TemporalError, TimeAxis, Toggles,
    VoxelObservations,
};
use froctomap_core::Occupancy;

/// Describes one model: its stable id and name, a one-line description, its options, and a
/// factory.
#[derive(Debug, Clone, Copy)]
pub struct ModelDescriptor {
    /// Stable id recorded in files.
    pub id: ModelId,
    /// Stable name used on command lines.
    pub name: &'static str,
    /// One line for `--help` and listings.
    pub description: &'static str,
    /// The options the model accepts in [`ModelConfig::options`](crate::ModelConfig), with
    /// their defaults.
    pub options: &'static [OptionDescriptor],
    /// Creates the model.
    pub factory: fn() -> Box<dyn TemporalModel>,
}

impl ModelDescriptor {
    /// A new instance of the model.
    pub fn create(&self) -> Box<dyn TemporalModel> {
        (self.factory)()
    }
}

/// Whether the exact states are kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OutlierMode {
    /// Keep the outlier set: every observed state is reproduced bit-exactly.
    Lossless,
    /// Drop it: tiny, and each voxel reports how many observed samples it gets wrong
    /// ([`FittedVoxel::model_errors`]).
    Lossy,
}

impl OutlierMode {
    pub(crate) fn to_byte(self) -> u8 {
        match self {
            OutlierMode::Lossless => 0,
            OutlierMode::Lossy => 1,
        }
    }

    pub(crate) fn from_byte(b: u8) -> Result<Self, TemporalError> {
        match b {
            0 => Ok(OutlierMode::Lossless),
            1 => Ok(OutlierMode::Lossy),
            _ => Err(TemporalError::Malformed("outlier mode")),
        }
    }
}

/// Settings of a model: the outlier mode every model has, and the model's own options as
/// text, which the model parses when it is prepared ([`OptionDescriptor`](crate::OptionDescriptor)s on its
/// [`ModelDescriptor`](crate::ModelDescriptor) list them with their defaults).
///
/// ```
/// use froctomap_temporal::{ModelConfig, ModelRegistry, OutlierMode, TemporalError};
/// let config = ModelConfig::default()
///     .with_outliers(OutlierMode::Lossy)
///     .with_option("order", 2)
///     .with_option("periods", "3600"); // also look for an hourly rhythm
/// let registry = ModelRegistry::with_default_models();
/// let fremen = registry.by_name("fremen-periods").unwrap().create();
/// assert!(fremen.check_options(&config.options).is_ok());
/// let static_mean = registry.by_name("static").unwrap().create();
/// assert!(matches!(
///     static_mean.check_options(&config.options),
///     Err(TemporalError::UnknownOption { .. })
/// ));
/// ```
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ModelConfig {
    /// Keep exact states or not. Default lossless.
    pub outliers: OutlierMode,
    /// The model's own options (`key=value`); none given means the model's defaults.
    pub options: ModelOptions,
}

impl Default for ModelConfig {
    fn default() -> Self {
        Self {
            outliers: OutlierMode::Lossless,
            options: ModelOptions::new(),
        }
    }
}

impl ModelConfig {
    /// This configuration with another outlier mode.
    pub fn with_outliers(mut self, outliers: OutlierMode) -> Self {
        self.outliers = outliers;
        self
    }

    /// This configuration with a model option set (its text form).
    pub fn with_option(mut self, key: &str, value: impl std::fmt::Display) -> Self {
        self.options.set(key, value);
        self
    }
}

/// A readable summary of one voxel's parameters (for `info`, `history` and tools).
#[derive(Debug, Clone, PartialEq, Default)]
#[non_exhaustive]
pub struct VoxelDescription {
    /// Mean occupancy over the observed samples, in `[0, 1]`.
    pub mean: f64,
    /// Periodic terms `A·cos(2π·t/P + φ)` (empty for non-spectral models), strongest first.
    pub periodic: Vec<PeriodicTerm>,
}

/// One periodic term of a [`VoxelDescription`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeriodicTerm {
    /// Period `P` in seconds.
    pub period_seconds: f64,
    /// Amplitude `A`.
    pub amplitude: f64,
    /// Phase `φ` in turns.
    pub phase_turns: f64,
}

/// A kind of temporal model; registered in a [`ModelRegistry`](crate::ModelRegistry).
pub trait TemporalModel: Send + Sync {
    /// The model's registration: id, name, description and options, as data.
    fn descriptor(&self) -> &'static ModelDescriptor;

    /// Stable id recorded in files.
    fn id(&self) -> ModelId {
        self.descriptor().id
    }

    /// Stable name (used on command lines).
    fn name(&self) -> &'static str {
        self.descriptor().name
    }

    /// Parses and validates the model's options (unknown keys and bad values are errors),
    /// as [`prepare`](Self::prepare) does, without preparing. The default accepts exactly
    /// the keys the descriptor declares; models whose options have values to check override
    /// it.
    fn check_options(&self, options: &ModelOptions) -> Result<(), TemporalError> {
        let descriptor = self.descriptor();
        options.check_keys(descriptor.name, descriptor.options)
    }

    /// Does the per-axis work shared by all voxels (tables, FFT plans) for fitting and
    /// evaluating voxels on `axis`.
    fn prepare(
        &self,
        axis: &TimeAxis,
        config: &ModelConfig,
    ) -> Result<Box<dyn PreparedModel>, TemporalError>;

    /// Rebuilds the prepared model a writer used, from its
    /// [`encode_parameters`](PreparedModel::encode_parameters) bytes, to decode and evaluate
    /// its voxels. Settings not stored there (e.g. the order) take their defaults.
    fn prepare_from_parameters(
        &self,
        axis: &TimeAxis,
        parameters: &[u8],
    ) -> Result<Box<dyn PreparedModel>, TemporalError>;
}

/// A model bound to one time axis: fits voxels and evaluates their parameter bytes.
///
/// A voxel's parameters are bytes the model defines ([`FittedVoxel::parameters`]); a
/// container stores them verbatim and delimits them with
/// [`parameters_len`](Self::parameters_len), which validates untrusted bytes. The other
/// methods taking `parameters` expect bytes that passed it (or came from
/// [`fit`](Self::fit)); given other bytes they return some value without panicking. The
/// exact state at sample `i` is `(p(i) > 0.5) XOR parity(toggles ≤ i)`.
pub trait PreparedModel: Send + Sync {
    /// Id of the model.
    fn id(&self) -> ModelId;

    /// The axis this model was prepared for.
    fn axis(&self) -> &TimeAxis;

    /// Whether voxels keep their outlier sets.
    fn outlier_mode(&self) -> OutlierMode;

    /// Fits one voxel. Fails when the observations reach beyond the axis or cover a missing
    /// sample.
    fn fit(&self, obs: &VoxelObservations) -> Result<FittedVoxel, TemporalError>;

    /// Validates the voxel parameters at the start of `bytes` and returns their length.
    /// Untrusted input: never panics, allocates nothing.
    fn parameters_len(&self, bytes: &[u8]) -> Result<usize, TemporalError>;

    /// `p(t)` at `seconds_since_axis_start` (any time, including the future), in `[0, 1]`.
    /// A non-finite time gives the mean.
    fn probability(&self, parameters: &[u8], seconds_since_axis_start: f64) -> f64;

    /// `p` at sample `sample`, computed exactly as the outlier set was (deterministically,
    /// from the parameter bytes, the same on every machine), in `[0, 1]`. Beyond the axis, a
    /// regular grid is extrapolated and an explicit axis repeats its last instant.
    fn probability_at_sample(&self, parameters: &[u8], sample: u32) -> f64;

    /// The voxel's mean occupancy over its observed samples, in `[0, 1]`.
    fn mean(&self, parameters: &[u8]) -> f64;

    /// Whether `p(t)` is the same at every time (then it is [`mean`](Self::mean)).
    fn is_constant(&self, parameters: &[u8]) -> bool;

    /// A readable summary of the parameters; fails on bytes `parameters_len` rejects.
    fn describe(&self, parameters: &[u8]) -> Result<VoxelDescription, TemporalError>;

    /// The model-global parameters to store once per file (see
    /// [`TemporalModel::prepare_from_parameters`]).
    fn encode_parameters(&self) -> Vec<u8>;

    /// The state at a sample: exact for observed samples in lossless mode, the thresholded
    /// model otherwise.
    fn state_at_sample(&self, voxel: &FittedVoxel, sample: u32) -> Occupancy {
        let predicted = self.probability_at_sample(voxel.parameters(), sample) > 0.5;
        Occupancy::from(predicted != voxel.toggles().parity_at(sample))
    }

    /// The model's state at any time: `p(t) > 0.5` (outliers do not extend to the future).
    fn predicted_state(&self, parameters: &[u8], seconds_since_axis_start: f64) -> Occupancy {
        Occupancy::from(self.probability(parameters, seconds_since_axis_start) > 0.5)
    }

    /// Appends the voxel's encoding: its parameter bytes, then its toggles in lossless mode
    /// ([`Toggles::encode`](crate::Toggles::encode)).
    fn encode_voxel(&self, voxel: &FittedVoxel, out: &mut Vec<u8>) {
        out.extend_from_slice(voxel.parameters());
        if self.outlier_mode() == OutlierMode::Lossless {
            voxel.toggles().encode(out);
        }
    }

    /// Decodes one voxel written by [`encode_voxel`](Self::encode_voxel) from the start of
    /// `bytes`: the voxel and the bytes consumed. Untrusted input is validated; it never
    /// panics or allocates beyond its size.
    fn decode_voxel(&self, bytes: &[u8]) -> Result<(FittedVoxel, usize), TemporalError> {
        let len = self.parameters_len(bytes)?;
        let (parameters, rest) = bytes
            .split_at_checked(len)
            .ok_or(TemporalError::Truncated("voxel parameters"))?;
        let (toggles, used) = match self.outlier_mode() {
            OutlierMode::Lossless => Toggles::decode(rest, self.axis().len())?,
            OutlierMode::Lossy => (Toggles::empty(), 0),
        };
        Ok((FittedVoxel::new(parameters, toggles), len + used))
    }

    /// How many observed samples of `obs` the thresholded model (without outliers) gets
    /// wrong: the reconstruction error of lossy mode.
    fn reconstruction_error(&self, voxel: &FittedVoxel, obs: &VoxelObservations) -> u64 {
        obs.iter()
            .filter(|&(i, s)| {
                (self.probability_at_sample(voxel.parameters(), i) > 0.5) != s.is_occupied()
            })
            .count() as u64
    }
}

/// Version of the common parameter header.
pub(crate) const PARAMETERS_VERSION: u8 = 1;

/// Writes the header every model's parameters start with: version, outlier mode.
pub(crate) fn write_parameters_header(out: &mut Vec<u8>, mode: OutlierMode) {
    out.push(PARAMETERS_VERSION);
    out.push(mode.to_byte());
}

/// Fails when bytes are left after a complete parameter block.
pub(crate) fn expect_end(r: &Reader<'_>) -> Result<(), TemporalError> {
    if r.remaining() == 0 {
        Ok(())
    } else {
        Err(TemporalError::Malformed(
            "model parameters (trailing bytes)",
        ))
    }
}

/// Reads a parameter block that is the common header alone (models without global
/// parameters): the outlier mode.
pub(crate) fn read_header_only_parameters(parameters: &[u8]) -> Result<OutlierMode, TemporalError> {
    let mut r = Reader::new(parameters);
    let mode = read_parameters_header(&mut r)?;
    expect_end(&r)?;
    Ok(mode)
}

/// Reads the common parameter header.
pub(crate) fn read_parameters_header(r: &mut Reader<'_>) -> Result<OutlierMode, TemporalError> {
    let version = r.u8("model parameters")?;
    if version != PARAMETERS_VERSION {
        return Err(TemporalError::UnsupportedVersion {
            what: "model parameters",
            version,
        });
    }
    OutlierMode::from_byte(r.u8("model parameters")?)
}
