//! Writes exported maps into one MCAP file, the [`MCAP`](crate::MCAP) format's
//! [`RecordingWriter`]: each map as an `octomap_msgs/msg/Octomap` message in CDR on
//! [`OCTOMAP_TOPIC`] (`binary`, the `ros2msg` schema embedded, so `ros2 bag play` replays
//! it to rviz), and its occupied voxels as a `foxglove.PointCloud` in JSON on
//! [`POINT_CLOUD_TOPIC`] (for Foxglove's 3D panel, without ROS), and the same points as a
//! `sensor_msgs/msg/PointCloud2` in CDR on [`POINT_CLOUD2_TOPIC`] (the standard message
//! rviz2 and Rerun draw). All are stamped with the map's time, as log and publish time
//! too; chunks are zstd-compressed.

use crate::encode::{
    encode_octomap_cdr, OCTOMAP_ROS2MSG, OCTOMAP_TYPE, POINT_CLOUD2_ROS2MSG, POINT_CLOUD2_TYPE,
};
use crate::error::McapWriteError;
use crate::foxglove::{
    point_cloud2, point_cloud_json, POINT_CLOUD_JSON_SCHEMA, POINT_CLOUD_SCHEMA,
};
use crate::topics::{FRAME_ID, OCTOMAP_TOPIC, POINT_CLOUD2_TOPIC, POINT_CLOUD_TOPIC};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_formats::{ExportedMap, PluginError as Cause, RecordingSink, RecordingWriter};
use froctomap_octomap_codec::{parse_header, FileKind};
use mcap::records::MessageHeader;
use std::collections::BTreeMap;
use std::io::Write;

/// An MCAP file being written.
struct McapMapWriter {
    writer: mcap::Writer<Box<dyn RecordingSink>>,
    octomap: u16,
    cloud: u16,
    cloud2: u16,
    sequence: u32,
}

/// [`RecordingFormat::create`](froctomap_formats::RecordingFormat::create) of MCAP.
pub(crate) fn create(sink: Box<dyn RecordingSink>) -> Result<Box<dyn RecordingWriter>, Cause> {
    Ok(Box::new(McapMapWriter::new(sink)?))
}

impl McapMapWriter {
    fn new(sink: Box<dyn RecordingSink>) -> Result<Self, McapWriteError> {
        let mut writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("froctomap ", env!("CARGO_PKG_VERSION")))
            .create(sink)?;
        let none = BTreeMap::new();
        let schema = writer.add_schema(OCTOMAP_TYPE, "ros2msg", OCTOMAP_ROS2MSG.as_bytes())?;
        let octomap = writer.add_channel(schema, OCTOMAP_TOPIC, "cdr", &none)?;
        let schema = writer.add_schema(
            POINT_CLOUD_SCHEMA,
            "jsonschema",
            POINT_CLOUD_JSON_SCHEMA.as_bytes(),
        )?;
        let cloud = writer.add_channel(schema, POINT_CLOUD_TOPIC, "json", &none)?;
        let schema = writer.add_schema(
            POINT_CLOUD2_TYPE,
            "ros2msg",
            POINT_CLOUD2_ROS2MSG.as_bytes(),
        )?;
        let cloud2 = writer.add_channel(schema, POINT_CLOUD2_TOPIC, "cdr", &none)?;
        Ok(Self {
            writer,
            octomap,
            cloud,
            cloud2,
            sequence: 0,
        })
    }

    fn write(&mut self, map: &ExportedMap<'_>) -> Result<(), McapWriteError> {
        let (log_time, stamp, message) = octomap_message(map.time, map.bt, Some(map.resolution))?;
        let cloud = point_cloud_json(map.time, FRAME_ID, map.kind, map.resolution, map.occupied)?;
        let cloud2 = point_cloud2(stamp, FRAME_ID, map.kind, map.resolution, map.occupied)?;
        for (channel_id, data) in [
            (self.octomap, &message),
            (self.cloud, &cloud),
            (self.cloud2, &cloud2),
        ] {
            let header = MessageHeader {
                channel_id,
                sequence: self.sequence,
                log_time,
                publish_time: log_time,
            };
            self.writer.write_to_known_channel(&header, data)?;
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
    bt: &[u8],
    resolution: Option<f64>,
) -> Result<OctomapMessage, McapWriteError> {
    let out_of_range = || McapWriteError::TimeOutOfRange(iso8601(time));
    let log_time = u64::try_from(time.0).map_err(|_| out_of_range())?;
    let stamp = ros2_stamp(time).ok_or_else(out_of_range)?;
    let header = parse_header(bt, FileKind::Binary).map_err(McapWriteError::NotBinary)?;
    let body = bt.get(header.body_offset..).unwrap_or_default();
    let resolution = resolution.unwrap_or(header.resolution);
    let message = encode_octomap_cdr(stamp, FRAME_ID, true, &header.tree_id, resolution, body)
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
        let (log_time, _, message) = octomap_message(time, bt, None)?;
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
