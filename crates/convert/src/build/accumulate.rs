//! Stage 3, accumulation: the batches of changes applied in time order to the cells'
//! histories ([`SeriesHistory`]), then handed on tile by tile.
//!
//! In: [`ChangeBatch`]es through [`Accumulator::push`]. Out: [`Accumulated`], whose
//! [`into_tiles`](Accumulated::into_tiles) yields one [`TileHistory`] per tile of the output,
//! in Morton order — all the fitting stage sees of the accumulation.
//!
//! Space is split into ranges at tile boundaries (which no cell straddles), chosen from the
//! first batch's changes, and each range is accumulated by a thread of its own while the
//! next batch is extracted.
//!
//! **Bounded memory.** Given a budget ([`Accumulator::spill_into`]), each thread keeps its
//! histories within its share of it: after a snapshot that takes them over, what grows with
//! the series (closed runs, unobserved gaps) is spilled to the thread's file in a spill
//! directory ([`super::spill`]). Once the series is read, every cell is finished (the runs
//! read back one tile at a time, merged with what is still in memory) and written out to a
//! cell file, freeing the cells, which the fit stage then reads back one at a time: the
//! same cells, in the same order, as an accumulator without a budget yields, so the fitter
//! and writer do not change, and they work beside none of the accumulator's memory.
//! Without a budget everything stays in memory.

use super::extract::{ChangeBatch, ChangeExtractor};
use super::spill::{CellFileReader, CellFileWriter, SpillPlace, SpillReader, SpillWriter};
use crate::error::ConvertError;
use crate::history::{PackedCell, PackedObservations, SeriesHistory};
use crate::progress::Progress;
use froctomap_core::{MortonCode, StateChange};
/// Runs extraction and accumulation side by side: changes are extracted in parallel batches
/// while the accumulating threads apply the previous batch's.
pub(super) fn accumulate_series(
    extractor: &mut ChangeExtractor<'_>,
    tile_depth: u8,
    (spill_place, memory): (&SpillPlace, u64),
    progress: &dyn Progress,
) -> Result<Accumulated, ConvertError> {
    let budget = usize::try_from(memory).unwrap_or(usize::MAX);
    let parts = rayon::current_num_threads().clamp(1, 8);
    std::thread::scope(|scope| {
        let mut accumulator =
            Accumulator::new(scope, tile_depth, parts, progress).spill_into(spill_place, budget);
        let produced = (|| -> Result<(), ConvertError> {
            for batch in extractor.by_ref() {
                crate::progress::stop_if_cancelled(progress)?;
                if !accumulator.push(batch?) {
                    // An accumulating thread stopped on an error, which `finish` reports.
                    break;
                }
            }
            Ok(())
        })();
        let accumulated = accumulator.finish()?;
        produced?;
        Ok(accumulated)
    })
}

#[cfg(test)]
use froctomap_temporal::TemporalError;
use froctomap_temporal::VoxelObservations;
use std::borrow::Cow;
use std::sync::mpsc::SyncSender;
use std::sync::Arc;
use std::thread::{Scope, ScopedJoinHandle};
use std::time::Instant;

/// A cell of the output: its first voxel, its depth and what was observed in it.
pub(crate) type ObservedCell = (MortonCode, u8, VoxelObservations);

/// Observations packed.
pub(crate) fn pack(observations: &VoxelObservations) -> PackedObservations {
    PackedObservations::pack(
        observations
            .runs()
            .iter()
            .map(|run| (run.first, run.len, run.state)),
    )
}

/// The cells of [`Accumulated::into_cells`], in Morton order.
pub(crate) type Cells<'a> = Box<dyn Iterator<Item = Result<PackedCell, ConvertError>> + Send + 'a>;

/// The cells of one tile of the output, in Morton order, with their observations — kept
/// packed, since the tiles waiting to be fitted would otherwise hold most of a long
/// series' memory; each cell is unpacked when it is fitted ([`cells`](Self::cells)).
#[derive(Debug, Default)]
pub(crate) struct TileHistory {
    cells: Vec<PackedCell>,
    runs: usize,
}

impl TileHistory {
    /// A tile of these cells (in Morton order).
    #[cfg(test)]
    pub fn new(cells: Vec<ObservedCell>) -> Self {
        Self::from_packed(
            cells
                .into_iter()
                .map(|(start, depth, observations)| (start, depth, pack(&observations)))
                .collect(),
        )
    }

