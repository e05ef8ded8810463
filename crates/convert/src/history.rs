//! Streaming accumulation of a series into per-cell observation runs.
//!
//! Snapshots arrive one at a time in time order, as the ranges where each differs from the
//! previous one ([`froctomap_core::changes`], or a format's byte-level differ), which callers can compute in parallel): only the ranges whose
//! state changed (including known ↔ unknown) touch the cells. Unchanged space
//! costs nothing per snapshot, so the work per snapshot is proportional to its leaves plus
//! its changes, and memory to the cells and their changes — never to the number of
//! snapshots.
//!
//! Cells are the common refinement of every snapshot seen: a cell is split only when a
//! change boundary falls inside it, and its history is inherited by its eight children.
//! Cells are never coarser than a tile of the output file.
//!
//! **Spilling.** What grows with the series — closed runs and the unobserved gaps — can be
//! handed out between snapshots ([`SeriesHistory::spill`]): each cell's runs up to now,
//! already cut by every gap recorded so far, after which the gaps are dropped. This is
//! exact because a gap recorded later never reaches back into runs that were closed (or
//! cut) before it: its start lies inside the cell's open run. At the end,
//! [`SeriesHistory::finish_with`] prepends what was spilled for each cell (and for the
//! coarser cells it was split from) to the runs still in memory.

use froctomap_core::{voxels_per_node, MortonCode, Occupancy, StateChange, TREE_DEPTH};
use froctomap_temporal::{varint, Run, TemporalError, VoxelObservations};
use std::collections::BTreeMap;

/// Closed runs packed as varints (gap since the previous run's end, then `len << 1 | state`):
/// two to four bytes a run instead of twelve, since a long series with partial views gives
/// every cell many runs.
#[derive(Clone, Debug, Default)]
struct PackedRuns {
    bytes: Vec<u8>,
    end: u32,
}

impl PackedRuns {
    fn push(&mut self, run: Run) {
        varint::write_u32(&mut self.bytes, run.first - self.end);
        varint::write_u64(
            &mut self.bytes,
            u64::from(run.len) << 1 | u64::from(run.state.is_occupied()),
        );
        self.end = run.first + run.len;
    }

    fn iter(&self) -> impl Iterator<Item = Run> + '_ {
        let mut pos = 0usize;
        let mut end = 0u32;
        std::iter::from_fn(move || {
            let rest = self.bytes.get(pos..)?;
            // Written by `push` above, so well-formed; a failure just ends the iteration.
            let (gap, a) = varint::read_u32(rest).ok()?;
            let (packed, b) = varint::read_u64(rest.get(a..)?).ok()?;
            pos += a + b;
            let first = end + gap;
            let len = (packed >> 1) as u32;
            end = first + len;
            let state = Occupancy::from(packed & 1 == 1);
            Some(Run { first, len, state })
        })
    }
}

#[derive(Clone, Debug)]
struct CellHistory {
    depth: u8,
    /// Closed runs; they may span samples without a snapshot, removed in `finish`.
    runs: PackedRuns,
    /// The state observed since a sample, while the cell is observed or may resume it.
    open: Option<(Occupancy, u32)>,
    /// Unobserved since this sample, with `open` kept: a partial view usually hides a
    /// region for a frame or two and then shows it unchanged, and closing a run in every
    /// cell of the region would make memory grow with every such frame.
    unobserved_since: Option<u32>,
}

impl CellHistory {
    fn new(depth: u8, open: Option<(Occupancy, u32)>) -> Self {
        Self {
            depth,
            runs: PackedRuns::default(),
            open,
            unobserved_since: None,
        }
    }

    /// Records the state observed from `sample` on (`None`: unknown). Returns the start of
    /// an unobserved gap that ends at `sample` when the cell reappears in the state it had
    /// before the gap: the caller records that gap once for a whole region ([`Gap`]).
    fn observe(&mut self, sample: u32, state: Option<Occupancy>) -> Option<u32> {
        let Some((old, _)) = self.open else {
            self.open = state.map(|s| (s, sample));
            return None;
        };
        match (state, self.unobserved_since) {
            (None, None) => self.unobserved_since = Some(sample),
            (None, Some(_)) => {}
            (Some(new), Some(since)) if new == old => {
                self.unobserved_since = None;
                return Some(since);
            }
            (Some(new), since) => {
                self.close(since.unwrap_or(sample));
                self.unobserved_since = None;
                self.open = Some((new, sample));
            }
        }
        None
    }

