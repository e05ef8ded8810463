//! A recording as froctomap's inputs see it: the maps of one octomap topic at their times,
//! fetched one at a time ([`RecordedMaps`]).

use crate::bag::{Bag, BagMessage};
use crate::error::{span, RosError};
use crate::mcap_file::{McapFile, McapMessage};
use crate::message::{decode_message, decode_stamp, Encoding, MessageType};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_formats::{
    PluginError as Cause, RecordedMaps, RecordedTime, Recording, RecordingOptions,
};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// A topic of a recording file with its type, as the file names them.
#[derive(Clone, Debug)]
pub(crate) struct TopicEntry {
    pub topic: String,
    pub type_name: String,
}

/// The topic to read among `topics` (several entries may share a topic): `wanted`, else the
/// one of an octomap type.
pub(crate) fn select_topic(
    path: &Path,
    topics: &[TopicEntry],
    wanted: Option<&str>,
) -> Result<(String, MessageType), RosError> {
    let mut listed: Vec<(String, String)> = topics
        .iter()
        .map(|t| (t.topic.clone(), t.type_name.clone()))
        .collect();
    listed.sort();
    listed.dedup();
    if let Some(wanted) = wanted {
        let Some((topic, type_name)) = listed.iter().find(|(t, _)| t == wanted) else {
            return Err(RosError::NoSuchTopic {
                path: path.to_path_buf(),
                topic: wanted.to_string(),
                topics: listed,
            });
        };
        return MessageType::from_name(type_name)
            .map(|kind| (topic.clone(), kind))
            .ok_or_else(|| RosError::NotOctomapTopic {
                path: path.to_path_buf(),
                topic: topic.clone(),
                found: type_name.clone(),
            });
    }
    let maps: Vec<(String, String)> = listed
        .iter()
        .filter(|(_, kind)| MessageType::from_name(kind).is_some())
        .cloned()
        .collect();
    match maps.as_slice() {
        [] => Err(RosError::NoOctomapTopic {
            path: path.to_path_buf(),
            topics: listed,
        }),
        [(topic, kind)] => Ok((
            topic.clone(),
            MessageType::from_name(kind).unwrap_or(MessageType::Octomap),
        )),
        _ => Err(RosError::SeveralOctomapTopics {
            path: path.to_path_buf(),
            topics: maps,
        }),
    }
}

/// Where one map is.
#[derive(Clone, Debug)]
enum Location {
    Bag(BagMessage),
    /// A message of the `file`-th MCAP file of the recording.
    Mcap(usize, McapMessage),
}

/// The files a recording is made of.
#[derive(Debug)]
enum Files {
    Bag(Bag),
    Mcap(Vec<(McapFile, Encoding)>),
}

/// The maps of one topic of a recording.
#[derive(Debug)]
struct TopicMaps {
    path: PathBuf,
    topic: String,
    kind: MessageType,
    files: Files,
    maps: Vec<(i64, Location)>,
    /// The last decompressed chunks (several maps often share one): a bag chunk by its
    /// position, an MCAP chunk by its file (high bits) and index.
    chunk_cache: ChunkCache,
}

/// The last few decompressed chunks, most recent first. Extraction reads the maps of a
/// batch on several threads, each from its own part of the batch, so one entry would be
/// evicted at every turn; [`ChunkCache::ENTRIES`] keeps each thread's chunk.
#[derive(Debug, Default)]
struct ChunkCache(Mutex<Vec<(u64, Arc<Vec<u8>>)>>);

impl ChunkCache {
    const ENTRIES: usize = 4;

    /// The chunk `key`, from the cache or `read` (then kept, evicting the oldest).
    fn get_or_read(
        &self,
        key: u64,
        limit: u64,
        read: impl FnOnce() -> Result<Vec<u8>, RosError>,
    ) -> Result<Arc<Vec<u8>>, RosError> {
        let entries = || self.0.lock().unwrap_or_else(|e| e.into_inner());
        {
            let mut entries = entries();
            if let Some(i) = entries
                .iter()
                .position(|(k, chunk)| *k == key && chunk.len() as u64 <= limit)
            {
                let entry = entries.remove(i);
                let chunk = entry.1.clone();
                entries.insert(0, entry);
                return Ok(chunk);
            }
        }
        let chunk = Arc::new(read()?);
        let mut entries = entries();
        entries.insert(0, (key, chunk.clone()));
        entries.truncate(Self::ENTRIES);
        Ok(chunk)
    }
}

