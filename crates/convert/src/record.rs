//! Recording: maps added to a FROctomap 2.0 file one at a time as they arrive, one segment
//! ([`append_segment`]) committed every so many maps or so much time — what `froctomap
//! record` and the ROS 2 node run.
//!
//! A [`Recorder`] holds the file's writer lock for its life. Maps are taken one at a time,
//! as map files ([`Recorder::take_file`]) or as map bytes ([`Recorder::take_bytes`], kept in
//! a [`MapSpool`] beside the file until committed, so memory and disk follow one commit,
//! not the stream). A map not later than the last one taken (the file's last sample at
//! first) is skipped and counted. A commit that fails is retried in halves (a segment
//! commits all its maps or none), so a bad map commits the maps before it and stops naming
//! it, or, with [`AppendOptions::skip_bad`], is left out and counted. A file that does not
//! exist gets the first commit's maps as its base (a build with the default model, then
//! converted to 2.0 in place); a 1.x file is converted to 2.0 when opened; a file of a model
//! that cannot grow is refused before anything is written. At the file's segment limit the
//! next commit is refused ([`RecordError::SegmentLimit`]) until the file is compacted.

use crate::background_compaction::BackgroundCompaction;
use crate::build::{
    append_segment, build, is_living_file, output_dir, refuse_growing_fixed_span, AppendOptions,
    BuildOptions,
};
use crate::compact::{compact_held, CompactOptions, CompactReport, COMPACT_PREFIX};
use crate::context::Context;
use crate::error::ConvertError;
use crate::inputs::{collect_recording, SeriesInput, STDIN_INPUT};
use crate::progress::Silent;
use crate::skip::SkippedInput;
use crate::time::{parse_duration, TimeError};
use froctomap_core::{remove_stale_temporary_dirs, remove_stale_temporary_files, Timestamp};
use froctomap_file::LivingWriter;
use froctomap_formats::{MapSpool, SpoolError, SPOOL_PREFIX};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// When a [`Recorder`] commits the maps it gathered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommitEvery {
    /// Once this many maps are gathered (at least 1).
    Maps(usize),
    /// Once this much time has passed since the first map of the commit arrived; the
    /// caller asks [`Recorder::time_left`] how long it may wait for the next map.
    Time(Duration),
}

impl Default for CommitEvery {
    fn default() -> Self {
        Self::Time(Duration::from_secs(5))
    }
}

/// How `record` says it: `720 maps`, `5.000 s`.
impl std::fmt::Display for CommitEvery {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Maps(n) => write!(f, "{n} maps"),
            Self::Time(t) => write!(f, "{:.3} s", t.as_secs_f64()),
        }
    }
}

/// Reads what `record --commit-every` takes: a number of maps (`720`) or a duration (`5s`,
/// `1min`).
///
/// ```
/// use froctomap_convert::CommitEvery;
/// use std::time::Duration;
/// assert_eq!("720".parse::<CommitEvery>().unwrap(), CommitEvery::Maps(720));
/// assert_eq!("5s".parse::<CommitEvery>().unwrap(), CommitEvery::Time(Duration::from_secs(5)));
/// assert!("0".parse::<CommitEvery>().unwrap_err().to_string().contains("at least 1 map"));
/// ```
impl std::str::FromStr for CommitEvery {
    type Err = TimeError;

    fn from_str(text: &str) -> Result<Self, TimeError> {
        let refuse = |reason: String| TimeError {
            input: text.to_string(),
            what: "number of maps or a duration",
            reason,
        };
        if let Ok(maps) = text.trim().parse::<usize>() {
            return match maps {
                0 => Err(refuse("give at least 1 map".into())),
                maps => Ok(Self::Maps(maps)),
            };
        }
        match parse_duration(text) {
            Ok(ns) if ns > 0 => Ok(Self::Time(Duration::from_nanos(ns.unsigned_abs()))),
            Ok(_) => Err(refuse("give a positive duration".into())),
            Err(error) => Err(refuse(error.reason)),
        }
    }
}