    /// A tile of these packed cells (in Morton order).
    pub fn from_packed(cells: Vec<PackedCell>) -> Self {
        let runs = cells.iter().map(|cell| cell.2.run_count()).sum();
        Self { cells, runs }
    }

    fn push(&mut self, cell: PackedCell) {
        self.runs += cell.2.run_count();
        self.cells.push(cell);
    }

    /// Its cells.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Observation runs of all its cells.
    #[cfg(test)]
    pub fn runs(&self) -> usize {
        self.runs
    }

    /// The cells, unpacked one at a time.
    #[cfg(test)]
    pub fn cells(&self) -> impl Iterator<Item = Result<ObservedCell, TemporalError>> + '_ {
        self.cells
            .iter()
            .map(|(start, depth, packed)| Ok((*start, *depth, packed.unpack()?)))
    }

    /// The first voxel of its first cell (`None`: no cell).
    pub fn first_start(&self) -> Option<MortonCode> {
        self.cells.first().map(|cell| cell.0)
    }

    /// The cells, packed, in place.
    #[cfg(test)]
    pub fn packed(&self) -> &[PackedCell] {
        &self.cells
    }

    /// The cells, packed.
    pub fn into_packed(self) -> Vec<PackedCell> {
        self.cells
    }

    /// All the cells, unpacked.
    #[cfg(test)]
    pub fn unpacked(&self) -> Vec<ObservedCell> {
        self.cells().map(Result::unwrap).collect()
    }
}

/// What an accumulating thread hands back: its part of the history, what it spilled (if
/// anything) and its busy seconds.
type Worked = Result<(SeriesHistory, Option<SpillWriter>, f64), ConvertError>;

/// Where and when accumulating threads spill.
#[derive(Clone, Copy, Debug)]
struct Spilling<'env> {
    place: &'env SpillPlace,
    /// Bytes of history each thread may hold.
    budget: usize,
}

impl Spilling<'_> {
    /// Whether `history` should be spilled now: over budget, with enough to spill that it
    /// is worth a pass over the cells (the cells themselves are not spilled).
    fn due(&self, history: &SeriesHistory) -> bool {
        history.memory_bytes() > self.budget && history.spillable_bytes() >= self.budget / 8
    }
}

/// The in-memory accumulator: one thread per range of space, started by the first batch.
pub(crate) struct Accumulator<'scope, 'env> {
    scope: &'scope Scope<'scope, 'env>,
    tile_depth: u8,
    parts: usize,
    progress: &'env dyn Progress,
    spilling: Option<Spilling<'env>>,
    workers: Vec<(
        SyncSender<Arc<ChangeBatch>>,
        ScopedJoinHandle<'scope, Worked>,
    )>,
}

impl<'scope, 'env> Accumulator<'scope, 'env> {
    /// An accumulator for cells no coarser than depth-`tile_depth` tiles, working on up to
    /// `parts` threads of `scope`. It advances `progress` by one per snapshot applied.
    pub fn new(
        scope: &'scope Scope<'scope, 'env>,
        tile_depth: u8,
        parts: usize,
        progress: &'env dyn Progress,
    ) -> Self {
        Self {
            scope,
            tile_depth,
            parts: parts.max(1),
            progress,
            spilling: None,
            workers: Vec::new(),
        }
    }

    /// Keeps the histories within about `budget` bytes in all by spilling them into files
    /// in `place` (see the module). Call before the first [`push`](Self::push).
    pub fn spill_into(mut self, place: &'env SpillPlace, budget: usize) -> Self {
        self.spilling = Some(Spilling {
            place,
            budget: budget / self.parts,
        });
        self
    }

