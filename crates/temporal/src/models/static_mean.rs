//! The static baseline: `p(t)` is the voxel's mean occupancy, at every time.

use crate::fit::{fit_voxel, Candidate, Evaluator, FitSettings, Spectral, Usable};
use crate::model::{read_header_only_parameters, write_parameters_header};
use crate::spectral::{self, canonical_sum, SpectralView};
use crate::{
    Component, FittedVoxel, ModelConfig, ModelDescriptor, ModelId, Order, OutlierMode,
    PreparedModel, TemporalError, TemporalModel, TimeAxis, VoxelDescription, VoxelObservations,
};

/// Registration of [`StaticMean`].
pub const DESCRIPTOR: ModelDescriptor = ModelDescriptor {
    id: ModelId::STATIC,
    name: "static",
    description: "mean occupancy only (the baseline); exact states via the outlier set",
    options: &[],
    factory: || Box::new(StaticMean),
};

/// The static model: mean only. Works on any axis; has no options.
///
/// ```
/// use froctomap_core::{Occupancy::*, Timestamp};
/// use froctomap_temporal::{models::StaticMean, *};
/// let axis = TimeAxis::regular(Timestamp(0), 1, 10, vec![])?;
/// let model = StaticMean.prepare(&axis, &ModelConfig::default())?;
/// let obs = VoxelObservations::from_runs([(0, 7, Free), (7, 3, Occupied)])?;
/// let voxel = model.fit(&obs)?;
/// assert!((model.probability(voxel.parameters(), 1e9) - 0.3).abs() < 1e-4);
/// assert_eq!(voxel.model_errors(), Some(3)); // the thresholded mean says "free" everywhere
/// assert_eq!(model.state_at_sample(&voxel, 8), Occupied); // ...but the toggles fix it
/// # Ok::<(), TemporalError>(())
/// ```
#[derive(Debug, Clone, Copy, Default)]
pub struct StaticMean;

impl TemporalModel for StaticMean {
    fn descriptor(&self) -> &'static ModelDescriptor {
        &DESCRIPTOR
    }

    fn prepare(
        &self,
        axis: &TimeAxis,
        config: &ModelConfig,
    ) -> Result<Box<dyn PreparedModel>, TemporalError> {
        self.check_options(&config.options)?;
        Ok(Box::new(PreparedStaticMean {
            axis: axis.clone(),
            mode: config.outliers,
        }))
    }

    fn prepare_from_parameters(
        &self,
        axis: &TimeAxis,
        parameters: &[u8],
    ) -> Result<Box<dyn PreparedModel>, TemporalError> {
        let mode = read_header_only_parameters(parameters)?;
        Ok(Box::new(PreparedStaticMean {
            axis: axis.clone(),
            mode,
        }))
    }
}

/// [`StaticMean`] bound to an axis.
#[derive(Debug, Clone)]
pub struct PreparedStaticMean {
    axis: TimeAxis,
    mode: OutlierMode,
}

/// Evaluates no components.
pub(crate) struct NoComponents;

impl Evaluator for NoComponents {
    fn angles(&mut self, _sample: u32, _out: &mut [(f64, f64)]) {}
}

impl Spectral for PreparedStaticMean {
    type Eval<'a> = NoComponents;

    fn evaluator(&self, _components: &[Component]) -> NoComponents {
        NoComponents
    }

    fn time_axis(&self) -> &TimeAxis {
        &self.axis
    }

    fn rate(&self, _component: &Component) -> f64 {
        0.0
    }

    fn longest_usable_period(&self, _range: (u32, u32), _usable: Usable) -> Option<f64> {
        None
    }

    fn candidates(
        &self,
        _obs: &VoxelObservations,
        _mean: f64,
        _max: usize,
        _usable: Usable,
    ) -> Vec<Candidate> {
        Vec::new()
    }
}

impl PreparedModel for PreparedStaticMean {
    fn id(&self) -> ModelId {
        ModelId::STATIC
    }

    fn axis(&self) -> &TimeAxis {
        &self.axis
    }

    fn outlier_mode(&self) -> OutlierMode {
        self.mode
    }

    fn fit(&self, obs: &VoxelObservations) -> Result<FittedVoxel, TemporalError> {
        self.axis.check(obs)?;
        let settings = FitSettings {
            order: Order::Fixed(0),
            mode: self.mode,
            criterion: crate::OrderCriterion::Prediction,
            holdout_fraction: 0.5,
            shrink: false,
        };
        Ok(fit_voxel(self, &settings, obs))
    }

    fn parameters_len(&self, bytes: &[u8]) -> Result<usize, TemporalError> {
        // No components: frequency limit 0 rejects any.
        spectral::parameters_len(bytes, 0)
    }

    fn probability(&self, parameters: &[u8], _seconds_since_axis_start: f64) -> f64 {
        SpectralView::new(parameters).mean()
    }

    fn probability_at_sample(&self, parameters: &[u8], _sample: u32) -> f64 {
        canonical_sum(parameters, |_| (0.0, 0.0)).clamp(0.0, 1.0)
    }

    fn mean(&self, parameters: &[u8]) -> f64 {
        SpectralView::new(parameters).mean()
    }

    fn is_constant(&self, _parameters: &[u8]) -> bool {
        true
    }

    fn describe(&self, parameters: &[u8]) -> Result<VoxelDescription, TemporalError> {
        spectral::describe(parameters, 0, |_| None)
    }

    fn encode_parameters(&self) -> Vec<u8> {
        let mut out = Vec::new();
        write_parameters_header(&mut out, self.mode);
        out
    }
}
