//! The seam of an append: the cells of an existing file (their observations up to its last
//! sample) merged with the cells accumulated from the snapshots appended (from the file's
//! last observed map on), tile by tile, into the histories of the whole series.
//!
//! In: two streams of [`TileHistory`] in Morton order (a tile may be in either or both).
//! Out: one such stream, whose cells are the common refinement of both cell sets (a coarser
//! cell is split into its eight children, which inherit its runs, until both sides agree),
//! each cell's old runs joined to its new runs. Where both sides observed the same sample
//! (the file's last observed map starts the new history), the old side's observation is kept;
//! a run that continues across the seam becomes one run.

use super::accumulate::{pack, TileHistory};
use crate::error::ConvertError;
use crate::history::PackedCell;
use froctomap_core::{voxels_per_node, MortonCode, TREE_DEPTH};
use froctomap_temporal::{TemporalError, VoxelObservations};
use std::iter::Peekable;

/// The tiles of `old` and `new` (each in Morton order) merged into one stream in Morton
/// order: tiles in both get [`merge_cells`], tiles in one only pass through.
pub(crate) fn merge_tiles<O, N>(old: O, new: N, tile_depth: u8) -> MergedTiles<O, N>
where
    O: Iterator<Item = Result<TileHistory, ConvertError>>,
    N: Iterator<Item = Result<TileHistory, ConvertError>>,
{
    MergedTiles {
        old: old.peekable(),
        new: new.peekable(),
        tile_depth,
    }
}

/// See [`merge_tiles`].
pub(crate) struct MergedTiles<O: Iterator, N: Iterator> {
    old: Peekable<O>,
    new: Peekable<N>,
    tile_depth: u8,
}

impl<O, N> Iterator for MergedTiles<O, N>
where
    O: Iterator<Item = Result<TileHistory, ConvertError>>,
    N: Iterator<Item = Result<TileHistory, ConvertError>>,
{
    type Item = Result<TileHistory, ConvertError>;

    fn next(&mut self) -> Option<Self::Item> {
        // `None` for an error or an empty tile, which pass through first.
        let tile_depth = self.tile_depth;
        let code = |tile: &Result<TileHistory, ConvertError>| match tile {
            Err(_) => None,
            Ok(tile) => tile.first_start().map(|c| c.node_start(tile_depth)),
        };
        let old = self.old.peek().map(code);
        let new = self.new.peek().map(code);
        match (old, new) {
            (None, None) => None,
            (Some(_), None) => self.old.next(),
            (None, Some(_)) => self.new.next(),
            (Some(None), _) => self.old.next(),
            (_, Some(None)) => self.new.next(),
            (Some(Some(a)), Some(Some(b))) if a < b => self.old.next(),
            (Some(Some(a)), Some(Some(b))) if b < a => self.new.next(),
            _ => {
                let (Some(Ok(old)), Some(Ok(new))) = (self.old.next(), self.new.next()) else {
                    return Some(Err(ConvertError::internal("a peeked tile went missing")));
                };
                Some(
                    merge_cells(old.into_packed(), new.into_packed())
                        .map(TileHistory::from_packed)
                        .map_err(ConvertError::from),
                )
            }
        }
    }
}

/// The common refinement of two sets of disjoint cells (each in Morton order), with each
/// cell's observations from `old` followed by those of `new` after the last sample `old`
/// observed. The cells stay packed: only a cell on both sides is unpacked, to be joined
/// (a tile of a long series unpacked takes several times its packed size).
pub(crate) fn merge_cells(
    old: Vec<PackedCell>,
    new: Vec<PackedCell>,
) -> Result<Vec<PackedCell>, TemporalError> {
    let mut out = Vec::with_capacity(old.len().max(new.len()));
    common_refinement(old, new, |start, depth, a, b| {
        out.push(match (a, b) {
            (Some(a), Some(b)) => (start, depth, pack(&joined(&a.unpack()?, &b.unpack()?)?)),
            (Some(cell), None) | (None, Some(cell)) => (start, depth, cell),
            (None, None) => return Ok(()),
        });
        Ok(())
    })?;
    Ok(out)
}

/// A cell (first voxel, depth) with what its pieces inherit when it is split.
pub(crate) type Piece<T> = (MortonCode, u8, T);

