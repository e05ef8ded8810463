//! Differences between two maps as ranges of voxels whose state changed.

use crate::key::MortonCode;
use crate::leaf::{Leaf, Occupancy};

/// A range of voxels whose state changed between two maps, and its new state
/// (`None`: unknown).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateChange {
    /// First voxel (Morton code).
    pub start: u64,
    /// One past the last voxel.
    pub end: u64,
    /// The state from now on (`None`: unknown).
    pub new: Option<Occupancy>,
}

/// Appends a change that starts at or after the end of the last one, extending the last one
/// instead when it continues it with the same new state. Changes pushed this way are maximal
/// per new state, so the list does not depend on how either map splits space into leaves.
///
/// ```
/// use froctomap_core::{push_merged, Occupancy, StateChange};
/// let mut changes = Vec::new();
/// push_merged(&mut changes, StateChange { start: 0, end: 8, new: Some(Occupancy::Free) });
/// push_merged(&mut changes, StateChange { start: 8, end: 9, new: Some(Occupancy::Free) });
/// push_merged(&mut changes, StateChange { start: 9, end: 10, new: None });
/// assert_eq!(changes.len(), 2);
/// assert_eq!(changes[0].end, 9);
/// ```
#[inline]
pub fn push_merged(changes: &mut Vec<StateChange>, change: StateChange) {
    match changes.last_mut() {
        Some(last) if last.end == change.start && last.new == change.new => last.end = change.end,
        _ => changes.push(change),
    }
}

/// The state at `pos` in sorted, disjoint leaves (advancing `i`), and where it ends.
fn state_at(leaves: &[Leaf], i: &mut usize, pos: u64) -> (Option<Occupancy>, u64) {
    while *i < leaves.len() && leaves[*i].end() <= pos {
        *i += 1;
    }
    match leaves.get(*i) {
        Some(l) if l.start.0 <= pos => (Some(l.occupancy()), l.end()),
        Some(l) => (None, l.start.0),
        None => (None, MortonCode::END),
    }
}

/// The ranges where `current` differs from `previous` (both sorted and disjoint, as a
/// [`Snapshot`](crate::Snapshot)'s leaves are), maximal per new state. Leaves equal in both
/// are skipped pairwise, so consecutive snapshots of a mostly static scene compare at the
/// speed of a linear scan; how either splits space into leaves does not matter.
///
/// ```
/// use froctomap_core::{changes, Leaf, MortonCode, Occupancy};
/// let free = |start, depth| Leaf { start: MortonCode(start), depth, log_odds: -2.0 };
/// // One free block of 8 voxels, then the same block as 8 single voxels, one occupied.
/// let before = [free(0, 15)];
/// let mut after: Vec<Leaf> = (0..8).map(|i| free(i, 16)).collect();
/// after[3].log_odds = 2.0;
/// let diff = changes(&before, &after);
/// assert_eq!(diff.len(), 1);
/// assert_eq!((diff[0].start, diff[0].end, diff[0].new), (3, 4, Some(Occupancy::Occupied)));
/// ```
pub fn changes(previous: &[Leaf], current: &[Leaf]) -> Vec<StateChange> {
    let mut out: Vec<StateChange> = Vec::new();
    let (mut i, mut j, mut pos) = (0usize, 0usize, 0u64);
    while pos < MortonCode::END {
        // Fast path: the same leaf in both.
        if let (Some(a), Some(b)) = (previous.get(i), current.get(j)) {
            if a.start.0 == pos
                && b.start.0 == pos
                && a.depth == b.depth
                && a.occupancy() == b.occupancy()
            {
                pos = a.end();
                i += 1;
                j += 1;
                continue;
            }
        }
        let (old, old_end) = state_at(previous, &mut i, pos);
        let (new, new_end) = state_at(current, &mut j, pos);
        let end = old_end.min(new_end);
        if old != new {
            push_merged(
                &mut out,
                StateChange {
                    start: pos,
                    end,
                    new,
                },
            );
        }
        pos = end;
    }
    out
}
