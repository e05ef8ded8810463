//! `ingest`: the one pipeline behind `build`, `append` and `record` — a series of maps
//! added to a target file, which a build creates empty.
//!
//! Every target runs the same stages over the new maps; only the plan before them and the
//! write after them depend on the target:
//!
//! 1. **plan** — per target: the axis the new maps are placed on, the tile depth, and what
//!    the target fixes (an existing file's resolution; the map a rewrite continues from).
//! 2. **intake** ([`Intake`]) — shared: input check → change extraction → accumulation, the
//!    left-out inputs tallied once, the axis given missing samples for them.
//! 3. **write** — per target: a new file fitted and written ([`IngestTarget::NewFile`]), an
//!    existing file's cells merged and refitted ([`IngestTarget::Rewrite`]), or the new
//!    maps joined to a format 2.0 file's base and committed as a segment
//!    ([`IngestTarget::Segment`], [`IngestTarget::Writer`]).

use super::accumulate::accumulate_series;
use super::accumulate::Accumulated;
use super::axis::{samples_left_out, with_absent_missing};
use super::check::{self, InputCheck, TileBudget};
use super::counts::ClassCounts;
use super::extract::{ChangeExtractor, ExtractOptions, SampleChanges};
use super::spill::SpillPlace;
use crate::context::Context;
use crate::error::ConvertError;
use crate::inputs::{CollectedInputs, SeriesInput};
use crate::progress::Progress;
use crate::skip::SkippedInput;
use crate::snapshot_changes::Accepted;
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_file::{Codec, LivingWriter, ToggleLayout};
use froctomap_formats::{Backend, ReadOptions};
use froctomap_temporal::{ModelConfig, TimeAxis};
use serde::Serialize;
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The default [`IngestOptions::memory`]: 64 MiB. Small enough that peak memory stops growing
/// with the series within hours of 5 s snapshots (on the benchmark's map a quarter of a day's
/// histories take about 80 MiB), at the price of writing the histories to disk once; series
/// whose histories fit in it never spill.
pub const DEFAULT_BUILD_MEMORY: u64 = 64 << 20;

/// How to ingest: one set of options for every target. The file settings (`model`,
/// `config`'s outlier mode, `tile_depth`, `codec`, `toggles`, `resolution`) make a new
/// file; an existing file keeps its own, and of `config` only its model options are used
/// (for the refit of [`IngestTarget::Rewrite`]).
#[derive(Clone, Debug)]
pub struct IngestOptions {
    /// Temporal model of a new file (see `froctomap_temporal::ModelRegistry`). Default
    /// `fremen-periods`, which works on any time axis.
    pub model: String,
    /// Model settings: lossless/lossy (a new file's), and the model's own options (see its
    /// descriptor). A file does not record the options it was built with: to rewrite one,
    /// give the ones of its build (none: the model's defaults).
    pub config: ModelConfig,
    /// Depth of a new file's tiles (default 10: cubes of 64 voxels per edge).
    pub tile_depth: u8,
    /// A new file's tile codec (default zstd level 19).
    pub codec: Codec,
    /// How a new file's toggle lists are stored (default: blocks of 256 samples, format
    /// 1.1, so that a query at one sample reads one block).
    pub toggles: ToggleLayout,
    /// Leave unreadable files and files of another resolution out (listed in the report)
    /// instead of stopping.
    pub skip_bad: bool,
    /// A new file's resolution, metres; `None`: the one most input headers give. Inputs of
    /// another resolution (for an existing file: of another than the file's) are refused
    /// (or left out with `skip_bad`).
    pub resolution: Option<f64>,
    /// With `skip_bad`, go on even when more than half of the inputs are left out (refused
    /// by default: the series is probably not the one meant; `record` allows it, its
    /// commits being pieces of one stream).
    pub allow_mostly_skipped: bool,
    /// Force the input map format.
    pub input_format: Option<String>,
    /// Preferred implementation for reading maps.
    pub backend: Option<Backend>,
    /// Extra metadata stored in the file header (replacing keys of the same name; a segment
    /// leaves the header as it is).
    pub metadata: Map<String, Value>,
    /// Files decoded in parallel per batch (bounds memory; default 8 × threads).
    pub batch: usize,
    /// When this ingest happened, stored in the metadata to the second (`created` of a new
    /// file, `appended` of a rewritten one; a segment leaves the header as it is); `None`:
    /// now. A fixed time makes the file reproducible (the timings are then not stored
    /// either): the same inputs and options give the same bytes.
    pub time: Option<Timestamp>,
    /// Memory budget of the accumulated histories, in bytes (default 64 MiB). What grows with
    /// the number of snapshots (each cell's closed runs, the regions partial views hid) is
    /// spilled to disk when the histories reach it, and read back one tile at a time for
    /// fitting, so peak memory depends on the map and this budget, not on the length of
    /// the series. The cells themselves, the snapshots being read and the tiles being
    /// fitted come on top. The output is the same whatever the budget; `0` spills after
    /// every snapshot.
    pub memory: u64,
    /// Directory for the spill data (default: the target file's directory). The data is
    /// kept in a hidden `.froct-spill-…` directory there, removed when the ingest ends,
    /// whether it succeeds or fails (and on Ctrl-C/SIGTERM in the command-line tool).
    pub tmp_dir: Option<PathBuf>,
}

