//! The plugin interface: model ids, configuration, and the two traits every model implements.

use crate::varint::Reader;
use crate::{FittedVoxel, TemporalError, TimeAxis, VoxelObservations};
use froctomap_core::Occupancy;
use std::fmt;

/// Stable numeric id of a temporal model, recorded in files. Never reuse a retired id.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ModelId(pub u16);

impl ModelId {
    /// [`StaticMean`](crate::models::StaticMean): the mean only.
    pub const STATIC: ModelId = ModelId(0);
    /// [`FremenRegular`](crate::models::FremenRegular): FreMEn over all DFT bins of a regular axis.
    pub const FREMEN_REGULAR: ModelId = ModelId(1);
    /// [`FremenPeriods`](crate::models::FremenPeriods): FreMEn at a candidate period set, any axis.
    pub const FREMEN_PERIODS: ModelId = ModelId(2);
}

impl fmt::Display for ModelId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// How many spectral components a voxel keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Order {
    /// At most this many (fewer when fewer usable frequencies exist or amplitudes quantise
    /// to zero). `Fixed(0)` is the mean alone.
    Fixed(u8),
    /// Chosen per voxel among `0..=max` by [`ModelConfig::criterion`]:
    /// - [`OrderCriterion::Prediction`] (default): the order with the smallest held-out
    ///   squared error of `p(t)`: the model is fitted on the first `1 − holdout_fraction` of
    ///   the voxel's observed samples and scored (Brier score) on the rest (at most 512
    ///   evenly spaced held-out samples); the lowest order within 1 % of the best score wins
    ///   (a component must earn its place: noise-like voxels keep the mean alone); the
    ///   chosen order is then refitted on all samples. This targets prediction;
    ///   in lossless mode the outliers still make the states exact.
    /// - [`OrderCriterion::SmallestFile`] (lossless only; lossy falls back to prediction):
    ///   the order with the smallest encoded voxel (parameters + toggles), ties to the lower
    ///   order; the most compact exact representation. Block-like series (long runs) often
    ///   come out at order 0 or 1: toggles at the run edges are cheaper than sinusoids
    ///   whose threshold crossings miss the edges, so such files predict no better than the
    ///   mean.
    Auto {
        /// Highest order tried.
        max: u8,
    },
}

impl Order {
    /// The highest number of components this order can give.
    pub fn max(self) -> u8 {
        match self {
            Order::Fixed(n) | Order::Auto { max: n } => n,
        }
    }
}

/// How [`Order::Auto`] chooses a voxel's order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum OrderCriterion {
    /// Best held-out prediction (default): the file predicts as well as it can.
    #[default]
    Prediction,
    /// Smallest encoded voxel (lossless mode): the file is as small as it can be.
    SmallestFile,
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

/// Settings of a model; fields not used by a model are ignored by it.
///
/// ```
/// use froctomap_temporal::{ModelConfig, Order, OutlierMode};
/// let mut config = ModelConfig::default();
/// config.order = Order::Fixed(2);
/// config.periods.push(3600.0); // also look for an hourly rhythm
/// assert_eq!(config.outliers, OutlierMode::Lossless);
/// assert_eq!(config.base_period, 604_800.0);
/// ```
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ModelConfig {
    /// Number of spectral components per voxel. Default `Auto { max: 5 }`.
    pub order: Order,
    /// Keep exact states or not. Default lossless.
    pub outliers: OutlierMode,
    /// How `Order::Auto` picks each voxel's order. Default [`OrderCriterion::Prediction`].
    pub criterion: OrderCriterion,
    /// Extra candidate periods in seconds for [`FremenPeriods`](crate::models::FremenPeriods),
    /// added to `base_period / k` for `k = 1..=harmonics`. Default none.
    pub periods: Vec<f64>,
    /// Base period in seconds of the default period set. Default one week (604 800 s).
    pub base_period: f64,
    /// Number of harmonics of `base_period` in the default period set (0 = none).
    /// Default 24 (one week down to 7 hours, including 1 day, 12 h and 8 h).
    pub harmonics: u32,
    /// A period is used for a voxel only when the voxel's observed time span (first to last
    /// observed sample) is at least `min_cycles` periods long. Default 1.5. Applies to the
    /// DFT bins of [`FremenRegular`](crate::models::FremenRegular) too.
    pub min_cycles: f64,
    /// Fraction of each voxel's observed samples (the latest ones) held out to choose the
    /// order in `Auto` + `Lossy` mode. Default 0.25.
    pub holdout_fraction: f64,
}

impl Default for ModelConfig {
    fn default() -> Self {
        Self {
            order: Order::Auto { max: 5 },
            outliers: OutlierMode::Lossless,
            criterion: OrderCriterion::Prediction,
            periods: Vec::new(),
            base_period: 604_800.0,
            harmonics: 24,
            min_cycles: 1.5,
            holdout_fraction: 0.25,
        }
    }
}

impl ModelConfig {
    /// Most candidate periods accepted (harmonics plus extra periods).
    pub const MAX_PERIODS: usize = 4096;

