//! Format 2.0, the living map ([FORMAT.md §10](../../../docs/FORMAT.md),
//! [LIVING-MAP.md](../../../docs/LIVING-MAP.md)): a base (a 1.x file body) followed by
//! segments, one per commit, made durable by a root written after the data is synced.
//!
//! [`LivingWriter::convert`] makes a 2.0 file from a 1.x file; [`LivingWriter::open`] takes
//! the file's lock and [`LivingWriter::begin_segment`] appends a segment, committed by
//! [`SegmentWriter::commit`]. [`LivingReader`] sees the root taken when it opened until
//! [`LivingReader::refresh`].
//!
//! ```
//! use froctomap_core::{Occupancy, Timestamp, VoxelKey};
//! use froctomap_file::*;
//! use froctomap_temporal::TimeAxis;
//! # let golden = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
//! #     .join("../../fixtures/froct/golden-v1.2.froct");
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("living.froct");
//! LivingWriter::convert(&golden, &path)?; // a 1.2 file becomes the base
//! let mut reader = LivingReader::open(&path)?;
//! let base_samples = reader.sample_count();
//!
//! // One more map, an hour after the base's last one: a new voxel, seen occupied.
//! let mut writer = LivingWriter::open(&path)?;
//! let hour = 3_600_000_000_000;
//! let next = Timestamp(reader.sample_time(base_samples - 1).unwrap().0 + hour);
//! let mut segment = writer.begin_segment(TimeAxis::regular(next, hour, 1, vec![])?)?;
//! let voxel = VoxelKey::new(1000, 1000, 1000).morton();
//! segment.push_tile(vec![SegmentCell {
//!     start: voxel, depth: 16, mask: None, content: SegmentContent::Constant(Occupancy::Occupied),
//! }])?;
//! segment.commit()?;
//!
//! // The open reader keeps its view until it refreshes.
//! assert_eq!(reader.sample_count(), base_samples);
//! assert!(reader.refresh()?);
//! let map = reader.observed_states(base_samples)?;
//! assert_eq!(map, vec![(voxel, 16, Occupancy::Occupied)]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::error::{corrupt, FileError, FormatViolation, TileEncodeError};
use crate::header::{Header, PREAMBLE_LEN};
use crate::index::{encode_footer, encode_index, TileEntry, FOOTER_LEN};
use crate::limits::ReadLimits;
use crate::reader::{Body, FroctReader};
use crate::root::{
    Root, LIVING_HEADER_AT, LIVING_MAJOR_VERSION, LIVING_MINOR_VERSION, ROOT_SLOTS_AT,
    ROOT_SLOT_LEN,
};
use crate::segment::{
    encode_record, InheritedModel, RawRecord, RecordHead, RemainderMask, SegmentCell,
    SegmentContent, SegmentRecord, SegmentTileEncoder, TileRemainder,
};
use crate::source::{ByteSource, FileSource};
use crate::tile::{CellRef, EncodedTile, WalkNeed};
use crate::writer::seal_tile;
use froctomap_core::{voxels_per_node, MortonCode, Occupancy, Timestamp};
use froctomap_temporal::{ModelRegistry, TimeAxis, Toggles};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A cell's state as a visit reports it: Morton code of its first voxel, depth, state.
pub type CellState = (MortonCode, u8, Occupancy);

/// One committed segment as a reader holds it: where its record is, which of its tiles are
/// patch tiles, and a tile reader over its samples (whose header holds the segment's axis).
/// The patch tiles' remainders are not kept: they are most of a record's decoded size (runs
/// and masks for every base region a view left out), so a reader holding them for every
/// segment would grow with the file's history; [`LivingReader::patches`] reads them again
/// when a query needs them.
struct Segment {
    /// Global index of the segment's first sample.
    first_sample: u32,
    /// Where its record starts, and where the tiles before it begin (its tiles lie between).
    record_at: u64,
    tiles_from: u64,
    /// One past the record's last byte.
    end: u64,
    /// Per tile, whether it is a patch tile.
    patch_tiles: Box<[bool]>,
    tiles: FroctReader,
}

impl Segment {
    /// The segment's own samples.
    fn axis(&self) -> &TimeAxis {
        &self.tiles.header().axis
    }
}

/// The patch remainders of a segment, per tile (`None` for a plain tile).
type Patches = Arc<[Option<Arc<TileRemainder>>]>;

/// How many segments' patch remainders a reader keeps decoded: queries go through a
/// segment's tiles one after another, and compaction through the segments in order.
const CACHED_PATCHES: usize = 4;

/// An open format 2.0 file: its base and its committed segments, as the root read at open
/// (or at the last [`refresh`](Self::refresh)) says. Bytes past the committed length are
/// never read.
pub struct LivingReader {
    path: PathBuf,
    source: Arc<dyn ByteSource>,
    limits: ReadLimits,
    root: Root,
    slot: usize,
    base: FroctReader,
    segments: Vec<Segment>,
    /// The patch remainders of the segments read last, newest first.
    patches: std::sync::Mutex<Vec<(usize, Patches)>>,
    /// Segment index bytes the limits still allow.
    index_budget: u64,
}

impl std::fmt::Debug for LivingReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LivingReader")
            .field("path", &self.path)
            .field("root", &self.root)
            .finish()
    }
}

/// Where a global sample lies.
enum SampleAt {
    Base(u32),
    Segment(usize, u32),
}

impl LivingReader {
    /// Opens a 2.0 file with the default [`ReadLimits`] and models.
    pub fn open(path: &Path) -> Result<Self, FileError> {
        Self::open_with_limits(
            path,
            ReadLimits::default(),
            &ModelRegistry::with_default_models(),
        )
    }

