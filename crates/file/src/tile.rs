//! Tiles: groups of cells stored and checksummed together ([FORMAT.md §5](../../../docs/FORMAT.md)).

use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation};
use crate::header::Codec;
use crate::limits::ReadLimits;
use crate::toggle_lists::{encode_lists, stream, ListBlock, ToggleLayout, ToggleListReader};
use froctomap_core::{voxels_per_node, MortonCode, Occupancy, TREE_DEPTH};
use froctomap_temporal::{varint, FittedVoxel, PreparedModel, TimeAxis, Toggles};
use std::collections::HashMap;
use std::sync::Arc;

const CLASS_FREE: u8 = 0;
const CLASS_OCCUPIED: u8 = 1;
const CLASS_MODELLED: u8 = 2;
const CLASS_KIND_MASK: u8 = 0b11;
const CLASS_HAS_MASK: u8 = 0b100;
const CLASS_HAS_OUTLIERS: u8 = 0b1000;

/// What a cell stores about its states.
#[derive(Clone, Debug, PartialEq)]
pub enum CellContent {
    /// Observed in this state only: costs one class byte.
    Constant(Occupancy),
    /// Almost always in `state`, except between toggles (state flips at each position):
    /// rare changes, such as sensor noise at a surface, whose mean occupancy is outside
    /// OctoMap's clamping bounds, so that a model would predict nothing a map can express
    /// beyond `state`. Lossy files drop the exceptions.
    ConstantExcept {
        /// The usual state.
        state: Occupancy,
        /// Where the state differs from the usual one.
        exceptions: Toggles,
    },
    /// A temporal model (with its outliers in lossless files).
    Modelled(FittedVoxel),
}

/// One cube of voxels that shares its state at every sample.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// Morton code of the first voxel.
    pub start: MortonCode,
    /// Depth (`tile_depth..=16`); the cell holds `8^(16 − depth)` voxels.
    pub depth: u8,
    /// Observation mask as toggles (observed-ness starts false and flips at each position);
    /// `None` means observed at every sample that is not missing from the axis. Shared:
    /// neighbouring cells usually have the same mask, which a tile stores once.
    pub mask: Option<Arc<Toggles>>,
    /// States.
    pub content: CellContent,
}

impl Cell {
    /// One past the Morton code of the last voxel.
    pub fn end(&self) -> u64 {
        self.start.0 + voxels_per_node(self.depth)
    }

    /// `true` when the cell was observed at `sample`.
    pub fn is_observed(&self, axis: &TimeAxis, sample: u32) -> bool {
        sample < axis.len()
            && !axis.is_missing(sample)
            && self.mask.as_ref().is_none_or(|mask| mask.parity_at(sample))
    }

    /// The state at a sample: `None` where the cell was not observed. Exact in lossless files.
    pub fn state_at(
        &self,
        axis: &TimeAxis,
        model: &dyn PreparedModel,
        sample: u32,
    ) -> Option<Occupancy> {
        if !self.is_observed(axis, sample) {
            return None;
        }
        Some(match &self.content {
            CellContent::Constant(state) => *state,
            CellContent::ConstantExcept { state, exceptions } => {
                if exceptions.parity_at(sample) {
                    flip(*state)
                } else {
                    *state
                }
            }
            CellContent::Modelled(voxel) => model.state_at_sample(voxel, sample),
        })
    }

    /// Occupancy probability at any instant, in seconds since the first sample of the axis.
    pub fn probability(&self, model: &dyn PreparedModel, seconds: f64) -> f64 {
        match &self.content {
            CellContent::Constant(state) | CellContent::ConstantExcept { state, .. } => {
                if state.is_occupied() {
                    1.0
                } else {
                    0.0
                }
            }
            CellContent::Modelled(voxel) => model.probability(voxel.parameters(), seconds),
        }
    }

    /// A sample range outside which the cell is never observed (it may be unobserved at
    /// some samples inside it).
    pub fn observed_span(&self, axis_len: u32) -> Option<(u32, u32)> {
        let last = axis_len.checked_sub(1)?;
        match &self.mask {
            None => Some((0, last)),
            Some(mask) => {
                let toggles = mask.as_slice();
                let first = *toggles.first()?;
                let end = if toggles.len() % 2 == 1 {
                    last
                } else {
                    toggles.last()?.checked_sub(1)?
                };
                Some((first, end))
            }
        }
    }
}

/// Raw bytes of each stream of a tile payload, before compression.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamSizes {
    /// Cell positions.
    pub geometry: u64,
    /// Cell depths.
    pub depth: u64,
    /// Class bytes.
    pub class: u64,
    /// Observation masks.
    pub masks: u64,
    /// Model parameters.
    pub models: u64,
    /// Outlier and exception toggles.
    pub outliers: u64,
}

impl StreamSizes {
    /// Sum of all streams.
    pub fn total(&self) -> u64 {
        self.geometry + self.depth + self.class + self.masks + self.models + self.outliers
    }

