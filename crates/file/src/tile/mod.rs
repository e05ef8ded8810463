//! Tiles: groups of cells stored and checksummed together ([FORMAT.md §5](../../../docs/FORMAT.md)).
//!
//! A tile's payload is a set of streams ([`streams`]: their names and order in one place),
//! stored in parts: one in format 1.0, the cells and one per toggle block in 1.1, those
//! grouped into compressed frames ([`frames`]). [`encode`] builds them from [`Cell`]s,
//! [`walk`] reads them back; [`model`] is the one place a cell's temporal model is touched.

mod cell;
mod encode;
mod frames;
mod model;
mod streams;
mod walk;

pub use cell::{mask_from_ranges, Cell, CellContent};
pub use encode::{encode_tile, EncodedTile, TileStreamEncoder};
pub(crate) use frames::{block_parts, decode_frame, frame_table};
pub use streams::StreamSizes;
pub(crate) use streams::{PartKind, TileParts};
pub(crate) use walk::{visit_payload_cells, walk_payload, CellRef, WalkNeed};

// A cell's class byte: its kind in the low bits, then flags.
const CLASS_FREE: u8 = 0;
const CLASS_OCCUPIED: u8 = 1;
const CLASS_MODELLED: u8 = 2;
const CLASS_KIND_MASK: u8 = 0b11;
const CLASS_HAS_MASK: u8 = 0b100;
const CLASS_HAS_OUTLIERS: u8 = 0b1000;