/// The map file a message of `topic` in `path`, logged at `log_ns`, stands for (refused
/// above `limit` bytes).
pub(crate) fn message_map_file(
    path: &Path,
    topic: &str,
    kind: MessageType,
    log_ns: i64,
    bytes: &[u8],
    encoding: Encoding,
    limit: u64,
) -> Result<Vec<u8>, RosError> {
    if bytes.len() as u64 > limit {
        return Err(RosError::TooLarge {
            path: path.to_path_buf(),
            what: "map message",
            bytes: bytes.len() as u64,
            limit,
        });
    }
    decode_message(bytes, encoding, kind)
        .and_then(|m| m.map_file())
        .map_err(|problem| RosError::BadMessage {
            path: path.to_path_buf(),
            topic: topic.to_string(),
            time: iso8601(Timestamp(log_ns)),
            problem: Box::new(problem),
        })
}

impl TopicMaps {
    fn bad_message(&self, log_ns: i64, problem: crate::MessageError) -> RosError {
        RosError::BadMessage {
            path: self.path.clone(),
            topic: self.topic.clone(),
            time: iso8601(Timestamp(log_ns)),
            problem: Box::new(problem),
        }
    }

    fn bag_chunk(&self, bag: &Bag, chunk_pos: u64, limit: u64) -> Result<Arc<Vec<u8>>, RosError> {
        self.chunk_cache
            .get_or_read(chunk_pos, limit, || bag.chunk(chunk_pos, limit))
    }

    /// The records of chunk `chunk` of MCAP file `file` (several maps often share one).
    fn mcap_records(
        &self,
        mcap: &McapFile,
        file: usize,
        chunk: usize,
        limit: u64,
    ) -> Result<Arc<Vec<u8>>, RosError> {
        let key = ((file as u64) << 40) | chunk as u64;
        self.chunk_cache
            .get_or_read(key, limit, || mcap.records(chunk, limit))
    }

    fn fetch(&self, index: usize, limit: u64) -> Result<Vec<u8>, RosError> {
        let Some((log_ns, location)) = self.maps.get(index) else {
            return Err(RosError::Malformed {
                path: self.path.clone(),
                what: "recording",
                problem: format!("no map {index}"),
            });
        };
        let decode = |bytes: &[u8], encoding| {
            message_map_file(
                &self.path,
                &self.topic,
                self.kind,
                *log_ns,
                bytes,
                encoding,
                limit,
            )
        };
        match (&self.files, location) {
            (Files::Bag(bag), Location::Bag(found)) => {
                let in_chunk = |problem| {
                    let times = bag
                        .chunks
                        .iter()
                        .find(|c| c.pos == found.chunk_pos)
                        .and_then(|c| c.times);
                    damaged(found.chunk_pos, Some(&self.topic), times, problem)
                };
                let chunk = self
                    .bag_chunk(bag, found.chunk_pos, limit)
                    .map_err(in_chunk)?;
                decode(
                    bag.message_in(&chunk, found.offset).map_err(in_chunk)?,
                    Encoding::Ros1,
                )
            }
            (Files::Mcap(files), Location::Mcap(file, found)) => {
                let (mcap, encoding) = files.get(*file).ok_or_else(|| RosError::Malformed {
                    path: self.path.clone(),
                    what: "recording",
                    problem: "no such file".into(),
                })?;
                let data = self
                    .mcap_records(mcap, *file, found.chunk, limit)
                    .and_then(|records| mcap.message_in(&records, found))
                    .map_err(|problem| {
                        let chunk = mcap.chunks.get(found.chunk);
                        damaged(
                            chunk.map_or(0, |c| c.offset()),
                            Some(&self.topic),
                            chunk.and_then(|c| c.times),
                            problem,
                        )
                    })?;
                decode(&data, *encoding)
            }
            _ => Err(RosError::Malformed {
                path: self.path.clone(),
                what: "recording",
                problem: "a location of another kind of file".into(),
            }),
        }
    }
}

impl RecordedMaps for TopicMaps {
    fn map_bytes(&self, index: usize, limit: u64) -> Result<Vec<u8>, Cause> {
        Ok(self.fetch(index, limit)?)
    }

    fn topic(&self) -> &str {
        &self.topic
    }
}

