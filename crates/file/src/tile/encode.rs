//! Encoding cells into a tile ready to be written.

use super::cell::{Cell, CellContent};
use super::frames::{compress, store_frames};
use super::model;
use super::streams::{write_part, ListSet, PartKind, Stream, StreamSizes};
use super::{
    CLASS_FREE, CLASS_HAS_MASK, CLASS_HAS_OUTLIERS, CLASS_KIND_MASK, CLASS_MODELLED, CLASS_OCCUPIED,
};
use crate::error::TileEncodeError;
use crate::layout::TileLayout;
use crate::toggle_lists::{encode_coded, encode_lists, Column, ListColumns, ToggleLayout};
use froctomap_core::{voxels_per_node, MortonCode, TREE_DEPTH};
use froctomap_temporal::{varint, PreparedModel, Toggles};
use std::collections::HashMap;

/// A tile ready to be written: only [`encode_tile`] makes one, so its stored bytes and
/// their decoded length always agree; the writer checksums the bytes it writes.
#[derive(Clone, Debug)]
pub struct EncodedTile {
    code: MortonCode,
    stored: Vec<u8>,
    raw_len: u32,
    cell_count: u32,
    first_sample: u32,
    last_sample: u32,
    streams: StreamSizes,
}

impl EncodedTile {
    /// Morton code of the tile's first voxel.
    pub fn code(&self) -> MortonCode {
        self.code
    }

    /// Bytes as stored in the file.
    pub fn stored(&self) -> &[u8] {
        &self.stored
    }

    /// Payload length before the codec.
    pub fn raw_len(&self) -> u32 {
        self.raw_len
    }

    /// Cells in the tile.
    pub fn cell_count(&self) -> u32 {
        self.cell_count
    }

    /// The samples outside which no cell of the tile is observed (first, last).
    pub fn sample_span(&self) -> (u32, u32) {
        (self.first_sample, self.last_sample)
    }

    /// Raw bytes per stream.
    pub fn streams(&self) -> &StreamSizes {
        &self.streams
    }
}

/// The cell streams of a tile as the encoder builds them.
#[derive(Default)]
struct CellStreams {
    geometry: Vec<u8>,
    depths: Vec<u8>,
    classes: Vec<u8>,
    mask_count: Vec<u8>,
    mask_refs: Vec<u8>,
    models: Vec<u8>,
}

/// All streams of a tile: the cell streams and, per block, the columns of both list sets.
struct EncodedStreams {
    cells: CellStreams,
    masks: Vec<ListColumns>,
    outliers: Vec<ListColumns>,
    /// Format 1.2: the coded exceptions of constant cells, per block.
    exceptions: Vec<ListColumns>,
}

impl EncodedStreams {
    /// A stream, taking list columns from `block`.
    fn get(&self, stream: Stream, block: usize) -> &[u8] {
        fn lists(set: &[ListColumns], block: usize, column: Column) -> &[u8] {
            set.get(block).map_or(&[], |l| l.get(column))
        }
        match stream {
            Stream::Geometry => &self.cells.geometry,
            Stream::Depth => &self.cells.depths,
            Stream::Class => &self.cells.classes,
            Stream::MaskCount => &self.cells.mask_count,
            Stream::MaskRefs => &self.cells.mask_refs,
            Stream::Models => &self.cells.models,
            Stream::List(ListSet::Masks, column) => lists(&self.masks, block, column),
            Stream::List(ListSet::Outliers, column) => lists(&self.outliers, block, column),
            Stream::List(ListSet::Exceptions, column) => lists(&self.exceptions, block, column),
        }
    }

    /// The payload's parts (one in format 1.0; the cells then one per block in 1.1), and
    /// the raw bytes of each stream they hold.
    fn parts(&self, layout: ToggleLayout, cell_count: usize) -> (Vec<Vec<u8>>, StreamSizes) {
        let mut sizes = StreamSizes::default();
        let cells = PartKind::cells_of(layout);
        sizes.add_part(cells, |s| self.get(s, 0));
        let mut parts = vec![write_part(cells, cell_count, |s| self.get(s, 0))];
        if cells == PartKind::Cells {
            let kind = PartKind::block_of(layout);
            for block in 0..self.masks.len() {
                sizes.add_part(kind, |s| self.get(s, block));
                parts.push(write_part(kind, 0, |s| self.get(s, block)));
            }
        }
        (parts, sizes)
    }
}

