//! Hostile files made on purpose: a raw (uncompressed) file's tiles taken apart into their
//! streams (FORMAT.md §5), one stream changed, and the file put back together with every
//! length, offset and checksum recomputed, so that the change reaches the tile parser.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use froctomap_file::{ToggleLayout, FOOTER_LEN, TILE_ENTRY_LEN};
use froctomap_temporal::varint;

/// Streams of the cell part (FORMAT.md §5.2).
pub const GEOMETRY: usize = 0;
pub const DEPTH: usize = 1;
pub const CLASS: usize = 2;
/// Streams of a 1.0 tile's single part: the outliers' columns.
pub const WHOLE_OUTLIER_COUNTS: usize = 9;
pub const WHOLE_OUTLIER_STARTS: usize = 10;
pub const WHOLE_OUTLIER_LENGTHS: usize = 11;
/// Streams of a block part (1.1, 1.2): the outliers' columns.
pub const BLOCK_OUTLIER_COUNTS: usize = 7;
pub const BLOCK_OUTLIER_STARTS: usize = 8;
pub const BLOCK_OUTLIER_LENGTHS: usize = 9;
/// The class flag of a cell with outliers (or exceptions).
pub const CLASS_HAS_OUTLIERS: u8 = 0b1000;

/// One raw tile's parts, each a list of streams.
#[derive(Clone, Debug, PartialEq)]
pub struct RawTile {
    pub cell_count: u64,
    /// The cell part (1.0: the only part).
    pub cells: Vec<Vec<u8>>,
    /// Per frame of blocks, its block parts (1.1, 1.2).
    pub frames: Vec<Vec<Vec<Vec<u8>>>>,
}

impl RawTile {
    /// Every block part in block order.
    pub fn blocks_mut(&mut self) -> impl Iterator<Item = &mut Vec<Vec<u8>>> {
        self.frames.iter_mut().flatten()
    }
}

struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn varint(&mut self) -> u64 {
        let (value, used) = varint::read_u64(self.0).unwrap();
        self.0 = &self.0[used..];
        value
    }

    fn take(&mut self, len: usize) -> Vec<u8> {
        let (taken, rest) = self.0.split_at(len);
        self.0 = rest;
        taken.to_vec()
    }

    fn streams(&mut self, count: usize) -> Vec<Vec<u8>> {
        (0..count)
            .map(|_| {
                let len = self.varint() as usize;
                self.take(len)
            })
            .collect()
    }
}

fn block_streams(toggles: ToggleLayout) -> usize {
    match toggles {
        ToggleLayout::Coded(_) => 11,
        _ => 10,
    }
}

fn write_streams(out: &mut Vec<u8>, streams: &[Vec<u8>]) {
    for stream in streams {
        varint::write_u64(out, stream.len() as u64);
        out.extend_from_slice(stream);
    }
}

/// Takes a raw tile's stored bytes apart.
pub fn parse_tile(stored: &[u8], toggles: ToggleLayout) -> RawTile {
    if toggles == ToggleLayout::Whole {
        let mut r = Reader(stored);
        let cell_count = r.varint();
        let cells = r.streams(12);
        assert!(r.0.is_empty());
        return RawTile {
            cell_count,
            cells,
            frames: Vec::new(),
        };
    }
    let mut r = Reader(stored);
    let count = r.varint() as usize;
    let stored_lens: Vec<usize> = (0..count).map(|_| r.varint() as usize).collect();
    let _raw_lens: Vec<u64> = (0..count).map(|_| r.varint()).collect();
    let block_counts: Vec<usize> = (1..count).map(|_| r.varint() as usize).collect();
    let frames: Vec<Vec<u8>> = stored_lens.iter().map(|&len| r.take(len)).collect();
    assert!(r.0.is_empty());
    let mut cell_part = Reader(&frames[0]);
    let cell_count = cell_part.varint();
    let cells = cell_part.streams(6);
    assert!(cell_part.0.is_empty());
    let frames = frames[1..]
        .iter()
        .zip(block_counts)
        .map(|(frame, blocks)| {
            let mut r = Reader(frame);
            let parts = (0..blocks)
                .map(|_| r.streams(block_streams(toggles)))
                .collect();
            assert!(r.0.is_empty());
            parts
        })
        .collect();
    RawTile {
        cell_count,
        cells,
        frames,
    }
}