    /// Adds another tile's sizes.
    pub fn add(&mut self, other: &StreamSizes) {
        self.geometry += other.geometry;
        self.depth += other.depth;
        self.class += other.class;
        self.masks += other.masks;
        self.models += other.models;
        self.outliers += other.outliers;
    }
}

/// A tile ready to be written.
#[derive(Clone, Debug)]
pub struct EncodedTile {
    /// Morton code of the tile's first voxel.
    pub code: MortonCode,
    /// Bytes as stored in the file.
    pub stored: Vec<u8>,
    /// Payload length before the codec.
    pub raw_len: u32,
    /// crc32c of `stored`.
    pub crc: u32,
    /// Cells in the tile.
    pub cell_count: u32,
    /// No cell is observed before this sample.
    pub first_sample: u32,
    /// No cell is observed after this sample.
    pub last_sample: u32,
    /// Raw bytes per stream.
    pub streams: StreamSizes,
}

/// Raw bytes after which a frame of block parts is closed (format 1.1): frames of a few
/// kilobytes cost zstd's tables many times over, frames of many blocks make a query at one
/// sample decompress blocks it does not read.
const BLOCK_FRAME_BYTES: usize = 32 * 1024;

/// How a file lays out its tiles: what a tile encoder and decoder need of the header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileLayout {
    /// Depth of the tiles' nodes.
    pub tile_depth: u8,
    /// How tile payloads are stored.
    pub codec: Codec,
    /// How toggle lists are stored.
    pub toggles: ToggleLayout,
}

