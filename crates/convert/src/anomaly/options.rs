//! What an anomaly search compares with and its thresholds.

use crate::error::ConvertError;

/// What a snapshot is compared with: the model at its time, or one of the simple
/// baselines the model has to beat.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Expectation {
    /// The file's model at the snapshot's time (static cells: their state).
    #[default]
    Model,
    /// Each cell's mean occupancy over the file's history, whatever the time.
    StaticMean,
    /// Each cell's state at the last snapshot at or before the time (the last seen map);
    /// cells not observed there count as never seen.
    LastSeen,
}

impl froctomap_core::Named for Expectation {
    const ALL: &'static [Self] = &[Self::Model, Self::StaticMean, Self::LastSeen];
    const WHAT: &'static str = "expectation";

    fn name(self) -> &'static str {
        match self {
            Self::Model => "model",
            Self::StaticMean => "static-mean",
            Self::LastSeen => "last-seen",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Self::Model => "The file's model at the snapshot's time",
            Self::StaticMean => "Each cell's mean occupancy over the file's history",
            Self::LastSeen => "The map as last seen at or before the time",
        }
    }
}

impl std::fmt::Display for Expectation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(froctomap_core::Named::name(*self))
    }
}

impl std::str::FromStr for Expectation {
    type Err = froctomap_core::UnknownName;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        froctomap_core::parse_named(name)
    }
}

/// Thresholds of [`anomalies`](super::anomalies). Surprises are in nats (`−ln p`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct AnomalyOptions {
    /// The most a static cell's stored state is taken to be wrong in a new snapshot (less
    /// after many observations), how close to 0 or 1 a model's `p(t)` may get, and how
    /// likely occupied is in space never observed (default 0.01).
    pub error_rate: f64,
    /// A voxel is surprising above this surprise (default `ln 5` ≈ 1.6: the model gave its
    /// state less than a 20 % chance; FreMEn's few smooth periodic terms rarely go below
    /// that around a change, even for a door open at that hour every day).
    pub voxel_threshold: f64,
    /// Regions whose score (surprise beyond the voxel threshold, summed) is below this are
    /// not reported (default 20 nats, a few voxels of static structure flipped: single
    /// noisy voxels stay quiet).
    pub min_region_score: f64,
    /// What the snapshot is compared with (default the model).
    pub expectation: Expectation,
}

impl Default for AnomalyOptions {
    fn default() -> Self {
        Self {
            error_rate: 0.01,
            voxel_threshold: 5f64.ln(),
            min_region_score: 20.0,
            expectation: Expectation::Model,
        }
    }
}

impl AnomalyOptions {
    pub(super) fn check(&self) -> Result<(), ConvertError> {
        let bad = |what: &'static str, value: f64| ConvertError::BadAnomalyOption { what, value };
        if !(self.error_rate > 0.0 && self.error_rate < 0.5) {
            return Err(bad("error rate (0 < rate < 0.5)", self.error_rate));
        }
        if !(self.voxel_threshold.is_finite() && self.voxel_threshold >= 0.0) {
            return Err(bad("voxel threshold (nats, ≥ 0)", self.voxel_threshold));
        }
        if !(self.min_region_score.is_finite() && self.min_region_score >= 0.0) {
            return Err(bad(
                "minimum region score (nats, ≥ 0)",
                self.min_region_score,
            ));
        }
        Ok(())
    }
}