    /// Ends the open run (if any) before `end`.
    fn close(&mut self, end: u32) {
        if let Some((state, first)) = self.open.take() {
            self.runs.push(Run {
                first,
                len: end - first,
                state,
            });
        }
    }

    /// Ends the history at the end of an axis of `axis_len` samples.
    fn finish(&mut self, axis_len: u32) {
        let end = self.unobserved_since.take().unwrap_or(axis_len);
        self.close(end);
    }
}

/// Cells `[start, end)` (Morton codes) that were all unobserved in samples `[from, to)` while
/// their open runs continued: cut out of those runs in `finish`. One gap stands for every
/// cell of a region a partial view hid, so memory grows with the number of such regions,
/// not with the cells in them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Gap {
    start: u64,
    end: u64,
    from: u32,
    to: u32,
}

/// The cells of a series so far, with their observation histories.
#[derive(Debug)]
pub struct SeriesHistory {
    cells: BTreeMap<u64, CellHistory>,
    /// Closed gaps, and the one still growing at the current sample.
    gaps: Vec<Gap>,
    growing_gap: Option<Gap>,
    tile_depth: u8,
    last_sample: Option<u32>,
    changed_voxels: u64,
    /// Bytes allocated for closed runs (capacity), the part of memory that grows with time.
    run_bytes: usize,
}

/// Estimated bytes of one cell held in memory besides its runs (the map node and the fixed
/// part of its history), for [`SeriesHistory::memory_bytes`].
const CELL_BYTES: usize = 96;

impl SeriesHistory {
    /// An empty history whose cells will never be coarser than a depth-`tile_depth` node.
    pub fn new(tile_depth: u8) -> Self {
        Self {
            cells: BTreeMap::new(),
            gaps: Vec::new(),
            growing_gap: None,
            tile_depth: tile_depth.clamp(1, TREE_DEPTH),
            last_sample: None,
            changed_voxels: 0,
            run_bytes: 0,
        }
    }

    /// An estimate of the memory held: the cells, their closed runs and the gaps.
    pub fn memory_bytes(&self) -> usize {
        self.cells.len() * CELL_BYTES + self.spillable_bytes()
    }

    /// The part of [`memory_bytes`](Self::memory_bytes) that [`spill`](Self::spill) frees:
    /// closed runs and gaps, which grow with the series.
    pub fn spillable_bytes(&self) -> usize {
        self.run_bytes + (self.gaps.len() + 1) * std::mem::size_of::<Gap>()
    }

    /// Number of cells so far.
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    /// Voxel-changes seen so far (a voxel changing state at one snapshot counts once).
    pub fn changed_voxels(&self) -> u64 {
        self.changed_voxels
    }

    /// Records the snapshot taken at `sample` (after the previous one) by the ranges where
    /// it differs from the previous snapshot ([`froctomap_core::changes`]); none when it is identical.
    pub fn apply_changes(
        &mut self,
        sample: u32,
        changes: &[StateChange],
    ) -> Result<(), TemporalError> {
        if self.last_sample.is_some_and(|last| sample <= last) {
            return Err(TemporalError::InvalidObservations {
                reason: "snapshots must arrive in increasing sample order",
                sample: u64::from(sample),
            });
        }
        self.last_sample = Some(sample);
        self.gaps.extend(self.growing_gap.take());
        if self.cells.is_empty() {
            // The first map (of a build, of each segment): every change is space seen for
            // the first time, so its cells are added in one pass in Morton order, without
            // `apply`'s search for cells to split. They go straight into the map (appended
            // at its right edge), not through a collected vector: a bulk build would hold
            // every cell twice, and a map of millions of leaves must stay within the
            // memory limit.
            for &change in changes {
                self.changed_voxels += change.end - change.start;
                if let Some(state) = change.new {
                    self.add_cells(change.start, change.end, sample, state);
                }
            }
            return Ok(());
        }
        for &change in changes {
            self.changed_voxels += change.end - change.start;
            self.apply(sample, change);
        }
        Ok(())
    }

