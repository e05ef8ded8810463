//! The one place a tile touches a cell's temporal model: its parameters written to the
//! models stream, read back, and evaluated.

use crate::error::FormatViolation;
use froctomap_core::Occupancy;
use froctomap_temporal::{FittedVoxel, PreparedModel, Toggles};

/// Appends a modelled cell's parameters (without its outliers, which the tile stores as a
/// toggle list) to the models stream.
pub(super) fn encode(voxel: &FittedVoxel, models: &mut Vec<u8>) {
    voxel.encode(false, models);
}

/// A modelled cell's outliers.
pub(super) fn outliers(voxel: &FittedVoxel) -> &Toggles {
    voxel.toggles()
}

/// A modelled cell's parameters with its outliers.
pub(super) fn with_outliers(voxel: &FittedVoxel, outliers: Option<Toggles>) -> FittedVoxel {
    voxel.clone().with_toggles(outliers.unwrap_or_default())
}

/// Reads the models stream, one modelled cell after another.
pub(super) struct ModelStream<'a> {
    models: &'a [u8],
    pos: usize,
    frequency_limit: u32,
    axis_len: u32,
}

impl<'a> ModelStream<'a> {
    pub(super) fn new(models: &'a [u8], model: &dyn PreparedModel) -> Self {
        Self {
            models,
            pos: 0,
            frequency_limit: model.frequency_limit(),
            axis_len: model.axis().len(),
        }
    }

    /// The next modelled cell's parameters.
    pub(super) fn next_voxel(&mut self) -> Result<FittedVoxel, FormatViolation> {
        let models = &self.models[self.pos..];
        let (voxel, used) =
            FittedVoxel::decode(models, self.frequency_limit, self.axis_len, false)?;
        self.pos += used;
        Ok(voxel)
    }

    /// `true` when every byte of the stream was used.
    pub(super) fn is_done(&self) -> bool {
        self.pos == self.models.len()
    }
}

pub(super) fn state_at_sample(
    model: &dyn PreparedModel,
    voxel: &FittedVoxel,
    sample: u32,
) -> Occupancy {
    model.state_at_sample(voxel, sample)
}

pub(super) fn probability(model: &dyn PreparedModel, voxel: &FittedVoxel, seconds: f64) -> f64 {
    model.probability(voxel, seconds)
}

pub(super) fn probability_at_sample(
    model: &dyn PreparedModel,
    voxel: &FittedVoxel,
    sample: u32,
) -> f64 {
    model.probability_at_sample(voxel, sample)
}
