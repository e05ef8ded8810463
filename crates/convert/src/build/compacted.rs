//! Compaction by merging histories: a file's base and segments become one base without
//! retrieving a single map. Each cell's observations are read from where they are stored
//! (the base's tiles on the base axis, each segment's tiles on its own axis piece, inherited
//! cells and patch-tile remainders through the base cell's frozen prediction), placed on
//! the axis of all the file's maps, joined in time order tile by tile, and refitted by the
//! build's own fit and write stages.
//!
//! In: a base reader and (for 2.0) the segments of the living reader. Out: a 1.x file whose
//! tiles are those of a [`build`](super::build) of the same maps: the merged cells are
//! brought to the build's cells ([`coarsest`]: eight sibling cells with the same history
//! are one cell, as the build never splits a cell that no change boundary falls inside).
//! Memory: one tile of each stream (base, segments) at a time, and the fit's chunks.

use super::accumulate::{pack, TileHistory};
use super::append::{OldTiles, SampleMap};
use super::axis::axis_for_times;
use super::fit::{cells_of_tiles, fit_and_write, TileFitter};
use super::merge::merge_tiles;
use super::write::{TileEncoder, TileWriter};
use crate::error::ConvertError;
use crate::history::{PackedCell, PackedObservations};
use crate::progress::Progress;
use froctomap_core::{voxels_per_node, MortonCode, Occupancy, Timestamp};
use froctomap_file::{
    Cell, CellContent, FroctReader, Header, LivingReader, SegmentCell, SegmentContent,
    TileRemainder, ToggleLayout,
};
use froctomap_temporal::{ModelConfig, OutlierMode, TemporalModel, Toggles, VoxelObservations};
use rayon::prelude::*;
use serde_json::{json, Map, Value};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

/// What [`merge_into`] wrote.
#[derive(Debug)]
pub(crate) struct Merged {
    /// Maps (samples with a map) of the series.
    pub maps: usize,
    /// Outlier toggles stored.
    pub toggles: u64,
}

/// How [`merge_into`] writes.
pub(crate) struct MergeSettings<'a> {
    /// The file's model, created from its registry entry.
    pub model: Box<dyn TemporalModel>,
    /// The model's configuration for the refit (outlier mode from the file).
    pub config: &'a ModelConfig,
    /// Tile depth written: the base's, or deeper (its cells split into the smaller tiles).
    pub tile_depth: u8,
    /// Toggle layout written.
    pub toggles: ToggleLayout,
    /// Header metadata written.
    pub metadata: Map<String, Value>,
    /// `true`: no wall-clock measurement in the file.
    pub reproducible: bool,
}

