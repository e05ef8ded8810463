//! Segments of a format 2.0 file ([FORMAT.md §10.3](../../../docs/FORMAT.md)): the cells a
//! commit adds over its own samples, in tiles laid out as the base's, and the record that
//! locates them (axis piece, tile index, previous segment).

use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation, TileEncodeError};
use crate::header::push_section;
use crate::header::{decode_axis, encode_axis};
use crate::index::{
    decode_index_with, encode_index, TileEntry, TAG_PATCH_TILES, TAG_REMAINDER_MASKS, TAG_SUMMARY,
};
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
    /// cells do not cover them, what observes that remainder; `None` for a plain tile.
    pub(crate) patches: Vec<Option<Arc<TileRemainder>>>,
    /// One past the record's last byte.
    pub(crate) end: u64,
}

/// The observation mask of what a patch tile leaves to the base (`None`: observed at every
/// sample of the segment that is not missing).
pub type RemainderMask = Option<Arc<Toggles>>;

/// What observes the remainder of a patch tile (FORMAT.md §10.6, §10.7): by default the
/// tile's remainder mask; the base cells (by rank: their position in the base tile, in
/// Morton order) that `runs` list take one of `masks` instead, or are observed at no sample
/// of the segment. A partial view hides whole regions: the base cells inside one share a
/// mask, and a run of ranks says so for all of them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TileRemainder {
    /// The mask of base cells no run lists.
    pub default: RemainderMask,
    /// Further masks, which runs name from 1 (`masks[v - 1]`).
    pub masks: Vec<RemainderMask>,
    /// Runs of base cells with another mask, by increasing, disjoint rank ranges.
    pub runs: Vec<RemainderRun>,
}

/// Consecutive base cells of a patch tile whose remainder another mask observes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RemainderRun {
    /// Rank of the first base cell (its position in the base tile, from 0).
    pub first: u32,
    /// Base cells in the run (≥ 1).
    pub len: u32,
    /// `0`: observed at no sample of the segment; `v ≥ 1`: at `masks[v - 1]`.
    pub mask: u32,
}

impl TileRemainder {
    /// One mask for the whole remainder.
    pub fn uniform(mask: RemainderMask) -> Self {
        Self {
            default: mask,
            masks: Vec::new(),
            runs: Vec::new(),
        }
    }

    /// The mask observing the remainder of base cell `rank` (`None`: observed at no sample).
    pub fn mask_of(&self, rank: u32) -> Option<&RemainderMask> {
        let i = self.runs.partition_point(|run| run.first <= rank);
        match i.checked_sub(1).map(|i| self.runs[i]) {
            Some(run) if rank - run.first < run.len => match run.mask {
                0 => None,
                v => self.masks.get(v as usize - 1),
            },
            _ => Some(&self.default),
        }
    }

    /// One past the last base cell rank the runs name (0 without runs).
    pub fn ranks_named(&self) -> u64 {
        self.runs
            .last()
            .map_or(0, |run| u64::from(run.first) + u64::from(run.len))
    }

    /// `true` when the runs are sorted, disjoint, non-empty and name existing masks.
    pub(crate) fn is_well_formed(&self) -> bool {
        let mut end = 0u64;
        self.runs.iter().all(|run| {
            let ok = run.len >= 1
                && u64::from(run.first) >= end
                && run.mask as usize <= self.masks.len();
            end = u64::from(run.first) + u64::from(run.len);
            ok
        })
    }
}