/// Encodes the cells of one tile (sorted, non-overlapping, all inside the tile).
///
/// Modelled cells are encoded with `model`, which must be the model the file header names.
pub fn encode_tile(
    layout: &TileLayout,
    cells: &[Cell],
    model: &dyn PreparedModel,
) -> Result<EncodedTile, String> {
    let TileLayout {
        tile_depth,
        codec,
        toggles: toggle_layout,
    } = *layout;
    let first = cells.first().ok_or("a tile needs at least one cell")?;
    let code = first.start.node_start(tile_depth);
    let tile_end = code.0 + voxels_per_node(tile_depth);
    let axis_len = model.axis().len();
    let mut geometry = Vec::new();
    let mut depths = Vec::with_capacity(cells.len());
    let mut classes = Vec::with_capacity(cells.len());
    let mut mask_table: Vec<&Toggles> = Vec::new();
    let mut mask_ids: HashMap<&[u32], u64> = HashMap::new();
    let mut mask_refs = Vec::new();
    let mut models = Vec::new();
    let mut outliers: Vec<&[u32]> = Vec::new();
    let mut previous_end = code.0;
    let mut span: Option<(u32, u32)> = None;
    for cell in cells {
        if !(tile_depth..=TREE_DEPTH).contains(&cell.depth)
            || cell.start.node_start(cell.depth) != cell.start
        {
            return Err(format!(
                "cell {:#x} at depth {} is not a valid cell of a depth-{tile_depth} tile",
                cell.start.0, cell.depth
            ));
        }
        if cell.start.0 < previous_end || cell.end() > tile_end {
            return Err(format!(
                "cell {:#x} is out of order, overlapping or outside its tile",
                cell.start.0
            ));
        }
        varint::write_u64(&mut geometry, cell.start.0 - previous_end);
        previous_end = cell.end();
        depths.push(cell.depth);
        let state_class = |state: &Occupancy| {
            if state.is_occupied() {
                CLASS_OCCUPIED
            } else {
                CLASS_FREE
            }
        };
        let (mut class, toggles) = match &cell.content {
            CellContent::Constant(state) => (state_class(state), None),
            CellContent::ConstantExcept { state, exceptions } => {
                (state_class(state), Some(exceptions))
            }
            CellContent::Modelled(voxel) => {
                // The model's parameter bytes, verbatim; the toggles go to the outlier lists.
                models.extend_from_slice(voxel.parameters());
                (CLASS_MODELLED, Some(voxel.toggles()))
            }
        };
        if let Some(toggles) = toggles.filter(|t| !t.is_empty()) {
            if toggles.as_slice().last().is_some_and(|&t| t >= axis_len) {
                return Err("outliers beyond the time axis".into());
            }
            class |= CLASS_HAS_OUTLIERS;
            outliers.push(toggles.as_slice());
        }
        if let Some(mask) = &cell.mask {
            if mask.as_slice().last().is_some_and(|&t| t >= axis_len) {
                return Err("observation mask beyond the time axis".into());
            }
            class |= CLASS_HAS_MASK;
            let next = mask_table.len() as u64;
            let id = *mask_ids.entry(mask.as_slice()).or_insert_with(|| {
                mask_table.push(mask);
                next
            });
            varint::write_u64(&mut mask_refs, id);
        }
        classes.push(class);
        let (a, b) = cell
            .observed_span(axis_len)
            .ok_or("a cell must be observed at least once")?;
        span = Some(span.map_or((a, b), |(x, y)| (x.min(a), y.max(b))));
    }
    // The tile's distinct masks are stored once; masked cells refer to them by index.
    let mask_lists: Vec<&[u32]> = mask_table.iter().map(|m| m.as_slice()).collect();
    let masks = encode_lists(&mask_lists, toggle_layout, axis_len);
    let outliers = encode_lists(&outliers, toggle_layout, axis_len);
    let mut mask_count = Vec::new();
    varint::write_u64(&mut mask_count, mask_table.len() as u64);
    let sizes = StreamSizes {
        geometry: geometry.len() as u64,
        depth: depths.len() as u64,
        class: classes.len() as u64,
        masks: (mask_count.len() + mask_refs.len()) as u64 + total_len(&masks),
        models: models.len() as u64,
        outliers: total_len(&outliers),
    };
    let cell_streams = [&geometry, &depths, &classes, &mask_count, &mask_refs];
    // Format 1.0: one payload, the lists between the cell streams. Format 1.1: a part with
    // the cells, then one part per block with that block's lists (see `frame_table`).
    let parts: Vec<Vec<u8>> = match toggle_layout {
        ToggleLayout::Whole => {
            let streams = cell_streams
                .into_iter()
                .chain(&masks[0])
                .chain([&models])
                .chain(&outliers[0]);
            vec![length_prefixed(Some(cells.len()), streams)]
        }
        ToggleLayout::Blocked(_) => {
            let cell_part =
                length_prefixed(Some(cells.len()), cell_streams.into_iter().chain([&models]));
            let blocks = masks
                .iter()
                .zip(&outliers)
                .map(|(m, o)| length_prefixed(None, m.iter().chain(o)));
            std::iter::once(cell_part).chain(blocks).collect()
        }
    };
    let raw_len = u32::try_from(parts.iter().map(Vec::len).sum::<usize>())
        .map_err(|_| "tile payload exceeds 4 GiB")?;
    let compress = |part: Vec<u8>| match codec {
        Codec::Raw => Ok(part),
        Codec::Zstd { level } => zstd::bulk::compress(&part, i32::from(level))
            .map_err(|e| format!("zstd compression failed: {e}")),
    };
    let stored = match toggle_layout {
        ToggleLayout::Whole => compress(parts.into_iter().next().unwrap_or_default())?,
        ToggleLayout::Blocked(_) => {
            // Consecutive block parts share a frame until it holds BLOCK_FRAME_BYTES: small
            // tiles then pay zstd's per-frame tables once, large ones keep a frame per block.
            let mut parts = parts.into_iter();
            let mut raw_parts = vec![parts.next().unwrap_or_default()];
            let mut block_counts = Vec::new();
            for part in parts {
                match (raw_parts.last_mut(), block_counts.last_mut()) {
                    (Some(open), Some(count)) if open.len() < BLOCK_FRAME_BYTES => {
                        open.extend_from_slice(&part);
                        *count += 1;
                    }
                    _ => {
                        raw_parts.push(part);
                        block_counts.push(1u64);
                    }
                }
            }
            let raw_lens: Vec<usize> = raw_parts.iter().map(Vec::len).collect();
            let frames = raw_parts
                .into_iter()
                .map(compress)
                .collect::<Result<Vec<_>, String>>()?;
            let mut stored = Vec::new();
            varint::write_u64(&mut stored, frames.len() as u64);
            for frame in &frames {
                varint::write_u64(&mut stored, frame.len() as u64);
            }
            for len in raw_lens {
                varint::write_u64(&mut stored, len as u64);
            }
            for count in block_counts {
                varint::write_u64(&mut stored, count);
            }
            for frame in frames {
                stored.extend(frame);
            }
            stored
        }
    };
    let (first_sample, last_sample) = span.unwrap_or((0, 0));
    Ok(EncodedTile {
        code,
        crc: crc32c::crc32c(&stored),
        stored,
        raw_len,
        cell_count: u32::try_from(cells.len()).map_err(|_| "too many cells in a tile")?,
        first_sample,
        last_sample,
        streams: sizes,
    })
}

/// Streams, each with its length, after an optional leading count.
fn length_prefixed<'s>(
    count: Option<usize>,
    streams: impl Iterator<Item = &'s Vec<u8>>,
) -> Vec<u8> {
    let mut out = Vec::new();
    if let Some(count) = count {
        varint::write_u64(&mut out, count as u64);
    }
    for stream in streams {
        varint::write_u64(&mut out, stream.len() as u64);
        out.extend_from_slice(stream);
    }
    out
}

fn total_len(blocks: &[Vec<Vec<u8>>]) -> u64 {
    blocks.iter().flatten().map(|s| s.len() as u64).sum()
}

/// The frames of a format 1.1 tile ([`frame_table`]).
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct FrameTable<'a> {
    /// Each frame's stored bytes and raw length; frame 0 is the cell part.
    pub(crate) frames: Vec<(&'a [u8], u32)>,
    /// `block_ends[i]`: one past the last block held by frame `i + 1`.
    pub(crate) block_ends: Vec<u32>,
}

