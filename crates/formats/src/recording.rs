//! Recordings: one file (or directory) holding many timed maps, such as a ROS bag or an MCAP
//! file. A format of recordings is a plugin described by data ([`RecordingFormat`]: its name,
//! how its content is recognised, how it is opened and, optionally, written), registered in
//! the [`FormatRegistry`](crate::FormatRegistry) beside the map formats. Opening a recording
//! reads what its index tells (the maps' times) and hands back a [`Recording`] that owns its
//! files; each map's bytes are fetched when that map is read.

use crate::error::PluginError;
use crate::probe::{file_head, Confidence};
use froctomap_core::Timestamp;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Which time a recorded map is given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum RecordedTime {
    /// The time the map's message carries (a ROS header stamp); messages without one
    /// (a zero stamp) take the recording time, with a warning.
    #[default]
    Header,
    /// The time the recorder logged the message.
    Log,
}

impl froctomap_core::Named for RecordedTime {
    const ALL: &'static [Self] = &[Self::Header, Self::Log];
    const WHAT: &'static str = "time source";

    fn name(self) -> &'static str {
        match self {
            Self::Header => "header",
            Self::Log => "log",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Self::Header => "The header stamp of each message",
            Self::Log => "The recording (log) time of each message",
        }
    }
}

impl std::fmt::Display for RecordedTime {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(froctomap_core::Named::name(*self))
    }
}

impl std::str::FromStr for RecordedTime {
    type Err = froctomap_core::UnknownName;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        froctomap_core::parse_named(name)
    }
}

/// How recordings are read: which topic and which time.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct RecordingOptions {
    /// The topic to read; `None`: the one topic of a map message type.
    pub topic: Option<String>,
    /// Which time each map gets.
    pub time: RecordedTime,
    /// Leave out the damaged parts of a recording (a chunk that does not decompress or
    /// whose checksum fails, a message whose stamp cannot be read) and list them in
    /// [`Recording::skipped`], instead of refusing the recording.
    pub skip_bad: bool,
    /// Where a recording read from a stream ([`RecordingFormat::open_stream`]) keeps its
    /// maps until they are built: a locked temporary directory made in it, removed with the
    /// recording. `None`: the system's temporary directory.
    pub spool_dir: Option<PathBuf>,
}

impl RecordingOptions {
    /// Options reading `topic` (or the one map topic) with `time`.
    pub fn new(topic: Option<String>, time: RecordedTime) -> Self {
        Self {
            topic,
            time,
            skip_bad: false,
            spool_dir: None,
        }
    }

    /// The same options, leaving damaged parts out when `skip_bad` (see
    /// [`RecordingOptions::skip_bad`]).
    pub fn with_skip_bad(self, skip_bad: bool) -> Self {
        Self { skip_bad, ..self }
    }

    /// The same options, spooling streams in `dir` (see [`RecordingOptions::spool_dir`]).
    pub fn with_spool_dir(self, dir: Option<PathBuf>) -> Self {
        Self {
            spool_dir: dir,
            ..self
        }
    }
}

/// The maps of an opened recording, fetched one at a time.
pub trait RecordedMaps: Send + Sync + std::fmt::Debug {
    /// The bytes of map `index` (an index into [`Recording::times`]) as a map file of a
    /// format in the registry (e.g. a `.bt` file). Refuses a map above `limit` bytes
    /// before reading it.
    fn map_bytes(&self, index: usize, limit: u64) -> Result<Vec<u8>, PluginError>;

    /// What the maps are within the recording (a topic name), for messages.
    fn topic(&self) -> &str;
}

/// A recording as its format's plugin opened it.
#[derive(Debug)]
#[non_exhaustive]
pub struct Recording {
    /// The time of each recorded map, in the recording's order.
    pub times: Vec<Timestamp>,
    /// Things to tell the user (e.g. zero stamps replaced by recording times).
    pub warnings: Vec<String>,
    /// Parts of the recording left out with [`RecordingOptions::skip_bad`], each an error
    /// naming the recording, what was lost (a chunk and its messages' times) and why.
    pub skipped: Vec<PluginError>,
    /// Where the maps are fetched from.
    pub maps: Arc<dyn RecordedMaps>,
}

