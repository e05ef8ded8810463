//! One reader for every FROctomap file the query layer opens: a 1.x file ([`FroctReader`])
//! or a 2.0 living map ([`LivingReader`]: a base and committed segments), behind the
//! [`SeriesRead`] view that retrieval, prediction and export use.
//!
//! Whole-history analyses (evaluation, anomalies, dynamics, one voxel's history, per-cell
//! statistics) read cells with their models over the whole axis, which a 1.x body holds:
//! [`FroctFile::whole_history`] gives it for a 1.x file and for a 2.0 file without
//! segments (its base), and [`ConvertError::NeedsCompaction`] for a 2.0 file with
//! segments, which `froctomap compact` turns into one base.

use crate::error::ConvertError;
use froctomap_core::{Leaf, MortonCode, Occupancy, Timestamp};
use froctomap_file::{FileError, FroctReader, Header, LivingReader, TileEntry};
use std::path::Path;

/// `visit(start, depth, state)` of a cell.
pub type StateVisit<'a> = &'a mut dyn FnMut(MortonCode, u8, Occupancy);

/// What retrieval, prediction and export need of a series file, whatever its version: its
/// samples (global indices over the base and every segment), the tiles and cell states of
/// the map observed at a sample, and the predicted map at any instant.
///
/// [`FroctReader`] (1.x), [`LivingReader`] (2.0) and [`FroctFile`] (either) implement it,
/// so `&reader` of any of them is a `&dyn SeriesRead`.
pub trait SeriesRead: Sync {
    /// The file's name, for errors.
    fn path(&self) -> &Path;
    /// The header (of the base for a 2.0 file): resolution, tile depth, model, and the
    /// instant model time counts from (its axis's start).
    fn header(&self) -> &Header;
    /// Samples of the whole series, missing ones included.
    fn sample_count(&self) -> u32;
    /// The instant of a sample.
    fn sample_time(&self, sample: u32) -> Option<Timestamp>;
    /// `true` when no map exists at a sample (or it lies beyond the series).
    fn is_missing(&self, sample: u32) -> bool;
    /// The last sample with a map at or before `t`.
    fn sample_at_or_before(&self, t: Timestamp) -> Option<u32>;
    /// The last instant of the series.
    fn last_instant(&self) -> Timestamp;
    /// The first instant of the series.
    fn first_instant(&self) -> Timestamp {
        self.header().axis.start()
    }
    /// Committed segments (0 for a 1.x file).
    fn segment_count(&self) -> usize {
        0
    }
    /// The whole history as one 1.x body, when the file is one: a 1.x file, or a 2.0 file
    /// without segments (its base).
    fn whole_body(&self) -> Option<&FroctReader>;
    /// The tiles that hold the map observed at `sample`.
    fn observed_tiles(&self, sample: u32) -> &[TileEntry];
    /// Each cell of tile `tile` of [`observed_tiles`](Self::observed_tiles) observed at
    /// `sample`, with its state there, in Morton order.
    fn visit_observed(
        &self,
        sample: u32,
        tile: usize,
        visit: StateVisit<'_>,
    ) -> Result<(), FileError>;
    /// Codes of the tiles of the predicted map, in Morton order, with a bound on each
    /// one's cells (for buffers).
    fn predicted_tiles(&self) -> Vec<(MortonCode, usize)>;
    /// Each cell of tile `code` of the predicted map at `seconds` after the first instant,
    /// with its predicted state, in Morton order.
    fn visit_predicted(
        &self,
        code: MortonCode,
        seconds: f64,
        visit: StateVisit<'_>,
    ) -> Result<(), FileError>;
    /// The leaves of tile `code` of the predicted map with `log_odds` of their `p(t)`.
    fn predicted_leaves(
        &self,
        code: MortonCode,
        seconds: f64,
        log_odds: &dyn Fn(f64) -> f32,
        out: &mut Vec<Leaf>,
    ) -> Result<(), FileError>;
}