    /// Opens a 2.0 file with explicit limits and model registry.
    pub fn open_with_limits(
        path: &Path,
        limits: ReadLimits,
        models: &ModelRegistry,
    ) -> Result<Self, FileError> {
        let source = FileSource::open(path).map_err(|source| FileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_source(Arc::new(source), limits, models)
    }

    /// Opens the 2.0 file `source` serves: preamble, root, the base's header and index, then
    /// every committed segment's record, each checked against `limits` and the committed
    /// bytes before it is read.
    pub fn from_source(
        source: Arc<dyn ByteSource>,
        limits: ReadLimits,
        models: &ModelRegistry,
    ) -> Result<Self, FileError> {
        let path = source.name().to_path_buf();
        let (root, slot) = read_root(source.as_ref(), &limits)?;
        let base = FroctReader::open_body(
            Box::new(Arc::clone(&source)),
            base_body(root.base_len),
            limits,
            models,
        )?;
        let mut reader = Self {
            path,
            source,
            limits,
            root: Root {
                sequence: 0,
                committed_len: root.base_len,
                last_segment: 0,
                segment_count: 0,
                sample_count: 0,
                ..root
            },
            slot,
            index_budget: limits.max_index_bytes,
            base,
            segments: Vec::new(),
            patches: std::sync::Mutex::new(Vec::new()),
        };
        reader.root.sample_count = reader.base.header().axis.len();
        reader.load_segments(root, slot)?;
        Ok(reader)
    }

    fn invalid(&self, violation: FormatViolation) -> FileError {
        FileError::Invalid {
            path: self.path.clone(),
            violation,
        }
    }

    /// Reads the segments `root` adds to those held, checking the chain: each record's
    /// previous offset, first sample and tile range, and the committed length.
    fn load_segments(&mut self, root: Root, slot: usize) -> Result<(), FileError> {
        let invalid = |v| FileError::Invalid {
            path: self.path.clone(),
            violation: v,
        };
        if u64::from(root.segment_count) > self.limits.max_segments {
            return Err(invalid(FormatViolation::Limit {
                what: "segments",
                value: u64::from(root.segment_count),
                limit: self.limits.max_segments,
            }));
        }
        let held = self.root;
        if root.base_len != held.base_len
            || root.segment_count < held.segment_count
            || root.committed_len < held.committed_len
        {
            return Err(invalid(corrupt(
                "root",
                "the committed state shrank or its base changed under an open reader",
            )));
        }
        let mut budget = self.index_budget;
        let heads = self.read_new_heads(&root, &mut budget)?;
        let header = self.base.header().clone();
        let mut tiles_from = held.committed_len;
        let mut samples = u64::from(held.sample_count);
        let mut last_instant = self.last_instant();
        let mut added = Vec::with_capacity(heads.len());
        for head in heads {
            let raw = head
                .read_body(self.source.as_ref())
                .map_err(|source| FileError::Io {
                    path: self.path.clone(),
                    source,
                })?
                .map_err(invalid)?;
            if u64::from(raw.first_sample) != samples {
                return Err(invalid(corrupt(
                    "segment record",
                    format!(
                        "first sample {} where the series has {samples}",
                        raw.first_sample
                    ),
                )));
            }
            let offset = raw.offset;
            let record = raw
                .decode(tiles_from, header.tile_depth, &self.limits)
                .map_err(invalid)?;
            let blocks = u64::from(header.toggles.blocks(record.axis.len()));
            if blocks > self.limits.max_toggle_blocks {
                return Err(invalid(FormatViolation::Limit {
                    what: "toggle blocks",
                    value: blocks,
                    limit: self.limits.max_toggle_blocks,
                }));
            }
            if record.axis.start() <= last_instant {
                return Err(invalid(corrupt(
                    "segment axis",
                    "a segment's first instant does not follow the samples before it",
                )));
            }
            samples += u64::from(record.axis.len());
            if samples > self.limits.max_samples {
                return Err(invalid(FormatViolation::Limit {
                    what: "sample count",
                    value: samples,
                    limit: self.limits.max_samples,
                }));
            }
            self.check_patches(&record)?;
            last_instant = record.axis.end();
            let patch_tiles = record.patches.iter().map(Option::is_some).collect();
            let segment = Segment {
                first_sample: record.first_sample,
                record_at: offset,
                tiles_from,
                end: record.end,
                patch_tiles,
                tiles: FroctReader::from_parts(
                    Box::new(Arc::clone(&self.source)),
                    Header {
                        axis: record.axis.clone(),
                        ..header.clone()
                    },
                    record.tiles,
                    Box::new(InheritedModel::new(record.axis)),
                    self.limits,
                ),
            };
            tiles_from = segment.end;
            added.push(segment);
        }
        if samples != u64::from(root.sample_count) {
            return Err(invalid(corrupt(
                "root",
                format!(
                    "{} samples where the segments hold {samples}",
                    root.sample_count
                ),
            )));
        }
        self.segments.extend(added);
        self.index_budget = budget;
        self.root = root;
        self.slot = slot;
        Ok(())
    }

    /// The heads of the records of the segments `root` commits beyond those held, oldest
    /// first, each checked to point to the one before it. Only heads: the bodies are read
    /// one at a time as they are decoded, so opening a file of many segments never holds
    /// them all.
    fn read_new_heads(&self, root: &Root, budget: &mut u64) -> Result<Vec<RecordHead>, FileError> {
        let invalid = |v| self.invalid(v);
        let io = |source| FileError::Io {
            path: self.path.clone(),
            source,
        };
        let held = self.root;
        // Newest first, back to the newest segment held.
        let mut heads = Vec::new();
        let (mut at, mut limit) = (root.last_segment, root.committed_len);
        for k in (held.segment_count..root.segment_count).rev() {
            let head = RecordHead::read(self.source.as_ref(), at, limit, budget)
                .map_err(io)?
                .map_err(invalid)?;
            if heads.is_empty() && head.end() != root.committed_len {
                return Err(invalid(corrupt(
                    "segment record",
                    "the newest segment does not end at the committed length",
                )));
            }
            let expected_previous = (k == held.segment_count).then_some(held.last_segment);
            let chained = match expected_previous {
                Some(previous) => head.previous == previous,
                None => head.previous >= self.root.base_len && head.previous < at,
            };
            if !chained {
                return Err(invalid(corrupt(
                    "segment record",
                    format!("segment {k} points to an impossible previous segment"),
                )));
            }
            (at, limit) = (head.previous, head.offset);
            heads.push(head);
        }
        heads.reverse();
        Ok(heads)
    }

    /// A segment's patch tiles each patch a base tile, naming only cells that tile has.
    fn check_patches(&self, record: &SegmentRecord) -> Result<(), FileError> {
        let invalid = |v| self.invalid(v);
        let base_tiles = self.base.tiles();
        for (entry, patch) in record.tiles.iter().zip(&record.patches) {
            let Some(remainder) = patch else { continue };
            let Ok(base) = base_tiles.binary_search_by_key(&entry.code, |t| t.code) else {
                return Err(invalid(corrupt(
                    "segment patch tiles",
                    format!("patch tile {:#x} has no base tile", entry.code.0),
                )));
            };
            if remainder.ranks_named() > u64::from(base_tiles[base].cell_count) {
                return Err(invalid(corrupt(
                    "segment remainder masks",
                    format!(
                        "patch tile {:#x} names base cells its base tile does not have",
                        entry.code.0
                    ),
                )));
            }
        }
        Ok(())
    }

    /// Reads the root again and the records of segments committed since: `true` when there
    /// were any. The view stays consistent: committed segments are never rewritten.
    pub fn refresh(&mut self) -> Result<bool, FileError> {
        let (root, slot) = read_root(self.source.as_ref(), &self.limits)?;
        if root.sequence == self.root.sequence {
            return Ok(false);
        }
        if root.sequence < self.root.sequence {
            return Err(self.invalid(corrupt("root", "the root went back to an older commit")));
        }
        let changed = root.segment_count != self.root.segment_count;
        self.load_segments(root, slot)?;
        Ok(changed)
    }

    /// The file's name, for errors.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The root this reader sees.
    pub fn root(&self) -> Root {
        self.root
    }

    /// The base, as a 1.x reader of its part of the file: header (its time axis is the
    /// base's samples), tiles, model; its `file_len` is the base's end.
    pub fn base(&self) -> &FroctReader {
        &self.base
    }

    /// A second reader of the base alone, over the same bytes: its header and index read
    /// again, no segment (the cost of the base, whatever the file's history). A writer
    /// lends its reader to nothing while a segment is being written; this is what code
    /// that needs the base meanwhile holds.
    pub fn reopen_base(&self, models: &ModelRegistry) -> Result<FroctReader, FileError> {
        FroctReader::open_body(
            Box::new(Arc::clone(&self.source)),
            base_body(self.root.base_len),
            self.limits,
            models,
        )
    }

    /// The header (the base's; segments carry their own samples).
    pub fn header(&self) -> &Header {
        self.base.header()
    }

    /// Samples of the whole series.
    pub fn sample_count(&self) -> u32 {
        self.root.sample_count
    }

    /// Committed segments seen.
    pub fn segment_count(&self) -> usize {
        self.segments.len()
    }

    /// Segment `k`'s global first sample and its own samples.
    pub fn segment_axis(&self, k: usize) -> Option<(u32, &TimeAxis)> {
        self.segments.get(k).map(|s| (s.first_sample, s.axis()))
    }

    /// Segment `k`'s tiles (sample ranges in the segment's own samples).
    pub fn segment_tiles(&self, k: usize) -> &[TileEntry] {
        self.segments.get(k).map_or(&[], |s| s.tiles.tiles())
    }

    /// The cells of tile `tile` of segment `k`, in Morton order. A patch tile's cells
    /// include what it inherits: the base cells (or their parts, as aligned nodes) that its
    /// stored cells do not cover, as inherited cells without outliers or mask.
    pub fn read_segment_tile(&self, k: usize, tile: usize) -> Result<Vec<SegmentCell>, FileError> {
        let remainder = self.remainder(k, tile)?;
        self.read_segment_tile_with(k, tile, remainder.as_deref())
    }

    /// The remainders of segment `k`'s tiles `tiles` (`None` for a tile that is not a
    /// patch tile), its record decoded once for them and not cached: for a reader of every
    /// segment's tile after tile (a compaction), which would miss the cache of the last
    /// segments asked for each time, and which holds a few tiles' remainders per segment.
    pub fn segment_tile_remainders(
        &self,
        k: usize,
        tiles: std::ops::Range<usize>,
    ) -> Result<Vec<Option<Arc<TileRemainder>>>, FileError> {
        let beyond = || FileError::Invalid {
            path: self.path.clone(),
            violation: corrupt(
                "segment tiles",
                format!("segment {k} has no tiles {tiles:?}"),
            ),
        };
        let flags = self.segment(k)?.patch_tiles.get(tiles.clone());
        if !flags.ok_or_else(beyond)?.iter().any(|&patch| patch) {
            return Ok(vec![None; tiles.len()]);
        }
        let patches = self.decode_patches(k)?;
        Ok(patches.get(tiles.clone()).ok_or_else(beyond)?.to_vec())
    }

    /// [`read_segment_tile`](Self::read_segment_tile) with the tile's remainder given (from
    /// [`segment_tile_remainders`](Self::segment_tile_remainders)).
    pub fn read_segment_tile_with(
        &self,
        k: usize,
        tile: usize,
        remainder: Option<&TileRemainder>,
    ) -> Result<Vec<SegmentCell>, FileError> {
        let segment = self.segment(k)?;
        let mut cells = Vec::new();
        segment
            .tiles
            .visit_cells(tile, |cell| cells.push(SegmentCell::from_cell(cell)))?;
        if let Some(remainder) = remainder {
            let covered: Vec<(u64, u64)> = cells
                .iter()
                .map(|c| (c.start.0, c.start.0 + voxels_per_node(c.depth)))
                .collect();
            let code = segment.tiles.tiles()[tile].code;
            self.visit_uncovered_base_cells(code, &covered, |start, depth, rank, _| {
                // A part observed at no sample is not a cell of the segment.
                if let Some(mask) = remainder.mask_of(rank) {
                    cells.push(SegmentCell {
                        start,
                        depth,
                        mask: mask.clone(),
                        content: SegmentContent::Inherited {
                            outliers: Toggles::default(),
                        },
                    });
                }
            })?;
            cells.sort_unstable_by_key(|c| c.start);
        }
        Ok(cells)
    }

    /// `true` when tile `tile` of segment `k` is a patch tile (FORMAT.md §10.6): the base
    /// tile's cells are inherited where its own cells do not cover them.
    pub fn is_patch_tile(&self, k: usize, tile: usize) -> bool {
        self.segments
            .get(k)
            .and_then(|s| s.patch_tiles.get(tile))
            .is_some_and(|&patch| patch)
    }

    /// For a patch tile, the observation mask of what it leaves to the base where no
    /// remainder run says otherwise (`Some(None)`: observed at every sample that is not
    /// missing); `None` for any other tile.
    pub fn remainder_mask(
        &self,
        k: usize,
        tile: usize,
    ) -> Result<Option<RemainderMask>, FileError> {
        Ok(self.remainder(k, tile)?.map(|r| r.default.clone()))
    }

    /// For a patch tile, what observes what it leaves to the base (its default mask, and
    /// the masks of runs of base cells, FORMAT.md §10.7); `None` for any other tile. Read
    /// from the segment's record unless one of the last segments asked for.
    pub fn remainder(
        &self,
        k: usize,
        tile: usize,
    ) -> Result<Option<Arc<TileRemainder>>, FileError> {
        if !self.is_patch_tile(k, tile) {
            return Ok(None);
        }
        Ok(self.patches(k)?.get(tile).cloned().flatten())
    }

    /// Segment `k`'s patch remainders: from the cache, or its record read, checked and
    /// decoded again (it was checked whole when the reader opened; what it says now must be
    /// what it said then).
    fn patches(&self, k: usize) -> Result<Patches, FileError> {
        let lock = || {
            self.patches
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
        };
        {
            let mut cache = lock();
            if let Some(i) = cache.iter().position(|(segment, _)| *segment == k) {
                let entry = cache.remove(i);
                let patches = Arc::clone(&entry.1);
                cache.insert(0, entry);
                return Ok(patches);
            }
        }
        let patches = self.decode_patches(k)?;
        let mut cache = lock();
        cache.insert(0, (k, Arc::clone(&patches)));
        cache.truncate(CACHED_PATCHES);
        Ok(patches)
    }

    /// Segment `k`'s patch remainders, its record read, checked and decoded again.
    fn decode_patches(&self, k: usize) -> Result<Patches, FileError> {
        let segment = self.segment(k)?;
        let invalid = |v| self.invalid(v);
        // Counted against the index budget when the reader opened.
        let mut budget = u64::MAX;
        let record = RawRecord::read(
            self.source.as_ref(),
            segment.record_at,
            segment.end,
            &mut budget,
        )
        .map_err(|source| FileError::Io {
            path: self.path.clone(),
            source,
        })?
        .map_err(invalid)?
        .decode(segment.tiles_from, self.header().tile_depth, &self.limits)
        .map_err(invalid)?;
        let same = record.first_sample == segment.first_sample
            && record.end == segment.end
            && record
                .patches
                .iter()
                .map(Option::is_some)
                .eq(segment.patch_tiles.iter().copied());
        if !same {
            return Err(invalid(corrupt(
                "segment record",
                format!("segment {k}'s record changed since the file was opened"),
            )));
        }
        self.check_patches(&record)?;
        let patches: Patches = record.patches.into();
        Ok(patches)
    }

    /// Calls `visit` with the parts of the cells of the base tile `code` that no range of
    /// `covered` (sorted, disjoint) overlaps, as aligned nodes, each with the rank (position
    /// in the base tile) of the base cell it lies in and that cell.
    fn visit_uncovered_base_cells(
        &self,
        code: MortonCode,
        covered: &[(u64, u64)],
        mut visit: impl FnMut(MortonCode, u8, u32, &CellRef<'_>),
    ) -> Result<(), FileError> {
        let Some(base_tile) = self.base.tile_containing(code) else {
            return Err(self.invalid(corrupt(
                "segment patch tiles",
                format!("patch tile {:#x} has no base tile", code.0),
            )));
        };
        // A stored cell can split a base cell into ~112 aligned nodes: the tile's cells,
        // stored and inherited, count against `max_cells_per_tile` (FORMAT.md §10.6).
        let limit = self.limits.max_cells_per_tile;
        let mut cells = covered.len() as u64;
        let mut parts = Vec::new();
        let mut rank = 0u32;
        self.base
            .walk_tile(base_tile, WalkNeed::ModelOnly, |cell| {
                let this = rank;
                rank = rank.saturating_add(1);
                if cells > limit {
                    return;
                }
                parts.clear();
                let range = (cell.start.0, cell.start.0 + voxels_per_node(cell.depth));
                subtract(range, covered, &mut parts);
                for &(a, b) in &parts {
                    aligned_nodes(a, b, |start, depth| {
                        cells += 1;
                        if cells <= limit {
                            visit(start, depth, this, &cell);
                        }
                    });
                }
            })?;
        if cells > limit {
            return Err(self.invalid(FormatViolation::Limit {
                what: "cells of a patch tile with its remainder",
                value: cells,
                limit,
            }));
        }
        Ok(())
    }

    /// The raw streams of tile `tile` of segment `k` by name (as
    /// [`FroctReader::tile_streams`]), for size analysis.
    pub fn segment_tile_streams(
        &self,
        k: usize,
        tile: usize,
    ) -> Result<Vec<(&'static str, Vec<u8>)>, FileError> {
        self.segment(k)?.tiles.tile_streams(tile)
    }

    fn segment(&self, k: usize) -> Result<&Segment, FileError> {
        self.segments.get(k).ok_or_else(|| FileError::NoSegment {
            path: self.path.clone(),
            segment: k,
            segments: self.segments.len(),
        })
    }

    fn locate(&self, sample: u32) -> Option<SampleAt> {
        let base_len = self.base.header().axis.len();
        if sample < base_len {
            return Some(SampleAt::Base(sample));
        }
        let k = self
            .segments
            .partition_point(|s| s.first_sample <= sample)
            .checked_sub(1)?;
        let local = sample - self.segments[k].first_sample;
        (local < self.segments[k].axis().len()).then_some(SampleAt::Segment(k, local))
    }

    /// The instant of a global sample.
    pub fn sample_time(&self, sample: u32) -> Option<Timestamp> {
        match self.locate(sample)? {
            SampleAt::Base(i) => self.base.header().axis.time(i),
            SampleAt::Segment(k, i) => self.segments[k].axis().time(i),
        }
    }

    /// `true` when no map exists at a global sample (every cell is unknown there).
    pub fn is_missing(&self, sample: u32) -> bool {
        match self.locate(sample) {
            Some(SampleAt::Base(i)) => self.base.header().axis.is_missing(i),
            Some(SampleAt::Segment(k, i)) => self.segments[k].axis().is_missing(i),
            None => true,
        }
    }

    /// The instant of the series' last sample: a new segment must start after it.
    pub fn last_instant(&self) -> Timestamp {
        self.segments
            .last()
            .map_or_else(|| self.base.header().axis.end(), |s| s.axis().end())
    }

    /// The last global sample with a map at or before `t` (missing samples skipped), `None`
    /// before the first one.
    pub fn sample_at_or_before(&self, t: Timestamp) -> Option<u32> {
        let k = self.segments.partition_point(|s| s.axis().start() <= t);
        self.segments[..k]
            .iter()
            .rev()
            .find_map(|s| {
                let local = s.axis().last_at_or_before(t)?;
                Some(s.first_sample + local)
            })
            .or_else(|| self.base.header().axis.last_at_or_before(t))
    }

    /// The tiles that hold the map at a global sample: the base's or its segment's (empty
    /// beyond the series).
    pub fn tiles_at(&self, sample: u32) -> &[TileEntry] {
        match self.locate(sample) {
            Some(SampleAt::Base(_)) => self.base.tiles(),
            Some(SampleAt::Segment(k, _)) => self.segments[k].tiles.tiles(),
            None => &[],
        }
    }

    /// Calls `visit` with each cell of tile `tile` of [`tiles_at(sample)`](Self::tiles_at)
    /// observed at global sample `sample`, with its state there, in Morton order.
    pub fn visit_observed_states(
        &self,
        sample: u32,
        tile: usize,
        mut visit: impl FnMut(MortonCode, u8, Occupancy),
    ) -> Result<(), FileError> {
        let (k, local) = match self.locate(sample) {
            None => return Ok(()),
            Some(SampleAt::Base(i)) => return self.base.visit_observed_states(tile, i, visit),
            Some(SampleAt::Segment(k, local)) => (k, local),
        };
        let segment = &self.segments[k];
        let Some(entry) = segment.tiles.tiles().get(tile).copied() else {
            return Err(FileError::NoTile {
                path: self.path.clone(),
                tile,
                tiles: segment.tiles.tiles().len(),
            });
        };
        let remainder = self.remainder(k, tile)?;
        let remainder = remainder.as_deref();
        let patch = remainder.is_some();
        if !entry.may_observe(local) && !patch {
            return Ok(());
        }
        // Constant cells know their state; inherited ones their outlier parity, to be
        // applied to the base cell's prediction.
        let mut cells: Vec<(MortonCode, u8, Result<Occupancy, bool>)> = Vec::new();
        let mut covered: Vec<(u64, u64)> = Vec::new();
        let model = segment.tiles.model();
        segment
            .tiles
            .walk_tile(tile, WalkNeed::StateAt(local), |cell| {
                if patch {
                    covered.push((cell.start.0, cell.start.0 + voxels_per_node(cell.depth)));
                }
                if cell.observed {
                    let state = match cell.constant {
                        Some(_) => Ok(cell.state(model, local)),
                        None => Err(cell.outlier_parity),
                    };
                    cells.push((cell.start, cell.depth, state));
                }
            })?;
        if cells.iter().any(|c| c.2.is_err()) {
            let seconds = self
                .sample_time(sample)
                .map_or(0.0, |t| t.secs_since(self.base.header().axis.start()));
            let inherited: Vec<(u64, u64)> = cells
                .iter()
                .filter(|c| c.2.is_err())
                .map(|c| (c.0 .0, c.0 .0 + voxels_per_node(c.1)))
                .collect();
            let predicted = self.base_predictions(entry.code, &inherited, seconds)?;
            let mut predicted = predicted.into_iter();
            for cell in &mut cells {
                if let Err(parity) = cell.2 {
                    let base = predicted.next().unwrap_or(Occupancy::Free);
                    cell.2 = Ok(if parity { !base } else { base });
                }
            }
        }
        // Whether the default mask and each further one observe the remainder here.
        let observes = |mask: &RemainderMask| mask.as_ref().is_none_or(|m| m.parity_at(local));
        let observed: Option<(bool, Vec<bool>)> = remainder
            .filter(|_| !segment.axis().is_missing(local))
            .map(|r| {
                (
                    observes(&r.default),
                    r.masks.iter().map(observes).collect::<Vec<bool>>(),
                )
            })
            .filter(|(default, masks)| *default || masks.contains(&true));
        if let (Some(remainder), Some((default, masks))) = (remainder, observed) {
            // The rest of the base tile, observed in its frozen prediction where its masks
            // say.
            let seconds = self
                .sample_time(sample)
                .map_or(0.0, |t| t.secs_since(self.base.header().axis.start()));
            let base_model = self.base.model();
            let seen = |rank: u32| {
                let i = remainder.runs.partition_point(|run| run.first <= rank);
                match i.checked_sub(1).map(|i| remainder.runs[i]) {
                    Some(run) if rank - run.first < run.len => {
                        run.mask.checked_sub(1).is_some_and(|v| masks[v as usize])
                    }
                    _ => default,
                }
            };
            self.visit_uncovered_base_cells(entry.code, &covered, |start, depth, rank, cell| {
                if seen(rank) {
                    let state = Occupancy::from(cell.probability(base_model, seconds) > 0.5);
                    cells.push((start, depth, Ok(state)));
                }
            })?;
            cells.sort_unstable_by_key(|c| c.0);
        }
        for (start, depth, state) in cells {
            visit(start, depth, state.unwrap_or(Occupancy::Free));
        }
        Ok(())
    }

    /// The predicted state (`p(t) > 0.5`) at `seconds` of the base cell holding each
    /// voxel range of `inside` (sorted, disjoint, in tile `code`), which must lie inside one
    /// base cell each.
    fn base_predictions(
        &self,
        code: MortonCode,
        inside: &[(u64, u64)],
        seconds: f64,
    ) -> Result<Vec<Occupancy>, FileError> {
        let uncovered = || {
            self.invalid(corrupt(
                "segment tile",
                format!(
                    "tile {:#x}: an inherited cell lies inside no base cell",
                    code.0
                ),
            ))
        };
        let base_tile = self.base.tile_containing(code).ok_or_else(uncovered)?;
        let model = self.base.model();
        let mut states = Vec::with_capacity(inside.len());
        let mut next = inside.iter().peekable();
        self.base
            .walk_tile(base_tile, WalkNeed::ModelOnly, |cell| {
                let (start, end) = (cell.start.0, cell.start.0 + voxels_per_node(cell.depth));
                let mut state = None;
                while let Some(&&(a, b)) = next.peek() {
                    if a >= end || a < start || b > end {
                        break;
                    }
                    let occupied = cell.probability(model, seconds) > 0.5;
                    let s = *state.get_or_insert(Occupancy::from(occupied));
                    states.push(s);
                    next.next();
                }
            })?;
        if states.len() != inside.len() {
            return Err(uncovered());
        }
        Ok(states)
    }

    /// Every cell observed at global sample `sample`, with its state, in Morton order.
    pub fn observed_states(&self, sample: u32) -> Result<Vec<CellState>, FileError> {
        let mut out = Vec::new();
        for tile in 0..self.tiles_at(sample).len() {
            self.visit_observed_states(sample, tile, |start, depth, state| {
                out.push((start, depth, state))
            })?;
        }
        Ok(out)
    }

    /// Codes of the tiles the predicted map covers: the base's and every segment's.
    pub fn predicted_tile_codes(&self) -> Vec<MortonCode> {
        let mut codes: Vec<MortonCode> = self
            .base
            .tiles()
            .iter()
            .chain(self.segments.iter().flat_map(|s| s.tiles.tiles()))
            .map(|t| t.code)
            .collect();
        codes.sort_unstable();
        codes.dedup();
        codes
    }

    /// Calls `visit` with the predicted state at `seconds` since the base's first sample of
    /// every cell of tile `code`, in Morton order: base cells by their model, space only
    /// segments saw by the newest segment's constant state there.
    pub fn visit_predicted_states(
        &self,
        code: MortonCode,
        seconds: f64,
        mut visit: impl FnMut(MortonCode, u8, Occupancy),
    ) -> Result<(), FileError> {
        let mut out: Vec<CellState> = Vec::new();
        let mut covered: Vec<(u64, u64)> = Vec::new();
        if let Some(tile) = self.base.tile_containing(code) {
            self.base
                .visit_predicted_states(tile, seconds, |start, depth, state| {
                    covered.push((start.0, start.0 + voxels_per_node(depth)));
                    out.push((start, depth, state));
                })?;
        }
        for segment in self.segments.iter().rev() {
            let Ok(tile) = segment
                .tiles
                .tiles()
                .binary_search_by_key(&code, |t| t.code)
            else {
                continue;
            };
            let mut seen = Vec::new();
            let mut inherited_outside = false;
            segment.tiles.walk_tile(tile, WalkNeed::ModelOnly, |cell| {
                let range = (cell.start.0, cell.start.0 + voxels_per_node(cell.depth));
                seen.push(range);
                let mut uncovered = Vec::new();
                subtract(range, &covered, &mut uncovered);
                match cell.constant {
                    Some(state) => {
                        for (a, b) in uncovered {
                            aligned_nodes(a, b, |start, depth| out.push((start, depth, state)));
                        }
                    }
                    None => inherited_outside |= !uncovered.is_empty(),
                }
            })?;
            if inherited_outside {
                return Err(self.invalid(corrupt(
                    "segment tile",
                    format!(
                        "tile {:#x}: an inherited cell lies inside no base cell",
                        code.0
                    ),
                )));
            }
            covered = merge(covered, seen);
        }
        out.sort_unstable_by_key(|c| c.0);
        for (start, depth, state) in out {
            visit(start, depth, state);
        }
        Ok(())
    }

    /// The predicted map at `seconds` since the base's first sample, in Morton order.
    pub fn predicted_states(&self, seconds: f64) -> Result<Vec<CellState>, FileError> {
        let mut out = Vec::new();
        for code in self.predicted_tile_codes() {
            self.visit_predicted_states(code, seconds, |start, depth, state| {
                out.push((start, depth, state))
            })?;
        }
        Ok(out)
    }
}

/// Where a 2.0 file's base lies: after the root slots, up to `base_len`.
fn base_body(base_len: u64) -> Body {
    Body {
        header_at: LIVING_HEADER_AT,
        end: base_len,
        major: LIVING_MAJOR_VERSION,
    }
}

/// Reads the preamble and the root slots: the current root and its slot, checked against
/// the bytes the source holds now.
fn read_root(source: &dyn ByteSource, limits: &ReadLimits) -> Result<(Root, usize), FileError> {
    let path = source.name().to_path_buf();
    let invalid = |violation| FileError::Invalid {
        path: path.clone(),
        violation,
    };
    let io = |source| FileError::Io {
        path: path.clone(),
        source,
    };
    let size = source.current_size().map_err(io)?;
    if size < LIVING_HEADER_AT {
        return Err(invalid(corrupt(
            "file",
            format!("{size} bytes is too short for a FROctomap 2.0 file"),
        )));
    }
    let mut head = [0u8; LIVING_HEADER_AT as usize];
    source.read_exact_at(0, &mut head).map_err(io)?;
    let preamble: [u8; PREAMBLE_LEN] = head[..PREAMBLE_LEN]
        .try_into()
        .map_err(|_| invalid(corrupt("preamble", "truncated")))?;
    Header::decode_preamble(&preamble, limits, LIVING_MAJOR_VERSION).map_err(invalid)?;
    let slots: [u8; 2 * ROOT_SLOT_LEN] = head[PREAMBLE_LEN..]
        .try_into()
        .map_err(|_| invalid(corrupt("root", "truncated")))?;
    let (root, slot) = Root::current(&slots).map_err(invalid)?;
    // Measured after the slots were read: a writer makes a commit's bytes visible before its
    // slot, so a root read while it commits never runs past them.
    let size = source.current_size().map_err(io)?;
    if root.committed_len > size {
        return Err(invalid(corrupt(
            "root",
            format!(
                "{} bytes are committed but the file has {size} (truncated)",
                root.committed_len
            ),
        )));
    }
    if u64::from(root.sample_count) > limits.max_samples {
        return Err(invalid(FormatViolation::Limit {
            what: "sample count",
            value: u64::from(root.sample_count),
            limit: limits.max_samples,
        }));
    }
    Ok((root, slot))
}

/// The parts of `range` that no interval of `covered` (sorted, disjoint) covers.
fn subtract(range: (u64, u64), covered: &[(u64, u64)], out: &mut Vec<(u64, u64)>) {
    let (mut at, end) = range;
    let first = covered.partition_point(|&(_, b)| b <= at);
    for &(a, b) in &covered[first..] {
        if a >= end {
            break;
        }
        if a > at {
            out.push((at, a));
        }
        at = at.max(b);
        if at >= end {
            return;
        }
    }
    if at < end {
        out.push((at, end));
    }
}

/// Sorted, disjoint intervals covering both lists.
fn merge(mut a: Vec<(u64, u64)>, b: Vec<(u64, u64)>) -> Vec<(u64, u64)> {
    a.extend(b);
    a.sort_unstable();
    let mut out: Vec<(u64, u64)> = Vec::with_capacity(a.len());
    for (s, e) in a {
        match out.last_mut() {
            Some(last) if s <= last.1 => last.1 = last.1.max(e),
            _ => out.push((s, e)),
        }
    }
    out
}

/// Calls `node(start, depth)` for the largest octree nodes that tile `[start, end)`, in order.
fn aligned_nodes(mut start: u64, end: u64, mut node: impl FnMut(MortonCode, u8)) {
    while start < end {
        let mut depth = 16u8;
        while depth > 0 {
            let size = voxels_per_node(depth - 1);
            if start % size != 0 || start + size > end {
                break;
            }
            depth -= 1;
        }
        node(MortonCode(start), depth);
        start += voxels_per_node(depth);
    }
}

/// Takes the exclusive lock of the one writer, or fails at once if another holds it.
/// Syncs the directory holding `path`, so that a rename into it is durable. A directory
/// cannot be opened on every platform; where it can, a failed sync is said.
fn sync_parent(path: &Path) -> std::io::Result<()> {
    let parent = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    match std::fs::File::open(parent) {
        Ok(dir) => dir.sync_all(),
        Err(_) => Ok(()),
    }
}

fn lock_exclusive(file: &File, path: &Path) -> Result<(), FileError> {
    #[cfg(unix)]
    {
        use rustix::fs::{flock, FlockOperation};
        match flock(file, FlockOperation::NonBlockingLockExclusive) {
            Ok(()) => Ok(()),
            Err(rustix::io::Errno::WOULDBLOCK) => Err(FileError::Locked {
                path: path.to_path_buf(),
            }),
            Err(e) => Err(FileError::Io {
                path: path.to_path_buf(),
                source: e.into(),
            }),
        }
    }
    #[cfg(not(unix))]
    {
        let _ = file;
        Err(FileError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::Unsupported,
                "format 2.0 writers need flock (Unix)",
            ),
        })
    }
}

