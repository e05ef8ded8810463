//! Segment ingest ([`IngestTarget::Writer`], [`IngestTarget::Segment`]): later maps added
//! to a format 2.0 file as one new segment
//! ([FORMAT.md §10](../../../../docs/FORMAT.md), [LIVING-MAP.md](../../../../docs/LIVING-MAP.md)),
//! at a cost that follows the new maps, not the file's history.
//!
//! The build's stages run over the new maps only, then two stages of its own join them to
//! the base:
//!
//! 1. **plan** ([`SegmentPlan`]) — the file's model must grow (`fremen-regular` is refused,
//!    naming `fremen-periods`), the inputs must come after the file's last sample; the
//!    segment's own axis piece numbers the new maps from 0 (`axis_for_times` of their
//!    instants: off the base's grid is fine, no earlier sample is renumbered).
//! 2. **check → extract → accumulate** — the ingest's shared [`Intake`] (the build's
//!    `InputCheck`, `ChangeExtractor`, `accumulate_series`) on the new maps, the first compared with
//!    nothing (a segment's lists restart at the segment, so its histories do too), inputs of
//!    another resolution than the file's refused. Unobserved samples are unknown.
//! 3. **join** ([`BaseJoin`]) — per accumulated tile, the cells observed in one state stay
//!    whole (stored constant whatever the base holds); the changing ones and the frozen
//!    predictions of the base tile with the same code (read with
//!    [`visit_frozen_predictions`](froctomap_file::FroctReader::visit_frozen_predictions):
//!    no mask or toggle decoded, no earlier segment read, and only for a tile with a
//!    changing cell) are walked as their common refinement ([`common_refinement`], the
//!    append seam's), so that a piece lies inside one base cell or outside all of them.
//! 4. **choose** ([`ContentChooser`]) — per piece: observed in one state → constant; else
//!    the cheaper of constant with exceptions and, inside a modelled base cell, *inherited*
//!    with its outliers (where the observation differs from the base model's `p(t) > 0.5` at
//!    the sample's instant, seconds since the base axis's first instant, as the readers
//!    evaluate it). `markov` cells are never inherited (their `p(t)` uses the platform's
//!    `exp`); cells new since the base are constant with exceptions.
//! 5. **write and commit** — each tile encoded ([`SegmentTileEncoder`]) and written after
//!    the committed bytes, then one commit. Everything that reads inputs runs before the
//!    first byte is written: a bad map commits nothing, and a failure while writing cuts
//!    what was written.

use super::accumulate::TileHistory;
use super::append::refuse_overlap;
use super::axis::axis_for_times;
use super::counts::TileStats;
use super::ingest::{Extended, IngestReport, Intake, Run};
use super::merge::{common_refinement, Piece};
use crate::context::Context;
use crate::error::ConvertError;
use crate::files::{is_living_file, output_dir};
use crate::history::PackedCell;
use crate::history::PackedObservations;
use crate::inputs::SeriesInput;
use froctomap_core::{voxels_per_node, MortonCode, Occupancy, Timestamp};
use froctomap_file::{
    mask_from_ranges, EncodedTile, FroctReader, FrozenPrediction, LivingReader, LivingWriter,
    RemainderMask, RemainderRun, SegmentCell, SegmentContent, SegmentTileEncoder, TileRemainder,
};
use froctomap_temporal::{OutlierMode, PreparedModel, TimeAxis, ToggleBuilder, VoxelObservations};
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// The model that segments cannot grow: its frequencies are bins of the axis length.
const FIXED_SPAN_MODEL: &str = "fremen-regular";
/// The model whose `p(t)` after its last observation uses `exp`, which differs across
/// platforms: its cells are stored constant with exceptions, never inherited.
const PLATFORM_DEPENDENT_MODEL: &str = "markov";

