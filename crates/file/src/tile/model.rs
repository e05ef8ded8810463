//! The one place a tile touches a cell's temporal model: its parameter bytes written to the
//! models stream, delimited by the model when read back, and evaluated in place. The bytes
//! are the model's own; the tile never interprets them.

use crate::error::FormatViolation;
use froctomap_core::Occupancy;
use froctomap_temporal::{FittedVoxel, PreparedModel, Toggles};

/// Appends a modelled cell's parameter bytes (without its outliers, which the tile stores as
/// a toggle list) to the models stream, verbatim.
pub(super) fn encode(voxel: &FittedVoxel, models: &mut Vec<u8>) {
    models.extend_from_slice(voxel.parameters());
}

/// A modelled cell's outliers.
pub(super) fn outliers(voxel: &FittedVoxel) -> &Toggles {
    voxel.toggles()
}

/// A modelled cell from its parameter bytes and its outliers.
pub(super) fn with_outliers(parameters: &[u8], outliers: Option<Toggles>) -> FittedVoxel {
    FittedVoxel::new(parameters, outliers.unwrap_or_default())
}

/// Reads the models stream, one modelled cell after another.
pub(super) struct ModelStream<'a> {
    models: &'a [u8],
    pos: usize,
    model: &'a dyn PreparedModel,
}

impl<'a> ModelStream<'a> {
    pub(super) fn new(models: &'a [u8], model: &'a dyn PreparedModel) -> Self {
        Self {
            models,
            pos: 0,
            model,
        }
    }

    /// The next modelled cell's parameter bytes, delimited and validated by the model.
    pub(super) fn next_parameters(&mut self) -> Result<&'a [u8], FormatViolation> {
        let rest = self.models.get(self.pos..).unwrap_or_default();
        let used = self.model.parameters_len(rest)?;
        let parameters = rest.get(..used).unwrap_or_default();
        self.pos += parameters.len();
        Ok(parameters)
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

pub(super) fn probability(model: &dyn PreparedModel, parameters: &[u8], seconds: f64) -> f64 {
    model.probability(parameters, seconds)
}

pub(super) fn probability_at_sample(
    model: &dyn PreparedModel,
    parameters: &[u8],
    sample: u32,
) -> f64 {
    model.probability_at_sample(parameters, sample)
}