impl SeriesRead for FroctReader {
    fn path(&self) -> &Path {
        FroctReader::path(self)
    }
    fn header(&self) -> &Header {
        FroctReader::header(self)
    }
    fn sample_count(&self) -> u32 {
        self.header().axis.len()
    }
    fn sample_time(&self, sample: u32) -> Option<Timestamp> {
        self.header().axis.time(sample)
    }
    fn is_missing(&self, sample: u32) -> bool {
        let axis = &self.header().axis;
        sample >= axis.len() || axis.is_missing(sample)
    }
    fn sample_at_or_before(&self, t: Timestamp) -> Option<u32> {
        self.header().axis.last_at_or_before(t)
    }
    fn last_instant(&self) -> Timestamp {
        self.header().axis.end()
    }
    fn whole_body(&self) -> Option<&FroctReader> {
        Some(self)
    }
    fn observed_tiles(&self, _sample: u32) -> &[TileEntry] {
        self.tiles()
    }
    fn visit_observed(
        &self,
        sample: u32,
        tile: usize,
        visit: StateVisit<'_>,
    ) -> Result<(), FileError> {
        self.visit_observed_states(tile, sample, visit)
    }
    fn predicted_tiles(&self) -> Vec<(MortonCode, usize)> {
        self.tiles()
            .iter()
            .map(|t| (t.code, t.cell_count as usize))
            .collect()
    }
    fn visit_predicted(
        &self,
        code: MortonCode,
        seconds: f64,
        visit: StateVisit<'_>,
    ) -> Result<(), FileError> {
        match self.tile_containing(code) {
            Some(tile) => self.visit_predicted_states(tile, seconds, visit),
            None => Ok(()),
        }
    }
    fn predicted_leaves(
        &self,
        code: MortonCode,
        seconds: f64,
        log_odds: &dyn Fn(f64) -> f32,
        out: &mut Vec<Leaf>,
    ) -> Result<(), FileError> {
        match self.tile_containing(code) {
            Some(tile) => FroctReader::predicted_leaves(self, tile, seconds, log_odds, out),
            None => Ok(()),
        }
    }
}

impl SeriesRead for LivingReader {
    fn path(&self) -> &Path {
        LivingReader::path(self)
    }
    fn header(&self) -> &Header {
        LivingReader::header(self)
    }
    fn sample_count(&self) -> u32 {
        LivingReader::sample_count(self)
    }
    fn sample_time(&self, sample: u32) -> Option<Timestamp> {
        LivingReader::sample_time(self, sample)
    }
    fn is_missing(&self, sample: u32) -> bool {
        LivingReader::is_missing(self, sample)
    }
    fn sample_at_or_before(&self, t: Timestamp) -> Option<u32> {
        LivingReader::sample_at_or_before(self, t)
    }
    fn last_instant(&self) -> Timestamp {
        LivingReader::last_instant(self)
    }
    fn segment_count(&self) -> usize {
        LivingReader::segment_count(self)
    }
    fn whole_body(&self) -> Option<&FroctReader> {
        (self.segment_count() == 0).then(|| self.base())
    }
    fn observed_tiles(&self, sample: u32) -> &[TileEntry] {
        self.tiles_at(sample)
    }
    fn visit_observed(
        &self,
        sample: u32,
        tile: usize,
        visit: StateVisit<'_>,
    ) -> Result<(), FileError> {
        self.visit_observed_states(sample, tile, visit)
    }
    fn predicted_tiles(&self) -> Vec<(MortonCode, usize)> {
        if self.segment_count() == 0 {
            return self.base().predicted_tiles();
        }
        let cells = |code: MortonCode| {
            let base = self
                .base()
                .tile_containing(code)
                .map_or(0, |t| self.base().tiles()[t].cell_count as usize);
            // A segment's constant cells outside every base cell are split into aligned
            // nodes: their count is not bounded by the stored cells, so this is a hint.
            // Each count is bounded alone by the limits, their sum is not: it saturates,
            // and the map's reader clamps it.
            (0..self.segment_count())
                .filter_map(|k| {
                    let tiles = self.segment_tiles(k);
                    tiles
                        .binary_search_by_key(&code, |t| t.code)
                        .ok()
                        .map(|t| tiles[t].cell_count as usize)
                })
                .fold(base, usize::saturating_add)
        };
        self.predicted_tile_codes()
            .into_iter()
            .map(|code| (code, cells(code)))
            .collect()
    }
    fn visit_predicted(
        &self,
        code: MortonCode,
        seconds: f64,
        visit: StateVisit<'_>,
    ) -> Result<(), FileError> {
        self.visit_predicted_states(code, seconds, visit)
    }
    /// The base's cells with their model's `p(t)`, exactly as in a 1.x file; space only
    /// segments saw with the newest segment's constant state (`p` 0 or 1, clamped by
    /// `log_odds`), as [`LivingReader::visit_predicted_states`] decides it.
    fn predicted_leaves(
        &self,
        code: MortonCode,
        seconds: f64,
        log_odds: &dyn Fn(f64) -> f32,
        out: &mut Vec<Leaf>,
    ) -> Result<(), FileError> {
        let mut base = Vec::new();
        SeriesRead::predicted_leaves(self.base(), code, seconds, log_odds, &mut base)?;
        if self.segment_count() == 0 {
            out.extend_from_slice(&base);
            return Ok(());
        }
        let mut base = base.into_iter().peekable();
        self.visit_predicted_states(code, seconds, |start, depth, state| {
            while base.next_if(|leaf| leaf.start < start).is_some() {}
            let log_odds = match base.next_if(|leaf| leaf.start == start && leaf.depth == depth) {
                Some(leaf) => leaf.log_odds,
                None => log_odds(if state.is_occupied() { 1.0 } else { 0.0 }),
            };
            out.push(Leaf {
                start,
                depth,
                log_odds,
            });
        })
    }
}