    /// Hands a batch (later than the ones before) to the accumulating threads. `false` when a
    /// thread has stopped on an error, which [`finish`](Self::finish) reports.
    pub fn push(&mut self, batch: ChangeBatch) -> bool {
        if self.workers.is_empty() {
            let bounds = split_points(&batch, self.parts, self.tile_depth);
            for (part, range) in ranges(&bounds).into_iter().enumerate() {
                // One thread reports progress for all.
                let progress = (part == 0).then_some(self.progress);
                let (sender, receiver) = std::sync::mpsc::sync_channel::<Arc<ChangeBatch>>(1);
                let tile_depth = self.tile_depth;
                let spilling = self.spilling;
                let worker = self.scope.spawn(move || -> Worked {
                    let mut history = SeriesHistory::new(tile_depth);
                    let mut spilled: Option<SpillWriter> = None;
                    let mut busy = 0.0;
                    for batch in receiver {
                        let started = Instant::now();
                        for snapshot in batch.iter() {
                            history
                                .apply_changes(snapshot.sample, &clip(&snapshot.changes, range))?;
                            if let Some(spilling) = spilling.filter(|s| s.due(&history)) {
                                let writer = match &mut spilled {
                                    Some(writer) => writer,
                                    None => spilled.insert(SpillWriter::create(
                                        &spilling.place.dir()?,
                                        part,
                                        tile_depth,
                                    )?),
                                };
                                writer.spill(&mut history)?;
                            }
                            if let Some(progress) = progress {
                                progress.advance(1);
                            }
                        }
                        busy += started.elapsed().as_secs_f64();
                    }
                    Ok((history, spilled, busy))
                });
                self.workers.push((sender, worker));
            }
        }
        let batch = Arc::new(batch);
        self.workers
            .iter()
            .all(|(sender, _)| sender.send(batch.clone()).is_ok())
    }

    /// Waits for the threads to apply every batch pushed.
    pub fn finish(self) -> Result<Accumulated, ConvertError> {
        let mut parts = Vec::with_capacity(self.workers.len());
        let mut busy_seconds = 0.0f64;
        let mut spills = 0;
        let mut failed = None;
        // Every thread is joined, also after one failed.
        for (sender, worker) in self.workers {
            drop(sender);
            let worked = worker
                .join()
                .map_err(|_| ConvertError::internal("an accumulating thread panicked"))
                .and_then(|worked| worked);
            match worked {
                Ok((history, spilled, seconds)) if failed.is_none() => {
                    spills = spills.max(spilled.as_ref().map_or(0, SpillWriter::spills));
                    let spilled = spilled.map(SpillWriter::into_reader).transpose();
                    match spilled {
                        Ok(spilled) => parts.push((history, spilled)),
                        Err(e) => failed = Some(e),
                    }
                    busy_seconds = busy_seconds.max(seconds);
                }
                Ok(_) => {}
                Err(e) => {
                    failed.get_or_insert(e);
                }
            }
        }
        if let Some(e) = failed {
            return Err(e);
        }
        Ok(Accumulated {
            parts,
            busy_seconds,
            spills,
            tile_depth: self.tile_depth,
        })
    }
}

/// The histories of a whole series, in ranges of space in Morton order.
#[derive(Debug)]
pub(crate) struct Accumulated {
    /// Each range's history in memory, and what it spilled.
    parts: Vec<(SeriesHistory, Option<SpillReader>)>,
    busy_seconds: f64,
    spills: usize,
    tile_depth: u8,
}

impl Accumulated {
    /// Cells in all.
    pub fn cell_count(&self) -> usize {
        self.parts.iter().map(|(h, _)| h.cell_count()).sum()
    }

    /// Voxel-changes seen (a voxel changing state at one snapshot counts once).
    pub fn changed_voxels(&self) -> u64 {
        self.parts.iter().map(|(h, _)| h.changed_voxels()).sum()
    }

    /// Bytes spilled to disk in all.
    pub fn spilled_bytes(&self) -> u64 {
        let spilled = self.parts.iter().filter_map(|(_, s)| s.as_ref());
        spilled.map(SpillReader::bytes).sum()
    }

    /// The most times one thread spilled.
    pub fn spills(&self) -> usize {
        self.spills
    }

    /// Seconds the busiest thread spent applying changes (the part that is sequential).
    pub fn busy_seconds(&self) -> f64 {
        self.busy_seconds
    }