/// How to record.
#[derive(Clone, Debug)]
pub struct RecordOptions {
    /// When to commit.
    pub commit_every: CommitEvery,
    /// How the maps are read and stored ([`AppendOptions::skip_bad`]: leave bad maps out
    /// instead of stopping; `memory`, `tmp_dir`: the ingest's spill). Also the options of
    /// the base build when the file does not exist.
    pub append: AppendOptions,
    /// Where the spool of maps taken as bytes goes; `None`: beside the file.
    pub spool_dir: Option<PathBuf>,
    /// When and how the file is compacted once due (see [`Recorder`]); after the commit
    /// that makes it due by default. A compaction refits with `append.config.options`, not
    /// the options the file was built with (files do not record them).
    pub compact: Compaction,
    /// The compactions' [`CompactOptions::tile_budget`]: past it, a compaction writes
    /// deeper (smaller) tiles, so that the recording compacts in bounded memory however
    /// long it runs.
    pub tile_budget: Option<u64>,
}

/// How a [`Recorder`] compacts its file once a compaction is due (see [`Recorder`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum Compaction {
    /// Never: the file grows by a segment per commit until `froctomap compact` makes it one
    /// base again.
    Off,
    /// In place, right after the commit that makes it due: no map is taken until it is done
    /// (a caller's queue or pipe holds them meanwhile).
    #[default]
    AfterCommit,
    /// On a thread of its own while commits go on: the file as committed when it became
    /// due is compacted beside it, the maps committed meanwhile are added to the result,
    /// which replaces the file at the first commit after it is done (or at
    /// [`Recorder::finish`], which waits for it). For live sources, whose maps would be lost
    /// while the recorder waited. Memory: the compaction's budget on top of the commits'.
    Background,
}

impl Default for RecordOptions {
    fn default() -> Self {
        Self {
            commit_every: CommitEvery::default(),
            append: AppendOptions::default(),
            spool_dir: None,
            compact: Compaction::AfterCommit,
            tile_budget: Some(crate::compact::DEFAULT_TILE_BUDGET),
        }
    }
}

/// When a [`Recorder`] compacts (LIVING-MAP.md, "Refits and compaction"): after a commit,
/// when the segments' bytes exceed [`SEGMENTS_PER_BASE`] of the base's and the samples
/// added since the base are at least [`ADDED_PER_BASE`] of the base's, or when the span
/// from the first sample to the last has reached [`SPAN_GROWTH`] times the base's.
///
/// The first rule keeps a file at most 1.5× its base; its guard makes every compaction of a
/// base of `n` samples follow at least `n` new ones, so that a compaction (a build of the
/// whole history) costs at most what compacting 2 maps does per map added, however long
/// the history; the second makes compactions a geometric series in time (each one's history
/// twice the last one's), refitting models as the span grows.
///
/// A third rule is a safety net: a compaction is also due when the segments reach
/// [`SEGMENT_LIMIT_SHARE`] of the format's segment limit
/// ([`ReadLimits::max_segments`](froctomap_file::ReadLimits::max_segments), 65,536). Without
/// it, commits every 5 s in real time (17,280 segments a day) reach the limit between two
/// doublings of the span (at about 11 days) and recording stops. Past that point its
/// compactions are not amortised: one every 16,384 commits (about 23 hours at 5 s), each a
/// build of the whole history (LIVING-MAP.md, "Segments piling up").
pub const SEGMENTS_PER_BASE: (u64, u64) = (1, 2);
/// See [`SEGMENTS_PER_BASE`].
pub const ADDED_PER_BASE: (u64, u64) = (1, 1);
/// See [`SEGMENTS_PER_BASE`].
pub const SPAN_GROWTH: i64 = 2;
/// See [`SEGMENTS_PER_BASE`]: a quarter of the segment limit, so that a background
/// compaction has the other three quarters' commits to finish in.
pub const SEGMENT_LIMIT_SHARE: (u64, u64) = (1, 4);

impl RecordOptions {
    /// The options of a live source (a ROS 2 subscription): commits every `commit_every`,
    /// a bad map is left out and said, never the end of the recording (`skip_bad`, however
    /// many are skipped), the spool beside the file and compaction in the background (in
    /// place it would stall the intake for as long as a build of the whole history).
    ///
    /// ```
    /// use froctomap_convert::{CommitEvery, Compaction, RecordOptions};
    /// let options = RecordOptions::for_live_source(CommitEvery::Maps(2));
    /// assert!(options.append.skip_bad && options.compact == Compaction::Background);
    /// ```
    pub fn for_live_source(commit_every: CommitEvery) -> Self {
        Self {
            commit_every,
            append: AppendOptions {
                skip_bad: true,
                allow_mostly_skipped: true,
                ..AppendOptions::default()
            },
            compact: Compaction::Background,
            ..Self::default()
        }
    }
}