/// The new maps as one segment of the file `writer` holds: the plan, the intake, then
/// join, choose, write and commit.
pub(super) fn add_segment(
    run: &Run<'_>,
    writer: &mut LivingWriter,
) -> Result<IngestReport, ConvertError> {
    let Run {
        context,
        inputs,
        progress,
        ..
    } = *run;
    let file = writer.reader().path().to_path_buf();
    let plan = SegmentPlan::new(context, writer.reader(), inputs)?;
    let header = writer.reader().header().clone();

    // Stage 2: the build's, over the new maps on the segment's axis.
    let intaken = Intake {
        axis: plan.axis,
        tile_depth: header.tile_depth,
        file: Some((&file, header.resolution)),
        seed: None,
        spill_dir: output_dir(&file),
    }
    .run(run)?;
    let axis = intaken.axis;

    // Stages 3–5: join, choose, write; then commit.
    let modelling = Instant::now();
    let before = writer.reader().root();
    let (samples_before, end_before) = (before.sample_count, writer.reader().last_instant());
    // A second reader of the base's tiles, which the segment being written cannot lend (it
    // borrows the writer); the lock keeps both the same. The base alone: opening the whole
    // file again would read every segment's record, a cost that grows with the history.
    let base_view = writer.reader().reopen_base(context.models())?;
    let base = &base_view;
    let chooser = ContentChooser::new(&file, &axis, base, plan.inherit_models);
    let join = BaseJoin { base };
    let accumulated = intaken.accumulated;
    progress.stage("joining cells to the base", accumulated.cell_count() as u64);
    let accumulate_seconds = accumulated.busy_seconds();
    let (spilled_bytes, spills) = (accumulated.spilled_bytes(), accumulated.spills());
    let tiles = accumulated.into_tiles(axis.len(), &intaken.absent);
    let mut segment = writer.begin_segment(axis.clone())?;
    let written = (|| -> Result<TileStats, ConvertError> {
        let mut stats = TileStats::default();
        let batch = 2 * rayon::current_num_threads().max(1);
        let mut tiles = tiles.peekable();
        while tiles.peek().is_some() {
            let chunk: Vec<(TileHistory, SegmentTileEncoder)> = tiles
                .by_ref()
                .take(batch)
                .map(|tile| Ok((tile?, segment.tile_encoder())))
                .collect::<Result<_, ConvertError>>()?;
            let encoded: Vec<(EncodedTile, Option<TileRemainder>, TileStats, u64)> = chunk
                .into_par_iter()
                .map(|(tile, encoder)| {
                    let cells: Vec<PackedCell> = tile.into_packed();
                    let count = cells.len() as u64;
                    let (pieces, patch) = match join.patch(&chooser, cells)? {
                        Ok((differing, remainder)) => (differing, Some(remainder)),
                        Err(cells) => (join.pieces(cells)?, None),
                    };
                    let (tile, stats) = chooser.encode(pieces, encoder)?;
                    Ok((tile, patch, stats, count))
                })
                .collect::<Result<_, ConvertError>>()?;
            for (tile, patch, tile_stats, cells) in encoded {
                match patch {
                    Some(remainder) => segment.write_patch_tile_with(&tile, remainder)?,
                    None => segment.write_tile(&tile)?,
                }
                stats.add(&tile_stats);
                progress.advance(cells);
            }
        }
        Ok(stats)
    })();
    let stats = match written {
        Ok(stats) => stats,
        Err(e) => {
            drop(segment);
            // Cut what was written past the committed bytes (readers ignore it anyway).
            drop(writer.begin_segment(axis));
            return Err(e);
        }
    };
    let root = segment.commit()?;
    let model_seconds = modelling.elapsed().as_secs_f64();
    let reader = writer.reader();
    Ok(IngestReport {
        output: file,
        inputs: inputs.len(),
        used: intaken.used,
        skipped: intaken.skipped,
        warnings: intaken.warnings,
        input_bytes: intaken.input_bytes,
        samples: root.sample_count,
        regular_axis: axis.step_ns().is_some(),
        cells: stats.cells,
        voxels: stats.voxels,
        toggles: stats.toggles,
        model_errors: 0,
        changed_voxels: intaken.changed_voxels,
        file_bytes: root.committed_len,
        header_bytes: 0,
        index_bytes: 0,
        tile_bytes: 0,
        read_seconds: intaken.read_seconds,
        accumulate_seconds,
        model_seconds,
        spilled_bytes,
        spills,
        extended: Some(Extended {
            samples_before,
            start: header.axis.start(),
            end_before,
            end: reader.last_instant(),
            lossless: base.model().outlier_mode() == OutlierMode::Lossless,
            bytes_before: before.committed_len,
            segments: Some(reader.segment_count()),
            converted: false,
        }),
    })
}