impl Recording {
    /// A recording of these maps at these times.
    pub fn new(times: Vec<Timestamp>, warnings: Vec<String>, maps: Arc<dyn RecordedMaps>) -> Self {
        Self {
            times,
            warnings,
            skipped: Vec::new(),
            maps,
        }
    }

    /// The same recording, with these parts left out.
    pub fn with_skipped(self, skipped: Vec<PluginError>) -> Self {
        Self { skipped, ..self }
    }
}

/// A format of recordings, described by data like a map format — once: the same
/// descriptor recognises, opens and (optionally) writes the format.
#[derive(Clone, Copy, Debug)]
pub struct RecordingFormat {
    /// Short name (e.g. `rosbag`).
    pub name: &'static str,
    /// One line for listings.
    pub description: &'static str,
    /// Extensions of its files, lower case, without dot, the usual first (for outputs named
    /// without `--format`).
    pub extensions: &'static [&'static str],
    /// Recognises a recording file from its first bytes (at most
    /// [`PROBE_BYTES`](crate::PROBE_BYTES)).
    pub probe: fn(&[u8]) -> Confidence,
    /// Recognises a recording that is a directory (a ROS 2 bag) from its layout; `None`:
    /// recordings of this format are single files.
    pub probe_dir: Option<fn(&Path) -> bool>,
    /// Opens a recording: its maps' times (from its index where it has one) and a handle,
    /// owning the opened files, to fetch the maps. The `u64` is the largest map read whole.
    pub open: fn(&Path, &RecordingOptions, u64) -> Result<Recording, PluginError>,
    /// Reads a recording from a stream that cannot seek (standard input, `-` among the
    /// inputs), message by message to its end, if the format can be streamed. A stream's
    /// maps all come before the series is built, so the plugin spools what it needs to
    /// disk ([`RecordingOptions::spool_dir`]) rather than into memory; a stream that ends
    /// early or does not read is an error naming where in the stream it stopped.
    pub open_stream: Option<OpenStream>,
    /// Writes a new recording of exported maps into one file, if the format can be written
    /// so.
    pub create: Option<CreateRecording>,
    /// Writes a new recording of exported maps that is a directory of files (a ROS 2 bag),
    /// if the format can be written so. The export makes the directory (new: an existing
    /// one is refused) and renames it into place once the writer finished.
    pub create_dir: Option<CreateRecordingDir>,
    /// Lists what a recording holds (every topic, not only maps), if the format can tell:
    /// `froctomap info` on a recording.
    pub describe: Option<DescribeRecording>,
}

/// Lists the topics of the recording at a path (`info`). The `u64` is the largest part
/// (chunk, message) read whole.
pub type DescribeRecording = fn(&Path, u64) -> Result<RecordingSummary, PluginError>;

/// One topic of a recording, as `ros2 bag info` lists it.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct RecordedTopic {
    /// Its name.
    pub topic: String,
    /// Its message type as the recording names it.
    pub type_name: String,
    /// How its messages are serialised (`cdr`, `ros1`…).
    pub encoding: String,
    /// Its messages.
    pub messages: u64,
    /// The log times of its first and last messages (`None`: no message).
    pub log_times: Option<(Timestamp, Timestamp)>,
}

impl RecordedTopic {
    /// A topic with its messages' count and log-time span.
    pub fn new(
        topic: String,
        type_name: String,
        encoding: String,
        messages: u64,
        log_times: Option<(Timestamp, Timestamp)>,
    ) -> Self {
        Self {
            topic,
            type_name,
            encoding,
            messages,
            log_times,
        }
    }
}

/// What a recording holds: its topics (in name order) and what its reader tolerated.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct RecordingSummary {
    /// The topics, in name order.
    pub topics: Vec<RecordedTopic>,
    /// Things to tell the user (a missing index read in order…).
    pub warnings: Vec<String>,
}

impl RecordingSummary {
    /// A summary of these topics (sorted by name here).
    pub fn new(mut topics: Vec<RecordedTopic>, warnings: Vec<String>) -> Self {
        topics.sort_by(|a, b| a.topic.cmp(&b.topic).then(a.type_name.cmp(&b.type_name)));
        Self { topics, warnings }
    }

    /// Messages of all topics.
    pub fn messages(&self) -> u64 {
        self.topics.iter().map(|t| t.messages).sum()
    }

