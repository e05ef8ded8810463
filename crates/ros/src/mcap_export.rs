//! Writes exported maps into one MCAP file, the [`MCAP`](crate::MCAP) format's
//! [`RecordingWriter`]. With the default profile ([`RecordingProfile::Ros2`]) every channel
//! is CDR with its `ros2msg` schema embedded, so `ros2 bag play` and `mcap-ros2-support`
//! read the whole file: each map as an `octomap_msgs/msg/Octomap` on [`OCTOMAP_TOPIC`]
//! (`binary`), its occupied voxels as a `sensor_msgs/msg/PointCloud2` on
//! [`POINT_CLOUD2_TOPIC`] (what rviz2 and Rerun draw) and its occupied cells as a
//! `visualization_msgs/msg/MarkerArray` on [`OCCUPIED_CELLS_TOPIC`] (one `CUBE_LIST` per
//! depth, as `octomap_server`'s `occupied_cells_vis_array`, for rviz2). The profile
//! [`RecordingProfile::Foxglove`] adds, in JSON with their `jsonschema` schemas, the voxels
//! as a `foxglove.PointCloud` on [`POINT_CLOUD_TOPIC`] and the cells as
//! `foxglove.SceneUpdate` cubes sized by the cell on [`SCENE_TOPIC`]. All are stamped with
//! the map's time, as log and publish time too; chunks are zstd-compressed.

use crate::encode::{
    encode_octomap_cdr, MARKER_ARRAY_ROS2MSG, OCTOMAP_ROS2MSG, OCTOMAP_TYPE, POINT_CLOUD2_ROS2MSG,
    POINT_CLOUD2_TYPE,
};
use crate::error::McapWriteError;
use crate::foxglove::{
    kind_name, point_cloud2, point_cloud_json, scene_update_json, POINT_CLOUD_JSON_SCHEMA,
    POINT_CLOUD_SCHEMA, SCENE_UPDATE_JSON_SCHEMA, SCENE_UPDATE_SCHEMA,
};
use crate::markers::{encode_occupied_marker_array_cdr, MARKER_ARRAY_TYPE};
use crate::topics::{
    FRAME_ID, OCCUPIED_CELLS_TOPIC, OCTOMAP_TOPIC, POINT_CLOUD2_TOPIC, POINT_CLOUD_TOPIC,
    SCENE_TOPIC,
};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_formats::{
    ExportedKind, ExportedMap, PluginError as Cause, RecordingProfile, RecordingSink,
    RecordingWriteOptions, RecordingWriter,
};
use froctomap_octomap_codec::{parse_header, FileKind};
use mcap::records::MessageHeader;
use std::collections::BTreeMap;
use std::io::Write;

/// The messages an exported map becomes, one channel each.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Channel {
    Octomap,
    PointCloud2,
    Markers,
    FoxglovePointCloud,
    FoxgloveScene,
}

impl Channel {
    /// The channels of a profile, in the order each map's messages are written.
    fn of(profile: RecordingProfile) -> &'static [Channel] {
        use Channel::*;
        match profile {
            RecordingProfile::Foxglove => &[
                Octomap,
                PointCloud2,
                Markers,
                FoxglovePointCloud,
                FoxgloveScene,
            ],
            _ => &[Octomap, PointCloud2, Markers],
        }
    }

    /// Topic, schema name, schema encoding, schema, message encoding.
    fn spec(
        self,
    ) -> (
        &'static str,
        &'static str,
        &'static str,
        &'static str,
        &'static str,
    ) {
        match self {
            Channel::Octomap => (
                OCTOMAP_TOPIC,
                OCTOMAP_TYPE,
                "ros2msg",
                OCTOMAP_ROS2MSG,
                "cdr",
            ),
            Channel::PointCloud2 => (
                POINT_CLOUD2_TOPIC,
                POINT_CLOUD2_TYPE,
                "ros2msg",
                POINT_CLOUD2_ROS2MSG,
                "cdr",
            ),
            Channel::Markers => (
                OCCUPIED_CELLS_TOPIC,
                MARKER_ARRAY_TYPE,
                "ros2msg",
                MARKER_ARRAY_ROS2MSG,
                "cdr",
            ),
            Channel::FoxglovePointCloud => (
                POINT_CLOUD_TOPIC,
                POINT_CLOUD_SCHEMA,
                "jsonschema",
                POINT_CLOUD_JSON_SCHEMA,
                "json",
            ),
            Channel::FoxgloveScene => (
                SCENE_TOPIC,
                SCENE_UPDATE_SCHEMA,
                "jsonschema",
                SCENE_UPDATE_JSON_SCHEMA,
                "json",
            ),
        }
    }
}

