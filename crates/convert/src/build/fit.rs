//! Stage 4, per-tile fit: each cell of a tile classified (always free, always occupied,
//! dynamic) and each dynamic cell's temporal model fitted, with its observation mask.
//!
//! In: [`TileHistory`] values. Out: [`FittedTile`]s, the cells as the file stores them and
//! their counts by class. [`fit_and_write`] runs this stage and the writer's over a stream of
//! tiles: fitted and encoded in parallel batches, written in order.

use super::accumulate::TileHistory;
use super::counts::TileStats;
use super::write::{TileEncoder, TileWriter};
use crate::error::ConvertError;
use crate::history::PackedCell;
use crate::progress::Progress;
use froctomap_core::{MortonCode, Occupancy};
use froctomap_file::{mask_from_ranges, Cell, CellContent, EncodedTile, TileStreamEncoder};
use froctomap_temporal::{OutlierMode, PreparedModel, TimeAxis, VoxelObservations};
use rayon::prelude::*;

/// The cells of one tile as stored, with their counts.
#[derive(Debug)]
pub(crate) struct FittedTile {
    pub cells: Vec<Cell>,
    pub stats: TileStats,
}

/// Fits the cells of tiles with a model prepared for the file's time axis.
pub(crate) struct TileFitter<'a> {
    axis: &'a TimeAxis,
    model: &'a dyn PreparedModel,
}

impl<'a> TileFitter<'a> {
    /// A fitter for cells observed on `axis`.
    pub fn new(axis: &'a TimeAxis, model: &'a dyn PreparedModel) -> Self {
        Self { axis, model }
    }

    /// The tile's cells as stored: constant ones as their state, dynamic ones as the model's
    /// fit (or, lossless, as a constant with exceptions when the fit is a constant no map can
    /// express), each with its observation mask. (A build fits chunks of cells; this is the
    /// same for a whole tile.)
    #[cfg(test)]
    pub fn fit(&self, tile: &TileHistory) -> Result<FittedTile, ConvertError> {
        self.fit_chunk(tile.packed())
    }

    /// Consecutive cells of one tile (packed), as stored, with their counts.
    fn fit_chunk(&self, cells: &[PackedCell]) -> Result<FittedTile, ConvertError> {
        let mut stats = TileStats::default();
        let mut fitted = Vec::with_capacity(cells.len());
        for (start, depth, packed) in cells {
            stats.history_bytes += packed.packed_bytes().len() as u64;
            let obs = packed.unpack()?;
            fitted.push(self.fit_cell(*start, *depth, &obs, &mut stats)?);
        }
        Ok(FittedTile {
            cells: fitted,
            stats,
        })
    }

    /// One cell as stored, counted into `stats`.
    fn fit_cell(
        &self,
        start: MortonCode,
        depth: u8,
        obs: &VoxelObservations,
        stats: &mut TileStats,
    ) -> Result<Cell, ConvertError> {
        let model = self.model;
        let voxels = froctomap_core::voxels_per_node(depth);
        let mask = mask_from_ranges(self.axis, &obs.observed_ranges());
        if mask.is_some() {
            stats.cells.unknown_sometimes += 1;
            stats.voxels.unknown_sometimes += voxels;
        }
        let content = match obs.is_constant() {
            Some(Occupancy::Free) => {
                stats.cells.static_free += 1;
                stats.voxels.static_free += voxels;
                CellContent::Constant(Occupancy::Free)
            }
            Some(Occupancy::Occupied) => {
                stats.cells.static_occupied += 1;
                stats.voxels.static_occupied += voxels;
                CellContent::Constant(Occupancy::Occupied)
            }
            None => {
                let fitted = model.fit(obs)?;
                stats.cells.dynamic += 1;
                stats.voxels.dynamic += voxels;
                stats.toggles += fitted.toggles().len() as u64;
                stats.model_errors += fitted.model_errors().unwrap_or(0);
                let lossless = model.outlier_mode() == OutlierMode::Lossless;
                let parameters = fitted.parameters();
                let mean = model.mean(parameters);
                if lossless && model.is_constant(parameters) && outside_clamping(mean) {
                    // A constant p no map can express (beyond the clamping bounds) adds
                    // nothing to the constant state; only the exceptions matter. (Lossy
                    // files keep the mean: without exceptions it is all they know of the
                    // changes.)
                    CellContent::ConstantExcept {
                        state: Occupancy::from(mean > 0.5),
                        exceptions: fitted.toggles().clone(),
                    }
                } else {
                    CellContent::Modelled(fitted)
                }
            }
        };
        Ok(Cell {
            start,
            depth,
            mask,
            content,
        })
    }
}

/// `true` for a probability OctoMap would clamp (below 0.1192 or above 0.971).
fn outside_clamping(p: f64) -> bool {
    use froctomap_core::defaults::{CLAMPING_MAX, CLAMPING_MIN};
    !(CLAMPING_MIN..=CLAMPING_MAX).contains(&p)
}

