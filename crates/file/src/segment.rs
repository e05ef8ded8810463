//! Segments of a format 2.0 file ([FORMAT.md §10.3](../../../docs/FORMAT.md)): the cells a
//! commit adds over its own samples, in tiles laid out as the base's, and the record that
//! locates them (axis piece, tile index, previous segment).

use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation, TileEncodeError};
use crate::header::push_section;
use crate::header::{decode_axis, encode_axis};
use crate::index::{decode_index_with, encode_index, TileEntry, TAG_PATCH_TILES, TAG_SUMMARY};
use crate::layout::{Codec, TileLayout};
use crate::limits::ReadLimits;
use crate::source::ByteSource;
use crate::tile::{Cell, CellContent, EncodedTile, TileStreamEncoder};
use froctomap_core::{MortonCode, Occupancy};
use froctomap_temporal::{
    varint, FittedVoxel, ModelId, OutlierMode, PreparedModel, TemporalError, TimeAxis, Toggles,
    VoxelDescription, VoxelObservations,
};
use serde_json::Map;
use std::sync::Arc;

/// First bytes of a segment record.
pub const SEGMENT_MAGIC: [u8; 8] = *b"FROCTSEG";
/// Bytes of a segment record before its body: magic, previous record, first sample, body
/// length.
pub(crate) const RECORD_HEAD_LEN: usize = 24;

/// What a segment stores of a cell over the segment's samples.
#[derive(Clone, Debug, PartialEq)]
pub enum SegmentContent {
    /// The frozen prediction of the base cell that contains this cell (its model's
    /// thresholded `p(t)`, or its constant state), flipped at each outlier position.
    Inherited {
        /// Where the state differs from the prediction, as positions in the segment.
        outliers: Toggles,
    },
    /// Observed in this state only, over the segment.
    Constant(Occupancy),
    /// Almost always `state`, flipped at each exception position.
    ConstantExcept {
        /// The usual state.
        state: Occupancy,
        /// Where the state differs from the usual one, as positions in the segment.
        exceptions: Toggles,
    },
}

/// One cell of a segment tile: a cube of voxels that shares its state at every sample of the
/// segment. Positions (mask, outliers, exceptions) count the segment's own samples from 0.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentCell {
    /// Morton code of the first voxel.
    pub start: MortonCode,
    /// Depth (`tile_depth..=16`). An inherited cell lies inside one base cell (it may be
    /// finer than it).
    pub depth: u8,
    /// Observation mask over the segment's samples; `None` means observed at every sample of
    /// the segment that is not missing.
    pub mask: Option<Arc<Toggles>>,
    /// States.
    pub content: SegmentContent,
}

impl SegmentCell {
    fn into_cell(self) -> Cell {
        let content = match self.content {
            SegmentContent::Inherited { outliers } => {
                CellContent::Modelled(FittedVoxel::new(&[], outliers))
            }
            SegmentContent::Constant(state) => CellContent::Constant(state),
            SegmentContent::ConstantExcept { state, exceptions } => {
                CellContent::ConstantExcept { state, exceptions }
            }
        };
        Cell {
            start: self.start,
            depth: self.depth,
            mask: self.mask,
            content,
        }
    }

    pub(crate) fn from_cell(cell: Cell) -> Self {
        let content = match cell.content {
            CellContent::Modelled(voxel) => SegmentContent::Inherited {
                outliers: voxel.toggles().clone(),
            },
            CellContent::Constant(state) => SegmentContent::Constant(state),
            CellContent::ConstantExcept { state, exceptions } => {
                SegmentContent::ConstantExcept { state, exceptions }
            }
        };
        Self {
            start: cell.start,
            depth: cell.depth,
            mask: cell.mask,
            content,
        }
    }
}

/// Encodes one segment tile cell by cell (sorted, non-overlapping, inside one tile), as
/// [`TileStreamEncoder`] does for a base tile: the cells of a segment tile are stored as a
/// base tile's over the segment's samples, an inherited cell as a modelled one without
/// parameters.
pub struct SegmentTileEncoder {
    inner: TileStreamEncoder,
}