/// A raw tile's stored bytes and its decoded length (its frames' bytes: the codec is raw).
pub fn encode_tile(tile: &RawTile) -> (Vec<u8>, usize) {
    let mut cells = Vec::new();
    varint::write_u64(&mut cells, tile.cell_count);
    write_streams(&mut cells, &tile.cells);
    if tile.frames.is_empty() {
        let len = cells.len();
        return (cells, len);
    }
    let mut frames = vec![cells];
    for parts in &tile.frames {
        let mut frame = Vec::new();
        for part in parts {
            write_streams(&mut frame, part);
        }
        frames.push(frame);
    }
    let mut out = Vec::new();
    varint::write_u64(&mut out, frames.len() as u64);
    for _lens in 0..2 {
        for frame in &frames {
            varint::write_u64(&mut out, frame.len() as u64);
        }
    }
    for parts in &tile.frames {
        varint::write_u64(&mut out, parts.len() as u64);
    }
    let raw_len = frames.iter().map(Vec::len).sum();
    for frame in frames {
        out.extend(frame);
    }
    (out, raw_len)
}

fn le32(b: &[u8]) -> usize {
    u32::from_le_bytes(b.try_into().unwrap()) as usize
}

fn le64(b: &[u8]) -> usize {
    u64::from_le_bytes(b.try_into().unwrap()) as usize
}

/// The tiles of a raw file, taken apart.
pub fn tiles_of(bytes: &[u8], toggles: ToggleLayout) -> Vec<RawTile> {
    let footer = bytes.len() - FOOTER_LEN;
    let index = le64(&bytes[footer..footer + 8]);
    let count = le32(&bytes[index..index + 4]);
    (0..count)
        .map(|t| {
            let entry = index + 4 + t * TILE_ENTRY_LEN;
            let offset = le64(&bytes[entry + 8..entry + 16]);
            let stored = le32(&bytes[entry + 16..entry + 20]);
            parse_tile(&bytes[offset..offset + stored], toggles)
        })
        .collect()
}

/// The raw file `bytes` with its tiles replaced by `tiles` (same count, same order): the
/// header and the index's other fields kept, every offset, length and checksum recomputed.
pub fn with_tiles(bytes: &[u8], tiles: &[RawTile]) -> Vec<u8> {
    let footer = bytes.len() - FOOTER_LEN;
    let index = le64(&bytes[footer..footer + 8]);
    let index_len = le64(&bytes[footer + 8..footer + 16]);
    let mut index_bytes = bytes[index..index + index_len].to_vec();
    assert_eq!(le32(&index_bytes[..4]), tiles.len());
    let first = le64(&index_bytes[4 + 8..4 + 16]);
    let mut out = bytes[..first].to_vec();
    for (t, tile) in tiles.iter().enumerate() {
        let (stored, raw_len) = encode_tile(tile);
        let entry = 4 + t * TILE_ENTRY_LEN;
        index_bytes[entry + 8..entry + 16].copy_from_slice(&(out.len() as u64).to_le_bytes());
        let stored_len = (stored.len() as u32).to_le_bytes();
        index_bytes[entry + 16..entry + 20].copy_from_slice(&stored_len);
        index_bytes[entry + 20..entry + 24].copy_from_slice(&(raw_len as u32).to_le_bytes());
        out.extend(stored);
    }
    let index_offset = out.len() as u64;
    out.extend(&index_bytes);
    let mut tail = bytes[footer..].to_vec();
    tail[0..8].copy_from_slice(&index_offset.to_le_bytes());
    out.extend(tail);
    super::reseal(&mut out);
    out
}

/// `stream` with its `k`-th varint replaced by `value` (`None` when it has fewer).
pub fn with_varint(stream: &[u8], k: usize, value: u64) -> Option<Vec<u8>> {
    let mut at = 0;
    for _ in 0..k {
        at += varint::read_u64(stream.get(at..)?).ok()?.1;
    }
    let (_, used) = varint::read_u64(stream.get(at..)?).ok()?;
    let mut out = stream[..at].to_vec();
    varint::write_u64(&mut out, value);
    out.extend_from_slice(&stream[at + used..]);
    Some(out)
}