/// Most observation runs in one chunk of a tile's cells (fitted on one thread).
const CHUNK_RUNS: usize = 1 << 16;
/// Most cells in one chunk.
const CHUNK_CELLS: usize = 1 << 11;
/// Most runs fitted in one parallel step (a few megabytes, whatever the series' length).
const STEP_RUNS: usize = 1 << 19;

/// Consecutive cells of one tile (at `tile`), fitted together on one thread.
struct Chunk {
    tile: u64,
    cells: Vec<PackedCell>,
}

/// Fits, encodes and writes a stream of cells (in Morton order, each inside one tile of
/// depth `tile_depth`), advancing `progress` by the cells.
///
/// Memory is bounded whatever the length of the series: a thread of its own pulls the
/// cells and cuts them into chunks of a few thousand cells or runs (never across tiles);
/// each parallel step fits a bounded number of chunks (both cores work within one tile of
/// a long series) and compresses the tiles completed before it. A fitted cell is turned
/// into its tile's streams ([`TileStreamEncoder`](froctomap_file::TileStreamEncoder)) as
/// soon as its chunk is fitted, and dropped: a tile waiting to be compressed holds its
/// streams (varint and range-coded toggles), not its cells (4-byte toggles each), which is
/// what a large tile of a long series held before. The output does not depend on the
/// chunking: cells reach the encoder in the same order, grouped in the same tiles.
pub(crate) fn fit_and_write(
    cells: impl Iterator<Item = Result<PackedCell, ConvertError>> + Send,
    tile_depth: u8,
    fitter: &TileFitter<'_>,
    encoder: &TileEncoder<'_>,
    writer: &mut TileWriter,
    progress: &dyn Progress,
) -> Result<(), ConvertError> {
    let threads = rayon::current_num_threads().max(1);
    let step_chunks = 4 * threads;
    std::thread::scope(|scope| -> Result<(), ConvertError> {
        let (sender, receiver) =
            std::sync::mpsc::sync_channel::<Result<Chunk, ConvertError>>(step_chunks);
        scope.spawn(move || {
            let mut chunk: Option<(Chunk, usize)> = None;
            for cell in cells {
                let cell = match cell {
                    Ok(cell) => cell,
                    Err(e) => {
                        let _ = sender.send(Err(e));
                        return;
                    }
                };
                let tile = cell.0.node_start(tile_depth).0;
                let full = chunk.as_ref().is_some_and(|(c, runs)| {
                    c.tile != tile || c.cells.len() >= CHUNK_CELLS || *runs >= CHUNK_RUNS
                });
                if full {
                    if let Some((done, _)) = chunk.take() {
                        if sender.send(Ok(done)).is_err() {
                            // The writer stopped on an error.
                            return;
                        }
                    }
                }
                let (current, runs) = chunk.get_or_insert_with(|| {
                    (
                        Chunk {
                            tile,
                            cells: Vec::new(),
                        },
                        0,
                    )
                });
                *runs += cell.2.run_count();
                current.cells.push(cell);
            }
            if let Some((done, _)) = chunk {
                let _ = sender.send(Ok(done));
            }
        });
        let mut pending = PendingTiles::default();
        let mut chunks = receiver.into_iter().peekable();
        while chunks.peek().is_some() || !pending.complete.is_empty() {
            crate::progress::stop_if_cancelled(progress)?;
            let mut step: Vec<Chunk> = Vec::new();
            let mut runs = 0usize;
            while step.len() < step_chunks && runs < STEP_RUNS {
                let Some(chunk) = chunks.next() else { break };
                let chunk = chunk?;
                runs += chunk.cells.iter().map(|c| c.2.run_count()).sum::<usize>();
                step.push(chunk);
            }
            let complete = std::mem::take(&mut pending.complete);
            let (encoded, fitted) = rayon::join(
                || {
                    complete
                        .into_par_iter()
                        .map(|(tile, stats)| Ok((encoder.finish(tile)?, stats)))
                        .collect::<Result<Vec<(EncodedTile, TileStats)>, ConvertError>>()
                },
                || {
                    step.par_iter()
                        .map(|chunk| {
                            let fitted = fitter.fit_chunk(&chunk.cells)?;
                            progress.advance(chunk.cells.len() as u64);
                            Ok((chunk.tile, fitted))
                        })
                        .collect::<Result<Vec<(u64, FittedTile)>, ConvertError>>()
                },
            );
            for (tile, stats) in encoded? {
                writer.write(&tile, &stats)?;
            }
            for (tile, fitted) in fitted? {
                pending.add(tile, fitted, encoder)?;
            }
            if chunks.peek().is_none() {
                pending.close();
            }
        }
        Ok(())
    })
}