/// Walks the common refinement of two sets of disjoint cells (each in Morton order): calls
/// `emit(start, depth, a, b)` for each piece in Morton order, with the payload of the cell
/// of `a` and of `b` that holds it (`None` on the side that has no cell there). A coarser
/// cell is split into its eight children, which inherit its payload, until both sides
/// agree; a cell on one side only passes whole. The append's seam and a format 2.0
/// segment's join with its base both use it.
pub(crate) fn common_refinement<A: Clone, B: Clone, E: From<TemporalError>>(
    mut a: Vec<Piece<A>>,
    mut b: Vec<Piece<B>>,
    mut emit: impl FnMut(MortonCode, u8, Option<A>, Option<B>) -> Result<(), E>,
) -> Result<(), E> {
    // Stacks: the next cell is at the end.
    a.reverse();
    b.reverse();
    let span = |start: MortonCode, depth: u8| (start.0, start.0 + voxels_per_node(depth));
    loop {
        let (x, y) = match (a.last(), b.last()) {
            (None, None) => break,
            (Some(_), None) => (a.pop(), None),
            (None, Some(_)) => (None, b.pop()),
            (Some(x), Some(y)) => {
                let ((x_start, x_end), (y_start, y_end)) = (span(x.0, x.1), span(y.0, y.1));
                if x_end <= y_start {
                    (a.pop(), None)
                } else if y_end <= x_start {
                    (None, b.pop())
                } else if x.1 < y.1 {
                    split_last(&mut a)?;
                    continue;
                } else if y.1 < x.1 {
                    split_last(&mut b)?;
                    continue;
                } else {
                    (a.pop(), b.pop())
                }
            }
        };
        match (x, y) {
            (Some(x), Some(y)) => emit(x.0, x.1, Some(x.2), Some(y.2))?,
            (Some(x), None) => emit(x.0, x.1, Some(x.2), None)?,
            (None, Some(y)) => emit(y.0, y.1, None, Some(y.2))?,
            (None, None) => break,
        }
    }
    Ok(())
}

/// Replaces the cell on top of `stack` by its eight children (the first on top), which
/// inherit its payload. Two overlapping cells are nested, so the coarser one is never a
/// single voxel.
fn split_last<T: Clone>(stack: &mut Vec<Piece<T>>) -> Result<(), TemporalError> {
    let Some((start, depth, payload)) = stack.pop() else {
        return Ok(());
    };
    if depth >= TREE_DEPTH {
        return Err(TemporalError::InvalidObservations {
            reason: "overlapping cells of the same size",
            sample: 0,
        });
    }
    let size = voxels_per_node(depth + 1);
    for child in (0..8u64).rev() {
        stack.push((
            MortonCode(start.0 + child * size),
            depth + 1,
            payload.clone(),
        ));
    }
    Ok(())
}