/// An MCAP file being written (also a ROS 2 bag's storage file).
pub(crate) struct McapMapWriter {
    writer: mcap::Writer<Box<dyn RecordingSink>>,
    /// The profile's channels and their ids.
    channels: Vec<(Channel, u16)>,
    topic_prefix: String,
    frame_id: String,
    sequence: u32,
}

/// The name of the MCAP metadata record written with each map: `time_ns` (the map's time,
/// nanoseconds since 1970), `map` (`retrieved` or `predicted`) and, for a retrieved map,
/// `sample` (its index on the file's axis).
pub const MAP_METADATA: &str = "froctomap.map";

/// Refuses options a recording cannot be written with, naming the option (made an error by
/// `refused`: option, value, reason).
pub(crate) fn check_options<E>(
    options: &RecordingWriteOptions,
    refused: fn(&'static str, String, &'static str) -> E,
) -> Result<(), E> {
    let bad = |option, value: &str, reason| Err(refused(option, value.to_string(), reason));
    let frame = &options.frame_id;
    if frame.is_empty() || frame.len() > 256 || frame.chars().any(char::is_whitespace) {
        return bad(
            "frame id",
            frame,
            "expected a tf2 frame name: 1 to 256 bytes, no spaces",
        );
    }
    let prefix = &options.topic_prefix;
    let valid_name = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '/';
    if !prefix.is_empty()
        && (!prefix.starts_with('/')
            || prefix.ends_with('/')
            || prefix.contains("//")
            || !prefix.chars().all(valid_name))
    {
        return bad(
            "topic prefix",
            prefix,
            "expected a ROS name such as /robot1: starting with /, not ending with one, \
             of letters, digits, _ and /",
        );
    }
    if !(0.0..1.0).contains(&options.threshold) {
        return bad(
            "threshold",
            &options.threshold.to_string(),
            "expected a probability from 0 to below 1",
        );
    }
    Ok(())
}

/// [`RecordingFormat::create`](froctomap_formats::RecordingFormat::create) of MCAP.
pub(crate) fn create(
    sink: Box<dyn RecordingSink>,
    options: &RecordingWriteOptions,
) -> Result<Box<dyn RecordingWriter>, Cause> {
    Ok(Box::new(McapMapWriter::new(sink, options)?))
}

impl McapMapWriter {
    pub(crate) fn new(
        sink: Box<dyn RecordingSink>,
        options: &RecordingWriteOptions,
    ) -> Result<Self, McapWriteError> {
        check_options(options, |option, value, reason| McapWriteError::BadOption {
            option,
            value,
            reason,
        })?;
        // MCAP's `ros2` profile promises CDR channels with `ros2msg` schemas only: a file
        // with Foxglove's JSON channels names no profile.
        let header_profile = match options.profile {
            RecordingProfile::Ros2 => "ros2",
            _ => "",
        };
        let mut writer = mcap::WriteOptions::new()
            .profile(header_profile)
            .library(concat!("froctomap ", env!("CARGO_PKG_VERSION")))
            .create(sink)?;
        let none = BTreeMap::new();
        let mut channels = Vec::new();
        for &channel in Channel::of(options.profile) {
            let (topic, name, schema_encoding, schema, encoding) = channel.spec();
            let topic = format!("{}{topic}", options.topic_prefix);
            let schema = writer.add_schema(name, schema_encoding, schema.as_bytes())?;
            channels.push((
                channel,
                writer.add_channel(schema, &topic, encoding, &none)?,
            ));
        }
        Ok(Self {
            writer,
            channels,
            topic_prefix: options.topic_prefix.clone(),
            frame_id: options.frame_id.clone(),
            sequence: 0,
        })
    }