impl Default for IngestOptions {
    fn default() -> Self {
        Self {
            model: froctomap_temporal::models::DEFAULT_MODEL.to_string(),
            config: ModelConfig::default(),
            tile_depth: 10,
            codec: Codec::default(),
            toggles: ToggleLayout::DEFAULT,
            skip_bad: false,
            resolution: None,
            allow_mostly_skipped: false,
            input_format: None,
            backend: None,
            metadata: Map::new(),
            batch: 8 * rayon::current_num_threads().max(1),
            time: None,
            memory: DEFAULT_BUILD_MEMORY,
            tmp_dir: None,
        }
    }
}

impl IngestOptions {
    /// How the new maps are extracted, into tiles of `tile_depth` (the target's).
    fn extract_options(&self, context: &Context, tile_depth: u8) -> ExtractOptions<'_> {
        ExtractOptions {
            read: ReadOptions {
                format: self.input_format.as_deref(),
                backend: self.backend,
            },
            skip_bad: self.skip_bad,
            batch: self.batch,
            tiles: TileBudget {
                tile_depth,
                max_tiles: context.limits().max_snapshot_tiles,
            },
        }
    }
}

/// Where the maps of an ingest go.
#[derive(Debug)]
pub enum IngestTarget<'a> {
    /// A new file at this path (a build; a file there is replaced, atomically).
    NewFile(&'a Path),
    /// The existing file at this path (format 1.x), rewritten with the new maps: every
    /// cell refitted on its whole history, the file replaced atomically (`append`).
    Rewrite(&'a Path),
    /// The existing file at this path as a format 2.0 file, the new maps one segment: a
    /// 2.0 file gets it under its writer's lock; a 1.x file is first converted beside it
    /// and renamed over it only once the segment is committed (`append --format-version
    /// 2.0`).
    Segment(&'a Path),
    /// The format 2.0 file this writer holds, the new maps one segment (`record`'s
    /// commits, which keep the writer and its lock between them).
    Writer(&'a mut LivingWriter),
}

/// The maps of an ingest: a time-sorted series ([`collect_inputs`](crate::collect_inputs))
/// and the damaged parts of its recordings left out before any map was read, which the
/// report lists first among the inputs left out.
#[derive(Clone, Copy, Debug)]
pub struct IngestInputs<'a> {
    /// The maps, sorted by time, with distinct times.
    pub maps: &'a [SeriesInput],
    /// Left out while collecting (the recording and why).
    pub left_out: &'a [SkippedInput],
}

impl<'a> From<&'a [SeriesInput]> for IngestInputs<'a> {
    fn from(maps: &'a [SeriesInput]) -> Self {
        Self {
            maps,
            left_out: &[],
        }
    }
}

impl<'a> From<&'a Vec<SeriesInput>> for IngestInputs<'a> {
    fn from(maps: &'a Vec<SeriesInput>) -> Self {
        maps.as_slice().into()
    }
}

impl<'a> From<&'a CollectedInputs> for IngestInputs<'a> {
    fn from(collected: &'a CollectedInputs) -> Self {
        Self {
            maps: &collected.series,
            left_out: &collected.skipped,
        }
    }
}