    /// This configuration with another order criterion.
    pub fn with_criterion(mut self, criterion: OrderCriterion) -> Self {
        self.criterion = criterion;
        self
    }

    /// This configuration with another order.
    pub fn with_order(mut self, order: Order) -> Self {
        self.order = order;
        self
    }

    /// This configuration with another outlier mode.
    pub fn with_outliers(mut self, outliers: OutlierMode) -> Self {
        self.outliers = outliers;
        self
    }

    /// This configuration with extra candidate periods (seconds).
    pub fn with_periods(mut self, periods: Vec<f64>) -> Self {
        self.periods = periods;
        self
    }

    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), TemporalError> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(self.base_period) {
            return Err(TemporalError::InvalidConfig("base_period must be positive"));
        }
        if !self.periods.iter().all(|&p| positive(p)) {
            return Err(TemporalError::InvalidConfig("periods must be positive"));
        }
        if self.harmonics as usize + self.periods.len() > Self::MAX_PERIODS {
            return Err(TemporalError::InvalidConfig("too many candidate periods"));
        }
        if !positive(self.min_cycles) {
            return Err(TemporalError::InvalidConfig("min_cycles must be positive"));
        }
        if !(self.holdout_fraction > 0.0 && self.holdout_fraction < 1.0) {
            return Err(TemporalError::InvalidConfig(
                "holdout_fraction must be in (0, 1)",
            ));
        }
        Ok(())
    }
}

/// A kind of temporal model; registered in a [`ModelRegistry`](crate::ModelRegistry).
pub trait TemporalModel: Send + Sync {
    /// Stable id recorded in files.
    fn id(&self) -> ModelId;

    /// Stable name (used on command lines).
    fn name(&self) -> &'static str;

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

/// A model bound to one time axis: fits, evaluates, encodes and decodes voxels.
///
/// The probability of a voxel is `p(t) = mean + Σ_c A_c·cos(2π·t/P_c + φ_c)` for the kept
/// components `c` (period `P_c`, amplitude `A_c`, phase `φ_c`), clamped to `[0, 1]`. The exact
/// state at sample `i` is `(p(i) > 0.5) XOR parity(toggles ≤ i)`.
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

    /// `p(t)` at `seconds_since_axis_start` (any time, including the future), in `[0, 1]`.
    /// A non-finite time gives the mean.
    fn probability(&self, voxel: &FittedVoxel, seconds_since_axis_start: f64) -> f64;

    /// `p` at sample `sample`, computed exactly as the outlier set was (deterministically,
    /// from the encoded parameters), in `[0, 1]`. Beyond the axis, a regular grid is
    /// extrapolated and an explicit axis repeats its last instant.
    fn probability_at_sample(&self, voxel: &FittedVoxel, sample: u32) -> f64;

    /// The state at a sample: exact for observed samples in lossless mode, the thresholded
    /// model otherwise.
    fn state_at_sample(&self, voxel: &FittedVoxel, sample: u32) -> Occupancy {
        let predicted = self.probability_at_sample(voxel, sample) > 0.5;
        occupancy(predicted != voxel.toggles().parity_at(sample))
    }

    /// The model's state at any time: `p(t) > 0.5` (outliers do not extend to the future).
    fn predicted_state(&self, voxel: &FittedVoxel, seconds_since_axis_start: f64) -> Occupancy {
        occupancy(self.probability(voxel, seconds_since_axis_start) > 0.5)
    }

    /// Period in seconds of a component of this model (`None` when the model has no such
    /// component).
    fn period_seconds(&self, component: &crate::Component) -> Option<f64>;

    /// Appends the voxel's encoding (layout in the crate docs): parameters, then its
    /// toggles in lossless mode.
    fn encode_voxel(&self, voxel: &FittedVoxel, out: &mut Vec<u8>);

    /// One past the largest valid [`Component::frequency`](crate::Component) of this
    /// model (0 when it has no components). Containers that store a voxel's parameters
    /// and its toggles in separate places decode the parameters with
    /// [`FittedVoxel::decode`]`(bytes, model.frequency_limit(), axis_len, false)`.
    fn frequency_limit(&self) -> u32;

    /// Decodes one voxel from the start of `bytes`: the voxel and the bytes consumed.
    /// Untrusted input is validated; it never panics or allocates beyond its size.
    fn decode_voxel(&self, bytes: &[u8]) -> Result<(FittedVoxel, usize), TemporalError>;

    /// The model-global parameters to store once per file (see
    /// [`TemporalModel::prepare_from_parameters`]).
    fn encode_parameters(&self) -> Vec<u8>;

    /// How many observed samples of `obs` the thresholded model (without outliers) gets
    /// wrong: the reconstruction error of lossy mode.
    fn reconstruction_error(&self, voxel: &FittedVoxel, obs: &VoxelObservations) -> u64 {
        obs.iter()
            .filter(|&(i, s)| (self.probability_at_sample(voxel, i) > 0.5) != s.is_occupied())
            .count() as u64
    }
}

pub(crate) fn occupancy(occupied: bool) -> Occupancy {
    if occupied {
        Occupancy::Occupied
    } else {
        Occupancy::Free
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
