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
use crate::toggle_lists::{Column, ListColumns, ListsEncoder, ToggleLayout};
use froctomap_core::{voxels_per_node, MortonCode, TREE_DEPTH};
use froctomap_temporal::{varint, PreparedModel, Toggles};
use std::collections::hash_map::DefaultHasher;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::Arc;

/// A tile ready to be written: only [`TileStreamEncoder`] makes one, so its stored bytes and
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
    /// the raw bytes of each stream they hold. Each block's columns are freed once its part
    /// is written, so the streams and their parts are not held twice.
    fn into_parts(
        mut self,
        layout: ToggleLayout,
        cell_count: usize,
    ) -> (Vec<Vec<u8>>, StreamSizes) {
        let mut sizes = StreamSizes::default();
        let cells = PartKind::cells_of(layout);
        sizes.add_part(cells, |s| self.get(s, 0));
        let mut parts = vec![write_part(cells, cell_count, |s| self.get(s, 0))];
        if cells == PartKind::Cells {
            self.cells = CellStreams::default();
            let kind = PartKind::block_of(layout);
            for block in 0..self.masks.len() {
                sizes.add_part(kind, |s| self.get(s, block));
                parts.push(write_part(kind, 0, |s| self.get(s, block)));
                for set in [&mut self.masks, &mut self.outliers, &mut self.exceptions] {
                    if let Some(columns) = set.get_mut(block) {
                        *columns = ListColumns::default();
                    }
                }
            }
        }
        (parts, sizes)
    }
}

/// Encodes the cells of one tile (sorted, non-overlapping, all inside the tile).
///
/// Modelled cells are encoded with `model`, which must be the model the file header names.
/// ([`TileStreamEncoder`] does the same for cells that arrive one at a time.)
pub fn encode_tile(
    layout: &TileLayout,
    cells: &[Cell],
    model: &dyn PreparedModel,
) -> Result<EncodedTile, TileEncodeError> {
    let mut encoder = TileStreamEncoder::new(layout, model);
    for cell in cells {
        encoder.push(cell)?;
    }
    encoder.finish()
}

/// Encodes one tile cell by cell: [`push`](Self::push) its cells in order (sorted,
/// non-overlapping, all inside one tile), then [`finish`](Self::finish) it; the result is
/// what [`encode_tile`] gives for the same cells.
///
/// Each cell is turned into the tile's streams as it is pushed and need not be kept: a large
/// tile of a long series takes a fraction of the memory as streams that it takes as cells
/// (whose toggle lists are 4-byte positions).
pub struct TileStreamEncoder {
    layout: TileLayout,
    axis_len: u32,
    /// The tile's first voxel and one past its last, from the first cell.
    tile: Option<(MortonCode, u64)>,
    cells: CellStreams,
    cell_count: usize,
    previous_end: u64,
    /// The samples outside which no cell pushed is observed.
    span: Option<(u32, u32)>,
    /// The tile's distinct masks in the order first seen (stored once; masked cells refer to
    /// them by index), and their indices by the hash of their positions.
    mask_table: Vec<Arc<Toggles>>,
    mask_ids: HashMap<u64, Vec<usize>>,
    outliers: ListsEncoder,
    /// Format 1.2 range codes the exceptions of constant cells (sensor noise: independent
    /// from cell to cell) and keeps the outliers of modelled cells (which neighbours share,
    /// and zstd finds) in columns.
    exceptions: Option<ListsEncoder>,
}

impl TileStreamEncoder {
    /// An empty tile of a file of this layout, whose dynamic cells `model` fitted (the model
    /// the file header names).
    pub fn new(layout: &TileLayout, model: &dyn PreparedModel) -> Self {
        let axis_len = model.axis().len();
        let coded = matches!(layout.toggles, ToggleLayout::Coded(_));
        Self {
            layout: *layout,
            axis_len,
            tile: None,
            cells: CellStreams::default(),
            cell_count: 0,
            previous_end: 0,
            span: None,
            mask_table: Vec::new(),
            mask_ids: HashMap::new(),
            outliers: ListsEncoder::columns(layout.toggles, axis_len),
            exceptions: coded.then(|| ListsEncoder::coded(layout.toggles, axis_len)),
        }
    }