    fn apply(&mut self, sample: u32, change: StateChange) {
        self.split_at(change.start);
        self.split_at(change.end);
        // A gap may only stretch over space that holds no other cell.
        if let Some(gap) = self.growing_gap {
            if self.cells.range(gap.end..change.start).next().is_some() {
                self.gaps.extend(self.growing_gap.take());
            }
        }
        let mut cursor = change.start;
        let mut unseen = Vec::new();
        for (&start, cell) in self.cells.range_mut(change.start..change.end) {
            if start > cursor {
                unseen.push((cursor, start));
            }
            cursor = start + voxels_per_node(cell.depth);
            let capacity = cell.runs.bytes.capacity();
            let reappeared = cell.observe(sample, change.new);
            self.run_bytes += cell.runs.bytes.capacity() - capacity;
            match reappeared {
                Some(from) => match &mut self.growing_gap {
                    Some(gap) if gap.from == from => gap.end = cursor,
                    growing => {
                        self.gaps.extend(growing.take());
                        *growing = Some(Gap {
                            start,
                            end: cursor,
                            from,
                            to: sample,
                        });
                    }
                },
                None => self.gaps.extend(self.growing_gap.take()),
            }
        }
        if cursor < change.end {
            unseen.push((cursor, change.end));
        }
        // Space seen for the first time becomes new cells (only where something is known).
        // They start at `sample`, after any gap that may stretch over them.
        if let Some(state) = change.new {
            for (from, to) in unseen {
                self.add_cells(from, to, sample, state);
            }
        }
    }

    /// Covers `[from, to)` with maximal aligned cells no coarser than a tile.
    fn add_cells(&mut self, mut from: u64, to: u64, sample: u32, state: Occupancy) {
        while from < to {
            let mut depth = TREE_DEPTH;
            while depth > self.tile_depth {
                let bigger = voxels_per_node(depth - 1);
                if from % bigger != 0 || from + bigger > to {
                    break;
                }
                depth -= 1;
            }
            self.cells
                .insert(from, CellHistory::new(depth, Some((state, sample))));
            from += voxels_per_node(depth);
        }
    }

    /// Splits the cell that strictly contains position `at`, recursively, until `at` is a
    /// cell boundary. Children inherit the history.
    fn split_at(&mut self, at: u64) {
        loop {
            let Some((&start, cell)) = self.cells.range(..at).next_back() else {
                return;
            };
            if start + voxels_per_node(cell.depth) <= at || cell.depth >= TREE_DEPTH {
                return;
            }
            let Some(parent) = self.cells.remove(&start) else {
                return;
            };
            let depth = parent.depth + 1;
            let size = voxels_per_node(depth);
            // Seven more copies of the runs (a clone allocates just their length).
            self.run_bytes += 8 * parent.runs.bytes.len();
            self.run_bytes -= parent.runs.bytes.capacity();
            for child in 0..8 {
                let history = CellHistory {
                    depth,
                    ..parent.clone()
                };
                self.cells.insert(start + child * size, history);
            }
        }
    }

