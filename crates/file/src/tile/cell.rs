//! What a tile holds: cells, each a cube of voxels that shares its state at every sample.

use super::model;
use froctomap_core::{voxels_per_node, MortonCode, Occupancy};
use froctomap_temporal::{FittedVoxel, PreparedModel, TimeAxis, Toggles};
use std::sync::Arc;

/// What a cell stores about its states.
#[derive(Clone, Debug, PartialEq)]
pub enum CellContent {
    /// Observed in this state only: costs one class byte.
    Constant(Occupancy),
    /// Almost always in `state`, except between toggles (state flips at each position):
    /// rare changes, such as sensor noise at a surface, whose mean occupancy is outside
    /// OctoMap's clamping bounds, so that a model would predict nothing a map can express
    /// beyond `state`. Lossy files drop the exceptions.
    ConstantExcept {
        /// The usual state.
        state: Occupancy,
        /// Where the state differs from the usual one.
        exceptions: Toggles,
    },
    /// A temporal model (with its outliers in lossless files).
    Modelled(FittedVoxel),
}

/// One cube of voxels that shares its state at every sample.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// Morton code of the first voxel.
    pub start: MortonCode,
    /// Depth (`tile_depth..=16`); the cell holds `8^(16 − depth)` voxels.
    pub depth: u8,
    /// Observation mask as toggles (observed-ness starts false and flips at each position);
    /// `None` means observed at every sample that is not missing from the axis. Shared:
    /// neighbouring cells usually have the same mask, which a tile stores once.
    pub mask: Option<Arc<Toggles>>,
    /// States.
    pub content: CellContent,
}

impl Cell {
    /// One past the Morton code of the last voxel.
    pub fn end(&self) -> u64 {
        self.start.0 + voxels_per_node(self.depth)
    }

    /// `true` when the cell was observed at `sample`.
    pub fn is_observed(&self, axis: &TimeAxis, sample: u32) -> bool {
        sample < axis.len()
            && !axis.is_missing(sample)
            && self.mask.as_ref().is_none_or(|mask| mask.parity_at(sample))
    }

    /// The state at a sample: `None` where the cell was not observed. Exact in lossless files.
    pub fn state_at(
        &self,
        axis: &TimeAxis,
        model: &dyn PreparedModel,
        sample: u32,
    ) -> Option<Occupancy> {
        if !self.is_observed(axis, sample) {
            return None;
        }
        Some(match &self.content {
            CellContent::Constant(state) => *state,
            CellContent::ConstantExcept { state, exceptions } => {
                if exceptions.parity_at(sample) {
                    !*state
                } else {
                    *state
                }
            }
            CellContent::Modelled(voxel) => model::state_at_sample(model, voxel, sample),
        })
    }

    /// Occupancy probability at any instant, in seconds since the first sample of the axis.
    pub fn probability(&self, model: &dyn PreparedModel, seconds: f64) -> f64 {
        match &self.content {
            CellContent::Constant(state) | CellContent::ConstantExcept { state, .. } => {
                f64::from(u8::from(state.is_occupied()))
            }
            CellContent::Modelled(voxel) => model::probability(model, voxel.parameters(), seconds),
        }
    }

    /// A sample range outside which the cell is never observed (it may be unobserved at
    /// some samples inside it).
    pub fn observed_span(&self, axis_len: u32) -> Option<(u32, u32)> {
        let last = axis_len.checked_sub(1)?;
        match &self.mask {
            None => Some((0, last)),
            Some(mask) => {
                let toggles = mask.as_slice();
                let first = *toggles.first()?;
                let end = if toggles.len() % 2 == 1 {
                    last
                } else {
                    toggles.last()?.checked_sub(1)?
                };
                Some((first, end))
            }
        }
    }
}

/// Helper for writers that build masks from observed runs: the mask toggles of a list of
/// observed sample ranges `[first, end)`, or `None` when they cover every sample that is not
/// missing from the axis.
pub fn mask_from_ranges(axis: &TimeAxis, ranges: &[(u32, u64)]) -> Option<Arc<Toggles>> {
    let mut toggles: Vec<u32> = Vec::with_capacity(ranges.len() * 2);
    let mut observed_end: Option<u64> = None;
    for &(first, end) in ranges {
        // Bridge gaps made only of missing samples: they are unknown for every cell anyway.
        let bridged = observed_end.is_some_and(|prev| all_missing(axis, prev, u64::from(first)));
        if bridged {
            toggles.pop();
        } else {
            let leading = observed_end.is_none() && all_missing(axis, 0, u64::from(first));
            toggles.push(if leading { 0 } else { first });
        }
        if end < u64::from(axis.len()) {
            toggles.push(end as u32);
        }
        observed_end = Some(end);
    }
    // Trailing samples after the last run that are all missing need no toggle either.
    if let (Some(end), Some(&last)) = (observed_end, toggles.last()) {
        if toggles.len() % 2 == 0
            && u64::from(last) == end
            && all_missing(axis, end, u64::from(axis.len()))
        {
            toggles.pop();
        }
    }
    if toggles == [0] {
        return None;
    }
    Toggles::new(toggles).ok().map(Arc::new)
}

/// `true` when every sample in `[first, end)` is missing from the axis (vacuously for an
/// empty range).
fn all_missing(axis: &TimeAxis, first: u64, end: u64) -> bool {
    if end <= first {
        return true;
    }
    let missing = axis.missing();
    let from = missing.partition_point(|&m| u64::from(m) < first);
    let to = missing.partition_point(|&m| u64::from(m) < end);
    (to - from) as u64 == end - first
}
