//! Why a recording or one of its messages could not be read. Every variant names the file.

use std::path::PathBuf;

/// Why a recording could not be read. Messages name the recording (and the topic or message
/// where one is concerned).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RosError {
    /// The file could not be opened or read.
    #[error("{}: cannot read", path.display())]
    Io {
        /// The recording.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The file ends inside a record.
    #[error("{}: truncated: {what} ends past the end of the file", path.display())]
    Truncated {
        /// The recording.
        path: PathBuf,
        /// The record that is cut off.
        what: &'static str,
    },
    /// A record does not follow the format.
    #[error("{}: malformed {what}: {problem}", path.display())]
    Malformed {
        /// The recording.
        path: PathBuf,
        /// The record concerned.
        what: &'static str,
        /// What is wrong.
        problem: String,
    },
    /// A length field asks for more than the limits allow (hostile or damaged input).
    #[error("{}: {what} of {bytes} bytes is more than the limit of {limit} bytes", path.display())]
    TooLarge {
        /// The recording.
        path: PathBuf,
        /// What the length is of.
        what: &'static str,
        /// The length found.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// A chunk compressed in a way this reader does not know.
    #[error("{}: chunk compression `{name}` is not supported ({supported} are)", path.display())]
    UnsupportedCompression {
        /// The recording.
        path: PathBuf,
        /// The compression named in the chunk.
        name: String,
        /// The compressions this kind of recording may use that are read.
        supported: &'static str,
    },
    /// The MCAP library refused the file.
    #[error("{}", path.display())]
    Mcap {
        /// The recording.
        path: PathBuf,
        /// The cause.
        #[source]
        source: mcap::McapError,
    },
    /// An MCAP file without a summary section: its chunks cannot be found without reading all.
    #[error("{}: MCAP file without a summary (chunk index); re-index it with `mcap recover`", path.display())]
    NoSummary {
        /// The recording.
        path: PathBuf,
    },
    /// A ROS 2 bag directory without storage files (`.mcap`, `.db3`, `.db3.zstd`).
    #[error("{}: ROS 2 bag without storage files (.mcap, .db3)", path.display())]
    NoStorageInBag {
        /// The bag directory.
        path: PathBuf,
    },
    /// A ROS 2 bag compressed in a way this reader does not read (its `metadata.yaml`'s
    /// `compression_mode` and `compression_format`).
    #[error("{}: compression mode `{mode}` with format `{format}` is not read (sqlite3 storage: none, message or file with zstd; MCAP storage: none — `ros2 bag convert` rewrites it)", path.display())]
    UnsupportedBagCompression {
        /// The bag directory (or its storage file).
        path: PathBuf,
        /// `compression_mode`.
        mode: String,
        /// `compression_format`.
        format: String,
    },
    /// SQLite refused a database of a ROS 2 bag (it is not a database, is damaged or cut).
    #[error("{}: SQLite", path.display())]
    Sqlite {
        /// The storage file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: rusqlite::Error,
    },
    /// No topic of an octomap message type.
    #[error("{}: no topic of type octomap_msgs/Octomap; topics: {}", path.display(), list_topics(topics))]
    NoOctomapTopic {
        /// The recording.
        path: PathBuf,
        /// Every topic and its type.
        topics: Vec<(String, String)>,
    },
    /// Several topics of an octomap message type and no `--topic`.
    #[error("{}: several octomap topics ({}); choose one with --topic", path.display(), list_topics(topics))]
    SeveralOctomapTopics {
        /// The recording.
        path: PathBuf,
        /// The octomap topics and their types.
        topics: Vec<(String, String)>,
    },
    /// The topic asked for is not in the recording.
    #[error("{}: no topic `{topic}`; topics: {}", path.display(), list_topics(topics))]
    NoSuchTopic {
        /// The recording.
        path: PathBuf,
        /// The topic asked for.
        topic: String,
        /// Every topic and its type.
        topics: Vec<(String, String)>,
    },
    /// The topic asked for carries another message type.
    #[error("{}: topic `{topic}` has type {found}, not octomap_msgs/Octomap", path.display())]
    NotOctomapTopic {
        /// The recording.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Its type.
        found: String,
    },
    /// The topic's messages are in an encoding this reader does not decode.
    #[error("{}: topic `{topic}` is encoded as `{encoding}` (ros1 and cdr are read)", path.display())]
    UnsupportedEncoding {
        /// The recording.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Its message encoding.
        encoding: String,
    },
    /// Several messages of the topic carry the same time.
    #[error("{}: {count} messages on `{topic}` have the same time {time} (a republished map? `--time-source log` takes the recording times)", path.display())]
    DuplicateTimes {
        /// The recording.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// The time (ISO 8601).
        time: String,
        /// How many messages have it.
        count: usize,
    },
    /// A chunk that does not read (it does not decompress, its checksum fails, its records
    /// are cut…): the problem (which names the recording), then which chunk and, where its
    /// index or records tell, the topic and the log times of its messages. The problem is
    /// this error's own detail, shown whole (with its causes) in its message, not a separate
    /// cause: the message starts with the recording the problem names.
    #[error("{} (chunk at byte {offset}{}{})", froctomap_core::error_message(&**problem), topic.as_ref().map(|t| format!(", messages on `{t}`")).unwrap_or_default(), times.as_ref().map(|t| format!(" logged {t}")).unwrap_or_default())]
    DamagedChunk {
        /// Where the chunk starts in its file.
        offset: u64,
        /// The topic read from the recording, when the chunk holds its messages.
        topic: Option<String>,
        /// The log times of the chunk's messages (`from A to B`, ISO 8601), when known.
        times: Option<String>,
        /// What is wrong with the chunk.
        problem: Box<RosError>,
    },
    /// An MCAP stream (standard input) that does not read: it ends inside a record or
    /// before its end magic (its writer stopped), or holds a record that is not MCAP.
    #[error(
        "MCAP stream on standard input: does not read after {messages} message(s), at byte {bytes}"
    )]
    Stream {
        /// The bytes read from the stream when it stopped.
        bytes: u64,
        /// The messages read whole before it stopped.
        messages: u64,
        /// What the MCAP reader found.
        #[source]
        source: mcap::McapError,
    },
    /// A message that does not decode as `octomap_msgs/Octomap`.
    #[error("{}: message on `{topic}` at {time}", path.display())]
    BadMessage {
        /// The recording.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// The message's log time (ISO 8601).
        time: String,
        /// What is wrong (boxed: the codec's errors are large).
        #[source]
        problem: Box<MessageError>,
    },
}