    /// Closes every history at the end of an axis of `axis_len` samples and yields each
    /// cell's observations in Morton order, with the samples in `absent` (sorted: samples
    /// with no snapshot) and the cell's unobserved gaps removed from the runs.
    pub fn finish(
        self,
        axis_len: u32,
        absent: &[u32],
    ) -> impl Iterator<Item = Result<(MortonCode, u8, VoxelObservations), TemporalError>> + '_ {
        self.finish_with(axis_len, absent, |_, _, _| Ok::<(), TemporalError>(()))
            .map(|cell| {
                let (start, depth, packed) = cell?;
                Ok((start, depth, packed.unpack()?))
            })
    }

    /// [`finish`](Self::finish) for a history that was [`spill`](Self::spill)ed, with each
    /// cell's observations still packed: `spilled` appends, for the cell at `start` of
    /// `depth`, the runs spilled for it and for the coarser cells it was split from, in the
    /// order they were spilled.
    pub fn finish_with<'a, E>(
        mut self,
        axis_len: u32,
        absent: &'a [u32],
        mut spilled: impl FnMut(u64, u8, &mut Vec<Run>) -> Result<(), E> + 'a,
    ) -> impl Iterator<Item = Result<(MortonCode, u8, PackedObservations), E>> + 'a {
        self.gaps.extend(self.growing_gap.take());
        let mut containing = ContainingGaps::new(std::mem::take(&mut self.gaps));
        let mut earlier: Vec<Run> = Vec::new();
        self.cells.into_iter().map(move |(start, mut cell)| {
            cell.finish(axis_len);
            let cut = containing.at(start);
            earlier.clear();
            spilled(start, cell.depth, &mut earlier)?;
            // Spilled runs were cut by the gaps of their time; the gaps left are later.
            let runs = earlier
                .iter()
                .copied()
                .chain(cell.runs.iter().flat_map(|run| without_gaps(run, cut)))
                .flat_map(|run| without_absent(run, absent));
            Ok((
                MortonCode(start),
                cell.depth,
                PackedObservations::pack(runs),
            ))
        })
    }

    /// Hands out what grows with the series, between two snapshots: `sink` gets, for each
    /// cell in Morton order with anything to hand out (its start, its depth), its closed
    /// runs and the parts of its open run before the last gap recorded in it, all cut by
    /// the gaps recorded so far; the runs are then dropped, the open runs shortened and the
    /// gaps forgotten. [`finish_with`](Self::finish_with) must be given the runs back.
    pub fn spill<E>(
        &mut self,
        mut sink: impl FnMut(u64, u8, &[Run]) -> Result<(), E>,
    ) -> Result<(), E> {
        self.gaps.extend(self.growing_gap.take());
        let mut containing = ContainingGaps::new(std::mem::take(&mut self.gaps));
        let mut pieces: Vec<Run> = Vec::new();
        for (&start, cell) in self.cells.iter_mut() {
            let cut = containing.at(start);
            pieces.clear();
            pieces.extend(cell.runs.iter().flat_map(|run| without_gaps(run, cut)));
            if let Some((state, first)) = &mut cell.open {
                // Gaps recorded inside the open run end before now: the run's pieces before
                // the last of them are final, as they would be cut at the end.
                for &(from, to) in cut {
                    if to <= *first {
                        continue;
                    }
                    if from > *first {
                        pieces.push(Run {
                            first: *first,
                            len: from - *first,
                            state: *state,
                        });
                    }
                    *first = (*first).max(to);
                }
            }
            if !pieces.is_empty() {
                sink(start, cell.depth, &pieces)?;
            }
            cell.runs = PackedRuns::default();
        }
        self.run_bytes = 0;
        Ok(())
    }
}

/// The gaps (sorted by start) that contain each cell in turn, for cells visited in Morton
/// order (cells never straddle a gap's bounds).
struct ContainingGaps {
    gaps: Vec<Gap>,
    next_gap: usize,
    containing: Vec<Gap>,
    first_end: u64,
    /// The `(from, to)` sample ranges of the gaps containing the current cell, sorted.
    cut: Vec<(u32, u32)>,
}

impl ContainingGaps {
    fn new(mut gaps: Vec<Gap>) -> Self {
        gaps.sort_unstable_by_key(|gap| gap.start);
        Self {
            gaps,
            next_gap: 0,
            containing: Vec::new(),
            first_end: u64::MAX,
            cut: Vec::new(),
        }
    }