impl FrameTable<'_> {
    /// Blocks held by frame `frame` (≥ 1).
    pub(crate) fn blocks_in(&self, frame: usize) -> usize {
        let end = self.block_ends.get(frame - 1).copied().unwrap_or(0);
        let start = if frame >= 2 {
            self.block_ends.get(frame - 2).copied().unwrap_or(0)
        } else {
            0
        };
        end.saturating_sub(start) as usize
    }

    /// The frames (indices ≥ 1) holding the blocks `blocks`, and the first block of the first.
    pub(crate) fn frames_of(&self, blocks: &std::ops::Range<u32>) -> (std::ops::Range<usize>, u32) {
        if blocks.is_empty() {
            return (1..1, 0);
        }
        let first = self.block_ends.partition_point(|&end| end <= blocks.start);
        let last = self.block_ends.partition_point(|&end| end < blocks.end);
        let first_block = if first == 0 {
            0
        } else {
            self.block_ends[first - 1]
        };
        (first + 1..last + 2, first_block)
    }
}

/// The frames of a format 1.1 tile's stored bytes: `varint F`, `F` stored lengths, `F` raw
/// lengths, `F − 1` block counts (all varints), then the frames: the cell part, then frames
/// of consecutive block parts. Checks the counts against the `blocks` the axis has and the
/// lengths against the bytes and `raw_total`.
pub(crate) fn frame_table(
    stored: &[u8],
    blocks: u32,
    raw_total: u32,
) -> Result<FrameTable<'_>, FormatViolation> {
    let mut c = Cursor::new(stored, "tile frames");
    let count = c.varint()?;
    // Each frame takes at least three bytes of table: a hostile count fails here, before
    // anything is allocated for it.
    if count < 2 || count > u64::from(blocks) + 1 || count > (stored.len() / 3) as u64 {
        return Err(corrupt(
            "tile frames",
            format!(
                "{count} frames for {blocks} blocks in {} bytes",
                stored.len()
            ),
        ));
    }
    let count = count as usize;
    let mut stored_lens = Vec::with_capacity(count);
    for _ in 0..count {
        stored_lens.push(c.count("frame length", 1, u64::MAX)?);
    }
    let mut raw_lens = Vec::with_capacity(count);
    let mut raw_sum = 0u64;
    for _ in 0..count {
        let raw = c.varint()?;
        raw_sum = raw_sum.saturating_add(raw);
        raw_lens.push(raw);
    }
    if raw_sum != u64::from(raw_total) {
        return Err(corrupt(
            "tile frames",
            format!("frames hold {raw_sum} raw bytes, the index says {raw_total}"),
        ));
    }
    let mut block_ends = Vec::with_capacity(count - 1);
    let mut end = 0u64;
    for _ in 1..count {
        let held = c.varint()?;
        end = end.saturating_add(held);
        if held == 0 || end > u64::from(blocks) {
            return Err(corrupt("tile frames", "block counts do not fit the axis"));
        }
        block_ends.push(end as u32);
    }
    if end != u64::from(blocks) {
        return Err(corrupt(
            "tile frames",
            format!("frames hold {end} blocks where the axis has {blocks}"),
        ));
    }
    let mut frames = Vec::with_capacity(count);
    for (len, raw) in stored_lens.into_iter().zip(raw_lens) {
        // `raw ≤ raw_total`, a u32.
        frames.push((c.take(len)?, raw as u32));
    }
    if !c.is_empty() {
        return Err(corrupt("tile frames", "bytes after the last frame"));
    }
    Ok(FrameTable { frames, block_ends })
}

/// Streams in a block part: parity, lists, counts, starts and lengths of the masks, then of
/// the outliers.
const BLOCK_PART_STREAMS: usize = 10;

/// The block parts a decoded frame holds, in order: each is [`BLOCK_PART_STREAMS`]
/// length-prefixed streams.
pub(crate) fn block_parts(frame: &[u8], count: usize) -> Result<Vec<&[u8]>, FormatViolation> {
    let mut c = Cursor::new(frame, "tile block");
    let mut parts = Vec::with_capacity(count.min(frame.len()));
    for _ in 0..count {
        let before = c.remaining();
        for _ in 0..BLOCK_PART_STREAMS {
            stream(&mut c)?;
        }
        let start = frame.len() - before;
        parts.push(&frame[start..frame.len() - c.remaining()]);
    }
    if !c.is_empty() {
        return Err(corrupt("tile block", "bytes after the last block"));
    }
    Ok(parts)
}