/// What the file was when the recorder opened it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Opened {
    /// A 2.0 file.
    Living,
    /// A 1.x file, converted to 2.0 in place (older releases cannot read it any more).
    Converted,
    /// No file: the first commit's maps become its base.
    Missing,
}

/// What a commit added.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct CommitReport {
    /// The file's segment count after the commit; `None` for the base built into a file
    /// that did not exist.
    pub segment: Option<usize>,
    /// Maps committed.
    pub maps: usize,
    /// The first and the last map's time.
    pub first: Timestamp,
    /// See `first`.
    pub last: Timestamp,
    /// The file's committed bytes before (0 for a new file) and after the commit.
    pub bytes_before: u64,
    /// See `bytes_before`.
    pub bytes: u64,
    /// How long the commit took.
    pub elapsed: Duration,
    /// (input, warning) of maps that read with a warning.
    pub warnings: Vec<(PathBuf, String)>,
    /// (input, reason) of maps skipped (with `skip_bad`).
    pub skipped: Vec<SkippedInput>,
}

/// What happened while recording, in the order it happened, as [`Recorder::on_event`]'s
/// observer receives it.
#[derive(Debug)]
#[non_exhaustive]
pub enum RecordEvent<'e> {
    /// A commit (the base of a new file, or a segment).
    Committed(&'e CommitReport),
    /// Maps left out with `skip_bad`: how many, and why (the error of their commit).
    LeftOut {
        /// How many maps.
        maps: usize,
        /// Which ("committing the map of … (…)", "committing N maps (… .. …)").
        what: &'e str,
        /// Why.
        error: &'e ConvertError,
    },
    /// The file compacted after a commit: base and segments refitted into one base (in
    /// the background: swapped in, [`CompactReport::maps_added_meanwhile`] the maps
    /// committed while it ran).
    Compacted(&'e CompactReport),
    /// A background compaction failed: the file keeps every commit, as before it, and
    /// this recorder compacts no more (`froctomap compact` the file later).
    CompactionFailed(&'e ConvertError),
    /// A commit of several maps failed and is tried again as two halves, in order (a bad
    /// map among them is then found and left out, or the failure repeats): how many maps,
    /// which, and the error of the whole.
    Retrying {
        /// How many maps the failed commit held.
        maps: usize,
        /// Which ("committing N maps (… .. …)").
        what: &'e str,
        /// Why the whole failed.
        error: &'e ConvertError,
    },
}

/// Counts of a recording so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct RecordSummary {
    /// Maps committed.
    pub committed_maps: usize,
    /// Commits made (the base of a new file included).
    pub commits: usize,
    /// Maps skipped as not later than the last one taken.
    pub older: u64,
    /// Bad maps left out (with `skip_bad`).
    pub bad: u64,
    /// Automatic compactions.
    pub compactions: usize,
}

/// Why recording failed. What was committed before stays committed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// Opening, converting or reading the file, or reading inputs, failed.
    #[error(transparent)]
    Convert(#[from] ConvertError),
    /// The spool of maps taken as bytes could not be written or read.
    #[error(transparent)]
    Spool(#[from] SpoolError),
    /// The file holds the most segments it may: `froctomap compact` makes it one again.
    #[error("{} holds {segments} segments, the most a file may hold: run `froctomap compact {}` and record on (the maps received before are committed)", file.display(), file.display())]
    SegmentLimit {
        /// The file.
        file: PathBuf,
        /// Its segments.
        segments: usize,
        /// The limit.
        limit: u64,
    },
    /// An automatic compaction failed; the file holds every commit made, as before it.
    #[error("{}: compacting after a commit failed (every commit is kept; `froctomap compact` it, or record with --no-compact)", file.display())]
    Compact {
        /// The file.
        file: PathBuf,
        /// Why it failed.
        #[source]
        source: Box<ConvertError>,
    },
    /// A commit failed: `what` says which maps ("committing the map of … (…)",
    /// "committing N maps (… .. …)"); the maps before it are committed.
    #[error("{what}")]
    Commit {
        /// The maps of the commit.
        what: String,
        /// Why it failed.
        #[source]
        source: Box<ConvertError>,
    },
}

impl RecordError {
    /// Whether the error is a map's own (unreadable, of another resolution, too large),
    /// which `skip_bad` leaves out, rather than the file's or the disk's.
    pub fn is_bad_map(&self) -> bool {
        match self {
            Self::Commit { source, .. } => is_bad_map(source),
            Self::Convert(source) => is_bad_map(source),
            _ => false,
        }
    }
}

/// The observer of [`RecordEvent`]s.
type Observer<'a> = Box<dyn FnMut(RecordEvent<'_>) + 'a>;

/// Maps added to a FROctomap 2.0 file one at a time, committed as segments when due.
///
/// The recorder holds the file's writer lock for its life. Maps are taken as map files
/// ([`take_file`](Self::take_file)) or as map bytes ([`take_bytes`](Self::take_bytes), kept
/// in a spool beside the file until committed). A map not later than the last one taken is
/// skipped and counted. A commit that fails is retried in halves, so a bad map commits the
/// maps before it and stops naming it ([`RecordError::Commit`]), or, with
/// [`AppendOptions::skip_bad`], is left out and counted. A missing file gets the first
/// commit's maps as its base; a 1.x file is converted to 2.0 when opened; at the segment
/// limit the next commit is refused ([`RecordError::SegmentLimit`]).
///
/// **Compaction.** With [`RecordOptions::compact`] (the default), after a commit the file
/// is compacted in place ([`compact`](crate::compact()): base and segments refitted into one
/// base, equal to a build of the same maps at the depth written, which deepens past
/// [`RecordOptions::tile_budget`]; the build's bounded memory,
/// [`AppendOptions::memory`]; atomic; under the writer lock the recorder holds) when its
/// segments exceed half of its base's bytes (once the samples added since the base are as
/// many as the base's), or when the span from its first sample to its last has reached
/// twice the base's span ([`SEGMENTS_PER_BASE`]): at most 1.5× the base at every commit
/// where segments cost per map at most twice what the base does, at an amortised cost per
/// map that does not grow with the history; and when the segments reach a quarter of the
/// segment limit ([`SEGMENT_LIMIT_SHARE`]), so that frequent commits never reach it. Maps are not taken while it runs (a caller's
/// queue or pipe holds them).
///
/// ```no_run
/// use froctomap_convert::*;
/// use std::path::{Path, PathBuf};
/// let context = Context::with_default_plugins();
/// let options = RecordOptions { commit_every: CommitEvery::Maps(60), ..RecordOptions::default() };
/// let mut recorder = Recorder::open(&context, Path::new("office.froct"), options)?;
/// recorder.on_event(|event| {
///     if let RecordEvent::Committed(commit) = event {
///         println!("{} maps committed, {} bytes", commit.maps, commit.bytes);
///     }
/// });
/// for input in collect_inputs(&context, &[PathBuf::from("maps/")], TimeSource::Auto)? {
///     recorder.take_file(input)?;
/// }
/// let summary = recorder.finish()?;
/// println!("{} maps in {} commits, {} older skipped", summary.committed_maps, summary.commits, summary.older);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Recorder<'a> {
    context: &'a Context,
    file: PathBuf,
    /// `None`: the file does not exist yet, and the first commit's maps become its base.
    writer: Option<LivingWriter>,
    opened: Opened,
    options: RecordOptions,
    spool_dir: PathBuf,
    /// The last time taken (the file's last sample at first).
    last: Option<Timestamp>,
    files: Vec<SeriesInput>,
    spool: Option<MapSpool>,
    /// When the first map of the commit being gathered arrived.
    gathering_since: Option<Instant>,
    summary: RecordSummary,
    observer: Observer<'a>,
    /// A compaction running on its own thread ([`Compaction::Background`]).
    background: Option<BackgroundCompaction>,
    /// A background compaction failed: no more are started.
    compaction_failed: bool,
}

