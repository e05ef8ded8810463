//! Stage 4, per-tile fit: each cell of a tile classified (always free, always occupied,
//! dynamic) and each dynamic cell's temporal model fitted, with its observation mask.
//!
//! In: [`TileHistory`] values. Out: [`FittedTile`]s, the cells as the file stores them and
//! their counts by class. [`fit_and_write`] runs this stage and the writer's over a stream of
//! tiles: fitted and encoded in parallel batches, written in order.

use super::accumulate::TileHistory;
use super::write::{TileEncoder, TileWriter};
use crate::build::ClassCounts;
use crate::error::ConvertError;
use crate::progress::Progress;
use froctomap_core::Occupancy;
use froctomap_file::{mask_from_ranges, Cell, CellContent, EncodedTile};
use froctomap_temporal::{OutlierMode, PreparedModel, TimeAxis};
use rayon::prelude::*;

/// Counts of a tile's (or a file's) cells, voxels and stored toggles.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct TileStats {
    pub cells: ClassCounts,
    pub voxels: ClassCounts,
    pub toggles: u64,
    pub model_errors: u64,
}

impl TileStats {
    /// Adds another tile's counts.
    pub fn add(&mut self, other: &TileStats) {
        self.cells.add(&other.cells);
        self.voxels.add(&other.voxels);
        self.toggles += other.toggles;
        self.model_errors += other.model_errors;
    }
}

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
    /// express), each with its observation mask.
    pub fn fit(&self, tile: &TileHistory) -> Result<FittedTile, ConvertError> {
        let model = self.model;
        let mut stats = TileStats::default();
        let mut cells = Vec::with_capacity(tile.len());
        for cell in tile.cells() {
            let (start, depth, obs) = cell?;
            let obs = &obs;
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
            cells.push(Cell {
                start,
                depth,
                mask,
                content,
            });
        }
        Ok(FittedTile { cells, stats })
    }
}

/// `true` for a probability OctoMap would clamp (below 0.1192 or above 0.971).
fn outside_clamping(p: f64) -> bool {
    use froctomap_core::defaults::{CLAMPING_MAX, CLAMPING_MIN};
    !(CLAMPING_MIN..=CLAMPING_MAX).contains(&p)
}

/// Fits, encodes and writes a stream of tiles (in Morton order), advancing `progress` by
/// their cells.
///
/// Tiles are fitted in parallel batches; a batch ends at a few tiles per thread or at a
/// bound on the runs it holds (cells' observations are unpacked here, and a long series
/// with partial views gives every cell many runs), whichever comes first. A thread of its
/// own pulls the tiles and gathers the next batch while one is fitted, so up to three
/// batches exist at once (4-week series: peak 401 MiB with 4 Mi runs, 300 with 1 Mi).
pub(crate) fn fit_and_write(
    tiles: impl Iterator<Item = Result<TileHistory, ConvertError>> + Send,
    fitter: &TileFitter<'_>,
    encoder: &TileEncoder<'_>,
    writer: &mut TileWriter,
    progress: &dyn Progress,
) -> Result<(), ConvertError> {
    const BATCH_RUNS: usize = 1 << 20;
    let batch_tiles = 4 * rayon::current_num_threads().max(1);
    type Batch = Vec<TileHistory>;
    std::thread::scope(|scope| -> Result<(), ConvertError> {
        let (sender, receiver) = std::sync::mpsc::sync_channel::<Result<Batch, ConvertError>>(0);
        scope.spawn(move || {
            let mut batch: Batch = Vec::new();
            let mut batch_runs = 0usize;
            for tile in tiles {
                let tile = match tile {
                    Ok(tile) => tile,
                    Err(e) => {
                        let _ = sender.send(Err(e));
                        return;
                    }
                };
                batch_runs += tile.runs();
                batch.push(tile);
                if batch.len() >= batch_tiles || batch_runs >= BATCH_RUNS {
                    if sender.send(Ok(std::mem::take(&mut batch))).is_err() {
                        // The writer stopped on an error.
                        return;
                    }
                    batch_runs = 0;
                }
            }
            let _ = sender.send(Ok(batch));
        });
        for batch in receiver {
            let encoded: Vec<Result<(EncodedTile, TileStats), ConvertError>> = batch?
                .par_iter()
                .map(|tile| {
                    let fitted = fitter.fit(tile)?;
                    let encoded = encoder.encode(&fitted.cells)?;
                    progress.advance(tile.len() as u64);
                    Ok((encoded, fitted.stats))
                })
                .collect();
            for result in encoded {
                let (tile, stats) = result?;
                writer.write(&tile, &stats)?;
            }
        }
        Ok(())
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