/// The one writer of a format 2.0 file: holds its exclusive lock from
/// [`open`](Self::open) until dropped, and appends segments.
pub struct LivingWriter {
    path: PathBuf,
    file: File,
    reader: LivingReader,
}

impl std::fmt::Debug for LivingWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LivingWriter")
            .field("path", &self.path)
            .field("root", &self.reader.root)
            .finish()
    }
}

impl LivingWriter {
    /// The file this writer holds is still the one its path names: a segment written into
    /// a file removed (or replaced by a compaction of another process) since it was opened
    /// would be committed and lost.
    fn check_in_place(&self) -> Result<(), FileError> {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let io = |source| FileError::Io {
                path: self.path.clone(),
                source,
            };
            let held = self.file.metadata().map_err(io)?;
            let named = std::fs::metadata(&self.path).map_err(io)?;
            if (held.dev(), held.ino()) != (named.dev(), named.ino()) {
                return Err(FileError::Replaced {
                    path: self.path.clone(),
                });
            }
        }
        Ok(())
    }

    /// Writes the 2.0 file `output` whose base is the 1.x file `input` (tiles copied
    /// verbatim, offsets moved past the root slots), with no segment. Atomic: `output`
    /// appears complete or not at all, and `input` is only read (it may be `output` itself,
    /// which is then replaced). Fails if a writer holds `output`.
    pub fn convert(input: &Path, output: &Path) -> Result<Root, FileError> {
        Self::convert_into(input, output, true)
    }

    /// Replaces this writer's file by the 2.0 file whose base is the 1.x file `base` (as
    /// [`convert`](Self::convert)), holding the lock until the new file is in place, so no
    /// segment is committed to the old file meanwhile: how `compact` swaps in its result.
    /// Readers that had the old file open keep reading it.
    pub fn replace_with_base(self, base: &Path) -> Result<Root, FileError> {
        let root = Self::convert_into(base, &self.path, false)?;
        drop(self);
        Ok(root)
    }

    /// Replaces this writer's file by the 2.0 file `replacement` holds (renamed over it,
    /// then the directory synced), and returns `replacement` as the writer of this path.
    /// Both locks are held throughout, so no other writer appends to either meanwhile; how
    /// a compaction made beside the file while segments kept coming is swapped in. Readers
    /// that had the old file open keep reading it. Everything `replacement` holds must be
    /// committed (its commits are synced).
    pub fn replace_with(
        self,
        replacement: LivingWriter,
        models: &ModelRegistry,
    ) -> Result<LivingWriter, FileError> {
        self.check_in_place()?;
        replacement.check_in_place()?;
        let io = |source| FileError::Io {
            path: self.path.clone(),
            source,
        };
        std::fs::rename(&replacement.path, &self.path).map_err(io)?;
        // Durable only once the directory is: until then a power loss could bring the old
        // file back under segments committed to the new one.
        sync_parent(&self.path).map_err(io)?;
        let reader = LivingReader::open_with_limits(&self.path, replacement.reader.limits, models)?;
        let LivingWriter { path, .. } = self;
        Ok(LivingWriter {
            path,
            file: replacement.file,
            reader,
        })
    }

    /// [`convert`](Self::convert); `lock`: take the lock of an existing `output` first
    /// (`false` when the caller holds it).
    fn convert_into(input: &Path, output: &Path, lock: bool) -> Result<Root, FileError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| FileError::Io {
                path: path.clone(),
                source,
            }
        };
        let base = FroctReader::open(input)?;
        // Held until the new file is in place: no writer may be appending to what it
        // replaces.
        let _held = match File::options().read(true).write(true).open(output) {
            Ok(_) if !lock => None,
            Ok(existing) => {
                lock_exclusive(&existing, output)?;
                Some(existing)
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(io(output)(e)),
        };
        let mut input_file = File::open(input).map_err(io(input))?;
        let mut preamble = [0u8; PREAMBLE_LEN];
        input_file.read_exact(&mut preamble).map_err(io(input))?;
        let old_header_len = u64::from(u32::from_le_bytes([
            preamble[12],
            preamble[13],
            preamble[14],
            preamble[15],
        ]));
        let old_data_start = PREAMBLE_LEN as u64 + old_header_len + 4;
        let header = base
            .header()
            .encode_as((LIVING_MAJOR_VERSION, LIVING_MINOR_VERSION));
        let new_data_start = LIVING_HEADER_AT + (header.len() - PREAMBLE_LEN) as u64;
        let data_end = base
            .tiles()
            .last()
            .map_or(old_data_start, |t| t.offset + u64::from(t.stored_len));
        let entries: Vec<TileEntry> = base
            .tiles()
            .iter()
            .map(|t| TileEntry {
                offset: t.offset - old_data_start + new_data_start,
                ..*t
            })
            .collect();
        let index = encode_index(&entries, base.summary());
        let index_offset = new_data_start + (data_end - old_data_start);
        let footer = encode_footer(index_offset, &index);
        let base_len = index_offset + (index.len() + FOOTER_LEN) as u64;
        let root = Root {
            sequence: 1,
            committed_len: base_len,
            base_len,
            last_segment: 0,
            segment_count: 0,
            sample_count: base.header().axis.len(),
        };
        let temp = froctomap_core::temporary_beside(output, std::ffi::OsStr::new(".froct-"))
            .map_err(io(output))?;
        {
            let mut out = std::io::BufWriter::with_capacity(1 << 20, temp.as_file());
            out.write_all(&header[..PREAMBLE_LEN])
                .and_then(|()| out.write_all(&root.encode()))
                .and_then(|()| out.write_all(&[0u8; ROOT_SLOT_LEN]))
                .and_then(|()| out.write_all(&header[PREAMBLE_LEN..]))
                .map_err(io(output))?;
            input_file
                .seek(SeekFrom::Start(old_data_start))
                .map_err(io(input))?;
            let copied = std::io::copy(
                &mut (&mut input_file).take(data_end - old_data_start),
                &mut out,
            )
            .map_err(io(input))?;
            if copied != data_end - old_data_start {
                return Err(FileError::Invalid {
                    path: input.to_path_buf(),
                    violation: corrupt("file", "shorter than its index says"),
                });
            }
            out.write_all(&index)
                .and_then(|()| out.write_all(&footer))
                .and_then(|()| out.flush())
                .map_err(io(output))?;
        }
        temp.as_file().sync_all().map_err(io(output))?;
        temp.persist(output).map_err(io(output))?;
        // The rename is durable only once the directory is: until then a power loss could
        // bring the old file back under segments committed to the new one.
        sync_parent(output).map_err(io(output))?;
        Ok(root)
    }

    /// Opens a 2.0 file for appending with the default limits and models: takes its
    /// exclusive lock (failing at once with [`FileError::Locked`] if another writer holds
    /// it) and reads its committed state.
    pub fn open(path: &Path) -> Result<Self, FileError> {
        Self::open_with_limits(
            path,
            ReadLimits::default(),
            &ModelRegistry::with_default_models(),
        )
    }

    /// [`open`](Self::open) with explicit limits (what the file may grow to) and models.
    pub fn open_with_limits(
        path: &Path,
        limits: ReadLimits,
        models: &ModelRegistry,
    ) -> Result<Self, FileError> {
        let file = File::options()
            .read(true)
            .write(true)
            .open(path)
            .map_err(|source| FileError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        lock_exclusive(&file, path)?;
        let reader = LivingReader::open_with_limits(path, limits, models)?;
        Ok(Self {
            path: path.to_path_buf(),
            file,
            reader,
        })
    }

    /// The committed state: base, segments, root.
    pub fn reader(&self) -> &LivingReader {
        &self.reader
    }

    /// Starts a segment of the samples of `axis`, which must all come after the file's last
    /// sample. Cuts what a crashed writer left past the committed length first. Nothing is
    /// visible to readers until [`SegmentWriter::commit`]; a segment dropped uncommitted
    /// leaves bytes past the committed length, which readers ignore and the next segment cuts.
    pub fn begin_segment(&mut self, axis: TimeAxis) -> Result<SegmentWriter<'_>, FileError> {
        self.check_in_place()?;
        let path = self.path.clone();
        let last = self.reader.last_instant();
        if axis.start() <= last {
            return Err(FileError::SegmentTime {
                path,
                first: axis.start(),
                last,
            });
        }
        let limits = self.reader.limits;
        let root = self.reader.root;
        let checks = [
            (
                "samples",
                u64::from(root.sample_count) + u64::from(axis.len()),
                limits.max_samples.min(u64::from(u32::MAX)),
            ),
            (
                "toggle blocks of a segment",
                u64::from(self.reader.header().toggles.blocks(axis.len())),
                limits.max_toggle_blocks,
            ),
            (
                "segments",
                u64::from(root.segment_count) + 1,
                limits.max_segments,
            ),
        ];
        for (what, value, limit) in checks {
            if value > limit {
                return Err(FileError::TooLarge {
                    path,
                    what,
                    value,
                    limit,
                });
            }
        }
        let io = |source| FileError::Io {
            path: self.path.clone(),
            source,
        };
        self.file.set_len(root.committed_len).map_err(io)?;
        (&self.file)
            .seek(SeekFrom::Start(root.committed_len))
            .map_err(io)?;
        Ok(SegmentWriter {
            first_sample: root.sample_count,
            offset: root.committed_len,
            entries: Vec::new(),
            patches: Vec::new(),
            axis,
            writer: self,
        })
    }
}

