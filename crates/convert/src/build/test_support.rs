//! Setup shared by the stages' tests.

use crate::context::Context;
use froctomap_core::Timestamp;
use froctomap_temporal::{ModelConfig, ModelId, PreparedModel, TimeAxis};

/// The default model prepared (lossless) for a regular axis of `samples` seconds.
pub(super) struct PreparedOnAxis {
    pub axis: TimeAxis,
    pub id: ModelId,
    pub model: Box<dyn PreparedModel>,
}

pub(super) fn default_model(samples: u32) -> PreparedOnAxis {
    let axis = TimeAxis::regular(Timestamp::from_secs(0), 1_000_000_000, samples, Vec::new())
        .expect("a valid axis");
    let context = Context::with_default_plugins();
    let model = context
        .models()
        .by_name(froctomap_temporal::models::DEFAULT_MODEL)
        .expect("the default model")
        .create();
    let prepared = model
        .prepare(&axis, &ModelConfig::default())
        .expect("the default model on a regular axis");
    PreparedOnAxis {
        axis,
        id: model.id(),
        model: prepared,
    }
}