/// A FROctomap file of any version, as [`Context::open_series`](crate::Context::open_series)
/// opens it.
#[derive(Debug)]
// One per open file: boxing the larger reader would save nothing worth an indirection.
#[allow(clippy::large_enum_variant)]
pub enum FroctFile {
    /// A 1.0–1.2 file.
    Flat(FroctReader),
    /// A 2.0 file: a base and committed segments.
    Living(LivingReader),
}

impl FroctFile {
    /// Opens a file of any version with the default limits and models (as
    /// [`FroctReader::open`] and [`LivingReader::open`]); a program with its own registries
    /// uses [`Context::open_series`](crate::Context::open_series).
    pub fn open(path: &Path) -> Result<Self, FileError> {
        // A FIFO or device is refused before it is opened: opening one may never return.
        let living = crate::files::is_living_file(path).map_err(|error| match error {
            ConvertError::File(error) => error,
            other => FileError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    froctomap_core::error_message(&other),
                ),
            },
        })?;
        if living {
            LivingReader::open(path).map(FroctFile::Living)
        } else {
            FroctReader::open(path).map(FroctFile::Flat)
        }
    }

    /// The format version, `(major, minor)`.
    pub fn version(&self) -> (u16, u16) {
        match self {
            FroctFile::Flat(reader) => reader.header().version,
            FroctFile::Living(_) => (
                froctomap_file::LIVING_MAJOR_VERSION,
                froctomap_file::LIVING_MINOR_VERSION,
            ),
        }
    }

    /// The reader of the whole history as one 1.x body (cells, models and toggles over
    /// every sample), which whole-history analyses need: the file itself, or the base of a
    /// 2.0 file without segments. A 2.0 file with segments is refused with
    /// [`ConvertError::NeedsCompaction`].
    pub fn whole_history(&self) -> Result<&FroctReader, ConvertError> {
        match self {
            FroctFile::Flat(reader) => Ok(reader),
            FroctFile::Living(living) if living.segment_count() == 0 => Ok(living.base()),
            FroctFile::Living(living) => Err(ConvertError::NeedsCompaction {
                path: living.path().to_path_buf(),
                segments: living.segment_count(),
            }),
        }
    }

    /// The 2.0 reader, if this is a 2.0 file.
    pub fn living(&self) -> Option<&LivingReader> {
        match self {
            FroctFile::Living(living) => Some(living),
            FroctFile::Flat(_) => None,
        }
    }

    /// Reads what was committed since the file was opened (or last refreshed): `true` when
    /// the view changed. A 1.x file is never changed in place (a new one is renamed over
    /// it), so its view never changes.
    pub fn refresh(&mut self) -> Result<bool, ConvertError> {
        match self {
            FroctFile::Flat(_) => Ok(false),
            FroctFile::Living(living) => Ok(living.refresh()?),
        }
    }

    fn view(&self) -> &dyn SeriesRead {
        match self {
            FroctFile::Flat(reader) => reader,
            FroctFile::Living(living) => living,
        }
    }
}

impl SeriesRead for FroctFile {
    fn path(&self) -> &Path {
        self.view().path()
    }
    fn header(&self) -> &Header {
        self.view().header()
    }
    fn sample_count(&self) -> u32 {
        self.view().sample_count()
    }
    fn sample_time(&self, sample: u32) -> Option<Timestamp> {
        self.view().sample_time(sample)
    }
    fn is_missing(&self, sample: u32) -> bool {
        self.view().is_missing(sample)
    }
    fn sample_at_or_before(&self, t: Timestamp) -> Option<u32> {
        self.view().sample_at_or_before(t)
    }
    fn last_instant(&self) -> Timestamp {
        self.view().last_instant()
    }
    fn segment_count(&self) -> usize {
        self.view().segment_count()
    }
    fn whole_body(&self) -> Option<&FroctReader> {
        self.view().whole_body()
    }
    fn observed_tiles(&self, sample: u32) -> &[TileEntry] {
        self.view().observed_tiles(sample)
    }
    fn visit_observed(
        &self,
        sample: u32,
        tile: usize,
        visit: StateVisit<'_>,
    ) -> Result<(), FileError> {
        self.view().visit_observed(sample, tile, visit)
    }
    fn predicted_tiles(&self) -> Vec<(MortonCode, usize)> {
        self.view().predicted_tiles()
    }
    fn visit_predicted(
        &self,
        code: MortonCode,
        seconds: f64,
        visit: StateVisit<'_>,
    ) -> Result<(), FileError> {
        self.view().visit_predicted(code, seconds, visit)
    }
    fn predicted_leaves(
        &self,
        code: MortonCode,
        seconds: f64,
        log_odds: &dyn Fn(f64) -> f32,
        out: &mut Vec<Leaf>,
    ) -> Result<(), FileError> {
        self.view().predicted_leaves(code, seconds, log_odds, out)
    }
}
