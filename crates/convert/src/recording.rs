//! Recordings: one file (or directory) holding many timed maps, such as a ROS bag or an MCAP
//! file. Formats of recordings are plugins ([`RecordingFormat`]) registered in the
//! [`Context`]; [`collect_inputs`](crate::collect_inputs) expands a recording into one input
//! per recorded map (its path is the recording's, its time the map's), cheaply, from what
//! the recording's index tells; extraction fetches each map's bytes when it reads that
//! snapshot. `build` has no case of its own for them.

use crate::context::Context;
use crate::error::{Cause, SnapshotError};
use crate::inputs::SeriesInput;
use froctomap_core::Timestamp;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

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
}

impl RecordingOptions {
    /// Options reading `topic` (or the one map topic) with `time`.
    pub fn new(topic: Option<String>, time: RecordedTime) -> Self {
        Self {
            topic,
            time,
            skip_bad: false,
        }
    }

    /// The same options, leaving damaged parts out when `skip_bad` (see
    /// [`RecordingOptions::skip_bad`]).
    pub fn with_skip_bad(self, skip_bad: bool) -> Self {
        Self { skip_bad, ..self }
    }
}

/// The maps of an opened recording, fetched one at a time.
pub trait RecordedMaps: Send + Sync + std::fmt::Debug {
    /// The bytes of map `index` (an index into [`Recording::times`]) as a map file of a
    /// format in the registry (e.g. a `.bt` file). Refuses a map above `limit` bytes
    /// before reading it.
    fn map_bytes(&self, index: usize, limit: u64) -> Result<Vec<u8>, Cause>;

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
    pub skipped: Vec<Cause>,
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
    pub fn with_skipped(self, skipped: Vec<Cause>) -> Self {
        Self { skipped, ..self }
    }
}

/// A format of recordings, described by data like a map format.
#[derive(Clone, Copy, Debug)]
pub struct RecordingFormat {
    /// Short name (e.g. `rosbag`).
    pub name: &'static str,
    /// One line for listings.
    pub description: &'static str,
    /// Recognises a recording from its path (a file's first bytes, or a directory's layout).
    pub probe: fn(&Path) -> bool,
    /// Opens a recording: its maps' times (from its index where it has one) and a handle to
    /// fetch them.
    pub open: fn(&Path, &RecordingOptions, u64) -> Result<Recording, Cause>,
    /// Extensions of its files, the usual first (for outputs named without `--format`).
    pub extensions: &'static [&'static str],
    /// Writes a new recording of exported maps, if the format can be written.
    pub create: Option<CreateRecording>,
}

/// The recordings a [`Context`] has opened while collecting inputs, by path, so that
/// extraction finds the map of an input (a recording's path and a time) again.
#[derive(Clone, Debug, Default)]
pub(crate) struct OpenRecordings {
    opened: Arc<Mutex<HashMap<PathBuf, Arc<OpenRecording>>>>,
}

#[derive(Debug)]
struct OpenRecording {
    /// (time, index into the recording's maps), sorted by time.
    by_time: Vec<(Timestamp, usize)>,
    maps: Arc<dyn RecordedMaps>,
}

impl OpenRecordings {
    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<PathBuf, Arc<OpenRecording>>> {
        // A panic elsewhere while holding the lock leaves the map intact.
        self.opened.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn insert(&self, path: &Path, recording: &Recording) {
        let mut by_time: Vec<(Timestamp, usize)> = recording
            .times
            .iter()
            .enumerate()
            .map(|(i, &t)| (t, i))
            .collect();
        by_time.sort_unstable();
        let open = OpenRecording {
            by_time,
            maps: recording.maps.clone(),
        };
        self.lock().insert(path.to_path_buf(), Arc::new(open));
    }

    fn get(&self, path: &Path) -> Option<Arc<OpenRecording>> {
        self.lock().get(path).cloned()
    }
}

/// The recording format that recognises `path`, if any.
pub(crate) fn recording_format<'c>(
    context: &'c Context,
    path: &Path,
) -> Option<&'c RecordingFormat> {
    context.recording_formats().iter().find(|f| (f.probe)(path))
}

/// The recording format named `name` if it can be written.
pub(crate) fn writable_recording<'c>(
    context: &'c Context,
    name: &str,
) -> Option<&'c RecordingFormat> {
    context
        .recording_formats()
        .iter()
        .find(|f| f.name == name && f.create.is_some())
}

/// Opens `path` with `format` and remembers it in `context` for extraction.
pub(crate) fn open_recording(
    context: &Context,
    format: &RecordingFormat,
    path: &Path,
) -> Result<Recording, crate::ConvertError> {
    let limit = context.limits().max_map_file_bytes;
    let recording = (format.open)(path, context.recording_options(), limit).map_err(|source| {
        crate::ConvertError::Recording {
            path: path.to_path_buf(),
            format: format.name,
            source,
        }
    })?;
    context.open_recordings().insert(path, &recording);
    Ok(recording)
}

/// `true` when `input` is a map of a recording opened while collecting the inputs.
pub(crate) fn is_recorded(context: &Context, input: &SeriesInput) -> bool {
    context.open_recordings().get(&input.path).is_some()
}

/// How messages name an input: its path, or for a recorded map
/// `recording/topic@time` (a name without an extension, so that no reader takes the
/// recording's extension for the map's).
pub(crate) fn input_name(context: &Context, input: &SeriesInput) -> PathBuf {
    match context.open_recordings().get(&input.path) {
        None => input.path.clone(),
        Some(open) => {
            let time = froctomap_core::calendar::iso8601(input.time).replace('.', ",");
            let topic = open.maps.topic().trim_matches('/').replace('.', "_");
            input.path.join(format!("{topic}@{time}"))
        }
    }
}

/// The bytes of an input's map: the file, or the recorded map at its time when its path is
/// a recording opened while collecting the inputs.
pub(crate) fn snapshot_bytes(
    context: &Context,
    input: &SeriesInput,
    limit: u64,
) -> Result<Vec<u8>, SnapshotError> {
    let Some(open) = context.open_recordings().get(&input.path) else {
        return crate::build::read_input(&input.path, limit);
    };
    let index = open
        .by_time
        .binary_search_by_key(&input.time, |&(t, _)| t)
        .map(|k| open.by_time[k].1)
        .map_err(|_| SnapshotError::Internal("an input time that its recording does not have"))?;
    open.maps
        .map_bytes(index, limit)
        .map_err(|e| SnapshotError::Recorded(Arc::from(e)))
}

/// Where a [`RecordingWriter`] writes: a temporary file beside the output, renamed over it
/// once the writer finished, so a failed export leaves no partial recording.
pub trait RecordingSink: std::io::Write + std::io::Seek + Send {}

impl<T: std::io::Write + std::io::Seek + Send> RecordingSink for T {}

/// Makes a writer of a new recording into a sink.
pub type CreateRecording = fn(Box<dyn RecordingSink>) -> Result<Box<dyn RecordingWriter>, Cause>;

/// A recording being written, one map at a time in time order ([`export`](crate::export)
/// to a recording format that has [`RecordingFormat::create`]).
pub trait RecordingWriter {
    /// Adds one map.
    fn write_map(&mut self, map: &ExportedMap<'_>) -> Result<(), Cause>;

    /// Completes the recording (its index, summary…) and flushes the sink.
    fn finish(self: Box<Self>) -> Result<(), Cause>;
}

/// What an exported map is.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
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