/// What an ingest did. Its JSON is `froctomap build --json`'s (with `extended` when the
/// target existed); `froctomap append --json` prints its [`AppendReport`](crate::AppendReport)
/// view.
#[derive(Clone, Debug, Serialize)]
pub struct IngestReport {
    /// The file written.
    pub output: PathBuf,
    /// Snapshots given.
    pub inputs: usize,
    /// Snapshots used (added).
    pub used: usize,
    /// Files and parts of recordings left out with `skip_bad`, and why.
    pub skipped: Vec<SkippedInput>,
    /// Reader warnings (file, message), e.g. tolerated header problems.
    pub warnings: Vec<(PathBuf, String)>,
    /// Total bytes of the input files used.
    pub input_bytes: u64,
    /// Samples of the time axis (of the whole file).
    pub samples: u32,
    /// `true` for a regular axis (of the new maps, for a segment).
    pub regular_axis: bool,
    /// Cells by class (written by this ingest: a segment's own).
    pub cells: ClassCounts,
    /// Voxels by class (as `cells`).
    pub voxels: ClassCounts,
    /// Outlier toggles stored (lossless).
    pub toggles: u64,
    /// Observed cell-samples the model gets wrong without outliers (lossy files store no
    /// outliers, so these are their reconstruction errors; 0 for a segment, which keeps
    /// every observed state exactly).
    pub model_errors: u64,
    /// Voxel-samples of the new maps whose state changed from the snapshot before (a
    /// segment's first map is compared with nothing).
    pub changed_voxels: u64,
    /// Bytes of the file now.
    pub file_bytes: u64,
    /// Header bytes (0 for a segment, written after the committed bytes).
    pub header_bytes: u64,
    /// Index and footer bytes (0 for a segment).
    pub index_bytes: u64,
    /// Stored tile bytes (0 for a segment).
    pub tile_bytes: u64,
    /// Seconds spent reading and accumulating the inputs.
    pub read_seconds: f64,
    /// Of those, seconds spent applying changes to the cells (the part that is sequential).
    pub accumulate_seconds: f64,
    /// Seconds spent fitting (or joining), encoding and writing.
    pub model_seconds: f64,
    /// Bytes of history spilled to disk to stay within [`IngestOptions::memory`] (0: all
    /// stayed in memory). Not stored in the file, whose bytes do not depend on the budget.
    pub spilled_bytes: u64,
    /// The most times one accumulating thread spilled.
    pub spills: usize,
    /// What the target was before (`None`: a new file).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extended: Option<Extended>,
}

/// The file an ingest added to, before and after.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Extended {
    /// Samples of the time axis before.
    pub samples_before: u32,
    /// First instant of the file.
    #[serde(serialize_with = "as_iso8601")]
    pub start: Timestamp,
    /// Last instant before.
    #[serde(serialize_with = "as_iso8601")]
    pub end_before: Timestamp,
    /// Last instant now.
    #[serde(serialize_with = "as_iso8601")]
    pub end: Timestamp,
    /// `true` when the file keeps every observed state exactly.
    pub lossless: bool,
    /// Bytes of the file before.
    pub bytes_before: u64,
    /// Segments of a format 2.0 file now (`None`: a 1.x file, rewritten).
    pub segments: Option<usize>,
    /// `true` when a 1.x file was converted to format 2.0 for its first segment.
    pub converted: bool,
}

pub(super) fn as_iso8601<S: serde::Serializer>(
    t: &Timestamp,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(&iso8601(*t))
}

/// One ingest's inputs and settings, handed to the target's plan and write.
pub(super) struct Run<'a> {
    pub context: &'a Context,
    pub inputs: &'a [SeriesInput],
    pub options: &'a IngestOptions,
    pub progress: &'a dyn Progress,
    /// When the ingest started (reading time is counted from it).
    pub started: Instant,
}

/// Stage 2, shared by every target: the new maps checked, extracted and accumulated on the
/// plan's axis.
pub(super) struct Intake<'a> {
    /// The axis the new maps are placed on (has every input's time).
    pub axis: TimeAxis,
    /// The target's tile depth.
    pub tile_depth: u8,
    /// The existing file the maps go into and its resolution, which inputs must have;
    /// `None`: a new file, of the resolution the options give or most headers do.
    pub file: Option<(&'a Path, f64)>,
    /// The map the new histories continue from (a rewrite's last observed map, at its
    /// sample of `axis`): its changes from nothing, and the map the first input is
    /// compared with. `None`: the first input is compared with nothing.
    pub seed: Option<(SampleChanges, Accepted)>,
    /// Where spill data goes unless the options say.
    pub spill_dir: &'a Path,
}