    /// The log times of the first and last messages of all topics.
    pub fn log_times(&self) -> Option<(Timestamp, Timestamp)> {
        self.topics
            .iter()
            .filter_map(|t| t.log_times)
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
    }
}

/// Reads a recording from a stream whose first bytes the format's probe recognised
/// ([`RecordingFormat::open_stream`]). The `u64` is the largest map read whole.
pub type OpenStream =
    fn(&mut dyn std::io::Read, &RecordingOptions, u64) -> Result<Recording, PluginError>;

impl RecordingFormat {
    /// `true` when this format can be written ([`create`](Self::create) or
    /// [`create_dir`](Self::create_dir)).
    pub fn writable(&self) -> bool {
        self.create.is_some() || self.create_dir.is_some()
    }

    /// `true` when this format recognises `path`: a directory by its layout, a file by its
    /// first bytes. A file that cannot be read is nobody's recording (its reader says why).
    pub fn recognises(&self, path: &Path) -> bool {
        if path.is_dir() {
            return self.probe_dir.is_some_and(|probe| probe(path));
        }
        file_head(path).is_ok_and(|head| (self.probe)(&head) > Confidence::No)
    }
}

/// Where a [`RecordingWriter`] writes: a temporary file beside the output, renamed over it
/// once the writer finished, so a failed export leaves no partial recording.
pub trait RecordingSink: std::io::Write + std::io::Seek + Send {}

impl<T: std::io::Write + std::io::Seek + Send> RecordingSink for T {}

/// Makes a writer of a new recording into a sink, with the export's options.
pub type CreateRecording = fn(
    Box<dyn RecordingSink>,
    &RecordingWriteOptions,
) -> Result<Box<dyn RecordingWriter>, PluginError>;

/// Where a writer of a recording that is a directory ([`RecordingFormat::create_dir`]) puts
/// its files: a new temporary directory beside the output, owned by the export, renamed
/// to the output once the writer finished (so a failed export leaves nothing).
pub trait RecordingDir: Send {
    /// The name the recording will have (the output directory's own name, lossily UTF-8),
    /// for the names of the files in it (a ROS 2 bag's `NAME_0.mcap`).
    fn name(&self) -> &str;

    /// A new file `name` in the directory (a plain file name), to write.
    fn create_file(&mut self, name: &str) -> Result<Box<dyn RecordingSink>, PluginError>;
}

/// Makes a writer of a new recording that is a directory, with the export's options.
pub type CreateRecordingDir = fn(
    Box<dyn RecordingDir>,
    &RecordingWriteOptions,
) -> Result<Box<dyn RecordingWriter>, PluginError>;

/// Which messages a written recording holds beside the maps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum RecordingProfile {
    /// Standard ROS 2 messages only, every one in CDR with its `ros2msg` schema: what
    /// `ros2 bag play`, rviz2 and `mcap-ros2-support` read whole.
    #[default]
    Ros2,
    /// The ROS 2 messages, and Foxglove's own schemas (`foxglove.PointCloud`,
    /// `foxglove.SceneUpdate` cubes sized by the cell) in JSON for Foxglove's 3D panel.
    Foxglove,
}

impl froctomap_core::Named for RecordingProfile {
    const ALL: &'static [Self] = &[Self::Ros2, Self::Foxglove];
    const WHAT: &'static str = "recording profile";

    fn name(self) -> &'static str {
        match self {
            Self::Ros2 => "ros2",
            Self::Foxglove => "foxglove",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Self::Ros2 => "Standard ROS 2 messages only, all CDR",
            Self::Foxglove => "Also Foxglove's schemas (JSON)",
        }
    }
}

impl std::fmt::Display for RecordingProfile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(froctomap_core::Named::name(*self))
    }
}

impl std::str::FromStr for RecordingProfile {
    type Err = froctomap_core::UnknownName;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        froctomap_core::parse_named(name)
    }
}