/// Refuses a file (of any version) whose model cannot grow by segments
/// ([`ConvertError::ModelCannotGrow`]), so that a caller can say so before converting a
/// 1.x file to 2.0; a file that does not open is refused as it would be for an append.
pub fn refuse_growing_fixed_span(context: &Context, path: &Path) -> Result<(), ConvertError> {
    if is_living_file(path)? {
        let file = LivingReader::open_with_limits(path, context.limits().froct, context.models())?;
        refuse_fixed_span(context, path, file.header())?;
    } else {
        refuse_fixed_span(context, path, context.open_froct(path)?.header())?;
    }
    Ok(())
}

/// The model of the file `path` with `header`, unless it is the one that cannot grow.
fn refuse_fixed_span<'c>(
    context: &'c Context,
    path: &Path,
    header: &froctomap_file::Header,
) -> Result<&'c froctomap_temporal::ModelDescriptor, ConvertError> {
    let model = context.model_of(header)?;
    if model.name == FIXED_SPAN_MODEL {
        return Err(ConvertError::ModelCannotGrow {
            file: path.to_path_buf(),
            model: model.name,
        });
    }
    Ok(model)
}

/// The new maps as a segment of the file at `path`, a 1.x file converted first.
pub(super) fn into_living(run: &Run<'_>, path: &Path) -> Result<IngestReport, ConvertError> {
    let context = run.context;
    let open = |at: &Path| {
        LivingWriter::open_with_limits(at, context.limits().froct, context.models())
            .map_err(ConvertError::from)
    };
    if is_living_file(path)? {
        return add_segment(run, &mut open(path)?);
    }
    // Refused as a 1.x file would be (a map file, a damaged file) before anything is written.
    let before = context.open_froct(path)?.file_len();
    let io = |source| {
        ConvertError::File(froctomap_file::FileError::Io {
            path: path.to_path_buf(),
            source,
        })
    };
    // The converted file is made under a temporary name beside the file (`.froct-…tmp`,
    // which the next writer there removes if this process dies unlocked) and renamed over
    // it once its segment is committed. The name is reserved, then released for `convert`,
    // which writes its own temporary file and renames it there, and the writer locks it.
    let converted = UpgradeFile(
        froctomap_core::temporary_beside(path, std::ffi::OsStr::new(".froct-upgrade-"))
            .map_err(io)?
            .path()
            .to_path_buf(),
    );
    LivingWriter::convert(path, &converted.0)?;
    let mut report = add_segment(run, &mut open(&converted.0)?)?;
    std::fs::rename(&converted.0, path).map_err(io)?;
    // The rename is durable only once the directory is synced, as compaction's.
    crate::files::sync_parent(path);
    report.output = path.to_path_buf();
    if let Some(extended) = &mut report.extended {
        extended.bytes_before = before;
        extended.converted = true;
    }
    Ok(report)
}

/// A converted file not yet renamed into place: removed when dropped (a failed append).
struct UpgradeFile(std::path::PathBuf);

impl Drop for UpgradeFile {
    fn drop(&mut self) {
        // Gone already once renamed into place.
        let _ = std::fs::remove_file(&self.0);
    }
}

