//! Writes exported maps into a ROS 1 bag (format 2.0), the [`ROSBAG`](crate::ROSBAG)
//! format's [`RecordingWriter`]: each map as an `octomap_msgs/Octomap` (`binary`) on
//! [`OCTOMAP_TOPIC`] (under the export's topic prefix), stamped and logged at the map's time,
//! what `rosbag play` publishes for ROS 1's `octomap_server` and rviz.
//!
//! The layout is the one `rosbag` writes (see [`bag`](crate::bag) for the records): the magic
//! line, the bag header (padded to 4,096 bytes, rewritten at the end with where the index
//! is), one uncompressed chunk per map holding its message record (the first chunk also the
//! connection record) followed by its index record, then the connection record and one
//! chunk-info record per chunk. No maintained Rust crate writes bags (the `rosbag` crate
//! reads them), and the format is short.

use crate::bag::{
    MAGIC, OP_BAG_HEADER, OP_CHUNK, OP_CHUNK_INFO, OP_CONNECTION, OP_INDEX, OP_MESSAGE,
};
use crate::encode::{
    encode_octomap_ros1, OCTOMAP_ROS1_DEFINITION, OCTOMAP_ROS1_MD5, OCTOMAP_ROS1_TYPE,
};
use crate::error::BagWriteError;
use crate::mcap_export::check_options;
use crate::topics::OCTOMAP_TOPIC;
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_formats::{
    ExportedMap, PluginError as Cause, RecordingProfile, RecordingSink, RecordingWriteOptions,
    RecordingWriter,
};
use froctomap_octomap_codec::{parse_header, FileKind};
use std::io::{Seek, SeekFrom, Write};

/// The bag header record's length: `rosbag` pads it so that it can be rewritten in place.
const BAG_HEADER_LEN: usize = 4096;

/// The one connection's id.
const CONNECTION: u32 = 0;

/// [`RecordingFormat::create`](froctomap_formats::RecordingFormat::create) of ROS 1 bags.
pub(crate) fn create(
    sink: Box<dyn RecordingSink>,
    options: &RecordingWriteOptions,
) -> Result<Box<dyn RecordingWriter>, Cause> {
    Ok(Box::new(BagMapWriter::new(sink, options)?))
}

/// A chunk written: where, and the time of its one message.
struct ChunkInfo {
    pos: u64,
    time: (u32, u32),
}

struct BagMapWriter {
    sink: Box<dyn RecordingSink>,
    topic: String,
    frame_id: String,
    /// Where the next record goes.
    pos: u64,
    chunks: Vec<ChunkInfo>,
}

impl BagMapWriter {
    fn new(
        sink: Box<dyn RecordingSink>,
        options: &RecordingWriteOptions,
    ) -> Result<Self, BagWriteError> {
        check_options(options, |option, value, reason| BagWriteError::BadOption {
            option,
            value,
            reason,
        })?;
        if options.profile != RecordingProfile::Ros2 {
            return Err(BagWriteError::BadOption {
                option: "profile",
                value: format!("{:?}", options.profile).to_lowercase(),
                reason: "a ROS 1 bag holds the maps as octomap_msgs/Octomap only \
                         (the profiles choose the messages of an MCAP export)",
            });
        }
        let mut writer = Self {
            sink,
            topic: format!("{}{OCTOMAP_TOPIC}", options.topic_prefix),
            frame_id: options.frame_id.clone(),
            pos: 0,
            chunks: Vec::new(),
        };
        writer.put(MAGIC)?;
        // Rewritten by `finish` with where the index is.
        writer.put(&bag_header(0, 0, 0))?;
        Ok(writer)
    }

    fn put(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.sink.write_all(bytes)?;
        self.pos += bytes.len() as u64;
        Ok(())
    }

    /// The connection record: the topic, and its type as subscribers check it.
    fn connection(&self) -> Vec<u8> {
        let data = fields(&[
            ("topic", self.topic.as_bytes()),
            ("type", OCTOMAP_ROS1_TYPE.as_bytes()),
            ("md5sum", OCTOMAP_ROS1_MD5.as_bytes()),
            ("message_definition", OCTOMAP_ROS1_DEFINITION.as_bytes()),
        ]);
        record(
            &[
                ("op", &[OP_CONNECTION]),
                ("conn", &CONNECTION.to_le_bytes()),
                ("topic", self.topic.as_bytes()),
            ],
            &data,
        )
    }

    /// One map: its chunk (the connection first in the first one), then the chunk's index.
    fn write(&mut self, map: &ExportedMap<'_>) -> Result<(), BagWriteError> {
        let time = ros1_time(map.time)?;
        let header = parse_header(map.bt, FileKind::Binary).map_err(BagWriteError::NotBinary)?;
        let body = map.bt.get(header.body_offset..).unwrap_or_default();
        let too_long = || BagWriteError::MessageTooLong {
            bytes: body.len() as u64,
        };
        let sequence = u32::try_from(self.chunks.len()).map_err(|_| too_long())?;
        let message = encode_octomap_ros1(
            sequence,
            time,
            &self.frame_id,
            true,
            &header.tree_id,
            map.resolution,
            body,
        )
        .ok_or_else(too_long)?;
        let mut chunk = if self.chunks.is_empty() {
            self.connection()
        } else {
            Vec::new()
        };
        let offset = u32::try_from(chunk.len()).map_err(|_| too_long())?;
        chunk.extend(record(
            &[
                ("op", &[OP_MESSAGE]),
                ("conn", &CONNECTION.to_le_bytes()),
                ("time", &time_bytes(time)),
            ],
            &message,
        ));
        let size = u32::try_from(chunk.len()).map_err(|_| too_long())?;
        let chunk_record = record(
            &[
                ("op", &[OP_CHUNK]),
                ("compression", b"none"),
                ("size", &size.to_le_bytes()),
            ],
            &chunk,
        );
        let mut index = time_bytes(time).to_vec();
        index.extend(offset.to_le_bytes());
        let index_record = record(
            &[
                ("op", &[OP_INDEX]),
                ("ver", &1u32.to_le_bytes()),
                ("conn", &CONNECTION.to_le_bytes()),
                ("count", &1u32.to_le_bytes()),
            ],
            &index,
        );
        let pos = self.pos;
        self.put(&chunk_record)?;
        self.put(&index_record)?;
        self.chunks.push(ChunkInfo { pos, time });
        Ok(())
    }