/// Decodes one stored frame (a format 1.0 tile, or one part of a 1.1 tile) into `out`,
/// reusing `out` and the zstd context across calls.
pub(crate) fn decode_frame(
    stored: &[u8],
    raw_len: u32,
    codec: Codec,
    zstd_context: &mut Option<zstd::bulk::Decompressor<'static>>,
    out: &mut Vec<u8>,
) -> Result<(), FormatViolation> {
    out.clear();
    match codec {
        Codec::Raw => {
            if stored.len() != raw_len as usize {
                return Err(corrupt(
                    "tile",
                    "stored length differs from the raw length of a raw tile",
                ));
            }
            out.extend_from_slice(stored);
        }
        Codec::Zstd { .. } => {
            let context = match zstd_context {
                Some(context) => context,
                None => zstd_context.insert(
                    zstd::bulk::Decompressor::new()
                        .map_err(|e| corrupt("tile", format!("zstd: {e}")))?,
                ),
            };
            out.reserve(raw_len as usize);
            let len = context
                .decompress_to_buffer(stored, out)
                .map_err(|e| corrupt("tile", format!("zstd: {e}")))?;
            if len != raw_len as usize {
                return Err(corrupt(
                    "tile",
                    format!("decoded {len} bytes, index says {raw_len}"),
                ));
            }
        }
    }
    Ok(())
}

/// A tile's decoded payload as a walk reads it.
pub(crate) struct TileParts<'a> {
    /// Format 1.0: the whole payload. Format 1.1: the cell part.
    pub(crate) cells: &'a [u8],
    /// Format 1.1: the decoded parts of the blocks the walk needs ([`WalkNeed::blocks`]),
    /// with their indices, in block order.
    pub(crate) blocks: Vec<(u32, &'a [u8])>,
}

/// What a payload walk needs of each cell's mask and outliers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum WalkNeed {
    /// Everything (to build [`Cell`]s).
    Everything,
    /// Only whether the cell is observed at this sample and its state there: masks are
    /// evaluated once per distinct mask, outlier lists only as far as the sample.
    StateAt(u32),
    /// Only the model (for predictions): masks and outliers are skipped undecoded.
    ModelOnly,
}

impl WalkNeed {
    /// The toggle blocks (format 1.1) this walk reads: all, the one holding the sample, or
    /// none.
    pub(crate) fn blocks(self, toggles: ToggleLayout, axis_len: u32) -> std::ops::Range<u32> {
        let count = toggles.blocks(axis_len);
        match (self, toggles) {
            (_, ToggleLayout::Whole) | (WalkNeed::ModelOnly, _) => 0..0,
            (WalkNeed::Everything, _) => 0..count,
            (WalkNeed::StateAt(sample), ToggleLayout::Blocked(len)) => {
                let b = (sample / len.max(1)).min(count - 1);
                b..b + 1
            }
        }
    }
}

/// One cell as the payload walk sees it, borrowing from the tile instead of allocating.
pub(crate) struct CellRef<'a> {
    pub(crate) start: MortonCode,
    pub(crate) depth: u8,
    /// With [`WalkNeed::Everything`]: the cell's observation mask (shared by the tile), if
    /// it has one (a query at one sample gets `observed` instead).
    pub(crate) mask: Option<&'a Arc<Toggles>>,
    /// The constant state, or `None` for a modelled cell.
    pub(crate) constant: Option<Occupancy>,
    /// A modelled cell's parameter bytes (without outliers), for the file's model.
    pub(crate) model: Option<&'a [u8]>,
    /// With [`WalkNeed::Everything`]: the cell's outlier (or exception) toggles.
    pub(crate) outliers: &'a [u32],
    /// With [`WalkNeed::StateAt`]: whether the cell is observed at the sample, and whether
    /// an odd number of its outliers lie at or before it.
    pub(crate) observed: bool,
    pub(crate) outlier_parity: bool,
}

impl CellRef<'_> {
    /// With [`WalkNeed::StateAt`]: the state at the sample (meaningful when observed).
    #[inline]
    pub(crate) fn state(&self, model: &dyn PreparedModel, sample: u32) -> Occupancy {
        let base = match (self.constant, self.model) {
            (Some(state), _) => state,
            (None, Some(parameters)) => {
                occupancy(model.probability_at_sample(parameters, sample) > 0.5)
            }
            (None, None) => Occupancy::Free,
        };
        if self.outlier_parity {
            flip(base)
        } else {
            base
        }
    }

    /// Occupancy probability at any instant.
    #[inline]
    pub(crate) fn probability(&self, model: &dyn PreparedModel, seconds: f64) -> f64 {
        match (self.constant, self.model) {
            (Some(state), _) => f64::from(u8::from(state.is_occupied())),
            (None, Some(parameters)) => model.probability(parameters, seconds),
            (None, None) => 0.0,
        }
    }
}

fn occupancy(occupied: bool) -> Occupancy {
    if occupied {
        Occupancy::Occupied
    } else {
        Occupancy::Free
    }
}