/// How a recording is written: what a [`RecordingFormat::create`] is handed (and, for
/// `threshold`, what the exporter draws). Writers ignore what their format has no use for.
///
/// ```
/// use froctomap_formats::{RecordingProfile, RecordingWriteOptions};
/// let options = RecordingWriteOptions::default()
///     .with_profile(RecordingProfile::Foxglove)
///     .with_frame_id("odom")
///     .with_topic_prefix("/robot1")
///     .with_threshold(0.3);
/// assert_eq!((options.frame_id.as_str(), options.threshold), ("odom", 0.3));
/// ```
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct RecordingWriteOptions {
    /// Which messages beside the maps.
    pub profile: RecordingProfile,
    /// The `frame_id` of every message (default `map`).
    pub frame_id: String,
    /// Put before every topic name (`/robot1`: `/robot1/octomap_binary`…); empty: none.
    /// Starts with `/`, does not end with one.
    pub topic_prefix: String,
    /// A predicted cell is drawn (point clouds, markers, cubes) where its probability is
    /// above this (default 0.5, what the predicted map holds as occupied). The maps
    /// themselves are unchanged.
    pub threshold: f64,
}

impl Default for RecordingWriteOptions {
    fn default() -> Self {
        Self {
            profile: RecordingProfile::default(),
            frame_id: "map".to_string(),
            topic_prefix: String::new(),
            threshold: 0.5,
        }
    }
}

impl RecordingWriteOptions {
    /// The same options with `profile`.
    pub fn with_profile(self, profile: RecordingProfile) -> Self {
        Self { profile, ..self }
    }

    /// The same options with `frame_id`.
    pub fn with_frame_id(self, frame_id: impl Into<String>) -> Self {
        Self {
            frame_id: frame_id.into(),
            ..self
        }
    }

    /// The same options with `topic_prefix`.
    pub fn with_topic_prefix(self, topic_prefix: impl Into<String>) -> Self {
        Self {
            topic_prefix: topic_prefix.into(),
            ..self
        }
    }

    /// The same options with `threshold`.
    pub fn with_threshold(self, threshold: f64) -> Self {
        Self { threshold, ..self }
    }
}

/// A recording being written, one map at a time in time order (an export
/// to a recording format that has [`RecordingFormat::create`]).
pub trait RecordingWriter {
    /// Adds one map.
    fn write_map(&mut self, map: &ExportedMap<'_>) -> Result<(), PluginError>;

    /// Completes the recording (its index, summary…) and flushes the sink.
    fn finish(self: Box<Self>) -> Result<(), PluginError>;
}

/// What an exported map is.
/// A closed set: a map is observed or predicted, so writers match it exhaustively.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ExportedKind {
    /// The map as observed at this sample of the file's axis.
    Retrieved {
        /// The sample.
        sample: u32,
    },
    /// The map predicted for the instant (occupied where `p(t) > 0.5`).
    Predicted,
}

/// How an occupied cell of an exported map is to be shown.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum CellShade {
    /// A predicted cell, with its probability of being occupied (above 0.5).
    Probability(f32),
    /// A retrieved cell whose state changes over the file's span.
    Dynamic,
    /// A retrieved cell occupied over the whole span (wherever it was observed).
    Static,
}

/// An occupied cell of an exported map: `8^(16 − depth)` voxels from `start` in Morton
/// order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OccupiedCell {
    /// Morton code of its first voxel.
    pub start: froctomap_core::MortonCode,
    /// Its depth in the octree (16: one voxel).
    pub depth: u8,
    /// How to show it.
    pub shade: CellShade,
}

/// One map handed to a [`RecordingWriter`]: its time, what it is, its canonical `.bt` file
/// (the bytes a `.bt` export of the same time writes) and its occupied cells.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub struct ExportedMap<'a> {
    /// The instant the map is for.
    pub time: Timestamp,
    /// Retrieved or predicted.
    pub kind: ExportedKind,
    /// Voxel edge length, metres.
    pub resolution: f64,
    /// The map as a `.bt` file.
    pub bt: &'a [u8],
    /// The occupied cells, in Morton order.
    pub occupied: &'a [OccupiedCell],
}

impl<'a> ExportedMap<'a> {
    /// A map for a writer (writers' tests build their own).
    pub fn new(
        time: Timestamp,
        kind: ExportedKind,
        resolution: f64,
        bt: &'a [u8],
        occupied: &'a [OccupiedCell],
    ) -> Self {
        Self {
            time,
            kind,
            resolution,
            bt,
            occupied,
        }
    }
}
