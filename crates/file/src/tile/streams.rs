//! The streams of a tile payload ([FORMAT.md §5.2](../../../docs/FORMAT.md)): their names,
//! their order in each part and their length-prefixed layout, in this one place for the
//! encoder, the payload walk and size analysis.

use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation};
use crate::toggle_lists::{Column, ListBlock, ToggleLayout};
use froctomap_temporal::varint;

/// The two sets of toggle lists a tile stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ListSet {
    /// Observation masks (the tile's distinct masks).
    Masks,
    /// Outliers of modelled cells and exceptions of nearly constant ones (format 1.2:
    /// outliers of modelled cells only).
    Outliers,
    /// Format 1.2: exceptions of nearly constant cells, range coded.
    Exceptions,
}

/// One stream of a tile payload.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Stream {
    /// Gaps between cells (varints).
    Geometry,
    /// One depth byte per cell.
    Depth,
    /// One class byte per cell.
    Class,
    /// The number of distinct masks (a varint).
    MaskCount,
    /// The mask index of each masked cell (varints).
    MaskRefs,
    /// The model parameters of the modelled cells.
    Models,
    /// A column of a set of toggle lists.
    List(ListSet, Column),
}

use Column::{Code, Counts, Lengths, Lists, Parity, Starts};
use ListSet::{Exceptions, Masks, Outliers};
use Stream::{Class, Depth, Geometry, List, MaskCount, MaskRefs, Models};

/// The parts a tile payload is made of. Format 1.0 has one part; format 1.1 a part with
/// the cells, then one part per toggle block with that block's lists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PartKind {
    /// Format 1.0: the cells with their whole lists.
    Whole,
    /// Format 1.1: the cells.
    Cells,
    /// Format 1.1: one toggle block of both list sets.
    Block,
    /// Format 1.2: one toggle block of both list sets, range coded.
    CodedBlock,
}

impl PartKind {
    /// The part holding the cells in a layout.
    pub(crate) fn cells_of(layout: ToggleLayout) -> Self {
        match layout {
            ToggleLayout::Whole => PartKind::Whole,
            ToggleLayout::Blocked(_) | ToggleLayout::Coded(_) => PartKind::Cells,
        }
    }

    /// The parts holding toggle blocks in a blocked layout.
    pub(crate) fn block_of(layout: ToggleLayout) -> Self {
        match layout {
            ToggleLayout::Coded(_) => PartKind::CodedBlock,
            ToggleLayout::Whole | ToggleLayout::Blocked(_) => PartKind::Block,
        }
    }

    /// The part's streams in file order.
    pub(crate) const fn streams(self) -> &'static [Stream] {
        match self {
            PartKind::Whole => &[
                Geometry,
                Depth,
                Class,
                MaskCount,
                MaskRefs,
                List(Masks, Counts),
                List(Masks, Starts),
                List(Masks, Lengths),
                Models,
                List(Outliers, Counts),
                List(Outliers, Starts),
                List(Outliers, Lengths),
            ],
            PartKind::Cells => &[Geometry, Depth, Class, MaskCount, MaskRefs, Models],
            PartKind::Block => &[
                List(Masks, Parity),
                List(Masks, Lists),
                List(Masks, Counts),
                List(Masks, Starts),
                List(Masks, Lengths),
                List(Outliers, Parity),
                List(Outliers, Lists),
                List(Outliers, Counts),
                List(Outliers, Starts),
                List(Outliers, Lengths),
            ],
            PartKind::CodedBlock => &[
                List(Masks, Parity),
                List(Masks, Lists),
                List(Masks, Counts),
                List(Masks, Starts),
                List(Masks, Lengths),
                List(Outliers, Parity),
                List(Outliers, Lists),
                List(Outliers, Counts),
                List(Outliers, Starts),
                List(Outliers, Lengths),
                List(Exceptions, Code),
            ],
        }
    }

    /// `true` for the parts of one toggle block.
    pub(crate) fn is_block(self) -> bool {
        matches!(self, PartKind::Block | PartKind::CodedBlock)
    }

    /// What errors call the part.
    fn name(self) -> &'static str {
        match self {
            PartKind::Whole | PartKind::Cells => "tile",
            PartKind::Block | PartKind::CodedBlock => "tile block",
        }
    }
}

/// Most streams in one part.
const MAX_PART_STREAMS: usize = 12;
const _: () = assert!(PartKind::CodedBlock.streams().len() <= MAX_PART_STREAMS);

impl Stream {
    /// The name size analysis reports the stream by.
    pub(crate) fn name(self) -> &'static str {
        let column = |column, names: [&'static str; 6]| match column {
            Parity => names[0],
            Lists => names[1],
            Counts => names[2],
            Starts => names[3],
            Lengths => names[4],
            Code => names[5],
        };
        match self {
            Geometry => "geometry",
            Depth => "depth",
            Class => "class",
            MaskCount => "mask count",
            MaskRefs => "mask refs",
            Models => "models",
            List(Masks, c) => column(
                c,
                [
                    "mask parity",
                    "mask lists",
                    "mask counts",
                    "mask starts",
                    "mask lengths",
                    "mask code",
                ],
            ),
            List(Outliers, c) => column(
                c,
                [
                    "outlier parity",
                    "outlier lists",
                    "outlier counts",
                    "outlier starts",
                    "outlier lengths",
                    "outlier code",
                ],
            ),
            List(Exceptions, _) => "exception code",
        }
    }
}