/// Parses a tile payload, handing each cell to `visit` in Morton order, decoding only what
/// `need` asks for. Validates the structure it reads; allocates per distinct mask and per
/// modelled cell only.
pub(crate) fn walk_payload(
    parts: &TileParts<'_>,
    code: MortonCode,
    layout: &TileLayout,
    model: &dyn PreparedModel,
    limits: &ReadLimits,
    need: WalkNeed,
    mut visit: impl FnMut(CellRef<'_>),
) -> Result<usize, FormatViolation> {
    let tile_depth = layout.tile_depth;
    let axis = model.axis();
    let axis_len = axis.len();
    let mut c = Cursor::new(parts.cells, "tile");
    let count = c.count("cells per tile", 1, limits.max_cells_per_tile)?;
    if count == 0 {
        return Err(corrupt("tile", "no cells"));
    }
    let geometry = stream(&mut c)?;
    let depths = stream(&mut c)?;
    let classes = stream(&mut c)?;
    let mask_count = stream(&mut c)?;
    let mask_refs = stream(&mut c)?;
    let (mask_blocks, models, outlier_blocks) = match layout.toggles {
        ToggleLayout::Whole => {
            let masks = ListBlock::take_whole(&mut c)?;
            let models = stream(&mut c)?;
            (vec![masks], models, vec![ListBlock::take_whole(&mut c)?])
        }
        ToggleLayout::Blocked(_) => {
            let models = stream(&mut c)?;
            let mut masks = Vec::with_capacity(parts.blocks.len());
            let mut outliers = Vec::with_capacity(parts.blocks.len());
            for &(b, part) in &parts.blocks {
                let mut p = Cursor::new(part, "tile block");
                masks.push(ListBlock::take_blocked(
                    &mut p,
                    layout.toggles,
                    b,
                    axis_len,
                )?);
                outliers.push(ListBlock::take_blocked(
                    &mut p,
                    layout.toggles,
                    b,
                    axis_len,
                )?);
                if !p.is_empty() {
                    return Err(corrupt("tile block", "bytes after the last stream"));
                }
            }
            (masks, models, outliers)
        }
    };
    if !c.is_empty() {
        return Err(corrupt("tile", "bytes after the last stream"));
    }
    let mut masks = ToggleListReader::new(mask_blocks, layout.toggles, axis_len, "tile masks");
    let mut outliers =
        ToggleListReader::new(outlier_blocks, layout.toggles, axis_len, "tile outliers");
    if depths.len() != count || classes.len() != count {
        return Err(corrupt(
            "tile",
            "depth or class stream does not hold one byte per cell",
        ));
    }
    let mut mask_count = Cursor::new(mask_count, "tile masks");
    let distinct = mask_count.varint()?;
    if distinct > count as u64 || distinct > masks.max_lists() as u64 {
        return Err(corrupt(
            "tile masks",
            format!("{distinct} distinct masks cannot fit"),
        ));
    }
    let distinct = distinct as usize;
    let mut scratch = Vec::new();
    // For a query at one sample, only whether each distinct mask observes it: evaluated
    // once per mask, not per cell, and without decoding the mask past the sample.
    let (sample_present, mask_observed, mask_table): (bool, Vec<bool>, Vec<Arc<Toggles>>) =
        match need {
            WalkNeed::StateAt(sample) => (
                sample < axis_len && !axis.is_missing(sample),
                (0..distinct)
                    .map(|_| masks.parity_at(sample))
                    .collect::<Result<_, _>>()?,
                Vec::new(),
            ),
            WalkNeed::ModelOnly => {
                for _ in 0..distinct {
                    masks.skip_list()?;
                }
                (false, Vec::new(), Vec::new())
            }
            WalkNeed::Everything => {
                let mut mask_table = Vec::with_capacity(distinct);
                for _ in 0..distinct {
                    masks.next_list_into(&mut scratch)?;
                    if scratch.is_empty() {
                        return Err(corrupt(
                            "tile masks",
                            "a mask under which a cell is never observed",
                        ));
                    }
                    let toggles = Toggles::new(scratch.clone())
                        .map_err(|e| corrupt("tile masks", e.to_string()))?;
                    mask_table.push(Arc::new(toggles));
                }
                (false, Vec::new(), mask_table)
            }
        };
    let mut mask_refs = Cursor::new(mask_refs, "tile masks");
    let tile_end = code.0 + voxels_per_node(tile_depth);
    let mut geometry = Cursor::new(geometry, "tile geometry");
    let mut model_pos = 0usize;
    let mut previous_end = code.0;
    for (&depth, &class) in depths.iter().zip(classes) {
        let gap = geometry.varint()?;
        if !(tile_depth..=TREE_DEPTH).contains(&depth) {
            return Err(corrupt(
                "tile",
                format!("cell depth {depth} outside {tile_depth}..=16"),
            ));
        }
        let start = previous_end
            .checked_add(gap)
            .filter(|s| s & (voxels_per_node(depth) - 1) == 0)
            .ok_or_else(|| corrupt("tile", "cell not aligned to its depth"))?;
        let end = start + voxels_per_node(depth);
        if end > tile_end {
            return Err(corrupt("tile", "cell outside its tile"));
        }
        previous_end = end;
        if class & !(CLASS_KIND_MASK | CLASS_HAS_MASK | CLASS_HAS_OUTLIERS) != 0 {
            return Err(corrupt("tile", format!("reserved class bits {class:#x}")));
        }
        let (mask, mask_index) = if class & CLASS_HAS_MASK != 0 {
            let id = mask_refs.varint()?;
            let index = usize::try_from(id)
                .ok()
                .filter(|&i| i < distinct)
                .ok_or_else(|| {
                    corrupt(
                        "tile masks",
                        format!("mask index {id} beyond the {distinct} masks"),
                    )
                })?;
            (mask_table.get(index), Some(index))
        } else {
            (None, None)
        };
        let observed = sample_present
            && mask_index.is_none_or(|i| mask_observed.get(i).copied().unwrap_or(false));
        let mut outlier_parity = false;
        let mut has_list = false;
        if class & CLASS_HAS_OUTLIERS != 0 {
            match need {
                WalkNeed::Everything => {
                    has_list = true;
                    outliers.next_list_into(&mut scratch)?;
                    if scratch.is_empty() {
                        return Err(corrupt(
                            "tile outliers",
                            "an empty outlier list is stored by leaving the flag clear",
                        ));
                    }
                }
                WalkNeed::StateAt(sample) => outlier_parity = outliers.parity_at(sample)?,
                WalkNeed::ModelOnly => outliers.skip_list()?,
            }
        }
        // A modelled cell passes its parameter bytes in place: the model delimits and
        // validates them, and evaluates them without decoding.
        let (constant, model_ref) = match class & CLASS_KIND_MASK {
            CLASS_FREE => (Some(Occupancy::Free), None),
            CLASS_OCCUPIED => (Some(Occupancy::Occupied), None),
            CLASS_MODELLED => {
                let rest = models.get(model_pos..).unwrap_or_default();
                let used = model.parameters_len(rest)?;
                let parameters = rest.get(..used).unwrap_or_default();
                model_pos += used;
                (None, Some(parameters))
            }
            _ => return Err(corrupt("tile", "invalid cell class 3")),
        };
        visit(CellRef {
            start: MortonCode(start),
            depth,
            mask,
            constant,
            model: model_ref,
            // Not `&scratch` for every cell: storing its cleared length and loading it back
            // with the pointer stalled the loop (a store-to-load forwarding failure).
            outliers: if has_list { &scratch } else { &[] },
            observed,
            outlier_parity,
        });
    }
    if !geometry.is_empty()
        || !mask_refs.is_empty()
        || !mask_count.is_empty()
        || model_pos != models.len()
    {
        return Err(corrupt("tile", "a stream has bytes no cell uses"));
    }
    masks.finish()?;
    outliers.finish()?;
    Ok(count)
}

/// Parses a tile payload into its cells.
pub(crate) fn decode_payload(
    parts: &TileParts<'_>,
    code: MortonCode,
    layout: &TileLayout,
    model: &dyn PreparedModel,
    limits: &ReadLimits,
) -> Result<Vec<Cell>, FormatViolation> {
    let mut cells = Vec::new();
    let mut invalid = None;
    walk_payload(
        parts,
        code,
        layout,
        model,
        limits,
        WalkNeed::Everything,
        |cell: CellRef<'_>| {
            let outliers = if cell.outliers.is_empty() {
                None
            } else {
                match Toggles::new(cell.outliers.to_vec()) {
                    Ok(t) => Some(t),
                    Err(e) => {
                        invalid.get_or_insert(e.to_string());
                        None
                    }
                }
            };
            let content = match (cell.constant, cell.model, outliers) {
                (Some(state), _, None) => CellContent::Constant(state),
                (Some(state), _, Some(exceptions)) => {
                    CellContent::ConstantExcept { state, exceptions }
                }
                (None, Some(parameters), toggles) => {
                    CellContent::Modelled(FittedVoxel::new(parameters, toggles.unwrap_or_default()))
                }
                (None, None, _) => return,
            };
            cells.push(Cell {
                start: cell.start,
                depth: cell.depth,
                mask: cell.mask.cloned(),
                content,
            });
        },
    )?;
    if let Some(detail) = invalid {
        return Err(corrupt("tile outliers", detail));
    }
    Ok(cells)
}

