//! Writes exported maps into a ROS 2 bag directory with MCAP storage, the
//! [`ROS2_BAG`](crate::ROS2_BAG) format's directory writer: `NAME/NAME_0.mcap`, written by the
//! MCAP export's writer (the same messages on the same topics, with the same options), and
//! `NAME/metadata.yaml` as rosbag2 writes it for MCAP storage (version 8): the storage, its
//! one file, every topic with its type, `cdr` and its message count, the first message's
//! time and the span to the last, no compression. `ros2 bag info`/`play` and rosbags'
//! `rosbag2.Reader` open the directory; rosbag2 reads only CDR, so the
//! [`RecordingProfile::Foxglove`] profile (JSON messages) is refused.

use crate::error::McapWriteError;
use crate::mcap_export::McapMapWriter;
use froctomap_formats::{
    ExportedMap, PluginError as Cause, RecordingDir, RecordingProfile, RecordingWriteOptions,
    RecordingWriter,
};
use std::fmt::Write as _;
use std::io::Write;

/// The `metadata.yaml` version written: rosbag2's of ROS 2 Iron (Jazzy reads it), with the
/// QoS profiles as a YAML string (empty: the publisher's are not known).
const METADATA_VERSION: u32 = 8;

/// [`RecordingFormat::create_dir`](froctomap_formats::RecordingFormat::create_dir) of ROS 2
/// bags.
pub(crate) fn create(
    mut dir: Box<dyn RecordingDir>,
    options: &RecordingWriteOptions,
) -> Result<Box<dyn RecordingWriter>, Cause> {
    if options.profile != RecordingProfile::Ros2 {
        return Err(McapWriteError::BadOption {
            option: "profile",
            value: options.profile.to_string(),
            reason: "a ROS 2 bag holds CDR messages only (rosbag2 reads no other \
                     serialisation); export the foxglove profile to a .mcap file",
        }
        .into());
    }
    let file = format!("{}_0.mcap", dir.name());
    let sink = dir.create_file(&file)?;
    let mcap = McapMapWriter::new(sink, options)?;
    Ok(Box::new(Ros2BagWriter {
        mcap,
        dir,
        file,
        maps: 0,
        span: None,
    }))
}

struct Ros2BagWriter {
    mcap: McapMapWriter,
    dir: Box<dyn RecordingDir>,
    /// The storage file's name.
    file: String,
    /// Maps written (one message on each topic per map).
    maps: u64,
    /// The first and last log times written, nanoseconds since 1970.
    span: Option<(u64, u64)>,
}

impl RecordingWriter for Ros2BagWriter {
    fn write_map(&mut self, map: &ExportedMap<'_>) -> Result<(), Cause> {
        self.mcap.write(map)?;
        // Written: its time is a valid log time.
        let time = u64::try_from(map.time.0).unwrap_or_default();
        self.span = Some(match self.span {
            Some((first, last)) => (first.min(time), last.max(time)),
            None => (time, time),
        });
        self.maps += 1;
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<(), Cause> {
        let Ros2BagWriter {
            mcap,
            mut dir,
            file,
            maps,
            span,
        } = *self;
        let topics = mcap.topics();
        Box::new(mcap).finish()?;
        let text = metadata_yaml(&file, maps, span, &topics);
        let mut out = dir.create_file("metadata.yaml")?;
        out.write_all(text.as_bytes())
            .and_then(|()| out.flush())
            .map_err(McapWriteError::from)?;
        Ok(())
    }
}

/// `metadata.yaml` of a bag whose one storage `file` holds `maps` messages on each of
/// `topics` (name, type, encoding), logged over `span`.
fn metadata_yaml(
    file: &str,
    maps: u64,
    span: Option<(u64, u64)>,
    topics: &[(String, &str, &str)],
) -> String {
    let (start, duration) = span.map_or((0, 0), |(first, last)| (first, last - first));
    let messages = maps * topics.len() as u64;
    let file = quoted(file);
    let mut out = String::new();
    // Writing into a String cannot fail.
    let _ = write!(
        out,
        "rosbag2_bagfile_information:\n  version: {METADATA_VERSION}\n  \
         storage_identifier: mcap\n  duration:\n    nanoseconds: {duration}\n  \
         starting_time:\n    nanoseconds_since_epoch: {start}\n  \
         message_count: {messages}\n  topics_with_message_count:\n"
    );
    for (name, type_name, encoding) in topics {
        let _ = write!(
            out,
            "    - topic_metadata:\n        name: {}\n        type: {}\n        \
             serialization_format: {}\n        offered_qos_profiles: \"\"\n        \
             type_description_hash: \"\"\n      message_count: {maps}\n",
            quoted(name),
            quoted(type_name),
            quoted(encoding)
        );
    }
    let _ = write!(
        out,
        "  compression_format: \"\"\n  compression_mode: \"\"\n  \
         relative_file_paths:\n    - {file}\n  files:\n    - path: {file}\n      \
         starting_time:\n        nanoseconds_since_epoch: {start}\n      duration:\n        \
         nanoseconds: {duration}\n      message_count: {messages}\n  custom_data: {{}}\n  \
         ros_distro: \"\"\n"
    );
    out
}

/// `text` as a YAML double-quoted scalar (a bag's name may hold any character).
fn quoted(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 2);
    out.push('"');
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => {
                let _ = write!(out, "\\u{:04x}", u32::from(c));
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bag_metadata::BagMetadata;

    /// What our own reader takes from the metadata (rosbags reads it in
    /// tests/recordings.rs).
    #[test]
    fn the_metadata_names_the_storage_and_its_file() {
        let topics = [(
            "/octomap_binary".to_string(),
            "octomap_msgs/msg/Octomap",
            "cdr",
        )];
        let text = metadata_yaml("odd \"bag\\\" \t_0.mcap", 2, Some((5, 9)), &topics);
        let metadata = BagMetadata::parse(&text).unwrap();
        assert_eq!(metadata.storage, "mcap");
        assert_eq!(metadata.files, ["odd \"bag\\\" \t_0.mcap"]);
        assert!(metadata.compression_mode.is_empty());
        assert!(text.contains("nanoseconds: 4\n"));
        assert!(text.contains("message_count: 2\n"));
    }
}