/// Stage 1: what the file allows and the segment's own axis.
struct SegmentPlan {
    /// The segment's samples: the new maps' instants, numbered from 0.
    axis: TimeAxis,
    /// Whether modelled base cells may be inherited (their `p(t)` is the same everywhere).
    inherit_models: bool,
}

impl SegmentPlan {
    fn new(
        context: &Context,
        file: &LivingReader,
        inputs: &[SeriesInput],
    ) -> Result<Self, ConvertError> {
        let first = inputs.first().ok_or(ConvertError::NoInputs)?;
        let model = refuse_fixed_span(context, file.path(), file.header())?;
        let last: Timestamp = file.last_instant();
        if first.time <= last {
            return Err(refuse_overlap(file.path(), inputs, last));
        }
        let times: Vec<Timestamp> = inputs.iter().map(|i| i.time).collect();
        Ok(Self {
            axis: axis_for_times(&times)?,
            inherit_models: model.name != PLATFORM_DEPENDENT_MODEL,
        })
    }
}

/// What a base cell predicts, owned (pieces of it share it). A constant base cell's
/// prediction is its state, which inheriting can never beat (a constant segment cell of the
/// better state has at most as many exceptions), so its state is not kept.
#[derive(Clone, Debug)]
enum BasePrediction {
    Constant,
    Model(Arc<[u8]>),
}

/// A piece of the refinement: inside one base cell (`Some`) or outside all of them.
type JoinedPiece = (MortonCode, u8, PackedObservations, Option<BasePrediction>);

/// Stage 3: an accumulated tile joined to the base tile with the same code.
struct BaseJoin<'a> {
    base: &'a FroctReader,
}

impl BaseJoin<'_> {
    /// The tile's cells, those that change over the segment split into their common
    /// refinement with the base cells (so that each piece lies inside one base cell or
    /// outside all of them). A cell observed in one state is stored constant whatever the
    /// base holds there, so it stays whole, and a tile without a changing cell is not
    /// joined at all: the base tile is read only where inheriting may pay.
    fn pieces(&self, cells: Vec<PackedCell>) -> Result<Vec<JoinedPiece>, ConvertError> {
        let Some(code) = cells.first().map(|cell| cell.0) else {
            return Ok(Vec::new());
        };
        let mut whole: Vec<JoinedPiece> = Vec::with_capacity(cells.len());
        let mut changing: Vec<PackedCell> = Vec::new();
        for cell in cells {
            let constant = cell.2.run_count() == 1 || cell.2.unpack()?.is_constant().is_some();
            if constant {
                whole.push((cell.0, cell.1, cell.2, None));
            } else {
                changing.push(cell);
            }
        }
        if changing.is_empty() {
            return Ok(whole);
        }
        let mut base_cells: Vec<Piece<BasePrediction>> = Vec::new();
        if let Some(index) = self.base.tile_containing(code) {
            self.base
                .visit_frozen_predictions(index, |start, depth, prediction| {
                    let owned = match prediction {
                        FrozenPrediction::State(_) => BasePrediction::Constant,
                        FrozenPrediction::Model(parameters) => {
                            BasePrediction::Model(Arc::from(parameters))
                        }
                    };
                    base_cells.push((start, depth, owned));
                })?;
        }
        let mut refined = Vec::with_capacity(changing.len());
        common_refinement(changing, base_cells, |start, depth, new, base| {
            if let Some(observations) = new {
                refined.push((start, depth, observations, base));
            }
            Ok::<(), ConvertError>(())
        })?;
        // Both in Morton order and disjoint: merged into one.
        let mut pieces = Vec::with_capacity(whole.len() + refined.len());
        let mut refined = refined.into_iter().peekable();
        for piece in whole {
            while let Some(next) = refined.next_if(|r| r.0 < piece.0) {
                pieces.push(next);
            }
            pieces.push(piece);
        }
        pieces.extend(refined);
        Ok(pieces)
    }
}