    /// The sample ranges to cut out of the runs of the cell at `start` (after the cells
    /// before it).
    fn at(&mut self, start: u64) -> &[(u32, u32)] {
        if start >= self.first_end {
            self.containing.retain(|gap| gap.end > start);
            self.first_end = self
                .containing
                .iter()
                .map(|g| g.end)
                .min()
                .unwrap_or(u64::MAX);
        }
        while let Some(&gap) = self.gaps.get(self.next_gap).filter(|g| g.start <= start) {
            self.next_gap += 1;
            if gap.end > start {
                self.first_end = self.first_end.min(gap.end);
                self.containing.push(gap);
            }
        }
        self.cut.clear();
        self.cut
            .extend(self.containing.iter().map(|gap| (gap.from, gap.to)));
        self.cut.sort_unstable();
        &self.cut
    }
}

/// A cell with its observations packed ([`PackedObservations`]).
pub(crate) type PackedCell = (MortonCode, u8, PackedObservations);

/// A cell's observation runs as `(first, len, state)`, packed as varints until they are
/// needed: three bytes or so a run where [`VoxelObservations`] takes twelve, so that the
/// tiles waiting to be fitted hold a fraction of the memory. Unpacking gives exactly the
/// runs packed (checked then, as [`VoxelObservations::from_runs`] checks them).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PackedObservations {
    bytes: Box<[u8]>,
    runs: usize,
}

impl PackedObservations {
    /// Packs runs (any `u32` values: they come back as given).
    pub fn pack(runs: impl IntoIterator<Item = (u32, u32, Occupancy)>) -> Self {
        let mut bytes = Vec::new();
        let mut end = 0u32;
        let mut count = 0usize;
        for (first, len, state) in runs {
            varint::write_u32(&mut bytes, first.wrapping_sub(end));
            varint::write_u64(
                &mut bytes,
                u64::from(len) << 1 | u64::from(state.is_occupied()),
            );
            end = first.wrapping_add(len);
            count += 1;
        }
        Self {
            bytes: bytes.into_boxed_slice(),
            runs: count,
        }
    }