/// Writes a part: the cell count where the part has one, then each stream of `kind` in
/// file order with its length.
pub(crate) fn write_part<'s>(
    kind: PartKind,
    cell_count: usize,
    stream: impl Fn(Stream) -> &'s [u8],
) -> Vec<u8> {
    let mut out = Vec::new();
    if !kind.is_block() {
        varint::write_u64(&mut out, cell_count as u64);
    }
    for &name in kind.streams() {
        let bytes = stream(name);
        varint::write_u64(&mut out, bytes.len() as u64);
        out.extend_from_slice(bytes);
    }
    out
}

/// The streams of one part as read from a tile.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PartStreams<'a> {
    kind: PartKind,
    streams: [&'a [u8]; MAX_PART_STREAMS],
}

impl<'a> PartStreams<'a> {
    /// Takes a part's streams (after its cell count) from the cursor.
    pub(crate) fn take(c: &mut Cursor<'a>, kind: PartKind) -> Result<Self, FormatViolation> {
        let mut streams = [&[][..]; MAX_PART_STREAMS];
        for slot in streams.iter_mut().take(kind.streams().len()) {
            let len = c.count("stream length", u64::MAX, 1)?;
            *slot = c.take(len)?;
        }
        Ok(Self { kind, streams })
    }

    /// Reads a whole part: its cell count (checked against `max_cells`) where it has one,
    /// and its streams, which must end where the bytes do.
    pub(crate) fn read(
        bytes: &'a [u8],
        kind: PartKind,
        max_cells: u64,
    ) -> Result<(usize, Self), FormatViolation> {
        let mut c = Cursor::new(bytes, kind.name());
        let count = match kind {
            PartKind::Block | PartKind::CodedBlock => 0,
            PartKind::Whole | PartKind::Cells => c.count("cells per tile", max_cells, 1)?,
        };
        let part = Self::take(&mut c, kind)?;
        if !c.is_empty() {
            return Err(corrupt(kind.name(), "bytes after the last stream"));
        }
        Ok((count, part))
    }

    /// A stream of the part (empty when the part has no such stream).
    pub(crate) fn get(&self, stream: Stream) -> &'a [u8] {
        self.kind
            .streams()
            .iter()
            .position(|&s| s == stream)
            .map_or(&[], |i| self.streams[i])
    }

    /// The part's streams with their names, in file order.
    pub(crate) fn named(&self) -> impl Iterator<Item = (Stream, &'a [u8])> + '_ {
        self.kind.streams().iter().copied().zip(self.streams)
    }

    /// The block of a list set this part holds, starting at sample `start`.
    pub(crate) fn list_block(&self, set: ListSet, start: u32) -> ListBlock<'a> {
        ListBlock {
            start,
            parity: self.get(List(set, Parity)),
            present: self.kind.is_block().then(|| self.get(List(set, Lists))),
            columns: [Counts, Starts, Lengths].map(|c| self.get(List(set, c))),
            code: self.get(List(set, Code)),
        }
    }
}

/// A tile's decoded payload as a walk reads it.
pub(crate) struct TileParts<'a> {
    /// Format 1.0: the whole payload. Format 1.1: the cell part.
    pub(crate) cells: &'a [u8],
    /// Format 1.1: the block parts a walk needs, with their indices, in block order.
    pub(crate) blocks: Vec<(u32, PartStreams<'a>)>,
}

impl TileParts<'_> {
    /// The streams by name, copied out (a list set's streams of one kind joined over the
    /// blocks), in file order of their first appearance.
    pub(crate) fn named_streams(
        &self,
        layout: ToggleLayout,
    ) -> Result<Vec<(&'static str, Vec<u8>)>, FormatViolation> {
        let (_, cells) = PartStreams::read(self.cells, PartKind::cells_of(layout), u64::MAX)?;
        let mut named: Vec<(&'static str, Vec<u8>)> = Vec::new();
        let parts = std::iter::once(&cells).chain(self.blocks.iter().map(|(_, part)| part));
        for (stream, bytes) in parts.flat_map(PartStreams::named) {
            let name = stream.name();
            match named.iter_mut().find(|n| n.0 == name) {
                Some(entry) => entry.1.extend_from_slice(bytes),
                None => named.push((name, bytes.to_vec())),
            }
        }
        Ok(named)
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

    /// Counts the streams of a part as written.
    pub(crate) fn add_part<'s>(&mut self, kind: PartKind, stream: impl Fn(Stream) -> &'s [u8]) {
        for &name in kind.streams() {
            let len = stream(name).len() as u64;
            *match name {
                Geometry => &mut self.geometry,
                Depth => &mut self.depth,
                Class => &mut self.class,
                MaskCount | MaskRefs | List(Masks, _) => &mut self.masks,
                Models => &mut self.models,
                List(Outliers | Exceptions, _) => &mut self.outliers,
            } += len;
        }
    }
}