/// The recording's times as `options` ask, each map's stamp (`None`: not read) replaced by
/// its log time when zero, with one warning counting those and one counting maps stamped
/// earlier than a map logged before them (the maps are taken in time order). Two maps of
/// one time are an error naming it.
pub(crate) fn times(
    path: &Path,
    topic: &str,
    stamps: &[(i64, Option<i64>)],
    time: RecordedTime,
) -> Result<(Vec<Timestamp>, Vec<String>), RosError> {
    let mut zero = 0usize;
    let times: Vec<Timestamp> = stamps
        .iter()
        .map(|&(log_ns, stamp)| match (time, stamp) {
            (RecordedTime::Header, Some(0)) => {
                zero += 1;
                Timestamp(log_ns)
            }
            (RecordedTime::Header, Some(stamp)) => Timestamp(stamp),
            _ => Timestamp(log_ns),
        })
        .collect();
    let mut warnings = Vec::new();
    if zero > 0 {
        warnings.push(format!(
            "{zero} message(s) with a zero header stamp take their recording (log) time"
        ));
    }
    let mut latest = None;
    let mut earlier = 0usize;
    for &t in &times {
        if latest.is_some_and(|l| t < l) {
            earlier += 1;
        }
        latest = latest.max(Some(t));
    }
    if earlier > 0 {
        warnings.push(format!(
            "{earlier} message(s) on `{}` stamped earlier than a message recorded before them; the maps are taken in time order",
            topic
        ));
    }
    let mut sorted = times.clone();
    sorted.sort_unstable();
    if let Some(pair) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(RosError::DuplicateTimes {
            path: path.to_path_buf(),
            topic: topic.to_string(),
            time: iso8601(pair[0]),
            count: sorted.iter().filter(|&&t| t == pair[0]).count(),
        });
    }
    Ok((times, warnings))
}

/// A bag message with its header stamp (`None`: not read), or why that does not decode.
type StampedMessage = (BagMessage, Result<Option<i64>, RosError>);

/// A chunk's problem as an error naming the chunk, the topic and its messages' times.
fn damaged(
    offset: u64,
    topic: Option<&str>,
    times: Option<(i64, i64)>,
    problem: RosError,
) -> RosError {
    match problem {
        // Already named (a damaged chunk found while opening a file without its index).
        RosError::DamagedChunk { .. } => problem,
        problem => RosError::DamagedChunk {
            offset,
            topic: topic.map(str::to_string),
            times: times.map(span),
            problem: Box::new(problem),
        },
    }
}

/// Where a problem of one part of a recording goes: an error, or with `skip_bad` the list
/// of parts left out.
pub(crate) struct Damage<'a> {
    pub skip_bad: bool,
    pub skipped: &'a mut Vec<Cause>,
}

impl Damage<'_> {
    pub fn left_out(&mut self, problem: RosError) -> Result<(), RosError> {
        if !self.skip_bad {
            return Err(problem);
        }
        self.skipped.push(Box::new(problem));
        Ok(())
    }
}

/// Opens a ROS 1 bag.
pub(crate) fn open_bag(
    path: &Path,
    options: &RecordingOptions,
    limit: u64,
) -> Result<Recording, RosError> {
    let mut bag = Bag::open(path, limit, options.skip_bad)?;
    let left_out = std::mem::take(&mut bag.damaged);
    let mut warnings = std::mem::take(&mut bag.warnings);
    let topics: Vec<TopicEntry> = bag
        .connections
        .iter()
        .map(|c| TopicEntry {
            topic: c.topic.clone(),
            type_name: c.type_name.clone(),
        })
        .collect();
    let (topic, kind) = select_topic(path, &topics, options.topic.as_deref())?;
    let ids: Vec<u32> = bag
        .connections
        .iter()
        .filter(|c| c.topic == topic)
        .map(|c| c.id)
        .collect();
    let mut skipped: Vec<Cause> = Vec::new();
    let mut maps = TopicMaps {
        path: path.to_path_buf(),
        topic,
        kind,
        files: Files::Bag(bag),
        maps: Vec::new(),
        chunk_cache: ChunkCache::default(),
    };
    let mut stamps = Vec::new();
    let mut locations = Vec::new();
    if let Files::Bag(bag) = &maps.files {
        let mut damage = Damage {
            skip_bad: options.skip_bad,
            skipped: &mut skipped,
        };
        for (info, problem) in left_out {
            damage.left_out(damaged(info.pos, None, info.times, problem))?;
        }
        for info in &bag.chunks {
            if !info.connections.iter().any(|c| ids.contains(c)) {
                continue;
            }
            let read = || -> Result<Vec<StampedMessage>, RosError> {
                let found = bag.chunk_messages(info, &ids)?;
                if options.time != RecordedTime::Header {
                    return Ok(found.into_iter().map(|m| (m, Ok(None))).collect());
                }
                let chunk = maps.bag_chunk(bag, info.pos, limit)?;
                found
                    .into_iter()
                    .map(|message| {
                        let bytes = bag.message_in(&chunk, message.offset)?;
                        let stamp = decode_stamp(bytes, Encoding::Ros1, kind)
                            .map(Some)
                            .map_err(|e| maps.bad_message(message.log_ns, e));
                        Ok((message, stamp))
                    })
                    .collect()
            };
            let found = match read() {
                Ok(found) => found,
                Err(problem) => {
                    damage.left_out(damaged(info.pos, Some(&maps.topic), info.times, problem))?;
                    continue;
                }
            };
            for (message, stamp) in found {
                match stamp {
                    Ok(stamp) => {
                        stamps.push((message.log_ns, stamp));
                        locations.push((message.log_ns, Location::Bag(message)));
                    }
                    Err(problem) => damage.left_out(problem)?,
                }
            }
        }
    }
    maps.maps = locations;
    let (times, more) = times(&maps.path, &maps.topic, &stamps, options.time)?;
    warnings.extend(more);
    Ok(Recording::new(times, warnings, Arc::new(maps)).with_skipped(skipped))
}