/// Why a message's bytes are not an `octomap_msgs/Octomap`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MessageError {
    /// The bytes end inside a field.
    #[error("the message ends inside its `{field}` field")]
    Truncated {
        /// The field.
        field: &'static str,
    },
    /// A CDR encapsulation this reader does not decode.
    #[error("CDR encapsulation {0:#06x} is not plain CDR (0x0000 big or 0x0001 little endian)")]
    Encapsulation(u16),
    /// A string that is not UTF-8 or lacks its terminating NUL.
    #[error("field `{field}` is not a valid string")]
    BadString {
        /// The field.
        field: &'static str,
    },
    /// The resolution is not a positive number.
    #[error("resolution {0} is not a positive number")]
    Resolution(String),
    /// The map data is not an OctoMap tree.
    #[error("the map data is not an OctoMap tree")]
    NotAMap(#[source] froctomap_octomap_codec::CodecError),
}

/// A span of log times (nanoseconds) for messages: `at A` or `from A to B`.
pub(crate) fn span((first, last): (i64, i64)) -> String {
    use froctomap_core::calendar::iso8601;
    use froctomap_core::Timestamp;
    if first == last {
        format!("at {}", iso8601(Timestamp(first)))
    } else {
        format!(
            "from {} to {}",
            iso8601(Timestamp(first)),
            iso8601(Timestamp(last))
        )
    }
}