impl BaseJoin<'_> {
    /// The tile as a *patch tile* (FORMAT.md §10.6, §10.7) when the base has a tile with its
    /// code: `Ok` with the pieces (of the cells' common refinement with the base tile's)
    /// it stores (at least one, as a tile holds a cell) and what observes the rest, which
    /// it leaves to the base's frozen predictions; `Err` with the cells when the base has
    /// no tile there.
    ///
    /// Each base cell's remainder takes the most common mask among its pieces that follow
    /// its frozen prediction wherever observed (a partial view hides whole regions, whose
    /// pieces share one), or no sample when a part of it is never observed over the
    /// segment; the tile's default mask is the one most base cells take, the others are
    /// runs of ranks. Every other piece is stored: another state than the prediction at
    /// some sample, another mask, outside every base cell, or in a base cell of which a
    /// part is never observed.
    #[allow(clippy::type_complexity)]
    fn patch(
        &self,
        chooser: &ContentChooser<'_>,
        cells: Vec<PackedCell>,
    ) -> Result<Result<(Vec<JoinedPiece>, TileRemainder), Vec<PackedCell>>, ConvertError> {
        let Some(index) = cells
            .first()
            .and_then(|cell| self.base.tile_containing(cell.0))
        else {
            return Ok(Err(cells));
        };
        let base_cells = self.frozen_cells(index)?;
        let ranks = base_cells.len();
        let indexed: Vec<Piece<usize>> = cells
            .iter()
            .enumerate()
            .map(|(i, cell)| (cell.0, cell.1, i))
            .collect();
        // Each cell decoded once, when its first piece needs it.
        let mut decoded: Vec<Option<Observed>> = vec![None; cells.len()];
        // Per base cell: a part of it is never observed over the segment.
        let mut unobserved = vec![false; ranks];
        // The observed pieces with the cell they come from, the base cell holding them, and
        // whether they follow its prediction wherever observed.
        let mut pieces: Vec<(MortonCode, u8, usize, Option<(u32, Frozen)>, bool)> = Vec::new();
        common_refinement(indexed, base_cells, |start, depth, new, base| {
            let never = |base: &Option<(u32, Frozen)>, unobserved: &mut Vec<bool>| {
                if let Some((rank, _)) = base {
                    unobserved[*rank as usize] = true;
                }
            };
            let Some(i) = new else {
                never(&base, &mut unobserved);
                return Ok(());
            };
            let observed = match &mut decoded[i] {
                Some(observed) => observed,
                slot => slot.insert(chooser.observed(&cells[i].2)?),
            };
            if observed.mask.as_ref().is_some_and(|mask| mask.is_empty()) {
                // Observed at no sample: unknown, as a part no cell covers.
                never(&base, &mut unobserved);
                return Ok(());
            }
            let predicted = base
                .as_ref()
                .is_some_and(|(_, base)| chooser.predicts(observed, base));
            pieces.push((start, depth, i, base, predicted));
            Ok::<(), ConvertError>(())
        })?;
        // The candidate masks (bounded: a tile of many distinct masks keeps the first
        // ones), each predicted piece's, and per base cell the votes of its pieces (pieces
        // of one base cell are consecutive).
        let mut candidates: Vec<&RemainderMask> = Vec::new();
        let mut candidate_of: Vec<Option<usize>> = vec![None; pieces.len()];
        let mut choice: Vec<Option<usize>> = vec![None; ranks];
        let mut votes: Vec<(usize, usize)> = Vec::new();
        let mut group: Option<u32> = None;
        let mut close = |rank: Option<u32>, votes: &mut Vec<(usize, usize)>| {
            if let Some(rank) = rank {
                choice[rank as usize] = votes.iter().max_by_key(|v| v.1).map(|v| v.0);
            }
            votes.clear();
        };
        for (p, piece) in pieces.iter().enumerate() {
            let rank = piece.3.as_ref().map(|b| b.0);
            if rank != group {
                close(group, &mut votes);
                group = rank;
            }
            let (Some(rank), true) = (rank, piece.4) else {
                continue;
            };
            if unobserved[rank as usize] {
                continue;
            }
            let Some(mask) = decoded[piece.2].as_ref().map(|o| &o.mask) else {
                continue;
            };
            let c = match candidates.iter().position(|m| *m == mask) {
                Some(c) => c,
                None if candidates.len() < MAX_REMAINDER_CANDIDATES => {
                    candidates.push(mask);
                    candidates.len() - 1
                }
                None => continue,
            };
            candidate_of[p] = Some(c);
            match votes.iter_mut().find(|v| v.0 == c) {
                Some(v) => v.1 += 1,
                None => votes.push((c, 1)),
            }
        }
        close(group, &mut votes);
        let Resolution {
            default,
            resolved,
            extras,
            runs,
        } = resolve_remainders(&choice, &unobserved, candidates.len());
        let mask_of = |c: usize| candidates[c].clone();
        let remainder = TileRemainder {
            default: default.and_then(mask_of),
            masks: extras.iter().map(|&c| mask_of(c)).collect(),
            runs,
        };
        let mut differing: Vec<JoinedPiece> = Vec::new();
        let mut first: Option<JoinedPiece> = None;
        for (p, (start, depth, i, base, _)) in pieces.into_iter().enumerate() {
            let inherits = match (&base, candidate_of[p]) {
                (Some((rank, _)), Some(c)) => resolved[*rank as usize] == Some(c),
                _ => false,
            };
            if inherits && first.is_some() {
                continue;
            }
            let piece = (
                start,
                depth,
                cells[i].2.clone(),
                base.map(|(_, frozen)| BasePrediction::from(frozen)),
            );
            if inherits {
                first = Some(piece);
            } else {
                differing.push(piece);
            }
        }
        if differing.is_empty() {
            differing.extend(first);
        }
        Ok(Ok((differing, remainder)))
    }

    /// The base tile's cells with their ranks and frozen predictions, owned.
    fn frozen_cells(&self, index: usize) -> Result<Vec<Piece<(u32, Frozen)>>, ConvertError> {
        let mut base_cells: Vec<Piece<(u32, Frozen)>> = Vec::new();
        self.base
            .visit_frozen_predictions(index, |start, depth, prediction| {
                let owned = match prediction {
                    FrozenPrediction::State(state) => Frozen::State(state),
                    FrozenPrediction::Model(parameters) => Frozen::Model(Arc::from(parameters)),
                };
                let rank = base_cells.len() as u32;
                base_cells.push((start, depth, (rank, owned)));
            })?;
        Ok(base_cells)
    }
}