/// Writes into `output` (a new 1.x file) the compaction of `base` and, for a 2.0 file, the
/// segments of `living` (whose base is `base`): every cell's history over every map of the
/// series, refitted.
pub(crate) fn merge_into(
    base: &FroctReader,
    living: Option<&LivingReader>,
    output: &Path,
    settings: MergeSettings<'_>,
    progress: &dyn Progress,
) -> Result<Merged, ConvertError> {
    let old = base.header();
    let segments = living.map_or(0, LivingReader::segment_count);
    let mut times: Vec<Timestamp> = present_times(&old.axis);
    for k in 0..segments {
        if let Some((_, axis)) = living.and_then(|l| l.segment_axis(k)) {
            times.extend(present_times(axis));
        }
    }
    let maps = times.len();
    let axis = axis_for_times(&times)?;
    drop(times);
    let prepared = settings.model.prepare(&axis, settings.config)?;
    let mut header = Header::new(
        old.resolution,
        settings.tile_depth,
        axis.clone(),
        settings.model.id(),
        prepared.encode_parameters(),
        old.codec,
    );
    header.toggles = settings.toggles;
    header.metadata = settings.metadata;
    let mut writer = TileWriter::create(output, &header)?;
    let stored: u64 = base
        .tiles()
        .iter()
        .map(|t| u64::from(t.cell_count))
        .sum::<u64>()
        + (0..segments)
            .map(|k| {
                living.map_or(0, |l| {
                    l.segment_tiles(k)
                        .iter()
                        .map(|t| u64::from(t.cell_count))
                        .sum()
                })
            })
            .sum::<u64>();
    progress.stage("merging and modelling cells", stored);
    let started = std::time::Instant::now();

    let base_samples = SampleMap::new(&old.axis, &axis);
    let segment_samples: Vec<SampleMap<'_>> = (0..segments)
        .filter_map(|k| living.and_then(|l| l.segment_axis(k)))
        .map(|(_, piece)| SampleMap::new(piece, &axis))
        .collect();
    let (tile_depth, written_depth) = (old.tile_depth, settings.tile_depth);
    // The base and the segments, in time order, merged as a balanced tree of seams: a
    // chain (base + s0, then + s1, …) would unpack and pack every cell's history so far
    // once per segment, the cost growing with the square of the segments.
    let mut parts: Vec<TileStream<'_>> = vec![Box::new(OldTiles::new(base, &base_samples))];
    if let Some(living) = living {
        for (k, samples) in segment_samples.iter().enumerate() {
            parts.push(Box::new(SegmentTiles::new(living, k, samples)));
        }
    }
    let tiles = merged_in_order(parts, tile_depth);
    let tiles = tiles.map(move |tile| {
        tile.map(|tile| {
            let cells = split_to(tile.into_packed(), written_depth);
            TileHistory::from_packed(coarsest(cells, written_depth))
        })
    });
    let fitter = TileFitter::new(&axis, prepared.as_ref());
    let encoder = TileEncoder::new(header.tile_layout(), prepared.as_ref());
    fit_and_write(
        cells_of_tiles(tiles),
        written_depth,
        &fitter,
        &encoder,
        &mut writer,
        progress,
    )?;
    let stats = writer.stats().clone();
    let lossless = settings.config.outliers == OutlierMode::Lossless;
    let mut summary = stats.summary(lossless);
    let mut put = |key: &str, value: Value| summary.insert(key.to_string(), value);
    put("snapshots_used", json!(maps));
    put("snapshots_skipped", json!(0));
    if !settings.reproducible {
        put("model_seconds", json!(started.elapsed().as_secs_f64()));
    }
    writer.finish(summary)?;
    Ok(Merged {
        maps,
        toggles: stats.toggles,
    })
}

/// A stream of tiles in Morton order.
type TileStream<'a> = Box<dyn Iterator<Item = Result<TileHistory, ConvertError>> + Send + 'a>;

