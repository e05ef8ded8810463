//! An MCAP stream that cannot seek (standard input, `-` among the inputs), read message by
//! message with the `mcap` crate's sans-io [`MessageReader`] as the bytes arrive.
//!
//! A series' time axis is made from every time before any map is read, so a stream is read
//! to its end first. Memory must not hold its maps: the data of each map message is
//! appended to a spool file in a locked temporary directory
//! ([`RecordingOptions::spool_dir`], else the system's temporary directory;
//! `froctomap_core::temporary_dir_in`), and the recording keeps, per map, only where its
//! bytes are (about 40 bytes). From there the stream is a recording like a file: each map's
//! bytes are read back and decoded when extraction asks for them, and the spool is removed
//! with the recording (or, after a `kill -9`, by the next reader of streams there).
//!
//! A stream that ends inside a record, lacks its end magic (its writer died) or holds a
//! record that does not read is refused with [`RosError::Stream`], naming how many bytes
//! and messages were read: unlike a cut file, there is no one to re-run the recording, and
//! a build of part of it would look complete.

use crate::error::RosError;
use crate::message::{decode_message, decode_stamp, Encoding, MessageType};
use crate::source::{select_topic, times, Damage, TopicEntry};
use froctomap_core::calendar::iso8601;
use froctomap_core::{temporary_dir_in, Timestamp};
use froctomap_formats::{PluginError as Cause, RecordedMaps, RecordingOptions};
use froctomap_formats::{RecordedTime, Recording};
use mcap::sans_io::{LinearReaderOptions, MessageReadEvent, MessageReader};
use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::os::unix::fs::FileExt;
use std::path::PathBuf;
use std::sync::Arc;

/// How the stream is named in messages (what the user typed).
pub const STREAM_PATH: &str = "-";

/// The prefix of spool directories.
const SPOOL_PREFIX: &str = ".froct-stream-";

/// Bytes asked of the stream at a time (the reader asks for a whole record at once).
const READ_STEP: usize = 1 << 20;

/// One spooled map message.
#[derive(Clone, Copy, Debug)]
struct Spooled {
    /// Index into the topics seen.
    topic: usize,
    encoding: Encoding,
    log_ns: i64,
    /// Header stamp (`None`: not read).
    stamp: Option<i64>,
    offset: u64,
    len: u64,
}

/// The maps of one topic of a stream, in its spool.
#[derive(Debug)]
struct StreamMaps {
    path: PathBuf,
    topic: String,
    kind: MessageType,
    spool: File,
    maps: Vec<Spooled>,
    /// Removed (with the spool) when the recording is dropped.
    _dir: froctomap_core::TemporaryDir,
}

impl StreamMaps {
    fn fetch(&self, index: usize, limit: u64) -> Result<Vec<u8>, RosError> {
        let Some(map) = self.maps.get(index) else {
            return Err(RosError::Malformed {
                path: self.path.clone(),
                what: "stream",
                problem: format!("no map {index}"),
            });
        };
        if map.len > limit {
            return Err(RosError::TooLarge {
                path: self.path.clone(),
                what: "map message",
                bytes: map.len,
                limit,
            });
        }
        // Within `limit`, which the reader's record limit bounded too.
        let mut data = vec![0u8; usize::try_from(map.len).unwrap_or(usize::MAX)];
        self.spool
            .read_exact_at(&mut data, map.offset)
            .map_err(|source| RosError::Io {
                path: self.path.clone(),
                source,
            })?;
        decode_message(&data, map.encoding, self.kind)
            .and_then(|m| m.map_file())
            .map_err(|problem| RosError::BadMessage {
                path: self.path.clone(),
                topic: self.topic.clone(),
                time: iso8601(Timestamp(map.log_ns)),
                problem: Box::new(problem),
            })
    }
}

impl RecordedMaps for StreamMaps {
    fn map_bytes(&self, index: usize, limit: u64) -> Result<Vec<u8>, Cause> {
        Ok(self.fetch(index, limit)?)
    }

    fn topic(&self) -> &str {
        &self.topic
    }
}

/// What reading the stream has counted so far, for errors.
struct Position {
    bytes: u64,
    messages: u64,
}