    /// The histories closed at the end of an axis of `axis_len` samples, tile by tile in
    /// Morton order, with the samples in `absent` (sorted: no snapshot) cut out.
    pub fn into_tiles(self, axis_len: u32, absent: &[u32]) -> TileHistories<Cells<'_>> {
        let tile_depth = self.tile_depth;
        TileHistories {
            cells: self.into_cells(axis_len, absent),
            tile_depth,
            next: None,
        }
    }

    /// The histories closed at the end of an axis of `axis_len` samples, cell by cell in
    /// Morton order (a tile's cells one after the other), with the samples in `absent`
    /// (sorted: no snapshot) cut out.
    ///
    /// When the histories were spilled (a long series), every cell is first written out,
    /// finished, into a file in the spill directory ([`CellFileWriter`]), each range's
    /// cells by a thread of their own (into a file per range, read back one after the other)
    /// and freed as they go, and the cells are then read back one at a time: the fit stage
    /// that follows holds none of the accumulator's cells beside its own work, so that the
    /// peak of the build is the larger of the accumulation's and the fit's, not their sum.
    /// Otherwise the cells are handed out from memory. Either way only the cell being
    /// handed out, and the spilled runs of its tile, are read back at a time.
    pub fn into_cells(self, axis_len: u32, absent: &[u32]) -> Cells<'_> {
        let spill_dir = self
            .parts
            .iter()
            .find_map(|(_, spilled)| spilled.as_ref().map(SpillReader::dir));
        let Some(dir) = spill_dir else {
            return Box::new(self.cells_in_memory(axis_len, absent));
        };
        let settled = std::thread::scope(|scope| {
            let settling: Vec<_> = self
                .parts
                .into_iter()
                .enumerate()
                .map(|(part, (history, mut spilled))| {
                    let dir = &dir;
                    scope.spawn(move || -> Result<CellFileReader, ConvertError> {
                        let mut file = CellFileWriter::create(dir, part)?;
                        let cells = history.finish_with(axis_len, absent, |start, _, runs| {
                            match &mut spilled {
                                Some(spilled) => spilled.runs_for(start, runs),
                                None => Ok(()),
                            }
                        });
                        for cell in cells {
                            file.push(&cell?)?;
                        }
                        file.into_reader()
                    })
                })
                .collect();
            settling
                .into_iter()
                .map(|thread| {
                    thread
                        .join()
                        .map_err(|_| ConvertError::internal("a thread settling cells panicked"))?
                })
                .collect::<Result<Vec<CellFileReader>, ConvertError>>()
        });
        match settled {
            Ok(ranges) => Box::new(ranges.into_iter().flatten()),
            Err(e) => Box::new(std::iter::once(Err(e))),
        }
    }

    /// [`into_cells`](Self::into_cells) from the histories in memory and the spilled runs.
    fn cells_in_memory(
        self,
        axis_len: u32,
        absent: &[u32],
    ) -> impl Iterator<Item = Result<PackedCell, ConvertError>> + Send + '_ {
        self.parts
            .into_iter()
            .flat_map(move |(history, mut spilled)| {
                history.finish_with(axis_len, absent, move |start, _, runs| match &mut spilled {
                    Some(spilled) => spilled.runs_for(start, runs),
                    None => Ok(()),
                })
            })
    }

    /// The depth of the tiles the cells are grouped in.
    pub fn tile_depth(&self) -> u8 {
        self.tile_depth
    }
}

/// Cells grouped into the tiles of the output.
pub(crate) struct TileHistories<I> {
    cells: I,
    tile_depth: u8,
    /// The first cell of the next tile, read past the end of the one before.
    next: Option<PackedCell>,
}

impl<I: Iterator<Item = Result<PackedCell, ConvertError>>> Iterator for TileHistories<I> {
    type Item = Result<TileHistory, ConvertError>;

    fn next(&mut self) -> Option<Self::Item> {
        let mut tile = TileHistory::default();
        if let Some(cell) = self.next.take() {
            tile.push(cell);
        }
        for cell in self.cells.by_ref() {
            let cell = match cell {
                Ok(cell) => cell,
                Err(e) => return Some(Err(e)),
            };
            let tile_of = |c: &PackedCell| c.0.node_start(self.tile_depth);
            if tile
                .cells
                .first()
                .is_some_and(|first| tile_of(first) != tile_of(&cell))
            {
                self.next = Some(cell);
                break;
            }
            tile.push(cell);
        }
        (!tile.cells.is_empty()).then_some(Ok(tile))
    }
}