/// One segment being written: its tiles in increasing Morton order, then
/// [`commit`](Self::commit).
pub struct SegmentWriter<'w> {
    writer: &'w mut LivingWriter,
    axis: TimeAxis,
    first_sample: u32,
    offset: u64,
    entries: Vec<TileEntry>,
    /// Indices (into `entries`) of the patch tiles, with what observes their remainders.
    patches: Vec<(u32, TileRemainder)>,
}

impl std::fmt::Debug for SegmentWriter<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SegmentWriter")
            .field("path", &self.writer.path)
            .field("first_sample", &self.first_sample)
            .field("tiles", &self.entries.len())
            .finish()
    }
}

impl SegmentWriter<'_> {
    /// The segment's own samples.
    pub fn axis(&self) -> &TimeAxis {
        &self.axis
    }

    /// The global index of the segment's first sample.
    pub fn first_sample(&self) -> u32 {
        self.first_sample
    }

    /// An encoder for one tile of this segment.
    pub fn tile_encoder(&self) -> SegmentTileEncoder {
        SegmentTileEncoder::new(&self.writer.reader.header().tile_layout(), &self.axis)
    }

    /// Encodes and writes one tile's cells (sorted, inside one tile), after checking that
    /// each inherited cell lies inside one base cell (reading the base tile's cells).
    pub fn push_tile(
        &mut self,
        cells: impl IntoIterator<Item = SegmentCell>,
    ) -> Result<(), FileError> {
        let encode_error = |source| FileError::TileEncode {
            path: self.writer.path.clone(),
            source,
        };
        let mut encoder = self.tile_encoder();
        let mut inherited = Vec::new();
        for cell in cells {
            if let SegmentContent::Inherited { .. } = cell.content {
                inherited.push((cell.start.0, cell.start.0 + voxels_per_node(cell.depth)));
            }
            encoder.push(cell).map_err(encode_error)?;
        }
        let tile = encoder.finish().map_err(encode_error)?;
        if !inherited.is_empty() {
            // The states are not needed, only that every inherited cell has a base cell.
            self.writer
                .reader
                .base_predictions(tile.code(), &inherited, 0.0)?;
        }
        self.write_tile(&tile)
    }

    /// Writes a tile made by [`tile_encoder`](Self::tile_encoder); tiles must come in
    /// strictly increasing Morton order. Unlike [`push_tile`](Self::push_tile) it does not
    /// check inherited cells against the base: a reader reports one outside every base cell
    /// as corrupt when it reads that tile.
    pub fn write_tile(&mut self, tile: &EncodedTile) -> Result<(), FileError> {
        let path = &self.writer.path;
        let entry = seal_tile(path, self.entries.last(), tile, self.offset)?;
        (&self.writer.file)
            .write_all(tile.stored())
            .map_err(|source| FileError::Io {
                path: path.clone(),
                source,
            })?;
        self.entries.push(entry);
        self.offset += u64::from(entry.stored_len);
        Ok(())
    }

    /// Writes a tile made by [`tile_encoder`](Self::tile_encoder) as a *patch tile*
    /// (FORMAT.md §10.6): besides its own cells, the segment holds every part of the base
    /// tile with the same code that they do not cover, observed where `remainder` says
    /// (an observation mask over the segment's samples; `None`: at every sample that is not
    /// missing) in the base cell's frozen prediction. So a tile whose maps match the base's
    /// predictions stores only where they differ. The base must have a tile with this code,
    /// the mask must lie within the segment's samples and hold at least one position (an
    /// empty mask would observe nothing; the format has no way to say so)
    /// ([`FileError::TileEncode`] otherwise, nothing written).
    pub fn write_patch_tile(
        &mut self,
        tile: &EncodedTile,
        remainder: Option<Arc<Toggles>>,
    ) -> Result<(), FileError> {
        self.write_patch_tile_with(tile, TileRemainder::uniform(remainder))
    }

    /// [`write_patch_tile`](Self::write_patch_tile) whose remainder several masks observe
    /// (FORMAT.md §10.7): the base cells that `remainder`'s runs name (by rank in the base
    /// tile) take their run's mask, or are observed at no sample, the others the default
    /// mask. The runs must be sorted, disjoint, non-empty, name masks the remainder has and
    /// base cells the base tile has; every mask obeys `write_patch_tile`'s rules
    /// ([`FileError::TileEncode`] otherwise, nothing written).
    pub fn write_patch_tile_with(
        &mut self,
        tile: &EncodedTile,
        remainder: TileRemainder,
    ) -> Result<(), FileError> {
        let masks = || std::iter::once(&remainder.default).chain(&remainder.masks);
        let beyond = masks().any(|mask| {
            mask.as_ref()
                .and_then(|mask| mask.as_slice().last())
                .is_some_and(|&last| last >= self.axis.len())
        });
        if beyond {
            return Err(FileError::TileEncode {
                path: self.writer.path.clone(),
                source: TileEncodeError::BeyondAxis {
                    start: tile.code().0,
                    list: "remainder mask",
                },
            });
        }
        if masks().any(|mask| mask.as_ref().is_some_and(|mask| mask.is_empty())) {
            return Err(FileError::TileEncode {
                path: self.writer.path.clone(),
                source: TileEncodeError::EmptyRemainderMask {
                    code: tile.code().0,
                },
            });
        }
        let base = &self.writer.reader.base;
        let Some(base_tile) = base.tile_containing(tile.code()) else {
            return Err(FileError::TileEncode {
                path: self.writer.path.clone(),
                source: TileEncodeError::NoBaseTile {
                    code: tile.code().0,
                },
            });
        };
        let base_cells = u64::from(base.tiles()[base_tile].cell_count);
        if !remainder.is_well_formed() || remainder.ranks_named() > base_cells {
            return Err(FileError::TileEncode {
                path: self.writer.path.clone(),
                source: TileEncodeError::BadRemainderRuns {
                    code: tile.code().0,
                },
            });
        }
        let index = u32::try_from(self.entries.len()).map_err(|_| FileError::TileEncode {
            path: self.writer.path.clone(),
            source: TileEncodeError::TooLarge("segment index"),
        })?;
        self.write_tile(tile)?;
        self.patches.push((index, remainder));
        Ok(())
    }

    /// Commits the segment: writes its record after its tiles, syncs, writes the root slot
    /// that is not current with the next sequence, syncs. A crash before the second sync
    /// leaves the previous commit; after it, this one. Returns the new root.
    pub fn commit(self) -> Result<Root, FileError> {
        let writer = self.writer;
        let io = |source| FileError::Io {
            path: writer.path.clone(),
            source,
        };
        let held = writer.reader.root;
        let record = encode_record(
            held.last_segment,
            self.first_sample,
            &self.axis,
            &self.entries,
            &self.patches,
        )
        .map_err(|source| FileError::TileEncode {
            path: writer.path.clone(),
            source,
        })?;
        (&writer.file).write_all(&record).map_err(io)?;
        writer.file.sync_data().map_err(io)?;
        let root = Root {
            sequence: held.sequence + 1,
            committed_len: self.offset + record.len() as u64,
            base_len: held.base_len,
            last_segment: self.offset,
            segment_count: held.segment_count + 1,
            sample_count: self.first_sample + self.axis.len(),
        };
        let slot = 1 - writer.reader.slot.min(1);
        (&writer.file)
            .seek(SeekFrom::Start(Root::slot_offset(slot)))
            .and_then(|_| (&writer.file).write_all(&root.encode()))
            .map_err(io)?;
        writer.file.sync_data().map_err(io)?;
        writer.reader.refresh()?;
        Ok(root)
    }
}

const _: () = assert!(ROOT_SLOTS_AT == PREAMBLE_LEN as u64);
