//! Recorded maps as inputs. A recording's format (a plugin registered in the
//! [`FormatRegistry`](froctomap_formats::FormatRegistry)) opens it;
//! [`collect_inputs`](crate::collect_inputs) expands it into one input per recorded map, each
//! holding the opened recording ([`RecordedMap`]), so that extraction fetches a map's bytes
//! through its input alone — no registry or cache remembers what was opened. `build` has no
//! case of its own for them.

use crate::context::Context;
use crate::error::{ConvertError, SnapshotError};
use froctomap_formats::{RecordedMaps, Recording, RecordingFormat};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// One map of an opened recording: the recording (shared by all its maps, owning its files)
/// and the map's index in it. Dropping the last input of a recording closes it.
#[derive(Clone)]
pub struct RecordedMap {
    maps: Arc<dyn RecordedMaps>,
    index: usize,
}

impl RecordedMap {
    /// Map `index` of `maps` (an index into [`Recording::times`]).
    pub fn new(maps: Arc<dyn RecordedMaps>, index: usize) -> Self {
        Self { maps, index }
    }

    /// What the maps are within the recording (a topic name).
    pub fn topic(&self) -> &str {
        self.maps.topic()
    }

    /// The map's index in its recording.
    pub fn index(&self) -> usize {
        self.index
    }

    /// The map's bytes (the `.bt`/`.ot` file its message stands for), refused above `limit`.
    pub(crate) fn map_bytes(&self, limit: u64) -> Result<Vec<u8>, SnapshotError> {
        self.maps
            .map_bytes(self.index, limit)
            .map_err(|e| SnapshotError::Recorded(Arc::from(e)))
    }
}

impl std::fmt::Debug for RecordedMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RecordedMap")
            .field("topic", &self.maps.topic())
            .field("index", &self.index)
            .finish()
    }
}

/// The same map of the same opened recording.
impl PartialEq for RecordedMap {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::addr_eq(Arc::as_ptr(&self.maps), Arc::as_ptr(&other.maps))
            && self.index == other.index
    }
}

impl Eq for RecordedMap {}

/// Opens `path` with `format`, reading as `context`'s recording options say.
pub(crate) fn open_recording(
    context: &Context,
    format: &RecordingFormat,
    path: &Path,
) -> Result<Recording, ConvertError> {
    let limit = context.limits().max_map_file_bytes;
    (format.open)(path, context.recording_options(), limit).map_err(|source| {
        ConvertError::Recording {
            path: path.to_path_buf(),
            format: format.name,
            source,
        }
    })
}

/// What `info` says of a recording: its format, messages, log-time span and topics (as
/// `ros2 bag info` lists them), ready for `--json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RecordingInfo {
    /// The recording.
    pub file: PathBuf,
    /// Its format's name and description.
    pub format: &'static str,
    /// Its format's description.
    pub format_description: &'static str,
    /// Messages of all topics.
    pub messages: u64,
    /// The first and last log times (ISO 8601), and the span in seconds.
    pub start: Option<String>,
    /// The last log time (ISO 8601).
    pub end: Option<String>,
    /// Seconds from the first to the last message.
    pub duration_s: Option<f64>,
    /// The topics, in name order.
    pub topics: Vec<RecordedTopicInfo>,
    /// What the reader tolerated.
    pub warnings: Vec<String>,
}

/// One topic of [`RecordingInfo`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct RecordedTopicInfo {
    /// Its name.
    pub topic: String,
    /// Its message type.
    #[serde(rename = "type")]
    pub type_name: String,
    /// How its messages are serialised.
    pub encoding: String,
    /// Its messages.
    pub messages: u64,
    /// Log time of its first message (ISO 8601; nanoseconds in `first_ns`).
    pub first: Option<String>,
    /// Log time of its last message.
    pub last: Option<String>,
    /// Its first log time, nanoseconds since 1970.
    pub first_ns: Option<i64>,
    /// Its last log time, nanoseconds since 1970.
    pub last_ns: Option<i64>,
}

/// Describes `path` if it is a recording of a format that can list its topics (`None`: not
/// a recording).
pub fn describe_recording(
    context: &Context,
    path: &Path,
) -> Result<Option<RecordingInfo>, ConvertError> {
    use froctomap_core::calendar::iso8601;
    let Some(format) = context.formats().recording_for(path) else {
        return Ok(None);
    };
    let Some(describe) = format.describe else {
        return Ok(None);
    };
    let summary = describe(path, context.limits().max_map_file_bytes).map_err(|source| {
        ConvertError::Recording {
            path: path.to_path_buf(),
            format: format.name,
            source,
        }
    })?;
    let span = summary.log_times();
    let topics = summary
        .topics
        .iter()
        .map(|t| RecordedTopicInfo {
            topic: t.topic.clone(),
            type_name: t.type_name.clone(),
            encoding: t.encoding.clone(),
            messages: t.messages,
            first: t.log_times.map(|(a, _)| iso8601(a)),
            last: t.log_times.map(|(_, b)| iso8601(b)),
            first_ns: t.log_times.map(|(a, _)| a.0),
            last_ns: t.log_times.map(|(_, b)| b.0),
        })
        .collect();
    Ok(Some(RecordingInfo {
        file: path.to_path_buf(),
        format: format.name,
        format_description: format.description,
        messages: summary.messages(),
        start: span.map(|(a, _)| iso8601(a)),
        end: span.map(|(_, b)| iso8601(b)),
        duration_s: span.map(|(a, b)| b.secs_since(a)),
        topics,
        warnings: summary.warnings,
    }))
}