/// The streams of a tile by name, copied out (a list set's streams of one kind joined over
/// the blocks), from parts holding every block.
pub(crate) fn split_streams(
    parts: &TileParts<'_>,
    layout: &TileLayout,
) -> Result<Vec<(&'static str, Vec<u8>)>, FormatViolation> {
    // Per list set: parity and lists (blocked layout only), counts, starts, lengths.
    const MASKS: [&str; 5] = [
        "mask parity",
        "mask lists",
        "mask counts",
        "mask starts",
        "mask lengths",
    ];
    const OUTLIERS: [&str; 5] = [
        "outlier parity",
        "outlier lists",
        "outlier counts",
        "outlier starts",
        "outlier lengths",
    ];
    let mut c = Cursor::new(parts.cells, "tile");
    c.varint()?;
    let mut named: Vec<(&'static str, Vec<u8>)> = Vec::new();
    let mut add = |name: &'static str, bytes: &[u8]| match named.iter_mut().find(|n| n.0 == name) {
        Some(entry) => entry.1.extend_from_slice(bytes),
        None => named.push((name, bytes.to_vec())),
    };
    for name in ["geometry", "depth", "class", "mask count", "mask refs"] {
        add(name, stream(&mut c)?);
    }
    match layout.toggles {
        ToggleLayout::Whole => {
            for name in &MASKS[2..] {
                add(name, stream(&mut c)?);
            }
            add("models", stream(&mut c)?);
            for name in &OUTLIERS[2..] {
                add(name, stream(&mut c)?);
            }
        }
        ToggleLayout::Blocked(_) => {
            add("models", stream(&mut c)?);
            for (_, part) in &parts.blocks {
                let mut p = Cursor::new(part, "tile block");
                for name in MASKS.iter().chain(&OUTLIERS) {
                    add(name, stream(&mut p)?);
                }
            }
        }
    }
    Ok(named)
}