/// The zstd level of segment tiles when the file's is higher: a commit compresses what its
/// maps changed while maps arrive, and compaction recompresses at the file's level (the
/// level is informative, FORMAT.md §3.1, so readers do not care). Measured on the segments
/// of an hour of the FR-079 office (`examples/segment_sizes.rs`): level 19 took 4.3 s for
/// 834 kB, level 9 0.29 s for 902 kB (+8 %), level 3 0.06 s for 990 kB (+19 %).
pub const SEGMENT_ZSTD_LEVEL: i8 = 9;

impl SegmentTileEncoder {
    pub(crate) fn new(layout: &TileLayout, axis: &TimeAxis) -> Self {
        let model = InheritedModel::new(axis.clone());
        let codec = match layout.codec {
            Codec::Zstd { level } => Codec::Zstd {
                level: level.min(SEGMENT_ZSTD_LEVEL),
            },
            Codec::Raw => Codec::Raw,
        };
        let layout = TileLayout { codec, ..*layout };
        Self {
            inner: TileStreamEncoder::new(&layout, &model),
        }
    }

    /// Adds the next cell of the tile.
    pub fn push(&mut self, cell: SegmentCell) -> Result<(), TileEncodeError> {
        self.inner.push(&cell.into_cell())
    }

    /// The tile, ready for [`SegmentWriter::write_tile`](crate::SegmentWriter::write_tile).
    pub fn finish(self) -> Result<EncodedTile, TileEncodeError> {
        self.inner.finish()
    }
}

/// The "model" of segment tiles: an inherited cell has no parameters of its own (its
/// prediction is the base cell's, which the segment reader evaluates), so the tile machinery
/// reads an empty parameter block for it and predicts free, leaving the outlier parity.
pub(crate) struct InheritedModel {
    axis: TimeAxis,
}

impl InheritedModel {
    pub(crate) fn new(axis: TimeAxis) -> Self {
        Self { axis }
    }
}

impl PreparedModel for InheritedModel {
    fn id(&self) -> ModelId {
        ModelId(u16::MAX)
    }

    fn axis(&self) -> &TimeAxis {
        &self.axis
    }

    fn outlier_mode(&self) -> OutlierMode {
        OutlierMode::Lossless
    }

    fn fit(&self, _obs: &VoxelObservations) -> Result<FittedVoxel, TemporalError> {
        Err(TemporalError::Unsupported {
            model: "inherited",
            reason: "fitting (segment cells inherit the base cell's model)",
        })
    }

    fn parameters_len(&self, _bytes: &[u8]) -> Result<usize, TemporalError> {
        Ok(0)
    }

    fn probability(&self, _parameters: &[u8], _seconds: f64) -> f64 {
        0.0
    }

    fn probability_at_sample(&self, _parameters: &[u8], _sample: u32) -> f64 {
        0.0
    }

    fn mean(&self, _parameters: &[u8]) -> f64 {
        0.0
    }

    fn is_constant(&self, _parameters: &[u8]) -> bool {
        true
    }

    fn describe(&self, _parameters: &[u8]) -> Result<VoxelDescription, TemporalError> {
        Err(TemporalError::Unsupported {
            model: "inherited",
            reason: "describing (see the base cell's model)",
        })
    }

    fn encode_parameters(&self) -> Vec<u8> {
        Vec::new()
    }
}

/// A segment's record: where its tiles are and which samples it covers.
#[derive(Clone, Debug)]
pub(crate) struct SegmentRecord {
    /// Global index of the segment's first sample.
    pub(crate) first_sample: u32,
    /// The segment's own samples.
    pub(crate) axis: TimeAxis,
    /// The segment's tiles (sample ranges in the segment's samples).
    pub(crate) tiles: Vec<TileEntry>,
    /// Per tile: for a *patch tile*, whose base tile's cells are inherited where its own
    /// cells do not cover them, the observation mask of that remainder (`None` inside: at
    /// every sample that is not missing); `None` for a plain tile.
    pub(crate) patches: Vec<Option<RemainderMask>>,
    /// One past the record's last byte.
    pub(crate) end: u64,
}

/// The observation mask of what a patch tile leaves to the base (`None`: observed at every
/// sample of the segment that is not missing).
pub(crate) type RemainderMask = Option<Arc<Toggles>>;

