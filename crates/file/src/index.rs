//! The tile index and the footer ([FORMAT.md §2.3, §7](../../../docs/FORMAT.md)).

use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation};
use crate::header::{push_section, Sections, END_MAGIC};
use crate::limits::ReadLimits;
use froctomap_core::{voxels_per_node, MortonCode};
use serde_json::{Map, Value};

/// Bytes of the footer.
pub const FOOTER_LEN: usize = 32;
/// Bytes of one tile entry.
pub const TILE_ENTRY_LEN: usize = 40;
pub(crate) const TAG_SUMMARY: u16 = 0x0101;

/// Where a tile is and what it holds, as listed in the index.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileEntry {
    /// Morton code of the tile's first voxel.
    pub code: MortonCode,
    /// File offset of the stored bytes.
    pub offset: u64,
    /// Stored length.
    pub stored_len: u32,
    /// Payload length after decoding.
    pub raw_len: u32,
    /// crc32c of the stored bytes.
    pub crc: u32,
    /// Cells in the tile.
    pub cell_count: u32,
    /// No cell of the tile is observed before this sample.
    pub first_sample: u32,
    /// No cell of the tile is observed after this sample.
    pub last_sample: u32,
}

impl TileEntry {
    /// `true` when some cell of the tile may be observed at `sample`.
    pub fn may_observe(&self, sample: u32) -> bool {
        (self.first_sample..=self.last_sample).contains(&sample)
    }
}

pub(crate) fn encode_index(entries: &[TileEntry], summary: &Map<String, Value>) -> Vec<u8> {
    let mut out = Vec::with_capacity(4 + entries.len() * TILE_ENTRY_LEN);
    out.extend((entries.len() as u32).to_le_bytes());
    for e in entries {
        out.extend(e.code.0.to_le_bytes());
        out.extend(e.offset.to_le_bytes());
        for value in [
            e.stored_len,
            e.raw_len,
            e.crc,
            e.cell_count,
            e.first_sample,
            e.last_sample,
        ] {
            out.extend(value.to_le_bytes());
        }
    }
    if !summary.is_empty() {
        let json = Value::Object(summary.clone()).to_string();
        push_section(&mut out, TAG_SUMMARY, false, json.as_bytes());
    }
    out
}

/// Decodes the index; `data` is the byte range tiles may occupy.
pub(crate) fn decode_index(
    bytes: &[u8],
    data: std::ops::Range<u64>,
    tile_depth: u8,
    limits: &ReadLimits,
) -> Result<(Vec<TileEntry>, Map<String, Value>), FormatViolation> {
    let (entries, summary, _) = decode_index_with(bytes, data, tile_depth, limits, &[TAG_SUMMARY])?;
    Ok((entries, summary))
}