/// What the intake gives the target's write.
pub(super) struct Intaken {
    pub accumulated: Accumulated,
    /// The plan's axis, with the samples of inputs left out missing when it is regular.
    pub axis: TimeAxis,
    /// `true` when `axis` differs from the plan's (the model is to be prepared again).
    pub regridded: bool,
    /// The samples without a snapshot (sorted).
    pub absent: Vec<u32>,
    /// The series' resolution.
    pub resolution: f64,
    /// Snapshots used.
    pub used: usize,
    pub input_bytes: u64,
    /// Inputs left out by the check and by extraction, in that order.
    pub skipped: Vec<SkippedInput>,
    pub warnings: Vec<(PathBuf, String)>,
    /// Voxel-samples of the inputs whose state changed (the seed not counted).
    pub changed_voxels: u64,
    pub read_seconds: f64,
    /// Where `accumulated` spilled: removed when dropped, so held (never read) until the
    /// write is done.
    _spill_place: SpillPlace,
}

impl Intake<'_> {
    pub fn run(self, run: &Run<'_>) -> Result<Intaken, ConvertError> {
        let Run {
            context,
            inputs,
            options,
            progress,
            ..
        } = *run;
        let extract = options.extract_options(context, self.tile_depth);
        let check = InputCheck {
            formats: context.formats(),
            read: extract.read,
            skip_bad: options.skip_bad,
            resolution: self.file.map(|(_, r)| r).or(options.resolution),
            allow_mostly_skipped: options.allow_mostly_skipped,
        };
        let checked = match self.file {
            Some((file, resolution)) => check.run_for_file(inputs, file, resolution, progress)?,
            None => check.run(inputs, &SeriesInput::is_recorded, progress)?,
        };

        let seeded = u64::from(self.seed.is_some());
        progress.stage("reading snapshots", inputs.len() as u64 + seeded);
        let mut extractor =
            ChangeExtractor::new(context, extract, inputs, &checked, &self.axis, progress);
        let mut seed_voxels = 0;
        extractor = match (self.seed, self.file) {
            (Some((start, previous)), Some((file, resolution))) => {
                seed_voxels = start.changes.iter().map(|c| c.end - c.start).sum();
                extractor.continuing(start, previous, resolution, file)
            }
            (None, Some((file, resolution))) => extractor.of_file(resolution, file),
            (Some(_), None) => {
                return Err(ConvertError::internal(
                    "a seed without the file it continues",
                ))
            }
            (None, None) => extractor,
        };
        let spill_place = SpillPlace::new(options.tmp_dir.as_deref().unwrap_or(self.spill_dir));
        let accumulated = accumulate_series(
            &mut extractor,
            self.tile_depth,
            (&spill_place, options.memory),
            progress,
        )?;
        let extracted = extractor.finish();
        let mut skipped = checked.skipped;
        skipped.extend(extracted.skipped);
        check::refuse_mostly_skipped(
            inputs.len(),
            &skipped,
            extracted.resolution,
            options.allow_mostly_skipped,
        )?;
        let resolution = match extracted.resolution {
            Some(resolution) if extracted.used > 0 => resolution,
            _ => {
                return Err(ConvertError::NothingToBuild {
                    inputs: inputs.len(),
                })
            }
        };
        let absent = samples_left_out(&self.axis, inputs, &checked.usable, &extracted.absent);
        let read_seconds = run.started.elapsed().as_secs_f64();
        let changed_voxels = accumulated.changed_voxels().saturating_sub(seed_voxels);
        // Snapshots left out become missing samples of a regular axis, so the file says
        // there is no snapshot at their time (an explicit axis keeps the instant, with
        // nothing observed at it).
        let (axis, regridded) = match with_absent_missing(&self.axis, &absent)? {
            Some(regular) => (regular, true),
            None => (self.axis, false),
        };
        Ok(Intaken {
            accumulated,
            axis,
            regridded,
            absent,
            resolution,
            used: extracted.used,
            input_bytes: extracted.input_bytes,
            skipped,
            warnings: extracted.warnings,
            changed_voxels,
            read_seconds,
            _spill_place: spill_place,
        })
    }
}

/// Ingest metadata's time: the one given, else now, to the second.
pub(crate) fn stamp(time: Option<Timestamp>) -> Value {
    let now = time.unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| Timestamp(i64::try_from(d.as_nanos()).unwrap_or(i64::MAX)))
            .unwrap_or_default()
    });
    Value::from(iso8601(Timestamp(now.0 - now.0 % 1_000_000_000)))
}