/// `parts` (each later in time than the one before) merged into one stream, neighbours
/// first, level by level.
fn merged_in_order(mut parts: Vec<TileStream<'_>>, tile_depth: u8) -> TileStream<'_> {
    while parts.len() > 1 {
        let mut level = Vec::with_capacity(parts.len().div_ceil(2));
        let mut pairs = parts.into_iter();
        while let Some(earlier) = pairs.next() {
            level.push(match pairs.next() {
                Some(later) => Box::new(merge_tiles(earlier, later, tile_depth)) as TileStream<'_>,
                None => earlier,
            });
        }
        parts = level;
    }
    parts.pop().unwrap_or_else(|| Box::new(std::iter::empty()))
}

/// The instants of an axis's samples that have a map.
fn present_times(axis: &froctomap_temporal::TimeAxis) -> Vec<Timestamp> {
    (0..axis.len())
        .filter(|&s| !axis.is_missing(s))
        .filter_map(|s| axis.time(s))
        .collect()
}

/// Cells (one tile's, in Morton order) brought to the coarsest cells a build makes of the
/// same histories: eight siblings below the tile depth with the same runs become their
/// parent, repeatedly. A build splits a cell only where a change boundary falls inside it,
/// so its siblings never share a whole history; the merge splits a cell wherever any
/// stream did (a segment splits a base cell around what changed in its maps only).
///
/// In place, freeing the runs of merged siblings at once: a tile of a long series is held
/// once, not once read and once written.
pub(crate) fn coarsest(mut cells: Vec<PackedCell>, tile_depth: u8) -> Vec<PackedCell> {
    // `cells[..kept]` are the cells so far; the ones from `kept` to the one read are spent.
    let mut kept = 0;
    for read in 0..cells.len() {
        cells.swap(kept, read);
        kept += 1;
        while same_siblings(&cells[..kept], tile_depth) {
            let first = kept - 8;
            for sibling in &mut cells[first + 1..kept] {
                sibling.2 = PackedObservations::pack([]);
            }
            // The first child starts where its parent does.
            cells[first].1 -= 1;
            kept = first + 1;
        }
    }
    cells.truncate(kept);
    cells
}

/// Cells (in Morton order) coarser than `depth` split into their pieces of that depth, each
/// with the cell's runs: the cells of smaller tiles than the file's, as a build at `depth`
/// makes them (a leaf coarser than a tile is split into the tiles it covers).
fn split_to(cells: Vec<PackedCell>, depth: u8) -> Vec<PackedCell> {
    if cells.iter().all(|(_, d, _)| *d >= depth) {
        return cells;
    }
    let size = voxels_per_node(depth);
    let mut out = Vec::with_capacity(cells.len());
    for (start, d, runs) in cells {
        if d >= depth {
            out.push((start, d, runs));
            continue;
        }
        let pieces = voxels_per_node(d) / size;
        out.extend((0..pieces).map(|i| (MortonCode(start.0 + i * size), depth, runs.clone())));
    }
    out
}

/// Whether the last eight of `cells` are the eight children of one parent with the same
/// runs.
fn same_siblings(cells: &[PackedCell], tile_depth: u8) -> bool {
    let Some(last) = cells
        .len()
        .checked_sub(8)
        .and_then(|from| cells.get(from..))
    else {
        return false;
    };
    let (start, depth, runs) = &last[0];
    if *depth <= tile_depth || start.0 % voxels_per_node(depth - 1) != 0 {
        return false;
    }
    let size = voxels_per_node(*depth);
    last.iter().enumerate().all(|(i, (s, d, r))| {
        d == depth
            && s.0 == start.0 + i as u64 * size
            && r.run_count() == runs.run_count()
            && r.packed_bytes() == runs.packed_bytes()
    })
}

/// Segment `k`'s tiles as [`TileHistory`] values on the compacted axis, in Morton order,
/// one tile at a time (its cells in parallel).
struct SegmentTiles<'a> {
    living: &'a LivingReader,
    k: usize,
    samples: &'a SampleMap<'a>,
    /// Seconds from the base axis's first instant of each sample of the segment (where the
    /// base's models are evaluated for the frozen prediction).
    seconds: Vec<f64>,
    next: usize,
    /// The remainders of the tiles from `window.0` on, decoded together from the
    /// segment's record ([`REMAINDER_WINDOW`] at a time).
    window: (usize, Vec<Option<Arc<TileRemainder>>>),
}

/// How many tiles' remainders a segment's stream decodes at once: the merge walks every
/// segment for each tile, so decoding a record per tile would decode each record once per
/// tile; holding them all would hold every segment's remainders at once.
const REMAINDER_WINDOW: usize = 8;

impl<'a> SegmentTiles<'a> {
    fn new(living: &'a LivingReader, k: usize, samples: &'a SampleMap<'a>) -> Self {
        let origin = living.base().header().axis.start();
        let seconds = living.segment_axis(k).map_or_else(Vec::new, |(_, axis)| {
            (0..axis.len())
                .map(|j| axis.time(j).map_or(0.0, |t| t.secs_since(origin)))
                .collect()
        });
        Self {
            living,
            k,
            samples,
            seconds,
            next: 0,
            window: (0, Vec::new()),
        }
    }

    /// Tile `i`'s remainder (the window moved on to `i` when it lies past it).
    fn remainder(&mut self, i: usize) -> Result<Option<Arc<TileRemainder>>, ConvertError> {
        let (from, held) = &self.window;
        if i < *from || i >= from + held.len() {
            let tiles = self.living.segment_tiles(self.k).len();
            let window = i..(i + REMAINDER_WINDOW).min(tiles);
            let held = self.living.segment_tile_remainders(self.k, window)?;
            self.window = (i, held);
        }
        let (from, held) = &self.window;
        Ok(held.get(i - from).cloned().flatten())
    }