    /// Adds the next cell of the tile (after the ones before it, inside the tile of the
    /// first).
    pub fn push(&mut self, cell: &Cell) -> Result<(), TileEncodeError> {
        let tile_depth = self.layout.tile_depth;
        let (_, tile_end) = match self.tile {
            Some(tile) => tile,
            None => {
                let code = cell.start.node_start(tile_depth);
                self.previous_end = code.0;
                *self
                    .tile
                    .insert((code, code.0 + voxels_per_node(tile_depth)))
            }
        };
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
        if start < self.previous_end || cell.end() > tile_end {
            return Err(TileEncodeError::OutOfPlace { start });
        }
        let axis_len = self.axis_len;
        let beyond_axis =
            |toggles: &Toggles| toggles.as_slice().last().is_some_and(|&t| t >= axis_len);
        let out = &mut self.cells;
        varint::write_u64(&mut out.geometry, start - self.previous_end);
        self.previous_end = cell.end();
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
            match &mut self.exceptions {
                Some(exceptions) if class & CLASS_KIND_MASK != CLASS_MODELLED => {
                    exceptions.push(toggles.as_slice());
                }
                _ => self.outliers.push(toggles.as_slice()),
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
            let id = self.mask_id(mask);
            varint::write_u64(&mut self.cells.mask_refs, id as u64);
        }
        self.cells.classes.push(class);
        let (a, b) = cell
            .observed_span(axis_len)
            .ok_or(TileEncodeError::NeverObserved { start })?;
        self.span = Some(self.span.map_or((a, b), |(x, y)| (x.min(a), y.max(b))));
        self.cell_count += 1;
        Ok(())
    }

    /// The index of `mask` in the tile's mask table, added when new.
    fn mask_id(&mut self, mask: &Arc<Toggles>) -> usize {
        let mut hasher = DefaultHasher::new();
        mask.as_slice().hash(&mut hasher);
        let same = self.mask_ids.entry(hasher.finish()).or_default();
        let table = &mut self.mask_table;
        if let Some(&id) = same
            .iter()
            .find(|&&id| table[id].as_slice() == mask.as_slice())
        {
            return id;
        }
        table.push(Arc::clone(mask));
        same.push(table.len() - 1);
        table.len() - 1
    }

    /// The tile, stored as the layout says.
    pub fn finish(self) -> Result<EncodedTile, TileEncodeError> {
        let (code, _) = self.tile.ok_or(TileEncodeError::NoCells)?;
        let layout = self.layout;
        let mut cells = self.cells;
        varint::write_u64(&mut cells.mask_count, self.mask_table.len() as u64);
        let mut masks = ListsEncoder::columns(layout.toggles, self.axis_len);
        for mask in &self.mask_table {
            masks.push(mask.as_slice());
        }
        let streams = EncodedStreams {
            cells,
            masks: masks.finish(),
            outliers: self.outliers.finish(),
            exceptions: self
                .exceptions
                .map(ListsEncoder::finish)
                .unwrap_or_default(),
        };
        let (parts, sizes) = streams.into_parts(layout.toggles, self.cell_count);
        let raw_len = u32::try_from(parts.iter().map(Vec::len).sum::<usize>())
            .map_err(|_| TileEncodeError::TooLarge("tile payload"))?;
        let stored = match layout.toggles {
            ToggleLayout::Whole => {
                compress(parts.into_iter().next().unwrap_or_default(), layout.codec)?
            }
            ToggleLayout::Blocked(_) | ToggleLayout::Coded(_) => store_frames(parts, layout.codec)?,
        };
        let (first_sample, last_sample) = self.span.unwrap_or((0, 0));
        Ok(EncodedTile {
            code,
            stored,
            raw_len,
            cell_count: u32::try_from(self.cell_count)
                .map_err(|_| TileEncodeError::TooLarge("cell count"))?,
            first_sample,
            last_sample,
            streams: sizes,
        })
    }
}