/// Reads an MCAP stream to its end, spooling the messages of map topics (or of
/// `options.topic`), then picks the topic as for a file.
pub(crate) fn open_mcap_stream(
    input: &mut dyn Read,
    options: &RecordingOptions,
    limit: u64,
) -> Result<Recording, RosError> {
    let path = PathBuf::from(STREAM_PATH);
    let parent = options.spool_dir.clone().unwrap_or_else(std::env::temp_dir);
    let spool_error = |source| RosError::Io {
        path: parent.clone(),
        source,
    };
    let dir = temporary_dir_in(&parent, SPOOL_PREFIX.as_ref()).map_err(spool_error)?;
    let spool_path = dir.path().join("maps");
    let spool = File::options()
        .read(true)
        .write(true)
        .create_new(true)
        .open(&spool_path)
        .map_err(spool_error)?;
    let mut out = BufWriter::new(&spool);
    let mut topics: Vec<TopicEntry> = Vec::new();
    let mut by_channel: std::collections::HashMap<u16, usize> = std::collections::HashMap::new();
    let mut spooled: Vec<Spooled> = Vec::new();
    let mut skipped: Vec<Cause> = Vec::new();
    let mut damage = Damage {
        skip_bad: options.skip_bad,
        skipped: &mut skipped,
    };
    let mut at = Position {
        bytes: 0,
        messages: 0,
    };
    let mut written = 0u64;
    // A message record is its data and a 22-byte header; a chunk holds several.
    let record_limit = usize::try_from(limit.saturating_add(1 << 20)).unwrap_or(usize::MAX);
    let mut reader = MessageReader::new_with_options(
        LinearReaderOptions::default()
            .with_record_length_limit(record_limit)
            .with_validate_chunk_crcs(true),
    );
    let stream_error = |at: &Position, source| RosError::Stream {
        bytes: at.bytes,
        messages: at.messages,
        source,
    };
    while let Some(event) = reader.next_event() {
        let message = match event.map_err(|e| stream_error(&at, e))? {
            MessageReadEvent::ReadRequest(wanted) => {
                let buffer = reader.insert(wanted.clamp(1, READ_STEP));
                let read = loop {
                    match input.read(buffer) {
                        Ok(read) => break read,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        Err(source) => {
                            return Err(RosError::Io {
                                path: path.clone(),
                                source,
                            })
                        }
                    }
                };
                reader.notify_read(read);
                at.bytes += read as u64;
                continue;
            }
            MessageReadEvent::Message(message) => message,
        };
        at.messages += 1;
        let channel = &message.channel;
        let schema = channel.schema.as_ref().map_or("", |s| s.name.as_str());
        // The reader refuses a channel id redefined otherwise, so an id stands for its
        // topic and schema.
        let topic = *by_channel.entry(channel.id).or_insert_with(|| {
            topics.push(TopicEntry {
                topic: channel.topic.clone(),
                type_name: schema.to_string(),
            });
            topics.len() - 1
        });
        let wanted = match &options.topic {
            Some(wanted) => *wanted == channel.topic,
            None => true,
        };
        let Some(kind) = MessageType::from_name(schema).filter(|_| wanted) else {
            continue;
        };
        let encoding = match channel.message_encoding.as_str() {
            "cdr" => Encoding::Cdr,
            "ros1" => Encoding::Ros1,
            other => {
                return Err(RosError::UnsupportedEncoding {
                    path,
                    topic: channel.topic.clone(),
                    encoding: other.to_string(),
                })
            }
        };
        let log_ns = i64::try_from(message.log_time).unwrap_or(i64::MAX);
        let stamp = match options.time {
            RecordedTime::Header => match decode_stamp(&message.data, encoding, kind) {
                Ok(stamp) => Some(stamp),
                Err(problem) => {
                    damage.left_out(RosError::BadMessage {
                        path: path.clone(),
                        topic: channel.topic.clone(),
                        time: iso8601(Timestamp(log_ns)),
                        problem: Box::new(problem),
                    })?;
                    continue;
                }
            },
            _ => None,
        };
        out.write_all(&message.data).map_err(spool_error)?;
        let len = message.data.len() as u64;
        spooled.push(Spooled {
            topic,
            encoding,
            log_ns,
            stamp,
            offset: written,
            len,
        });
        written += len;
    }
    out.flush().map_err(spool_error)?;
    drop(out);
    let (topic, kind) = select_topic(&path, &topics, options.topic.as_deref())?;
    spooled.retain(|m| topics.get(m.topic).is_some_and(|t| t.topic == topic));
    let stamps: Vec<(i64, Option<i64>)> = spooled.iter().map(|m| (m.log_ns, m.stamp)).collect();
    let (times, warnings) = times(&path, &topic, &stamps, options.time)?;
    let maps = StreamMaps {
        path,
        topic,
        kind,
        spool,
        maps: spooled,
        _dir: dir,
    };
    Ok(Recording::new(times, warnings, Arc::new(maps)).with_skipped(skipped))
}
