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
    let mut reader = message_reader(limit);
    while let Some(message) = next_message(&mut reader, input, &mut at)? {
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
        let encoding = encoding_of(channel)?;
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

/// How the messages of `channel` are encoded, if one we read.
fn encoding_of(channel: &mcap::Channel<'_>) -> Result<Encoding, RosError> {
    match channel.message_encoding.as_str() {
        "cdr" => Ok(Encoding::Cdr),
        "ros1" => Ok(Encoding::Ros1),
        other => Err(RosError::UnsupportedEncoding {
            path: PathBuf::from(STREAM_PATH),
            topic: channel.topic.clone(),
            encoding: other.to_string(),
        }),
    }
}

/// A sans-io reader of MCAP messages whose records may hold a map of up to `limit` bytes.
fn message_reader(limit: u64) -> MessageReader {
    // A message record is its data and a 22-byte header; a chunk holds several.
    let record_limit = usize::try_from(limit.saturating_add(1 << 20)).unwrap_or(usize::MAX);
    MessageReader::new_with_options(
        LinearReaderOptions::default()
            .with_record_length_limit(record_limit)
            .with_validate_chunk_crcs(true),
    )
}

/// The next message of the stream, reading `input` as the reader asks (`None`: the stream
/// ended whole). Counts the bytes read and the messages in `at`.
fn next_message(
    reader: &mut MessageReader,
    input: &mut dyn Read,
    at: &mut Position,
) -> Result<Option<mcap::Message<'static>>, RosError> {
    while let Some(event) = reader.next_event() {
        let event = event.map_err(|source| RosError::Stream {
            bytes: at.bytes,
            messages: at.messages,
            source,
        })?;
        match event {
            MessageReadEvent::ReadRequest(wanted) => {
                let buffer = reader.insert(wanted.clamp(1, READ_STEP));
                let read = loop {
                    match input.read(buffer) {
                        Ok(read) => break read,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        Err(source) => {
                            return Err(RosError::Io {
                                path: PathBuf::from(STREAM_PATH),
                                source,
                            })
                        }
                    }
                };
                reader.notify_read(read);
                at.bytes += read as u64;
            }
            MessageReadEvent::Message(message) => {
                at.messages += 1;
                return Ok(Some(message));
            }
        }
    }
    Ok(None)
}

/// One map of a [`McapStreamMaps`]: its time, its bytes as a map file, and where the
/// stream held it.
#[derive(Debug)]
pub struct StreamedMap {
    /// Its header stamp or log time (as [`RecordingOptions::time`] says).
    pub time: Timestamp,
    /// The map as a `.bt`/`.ot` file ([`OctomapMessage::map_file`](crate::OctomapMessage::map_file)).
    pub bytes: Vec<u8>,
    /// Its message's place in the stream (1 for the first message, of any topic).
    pub message: u64,
    /// The stream's bytes read when it was read whole.
    pub offset: u64,
}

/// The maps of an MCAP stream one at a time as they arrive, for a consumer that keeps
/// only what it has not yet committed (`froctomap record`): unlike `-` among a build's
/// inputs, which is read to its end first, nothing is spooled here.
///
/// The topic is `options.topic`, else the first topic of a map type: maps on a second
/// such topic are an error (give `--topic`).
///
/// ```
/// use froctomap_core::{Leaf, Snapshot, Timestamp, VoxelKey};
/// use froctomap_formats::RecordingOptions;
/// use froctomap_ros::{McapMapStream, McapStreamMaps};
/// let map = Snapshot::from_leaves(0.1, vec![Leaf::voxel(VoxelKey::new(32768, 32768, 32768), 3.5)])?;
/// let bt = froctomap_octomap_codec::encode_binary(&map);
/// let mut stream = McapMapStream::new(Vec::new())?;
/// stream.write_map(Timestamp::from_secs(1_451_865_600), &bt)?;
/// let bytes = stream.finish()?;
/// let mut maps = McapStreamMaps::new(&bytes[..], &RecordingOptions::default(), 1 << 20);
/// let map = maps.next_map()?.expect("one map")?;
/// assert_eq!(map.time, Timestamp::from_secs(1_451_865_600));
/// assert!(map.bytes.starts_with(b"# Octomap OcTree binary file"));
/// assert!(maps.next_map()?.is_none());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct McapStreamMaps<R> {
    input: R,
    reader: MessageReader,
    at: Position,
    options: RecordingOptions,
    /// The topic taken and its message type, once known.
    topic: Option<(String, MessageType)>,
}

impl<R: Read> McapStreamMaps<R> {
    /// Reads maps of at most `limit` bytes from `input` as `options` say (topic, time).
    pub fn new(input: R, options: &RecordingOptions, limit: u64) -> Self {
        Self {
            input,
            reader: message_reader(limit),
            at: Position {
                bytes: 0,
                messages: 0,
            },
            options: options.clone(),
            topic: None,
        }
    }

    /// The bytes and messages read so far.
    pub fn position(&self) -> (u64, u64) {
        (self.at.bytes, self.at.messages)
    }

    /// The next map (`Ok(None)`: the stream ended whole). The outer error ends the stream
    /// (it is cut or does not read); the inner one is a map message that does not decode,
    /// after which reading may go on.
    #[allow(clippy::type_complexity)]
    pub fn next_map(&mut self) -> Result<Option<Result<StreamedMap, RosError>>, RosError> {
        let path = PathBuf::from(STREAM_PATH);
        while let Some(message) = next_message(&mut self.reader, &mut self.input, &mut self.at)? {
            let channel = &message.channel;
            let schema = channel.schema.as_ref().map_or("", |s| s.name.as_str());
            let Some(kind) = MessageType::from_name(schema) else {
                continue;
            };
            match (&self.options.topic, &self.topic) {
                (Some(wanted), _) if *wanted != channel.topic => continue,
                (None, Some((taken, _))) if *taken != channel.topic => {
                    return Err(RosError::Malformed {
                        path,
                        what: "stream",
                        problem: format!(
                            "maps on two topics, `{taken}` and `{}`: choose one with --topic",
                            channel.topic
                        ),
                    })
                }
                _ => {}
            }
            self.topic
                .get_or_insert_with(|| (channel.topic.clone(), kind));
            let log_ns = i64::try_from(message.log_time).unwrap_or(i64::MAX);
            let bad = |problem| RosError::BadMessage {
                path: path.clone(),
                topic: channel.topic.clone(),
                time: iso8601(Timestamp(log_ns)),
                problem: Box::new(problem),
            };
            let encoding = encoding_of(channel)?;
            let time = match self.options.time {
                RecordedTime::Header => match decode_stamp(&message.data, encoding, kind) {
                    Ok(0) => Timestamp(log_ns),
                    Ok(stamp) => Timestamp(stamp),
                    Err(problem) => return Ok(Some(Err(bad(problem)))),
                },
                _ => Timestamp(log_ns),
            };
            let map = decode_message(&message.data, encoding, kind).and_then(|m| m.map_file());
            return Ok(Some(match map {
                Ok(bytes) => Ok(StreamedMap {
                    time,
                    bytes,
                    message: self.at.messages,
                    offset: self.at.bytes,
                }),
                Err(problem) => Err(bad(problem)),
            }));
        }
        Ok(None)
    }
}