impl std::fmt::Debug for Recorder<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("file", &self.file)
            .field("opened", &self.opened)
            .field("pending", &self.pending())
            .field("summary", &self.summary)
            .finish_non_exhaustive()
    }
}

impl<'a> Recorder<'a> {
    /// Opens `file` for recording, taking its writer lock: a 2.0 file as it is, a 1.x file
    /// converted to 2.0 in place first (atomically), a missing file left to the first
    /// commit. A file whose model cannot grow (`fremen-regular`) is refused before
    /// anything is written ([`ConvertError::ModelCannotGrow`]).
    pub fn open(
        context: &'a Context,
        file: &Path,
        options: RecordOptions,
    ) -> Result<Self, RecordError> {
        let (writer, opened) = if file.exists() {
            refuse_growing_fixed_span(context, file)?;
            let opened = if is_living_file(file)? {
                Opened::Living
            } else {
                LivingWriter::convert(file, file).map_err(ConvertError::from)?;
                Opened::Converted
            };
            let writer =
                LivingWriter::open_with_limits(file, context.limits().froct, context.models())
                    .map_err(ConvertError::from)?;
            (Some(writer), opened)
        } else {
            (None, Opened::Missing)
        };
        let last = writer.as_ref().map(|w| w.reader().last_instant());
        let spool_dir = options
            .spool_dir
            .clone()
            .unwrap_or_else(|| output_dir(file).to_path_buf());
        // What a killed recorder left (its spool, a compaction's work) goes now, not only
        // when this one spools or compacts; a live writer's is locked and stays.
        remove_stale_temporary_dirs(&spool_dir, OsStr::new(SPOOL_PREFIX));
        remove_stale_temporary_dirs(output_dir(file), OsStr::new(COMPACT_PREFIX));
        // And a compaction's or a conversion's copy of the file killed before its rename
        // (`.froct-…tmp`, `LivingWriter::convert`): a file the size of the map otherwise.
        remove_stale_temporary_files(output_dir(file), OsStr::new(".froct-"));
        Ok(Self {
            context,
            file: file.to_path_buf(),
            writer,
            opened,
            options,
            spool_dir,
            last,
            files: Vec::new(),
            spool: None,
            gathering_since: None,
            summary: RecordSummary::default(),
            observer: Box::new(|_| {}),
            background: None,
            compaction_failed: false,
        })
    }