/// Up to `parts - 1` increasing tile boundaries that split the changes of a batch into parts
/// of about as many changes (the first snapshot, which is all new, is left out when others
/// follow: later snapshots change where the scene moves).
fn split_points(batch: &[super::extract::SampleChanges], parts: usize, tile_depth: u8) -> Vec<u64> {
    let sample = match batch {
        [_, rest @ ..] if rest.iter().any(|s| !s.changes.is_empty()) => rest,
        all => all,
    };
    let mut starts: Vec<u64> = sample
        .iter()
        .flat_map(|s| s.changes.iter().map(|c| c.start))
        .collect();
    starts.sort_unstable();
    let mut bounds: Vec<u64> = (1..parts)
        .filter_map(|i| starts.get(starts.len() * i / parts))
        .map(|&at| MortonCode(at).node_start(tile_depth).0)
        .filter(|&at| at > 0)
        .collect();
    bounds.dedup();
    bounds
}

/// The ranges `[from, to)` between consecutive bounds, covering all space.
fn ranges(bounds: &[u64]) -> Vec<(u64, u64)> {
    let mut edges = vec![0];
    edges.extend_from_slice(bounds);
    edges.push(MortonCode::END);
    edges.windows(2).map(|w| (w[0], w[1])).collect()
}

/// The changes (sorted, disjoint) inside `[from, to)`, cut at its ends.
fn clip(changes: &[StateChange], (from, to): (u64, u64)) -> Cow<'_, [StateChange]> {
    let first = changes.partition_point(|c| c.end <= from);
    let last = changes.partition_point(|c| c.start < to).max(first);
    let inside = &changes[first..last];
    match (inside.first(), inside.last()) {
        (Some(a), Some(b)) if a.start < from || b.end > to => inside
            .iter()
            .map(|c| StateChange {
                start: c.start.max(from),
                end: c.end.min(to),
                new: c.new,
            })
            .collect(),
        _ => Cow::Borrowed(inside),
    }
}

#[cfg(test)]
mod tests {
    use super::super::extract::SampleChanges;
    use super::*;
    use crate::progress::Silent;
    use froctomap_core::{voxels_per_node, Occupancy};

    fn change(start: u64, end: u64, new: Option<Occupancy>) -> StateChange {
        StateChange { start, end, new }
    }

    fn occupied(start: u64, end: u64) -> StateChange {
        change(start, end, Some(Occupancy::Occupied))
    }

    #[test]
    fn changes_are_split_at_part_bounds_without_loss() {
        let changes = [occupied(0, 10), occupied(20, 40), occupied(50, 60)];
        let bounds = [30u64, 55];
        let parts = ranges(&bounds);
        assert_eq!(parts, [(0, 30), (30, 55), (55, MortonCode::END)]);
        let clipped: Vec<Vec<StateChange>> = parts
            .iter()
            .map(|&r| clip(&changes, r).into_owned())
            .collect();
        assert_eq!(clipped[0], [occupied(0, 10), occupied(20, 30)]);
        assert_eq!(clipped[1], [occupied(30, 40), occupied(50, 55)]);
        assert_eq!(clipped[2], [occupied(55, 60)]);
        // Changes inside one part are passed on as they are.
        assert!(matches!(clip(&changes[..1], parts[0]), Cow::Borrowed(_)));
        // Bounds are tile starts, increasing, from the changes after the first snapshot.
        let batch = vec![
            SampleChanges {
                sample: 0,
                changes: vec![occupied(0, 1 << 40)],
            },
            SampleChanges {
                sample: 1,
                changes: (0..100u64)
                    .map(|i| occupied(i << 34, (i << 34) + 1))
                    .collect(),
            },
        ];
        let bounds = split_points(&batch, 2, 10);
        assert_eq!(bounds.len(), 1);
        assert_eq!(bounds[0] % voxels_per_node(10), 0);
        assert!(bounds[0] > 40 << 34 && bounds[0] <= 50 << 34, "{bounds:?}");
        assert!(split_points(&[], 2, 10).is_empty());
    }

    /// A small series over four tiles of depth 14 (64 voxels each), with changes in each.
    fn series() -> Vec<ChangeBatch> {
        let tile = voxels_per_node(14);
        let free = |s, e| change(s, e, Some(Occupancy::Free));
        vec![
            vec![
                SampleChanges {
                    sample: 0,
                    changes: vec![free(0, 4 * tile)],
                },
                SampleChanges {
                    sample: 1,
                    changes: vec![occupied(3, 5), occupied(tile + 7, tile + 8)],
                },
            ],
            vec![
                SampleChanges {
                    sample: 2,
                    changes: vec![free(3, 5), change(2 * tile, 2 * tile + 8, None)],
                },
                SampleChanges {
                    sample: 4,
                    changes: vec![occupied(3 * tile + 1, 3 * tile + 2)],
                },
            ],
        ]
    }