/// How a patch tile's base cells' remainders are observed.
struct Resolution {
    /// The candidate mask most base cells take.
    default: Option<usize>,
    /// Per base cell, the candidate observing its remainder (`None`: no sample).
    resolved: Vec<Option<usize>>,
    /// The candidates other than the default that some base cell takes, in first use.
    extras: Vec<usize>,
    /// The base cells not taking the default, as runs of ranks.
    runs: Vec<RemainderRun>,
}

/// The default mask, each base cell's, and the runs of those that differ, from the mask
/// each base cell's pieces voted for (`choice`) among `candidates`.
fn resolve_remainders(
    choice: &[Option<usize>],
    unobserved: &[bool],
    candidates: usize,
) -> Resolution {
    let ranks = choice.len();
    // The default: the mask most base cells take.
    let mut takers = vec![0usize; candidates];
    for c in choice.iter().flatten() {
        takers[*c] += 1;
    }
    let default = (0..candidates).max_by_key(|&c| takers[c]);
    // Per base cell, what observes its remainder (`None`: no sample); a base cell
    // without a predicted piece has no remainder and takes its neighbour's, so that
    // runs stay long.
    let mut resolved: Vec<Option<usize>> = Vec::with_capacity(ranks);
    for rank in 0..ranks {
        let value = if unobserved[rank] {
            None
        } else {
            match choice[rank] {
                Some(c) => Some(c),
                None => resolved.last().copied().unwrap_or(default),
            }
        };
        resolved.push(value);
    }
    let mut extras: Vec<usize> = Vec::new();
    let mut runs: Vec<RemainderRun> = Vec::new();
    for (rank, &value) in resolved.iter().enumerate() {
        if value.is_some() && value == default {
            continue;
        }
        let mask = match value {
            None => 0,
            Some(c) => match extras.iter().position(|&e| e == c) {
                Some(e) => e as u32 + 1,
                None => {
                    extras.push(c);
                    extras.len() as u32
                }
            },
        };
        let rank = rank as u32;
        match runs.last_mut() {
            Some(run) if run.first + run.len == rank && run.mask == mask => run.len += 1,
            _ => runs.push(RemainderRun {
                first: rank,
                len: 1,
                mask,
            }),
        }
    }
    Resolution {
        default,
        resolved,
        extras,
        runs,
    }
}

