//! Leaves merged into runs of consecutive voxels with one state.
//!
//! A run is an interval of Morton codes, so consumers that merge several maps voxel by voxel
//! (or compare them) can step through intervals instead of expanding coarse leaves into
//! millions of voxels, and two files that split the same space differently into leaves give
//! the same runs.

use crate::{scan, CodecError, FileKind, ReadLimits, ScanSummary};
use froctomap_core::{Leaf, MortonCode, Occupancy};

/// Consecutive voxels `start .. end` (Morton codes) that all have `state`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct VoxelRun {
    /// Morton code of the first voxel.
    pub start: MortonCode,
    /// One past the Morton code of the last voxel.
    pub end: u64,
    /// State of every voxel of the run.
    pub state: Occupancy,
}

impl VoxelRun {
    /// Number of voxels in the run.
    pub fn len(&self) -> u64 {
        self.end - self.start.0
    }

    /// `true` when the run covers no voxel (never produced by [`scan_runs`]).
    pub fn is_empty(&self) -> bool {
        self.end <= self.start.0
    }
}

/// Checks a whole file like [`scan`] and streams its known space to `on_run` as maximal runs
/// of equal state (the binary state OctoMap gives each leaf's log-odds), in Morton order.
///
/// ```
/// use froctomap_octomap_codec::{scan_runs, ReadLimits};
/// // Root with children 0 and 1 free, 2 occupied: one free run of two octants, then one
/// // occupied run.
/// let file = b"# Octomap OcTree binary file\nid OcTree\nsize 4\nres 0.1\ndata\n\x25\x00";
/// let mut runs = Vec::new();
/// scan_runs(file, None, ReadLimits::default(), &mut |run| runs.push(run))?;
/// assert_eq!(runs.len(), 2);
/// assert_eq!(runs[0].len(), 2 << 45);
/// assert!(runs[1].state.is_occupied());
/// # Ok::<(), froctomap_octomap_codec::CodecError>(())
/// ```
pub fn scan_runs<F: FnMut(VoxelRun) + ?Sized>(
    bytes: &[u8],
    kind: Option<FileKind>,
    limits: ReadLimits,
    on_run: &mut F,
) -> Result<ScanSummary, CodecError> {
    let mut pending: Option<VoxelRun> = None;
    let summary = scan(bytes, kind, limits, &mut |leaf: Leaf| {
        let state = leaf.occupancy();
        match pending.as_mut() {
            Some(run) if run.end == leaf.start.0 && run.state == state => run.end = leaf.end(),
            _ => {
                if let Some(run) = pending.take() {
                    on_run(run);
                }
                pending = Some(VoxelRun {
                    start: leaf.start,
                    end: leaf.end(),
                    state,
                });
            }
        }
    })?;
    if let Some(run) = pending {
        on_run(run);
    }
    Ok(summary)
}
