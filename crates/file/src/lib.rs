//! The FROctomap file: one file for a whole series of occupancy maps of one place.
//!
//! The normative specification is [`docs/FORMAT.md`](../../../docs/FORMAT.md). In short: a
//! versioned, checksummed header (resolution, time axis, temporal model, codec, JSON
//! metadata); then *tiles* — octree nodes at a fixed depth — each holding its *cells*
//! (cubes of voxels that share their state at every sample) as zstd-compressed columnar
//! streams, their toggle lists (observation masks, outliers) cut into blocks of samples
//! (version 1.1, [`ToggleLayout`]) so that the map at one sample decodes the cells and one
//! block; then an index of tiles (offset, length, crc32c, cell count, sample range) and a
//! fixed-size footer. A writer streams tiles out in one pass; a reader opens a file by
//! reading only header, footer and index, and decodes any tile on its own.
//!
//! A reader reads its bytes from a [`ByteSource`]: a file ([`FroctReader::open`]), memory
//! ([`FroctReader::from_bytes`]) or anything that serves byte ranges
//! ([`FroctReader::from_source`]). A writer takes only [`EncodedTile`]s made by
//! [`encode_tile`] (or cell by cell, [`TileStreamEncoder`]) and seals them itself
//! (checksums of the bytes it writes).
//!
//! Format 2.0 grows by commits ([`LivingWriter`], [`LivingReader`]): the body above becomes
//! the *base*, each commit appends a *segment* (the cells its maps observed, over its own
//! samples) and then rewrites one of two checksummed root slots; one writer at a time holds
//! the file's lock, and readers see the root they opened until they refresh.
//!
//! Cells that never changed cost a class byte. Cells that changed carry a temporal model
//! from `froctomap-temporal`, with its outlier set in lossless files, so every observed state
//! is reproduced exactly. Unknown stays unknown: each cell has an observation mask unless it
//! was observed at every sample.
//!
//! ```
//! use froctomap_core::{Occupancy, Timestamp, VoxelKey};
//! use froctomap_file::*;
//! use froctomap_temporal::{ModelConfig, ModelRegistry, ObservationsBuilder, TimeAxis};
//!
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("door.froct");
//! let axis = TimeAxis::regular(Timestamp::from_secs(0), 600_000_000_000, 6, vec![])?;
//! let model = ModelRegistry::with_default_models().by_name("fremen-periods").unwrap().create();
//! let prepared = model.prepare(&axis, &ModelConfig::default())?;
//!
//! // A door voxel that opens and closes, and a wall voxel that never changes.
//! let mut door = ObservationsBuilder::new();
//! for (i, open) in [false, true, true, false, false, true].into_iter().enumerate() {
//!     door.push(i as u32, Some(Occupancy::from(!open)))?;
//! }
//! let cells = vec![
//!     Cell { start: VoxelKey::new(32768, 32768, 32768).morton(), depth: 16, mask: None,
//!            content: CellContent::Modelled(prepared.fit(&door.finish())?) },
//!     Cell { start: VoxelKey::new(32769, 32768, 32768).morton(), depth: 16, mask: None,
//!            content: CellContent::Constant(Occupancy::Occupied) },
//! ];
//! let header = Header::new(0.05, 10, axis, model.id(), prepared.encode_parameters(), Codec::default());
//! let mut writer = FroctWriter::create(&path, &header)?;
//! writer.write_tile(&encode_tile(&header.tile_layout(), &cells, prepared.as_ref())?)?;
//! writer.finish(Default::default())?;
//!
//! let reader = FroctReader::open(&path)?;
//! // The map at sample 1, tile by tile (`froctomap_convert::observed_map` does it for a whole
//! // file, tiles in parallel).
//! let mut leaves = Vec::new();
//! reader.observed_leaves(0, 1, &mut leaves)?;
//! let map = froctomap_core::Snapshot::from_leaves(0.05, leaves)?;
//! assert_eq!(map.state_at(VoxelKey::new(32768, 32768, 32768).morton()), Some(Occupancy::Free));
//! assert_eq!(reader.read_tile(0)?, cells);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod cursor;
mod error;
mod header;
mod index;
mod layout;
mod limits;
mod living;
mod query;
mod range_coder;
mod reader;
mod root;
mod segment;
mod source;
mod tile;
mod toggle_code;
mod toggle_lists;
mod writer;

pub use error::{FileError, FormatViolation, HeaderError, TileEncodeError};
pub use header::{
    encode_axis, Header, END_MAGIC, MAGIC, MAJOR_VERSION, MINOR_VERSION, PREAMBLE_LEN,
};
pub use index::{TileEntry, FOOTER_LEN, TILE_ENTRY_LEN};
pub use layout::{Codec, TileLayout};
pub use limits::ReadLimits;
pub use living::{CellState, LivingReader, LivingWriter, SegmentWriter};
pub use query::CellValue;
pub use reader::{CellClass, FroctReader, FrozenPrediction};
pub use root::{Root, LIVING_MAJOR_VERSION, LIVING_MINOR_VERSION, ROOT_SLOTS_AT, ROOT_SLOT_LEN};
pub use segment::{
    RemainderMask, RemainderRun, SegmentCell, SegmentContent, SegmentTileEncoder, TileRemainder,
    SEGMENT_MAGIC, SEGMENT_ZSTD_LEVEL,
};
pub use source::{ByteSource, FileSource, MemorySource, SeekSource};
pub use tile::{
    encode_tile, mask_from_ranges, Cell, CellContent, EncodedTile, StreamSizes, TileStreamEncoder,
};
pub use toggle_lists::ToggleLayout;
pub use writer::{FroctWriter, WrittenFile};