/// Encodes the cells of one tile (sorted, non-overlapping, all inside the tile).
///
/// Modelled cells are encoded with `model`, which must be the model the file header names.
pub fn encode_tile(
    layout: &TileLayout,
    cells: &[Cell],
    model: &dyn PreparedModel,
) -> Result<EncodedTile, TileEncodeError> {
    let first = cells.first().ok_or(TileEncodeError::NoCells)?;
    let code = first.start.node_start(layout.tile_depth);
    let axis_len = model.axis().len();
    let (streams, span) = encode_streams(layout, code, cells, axis_len)?;
    let (parts, sizes) = streams.parts(layout.toggles, cells.len());
    let raw_len = u32::try_from(parts.iter().map(Vec::len).sum::<usize>())
        .map_err(|_| TileEncodeError::TooLarge("tile payload"))?;
    let stored = match layout.toggles {
        ToggleLayout::Whole => {
            compress(parts.into_iter().next().unwrap_or_default(), layout.codec)?
        }
        ToggleLayout::Blocked(_) | ToggleLayout::Coded(_) => store_frames(parts, layout.codec)?,
    };
    let (first_sample, last_sample) = span;
    Ok(EncodedTile {
        code,
        stored,
        raw_len,
        cell_count: u32::try_from(cells.len())
            .map_err(|_| TileEncodeError::TooLarge("cell count"))?,
        first_sample,
        last_sample,
        streams: sizes,
    })
}

/// The streams of the cells of the tile at `code`, and the samples they are observed in.
fn encode_streams(
    layout: &TileLayout,
    code: MortonCode,
    cells: &[Cell],
    axis_len: u32,
) -> Result<(EncodedStreams, (u32, u32)), TileEncodeError> {
    let tile_depth = layout.tile_depth;
    let tile_end = code.0 + voxels_per_node(tile_depth);
    let mut out = CellStreams {
        depths: Vec::with_capacity(cells.len()),
        classes: Vec::with_capacity(cells.len()),
        ..CellStreams::default()
    };
    let mut mask_table: Vec<&Toggles> = Vec::new();
    let mut mask_ids: HashMap<&[u32], u64> = HashMap::new();
    let mut outliers: Vec<&[u32]> = Vec::new();
    // Format 1.2 range codes the exceptions of constant cells (sensor noise: independent
    // from cell to cell) and keeps the outliers of modelled cells (which neighbours share,
    // and zstd finds) in columns.
    let mut exceptions: Vec<&[u32]> = Vec::new();
    let coded = matches!(layout.toggles, ToggleLayout::Coded(_));
    let mut previous_end = code.0;
    let mut span: Option<(u32, u32)> = None;
    let beyond_axis = |toggles: &Toggles| toggles.as_slice().last().is_some_and(|&t| t >= axis_len);
    for cell in cells {
        let start = cell.start.0;
        if !(tile_depth..=TREE_DEPTH).contains(&cell.depth)
            || cell.start.node_start(cell.depth) != cell.start
        {
            return Err(TileEncodeError::InvalidCell {
                start,
                depth: cell.depth,
                tile_depth,
            });
        }
        if start < previous_end || cell.end() > tile_end {
            return Err(TileEncodeError::OutOfPlace { start });
        }
        varint::write_u64(&mut out.geometry, start - previous_end);
        previous_end = cell.end();
        out.depths.push(cell.depth);
        let state_class = |occupied: bool| if occupied { CLASS_OCCUPIED } else { CLASS_FREE };
        let (mut class, toggles) = match &cell.content {
            CellContent::Constant(state) => (state_class(state.is_occupied()), None),
            CellContent::ConstantExcept { state, exceptions } => {
                (state_class(state.is_occupied()), Some(exceptions))
            }
            CellContent::Modelled(voxel) => {
                model::encode(voxel, &mut out.models);
                (CLASS_MODELLED, Some(model::outliers(voxel)))
            }
        };
        if let Some(toggles) = toggles.filter(|t| !t.is_empty()) {
            if beyond_axis(toggles) {
                return Err(TileEncodeError::BeyondAxis {
                    start,
                    list: "outliers",
                });
            }
            class |= CLASS_HAS_OUTLIERS;
            if coded && class & CLASS_KIND_MASK != CLASS_MODELLED {
                exceptions.push(toggles.as_slice());
            } else {
                outliers.push(toggles.as_slice());
            }
        }
        if let Some(mask) = &cell.mask {
            if beyond_axis(mask) {
                return Err(TileEncodeError::BeyondAxis {
                    start,
                    list: "observation mask",
                });
            }
            class |= CLASS_HAS_MASK;
            let next = mask_table.len() as u64;
            let id = *mask_ids.entry(mask.as_slice()).or_insert_with(|| {
                mask_table.push(mask);
                next
            });
            varint::write_u64(&mut out.mask_refs, id);
        }
        out.classes.push(class);
        let (a, b) = cell
            .observed_span(axis_len)
            .ok_or(TileEncodeError::NeverObserved { start })?;
        span = Some(span.map_or((a, b), |(x, y)| (x.min(a), y.max(b))));
    }
    // The tile's distinct masks are stored once; masked cells refer to them by index.
    varint::write_u64(&mut out.mask_count, mask_table.len() as u64);
    let mask_lists: Vec<&[u32]> = mask_table.iter().map(|m| m.as_slice()).collect();
    let streams = EncodedStreams {
        cells: out,
        masks: encode_lists(&mask_lists, layout.toggles, axis_len),
        outliers: encode_lists(&outliers, layout.toggles, axis_len),
        exceptions: if coded {
            encode_coded(&exceptions, layout.toggles, axis_len)
        } else {
            Vec::new()
        },
    };
    Ok((streams, span.unwrap_or((0, 0))))
}