/// The record's bytes: head, body (axis piece, tile index, and the patch tiles section when
/// `patches`, the indices of the patch tiles in increasing order with their remainder
/// masks, is not empty) and crc.
pub(crate) fn encode_record(
    previous: u64,
    first_sample: u32,
    axis: &TimeAxis,
    tiles: &[TileEntry],
    patches: &[(u32, TileRemainder)],
) -> Result<Vec<u8>, TileEncodeError> {
    let mut body = encode_axis(axis);
    body.extend(encode_index(tiles, &Map::new()));
    if !patches.is_empty() {
        let indices: Vec<u32> = patches.iter().map(|p| p.0).collect();
        let mut payload = encode_runs(&indices);
        for (_, remainder) in patches {
            encode_mask(&remainder.default, &mut payload);
        }
        push_section(&mut body, TAG_PATCH_TILES, true, &payload);
        let regional: Vec<(usize, &TileRemainder)> = patches
            .iter()
            .enumerate()
            .filter(|(_, (_, r))| !r.runs.is_empty())
            .map(|(i, (_, r))| (i, r))
            .collect();
        if !regional.is_empty() {
            push_section(
                &mut body,
                TAG_REMAINDER_MASKS,
                true,
                &encode_regions(&regional),
            );
        }
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

/// A record's head: where it is, the one before it, its first sample and its body's
/// length, checked to fit the committed bytes; its body not read yet.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RecordHead {
    pub(crate) offset: u64,
    pub(crate) previous: u64,
    pub(crate) first_sample: u32,
    body_len: u64,
}

impl RecordHead {
    /// Where the record ends (its checksum included).
    pub(crate) fn end(&self) -> u64 {
        self.offset + (RECORD_HEAD_LEN + 4) as u64 + self.body_len
    }

    /// Reads the head of the record at `offset`, which must end at or before `limit`; its
    /// body counts against `budget` (the index bytes the reader still accepts).
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
        let (previous, first_sample, body_len) = match head_fields(&head) {
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
        Ok(Ok(Self {
            offset,
            previous,
            first_sample,
            body_len,
        }))
    }

    /// Reads the body and checks the record's checksum (head and body); the head is read
    /// again, so that what is checked is what the file holds now.
    pub(crate) fn read_body(
        self,
        source: &dyn ByteSource,
    ) -> Result<Result<RawRecord, FormatViolation>, std::io::Error> {
        let mut record = vec![0u8; RECORD_HEAD_LEN + self.body_len as usize + 4];
        source.read_exact_at(self.offset, &mut record)?;
        let crc_at = record.len() - 4;
        let stored = u32::from_le_bytes([
            record[crc_at],
            record[crc_at + 1],
            record[crc_at + 2],
            record[crc_at + 3],
        ]);
        if crc32c::crc32c(&record[..crc_at]) != stored {
            return Ok(Err(FormatViolation::Checksum("segment record")));
        }
        let same = head_fields(&record[..RECORD_HEAD_LEN])
            .is_ok_and(|head| head == (self.previous, self.first_sample, self.body_len));
        if !same {
            return Ok(Err(corrupt(
                "segment record",
                "its head changed while it was read",
            )));
        }
        record.truncate(crc_at);
        record.drain(..RECORD_HEAD_LEN);
        Ok(Ok(RawRecord {
            offset: self.offset,
            first_sample: self.first_sample,
            body: record,
        }))
    }
}

/// A record head's (previous, first sample, body length), after its magic.
fn head_fields(head: &[u8]) -> Result<(u64, u32, u64), FormatViolation> {
    if head.get(..8) != Some(&SEGMENT_MAGIC[..]) {
        return Err(corrupt("segment record", "the segment magic is missing"));
    }
    let mut c = Cursor::new(&head[8..], "segment record");
    Ok((c.u64()?, c.u32()?, u64::from(c.u32()?)))
}

/// A record read and checksummed, its body not yet decoded.
pub(crate) struct RawRecord {
    pub(crate) offset: u64,
    pub(crate) first_sample: u32,
    pub(crate) body: Vec<u8>,
}

impl RawRecord {
    pub(crate) fn end(&self) -> u64 {
        self.offset + (RECORD_HEAD_LEN + self.body.len() + 4) as u64
    }

    /// Reads the record at `offset` (see [`RecordHead::read`]) and its body.
    pub(crate) fn read(
        source: &dyn ByteSource,
        offset: u64,
        limit: u64,
        budget: &mut u64,
    ) -> Result<Result<Self, FormatViolation>, std::io::Error> {
        match RecordHead::read(source, offset, limit, budget)? {
            Ok(head) => head.read_body(source),
            Err(violation) => Ok(Err(violation)),
        }
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
            &[TAG_SUMMARY, TAG_PATCH_TILES, TAG_REMAINDER_MASKS],
        )?;
        let mut patches = vec![None; tiles.len()];
        let section = |tag: u16| sections.iter().find(|s| s.0 == tag).map(|s| s.1);
        if let Some(payload) = section(TAG_PATCH_TILES) {
            decode_patches(payload, axis.len(), &mut patches)?;
        }
        if let Some(payload) = section(TAG_REMAINDER_MASKS) {
            decode_regions(payload, axis.len(), &mut patches)?;
        }
        let patches = patches.into_iter().map(|p| p.map(Arc::new)).collect();
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

/// A remainder mask as FORMAT.md §10.6 stores it: a toggle list, empty for every sample.
fn encode_mask(mask: &RemainderMask, out: &mut Vec<u8>) {
    match mask {
        Some(mask) => mask.encode(out),
        None => Toggles::default().encode(out),
    }
}

/// The `REMAINDER_MASKS` payload (FORMAT.md §10.7) of the patch tiles with runs, given by
/// their position among the patch tiles, increasing.
fn encode_regions(regional: &[(usize, &TileRemainder)]) -> Vec<u8> {
    let mut out = Vec::new();
    varint::write_u64(&mut out, regional.len() as u64);
    let mut next = 0usize;
    for &(position, remainder) in regional {
        varint::write_u64(&mut out, (position - next) as u64);
        next = position + 1;
        varint::write_u64(&mut out, remainder.masks.len() as u64);
        for mask in &remainder.masks {
            encode_mask(mask, &mut out);
        }
        varint::write_u64(&mut out, remainder.runs.len() as u64);
        let mut end = 0u32;
        for run in &remainder.runs {
            varint::write_u32(&mut out, run.first - end);
            varint::write_u32(&mut out, run.len);
            varint::write_u32(&mut out, run.mask);
            end = run.first + run.len;
        }
    }
    out
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
    patches: &mut [Option<TileRemainder>],
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
        let mask = decode_mask(&mut c, samples)?;
        patches[tile] = Some(TileRemainder::uniform(mask));
    }
    if !c.is_empty() {
        return Err(corrupt("segment patch tiles", "bytes after the last mask"));
    }
    Ok(())
}

/// One remainder mask (a toggle list, positions below `samples`; empty: every sample).
fn decode_mask(c: &mut Cursor<'_>, samples: u32) -> Result<RemainderMask, FormatViolation> {
    let part = c.part();
    let rest = c.take(c.remaining())?;
    let (mask, used) = Toggles::decode(rest, samples).map_err(|_| {
        corrupt(
            part,
            "a remainder mask is malformed or reaches past the segment's samples",
        )
    })?;
    *c = Cursor::new(&rest[used..], part);
    Ok((!mask.is_empty()).then(|| Arc::new(mask)))
}

/// Adds the `REMAINDER_MASKS` section's masks and runs (FORMAT.md §10.7) to the patch tiles
/// (`patches`, one per tile of the segment, `Some` for a patch tile) it names by position
/// among them. A run's ranks are checked against the base tile when the segment is opened.
fn decode_regions(
    payload: &[u8],
    samples: u32,
    patches: &mut [Option<TileRemainder>],
) -> Result<(), FormatViolation> {
    const PART: &str = "segment remainder masks";
    let mut c = Cursor::new(payload, PART);
    let listed: Vec<usize> = (0..patches.len())
        .filter(|&t| patches[t].is_some())
        .collect();
    let count = c.varint()?;
    // Each tile takes at least three bytes (gap, masks, runs).
    let count = c.check_count("tiles with remainder masks", count, listed.len() as u64, 3)?;
    let mut next = 0u64;
    for _ in 0..count {
        let position = next
            .checked_add(c.varint()?)
            .filter(|&p| p < listed.len() as u64);
        let Some(position) = position else {
            return Err(corrupt(
                PART,
                "names a patch tile the segment does not have",
            ));
        };
        next = position + 1;
        let masks = c.varint()?;
        // A mask takes at least one byte.
        let masks = c.check_count("remainder masks of a tile", masks, u64::from(u32::MAX), 1)?;
        let masks = (0..masks)
            .map(|_| decode_mask(&mut c, samples))
            .collect::<Result<Vec<_>, _>>()?;
        let runs = c.varint()?;
        // A run takes three bytes; a tile lists at least one.
        let runs = c.check_count("remainder runs of a tile", runs, u64::from(u32::MAX), 3)?;
        if runs == 0 {
            return Err(corrupt(PART, "a tile lists no run"));
        }
        let mut end = 0u64;
        let mut parsed = Vec::with_capacity(runs);
        for _ in 0..runs {
            let (gap, len, mask) = (c.varint()?, c.varint()?, c.varint()?);
            let first = end.checked_add(gap).filter(|&f| f <= u64::from(u32::MAX));
            let stop = first
                .and_then(|f| f.checked_add(len))
                .filter(|&s| s <= u64::from(u32::MAX) + 1);
            let (Some(first), Some(stop)) = (first, stop) else {
                return Err(corrupt(PART, "a run's ranks overflow"));
            };
            if len == 0 || mask > masks.len() as u64 {
                return Err(corrupt(
                    PART,
                    "a run is empty or names a mask the tile does not have",
                ));
            }
            parsed.push(RemainderRun {
                first: first as u32,
                len: (stop - first) as u32,
                mask: mask as u32,
            });
            end = stop;
        }
        let tile = listed[position as usize];
        if let Some(remainder) = &mut patches[tile] {
            remainder.masks = masks;
            remainder.runs = parsed;
        }
    }
    if !c.is_empty() {
        return Err(corrupt(PART, "bytes after the last run"));
    }
    Ok(())
}