/// The record's bytes: head, body (axis piece, tile index, and the patch tiles section when
/// `patches`, the indices of the patch tiles in increasing order with their remainder
/// masks, is not empty) and crc.
pub(crate) fn encode_record(
    previous: u64,
    first_sample: u32,
    axis: &TimeAxis,
    tiles: &[TileEntry],
    patches: &[(u32, RemainderMask)],
) -> Result<Vec<u8>, TileEncodeError> {
    let mut body = encode_axis(axis);
    body.extend(encode_index(tiles, &Map::new()));
    if !patches.is_empty() {
        let indices: Vec<u32> = patches.iter().map(|p| p.0).collect();
        let mut payload = encode_runs(&indices);
        for (_, mask) in patches {
            match mask {
                Some(mask) => mask.encode(&mut payload),
                None => Toggles::default().encode(&mut payload),
            }
        }
        push_section(&mut body, TAG_PATCH_TILES, true, &payload);
    }
    let body_len =
        u32::try_from(body.len()).map_err(|_| TileEncodeError::TooLarge("segment index"))?;
    let mut out = Vec::with_capacity(RECORD_HEAD_LEN + body.len() + 4);
    out.extend(SEGMENT_MAGIC);
    out.extend(previous.to_le_bytes());
    out.extend(first_sample.to_le_bytes());
    out.extend(body_len.to_le_bytes());
    out.extend(body);
    let crc = crc32c::crc32c(&out);
    out.extend(crc.to_le_bytes());
    Ok(out)
}

/// A record read and checksummed, its body not yet decoded.
pub(crate) struct RawRecord {
    pub(crate) offset: u64,
    pub(crate) previous: u64,
    pub(crate) first_sample: u32,
    pub(crate) body: Vec<u8>,
}

impl RawRecord {
    pub(crate) fn end(&self) -> u64 {
        self.offset + (RECORD_HEAD_LEN + self.body.len() + 4) as u64
    }

    /// Reads the record at `offset`, which must end at or before `limit`; its body counts
    /// against `budget` (the index bytes the reader still accepts).
    pub(crate) fn read(
        source: &dyn ByteSource,
        offset: u64,
        limit: u64,
        budget: &mut u64,
    ) -> Result<Result<Self, FormatViolation>, std::io::Error> {
        let fits = offset
            .checked_add((RECORD_HEAD_LEN + 4) as u64)
            .is_some_and(|end| end <= limit);
        if !fits {
            return Ok(Err(corrupt(
                "segment record",
                "runs past the committed bytes",
            )));
        }
        let mut head = [0u8; RECORD_HEAD_LEN];
        source.read_exact_at(offset, &mut head)?;
        if head[..8] != SEGMENT_MAGIC {
            return Ok(Err(corrupt(
                "segment record",
                "the segment magic is missing",
            )));
        }
        let mut c = Cursor::new(&head[8..], "segment record");
        let (previous, first_sample, body_len) =
            match (|| Ok::<_, FormatViolation>((c.u64()?, c.u32()?, u64::from(c.u32()?))))() {
                Ok(fields) => fields,
                Err(e) => return Ok(Err(e)),
            };
        if body_len > *budget {
            return Ok(Err(FormatViolation::Limit {
                what: "segment index bytes",
                value: body_len,
                limit: *budget,
            }));
        }
        let end = offset + (RECORD_HEAD_LEN + 4) as u64 + body_len;
        if end > limit {
            return Ok(Err(corrupt(
                "segment record",
                "runs past the committed bytes",
            )));
        }
        *budget -= body_len;
        let mut rest = vec![0u8; body_len as usize + 4];
        source.read_exact_at(offset + RECORD_HEAD_LEN as u64, &mut rest)?;
        let crc_at = rest.len() - 4;
        let stored = u32::from_le_bytes([
            rest[crc_at],
            rest[crc_at + 1],
            rest[crc_at + 2],
            rest[crc_at + 3],
        ]);
        let mut hasher = crc32c::crc32c(&head);
        hasher = crc32c::crc32c_append(hasher, &rest[..crc_at]);
        if hasher != stored {
            return Ok(Err(FormatViolation::Checksum("segment record")));
        }
        rest.truncate(crc_at);
        Ok(Ok(Self {
            offset,
            previous,
            first_sample,
            body: rest,
        }))
    }