    /// Calls `observer` with each [`RecordEvent`] from now on, as it happens.
    pub fn on_event(&mut self, observer: impl FnMut(RecordEvent<'_>) + 'a) {
        self.observer = Box::new(observer);
    }

    /// What the file was when opened.
    pub fn opened(&self) -> Opened {
        self.opened
    }

    /// The file's tile depth (`None` until a missing file's first commit made its base,
    /// which takes [`AppendOptions::tile_depth`](crate::AppendOptions)).
    pub fn tile_depth(&self) -> Option<u8> {
        self.writer
            .as_ref()
            .map(|writer| writer.reader().header().tile_depth)
    }

    /// The file's last sample, or the last map taken since (`None`: a new file, nothing
    /// taken yet).
    pub fn last_time(&self) -> Option<Timestamp> {
        self.last
    }

    /// The counts so far.
    pub fn summary(&self) -> RecordSummary {
        self.summary
    }

    /// Maps taken and not committed yet.
    pub fn pending(&self) -> usize {
        self.files.len() + self.spool.as_ref().map_or(0, MapSpool::len)
    }

    /// Takes the map file (or recorded map) `input`; commits when due. Returns `false` when
    /// the map was skipped as not later than the last one taken.
    pub fn take_file(&mut self, input: SeriesInput) -> Result<bool, RecordError> {
        if self.pending() == 0 {
            self.refuse_full()?;
        }
        let taken = self.is_later(input.time);
        if taken {
            self.files.push(input);
        }
        self.commit_if_due()?;
        Ok(taken)
    }

    /// Takes the map `bytes` (a `.bt`/`.ot` file's bytes) taken at `time`, spooled beside
    /// the file until committed; commits when due. Returns `false` when the map was skipped
    /// as not later than the last one taken.
    pub fn take_bytes(&mut self, time: Timestamp, bytes: &[u8]) -> Result<bool, RecordError> {
        if self.pending() == 0 {
            self.refuse_full()?;
        }
        let taken = self.is_later(time);
        if taken {
            let spool = match &mut self.spool {
                Some(spool) => spool,
                None => self
                    .spool
                    .insert(MapSpool::new(Some(&self.spool_dir), STDIN_INPUT)?),
            };
            spool.push(time, bytes)?;
        }
        self.commit_if_due()?;
        Ok(taken)
    }

    /// Counts a map the caller could not read and left out (with `skip_bad`).
    pub fn count_bad(&mut self) {
        self.summary.bad += 1;
    }

    /// How long until a commit by time is due (`None`: none is — nothing gathered, or
    /// commits by count).
    pub fn time_left(&self) -> Option<Duration> {
        match (self.options.commit_every, self.gathering_since) {
            (CommitEvery::Time(every), Some(since)) => Some(every.saturating_sub(since.elapsed())),
            _ => None,
        }
    }

    /// Commits the maps gathered if a commit is due (by count or by time).
    pub fn commit_if_due(&mut self) -> Result<(), RecordError> {
        let due = match self.options.commit_every {
            CommitEvery::Maps(n) => self.pending() >= n,
            CommitEvery::Time(_) => self.time_left() == Some(Duration::ZERO),
        };
        if due {
            self.commit()?;
        }
        Ok(())
    }

    /// Commits the maps gathered now: as one segment, or, when that fails, in smaller
    /// pieces, so that every good map before a bad one is committed.
    pub fn commit(&mut self) -> Result<(), RecordError> {
        self.gathering_since = None;
        if self.pending() == 0 {
            return Ok(());
        }
        let mut series = std::mem::take(&mut self.files);
        if let Some(spool) = self.spool.take() {
            let recording = spool.into_recording()?;
            series.extend(collect_recording(PathBuf::from(STDIN_INPUT), recording)?.series);
        }
        series.sort_by_key(|input| input.time);
        self.commit_pieces(&series)?;
        if self.background.as_ref().is_some_and(|b| b.is_finished()) {
            self.swap_in_background()?;
        }
        if self.compaction_due() {
            match self.options.compact {
                Compaction::AfterCommit => self.compact()?,
                Compaction::Background => self.start_background()?,
                _ => {}
            }
        }
        Ok(())
    }

    /// Whether the file is past a compaction threshold (see [`Recorder`]).
    fn compaction_due(&self) -> bool {
        let Some(writer) = &self.writer else {
            return false;
        };
        let reader = writer.reader();
        let off = self.options.compact == Compaction::Off || self.compaction_failed;
        if off || self.background.is_some() || reader.segment_count() == 0 {
            return false;
        }
        let (l_num, l_den) = SEGMENT_LIMIT_SHARE;
        let limit = self.context.limits().froct.max_segments;
        if (reader.segment_count() as u64).saturating_mul(l_den) >= limit.saturating_mul(l_num) {
            return true;
        }
        let root = reader.root();
        let base = &reader.header().axis;
        let segments = root.committed_len.saturating_sub(root.base_len);
        let added = u64::from(reader.sample_count().saturating_sub(base.len()));
        let (s_num, s_den) = SEGMENTS_PER_BASE;
        let (a_num, a_den) = ADDED_PER_BASE;
        if segments.saturating_mul(s_den) > root.base_len.saturating_mul(s_num)
            && added.saturating_mul(a_den) >= u64::from(base.len()).saturating_mul(a_num)
        {
            return true;
        }
        let base_span = base.end().0.saturating_sub(base.start().0);
        let span = reader.last_instant().0.saturating_sub(base.start().0);
        span >= base_span.saturating_mul(SPAN_GROWTH)
    }

    /// Compacts the file in place, holding its lock throughout, then opens it again.
    fn compact(&mut self) -> Result<(), RecordError> {
        let Some(writer) = self.writer.take() else {
            return Ok(());
        };
        let options = self.compact_options();
        let compacted = compact_held(self.context, writer, &options, &Silent);
        // Opened again whether or not it succeeded: a failed compaction left the file as
        // it was.
        let reopened = LivingWriter::open_with_limits(
            &self.file,
            self.context.limits().froct,
            self.context.models(),
        );
        self.writer = reopened.ok();
        let report = compacted.map_err(|source| RecordError::Compact {
            file: self.file.clone(),
            source: Box::new(source),
        })?;
        if self.writer.is_none() {
            // Said at once; the next commit would fail on it too.
            LivingWriter::open_with_limits(
                &self.file,
                self.context.limits().froct,
                self.context.models(),
            )
            .map(|writer| self.writer = Some(writer))
            .map_err(ConvertError::from)?;
        }
        self.summary.compactions += 1;
        (self.observer)(RecordEvent::Compacted(&report));
        Ok(())
    }

    /// Starts compacting the file as committed now on a thread of its own.
    fn start_background(&mut self) -> Result<(), RecordError> {
        let series = self.context.open_series(&self.file)?;
        let started = BackgroundCompaction::start(
            self.context,
            series,
            &self.file,
            self.compact_options(),
            self.options.append.clone(),
        );
        match started {
            Ok(background) => self.background = Some(background),
            Err(error) => {
                self.compaction_failed = true;
                (self.observer)(RecordEvent::CompactionFailed(&error));
            }
        }
        Ok(())
    }

    /// Waits for the background compaction (if any), adds to its result the maps committed
    /// since it last looked, and makes it the file. A failure is said
    /// ([`RecordEvent::CompactionFailed`]), and leaves the file as it was: recording goes
    /// on, without compactions.
    fn swap_in_background(&mut self) -> Result<(), RecordError> {
        let Some(background) = self.background.take() else {
            return Ok(());
        };
        let swapped = background.join().and_then(|mut compacted| {
            compacted.catch_up(self.context, &self.file, &self.options.append, &Silent)?;
            let held = self
                .writer
                .take()
                .ok_or_else(|| ConvertError::internal("no writer to replace"))?;
            let writer = held
                .replace_with(compacted.writer, self.context.models())
                .map_err(ConvertError::from)?;
            self.writer = Some(writer);
            let mut report = compacted.report;
            report.bytes = self
                .writer
                .as_ref()
                .map_or(0, |w| w.reader().root().committed_len);
            report.seconds = compacted.started.elapsed().as_secs_f64();
            Ok(report)
        });
        match swapped {
            Ok(report) => {
                self.summary.compactions += 1;
                (self.observer)(RecordEvent::Compacted(&report));
            }
            Err(error) => {
                self.compaction_failed = true;
                (self.observer)(RecordEvent::CompactionFailed(&error));
            }
        }
        if self.writer.is_none() {
            // Lost with a swap that failed midway: the file is as it was.
            self.writer = Some(
                LivingWriter::open_with_limits(
                    &self.file,
                    self.context.limits().froct,
                    self.context.models(),
                )
                .map_err(ConvertError::from)?,
            );
        }
        Ok(())
    }

    /// The options of the recorder's compactions.
    fn compact_options(&self) -> CompactOptions {
        let append = &self.options.append;
        CompactOptions {
            model_options: append.config.options.clone(),
            memory: append.memory,
            tmp_dir: append.tmp_dir.clone(),
            tile_budget: self.options.tile_budget,
            ..CompactOptions::default()
        }
    }

    /// Commits what is gathered and ends the recording (the writer lock is released); a
    /// background compaction still running is waited for and swapped in.
    pub fn finish(mut self) -> Result<RecordSummary, RecordError> {
        self.commit()?;
        self.swap_in_background()?;
        Ok(self.summary)
    }

    /// Commits what is gathered and ends the recording at once (the writer lock is
    /// released): a background compaction still running is cancelled, its work lost, the
    /// file as committed (how a live recorder stops on a signal).
    pub fn stop(mut self) -> Result<RecordSummary, RecordError> {
        self.commit()?;
        if self.background.as_ref().is_some_and(|b| b.is_finished()) {
            self.swap_in_background()?;
        }
        drop(self.background.take());
        Ok(self.summary)
    }

    /// Whether a background compaction is running (not yet done).
    pub fn compacting(&self) -> bool {
        self.background.as_ref().is_some_and(|b| !b.is_finished())
    }

    /// Whether a map at `time` is later than the last one taken (else it is counted as
    /// older).
    fn is_later(&mut self, time: Timestamp) -> bool {
        if self.last.is_some_and(|last| time <= last) {
            self.summary.older += 1;
            return false;
        }
        self.last = Some(time);
        self.gathering_since.get_or_insert_with(Instant::now);
        true
    }

    /// Refuses to gather another commit when the file holds the most segments it may.
    fn refuse_full(&self) -> Result<(), RecordError> {
        let Some(writer) = &self.writer else {
            return Ok(());
        };
        let (segments, limit) = (
            writer.reader().segment_count(),
            self.context.limits().froct.max_segments,
        );
        if segments as u64 >= limit {
            return Err(RecordError::SegmentLimit {
                file: self.file.clone(),
                segments,
                limit,
            });
        }
        Ok(())
    }

    /// Commits `series` as one segment; when that fails, its halves in order (a segment
    /// commits all its maps or none). Without `skip_bad` the first map that fails alone
    /// stops with its error; with it, that map is reported, counted and left out. A failure
    /// that is not the maps' (the file, the disk) fails alone as well, after at most
    /// log2(maps) tries.
    fn commit_pieces(&mut self, series: &[SeriesInput]) -> Result<(), RecordError> {
        self.refuse_full()?;
        let error = match self.commit_segment(series) {
            Ok(()) => return Ok(()),
            Err(error) => error,
        };
        let skip_bad = self.options.append.skip_bad;
        if skip_bad && matches!(error, ConvertError::NothingToBuild { .. }) {
            self.summary.bad += series.len() as u64;
            (self.observer)(RecordEvent::LeftOut {
                maps: series.len(),
                what: &committing(series),
                error: &error,
            });
            return Ok(());
        }
        match series {
            [] => Ok(()),
            [_] if skip_bad && is_bad_map(&error) => {
                self.summary.bad += 1;
                (self.observer)(RecordEvent::LeftOut {
                    maps: 1,
                    what: &committing(series),
                    error: &error,
                });
                Ok(())
            }
            [_] => Err(RecordError::Commit {
                what: committing(series),
                source: Box::new(error),
            }),
            _ => {
                // Said, so that a failure the halves then get past (a transient one, the
                // file's or the disk's) is not hidden.
                (self.observer)(RecordEvent::Retrying {
                    maps: series.len(),
                    what: &committing(series),
                    error: &error,
                });
                let (before, after) = series.split_at(series.len() / 2);
                self.commit_pieces(before)?;
                self.commit_pieces(after)
            }
        }
    }

    /// Commits `series` (time-sorted) as one segment, or as the base of a new file.
    fn commit_segment(&mut self, series: &[SeriesInput]) -> Result<(), ConvertError> {
        let started = Instant::now();
        let (first, last) = match (series.first(), series.last()) {
            (Some(first), Some(last)) => (first.time, last.time),
            _ => return Ok(()),
        };
        let report = match &mut self.writer {
            // Only a file that did not exist is built, and only once: a writer lost to a
            // failed compaction never makes a new base over the file.
            None if self.opened != Opened::Missing || self.summary.commits > 0 => {
                return Err(ConvertError::internal(
                    "the file is no longer open for recording (it could not be opened again after a compaction)",
                ))
            }
            None => {
                let built = self.build_base(series)?;
                CommitReport {
                    segment: None,
                    maps: built.used,
                    first,
                    last,
                    bytes_before: 0,
                    bytes: built.file_bytes,
                    elapsed: started.elapsed(),
                    warnings: Vec::new(),
                    skipped: built.skipped,
                }
            }
            Some(writer) => {
                let appended =
                    append_segment(self.context, writer, series, &self.options.append, &Silent)?;
                CommitReport {
                    segment: Some(appended.segments.unwrap_or(0)),
                    maps: appended.added,
                    first,
                    last,
                    bytes_before: appended.bytes_before,
                    bytes: appended.file_bytes,
                    elapsed: started.elapsed(),
                    warnings: appended.warnings,
                    skipped: appended.skipped,
                }
            }
        };
        self.summary.commits += 1;
        self.summary.committed_maps += report.maps;
        (self.observer)(RecordEvent::Committed(&report));
        Ok(())
    }

    /// The first maps built into the file, which did not exist (atomically, as `build`
    /// writes), then converted to 2.0 in place (atomically) and opened for the segments.
    /// Killed between the two, the file is a 1.x build, which the next recorder converts.
    fn build_base(
        &mut self,
        series: &[SeriesInput],
    ) -> Result<crate::build::BuildReport, ConvertError> {
        let append = &self.options.append;
        let options = BuildOptions {
            skip_bad: append.skip_bad,
            allow_mostly_skipped: true,
            input_format: append.input_format.clone(),
            backend: append.backend,
            memory: append.memory,
            tmp_dir: append.tmp_dir.clone(),
            tile_depth: append.tile_depth,
            ..BuildOptions::default()
        };
        let report = build(self.context, series, &self.file, &options, &Silent)?;
        LivingWriter::convert(&self.file, &self.file)?;
        self.writer = Some(LivingWriter::open_with_limits(
            &self.file,
            self.context.limits().froct,
            self.context.models(),
        )?);
        Ok(report)
    }
}

/// "committing the map of … (…)" or "committing N maps (… .. …)".
fn committing(series: &[SeriesInput]) -> String {
    use froctomap_core::calendar::iso8601;
    match series {
        [one] => format!(
            "committing the map of {} ({})",
            iso8601(one.time),
            one.path.display()
        ),
        [first, .., last] => format!(
            "committing {} maps ({} .. {})",
            series.len(),
            iso8601(first.time),
            iso8601(last.time)
        ),
        [] => "committing no map".to_string(),
    }
}

/// Whether `error` is a map's own (unreadable, of another resolution, too large), which
/// `skip_bad` leaves out, rather than the file's or the disk's.
fn is_bad_map(error: &ConvertError) -> bool {
    matches!(
        error,
        ConvertError::MixedResolution { .. }
            | ConvertError::Snapshot { .. }
            | ConvertError::Read(_)
            | ConvertError::SnapshotResolution { .. }
            | ConvertError::NothingToBuild { .. }
            | ConvertError::AllSkipped { .. }
            | ConvertError::MostlySkipped { .. }
            | ConvertError::TooManyMaps { .. }
            | ConvertError::BadResolution { .. }
    )
}