/// Opens MCAP files as one recording (one file, or the files of a ROS 2 bag directory).
pub(crate) fn open_mcap(
    path: &Path,
    files: &[PathBuf],
    options: &RecordingOptions,
    limit: u64,
) -> Result<Recording, RosError> {
    let opened: Vec<McapFile> = files
        .iter()
        .map(|f| McapFile::open(f, limit, options.skip_bad))
        .collect::<Result<_, _>>()?;
    let topics: Vec<TopicEntry> = opened
        .iter()
        .flat_map(|f| &f.channels)
        .map(|c| TopicEntry {
            topic: c.topic.clone(),
            type_name: c.schema.clone(),
        })
        .collect();
    let (topic, kind) = select_topic(path, &topics, options.topic.as_deref())?;
    let mut stamps = Vec::new();
    let mut locations = Vec::new();
    let mut warnings = Vec::new();
    let mut skipped: Vec<Cause> = Vec::new();
    let mut with_encoding = Vec::with_capacity(opened.len());
    for (file_index, mut mcap) in opened.into_iter().enumerate() {
        // The files of a ROS 2 bag directory are named; a single file is the recording.
        warnings.extend(mcap.warnings.iter().map(|w| {
            if mcap.file.path == path {
                w.clone()
            } else {
                format!("{}: {w}", mcap.file.path.display())
            }
        }));
        let mut damage = Damage {
            skip_bad: options.skip_bad,
            skipped: &mut skipped,
        };
        for (chunk, problem) in std::mem::take(&mut mcap.damaged) {
            damage.left_out(damaged(chunk.offset(), None, chunk.times, problem))?;
        }
        let channels: Vec<_> = mcap.channels.iter().filter(|c| c.topic == topic).collect();
        let Some(first) = channels.first() else {
            with_encoding.push((mcap, Encoding::Cdr));
            continue;
        };
        let encoding = match first.encoding.as_str() {
            "cdr" => Encoding::Cdr,
            "ros1" => Encoding::Ros1,
            other => {
                return Err(RosError::UnsupportedEncoding {
                    path: mcap.file.path.clone(),
                    topic,
                    encoding: other.to_string(),
                })
            }
        };
        let ids: Vec<u16> = channels.iter().map(|c| c.id).collect();
        let header = options.time == RecordedTime::Header;
        let file_path = mcap.file.path.clone();
        for (i, chunk) in mcap.chunks.iter().enumerate() {
            if !chunk.may_hold(&ids) {
                continue;
            }
            let mut bad_messages = Vec::new();
            let found = mcap.chunk_messages(i, &ids, limit, &mut |log_ns, data| {
                if !header {
                    return Ok(Some(None));
                }
                match decode_stamp(data, encoding, kind) {
                    Ok(stamp) => Ok(Some(Some(stamp))),
                    Err(problem) => {
                        bad_messages.push(RosError::BadMessage {
                            path: file_path.clone(),
                            topic: topic.clone(),
                            time: iso8601(Timestamp(log_ns)),
                            problem: Box::new(problem),
                        });
                        Ok(None)
                    }
                }
            });
            let found = match found {
                Ok(found) => found,
                Err(problem) => {
                    let problem = damaged(chunk.offset(), Some(&topic), chunk.times, problem);
                    damage.left_out(problem)?;
                    continue;
                }
            };
            for problem in bad_messages {
                damage.left_out(problem)?;
            }
            for (message, stamp) in found {
                stamps.push((message.log_ns, stamp));
                locations.push((message.log_ns, Location::Mcap(file_index, message)));
            }
        }
        with_encoding.push((mcap, encoding));
    }
    let maps = TopicMaps {
        path: path.to_path_buf(),
        topic,
        kind,
        files: Files::Mcap(with_encoding),
        maps: locations,
        chunk_cache: ChunkCache::default(),
    };
    let (times, more) = times(&maps.path, &maps.topic, &stamps, options.time)?;
    warnings.extend(more);
    Ok(Recording::new(times, warnings, Arc::new(maps)).with_skipped(skipped))
}