    fn tile(&mut self, i: usize) -> Result<TileHistory, ConvertError> {
        let remainder = self.remainder(i)?;
        let living = self.living;
        let cells = living.read_segment_tile_with(self.k, i, remainder.as_deref())?;
        let inherits = cells
            .iter()
            .any(|c| matches!(c.content, SegmentContent::Inherited { .. }));
        let base = living.base();
        let base_cells: Vec<Cell> = match cells.first() {
            Some(first) if inherits => match base.tile_containing(first.start) {
                Some(t) => base.read_tile(t)?,
                None => return Err(no_base_cell()),
            },
            _ => Vec::new(),
        };
        // The base cell holding each inherited cell, and the frozen prediction at each of
        // the segment's samples of the modelled ones among them (computed once per base
        // cell: a patch tile's remainder gives a base cell many parts).
        let holder = |cell: &SegmentCell| -> Result<usize, ConvertError> {
            let i = base_cells
                .partition_point(|b| b.start <= cell.start)
                .checked_sub(1)
                .ok_or_else(no_base_cell)?;
            let b = &base_cells[i];
            let inside =
                cell.start.0 + voxels_per_node(cell.depth) <= b.start.0 + voxels_per_node(b.depth);
            inside.then_some(i).ok_or_else(no_base_cell)
        };
        let mut modelled: Vec<usize> = Vec::new();
        for cell in &cells {
            if matches!(cell.content, SegmentContent::Inherited { .. }) {
                let i = holder(cell)?;
                if matches!(base_cells[i].content, CellContent::Modelled(_)) {
                    modelled.push(i);
                }
            }
        }
        modelled.sort_unstable();
        modelled.dedup();
        let model = base.model();
        let predictions: HashMap<usize, Vec<Occupancy>> = modelled
            .par_iter()
            .map(|&i| {
                let cell = &base_cells[i];
                let states = self
                    .seconds
                    .iter()
                    .map(|&s| Occupancy::from(cell.probability(model, s) > 0.5))
                    .collect();
                (i, states)
            })
            .collect();
        let len = self.seconds.len() as u32;
        let packed = cells
            .par_iter()
            .map(|cell| {
                let frozen = match cell.content {
                    SegmentContent::Inherited { .. } => {
                        let i = holder(cell)?;
                        match &base_cells[i].content {
                            CellContent::Constant(state)
                            | CellContent::ConstantExcept { state, .. } => Frozen::Constant(*state),
                            CellContent::Modelled(_) => {
                                Frozen::Predicted(predictions.get(&i).ok_or_else(no_base_cell)?)
                            }
                        }
                    }
                    _ => Frozen::Constant(Occupancy::Free),
                };
                let observations = segment_observations(cell, &frozen, len, self.samples)?;
                Ok((cell.start, cell.depth, pack(&observations)))
            })
            .collect::<Result<Vec<PackedCell>, ConvertError>>()?;
        Ok(TileHistory::from_packed(packed))
    }
}

fn no_base_cell() -> ConvertError {
    ConvertError::internal("a segment's inherited cell lies inside no base cell")
}

impl Iterator for SegmentTiles<'_> {
    type Item = Result<TileHistory, ConvertError>;

    fn next(&mut self) -> Option<Self::Item> {
        let i = self.next;
        if i >= self.living.segment_tiles(self.k).len() {
            return None;
        }
        self.next += 1;
        Some(self.tile(i))
    }
}

/// The base's frozen prediction for an inherited cell over a segment's samples.
enum Frozen<'p> {
    Constant(Occupancy),
    /// The state at each sample of the segment.
    Predicted(&'p [Occupancy]),
}

/// A segment cell's observations on the compacted axis: over its mask's ranges of the
/// segment's `len` samples, its state (constant, flipped at exceptions, or the frozen
/// prediction flipped at outliers).
fn segment_observations(
    cell: &SegmentCell,
    frozen: &Frozen<'_>,
    len: u32,
    samples: &SampleMap<'_>,
) -> Result<VoxelObservations, ConvertError> {
    let ranges: Vec<(u32, u32)> = match &cell.mask {
        None => vec![(0, len)],
        Some(mask) => mask
            .as_slice()
            .chunks(2)
            .map(|pair| (pair[0], pair.get(1).copied().unwrap_or(len).min(len)))
            .filter(|(a, b)| a < b)
            .collect(),
    };
    let none = Toggles::default();
    let (state, flips) = match &cell.content {
        SegmentContent::Constant(state) => (*state, &none),
        SegmentContent::ConstantExcept { state, exceptions } => (*state, exceptions),
        SegmentContent::Inherited { outliers } => match frozen {
            Frozen::Constant(state) => (*state, outliers),
            Frozen::Predicted(states) => {
                let mut runs = Vec::new();
                for (first, end) in ranges {
                    predicted_runs(first, end, states, outliers, samples, &mut runs)?;
                }
                return Ok(VoxelObservations::from_runs(runs)?);
            }
        },
    };
    let mut runs = Vec::new();
    for (first, end) in ranges {
        flipped_runs(first, end, state, flips, samples, &mut runs)?;
    }
    Ok(VoxelObservations::from_runs(runs)?)
}