    /// Decodes the body: the axis piece, then the tile index, whose tiles must lie in
    /// `tiles_from..self.offset`.
    pub(crate) fn decode(
        self,
        tiles_from: u64,
        tile_depth: u8,
        limits: &ReadLimits,
    ) -> Result<SegmentRecord, FormatViolation> {
        let end = self.end();
        let mut c = Cursor::new(&self.body, "segment axis");
        let axis = decode_axis(&mut c, limits)?;
        let rest = c.take(c.remaining())?;
        let (tiles, _summary, sections) = decode_index_with(
            rest,
            tiles_from..self.offset,
            tile_depth,
            limits,
            &[TAG_SUMMARY, TAG_PATCH_TILES],
        )?;
        let mut patches = vec![None; tiles.len()];
        if let Some((_, payload)) = sections.iter().find(|(tag, _)| *tag == TAG_PATCH_TILES) {
            decode_patches(payload, axis.len(), &mut patches)?;
        }
        if let Some(t) = tiles.iter().find(|t| t.last_sample >= axis.len()) {
            return Err(corrupt(
                "segment index",
                format!("tile {:#x} observed beyond the segment's samples", t.code.0),
            ));
        }
        Ok(SegmentRecord {
            first_sample: self.first_sample,
            axis,
            tiles,
            patches,
            end,
        })
    }
}

/// Increasing tile indices as runs (FORMAT.md §10.3): a varint run count, then per run the
/// gap after the previous run's end (from 0 for the first) and the run's length (≥ 1).
fn encode_runs(indices: &[u32]) -> Vec<u8> {
    let mut runs: Vec<(u32, u32)> = Vec::new();
    for &i in indices {
        match runs.last_mut() {
            Some((start, len)) if *start + *len == i => *len += 1,
            _ => runs.push((i, 1)),
        }
    }
    let mut out = Vec::new();
    varint::write_u64(&mut out, runs.len() as u64);
    let mut end = 0u32;
    for (start, len) in runs {
        varint::write_u64(&mut out, u64::from(start - end));
        varint::write_u64(&mut out, u64::from(len));
        end = start + len;
    }
    out
}

/// Marks the tiles that `payload`'s runs list in `patches` (one per tile of the segment),
/// each with its remainder mask (positions below `samples`): tiles must exist, runs must
/// not overlap, and the payload must end after the last mask.
fn decode_patches(
    payload: &[u8],
    samples: u32,
    patches: &mut [Option<RemainderMask>],
) -> Result<(), FormatViolation> {
    let mut c = Cursor::new(payload, "segment patch tiles");
    let count = c.varint()?;
    // Each run takes at least two bytes.
    let count = c.check_count("patch tile runs", count, patches.len() as u64, 2)?;
    let mut end = 0u64;
    let mut listed = Vec::new();
    for _ in 0..count {
        let (gap, len) = (c.varint()?, c.varint()?);
        let start = end.checked_add(gap);
        let stop = start.and_then(|s| s.checked_add(len));
        match (start, stop) {
            (Some(start), Some(stop)) if len >= 1 && stop <= patches.len() as u64 => {
                listed.extend(start as usize..stop as usize);
                end = stop;
            }
            _ => {
                return Err(corrupt(
                    "segment patch tiles",
                    "a run is empty or lists a tile the segment does not have",
                ))
            }
        }
    }
    for tile in listed {
        let rest = c.take(c.remaining())?;
        let (mask, used) = Toggles::decode(rest, samples).map_err(|_| {
            corrupt(
                "segment patch tiles",
                "a remainder mask is malformed or reaches past the segment's samples",
            )
        })?;
        c = Cursor::new(&rest[used..], "segment patch tiles");
        patches[tile] = Some((!mask.is_empty()).then(|| Arc::new(mask)));
    }
    if !c.is_empty() {
        return Err(corrupt("segment patch tiles", "bytes after the last mask"));
    }
    Ok(())
}