    /// The packed bytes (for [`from_packed`](Self::from_packed)).
    pub(crate) fn packed_bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Observations packed before (`bytes` and `runs` as [`packed_bytes`](Self::packed_bytes)
    /// and [`run_count`](Self::run_count) gave them), e.g. read back from disk. `None` when
    /// `runs` cannot be right (every run takes two bytes at least), so that a damaged count
    /// never reserves a huge vector when unpacked; the bytes are checked when unpacked.
    pub(crate) fn from_packed(bytes: Box<[u8]>, runs: usize) -> Option<Self> {
        (runs <= bytes.len() / 2 && (runs > 0 || bytes.is_empty())).then_some(Self { bytes, runs })
    }

    /// Runs packed.
    pub fn run_count(&self) -> usize {
        self.runs
    }

    /// The observations.
    pub fn unpack(&self) -> Result<VoxelObservations, TemporalError> {
        let mut reader = varint::Reader::new(&self.bytes);
        let mut runs = Vec::with_capacity(self.runs);
        let mut end = 0u32;
        while reader.remaining() > 0 {
            let first = end.wrapping_add(reader.u32()?);
            let packed = reader.u64()?;
            let len = (packed >> 1) as u32;
            end = first.wrapping_add(len);
            runs.push((first, len, Occupancy::from(packed & 1 == 1)));
        }
        VoxelObservations::from_runs(runs)
    }
}

/// A run with the sample ranges `[from, to)` of `gaps` (sorted, disjoint) cut out.
fn without_gaps(run: Run, gaps: &[(u32, u32)]) -> Vec<Run> {
    let mut pieces = Vec::with_capacity(gaps.len() + 1);
    let mut first = run.first;
    let end = run.end();
    for &(from, to) in gaps {
        if u64::from(from) >= end {
            break;
        }
        if from > first {
            pieces.push(Run {
                first,
                len: from - first,
                state: run.state,
            });
        }
        first = first.max(to);
    }
    if u64::from(first) < end {
        pieces.push(Run {
            first,
            len: (end - u64::from(first)) as u32,
            state: run.state,
        });
    }
    pieces
}

/// A run with the absent samples cut out, as `(first, len, state)` pieces.
fn without_absent(run: Run, absent: &[u32]) -> Vec<(u32, u32, Occupancy)> {
    let end = run.end();
    let from = absent.partition_point(|&a| a < run.first);
    let to = absent.partition_point(|&a| u64::from(a) < end);
    let mut pieces = Vec::with_capacity(to - from + 1);
    let mut first = run.first;
    for &hole in &absent[from..to] {
        if hole > first {
            pieces.push((first, hole - first, run.state));
        }
        first = hole + 1;
    }
    if u64::from(first) < end {
        pieces.push((first, (end - u64::from(first)) as u32, run.state));
    }
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::{changes, Leaf, Snapshot, VoxelKey};
    use proptest::prelude::*;

    fn leaf(x: u16, depth: u8, occupied: bool) -> Leaf {
        Leaf::containing(
            VoxelKey::new(x, 0, 0),
            depth,
            if occupied { 1.0 } else { -1.0 },
        )
    }

    /// A snapshot of a proptest frame: a leaf per `(slot, depth, state)` at voxel `4 * slot`,
    /// those overlapping an earlier one left out.
    fn frame_snapshot(frame: Vec<(u16, u8, Option<bool>)>) -> Snapshot {
        let mut leaves: Vec<Leaf> = Vec::new();
        for (slot, depth, state) in frame {
            if let Some(occupied) = state {
                let l = leaf(slot * 4, depth, occupied);
                if leaves
                    .iter()
                    .all(|o| o.end() <= l.start.0 || l.end() <= o.start.0)
                {
                    leaves.push(l);
                }
            }
        }
        Snapshot::from_leaves(0.1, leaves).unwrap()
    }

    /// The state of a voxel at a sample according to the cells, by brute force.
    fn state(
        cells: &[(MortonCode, u8, VoxelObservations)],
        voxel: u64,
        sample: u32,
    ) -> Option<Occupancy> {
        let cell = cells
            .iter()
            .find(|(s, d, _)| s.0 <= voxel && voxel < s.0 + voxels_per_node(*d))?;
        cell.2.state_at(sample)
    }

    #[test]
    fn unchanged_space_is_not_touched_and_changes_split_cells() {
        let mut h = SeriesHistory::new(10);
        let first = vec![leaf(0, 13, false), leaf(64, 16, true)];
        h.apply_changes(0, &changes(&[], &first)).unwrap();
        let cells_after_first = h.cell_count();
        assert!(changes(&first, &first).is_empty());
        h.apply_changes(1, &changes(&first, &first)).unwrap();
        assert_eq!(
            h.cell_count(),
            cells_after_first,
            "identical snapshot changes nothing"
        );
        // One voxel inside the free block becomes occupied: the block splits down to it.
        let mut second = Snapshot::from_voxel_states(
            0.1,
            Snapshot::from_leaves(0.1, first.clone()).unwrap().voxels(),
        )
        .unwrap()
        .into_leaves();
        second[5].log_odds = 1.0;
        // Split differently but equal elsewhere: only the one voxel changed.
        let diff = changes(&first, &second);
        assert_eq!(diff.len(), 1, "{diff:?}");
        assert_eq!(diff[0].end - diff[0].start, 1);
        h.apply_changes(2, &diff).unwrap();
        assert!(h.cell_count() > cells_after_first);
        let cells: Vec<_> = h.finish(3, &[]).map(Result::unwrap).collect();
        let v5 = second[5].start.0;
        assert_eq!(state(&cells, v5, 1), Some(Occupancy::Free));
        assert_eq!(state(&cells, v5, 2), Some(Occupancy::Occupied));
        assert_eq!(state(&cells, v5 + 1, 2), Some(Occupancy::Free));
    }

    #[test]
    fn a_region_hidden_and_shown_unchanged_costs_one_gap_not_a_run_per_cell() {
        let mut h = SeriesHistory::new(10);
        // 40 single voxels every other slot, so that no two cells merge.
        let all: Vec<Leaf> = (0..40u16).map(|i| leaf(2 * i, 16, i % 3 == 0)).collect();
        // A partial view hides the first 30 of them.
        let partial = all[30..].to_vec();
        let frames = [&all, &partial, &partial, &all, &all, &partial, &all];
        let mut previous: &[Leaf] = &[];
        for (sample, frame) in frames.iter().enumerate() {
            h.apply_changes(sample as u32, &changes(previous, frame))
                .unwrap();
            previous = frame;
        }
        h.gaps.extend(h.growing_gap.take());
        assert_eq!(h.gaps.len(), 2, "{:?}", h.gaps);
        assert!(h.cells.values().all(|cell| cell.runs.bytes.is_empty()));
        let cells: Vec<_> = h.finish(7, &[]).map(Result::unwrap).collect();
        for (sample, frame) in frames.iter().enumerate() {
            let snapshot = Snapshot::from_leaves(0.1, frame.to_vec()).unwrap();
            for x in 0..80u16 {
                let voxel = VoxelKey::new(x, 0, 0).morton();
                assert_eq!(
                    state(&cells, voxel.0, sample as u32),
                    snapshot.state_at(voxel),
                    "x {x} sample {sample}"
                );
            }
        }
    }

    #[test]
    fn runs_are_cut_by_gaps() {
        let run = Run {
            first: 2,
            len: 10,
            state: Occupancy::Free,
        };
        let pieces: Vec<(u32, u32)> = without_gaps(run, &[(0, 3), (5, 7), (11, 20)])
            .iter()
            .map(|r| (r.first, r.len))
            .collect();
        assert_eq!(pieces, vec![(3, 2), (7, 4)]);
    }

    #[test]
    fn absent_samples_are_cut_out() {
        let run = Run {
            first: 2,
            len: 6,
            state: Occupancy::Free,
        };
        assert_eq!(
            without_absent(run, &[1, 3, 4, 7, 9]),
            vec![(2, 1, Occupancy::Free), (5, 2, Occupancy::Free)]
        );
    }

    /// Runs spilled by [`SeriesHistory::spill`], kept in memory: (cell start, depth, runs).
    type Spilled = Vec<(u64, u8, Vec<Run>)>;

    /// The runs spilled for the cell at `start` or the coarser cells it was split from.
    fn spilled_for(spilled: &Spilled, start: u64, out: &mut Vec<Run>) {
        for (s, d, runs) in spilled {
            if *s <= start && start < s + voxels_per_node(*d) {
                out.extend_from_slice(runs);
            }
        }
    }

    proptest! {
        /// Spilling between any snapshots gives the same cells as keeping everything, with
        /// partial views (gaps), coarse cells split later, and absent samples.
        #[test]
        fn spilling_changes_nothing(
            frames in proptest::collection::vec(proptest::collection::vec((0u16..24, 13u8..=16, proptest::option::of(any::<bool>())), 0..12), 1..10),
            spill_after in proptest::collection::btree_set(0usize..10, 0..10),
            absent in proptest::collection::btree_set(0u32..12, 0..3),
        ) {
            let mut kept = SeriesHistory::new(11);
            let mut spilling = SeriesHistory::new(11);
            let mut spilled: Spilled = Vec::new();
            let mut previous: Vec<Leaf> = Vec::new();
            let mut sample = 0u32;
            for (i, frame) in frames.into_iter().enumerate() {
                while absent.contains(&sample) { sample += 1; }
                let snapshot = frame_snapshot(frame);
                let diff = changes(&previous, snapshot.leaves());
                kept.apply_changes(sample, &diff).unwrap();
                spilling.apply_changes(sample, &diff).unwrap();
                if spill_after.contains(&i) {
                    spilling.spill(|start, depth, runs| {
                        spilled.push((start, depth, runs.to_vec()));
                        Ok::<(), TemporalError>(())
                    }).unwrap();
                    prop_assert!(spilling.spillable_bytes() <= std::mem::size_of::<Gap>());
                }
                previous = snapshot.into_leaves();
                sample += 1;
            }
            let absent: Vec<u32> = absent.into_iter().filter(|&s| s < sample).collect();
            let expected: Vec<_> = kept.finish(sample, &absent).map(Result::unwrap).collect();
            let got: Vec<_> = spilling
                .finish_with(sample, &absent, |start, _, out| {
                    spilled_for(&spilled, start, out);
                    Ok::<(), TemporalError>(())
                })
                .map(|cell| {
                    let (start, depth, packed) = cell.unwrap();
                    (start, depth, packed.unpack().unwrap())
                })
                .collect();
            prop_assert_eq!(got, expected);
        }
    }

    proptest! {
        /// Against brute force: every voxel's state at every sample is what the snapshots said.
        #[test]
        fn matches_brute_force(
            frames in proptest::collection::vec(proptest::collection::vec((0u16..24, 14u8..=16, proptest::option::of(any::<bool>())), 0..12), 1..8),
            absent in proptest::collection::btree_set(0u32..10, 0..3),
        ) {
            let mut h = SeriesHistory::new(12);
            let mut snapshots: Vec<(u32, Snapshot)> = Vec::new();
            let mut sample = 0u32;
            for frame in frames {
                while absent.contains(&sample) { sample += 1; }
                // Non-overlapping leaves: one per 4-voxel slot, at most.
                let mut leaves: Vec<Leaf> = Vec::new();
                for (slot, depth, state) in frame {
                    let x = slot * 4;
                    if let Some(occupied) = state {
                        let l = leaf(x, depth, occupied);
                        if leaves.iter().all(|o| o.end() <= l.start.0 || l.end() <= o.start.0) {
                            leaves.push(l);
                        }
                    }
                }
                let snapshot = Snapshot::from_leaves(0.1, leaves).unwrap();
                let previous = snapshots.last().map_or(&[][..], |(_, s)| s.leaves());
                h.apply_changes(sample, &changes(previous, snapshot.leaves())).unwrap();
                snapshots.push((sample, snapshot));
                sample += 1;
            }
            let axis_len = sample;
            let absent: Vec<u32> = (0..axis_len).filter(|s| !snapshots.iter().any(|(t, _)| t == s)).collect();
            let cells: Vec<_> = h.finish(axis_len, &absent).map(Result::unwrap).collect();
            for (t, snapshot) in &snapshots {
                for x in 0..100u16 {
                    let voxel = VoxelKey::new(x, 0, 0).morton();
                    prop_assert_eq!(state(&cells, voxel.0, *t), snapshot.state_at(voxel), "x {} sample {}", x, t);
                }
            }
            for s in &absent {
                for x in 0..100u16 {
                    prop_assert_eq!(state(&cells, VoxelKey::new(x, 0, 0).morton().0, *s), None);
                }
            }
        }
    }

    proptest! {
        /// The first map's cells built in one pass are the cells `apply` inserts one by one
        /// (the same cells, depths and observations), and stay so as later maps split them.
        #[test]
        fn first_map_in_one_pass_equals_change_by_change(
            frames in proptest::collection::vec(proptest::collection::vec((0u16..24, 11u8..=16, proptest::option::of(any::<bool>())), 0..12), 1..5),
        ) {
            let mut one_pass = SeriesHistory::new(11);
            let mut by_change = SeriesHistory::new(11);
            let mut previous: Vec<Leaf> = Vec::new();
            for (sample, frame) in (0u32..).zip(frames) {
                let snapshot = frame_snapshot(frame);
                let diff = changes(&previous, snapshot.leaves());
                one_pass.apply_changes(sample, &diff).unwrap();
                // `apply` itself, as for any later map.
                by_change.last_sample = Some(sample);
                by_change.gaps.extend(by_change.growing_gap.take());
                for &change in &diff {
                    by_change.changed_voxels += change.end - change.start;
                    by_change.apply(sample, change);
                }
                previous = snapshot.leaves().to_vec();
            }
            prop_assert_eq!(one_pass.changed_voxels(), by_change.changed_voxels());
            let axis_len = one_pass.last_sample.map_or(0, |s| s + 1);
            let a: Vec<_> = one_pass.finish(axis_len, &[]).map(Result::unwrap).collect();
            let b: Vec<_> = by_change.finish(axis_len, &[]).map(Result::unwrap).collect();
            prop_assert_eq!(a, b);
        }
    }
}
