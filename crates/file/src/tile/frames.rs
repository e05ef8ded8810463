//! How a tile's payload parts are stored: compressed by the file's codec, and in format
//! 1.1 grouped into frames behind a frame table ([FORMAT.md §5.1](../../../docs/FORMAT.md)).

use super::streams::{PartKind, PartStreams};
use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation, TileEncodeError};
use crate::layout::Codec;
use froctomap_temporal::varint;
use rayon::prelude::*;

/// Raw bytes after which a frame of block parts is closed (format 1.1): frames of a few
/// kilobytes cost zstd's tables many times over, frames of many blocks make a query at one
/// sample decompress blocks it does not read.
const BLOCK_FRAME_BYTES: usize = 32 * 1024;

/// One part (or frame) as the codec stores it.
pub(crate) fn compress(part: Vec<u8>, codec: Codec) -> Result<Vec<u8>, TileEncodeError> {
    match codec {
        Codec::Raw => Ok(part),
        Codec::Zstd { level } => {
            zstd::bulk::compress(&part, i32::from(level)).map_err(TileEncodeError::Compression)
        }
    }
}

/// The stored bytes of a format 1.1 tile from its parts (the cell part, then one part per
/// block): consecutive block parts share a frame until it holds [`BLOCK_FRAME_BYTES`], so
/// small tiles pay zstd's per-frame tables once and large ones keep a frame per block.
/// Layout as [`frame_table`] reads it.
pub(crate) fn store_frames(parts: Vec<Vec<u8>>, codec: Codec) -> Result<Vec<u8>, TileEncodeError> {
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
    // In parallel: a large tile of a long series has hundreds of frames, and compressing
    // them one after another left the other cores idle once the fits beside it were done.
    let frames = raw_parts
        .into_par_iter()
        .map(|part| compress(part, codec))
        .collect::<Result<Vec<_>, _>>()?;
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
    Ok(stored)
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
        stored_lens.push(c.count("frame length", u64::MAX, 1)?);
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
    let block_ends = block_ends(&mut c, count, blocks)?;
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

/// The block counts of `frames − 1` block frames, as running ends that must reach `blocks`.
fn block_ends(c: &mut Cursor<'_>, frames: usize, blocks: u32) -> Result<Vec<u32>, FormatViolation> {
    let mut block_ends = Vec::with_capacity(frames - 1);
    let mut end = 0u64;
    for _ in 1..frames {
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
    Ok(block_ends)
}

/// The `count` block parts (of `kind`) a decoded frame holds, in order.
pub(crate) fn block_parts(
    frame: &[u8],
    count: usize,
    kind: PartKind,
) -> Result<Vec<PartStreams<'_>>, FormatViolation> {
    let mut c = Cursor::new(frame, "tile block");
    let mut parts = Vec::with_capacity(count.min(frame.len()));
    for _ in 0..count {
        parts.push(PartStreams::take(&mut c, kind)?);
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

    #[test]
    fn stored_frames_read_back() {
        let parts = vec![vec![1u8, 2, 3], vec![4], vec![5, 6]];
        let stored = store_frames(parts, Codec::Raw).unwrap();
        let table = frame_table(&stored, 2, 6).unwrap();
        assert_eq!(
            table.frames,
            vec![(&[1u8, 2, 3][..], 3), (&[4u8, 5, 6][..], 3)]
        );
        assert_eq!(table.blocks_in(1), 2);
    }
}