fn flip(state: Occupancy) -> Occupancy {
    match state {
        Occupancy::Free => Occupancy::Occupied,
        Occupancy::Occupied => Occupancy::Free,
    }
}

/// Helper for writers that build masks from observed runs: the mask toggles of a list of
/// observed sample ranges `[first, end)`, or `None` when they cover every sample that is not
/// missing from the axis.
pub fn mask_from_ranges(axis: &TimeAxis, ranges: &[(u32, u64)]) -> Option<Arc<Toggles>> {
    let mut toggles: Vec<u32> = Vec::with_capacity(ranges.len() * 2);
    let mut observed_end: Option<u64> = None;
    for &(first, end) in ranges {
        // Bridge gaps made only of missing samples: they are unknown for every cell anyway.
        let bridged = observed_end.is_some_and(|prev| all_missing(axis, prev, u64::from(first)));
        if bridged {
            toggles.pop();
        } else {
            let leading = observed_end.is_none() && all_missing(axis, 0, u64::from(first));
            toggles.push(if leading { 0 } else { first });
        }
        if end < u64::from(axis.len()) {
            toggles.push(end as u32);
        }
        observed_end = Some(end);
    }
    // Trailing samples after the last run that are all missing need no toggle either.
    if let (Some(end), Some(&last)) = (observed_end, toggles.last()) {
        if toggles.len() % 2 == 0
            && u64::from(last) == end
            && all_missing(axis, end, u64::from(axis.len()))
        {
            toggles.pop();
        }
    }
    if toggles == [0] {
        return None;
    }
    Toggles::new(toggles).ok().map(Arc::new)
}

/// `true` when every sample in `[first, end)` is missing from the axis (vacuously for an
/// empty range).
fn all_missing(axis: &TimeAxis, first: u64, end: u64) -> bool {
    if end <= first {
        return true;
    }
    let missing = axis.missing();
    let from = missing.partition_point(|&m| u64::from(m) < first);
    let to = missing.partition_point(|&m| u64::from(m) < end);
    (to - from) as u64 == end - first
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_tables_are_checked_before_allocating() {
        // A header asking for four billion blocks meets a small tile.
        let err = frame_table(&[0x80, 0x80, 0x80, 0x80, 0x10, 1, 2], u32::MAX, 10).unwrap_err();
        assert!(err.to_string().contains("frames for"), "{err}");
        // The cell part (1 stored byte, 3 raw) and one frame of 2 blocks (2 bytes, 4 raw).
        let stored = [2, 1, 2, 3, 4, 2, 0xAA, 0xBB, 0xCC];
        let table = frame_table(&stored, 2, 7).unwrap();
        assert_eq!(table.frames, vec![(&stored[6..7], 3), (&stored[7..9], 4)]);
        assert_eq!(table.frames_of(&(1..2)), (1..2, 0));
        assert!(
            frame_table(&stored, 3, 7).is_err(),
            "frames hold fewer blocks"
        );
        assert!(
            frame_table(&stored, 1, 7).is_err(),
            "frames hold more blocks"
        );
        assert!(frame_table(&stored, 2, 8).is_err(), "raw total differs");
        assert!(frame_table(&stored[..8], 2, 7).is_err(), "truncated frame");
        let mut longer = stored.to_vec();
        longer.push(0);
        assert!(
            frame_table(&longer, 2, 7).is_err(),
            "bytes after the frames"
        );
    }

    #[test]
    fn blocks_map_to_the_frames_holding_them() {
        let table = FrameTable {
            frames: Vec::new(),
            block_ends: vec![3, 4, 9],
        };
        assert_eq!(table.frames_of(&(0..1)), (1..2, 0));
        assert_eq!(table.frames_of(&(2..3)), (1..2, 0));
        assert_eq!(table.frames_of(&(3..4)), (2..3, 3));
        assert_eq!(table.frames_of(&(8..9)), (3..4, 4));
        assert_eq!(table.frames_of(&(0..9)), (1..4, 0));
        assert_eq!(table.frames_of(&(0..0)), (1..1, 0));
    }
}