    /// The topics written, in order, each with its message type and encoding; every map
    /// is one message on each.
    pub(crate) fn topics(&self) -> Vec<(String, &'static str, &'static str)> {
        self.channels
            .iter()
            .map(|&(channel, _)| {
                let (topic, name, _, _, encoding) = channel.spec();
                (format!("{}{topic}", self.topic_prefix), name, encoding)
            })
            .collect()
    }

    pub(crate) fn write(&mut self, map: &ExportedMap<'_>) -> Result<(), McapWriteError> {
        let frame = self.frame_id.as_str();
        let (log_time, stamp, message) =
            octomap_message(map.time, frame, map.bt, Some(map.resolution))?;
        let mut metadata = BTreeMap::from([
            ("time_ns".to_string(), map.time.0.to_string()),
            ("map".to_string(), kind_name(map.kind).to_string()),
        ]);
        if let ExportedKind::Retrieved { sample } = map.kind {
            metadata.insert("sample".to_string(), sample.to_string());
        }
        self.writer.write_metadata(&mcap::records::Metadata {
            name: MAP_METADATA.to_string(),
            metadata,
        })?;
        let too_long = |bytes: usize| McapWriteError::MessageTooLong {
            bytes: bytes as u64,
        };
        for &(channel, channel_id) in &self.channels {
            let data = match channel {
                Channel::Octomap => None,
                Channel::PointCloud2 => {
                    Some(point_cloud2(stamp, frame, map.resolution, map.occupied)?)
                }
                Channel::Markers => Some(
                    encode_occupied_marker_array_cdr(stamp, frame, map.resolution, map.occupied)
                        .ok_or_else(|| too_long(map.occupied.len()))?,
                ),
                Channel::FoxglovePointCloud => Some(point_cloud_json(
                    map.time,
                    frame,
                    map.resolution,
                    map.occupied,
                )?),
                Channel::FoxgloveScene => Some(scene_update_json(
                    map.time,
                    frame,
                    map.kind,
                    map.resolution,
                    map.occupied,
                )?),
            };
            let header = MessageHeader {
                channel_id,
                sequence: self.sequence,
                log_time,
                publish_time: log_time,
            };
            self.writer
                .write_to_known_channel(&header, data.as_deref().unwrap_or(&message))?;
        }
        self.sequence = self.sequence.wrapping_add(1);
        Ok(())
    }
}

impl RecordingWriter for McapMapWriter {
    fn write_map(&mut self, map: &ExportedMap<'_>) -> Result<(), Cause> {
        Ok(self.write(map)?)
    }

    fn finish(mut self: Box<Self>) -> Result<(), Cause> {
        self.writer.finish().map_err(McapWriteError::from)?;
        let mut sink = self.writer.into_inner();
        sink.flush().map_err(McapWriteError::from)?;
        Ok(())
    }
}

/// An encoded map message: its log time, its ROS 2 stamp and its CDR bytes.
type OctomapMessage = (u64, (i32, u32), Vec<u8>);

