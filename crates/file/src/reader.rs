//! Random-access reading: header and index on open, any tile on demand.

use crate::error::{corrupt, FileError, FormatViolation};
use crate::header::{Header, MAJOR_VERSION, PREAMBLE_LEN};
use crate::index::{decode_footer, decode_index, TileEntry, FOOTER_LEN};
use crate::limits::ReadLimits;
use crate::source::{ByteSource, FileSource, MemorySource};
use crate::tile::{
    block_parts, decode_frame, frame_table, visit_payload_cells, walk_payload, Cell, CellRef,
    PartKind, TileParts, WalkNeed,
};
use crate::toggle_lists::ToggleLayout;
use froctomap_core::{Leaf, MortonCode, Occupancy, VoxelKey};
use froctomap_temporal::{ModelRegistry, PreparedModel};
use serde_json::{Map, Value};
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Buffers a thread reuses from tile to tile: stored bytes, decoded parts, a zstd context.
#[derive(Default)]
struct TileScratch {
    stored: Vec<u8>,
    parts: Vec<Vec<u8>>,
    zstd: Option<zstd::bulk::Decompressor<'static>>,
}

thread_local! {
    static TILE_SCRATCH: RefCell<TileScratch> = RefCell::default();
}

/// Where a file body lies in its source: the header's offset (after the preamble and, in
/// format 2.0, the root slots), the end of the footer, and the major version it must have.
pub(crate) struct Body {
    pub(crate) header_at: u64,
    pub(crate) end: u64,
    pub(crate) major: u16,
}

/// An open FROctomap file. Opening reads only the header, the footer and the index; tiles
/// are read with positioned reads when asked for, each on its own (a damaged tile does not
/// affect the others). The reader is `Sync`: tiles can be decoded from several threads.
///
/// The bytes come from a [`ByteSource`]: a file ([`open`](Self::open)), memory
/// ([`from_bytes`](Self::from_bytes)) or any source that serves byte ranges
/// ([`from_source`](Self::from_source)).
pub struct FroctReader {
    /// The source's name, for errors.
    path: PathBuf,
    source: Box<dyn ByteSource>,
    file_len: u64,
    header: Header,
    tiles: Vec<TileEntry>,
    summary: Map<String, Value>,
    model: Box<dyn PreparedModel>,
    limits: ReadLimits,
    /// Per tile, whether the full walk accepted it: a query at one sample reads one toggle
    /// block, which cannot tell on its own whether the cells' outlier flags match the lists
    /// (a flag set on a cell without a list shifts every list after it), so each tile a
    /// query reads is walked whole once per reader (docs/LIMITS.md).
    validated: Box<[AtomicBool]>,
}

impl std::fmt::Debug for FroctReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FroctReader")
            .field("path", &self.path)
            .field("tiles", &self.tiles.len())
            .finish()
    }
}

impl FroctReader {
    /// Opens a file with the default [`ReadLimits`].
    pub fn open(path: &Path) -> Result<Self, FileError> {
        Self::open_with_limits(
            path,
            ReadLimits::default(),
            &ModelRegistry::with_default_models(),
        )
    }

    /// Opens a file with explicit limits and model registry.
    pub fn open_with_limits(
        path: &Path,
        limits: ReadLimits,
        models: &ModelRegistry,
    ) -> Result<Self, FileError> {
        let source = FileSource::open(path).map_err(|source| FileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_source(source, limits, models)
    }

    /// Reads a file held in memory (named `memory` in errors; see [`MemorySource`] to name
    /// it), with the default [`ReadLimits`] and models.
    ///
    /// ```
    /// # use froctomap_file::FroctReader;
    /// # let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
    /// #     .join("../../fixtures/froct/golden-v1.1.froct");
    /// let bytes: Vec<u8> = std::fs::read(&path)?;
    /// let reader = FroctReader::from_bytes(bytes.clone())?;
    /// assert_eq!(reader.file_len(), bytes.len() as u64);
    /// assert!(!reader.read_tile(0)?.is_empty());
    ///
    /// // Damage is reported under the source's name.
    /// let err = FroctReader::from_bytes(bytes[..100].to_vec()).unwrap_err();
    /// assert!(err.to_string().starts_with("memory: "), "{err}");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn from_bytes(bytes: impl AsRef<[u8]> + Send + Sync + 'static) -> Result<Self, FileError> {
        Self::from_source(
            MemorySource::new(bytes),
            ReadLimits::default(),
            &ModelRegistry::with_default_models(),
        )
    }