fn list_topics(topics: &[(String, String)]) -> String {
    if topics.is_empty() {
        return "none".to_string();
    }
    topics
        .iter()
        .map(|(topic, kind)| format!("{topic} [{kind}]"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Why a map could not be written into a ROS 1 bag.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BagWriteError {
    /// Writing the output failed.
    #[error("cannot write")]
    Io(#[from] std::io::Error),
    /// A time before 1970 or after 2106, which a ROS 1 time (`u32` seconds) cannot hold.
    #[error("{0} cannot be written as a ROS 1 time (1970 to 2106)")]
    TimeOutOfRange(String),
    /// The exported map is not a `.bt` file (a fault of the exporter).
    #[error("the exported map is not a .bt file")]
    NotBinary(#[source] froctomap_octomap_codec::CodecError),
    /// A map too large for one record (a bag's lengths are `u32`).
    #[error("a map of {bytes} bytes is longer than one bag record may hold")]
    MessageTooLong {
        /// The map's bytes.
        bytes: u64,
    },
    /// An export option the bag cannot be written with.
    #[error("{option} {value:?}: {reason}")]
    BadOption {
        /// The option (`profile`, `frame id`, `topic prefix`, `threshold`).
        option: &'static str,
        /// Its value.
        value: String,
        /// What is wrong with it.
        reason: &'static str,
    },
}

/// Why a map could not be written into an MCAP recording.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum McapWriteError {
    /// The MCAP library failed (writing the file, most often).
    #[error(transparent)]
    Mcap(#[from] mcap::McapError),
    /// Flushing the output failed.
    #[error("cannot write")]
    Io(#[from] std::io::Error),
    /// A time that a ROS 2 stamp (`int32` seconds) or an MCAP log time (unsigned
    /// nanoseconds since 1970) cannot hold.
    #[error("{0} cannot be written as a ROS 2 stamp (1970 to 2038)")]
    TimeOutOfRange(String),
    /// The exported map is not a `.bt` file (a fault of the exporter).
    #[error("the exported map is not a .bt file")]
    NotBinary(#[source] froctomap_octomap_codec::CodecError),
    /// A map too large for one message (CDR lengths are `u32`).
    #[error("a map of {bytes} bytes is longer than one ROS 2 message may hold")]
    MessageTooLong {
        /// The map's bytes.
        bytes: u64,
    },
    /// An export option the recording cannot be written with.
    #[error("{option} {value:?}: {reason}")]
    BadOption {
        /// The option (`frame id`, `topic prefix`, `threshold`).
        option: &'static str,
        /// Its value.
        value: String,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A map with more occupied voxels than one point cloud may hold.
    #[error("{voxels} occupied voxels, more than the {limit} one point-cloud message may hold")]
    TooManyPoints {
        /// Occupied voxels of the map.
        voxels: u64,
        /// The limit.
        limit: u64,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::said_twice;
    use froctomap_octomap_codec::CodecError;

    fn path() -> PathBuf {
        PathBuf::from("a.bag")
    }
    fn mcap_error() -> mcap::McapError {
        mcap::McapError::UnexpectedEof
    }
    fn topics() -> Vec<(String, String)> {
        vec![("/map".into(), "octomap_msgs/Octomap".into())]
    }

    fn message_errors() -> Vec<MessageError> {
        let all = vec![
            MessageError::Truncated { field: "data" },
            MessageError::Encapsulation(7),
            MessageError::BadString { field: "id" },
            MessageError::Resolution("-1".into()),
            MessageError::NotAMap(CodecError::Empty),
        ];
        for e in &all {
            // Fails to compile when a variant is added and not listed above.
            match e {
                MessageError::Truncated { .. }
                | MessageError::Encapsulation(_)
                | MessageError::BadString { .. }
                | MessageError::Resolution(_)
                | MessageError::NotAMap(_) => {}
            }
        }
        all
    }

    fn write_errors() -> Vec<McapWriteError> {
        let all = vec![
            McapWriteError::Mcap(mcap_error()),
            McapWriteError::Io(std::io::Error::other("disk full")),
            McapWriteError::TimeOutOfRange("2100-01-01".into()),
            McapWriteError::NotBinary(CodecError::Empty),
            McapWriteError::MessageTooLong { bytes: 9 },
            McapWriteError::BadOption {
                option: "frame id",
                value: "".into(),
                reason: "is empty",
            },
            McapWriteError::TooManyPoints {
                voxels: 9,
                limit: 8,
            },
        ];
        for e in &all {
            match e {
                McapWriteError::Mcap(_)
                | McapWriteError::Io(_)
                | McapWriteError::TimeOutOfRange(_)
                | McapWriteError::NotBinary(_)
                | McapWriteError::MessageTooLong { .. }
                | McapWriteError::BadOption { .. }
                | McapWriteError::TooManyPoints { .. } => {}
            }
        }
        all
    }

    fn bag_write_errors() -> Vec<BagWriteError> {
        let all = vec![
            BagWriteError::Io(std::io::Error::other("disk full")),
            BagWriteError::TimeOutOfRange("2200-01-01".into()),
            BagWriteError::NotBinary(CodecError::Empty),
            BagWriteError::MessageTooLong { bytes: 9 },
            BagWriteError::BadOption {
                option: "profile",
                value: "foxglove".into(),
                reason: "a ROS 1 bag holds ROS 1 messages only",
            },
        ];
        for e in &all {
            match e {
                BagWriteError::Io(_)
                | BagWriteError::TimeOutOfRange(_)
                | BagWriteError::NotBinary(_)
                | BagWriteError::MessageTooLong { .. }
                | BagWriteError::BadOption { .. } => {}
            }
        }
        all
    }

    fn ros_errors() -> Vec<RosError> {
        let mut all = vec![
            RosError::Io {
                path: path(),
                source: std::io::Error::other("disk full"),
            },
            RosError::Truncated {
                path: path(),
                what: "a chunk",
            },
            RosError::Malformed {
                path: path(),
                what: "header",
                problem: "no op field".into(),
            },
            RosError::TooLarge {
                path: path(),
                what: "a chunk",
                bytes: 9,
                limit: 8,
            },
            RosError::UnsupportedCompression {
                path: path(),
                name: "lz5".into(),
                supported: "none, bz2, lz4",
            },
            RosError::Mcap {
                path: path(),
                source: mcap_error(),
            },
            RosError::NoSummary { path: path() },
            RosError::NoStorageInBag { path: path() },
            RosError::UnsupportedBagCompression {
                path: path(),
                mode: "file".into(),
                format: "lz4".into(),
            },
            RosError::Sqlite {
                path: path(),
                source: rusqlite::Error::InvalidQuery,
            },
            RosError::NoOctomapTopic {
                path: path(),
                topics: topics(),
            },
            RosError::SeveralOctomapTopics {
                path: path(),
                topics: topics(),
            },
            RosError::NoSuchTopic {
                path: path(),
                topic: "/x".into(),
                topics: topics(),
            },
            RosError::NotOctomapTopic {
                path: path(),
                topic: "/x".into(),
                found: "std_msgs/String".into(),
            },
            RosError::UnsupportedEncoding {
                path: path(),
                topic: "/x".into(),
                encoding: "json".into(),
            },
            RosError::DuplicateTimes {
                path: path(),
                topic: "/x".into(),
                time: "2024-01-01T00:00:00Z".into(),
                count: 2,
            },
            RosError::Stream {
                bytes: 9,
                messages: 1,
                source: mcap_error(),
            },
        ];
        let chunk = RosError::DamagedChunk {
            offset: 9,
            topic: Some("/x".into()),
            times: Some("at 2024-01-01T00:00:00Z".into()),
            problem: Box::new(RosError::Mcap {
                path: path(),
                source: mcap_error(),
            }),
        };
        all.push(chunk);
        all.extend(message_errors().into_iter().map(|e| RosError::BadMessage {
            path: path(),
            topic: "/x".into(),
            time: "2024-01-01T00:00:00Z".into(),
            problem: Box::new(e),
        }));
        for e in &all {
            match e {
                RosError::Io { .. }
                | RosError::Truncated { .. }
                | RosError::Malformed { .. }
                | RosError::TooLarge { .. }
                | RosError::UnsupportedCompression { .. }
                | RosError::Mcap { .. }
                | RosError::NoSummary { .. }
                | RosError::NoStorageInBag { .. }
                | RosError::UnsupportedBagCompression { .. }
                | RosError::Sqlite { .. }
                | RosError::NoOctomapTopic { .. }
                | RosError::SeveralOctomapTopics { .. }
                | RosError::NoSuchTopic { .. }
                | RosError::NotOctomapTopic { .. }
                | RosError::UnsupportedEncoding { .. }
                | RosError::DuplicateTimes { .. }
                | RosError::DamagedChunk { .. }
                | RosError::Stream { .. }
                | RosError::BadMessage { .. } => {}
            }
        }
        all
    }

    /// Every variant of this crate's errors, as its chain prints: no text repeats another
    /// and none is empty.
    #[test]
    fn every_error_is_said_once() {
        for e in ros_errors() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        for e in message_errors() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        for e in write_errors() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        for e in bag_write_errors() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
    }

    /// A damaged chunk still reads as before: the recording and its problem, then where.
    #[test]
    fn a_damaged_chunk_names_the_recording_first() {
        let chunk = RosError::DamagedChunk {
            offset: 9,
            topic: None,
            times: None,
            problem: Box::new(RosError::Io {
                path: path(),
                source: std::io::Error::other("disk full"),
            }),
        };
        assert_eq!(
            froctomap_core::error_message(&chunk),
            "a.bag: cannot read: disk full (chunk at byte 9)"
        );
    }
}
