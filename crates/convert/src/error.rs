//! Errors of the converters: one variant per kind of failure, so that callers route by
//! variant (a front end adds its own hints, e.g. the option that skips bad files) and never
//! by message text.

use crate::skip::{SkipReason, SkippedInput};
use crate::time::TimeError;
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use std::path::PathBuf;
use std::sync::Arc;

/// A cause kept as its typed value behind a trait object (a fault of a lower layer whose
/// type is that layer's business).
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a conversion failed. Messages name the files involved.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConvertError {
    /// No input files were given, or none was found.
    #[error("no input files")]
    NoInputs,
    /// Every map of the inputs was in a damaged part that `skip_bad` left out.
    #[error("{}: no map is left: every one was in a damaged part left out ({problem})", path.display())]
    AllSkipped {
        /// The first recording a damaged part was left out of.
        path: PathBuf,
        /// Why it was left out.
        problem: String,
    },
    /// An input that is neither a file, a directory nor a pattern that matches.
    #[error("{}: no such file or directory", path.display())]
    NotFound {
        /// The input as given.
        path: PathBuf,
    },
    /// A FIFO, device, socket (or, where a file is needed, a directory) given as a map file
    /// or manifest: refused before opening, since reading a FIFO waits for a writer forever.
    #[error("{}: {kind}, not a regular file; map files and manifests must be regular files", path.display())]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What it is instead (`"a FIFO"`…).
        kind: &'static str,
    },
    /// A glob pattern that does not parse.
    #[error("bad pattern {pattern:?}")]
    BadPattern {
        /// The pattern.
        pattern: String,
        /// What is wrong with it.
        #[source]
        source: glob::PatternError,
    },
    /// A glob pattern that matches no files.
    #[error("the pattern {pattern:?} matches no files")]
    NoMatch {
        /// The pattern.
        pattern: String,
    },
    /// A recording (a ROS bag, an MCAP file) that its format's plugin could not open or
    /// expand into maps (the cause names the recording).
    #[error("{format} recording")]
    Recording {
        /// The recording.
        path: PathBuf,
        /// Its format.
        format: &'static str,
        /// What went wrong, as the plugin's own error type.
        #[source]
        source: Cause,
    },
    /// Standard input (`-` among the inputs) that is not a stream of a recording format
    /// read from streams ([`RecordingFormat::open_stream`](froctomap_formats::RecordingFormat::open_stream)).
    #[error(
        "-: standard input is not a stream of a format read from streams ({formats}); {start}"
    )]
    UnknownStream {
        /// The formats read from streams.
        formats: String,
        /// How the stream starts.
        start: String,
    },
    /// `-` given more than once: standard input is read once.
    #[error("-: standard input is read once; give `-` once among the inputs")]
    StdinTwice,
    /// `-` given while standard input is a terminal (a stream must be piped in).
    #[error("-: standard input is a terminal; pipe an MCAP stream into it (e.g. `froctomap generate --stream | froctomap build - -o f.froct`)")]
    StdinIsTerminal,
    /// Standard input could not be read.
    #[error("-: cannot read standard input")]
    StdinRead {
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// `--start/--step` or a times file given with a recording, whose maps carry their own
    /// times.
    #[error("{}: a recording's maps carry their own times; --start/--step and --times-file apply to map files only", path.display())]
    RecordingTimes {
        /// The recording.
        path: PathBuf,
    },
    /// A directory without a manifest or map files.
    #[error("{}: no {manifest} or map files ({extensions}) in this directory", dir.display())]
    NoMapFiles {
        /// The directory.
        dir: PathBuf,
        /// The manifest name looked for.
        manifest: &'static str,
        /// The extensions of the registered formats, dotted.
        extensions: String,
    },
    /// A directory or manifest that cannot be read.
    #[error("{}", path.display())]
    Unlistable {
        /// The directory or manifest.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A manifest line that is not `path,time`.
    #[error("{}:{line}", manifest.display())]
    ManifestLine {
        /// The manifest.
        manifest: PathBuf,
        /// Line number, from 1.
        line: usize,
        /// What is wrong.
        #[source]
        problem: ManifestProblem,
    },
    /// A list of times (`--times-file`) whose length is not the number of files.
    #[error("{}: {times} time(s) for {files} file(s); give one time per file, in file order", list.display())]
    TimesCount {
        /// The list of times.
        list: PathBuf,
        /// Times it gives.
        times: usize,
        /// Files found.
        files: usize,
    },
    /// A manifest without entries.
    #[error("{}: the manifest lists no files", manifest.display())]
    EmptyManifest {
        /// The manifest.
        manifest: PathBuf,
    },
    /// Files whose times are neither in a manifest nor in their names.
    #[error("no time in the name of {} file(s): {}{}; give a manifest (path,time) or a start time and step", files.len(), shown(files), if files.len() > 5 { ", ..." } else { "" })]
    NoTimes {
        /// The files.
        files: Vec<PathBuf>,
    },
    /// A time that cannot be used for a file (outside the supported range, or past what a
    /// start and step can reach).
    #[error("{}", path.display())]
    InputTime {
        /// The file.
        path: PathBuf,
        /// What is wrong with its time.
        #[source]
        source: TimeError,
    },
    /// A file name that reads as a time before 1990: a frame number, not a time.
    #[error("{}: the name reads as {}, before 1990; this looks like a frame number, not a time", path.display(), iso8601(*time))]
    EarlyNameTime {
        /// The file.
        path: PathBuf,
        /// The time its name reads as.
        time: Timestamp,
    },
    /// Two files claim the same time.
    #[error("{} and {} have the same time {}", first.display(), second.display(), iso8601(*time))]
    DuplicateTime {
        /// One file.
        first: PathBuf,
        /// The other.
        second: PathBuf,
        /// Their time.
        time: Timestamp,
    },
    /// Snapshots of different resolutions.
    #[error("{} has resolution {second_resolution} m but {} has {first_resolution} m; a series must have one resolution", second.display(), first.display())]
    MixedResolution {
        /// A file with the series' resolution.
        first: PathBuf,
        /// Its resolution.
        first_resolution: f64,
        /// A file with another.
        second: PathBuf,
        /// That one.
        second_resolution: f64,
    },
    /// A snapshot of a series could not be used.
    #[error("{}", snapshot_message(path, source))]
    Snapshot {
        /// The file.
        path: PathBuf,
        /// Why (shared: a file byte-identical to a refused one is refused for its reason).
        #[source]
        source: Arc<SnapshotError>,
    },
    /// A map file (e.g. a ground truth) could not be read.
    #[error(transparent)]
    Read(froctomap_formats::FormatError),
    /// A map could not be written.
    #[error(transparent)]
    Write(froctomap_formats::FormatError),
    /// A single map where a series file is needed.
    #[error("{}: this is a map file (format `{format}`), not a FROctomap series file; build a .froct from it first", path.display())]
    MapNotSeries {
        /// The file.
        path: PathBuf,
        /// Name of the map format it is in.
        format: &'static str,
    },
    /// A whole-history analysis of a format 2.0 file that has segments: it reads one body
    /// of cells over the whole history, which `compact` makes.
    #[error("{}: a FROctomap 2.0 file with {segments} segment(s) after its base; this needs the whole history in one base: run `froctomap compact {}` first", path.display(), path.display())]
    NeedsCompaction {
        /// The file.
        path: PathBuf,
        /// Its committed segments.
        segments: usize,
    },
    /// A FROctomap file could not be read or written.
    #[error(transparent)]
    File(#[from] froctomap_file::FileError),
    /// No registered temporal model has this name.
    #[error("unknown model `{name}` (known: {})", known.join(", "))]
    UnknownModel {
        /// The name given.
        name: String,
        /// The registered names.
        known: Vec<&'static str>,
    },
    /// The temporal model refused its configuration or data.
    #[error("temporal model")]
    Model(#[from] froctomap_temporal::TemporalError),
    /// The snapshots' times make no time axis.
    #[error("the snapshots' times")]
    TimeAxis(#[source] froctomap_temporal::TemporalError),
    /// A time given by the user could not be read.
    #[error(transparent)]
    BadTime(#[from] TimeError),
    /// `index:` without a number.
    #[error("{text:?}: `index:` needs a sample number (index:0 is the first, index:-1 or `last` the last)")]
    BadSampleIndex {
        /// What was given.
        text: String,
    },
    /// A sample index past the end of the file's time axis.
    #[error("sample {sample} is beyond the {samples} samples of the file ({} .. {}); valid: index:0 .. index:{}, or index:-1 .. index:-{samples}", iso8601(*start), iso8601(*end), samples.saturating_sub(1))]
    SampleBeyondAxis {
        /// The sample asked for.
        sample: u32,
        /// Samples of the axis.
        samples: u32,
        /// First instant of the file.
        start: Timestamp,
        /// Last instant of the file.
        end: Timestamp,
    },
    /// A sample counted from the end (`index:-N`) before the start of the axis.
    #[error("index:-{back} is before the first of the {samples} samples of the file ({} .. {}); valid: index:-1 .. index:-{samples}, or index:0 .. index:{}", iso8601(*start), iso8601(*end), samples.saturating_sub(1))]
    SampleBeforeAxis {
        /// How many samples back from the end (1 = the last).
        back: u32,
        /// Samples of the axis.
        samples: u32,
        /// First instant of the file.
        start: Timestamp,
        /// Last instant of the file.
        end: Timestamp,
    },
    /// A sample of the axis at which no snapshot was stored.
    #[error("sample {sample} ({}) has no snapshot", iso8601(*time))]
    NoSnapshotAtSample {
        /// The sample.
        sample: u32,
        /// Its time.
        time: Timestamp,
    },
    /// An instant before the first snapshot, where nothing was observed.
    #[error(
        "{}: {} is before the first snapshot ({}); the time axis spans {} .. {}{}",
        path.display(),
        iso8601(*time),
        first.map_or_else(|| "none".to_string(), iso8601),
        iso8601(*start),
        iso8601(*end),
        if first.is_some_and(|f| f > *start) { ", the samples before the first snapshot are missing" } else { "" }
    )]
    BeforeFirstSnapshot {
        /// The file.
        path: std::path::PathBuf,
        /// The instant asked for.
        time: Timestamp,
        /// The time of the file's first snapshot (its first sample that is not missing).
        first: Option<Timestamp>,
        /// First instant of the file.
        start: Timestamp,
        /// Last instant of the file.
        end: Timestamp,
    },
    /// A point where the file has no cell: nothing was ever observed there (or it lies
    /// outside the space a map can address).
    #[error("{}: no cell at ({}, {}, {}) m: nothing was ever observed there{}", path.display(), point[0], point[1], point[2], extent_text(extent))]
    PointOutsideMap {
        /// The FROctomap file.
        path: PathBuf,
        /// The point, metres.
        point: [f64; 3],
        /// The metric box the file's tiles cover (minimum, maximum corner), if any.
        extent: Option<([f64; 3], [f64; 3])>,
    },
    /// A time range that holds no sample of the file.
    #[error("{}: no sample between {} and {}; the file covers {} .. {}", path.display(), iso8601(*from), iso8601(*to), iso8601(*start), iso8601(*end))]
    RangeOutsideAxis {
        /// The FROctomap file.
        path: PathBuf,
        /// First instant asked for.
        from: Timestamp,
        /// Last instant asked for.
        to: Timestamp,
        /// First instant of the file.
        start: Timestamp,
        /// Last instant of the file.
        end: Timestamp,
    },
    /// A snapshot to score for anomalies whose resolution is not the file's.
    #[error("{}: resolution {resolution} m, but {} has {file_resolution} m; a snapshot is scored against a file of its own resolution", snapshot.as_ref().map_or_else(|| "the snapshot".to_string(), |p| p.display().to_string()), file.display())]
    SnapshotResolution {
        /// The snapshot, when it came from a file.
        snapshot: Option<PathBuf>,
        /// Its resolution.
        resolution: f64,
        /// The FROctomap file.
        file: PathBuf,
        /// The file's resolution.
        file_resolution: f64,
    },
    /// A snapshot time before the first snapshot of the file: its model knows nothing of
    /// that time.
    #[error("{}: the snapshot's time {} is before the file's first snapshot; the file covers {} .. {}, and anomalies are judged at or after its start", file.display(), iso8601(*time), iso8601(*start), iso8601(*end))]
    AnomalyTimeBeforeFile {
        /// The FROctomap file.
        file: PathBuf,
        /// The snapshot's time.
        time: Timestamp,
        /// First instant of the file.
        start: Timestamp,
        /// Last instant of the file.
        end: Timestamp,
    },
    /// An anomaly threshold or rate out of its range.
    #[error("bad {what}: {value}")]
    BadAnomalyOption {
        /// Which setting, with its valid range.
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// An export range that ends before it starts.
    #[error("the range ends at {} before it starts at {}", iso8601(*to), iso8601(*from))]
    EmptyRange {
        /// First instant.
        from: Timestamp,
        /// Last instant.
        to: Timestamp,
    },
    /// An interval between exported maps that is not positive.
    #[error("the interval between maps must be positive")]
    NonPositiveInterval,
    /// More maps requested than [`Limits::max_exports`](crate::Limits).
    #[error("{count} maps requested, more than the limit of {limit}")]
    TooManyMaps {
        /// Maps the range and interval give.
        count: i128,
        /// The limit.
        limit: u64,
    },
    /// Cells of a FROctomap file that do not make a map (overlapping, out of order): only a
    /// damaged or foreign writer's file gets past the reader's checks this way.
    #[error("{}: inconsistent cells", path.display())]
    InconsistentCells {
        /// The FROctomap file.
        path: PathBuf,
        /// What the map builder refused.
        #[source]
        source: Cause,
    },
    /// The caller asked to stop ([`Progress::cancelled`](crate::Progress::cancelled)):
    /// nothing was written (outputs are written atomically, temporary files removed).
    #[error("stopped before the end, as asked; nothing was written")]
    Cancelled,
    /// Writing an output failed.
    #[error(transparent)]
    Output(#[from] froctomap_core::AtomicWriteError),
    /// A recording format's writer refused or failed to write an exported map.
    #[error("{}: writing the {format} recording failed{}", path.display(), at.map(|t| format!(" at the map for {}", iso8601(t))).unwrap_or_default())]
    RecordingWrite {
        /// The recording being written.
        path: PathBuf,
        /// Its format.
        format: &'static str,
        /// The map being written, if the failure was at one.
        at: Option<Timestamp>,
        /// The writer's own error.
        #[source]
        source: Cause,
    },
    /// A lossy compaction asked for in place: it would drop the file's outlier set, the
    /// only exact record of its past.
    #[error("{}: a lossy compaction in place would drop the file's exact history; write it elsewhere with -o", file.display())]
    LossyInPlace {
        /// The file.
        file: PathBuf,
    },
    /// A compaction asked for tiles larger than the file's (or past the deepest depth).
    #[error("{}: tile depth {tile_depth} for the compacted file: it can only be the file's ({file_depth}) or deeper, up to 16 (smaller tiles)", file.display())]
    CoarserTiles {
        /// The file.
        file: PathBuf,
        /// The depth asked for.
        tile_depth: u8,
        /// The file's.
        file_depth: u8,
    },
    /// An output that is one of the inputs (also through a link): writing it would destroy
    /// the input.
    #[error("{}: this output is the input {}; writing it would destroy the input", output.display(), input.display())]
    OutputIsInput {
        /// The output as given.
        output: PathBuf,
        /// The input it is.
        input: PathBuf,
    },
    /// An output that is written new (a recording that is a directory, such as a ROS 2
    /// bag) and already exists.
    #[error("{}: it already exists; this recording is a directory made new, never written into or over anything (remove it, or name another)", path.display())]
    OutputExists {
        /// The output.
        path: PathBuf,
    },
    /// An export to standard output or a device of something that is a directory (a series
    /// of map files, a ROS 2 bag).
    #[error("{}: a {format} export is a directory, which cannot go to standard output or a device (export one recording file, e.g. --format mcap, or name a directory)", path.display())]
    StreamNotADirectory {
        /// The output.
        path: PathBuf,
        /// The export's format.
        format: String,
    },
    /// An export directory that already holds files, which the export would replace.
    #[error("{}: the directory is not empty", dir.display())]
    DirectoryNotEmpty {
        /// The directory.
        dir: PathBuf,
    },
    /// A series resolution that no map can have (not positive and finite).
    #[error("the series' resolution")]
    BadResolution {
        /// As given.
        resolution: f64,
        /// Why.
        #[source]
        source: froctomap_core::MapError,
    },
    /// More than half of the inputs would be left out (with `skip_bad`): every one is
    /// listed, with why.
    #[error("{}", mostly_skipped_message(*inputs, skipped, *resolution))]
    MostlySkipped {
        /// Inputs given.
        inputs: usize,
        /// The inputs left out, and why.
        skipped: Vec<SkippedInput>,
        /// The series' resolution, where one was chosen.
        resolution: Option<f64>,
    },
    /// Every input was unreadable or skipped.
    #[error("no readable snapshots: all {inputs} inputs were left out")]
    NothingToBuild {
        /// Inputs given.
        inputs: usize,
    },
    /// A snapshot to append that is not later than the last sample of the file appended
    /// to: an append only extends a file's span.
    #[error("{}: its time {} is not after the last sample of {} ({}); append adds only snapshots later than the file's span", input.display(), iso8601(*time), file.display(), iso8601(*last))]
    AppendOverlap {
        /// The file appended to.
        file: PathBuf,
        /// The time of its last sample.
        last: Timestamp,
        /// The first input at or before it.
        input: PathBuf,
        /// That input's time.
        time: Timestamp,
    },
    /// The build's spill data (runs set aside on disk to bound memory, see
    /// `IngestOptions::memory`) could not be written or read back.
    #[error("{}: spill data of the build", path.display())]
    Spill {
        /// The spill file or directory.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A format 2.0 file whose model cannot take segments.
    #[error("{}: its model `{model}` cannot grow by segments (its frequencies are bins of the axis length); build the series with `--model fremen-periods` to append segments, or append to a format 1.x file", file.display())]
    ModelCannotGrow {
        /// The file.
        file: PathBuf,
        /// Its model.
        model: &'static str,
    },
    /// A fault of froctomap itself, not of the inputs (please report it).
    #[error("internal error: {what}")]
    Internal {
        /// What went wrong.
        what: &'static str,
        /// The cause, where there is one.
        #[source]
        source: Option<Cause>,
    },
}

impl ConvertError {
    /// An internal fault without a cause.
    pub(crate) fn internal(what: &'static str) -> Self {
        Self::Internal { what, source: None }
    }

    /// `true` when leaving the files concerned out of a series would get past this error
    /// (what a front end's "skip bad files" option does).
    pub fn is_skippable(&self) -> bool {
        match self {
            // Refused after the file became the one the next is compared with.
            Self::Snapshot { source, .. } => {
                !matches!(**source, SnapshotError::TooManyTiles { .. })
            }
            Self::MixedResolution { .. } | Self::Read(_) => true,
            _ => false,
        }
    }
}

/// Why one snapshot of a series was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SnapshotError {
    /// The file could not be read.
    #[error("cannot read")]
    Io(#[source] std::io::Error),
    /// The file is empty.
    #[error("the file is empty")]
    Empty,
    /// The file is larger than [`Limits::max_map_file_bytes`](crate::Limits).
    #[error("{bytes} bytes, more than the limit of {limit} bytes for one map")]
    TooLarge {
        /// Its size.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// No format reads it, or its format refused it (the message names the file).
    #[error(transparent)]
    Format(froctomap_formats::FormatError),
    /// Its format's reader accepts it but its byte-level comparison refused it.
    #[error("read but not compared")]
    NotCompared(#[source] froctomap_formats::FormatError),
    /// Its resolution is not the series'.
    #[error("resolution {found} m differs from the series' {series} m")]
    Resolution {
        /// The file's resolution.
        found: f64,
        /// The series' resolution.
        series: f64,
    },
    /// Its known space covers more tiles than [`Limits::max_snapshot_tiles`](crate::Limits)
    /// (a tiny file of a few huge leaves, each split into the tiles it covers). Stops a
    /// build even when bad files are skipped.
    #[error(
        "its known space covers more than {limit} tiles of depth {tile_depth}, each at least one cell (leaves coarser than a tile are split into tiles)"
    )]
    TooManyTiles {
        /// The build's tile depth.
        tile_depth: u8,
        /// The limit.
        limit: u64,
    },
    /// Byte-identical to a file refused before it, and so refused for the same reason.
    #[error("byte-identical to a file refused before it")]
    SameAsRefused(#[source] Arc<SnapshotError>),
    /// A recorded map could not be fetched from its recording (the cause names it).
    #[error(transparent)]
    Recorded(Arc<dyn std::error::Error + Send + Sync + 'static>),
    /// A fault of froctomap itself.
    #[error("internal error: {0}")]
    Internal(&'static str),
}

impl SnapshotError {
    /// `true` when the message names the file already.
    fn names_file(&self) -> bool {
        match self {
            Self::Format(_) | Self::NotCompared(_) | Self::Recorded(_) => true,
            // It names the earlier file, if any.
            _ => false,
        }
    }

    /// Why a file refused for this is left out, for routing (a copy of a refused file gives
    /// that file's reason).
    pub fn skip_reason(&self) -> SkipReason {
        match self {
            Self::Io(_) => SkipReason::Unreadable,
            Self::Empty => SkipReason::Empty,
            Self::TooLarge { .. } | Self::TooManyTiles { .. } => SkipReason::TooLarge,
            Self::Format(e) => format_skip_reason(e),
            Self::NotCompared(_) => SkipReason::NotCompared,
            Self::Resolution { .. } => SkipReason::ResolutionMismatch,
            Self::SameAsRefused(earlier) => earlier.skip_reason(),
            Self::Recorded(_) => SkipReason::DamagedRecording,
            Self::Internal(_) => SkipReason::Internal,
        }
    }

    /// The file at `path` left out for this.
    pub(crate) fn skipped(&self, path: PathBuf) -> SkippedInput {
        SkippedInput::new(
            path,
            self.skip_reason(),
            froctomap_core::error_message(self),
        )
    }

    /// The series' and the file's resolutions, when that is why the file was refused.
    pub fn resolution_mismatch(&self) -> Option<(f64, f64)> {
        match self {
            Self::Resolution { found, series } => Some((*series, *found)),
            Self::SameAsRefused(earlier) => earlier.resolution_mismatch(),
            _ => None,
        }
    }
}

/// Why a file its format refused is left out.
fn format_skip_reason(error: &froctomap_formats::FormatError) -> SkipReason {
    use froctomap_formats::FormatError;
    match error {
        FormatError::Io { .. } | FormatError::NotAFile { .. } => SkipReason::Unreadable,
        FormatError::Unrecognized { .. }
        | FormatError::SeriesNotMap { .. }
        | FormatError::UnknownFormat { .. }
        | FormatError::Unsupported { .. } => SkipReason::NotAMap,
        _ => SkipReason::Malformed,
    }
}

/// The file, unless the refusal (the cause) names it already.
fn snapshot_message(path: &std::path::Path, error: &SnapshotError) -> String {
    if error.names_file() {
        "refused as a snapshot of the series".to_string()
    } else {
        path.display().to_string()
    }
}

fn mostly_skipped_message(
    inputs: usize,
    skipped: &[SkippedInput],
    resolution: Option<f64>,
) -> String {
    let mut text = format!(
        "{} of {inputs} inputs would be left out, more than half",
        skipped.len()
    );
    if let Some(r) = resolution {
        text.push_str(&format!(" (the series' resolution is {r} m)"));
    }
    // One line (front ends escape control characters): every file, as `--skip-bad` lists
    // them, so that one run shows all of them.
    let listed: Vec<String> = skipped.iter().map(ToString::to_string).collect();
    format!("{text}: {}", listed.join("; "))
}

/// What is wrong with a manifest line.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ManifestProblem {
    /// No comma.
    #[error("expected `path,time`")]
    NotPathTime,
    /// The time does not parse.
    #[error(transparent)]
    Time(#[from] TimeError),
    /// A header row without a column of this kind.
    #[error("the header names no {wanted} column (expected one of {names})")]
    MissingColumn {
        /// `path` or `time`.
        wanted: &'static str,
        /// The names recognised for it.
        names: &'static str,
    },
    /// A row with fewer fields than the header's path and time columns need.
    #[error("expected a field in column {column}")]
    MissingField {
        /// The column, from 1.
        column: usize,
    },
}

fn extent_text(extent: &Option<([f64; 3], [f64; 3])>) -> String {
    match extent {
        Some((min, max)) => format!(
            " (the map's tiles span ({:.2}, {:.2}, {:.2}) .. ({:.2}, {:.2}, {:.2}) m)",
            min[0], min[1], min[2], max[0], max[1], max[2]
        ),
        None => " (the map is empty)".to_string(),
    }
}

fn shown(files: &[PathBuf]) -> String {
    let names: Vec<String> = files
        .iter()
        .take(5)
        .map(|p| p.display().to_string())
        .collect();
    names.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::said_twice;
    use froctomap_formats::FormatError;
    use froctomap_temporal::TemporalError;

    fn io() -> std::io::Error {
        std::io::Error::other("disk full")
    }
    fn path() -> PathBuf {
        PathBuf::from("a.bt")
    }
    fn time_error() -> TimeError {
        TimeError {
            input: "yesterday".into(),
            what: "time",
            reason: "not a date".into(),
        }
    }
    fn format_error() -> FormatError {
        FormatError::Io {
            path: path(),
            source: io(),
        }
    }

    fn snapshot_errors() -> Vec<SnapshotError> {
        let all = vec![
            SnapshotError::Io(io()),
            SnapshotError::Empty,
            SnapshotError::TooLarge { bytes: 9, limit: 8 },
            SnapshotError::Format(format_error()),
            SnapshotError::NotCompared(format_error()),
            SnapshotError::Resolution {
                found: 0.05,
                series: 0.1,
            },
            SnapshotError::TooManyTiles {
                tile_depth: 4,
                limit: 8,
            },
            SnapshotError::SameAsRefused(Arc::new(SnapshotError::Empty)),
            SnapshotError::Recorded(Arc::new(format_error())),
            SnapshotError::Internal("a test"),
        ];
        for e in &all {
            match e {
                SnapshotError::Io(_)
                | SnapshotError::Empty
                | SnapshotError::TooLarge { .. }
                | SnapshotError::Format(_)
                | SnapshotError::NotCompared(_)
                | SnapshotError::Resolution { .. }
                | SnapshotError::TooManyTiles { .. }
                | SnapshotError::SameAsRefused(_)
                | SnapshotError::Recorded(_)
                | SnapshotError::Internal(_) => {}
            }
        }
        all
    }

    fn manifest_problems() -> Vec<ManifestProblem> {
        let all = vec![
            ManifestProblem::NotPathTime,
            ManifestProblem::Time(time_error()),
            ManifestProblem::MissingColumn {
                wanted: "time",
                names: "time, stamp",
            },
            ManifestProblem::MissingField { column: 3 },
        ];
        for e in &all {
            match e {
                ManifestProblem::NotPathTime
                | ManifestProblem::Time(_)
                | ManifestProblem::MissingColumn { .. }
                | ManifestProblem::MissingField { .. } => {}
            }
        }
        all
    }

    /// Every variant of [`ConvertError`] (and through it of the errors it wraps).
    // A table: one entry per variant, then the match that fails to compile when one is missing.
    #[allow(clippy::too_many_lines)]
    fn convert_errors() -> Vec<ConvertError> {
        let t = Timestamp(1_700_000_000_000_000_000);
        let cause = || -> Cause { Box::new(format_error()) };
        let mut all = vec![
            ConvertError::NoInputs,
            ConvertError::AllSkipped {
                path: path(),
                problem: "damaged chunk".into(),
            },
            ConvertError::NotFound { path: path() },
            ConvertError::NotAFile {
                path: path(),
                kind: "a FIFO",
            },
            ConvertError::BadPattern {
                pattern: "[".into(),
                source: glob::Pattern::new("[").unwrap_err(),
            },
            ConvertError::NoMatch {
                pattern: "*.bt".into(),
            },
            ConvertError::Recording {
                path: path(),
                format: "rosbag",
                source: cause(),
            },
            ConvertError::UnknownStream {
                formats: "mcap".into(),
                start: "it starts with 00".into(),
            },
            ConvertError::StdinTwice,
            ConvertError::StdinIsTerminal,
            ConvertError::StdinRead { source: io() },
            ConvertError::RecordingTimes { path: path() },
            ConvertError::NoMapFiles {
                dir: path(),
                manifest: "manifest.csv",
                extensions: ".bt".into(),
            },
            ConvertError::Unlistable {
                path: path(),
                source: io(),
            },
            ConvertError::TimesCount {
                list: path(),
                times: 1,
                files: 2,
            },
            ConvertError::EmptyManifest { manifest: path() },
            ConvertError::NoTimes {
                files: vec![path(); 7],
            },
            ConvertError::InputTime {
                path: path(),
                source: time_error(),
            },
            ConvertError::EarlyNameTime {
                path: path(),
                time: t,
            },
            ConvertError::DuplicateTime {
                first: path(),
                second: "b.bt".into(),
                time: t,
            },
            ConvertError::MixedResolution {
                first: path(),
                first_resolution: 0.1,
                second: "b.bt".into(),
                second_resolution: 0.05,
            },
            ConvertError::Read(format_error()),
            ConvertError::Write(format_error()),
            ConvertError::MapNotSeries {
                path: path(),
                format: "octomap-binary",
            },
            ConvertError::NeedsCompaction {
                path: path(),
                segments: 2,
            },
            ConvertError::File(froctomap_file::FileError::Io {
                path: path(),
                source: io(),
            }),
            ConvertError::UnknownModel {
                name: "fourier".into(),
                known: vec!["fremen", "static-mean"],
            },
            ConvertError::Model(TemporalError::Malformed("parameters")),
            ConvertError::TimeAxis(TemporalError::InvalidAxis("no samples")),
            ConvertError::BadTime(time_error()),
            ConvertError::BadSampleIndex {
                text: "index:".into(),
            },
            ConvertError::SampleBeyondAxis {
                sample: 9,
                samples: 3,
                start: t,
                end: t,
            },
            ConvertError::SampleBeforeAxis {
                back: 9,
                samples: 3,
                start: t,
                end: t,
            },
            ConvertError::NoSnapshotAtSample { sample: 1, time: t },
            ConvertError::BeforeFirstSnapshot {
                path: path(),
                time: t,
                first: Some(t),
                start: t,
                end: t,
            },
            ConvertError::PointOutsideMap {
                path: path(),
                point: [1.0, 2.0, 3.0],
                extent: None,
            },
            ConvertError::RangeOutsideAxis {
                path: path(),
                from: t,
                to: t,
                start: t,
                end: t,
            },
            ConvertError::SnapshotResolution {
                snapshot: Some("b.bt".into()),
                resolution: 0.05,
                file: path(),
                file_resolution: 0.1,
            },
            ConvertError::AnomalyTimeBeforeFile {
                file: path(),
                time: t,
                start: t,
                end: t,
            },
            ConvertError::BadAnomalyOption {
                what: "threshold (0 .. 1)",
                value: 2.0,
            },
            ConvertError::EmptyRange { from: t, to: t },
            ConvertError::NonPositiveInterval,
            ConvertError::TooManyMaps { count: 9, limit: 8 },
            ConvertError::InconsistentCells {
                path: path(),
                source: Box::new(froctomap_core::MapError::InvalidResolution(0.0)),
            },
            ConvertError::Cancelled,
            ConvertError::Output(froctomap_core::AtomicWriteError {
                path: path(),
                source: io(),
            }),
            ConvertError::RecordingWrite {
                path: path(),
                format: "mcap",
                at: Some(t),
                source: cause(),
            },
            ConvertError::LossyInPlace { file: path() },
            ConvertError::CoarserTiles {
                file: path(),
                tile_depth: 9,
                file_depth: 10,
            },
            ConvertError::OutputIsInput {
                output: path(),
                input: path(),
            },
            ConvertError::OutputExists { path: path() },
            ConvertError::StreamNotADirectory {
                path: path(),
                format: "bt".to_string(),
            },
            ConvertError::DirectoryNotEmpty { dir: path() },
            ConvertError::BadResolution {
                resolution: 0.0,
                source: froctomap_core::MapError::InvalidResolution(0.0),
            },
            ConvertError::MostlySkipped {
                inputs: 3,
                skipped: vec![
                    SkippedInput::new(
                        path(),
                        SkipReason::Empty,
                        "the file is empty".into()
                    );
                    2
                ],
                resolution: Some(0.1),
            },
            ConvertError::NothingToBuild { inputs: 3 },
            ConvertError::AppendOverlap {
                file: path(),
                last: t,
                input: "b.bt".into(),
                time: t,
            },
            ConvertError::Spill {
                path: path(),
                source: io(),
            },
            ConvertError::ModelCannotGrow {
                file: path(),
                model: "fremen",
            },
            ConvertError::Internal {
                what: "a test",
                source: Some(cause()),
            },
        ];
        all.extend(
            snapshot_errors()
                .into_iter()
                .map(|e| ConvertError::Snapshot {
                    path: path(),
                    source: Arc::new(e),
                }),
        );
        all.extend(
            manifest_problems()
                .into_iter()
                .map(|problem| ConvertError::ManifestLine {
                    manifest: path(),
                    line: 2,
                    problem,
                }),
        );
        for e in &all {
            // Fails to compile when a variant is added and not listed above.
            match e {
                ConvertError::NoInputs
                | ConvertError::AllSkipped { .. }
                | ConvertError::NotFound { .. }
                | ConvertError::NotAFile { .. }
                | ConvertError::BadPattern { .. }
                | ConvertError::NoMatch { .. }
                | ConvertError::Recording { .. }
                | ConvertError::UnknownStream { .. }
                | ConvertError::StdinTwice
                | ConvertError::StdinIsTerminal
                | ConvertError::StdinRead { .. }
                | ConvertError::RecordingTimes { .. }
                | ConvertError::NoMapFiles { .. }
                | ConvertError::Unlistable { .. }
                | ConvertError::ManifestLine { .. }
                | ConvertError::TimesCount { .. }
                | ConvertError::EmptyManifest { .. }
                | ConvertError::NoTimes { .. }
                | ConvertError::InputTime { .. }
                | ConvertError::EarlyNameTime { .. }
                | ConvertError::DuplicateTime { .. }
                | ConvertError::MixedResolution { .. }
                | ConvertError::Snapshot { .. }
                | ConvertError::Read(_)
                | ConvertError::Write(_)
                | ConvertError::MapNotSeries { .. }
                | ConvertError::NeedsCompaction { .. }
                | ConvertError::File(_)
                | ConvertError::UnknownModel { .. }
                | ConvertError::Model(_)
                | ConvertError::TimeAxis(_)
                | ConvertError::BadTime(_)
                | ConvertError::BadSampleIndex { .. }
                | ConvertError::SampleBeyondAxis { .. }
                | ConvertError::SampleBeforeAxis { .. }
                | ConvertError::NoSnapshotAtSample { .. }
                | ConvertError::BeforeFirstSnapshot { .. }
                | ConvertError::PointOutsideMap { .. }
                | ConvertError::RangeOutsideAxis { .. }
                | ConvertError::SnapshotResolution { .. }
                | ConvertError::AnomalyTimeBeforeFile { .. }
                | ConvertError::BadAnomalyOption { .. }
                | ConvertError::EmptyRange { .. }
                | ConvertError::NonPositiveInterval
                | ConvertError::TooManyMaps { .. }
                | ConvertError::InconsistentCells { .. }
                | ConvertError::Cancelled
                | ConvertError::Output(_)
                | ConvertError::RecordingWrite { .. }
                | ConvertError::LossyInPlace { .. }
                | ConvertError::CoarserTiles { .. }
                | ConvertError::OutputIsInput { .. }
                | ConvertError::OutputExists { .. }
                | ConvertError::StreamNotADirectory { .. }
                | ConvertError::DirectoryNotEmpty { .. }
                | ConvertError::BadResolution { .. }
                | ConvertError::MostlySkipped { .. }
                | ConvertError::NothingToBuild { .. }
                | ConvertError::AppendOverlap { .. }
                | ConvertError::Spill { .. }
                | ConvertError::ModelCannotGrow { .. }
                | ConvertError::Internal { .. } => {}
            }
        }
        all
    }

    /// Every variant of this crate's errors (built above), as its chain prints: no text
    /// repeats another of the chain and none is empty.
    #[test]
    fn every_error_is_said_once() {
        for e in snapshot_errors() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        for e in manifest_problems() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        for e in convert_errors() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        let warnings = [
            crate::InputWarning::Unlisted {
                manifest: path(),
                files: vec![path()],
            },
            crate::InputWarning::Recording {
                path: path(),
                message: "zero stamps".into(),
            },
        ];
        for e in warnings {
            match e {
                crate::InputWarning::Unlisted { .. } | crate::InputWarning::Recording { .. } => {}
            }
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        let record = [
            crate::RecordError::Convert(ConvertError::NoInputs),
            crate::RecordError::Spool(froctomap_formats::SpoolError::NoMap {
                name: "spool".into(),
                index: 3,
            }),
            crate::RecordError::SegmentLimit {
                file: path(),
                segments: 9,
                limit: 9,
            },
            crate::RecordError::Compact {
                file: path(),
                source: Box::new(ConvertError::Cancelled),
            },
            crate::RecordError::Commit {
                what: "the map of 2024-01-01T00:00:00Z".into(),
                source: Box::new(ConvertError::Cancelled),
            },
        ];
        for e in record {
            match e {
                crate::RecordError::Convert(_)
                | crate::RecordError::Spool(_)
                | crate::RecordError::SegmentLimit { .. }
                | crate::RecordError::Compact { .. }
                | crate::RecordError::Commit { .. } => {}
            }
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
    }

    /// The chain still names the file and the problem.
    #[test]
    fn the_printed_chain_names_the_file_and_the_problem() {
        let e = ConvertError::Snapshot {
            path: path(),
            source: Arc::new(SnapshotError::Io(io())),
        };
        assert_eq!(
            froctomap_core::error_message(&e),
            "a.bt: cannot read: disk full"
        );
        let e = ConvertError::Snapshot {
            path: path(),
            source: Arc::new(SnapshotError::Format(format_error())),
        };
        assert_eq!(
            froctomap_core::error_message(&e),
            "refused as a snapshot of the series: a.bt: cannot read: disk full"
        );
    }
}