    /// Opens the file `source` serves: reads its preamble, header, footer and index (each
    /// checked against `limits` before it is read), and prepares its model from `models`.
    pub fn from_source(
        source: impl ByteSource + 'static,
        limits: ReadLimits,
        models: &ModelRegistry,
    ) -> Result<Self, FileError> {
        let file_len = source.size();
        let body = Body {
            header_at: PREAMBLE_LEN as u64,
            end: file_len,
            major: MAJOR_VERSION,
        };
        Self::open_body(Box::new(source), body, limits, models)
    }

    /// Opens a file body (preamble, header, tiles, index and footer) that lies in the source
    /// as `body` says: a whole 1.x file, or the base of a 2.0 file.
    pub(crate) fn open_body(
        source: Box<dyn ByteSource>,
        body: Body,
        limits: ReadLimits,
        models: &ModelRegistry,
    ) -> Result<Self, FileError> {
        let path = source.name().to_path_buf();
        let io = |source| FileError::Io {
            path: path.clone(),
            source,
        };
        let invalid = |violation| FileError::Invalid {
            path: path.clone(),
            violation,
        };
        let file_len = body.end;
        let min_len = body.header_at + (4 + FOOTER_LEN) as u64;
        if file_len < min_len {
            let violation = if file_len == 0 {
                corrupt("file", "the file is empty")
            } else {
                corrupt(
                    "file",
                    format!("{file_len} bytes is too short for a FROctomap file"),
                )
            };
            return Err(invalid(violation));
        }
        // Every length read here was checked against the limits and the file's length.
        let read = |offset: u64, len: usize| -> Result<Vec<u8>, FileError> {
            let mut buf = vec![0u8; len];
            source.read_exact_at(offset, &mut buf).map_err(io)?;
            Ok(buf)
        };
        let mut preamble = [0u8; PREAMBLE_LEN];
        source.read_exact_at(0, &mut preamble).map_err(io)?;
        let (_, header_len) =
            Header::decode_preamble(&preamble, &limits, body.major).map_err(invalid)?;
        let data_start = body.header_at + (header_len + 4) as u64;
        if data_start + FOOTER_LEN as u64 > file_len {
            return Err(invalid(corrupt(
                "header",
                "the header runs past the end of the file",
            )));
        }
        let header = Header::decode(
            &preamble,
            &read(body.header_at, header_len + 4)?,
            &limits,
            body.major,
        )
        .map_err(invalid)?;
        let mut footer_bytes = [0u8; FOOTER_LEN];
        source
            .read_exact_at(file_len - FOOTER_LEN as u64, &mut footer_bytes)
            .map_err(io)?;
        let footer =
            decode_footer(&footer_bytes, file_len, data_start, &limits).map_err(invalid)?;
        let index_len = usize::try_from(footer.index_len)
            .map_err(|_| invalid(corrupt("footer", "index too large")))?;
        let index = read(footer.index_offset, index_len)?;
        if crc32c::crc32c(&index) != footer.index_crc {
            return Err(invalid(FormatViolation::Checksum("index")));
        }
        let (tiles, summary) = decode_index(
            &index,
            data_start..footer.index_offset,
            header.tile_depth,
            &limits,
        )
        .map_err(invalid)?;
        let model = models
            .prepare_from_parameters(header.model_id, &header.axis, &header.model_parameters)
            .map_err(|e| invalid(FormatViolation::Model(e)))?;
        let validated = (0..tiles.len()).map(|_| AtomicBool::new(false)).collect();
        Ok(Self {
            path,
            source,
            file_len,
            header,
            tiles,
            summary,
            model,
            limits,
            validated,
        })
    }