/// `old`'s runs, then `new`'s from the end of `old`'s last run on (a run continuing across
/// the seam is merged by `from_runs`).
fn joined(
    old: &VoxelObservations,
    new: &VoxelObservations,
) -> Result<VoxelObservations, TemporalError> {
    let seam = old.runs().last().map_or(0, |run| run.end());
    let later = new.runs().iter().filter_map(|run| {
        let end = run.end();
        let first = u64::from(run.first).max(seam);
        (first < end).then(|| (first as u32, (end - first) as u32, run.state))
    });
    VoxelObservations::from_runs(
        old.runs()
            .iter()
            .map(|run| (run.first, run.len, run.state))
            .chain(later),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::accumulate::ObservedCell;

    /// [`merge_cells`] on unpacked cells.
    fn merge(
        old: Vec<ObservedCell>,
        new: Vec<ObservedCell>,
    ) -> Result<Vec<ObservedCell>, TemporalError> {
        let packed = |cells: Vec<ObservedCell>| {
            cells
                .into_iter()
                .map(|(start, depth, obs)| (start, depth, pack(&obs)))
                .collect()
        };
        merge_cells(packed(old), packed(new))?
            .into_iter()
            .map(|(start, depth, packed)| Ok((start, depth, packed.unpack()?)))
            .collect()
    }
    use froctomap_core::Occupancy::{self, Free, Occupied};

    fn cell(start: u64, depth: u8, runs: &[(u32, u32, Occupancy)]) -> ObservedCell {
        (
            MortonCode(start),
            depth,
            VoxelObservations::from_runs(runs.to_vec()).unwrap(),
        )
    }

    /// The state of a voxel at a sample according to the cells, by brute force.
    fn state(cells: &[ObservedCell], voxel: u64, sample: u32) -> Option<Occupancy> {
        let (_, _, obs) = cells
            .iter()
            .find(|(s, d, _)| s.0 <= voxel && voxel < s.0 + voxels_per_node(*d))?;
        obs.state_at(sample)
    }

    #[test]
    fn nested_cells_are_refined_and_runs_joined_across_the_seam() {
        // Old: a depth-14 cell (64 voxels) free over samples 0..4 (the seam is sample 3),
        // and a voxel seen only at sample 1.
        let old = vec![
            cell(0, 14, &[(0, 4, Free)]),
            cell(200, 16, &[(1, 1, Occupied)]),
        ];
        // New, from sample 3 on: voxel 9 becomes occupied at 5, the rest stays free;
        // voxel 300 is new.
        let mut new = vec![cell(0, 15, &[(3, 4, Free)])];
        new.push(cell(8, 16, &[(3, 4, Free)]));
        new.push(cell(9, 16, &[(3, 2, Free), (5, 2, Occupied)]));
        new.extend((10..16).map(|v| cell(v, 16, &[(3, 4, Free)])));
        new.extend((2..8).map(|k| cell(k * 8, 15, &[(3, 4, Free)])));
        new.push(cell(300, 16, &[(6, 1, Occupied)]));
        let merged = merge(old.clone(), new.clone()).unwrap();
        assert!(merged
            .windows(2)
            .all(|w| w[0].0 .0 + voxels_per_node(w[0].1) <= w[1].0 .0));
        // The refinement is the finer of the two wherever they overlap.
        assert_eq!(merged.len(), new.len() + 1);
        for voxel in [0, 8, 9, 10, 63, 200, 300] {
            for sample in 0..7 {
                let expected = if sample < 3 {
                    state(&old, voxel, sample)
                } else if sample == 3 {
                    state(&old, voxel, sample).or(state(&new, voxel, sample))
                } else {
                    state(&new, voxel, sample)
                };
                assert_eq!(
                    state(&merged, voxel, sample),
                    expected,
                    "voxel {voxel} sample {sample}"
                );
            }
        }
        // A run that continues across the seam is one run.
        let whole = merged.iter().find(|c| c.0 .0 == 0).unwrap();
        assert_eq!(whole.2.runs().len(), 1);
        assert_eq!((whole.2.runs()[0].first, whole.2.runs()[0].len), (0, 7));
        // Nothing on one side: the other passes unchanged.
        assert_eq!(merge(old.clone(), Vec::new()).unwrap(), old);
        assert_eq!(merge(Vec::new(), new.clone()).unwrap(), new);
    }

    #[test]
    fn the_old_side_decides_the_samples_both_observed() {
        let old = vec![cell(0, 16, &[(0, 2, Free), (2, 2, Occupied)])];
        let new = vec![cell(0, 16, &[(2, 3, Occupied)])];
        let merged = merge(old, new).unwrap();
        assert_eq!(
            merged[0].2,
            VoxelObservations::from_runs([(0, 2, Free), (2, 3, Occupied)]).unwrap()
        );
        // Old unobserved at the seam: the new runs follow the old ones' end.
        let old = vec![cell(0, 16, &[(0, 1, Free)])];
        let new = vec![cell(0, 16, &[(4, 2, Free)])];
        let merged = merge(old, new).unwrap();
        assert_eq!(
            merged[0].2,
            VoxelObservations::from_runs([(0, 1, Free), (4, 2, Free)]).unwrap()
        );
    }

    #[test]
    fn tiles_of_either_side_are_yielded_in_morton_order() {
        let depth = 14;
        let tile = voxels_per_node(depth);
        let history = |tiles: &[(u64, u32)]| -> Vec<Result<TileHistory, ConvertError>> {
            tiles
                .iter()
                .map(|&(t, first)| {
                    Ok(TileHistory::new(vec![cell(
                        t * tile,
                        depth,
                        &[(first, 1, Free)],
                    )]))
                })
                .collect()
        };
        let old = history(&[(0, 0), (2, 0), (5, 0)]);
        let new = history(&[(1, 1), (2, 1), (7, 1)]);
        let merged: Vec<TileHistory> = merge_tiles(old.into_iter(), new.into_iter(), depth)
            .map(Result::unwrap)
            .collect();
        let codes: Vec<u64> = merged.iter().map(|t| t.unpacked()[0].0 .0 / tile).collect();
        assert_eq!(codes, [0, 1, 2, 5, 7]);
        assert_eq!(merged[2].unpacked()[0].2.observed_count(), 2, "joined");
        // An error on either side comes through.
        let failing = vec![Err(ConvertError::internal("test"))];
        let mut merged = merge_tiles(history(&[(0, 0)]).into_iter(), failing.into_iter(), depth);
        assert!(matches!(
            merged.next(),
            Some(Err(ConvertError::Internal { what: "test", .. }))
        ));
    }
}