/// Distinct observation masks a tile's remainder is chosen from.
const MAX_REMAINDER_CANDIDATES: usize = 64;

/// A base cell's frozen prediction, owned.
#[derive(Clone, Debug)]
enum Frozen {
    State(Occupancy),
    Model(Arc<[u8]>),
}

impl From<Frozen> for BasePrediction {
    fn from(frozen: Frozen) -> Self {
        match frozen {
            Frozen::State(_) => BasePrediction::Constant,
            Frozen::Model(parameters) => BasePrediction::Model(parameters),
        }
    }
}

/// A cell's observations over the segment as the patch test needs them.
#[derive(Clone, Debug)]
struct Observed {
    /// Its observation mask (`None`: at every sample of the segment that is not missing).
    mask: RemainderMask,
    observations: VoxelObservations,
}

/// Stage 4: each piece's content over the segment, then its tile encoded.
struct ContentChooser<'a> {
    file: &'a Path,
    axis: &'a TimeAxis,
    /// Seconds since the base axis's first instant of each segment sample (0 where missing).
    seconds: Vec<f64>,
    model: &'a dyn PreparedModel,
    inherit_models: bool,
}

impl<'a> ContentChooser<'a> {
    fn new(
        file: &'a Path,
        axis: &'a TimeAxis,
        base: &'a FroctReader,
        inherit_models: bool,
    ) -> Self {
        let origin = base.header().axis.start();
        // As the reader computes a segment sample's instant.
        let seconds = (0..axis.len())
            .map(|j| axis.time(j).map_or(0.0, |t| t.secs_since(origin)))
            .collect();
        Self {
            file,
            axis,
            seconds,
            model: base.model(),
            inherit_models,
        }
    }

    /// A cell's observations, decoded, and whether they cover every sample.
    fn observed(&self, packed: &PackedObservations) -> Result<Observed, ConvertError> {
        let observations = packed.unpack()?;
        let mask = mask_from_ranges(self.axis, &observations.observed_ranges());
        Ok(Observed { mask, observations })
    }

    /// `true` when a cell observed as `observed` is, wherever observed, in the frozen
    /// prediction `base` (as the readers evaluate it), so that a patch tile whose remainder
    /// has its mask may inherit it.
    fn predicts(&self, observed: &Observed, base: &Frozen) -> bool {
        let parameters = match base {
            Frozen::State(state) => return observed.observations.is_constant() == Some(*state),
            Frozen::Model(_) if !self.inherit_models => return false,
            Frozen::Model(parameters) => parameters,
        };
        let prediction = FrozenPrediction::Model(parameters);
        observed.observations.runs().iter().all(|run| {
            (run.first..run.first + run.len).all(|sample| {
                let seconds = self.seconds.get(sample as usize).copied().unwrap_or(0.0);
                prediction.state(self.model, seconds) == run.state
            })
        })
    }