/// The tiles between fitting and compression: the one whose cells are still arriving, and
/// the completed ones waiting for the next step, each as its streams and counts.
#[derive(Default)]
struct PendingTiles {
    current: Option<(u64, TileStreamEncoder, TileStats)>,
    complete: Vec<(TileStreamEncoder, TileStats)>,
}

impl PendingTiles {
    /// Adds the fitted cells of a chunk of `tile` (chunks arrive in Morton order) to its
    /// streams, and drops them.
    fn add(
        &mut self,
        tile: u64,
        fitted: FittedTile,
        encoder: &TileEncoder<'_>,
    ) -> Result<(), ConvertError> {
        if self.current.as_ref().is_some_and(|(t, ..)| *t != tile) {
            self.close();
        }
        let (_, streams, stats) = self
            .current
            .get_or_insert_with(|| (tile, encoder.start(), TileStats::default()));
        for cell in &fitted.cells {
            encoder.push(streams, cell)?;
        }
        stats.add(&fitted.stats);
        Ok(())
    }

    /// The tile whose cells were arriving is complete.
    fn close(&mut self) {
        if let Some((_, streams, stats)) = self.current.take() {
            self.complete.push((streams, stats));
        }
    }
}

/// The cells of a stream of tiles (for [`fit_and_write`]).
pub(crate) fn cells_of_tiles(
    tiles: impl Iterator<Item = Result<TileHistory, ConvertError>>,
) -> impl Iterator<Item = Result<PackedCell, ConvertError>> {
    tiles.flat_map(|tile| -> Box<dyn Iterator<Item = _> + Send> {
        match tile {
            Ok(tile) => Box::new(tile.into_packed().into_iter().map(Ok)),
            Err(e) => Box::new(std::iter::once(Err(e))),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::test_support::default_model;
    use froctomap_core::MortonCode;
    use froctomap_temporal::VoxelObservations;

    fn cell(
        start: u64,
        depth: u8,
        runs: &[(u32, u32, Occupancy)],
    ) -> (MortonCode, u8, VoxelObservations) {
        (
            MortonCode(start),
            depth,
            VoxelObservations::from_runs(runs.to_vec()).unwrap(),
        )
    }

    #[test]
    fn cells_are_classified_counted_and_fitted() {
        use Occupancy::{Free, Occupied};
        let setup = default_model(8);
        let fitter = TileFitter::new(&setup.axis, setup.model.as_ref());
        let tile = TileHistory::new(vec![
            cell(0, 15, &[(0, 8, Free)]),
            cell(8, 15, &[(0, 8, Occupied)]),
            // Seen for half the series only: a mask.
            cell(16, 16, &[(4, 4, Occupied)]),
            cell(17, 16, &[(0, 2, Free), (2, 2, Occupied), (4, 4, Free)]),
        ]);
        let fitted = fitter.fit(&tile).unwrap();
        let contents: Vec<&CellContent> = fitted.cells.iter().map(|c| &c.content).collect();
        assert_eq!(contents[0], &CellContent::Constant(Free));
        assert_eq!(contents[1], &CellContent::Constant(Occupied));
        assert_eq!(contents[2], &CellContent::Constant(Occupied));
        assert!(matches!(contents[3], CellContent::Modelled(_)));
        assert!(fitted.cells[2].mask.is_some());
        assert!(fitted
            .cells
            .iter()
            .enumerate()
            .all(|(i, c)| (i == 2) == c.mask.is_some()));
        let starts: Vec<u64> = fitted.cells.iter().map(|c| c.start.0).collect();
        assert_eq!(starts, [0, 8, 16, 17]);
        let stats = &fitted.stats;
        assert_eq!(
            (
                stats.cells.static_free,
                stats.cells.static_occupied,
                stats.cells.dynamic
            ),
            (1, 2, 1)
        );
        assert_eq!(stats.cells.unknown_sometimes, 1);
        assert_eq!(
            (
                stats.voxels.static_free,
                stats.voxels.static_occupied,
                stats.voxels.dynamic
            ),
            (8, 9, 1)
        );
        // Lossless: the dynamic cell's fit with its toggles reproduces every observation.
        let CellContent::Modelled(fit) = contents[3] else {
            unreachable!()
        };
        assert_eq!(stats.toggles, fit.toggles().len() as u64);
    }

    #[test]
    fn a_model_that_refuses_the_observations_stops_the_fit() {
        let setup = default_model(4);
        let fitter = TileFitter::new(&setup.axis, setup.model.as_ref());
        // Observations past the end of the axis.
        let tile = TileHistory::new(vec![cell(
            0,
            16,
            &[(0, 4, Occupancy::Free), (4, 4, Occupancy::Occupied)],
        )]);
        assert!(matches!(fitter.fit(&tile), Err(ConvertError::Model(_))));
    }
}
