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
use crate::foxglove::{point_cloud, point_cloud2, POINT_CLOUD_JSON_SCHEMA, POINT_CLOUD_SCHEMA};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_formats::{ExportedMap, PluginError as Cause, RecordingSink, RecordingWriter};
use froctomap_octomap_codec::{parse_header, FileKind};
use mcap::records::MessageHeader;
use std::collections::BTreeMap;
use std::io::Write;

/// The topic of the exported maps (as `octomap_server` names its binary map topic).
pub const OCTOMAP_TOPIC: &str = "/octomap_binary";
/// The topic of the exported maps' occupied voxels.
pub const POINT_CLOUD_TOPIC: &str = "/froctomap/occupied_voxels";
/// The topic of the exported maps' occupied voxels as `sensor_msgs/msg/PointCloud2`.
pub const POINT_CLOUD2_TOPIC: &str = "/froctomap/occupied_voxels_pc2";
/// The frame every message is in.
pub const FRAME_ID: &str = "map";

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
        let out_of_range = || McapWriteError::TimeOutOfRange(iso8601(map.time));
        let log_time = u64::try_from(map.time.0).map_err(|_| out_of_range())?;
        let stamp = ros2_stamp(map.time).ok_or_else(out_of_range)?;
        let header = parse_header(map.bt, FileKind::Binary).map_err(McapWriteError::NotBinary)?;
        let body = map.bt.get(header.body_offset..).unwrap_or_default();
        let message =
            encode_octomap_cdr(stamp, FRAME_ID, true, &header.tree_id, map.resolution, body)
                .ok_or(McapWriteError::MessageTooLong {
                    bytes: body.len() as u64,
                })?;
        let cloud = point_cloud(map.time, FRAME_ID, map.kind, map.resolution, map.occupied)?;
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

/// A time as a ROS 2 stamp (`int32` seconds, nanoseconds), if it fits.
fn ros2_stamp(time: Timestamp) -> Option<(i32, u32)> {
    let seconds = i32::try_from(time.0.div_euclid(1_000_000_000)).ok()?;
    Some((seconds, time.0.rem_euclid(1_000_000_000) as u32))
}