    /// The connection and chunk-info records, then the bag header pointing to them.
    fn close(&mut self) -> Result<(), BagWriteError> {
        let index_pos = self.pos;
        let connections = u32::from(!self.chunks.is_empty());
        if connections > 0 {
            let connection = self.connection();
            self.put(&connection)?;
        }
        let infos: Vec<Vec<u8>> = self
            .chunks
            .iter()
            .map(|chunk| {
                let mut data = CONNECTION.to_le_bytes().to_vec();
                data.extend(1u32.to_le_bytes());
                record(
                    &[
                        ("op", &[OP_CHUNK_INFO]),
                        ("ver", &1u32.to_le_bytes()),
                        ("chunk_pos", &chunk.pos.to_le_bytes()),
                        ("start_time", &time_bytes(chunk.time)),
                        ("end_time", &time_bytes(chunk.time)),
                        ("count", &1u32.to_le_bytes()),
                    ],
                    &data,
                )
            })
            .collect();
        for info in &infos {
            self.put(info)?;
        }
        let chunk_count =
            u32::try_from(self.chunks.len()).map_err(|_| BagWriteError::MessageTooLong {
                bytes: self.chunks.len() as u64,
            })?;
        self.sink.seek(SeekFrom::Start(MAGIC.len() as u64))?;
        self.sink
            .write_all(&bag_header(index_pos, connections, chunk_count))?;
        self.sink.seek(SeekFrom::Start(self.pos))?;
        self.sink.flush()?;
        Ok(())
    }
}

impl RecordingWriter for BagMapWriter {
    fn write_map(&mut self, map: &ExportedMap<'_>) -> Result<(), Cause> {
        Ok(self.write(map)?)
    }

    fn finish(mut self: Box<Self>) -> Result<(), Cause> {
        Ok(self.close()?)
    }
}

/// A time as ROS 1 has it: `u32` seconds and nanoseconds since 1970.
fn ros1_time(time: Timestamp) -> Result<(u32, u32), BagWriteError> {
    let seconds = u32::try_from(time.0.div_euclid(1_000_000_000))
        .map_err(|_| BagWriteError::TimeOutOfRange(iso8601(time)))?;
    Ok((seconds, time.0.rem_euclid(1_000_000_000) as u32)) // < 1e9.
}

/// A time field: seconds, then nanoseconds.
fn time_bytes((seconds, nanoseconds): (u32, u32)) -> [u8; 8] {
    let mut bytes = [0; 8];
    bytes[..4].copy_from_slice(&seconds.to_le_bytes());
    bytes[4..].copy_from_slice(&nanoseconds.to_le_bytes());
    bytes
}

/// Header fields: each `name=value` after its `u32` length. Names and values are short
/// (the message definition is the longest), so the lengths fit.
fn fields(fields: &[(&str, &[u8])]) -> Vec<u8> {
    let mut out = Vec::new();
    for (name, value) in fields {
        let len = (name.len() + 1 + value.len()) as u32;
        out.extend(len.to_le_bytes());
        out.extend(name.as_bytes());
        out.push(b'=');
        out.extend(*value);
    }
    out
}

/// A record: its header fields after their `u32` length, then its data after its own.
/// The caller checked that `data` fits a `u32` length.
fn record(header: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
    let header = fields(header);
    let mut out = Vec::with_capacity(8 + header.len() + data.len());
    out.extend((header.len() as u32).to_le_bytes());
    out.extend(header);
    out.extend((data.len() as u32).to_le_bytes());
    out.extend(data);
    out
}

/// The bag header record, padded with spaces to [`BAG_HEADER_LEN`] bytes.
fn bag_header(index_pos: u64, connections: u32, chunks: u32) -> Vec<u8> {
    let header = fields(&[
        ("op", &[OP_BAG_HEADER]),
        ("index_pos", &index_pos.to_le_bytes()),
        ("conn_count", &connections.to_le_bytes()),
        ("chunk_count", &chunks.to_le_bytes()),
    ]);
    let padding = vec![b' '; BAG_HEADER_LEN - 8 - header.len()];
    let mut out = Vec::with_capacity(BAG_HEADER_LEN);
    out.extend((header.len() as u32).to_le_bytes());
    out.extend(header);
    out.extend((padding.len() as u32).to_le_bytes());
    out.extend(padding);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bag header keeps its length whatever it says, so it is rewritten in place.
    #[test]
    fn the_bag_header_is_always_4096_bytes() {
        assert_eq!(bag_header(0, 0, 0).len(), BAG_HEADER_LEN);
        assert_eq!(
            bag_header(u64::MAX, u32::MAX, u32::MAX).len(),
            BAG_HEADER_LEN
        );
    }

    #[test]
    fn times_outside_ros1_are_refused() {
        assert!(ros1_time(Timestamp(-1)).is_err());
        assert_eq!(
            ros1_time(Timestamp(1_500_000_000_250)).ok(),
            Some((1_500, 250))
        );
    }
}
