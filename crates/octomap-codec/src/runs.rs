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
    let mut merger = RunMerger::default();
    let summary = scan(bytes, kind, limits, &mut |leaf: Leaf| {
        if let Some(run) = merger.push(&leaf) {
            on_run(run);
        }
    })?;
    if let Some(run) = merger.finish() {
        on_run(run);
    }
    Ok(summary)
}

/// Merges Morton-ordered leaves into maximal runs of equal state, one leaf at a time.
#[derive(Clone, Debug, Default)]
pub struct RunMerger {
    pending: Option<VoxelRun>,
}

impl RunMerger {
    /// Adds the next leaf; returns a run that can no longer grow.
    pub fn push(&mut self, leaf: &Leaf) -> Option<VoxelRun> {
        let state = leaf.occupancy();
        match self.pending.as_mut() {
            Some(run) if run.end == leaf.start.0 && run.state == state => {
                run.end = leaf.end();
                None
            }
            _ => self.pending.replace(VoxelRun {
                start: leaf.start,
                end: leaf.end(),
                state,
            }),
        }
    }

    /// The last run, if any.
    pub fn finish(self) -> Option<VoxelRun> {
        self.pending
    }
}

/// The maximal runs of equal state of Morton-ordered leaves.
///
/// ```
/// use froctomap_core::{Leaf, VoxelKey};
/// let leaves = [Leaf::voxel(VoxelKey::new(0, 0, 0), 1.0), Leaf::voxel(VoxelKey::new(1, 0, 0), 2.0)];
/// let runs = froctomap_octomap_codec::merge_runs(&leaves);
/// assert_eq!((runs.len(), runs[0].len()), (1, 2));
/// ```
pub fn merge_runs<'a>(leaves: impl IntoIterator<Item = &'a Leaf>) -> Vec<VoxelRun> {
    let mut merger = RunMerger::default();
    let mut runs: Vec<VoxelRun> = leaves
        .into_iter()
        .filter_map(|leaf| merger.push(leaf))
        .collect();
    runs.extend(merger.finish());
    runs
}