    /// The tiles accumulated by `parts` threads.
    fn tiles(parts: usize) -> Vec<Vec<ObservedCell>> {
        tiles_spilling(parts, None)
    }

    /// The tiles accumulated by `parts` threads, spilling into `spill` (a directory and a
    /// budget) if given.
    fn tiles_spilling(parts: usize, spill: Option<(&SpillPlace, usize)>) -> Vec<Vec<ObservedCell>> {
        std::thread::scope(|scope| {
            let mut accumulator = Accumulator::new(scope, 14, parts, &Silent);
            if let Some((place, budget)) = spill {
                accumulator = accumulator.spill_into(place, budget);
            }
            for batch in series() {
                assert!(accumulator.push(batch));
            }
            let accumulated = accumulator.finish().unwrap();
            if spill.is_some() {
                assert!(accumulated.spilled_bytes() > 0 && accumulated.spills() > 0);
            }
            assert_eq!(accumulated.changed_voxels(), 4 * 64 + 2 + 1 + 2 + 8 + 1);
            let cells = accumulated.cell_count();
            let tiles: Vec<TileHistory> = accumulated
                .into_tiles(5, &[3])
                .map(Result::unwrap)
                .collect();
            for tile in &tiles {
                let runs: usize = tile.unpacked().iter().map(|c| c.2.runs().len()).sum();
                // Counted before adjacent runs of one state are merged.
                assert!(tile.runs() >= runs);
            }
            assert_eq!(tiles.iter().map(TileHistory::len).sum::<usize>(), cells);
            tiles.iter().map(TileHistory::unpacked).collect()
        })
    }

    #[test]
    fn histories_come_out_tile_by_tile_whatever_the_threads() {
        let one = tiles(1);
        assert_eq!(one.len(), 4);
        for (i, tile) in one.iter().enumerate() {
            let start = i as u64 * voxels_per_node(14);
            assert!(tile.windows(2).all(|w| w[0].0 < w[1].0), "Morton order");
            assert!(tile
                .iter()
                .all(|c| c.0.node_start(14).0 == start && c.1 >= 14));
        }
        // The changed voxel 3 of the first tile: free, occupied at 1, free from 2 on; the
        // absent sample 3 is cut out.
        let cell = one[0]
            .iter()
            .find(|c| c.0 .0 <= 3 && 3 < c.0 .0 + voxels_per_node(c.1))
            .unwrap();
        let states: Vec<Option<Occupancy>> = (0..5).map(|s| cell.2.state_at(s)).collect();
        use Occupancy::{Free, Occupied};
        assert_eq!(
            states,
            [Some(Free), Some(Occupied), Some(Free), None, Some(Free)]
        );
        // A tile that went unobserved keeps what it saw before.
        let hidden = &one[2][0];
        assert_eq!(hidden.2.state_at(1), Some(Free));
        assert_eq!(hidden.2.state_at(2), None);
        for parts in [2, 3, 8] {
            let split = tiles(parts);
            assert_eq!(split.len(), one.len());
            for (a, b) in split.iter().zip(&one) {
                assert_eq!(a, b, "{parts} threads");
            }
        }
    }

    #[test]
    fn spilled_histories_come_out_the_same() {
        let kept = tiles(1);
        for parts in [1, 3] {
            let dir = tempfile::tempdir().unwrap();
            let place = SpillPlace::new(dir.path());
            let spilled = tiles_spilling(parts, Some((&place, 0)));
            assert_eq!(spilled.len(), kept.len());
            for (a, b) in spilled.iter().zip(&kept) {
                assert_eq!(a, b, "{parts} threads");
            }
        }
    }

    #[test]
    fn an_out_of_order_batch_is_reported_by_finish() {
        let result = std::thread::scope(|scope| {
            let mut accumulator = Accumulator::new(scope, 14, 2, &Silent);
            let batch = |sample| {
                vec![SampleChanges {
                    sample,
                    changes: vec![occupied(0, 8)],
                }]
            };
            accumulator.push(batch(3));
            // The threads may or may not have stopped yet when the second batch arrives.
            accumulator.push(batch(1));
            accumulator.finish().map(|_| ())
        });
        assert!(matches!(
            result,
            Err(ConvertError::Model(
                TemporalError::InvalidObservations { .. }
            ))
        ));
    }
}