/// A `.bt` file at `time` as an `octomap_msgs/msg/Octomap` message in CDR, with its log
/// time and stamp; `resolution`: the map's (default: its header's).
fn octomap_message(
    time: Timestamp,
    frame_id: &str,
    bt: &[u8],
    resolution: Option<f64>,
) -> Result<OctomapMessage, McapWriteError> {
    let out_of_range = || McapWriteError::TimeOutOfRange(iso8601(time));
    let log_time = u64::try_from(time.0).map_err(|_| out_of_range())?;
    let stamp = ros2_stamp(time).ok_or_else(out_of_range)?;
    let header = parse_header(bt, FileKind::Binary).map_err(McapWriteError::NotBinary)?;
    let body = bt.get(header.body_offset..).unwrap_or_default();
    let resolution = resolution.unwrap_or(header.resolution);
    let message = encode_octomap_cdr(stamp, frame_id, true, &header.tree_id, resolution, body)
        .ok_or(McapWriteError::MessageTooLong {
            bytes: body.len() as u64,
        })?;
    Ok((log_time, stamp, message))
}

/// Maps written as an MCAP stream into a writer that cannot seek (standard output, a pipe):
/// each map as an `octomap_msgs/msg/Octomap` message in CDR on [`OCTOMAP_TOPIC`] with its
/// `ros2msg` schema, stamped and logged at the map's time, each in a zstd chunk of its own
/// (flushed as it is written, for readers of a live stream), with the summary
/// at the end, as `froctomap generate --stream` writes for `froctomap build -`.
///
/// ```
/// use froctomap_core::Timestamp;
/// let bt = froctomap_octomap_codec::encode_binary(&froctomap_core::Snapshot::empty(0.1)?);
/// let mut stream = froctomap_ros::McapMapStream::new(Vec::new())?;
/// stream.write_map(Timestamp::from_secs(1_451_865_600), &bt)?;
/// let bytes = stream.finish()?;
/// assert!(bytes.starts_with(b"\x89MCAP0\r\n"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct McapMapStream<W: Write> {
    writer: mcap::Writer<mcap::write::NoSeek<W>>,
    octomap: u16,
    sequence: u32,
}

impl<W: Write> McapMapStream<W> {
    /// A stream into `out`, its header, schema and channel written.
    pub fn new(out: W) -> Result<Self, McapWriteError> {
        let mut writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("froctomap ", env!("CARGO_PKG_VERSION")))
            .disable_seeking(true)
            .create(mcap::write::NoSeek::new(out))?;
        let schema = writer.add_schema(OCTOMAP_TYPE, "ros2msg", OCTOMAP_ROS2MSG.as_bytes())?;
        let octomap = writer.add_channel(schema, OCTOMAP_TOPIC, "cdr", &BTreeMap::new())?;
        Ok(Self {
            writer,
            octomap,
            sequence: 0,
        })
    }

    /// Adds the map `bt` (a `.bt` file) taken at `time`.
    pub fn write_map(&mut self, time: Timestamp, bt: &[u8]) -> Result<(), McapWriteError> {
        let (log_time, _, message) = octomap_message(time, FRAME_ID, bt, None)?;
        let header = MessageHeader {
            channel_id: self.octomap,
            sequence: self.sequence,
            log_time,
            publish_time: log_time,
        };
        self.writer.write_to_known_channel(&header, &message)?;
        // Its chunk ended and flushed: a reader of the stream (`froctomap record -`) gets
        // each map as it is written, not once a chunk fills.
        self.writer.flush()?;
        self.sequence = self.sequence.wrapping_add(1);
        Ok(())
    }

    /// Ends the stream (the last chunk, the summary, the end magic), flushed; the writer.
    pub fn finish(mut self) -> Result<W, McapWriteError> {
        self.writer.finish()?;
        let mut out = self.writer.into_inner().into_inner();
        out.flush()?;
        Ok(out)
    }
}

/// A time as a ROS 2 stamp (`int32` seconds, nanoseconds), if it fits.
fn ros2_stamp(time: Timestamp) -> Option<(i32, u32)> {
    let seconds = i32::try_from(time.0.div_euclid(1_000_000_000)).ok()?;
    Some((seconds, time.0.rem_euclid(1_000_000_000) as u32))
}