/// Decodes the index as [`decode_index`], accepting the sections tagged `known` (the
/// summary's and others, each of those at most once, whose payloads it returns with their
/// tags).
pub(crate) fn decode_index_with<'a>(
    bytes: &'a [u8],
    data: std::ops::Range<u64>,
    tile_depth: u8,
    limits: &ReadLimits,
    known: &'static [u16],
) -> Result<IndexParts<'a>, FormatViolation> {
    let mut c = Cursor::new(bytes, "index");
    let count = u64::from(c.u32()?);
    let count = c.check_count("tile count", count, limits.max_tiles, TILE_ENTRY_LEN)?;
    let tile_size = voxels_per_node(tile_depth);
    let mut entries: Vec<TileEntry> = Vec::with_capacity(count);
    let mut next_free = data.start;
    // Checked here so that no reader sizes anything by a count it has not bounded.
    let mut total_cells = 0u64;
    for _ in 0..count {
        let entry = TileEntry {
            code: MortonCode(c.u64()?),
            offset: c.u64()?,
            stored_len: c.u32()?,
            raw_len: c.u32()?,
            crc: c.u32()?,
            cell_count: c.u32()?,
            first_sample: c.u32()?,
            last_sample: c.u32()?,
        };
        if entry.code.0 >= MortonCode::END || entry.code.0 % tile_size != 0 {
            return Err(corrupt(
                "index",
                format!(
                    "tile code {:#x} is not a depth-{tile_depth} node",
                    entry.code.0
                ),
            ));
        }
        if entries.last().is_some_and(|p| p.code >= entry.code) {
            return Err(corrupt("index", "tile codes are not strictly increasing"));
        }
        let end = entry.offset.checked_add(u64::from(entry.stored_len));
        if entry.offset < next_free || end.is_none_or(|end| end > data.end) {
            return Err(corrupt(
                "index",
                format!("tile {:#x} has an impossible location", entry.code.0),
            ));
        }
        for (what, value) in [
            ("stored tile length", entry.stored_len),
            ("decoded tile length", entry.raw_len),
        ] {
            if u64::from(value) > limits.max_tile_bytes {
                return Err(FormatViolation::Limit {
                    what,
                    value: u64::from(value),
                    limit: limits.max_tile_bytes,
                });
            }
        }
        if entry.cell_count == 0 || entry.first_sample > entry.last_sample {
            return Err(corrupt(
                "index",
                format!(
                    "tile {:#x} has an impossible cell count or sample range",
                    entry.code.0
                ),
            ));
        }
        // Every cell has a depth byte and a class byte in the decoded payload.
        if u64::from(entry.cell_count) * 2 > u64::from(entry.raw_len) {
            return Err(corrupt(
                "index",
                format!(
                    "tile {:#x} claims more cells than its decoded length can hold",
                    entry.code.0
                ),
            ));
        }
        let cells = u64::from(entry.cell_count);
        if cells > limits.max_cells_per_tile {
            return Err(FormatViolation::Limit {
                what: "cells per tile",
                value: cells,
                limit: limits.max_cells_per_tile,
            });
        }
        // Cells are disjoint and lie inside the tile: at most one per voxel.
        if cells > tile_size {
            return Err(corrupt(
                "index",
                format!(
                    "tile {:#x} claims {} cells; a depth-{tile_depth} tile holds at most {tile_size}",
                    entry.code.0, cells
                ),
            ));
        }
        total_cells += cells;
        if total_cells > limits.max_total_cells {
            return Err(FormatViolation::Limit {
                what: "cells in the file",
                value: total_cells,
                limit: limits.max_total_cells,
            });
        }
        next_free = end.unwrap_or(data.end);
        entries.push(entry);
    }
    let mut summary = Map::new();
    let mut found: Vec<(u16, &[u8])> = Vec::new();
    let rest = c.take(c.remaining())?;
    for section in Sections::with_known(rest, "index", known) {
        let section = section?;
        if section.tag == TAG_SUMMARY {
            summary = match serde_json::from_slice(section.payload) {
                Ok(Value::Object(object)) => object,
                _ => return Err(corrupt("index summary", "not a JSON object")),
            };
        } else if found.iter().any(|(tag, _)| *tag == section.tag) {
            return Err(corrupt(
                "index",
                format!("section {} appears twice", section.tag),
            ));
        } else {
            found.push((section.tag, section.payload));
        }
    }
    Ok((entries, summary, found))
}

/// A decoded index: its tiles, its summary and the payloads of the extra sections asked for.
pub(crate) type IndexParts<'a> = (Vec<TileEntry>, Map<String, Value>, Vec<(u16, &'a [u8])>);

/// Tag of a segment record's *patch tiles* section (FORMAT.md §10.3, critical).
pub(crate) const TAG_PATCH_TILES: u16 = 0x0201;
/// Tag of a segment record's *remainder masks* section (FORMAT.md §10.7, critical): patch
/// tiles whose remainder more than one mask observes.
pub(crate) const TAG_REMAINDER_MASKS: u16 = 0x0202;

pub(crate) fn encode_footer(index_offset: u64, index: &[u8]) -> [u8; FOOTER_LEN] {
    let mut out = [0u8; FOOTER_LEN];
    out[0..8].copy_from_slice(&index_offset.to_le_bytes());
    out[8..16].copy_from_slice(&(index.len() as u64).to_le_bytes());
    out[16..20].copy_from_slice(&crc32c::crc32c(index).to_le_bytes());
    let crc = crc32c::crc32c(&out[0..20]);
    out[20..24].copy_from_slice(&crc.to_le_bytes());
    out[24..32].copy_from_slice(&END_MAGIC);
    out
}

/// Index location and checksum from the footer.
pub(crate) struct Footer {
    pub(crate) index_offset: u64,
    pub(crate) index_len: u64,
    pub(crate) index_crc: u32,
}

pub(crate) fn decode_footer(
    bytes: &[u8; FOOTER_LEN],
    file_len: u64,
    data_start: u64,
    limits: &ReadLimits,
) -> Result<Footer, FormatViolation> {
    if bytes[24..32] != END_MAGIC {
        return Err(corrupt(
            "footer",
            "the end magic is missing (truncated or not a FROctomap file)",
        ));
    }
    let mut c = Cursor::new(bytes, "footer");
    let index_offset = c.u64()?;
    let index_len = c.u64()?;
    let index_crc = c.u32()?;
    let footer_crc = c.u32()?;
    if crc32c::crc32c(&bytes[0..20]) != footer_crc {
        return Err(FormatViolation::Checksum("footer"));
    }
    if index_len > limits.max_index_bytes {
        return Err(FormatViolation::Limit {
            what: "index length",
            value: index_len,
            limit: limits.max_index_bytes,
        });
    }
    let footer_start = file_len - FOOTER_LEN as u64;
    if index_offset < data_start || index_offset.checked_add(index_len) != Some(footer_start) {
        return Err(corrupt(
            "footer",
            "the index location does not fit the file",
        ));
    }
    Ok(Footer {
        index_offset,
        index_len,
        index_crc,
    })
}