/// Runs of samples `[first, end)` in `state`, flipped where `flips` has odd parity.
fn flipped_runs(
    first: u32,
    end: u32,
    state: Occupancy,
    flips: &Toggles,
    samples: &SampleMap<'_>,
    out: &mut Vec<(u32, u32, Occupancy)>,
) -> Result<(), ConvertError> {
    let at = |s: u32| if flips.parity_at(s) { !state } else { state };
    let positions = flips.as_slice();
    let from = positions.partition_point(|&p| p <= first);
    let mut cursor = first;
    for &flip in positions[from..].iter().take_while(|&&p| p < end) {
        samples.push_run(cursor, flip, at(cursor), out)?;
        cursor = flip;
    }
    samples.push_run(cursor, end, at(cursor), out)
}

/// Runs of samples `[first, end)` in the predicted `states`, flipped where `flips` has odd
/// parity.
fn predicted_runs(
    first: u32,
    end: u32,
    states: &[Occupancy],
    flips: &Toggles,
    samples: &SampleMap<'_>,
    out: &mut Vec<(u32, u32, Occupancy)>,
) -> Result<(), ConvertError> {
    let positions = flips.as_slice();
    let mut next = positions.partition_point(|&p| p <= first);
    let mut parity = flips.parity_at(first);
    let state_at = |s: u32, parity: bool| {
        let predicted = states.get(s as usize).copied().unwrap_or(Occupancy::Free);
        if parity {
            !predicted
        } else {
            predicted
        }
    };
    let mut cursor = first;
    let mut current = state_at(first, parity);
    for s in first + 1..end {
        while positions.get(next).is_some_and(|&p| p <= s) {
            parity = !parity;
            next += 1;
        }
        let state = state_at(s, parity);
        if state != current {
            samples.push_run(cursor, s, current, out)?;
            (cursor, current) = (s, state);
        }
    }
    samples.push_run(cursor, end, current, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn runs(state: Occupancy) -> PackedObservations {
        PackedObservations::pack([(0, 3, state), (3, 2, !state)])
    }

    /// 64 single voxels (depth 16) with the given runs, in Morton order.
    fn voxels(odd_one: Option<u64>) -> Vec<PackedCell> {
        (0..64u64)
            .map(|i| {
                let state = if Some(i) == odd_one {
                    Occupancy::Occupied
                } else {
                    Occupancy::Free
                };
                (MortonCode(i), 16, runs(state))
            })
            .collect()
    }

    fn shape(cells: &[PackedCell]) -> Vec<(u64, u8)> {
        cells.iter().map(|(s, d, _)| (s.0, *d)).collect()
    }

    #[test]
    fn eight_siblings_with_the_same_runs_become_their_parent_repeatedly() {
        let merged = coarsest(voxels(None), 13);
        assert_eq!(shape(&merged), [(0, 14)]);
        assert_eq!(merged[0].2, runs(Occupancy::Free));
        // Not above the tile depth.
        let at_tiles = coarsest(voxels(None), 15);
        assert_eq!(
            shape(&at_tiles),
            (0..8).map(|i| (i * 8, 15)).collect::<Vec<_>>()
        );
    }

    #[test]
    fn one_sibling_with_other_runs_keeps_its_group_split() {
        let merged = coarsest(voxels(Some(9)), 13);
        let mut expected = vec![(0, 15)];
        expected.extend((8..16).map(|i| (i, 16)));
        expected.extend((2..8).map(|i| (i * 8, 15)));
        assert_eq!(shape(&merged), expected);
        assert_eq!(merged[2].2, runs(Occupancy::Occupied));
        assert!(merged
            .iter()
            .enumerate()
            .all(|(i, c)| (i == 2) == (c.2 == runs(Occupancy::Occupied))));
    }
}