    /// The tile's pieces as segment cells, encoded, with their counts.
    fn encode(
        &self,
        pieces: Vec<JoinedPiece>,
        mut encoder: SegmentTileEncoder,
    ) -> Result<(EncodedTile, TileStats), ConvertError> {
        let mut stats = TileStats::default();
        for (start, depth, packed, base) in pieces {
            let observations = packed.unpack()?;
            let cell = self.cell(start, depth, &observations, base.as_ref());
            count_cell(&cell, &mut stats);
            encoder
                .push(cell)
                .map_err(|source| self.encode_error(source))?;
        }
        let tile = encoder
            .finish()
            .map_err(|source| self.encode_error(source))?;
        Ok((tile, stats))
    }

    fn encode_error(&self, source: froctomap_file::TileEncodeError) -> ConvertError {
        ConvertError::File(froctomap_file::FileError::TileEncode {
            path: self.file.to_path_buf(),
            source,
        })
    }

    /// One piece as a segment cell.
    fn cell(
        &self,
        start: MortonCode,
        depth: u8,
        observations: &VoxelObservations,
        base: Option<&BasePrediction>,
    ) -> SegmentCell {
        let mask = mask_from_ranges(self.axis, &observations.observed_ranges());
        let content = self.content(observations, base);
        SegmentCell {
            start,
            depth,
            mask,
            content,
        }
    }

    fn content(
        &self,
        observations: &VoxelObservations,
        base: Option<&BasePrediction>,
    ) -> SegmentContent {
        if let Some(state) = observations.is_constant() {
            return SegmentContent::Constant(state);
        }
        // Constant with exceptions from the first observed state: the fewest toggles of the
        // two states (the other one needs one more).
        let runs = observations.runs();
        let state = runs.first().map_or(Occupancy::Free, |run| run.state);
        let mut exceptions = ToggleBuilder::new(true);
        for run in runs {
            exceptions.push_run(run.first, run.len, run.state != state);
        }
        let parameters = match base {
            Some(BasePrediction::Model(parameters)) if self.inherit_models => parameters,
            _ => {
                return SegmentContent::ConstantExcept {
                    state,
                    exceptions: exceptions.finish(),
                }
            }
        };
        let mut outliers = ToggleBuilder::new(true);
        for run in runs {
            for sample in run.first..run.first + run.len {
                let seconds = self.seconds.get(sample as usize).copied().unwrap_or(0.0);
                let predicted = FrozenPrediction::Model(parameters).state(self.model, seconds);
                outliers.push(sample, predicted != run.state);
            }
        }
        if outliers.encoded_len() < exceptions.encoded_len() {
            SegmentContent::Inherited {
                outliers: outliers.finish(),
            }
        } else {
            SegmentContent::ConstantExcept {
                state,
                exceptions: exceptions.finish(),
            }
        }
    }
}

/// Counts a segment cell into `stats` (constant cells as static, the others as dynamic).
fn count_cell(cell: &SegmentCell, stats: &mut TileStats) {
    let voxels = voxels_per_node(cell.depth);
    if cell.mask.is_some() {
        stats.cells.unknown_sometimes += 1;
        stats.voxels.unknown_sometimes += voxels;
    }
    match &cell.content {
        SegmentContent::Constant(Occupancy::Free) => {
            stats.cells.static_free += 1;
            stats.voxels.static_free += voxels;
        }
        SegmentContent::Constant(Occupancy::Occupied) => {
            stats.cells.static_occupied += 1;
            stats.voxels.static_occupied += voxels;
        }
        SegmentContent::Inherited { outliers: toggles }
        | SegmentContent::ConstantExcept {
            exceptions: toggles,
            ..
        } => {
            stats.cells.dynamic += 1;
            stats.voxels.dynamic += voxels;
            stats.toggles += toggles.len() as u64;
        }
    }
}