    /// A reader over tiles already located (a format 2.0 segment, [`crate::living`]).
    pub(crate) fn from_parts(
        source: Box<dyn ByteSource>,
        header: Header,
        tiles: Vec<TileEntry>,
        model: Box<dyn PreparedModel>,
        limits: ReadLimits,
    ) -> Self {
        let validated = (0..tiles.len()).map(|_| AtomicBool::new(false)).collect();
        Self {
            path: source.name().to_path_buf(),
            file_len: source.size(),
            source,
            header,
            tiles,
            summary: Map::new(),
            model,
            limits,
            validated,
        }
    }

    /// The file's path (the source's name for other sources).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Total file length.
    pub fn file_len(&self) -> u64 {
        self.file_len
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The tiles, in Morton order.
    pub fn tiles(&self) -> &[TileEntry] {
        &self.tiles
    }

    /// The summary stored in the index at write time.
    pub fn summary(&self) -> &Map<String, Value> {
        &self.summary
    }

    /// The temporal model, prepared for this file's time axis.
    pub fn model(&self) -> &dyn PreparedModel {
        self.model.as_ref()
    }

    /// Reads a tile, verifies its checksum, decodes the parts a walk with `need` reads
    /// and hands them to `use_parts`. Buffers and the zstd context are reused per thread.
    fn with_tile<R>(
        &self,
        tile: usize,
        need: WalkNeed,
        use_parts: impl FnOnce(&TileEntry, &TileParts<'_>) -> Result<R, FormatViolation>,
    ) -> Result<R, FileError> {
        let mut scratch = TILE_SCRATCH.with(|s| s.take());
        let result = self.with_tile_in(&mut scratch, tile, need, use_parts);
        TILE_SCRATCH.with(|s| s.replace(scratch));
        result
    }

    fn with_tile_in<R>(
        &self,
        scratch: &mut TileScratch,
        tile: usize,
        need: WalkNeed,
        use_parts: impl FnOnce(&TileEntry, &TileParts<'_>) -> Result<R, FormatViolation>,
    ) -> Result<R, FileError> {
        let invalid = |violation| FileError::Invalid {
            path: self.path.clone(),
            violation,
        };
        let entry = *self.tiles.get(tile).ok_or_else(|| FileError::NoTile {
            path: self.path.clone(),
            tile,
            tiles: self.tiles.len(),
        })?;
        let TileScratch {
            stored,
            parts,
            zstd,
        } = scratch;
        stored.clear();
        stored.resize(entry.stored_len as usize, 0);
        self.source
            .read_exact_at(entry.offset, stored)
            .map_err(|source| FileError::Io {
                path: self.path.clone(),
                source,
            })?;
        if crc32c::crc32c(stored) != entry.crc {
            return Err(invalid(FormatViolation::Checksum("tile")));
        }
        let layout = self.header.tile_layout();
        let axis_len = self.header.axis.len();
        let blocks = need.blocks(layout.toggles, axis_len);
        // The frames to decode (stored bytes, decoded length, blocks held), and the first
        // block of the first block frame among them.
        let (frames, first_block) = match layout.toggles {
            ToggleLayout::Whole => (vec![(&stored[..], entry.raw_len, 0)], 0),
            ToggleLayout::Blocked(_) | ToggleLayout::Coded(_) => {
                let table = frame_table(stored, layout.toggles.blocks(axis_len), entry.raw_len)
                    .map_err(invalid)?;
                let (block_frames, first_block) = table.frames_of(&blocks);
                let (cells, cells_len) = table.frames[0];
                let frames: Vec<(&[u8], u32, usize)> = std::iter::once((cells, cells_len, 0))
                    .chain(block_frames.map(|f| {
                        let (bytes, len) = table.frames[f];
                        (bytes, len, table.blocks_in(f))
                    }))
                    .collect();
                (frames, first_block)
            }
        };
        if parts.len() < frames.len() {
            parts.resize_with(frames.len(), Vec::new);
        }
        for ((frame, raw_len, _), out) in frames.iter().zip(parts.iter_mut()) {
            decode_frame(frame, *raw_len, layout.codec, zstd, out).map_err(invalid)?;
        }
        let block_kind = PartKind::block_of(layout.toggles);
        // Every block part of the decoded frames, numbered, then those the walk needs.
        let mut numbered = Vec::new();
        let mut next_block = first_block;
        for (part, &(_, _, held)) in parts[1..frames.len()].iter().zip(&frames[1..]) {
            for block in block_parts(part, held, block_kind).map_err(invalid)? {
                if blocks.contains(&next_block) {
                    numbered.push((next_block, block));
                }
                next_block += 1;
            }
        }
        let tile_parts = TileParts {
            cells: &parts[0],
            blocks: numbered,
        };
        use_parts(&entry, &tile_parts).map_err(invalid)
    }

    fn check_count(&self, entry: &TileEntry, count: usize) -> Result<(), FileError> {
        if count != entry.cell_count as usize {
            return Err(FileError::Invalid {
                path: self.path.clone(),
                violation: corrupt("tile", "cell count differs from the index"),
            });
        }
        Ok(())
    }

    /// Reads and decodes one tile: verifies its checksum, decompresses it and parses its cells.
    /// Holds every cell of the tile (up to [`ReadLimits::max_cells_per_tile`]); see
    /// [`visit_cells`](Self::visit_cells) to go through them one at a time.
    pub fn read_tile(&self, tile: usize) -> Result<Vec<Cell>, FileError> {
        let mut cells = Vec::new();
        self.visit_cells(tile, |cell| cells.push(cell))?;
        Ok(cells)
    }

    /// Calls `visit` with each cell of a tile, built, in Morton order, holding one cell at a
    /// time: what whole-file passes (counting, evaluation) use so that their memory is one
    /// tile's decoded bytes, not its cells. When it returns an error, the cells visited
    /// before are not to be trusted either.
    ///
    /// ```
    /// # use froctomap_file::FroctReader;
    /// # let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
    /// #     .join("../../fixtures/froct/golden-v1.1.froct");
    /// let reader = FroctReader::open(&path)?;
    /// let mut voxels = 0;
    /// reader.visit_cells(0, |cell| voxels += cell.end() - cell.start.0)?;
    /// assert!(voxels > 0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn visit_cells(&self, tile: usize, mut visit: impl FnMut(Cell)) -> Result<(), FileError> {
        let layout = self.header.tile_layout();
        let axis_len = self.header.axis.len();
        let (entry, count) = self.with_tile(tile, WalkNeed::Everything, |entry, parts| {
            // Queries at one sample skip the tiles whose index span leaves it out: a cell
            // observed outside that span would read differently through them.
            let mut outside_span = false;
            let count = visit_payload_cells(
                parts,
                entry.code,
                &layout,
                self.model.as_ref(),
                &self.limits,
                |cell| {
                    if let Some((first, last)) = cell.observed_span(axis_len) {
                        outside_span |= first < entry.first_sample || last > entry.last_sample;
                    }
                    visit(cell);
                },
            )?;
            if outside_span {
                return Err(corrupt(
                    "tile",
                    "a cell is observed outside the samples the index gives the tile",
                ));
            }
            Ok((*entry, count))
        })?;
        self.check_count(&entry, count)
    }

    /// Walks a tile whole, as [`visit_cells`](Self::visit_cells) does, the first time a
    /// query at one sample asks for it (before the index's sample span of the tile is
    /// trusted to skip it, and the lists read at one sample are trusted to match the cells'
    /// flags): such a query then refuses what the full walk refuses. Predictions read the
    /// models only, which the lists cannot shift.
    fn validate_once(&self, tile: usize) -> Result<(), FileError> {
        let Some(validated) = self.validated.get(tile) else {
            return Ok(()); // walk_tile reports the missing tile
        };
        if validated.load(Ordering::Acquire) {
            return Ok(());
        }
        self.visit_cells(tile, |_| {})?;
        validated.store(true, Ordering::Release);
        Ok(())
    }

    /// Walks one tile's cells without building them.
    pub(crate) fn walk_tile(
        &self,
        tile: usize,
        need: WalkNeed,
        visit: impl FnMut(CellRef<'_>),
    ) -> Result<(), FileError> {
        let layout = self.header.tile_layout();
        let (entry, count) = self.with_tile(tile, need, |entry, parts| {
            let count = walk_payload(
                parts,
                entry.code,
                &layout,
                self.model.as_ref(),
                &self.limits,
                need,
                visit,
            )?;
            Ok((*entry, count))
        })?;
        self.check_count(&entry, count)
    }

    /// Appends to `out` one leaf per cell of a tile observed at `sample`, with the `.bt`
    /// log-odds of its state (exact in lossless files), in Morton order. Streams through
    /// the tile without building cells: the fast path of a retrieval.
    pub fn observed_leaves(
        &self,
        tile: usize,
        sample: u32,
        out: &mut Vec<Leaf>,
    ) -> Result<(), FileError> {
        self.visit_observed_states(tile, sample, |start, depth, state| {
            out.push(Leaf {
                start,
                depth,
                log_odds: state.log_odds(),
            });
        })
    }

    /// Calls `visit(start, depth, state)` for each cell of a tile observed at `sample`, with
    /// its state there (exact in lossless files), in Morton order.
    pub fn visit_observed_states(
        &self,
        tile: usize,
        sample: u32,
        mut visit: impl FnMut(MortonCode, u8, Occupancy),
    ) -> Result<(), FileError> {
        // Before the index's sample span is trusted to skip the tile.
        self.validate_once(tile)?;
        if self.tiles.get(tile).is_some_and(|t| !t.may_observe(sample)) {
            return Ok(());
        }
        let model = self.model.as_ref();
        self.walk_tile(tile, WalkNeed::StateAt(sample), |cell| {
            if cell.observed {
                visit(cell.start, cell.depth, cell.state(model, sample));
            }
        })
    }

    /// Calls `visit(start, depth, state)` for every cell of a tile with its predicted state
    /// at `seconds` since the first sample (occupied when `p > 0.5`), in Morton order.
    pub fn visit_predicted_states(
        &self,
        tile: usize,
        seconds: f64,
        mut visit: impl FnMut(MortonCode, u8, Occupancy),
    ) -> Result<(), FileError> {
        let model = self.model.as_ref();
        self.walk_tile(tile, WalkNeed::ModelOnly, |cell| {
            let occupied = cell.probability(model, seconds) > 0.5;
            visit(cell.start, cell.depth, Occupancy::from(occupied));
        })
    }

    /// Calls `visit(start, depth, prediction)` for every cell of a tile, in Morton order,
    /// with what it predicts (its state, or its model's parameters) without decoding masks
    /// or toggles: the frozen prediction a format 2.0 segment's inherited cells use
    /// (FORMAT.md §10.3), evaluated by [`FrozenPrediction::state`] exactly as the readers do.
    /// As the format 2.0 reader's own lookup of inherited cells, it walks the models only,
    /// without validating the rest of the tile first (its cost is the tile's cells, not the
    /// length of their masks and toggles).
    pub fn visit_frozen_predictions(
        &self,
        tile: usize,
        mut visit: impl FnMut(MortonCode, u8, FrozenPrediction<'_>),
    ) -> Result<(), FileError> {
        self.visit_cell_classes(tile, |cell| visit(cell.start, cell.depth, cell.prediction))
    }

    /// Calls `visit` with every cell of a tile, in Morton order, as its class and model say
    /// ([`CellClass`]), without decoding masks or toggles: what a summary of where and how
    /// the world changes needs (`info`). Like
    /// [`visit_frozen_predictions`](Self::visit_frozen_predictions), it does not validate
    /// the rest of the tile first: its cost is the tile's cells, not their histories.
    ///
    /// ```
    /// # use froctomap_file::{FroctReader, FrozenPrediction};
    /// # let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
    /// #     .join("../../fixtures/froct/golden-v1.1.froct");
    /// let reader = FroctReader::open(&path)?;
    /// let (mut modelled, mut cells) = (0, 0);
    /// reader.visit_cell_classes(0, |cell| {
    ///     cells += 1;
    ///     modelled += usize::from(matches!(cell.prediction, FrozenPrediction::Model(_)));
    /// })?;
    /// let mut walked = 0;
    /// reader.visit_cells(0, |_| walked += 1)?;
    /// assert!(cells == walked && modelled <= cells);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn visit_cell_classes(
        &self,
        tile: usize,
        mut visit: impl FnMut(CellClass<'_>),
    ) -> Result<(), FileError> {
        self.walk_tile(tile, WalkNeed::ModelOnly, |cell| {
            let prediction = match (cell.constant, cell.model) {
                (Some(state), _) => FrozenPrediction::State(state),
                (None, Some(parameters)) => FrozenPrediction::Model(parameters),
                (None, None) => FrozenPrediction::State(Occupancy::Free),
            };
            visit(CellClass {
                start: cell.start,
                depth: cell.depth,
                prediction,
                has_outliers: cell.has_outliers,
                sometimes_unknown: cell.has_mask,
            });
        })
    }

    /// Appends to `out` one leaf per cell of a tile with `log_odds(p)` of its probability at
    /// `seconds` since the first sample (any instant), in Morton order.
    pub fn predicted_leaves(
        &self,
        tile: usize,
        seconds: f64,
        log_odds: &dyn Fn(f64) -> f32,
        out: &mut Vec<Leaf>,
    ) -> Result<(), FileError> {
        let model = self.model.as_ref();
        self.walk_tile(tile, WalkNeed::ModelOnly, |cell| {
            out.push(Leaf {
                start: cell.start,
                depth: cell.depth,
                log_odds: log_odds(cell.probability(model, seconds)),
            });
        })
    }

    /// The raw streams of a tile's payload by name, in the order of FORMAT.md §5.2 (a list
    /// set's blocks of one kind joined), for size analysis.
    pub fn tile_streams(&self, tile: usize) -> Result<Vec<(&'static str, Vec<u8>)>, FileError> {
        let layout = self.header.tile_layout();
        self.with_tile(tile, WalkNeed::Everything, |_, parts| {
            parts.named_streams(layout.toggles)
        })
    }

    /// Index of the tile holding a voxel, if that tile exists.
    pub fn tile_containing(&self, voxel: MortonCode) -> Option<usize> {
        let code = voxel.node_start(self.header.tile_depth);
        self.tiles.binary_search_by_key(&code, |t| t.code).ok()
    }

    /// Indices of the tiles that intersect the box of voxel keys `min..=max` (inclusive).
    pub fn tiles_in_box(&self, min: VoxelKey, max: VoxelKey) -> Vec<usize> {
        let edge = 1u32 << (16 - u32::from(self.header.tile_depth));
        self.tiles
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                let lo = t.code.key();
                let inside = |lo: u16, min: u16, max: u16| {
                    let hi = u32::from(lo) + edge - 1;
                    u32::from(lo) <= u32::from(max) && hi >= u32::from(min)
                };
                inside(lo.x, min.x, max.x)
                    && inside(lo.y, min.y, max.y)
                    && inside(lo.z, min.z, max.z)
            })
            .map(|(i, _)| i)
            .collect()
    }
}

/// A cell as its class and model say, without its mask or toggles (see
/// [`FroctReader::visit_cell_classes`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellClass<'a> {
    /// Morton code of the cell's first voxel.
    pub start: MortonCode,
    /// Depth of the cell's node.
    pub depth: u8,
    /// Its constant state, or its model's parameters.
    pub prediction: FrozenPrediction<'a>,
    /// A constant cell with exceptions, or a modelled one with outliers.
    pub has_outliers: bool,
    /// Not observed at every sample (it has an observation mask).
    pub sometimes_unknown: bool,
}

/// What a cell of a file predicts at any instant (see
/// [`FroctReader::visit_frozen_predictions`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FrozenPrediction<'a> {
    /// A constant cell (with or without exceptions): its state.
    State(Occupancy),
    /// A modelled cell: its parameters for the file's model.
    Model(&'a [u8]),
}

impl FrozenPrediction<'_> {
    /// The thresholded prediction (`p > 0.5`) at `seconds` since the base axis's first
    /// instant, computed as the readers compute it.
    pub fn state(&self, model: &dyn PreparedModel, seconds: f64) -> Occupancy {
        match self {
            Self::State(state) => *state,
            Self::Model(parameters) => {
                Occupancy::from(model.probability(parameters, seconds) > 0.5)
            }
        }
    }
}
