//! ROS 1 bags (format 2.0), read from their index without loading the bag.
//!
//! No maintained Rust crate reads bags without mapping the whole file into memory and
//! trusting its lengths, and the format is short, so this module reads it:
//!
//! * `#ROSBAG V2.0\n`, then records: `u32` header length, header fields (`u32` length then
//!   `name=value`), `u32` data length, data. Field `op` says the record's kind.
//! * The bag header record (`op=0x03`) gives `index_pos`, where the connection records
//!   (`0x07`: connection id, topic; data: `type`, `md5sum`, `message_definition`…) and chunk
//!   info records (`0x06`: `chunk_pos`; data: per connection its message count) lie.
//! * A chunk record (`0x05`: `compression` none/bz2/lz4, `size` uncompressed) holds message
//!   data records (`0x02`: `conn`, `time`; data: the serialised message); after it come
//!   index data records (`0x04`: `conn`, `count`; data: per message `u32` secs, `u32` nsecs,
//!   `u32` offset of its record in the uncompressed chunk).
//!
//! Every length is checked against the file size (or the caller's limit, for uncompressed
//! chunks) before anything is allocated.

use crate::error::{span, RosError};
use crate::io::RecordingFile;
use std::io::Read;
use std::path::Path;

/// The first bytes of a bag.
pub(crate) const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// The longest record header read (bag headers hold a few short fields).
const MAX_HEADER_BYTES: u64 = 1 << 20;

pub(crate) const OP_MESSAGE: u8 = 0x02;
pub(crate) const OP_BAG_HEADER: u8 = 0x03;
pub(crate) const OP_INDEX: u8 = 0x04;
pub(crate) const OP_CHUNK: u8 = 0x05;
pub(crate) const OP_CHUNK_INFO: u8 = 0x06;
pub(crate) const OP_CONNECTION: u8 = 0x07;

/// Header fields of a record.
struct Fields<'a>(Vec<(&'a [u8], &'a [u8])>);

impl<'a> Fields<'a> {
    fn parse(file: &RecordingFile, mut bytes: &'a [u8]) -> Result<Self, RosError> {
        let mut fields = Vec::new();
        while !bytes.is_empty() {
            let (len, rest) = split_u32(bytes)
                .ok_or_else(|| file.malformed("record header", "a field length is cut off"))?;
            let field = rest
                .get(..len as usize)
                .ok_or_else(|| file.malformed("record header", "a field runs past the header"))?;
            let eq = field
                .iter()
                .position(|&b| b == b'=')
                .ok_or_else(|| file.malformed("record header", "a field without `=`"))?;
            fields.push((&field[..eq], &field[eq + 1..]));
            bytes = &rest[len as usize..];
        }
        Ok(Self(fields))
    }

    fn get(&self, name: &str) -> Option<&'a [u8]> {
        self.0
            .iter()
            .find(|(n, _)| *n == name.as_bytes())
            .map(|(_, v)| *v)
    }

    fn op(&self) -> Option<u8> {
        self.get("op").and_then(|v| v.first().copied())
    }

    /// The record's kind: every record header has one (a header of length 0 has none).
    /// `place` says where the record is, for the error.
    fn required_op(
        &self,
        file: &RecordingFile,
        place: impl FnOnce() -> String,
    ) -> Result<Option<u8>, RosError> {
        match self.op() {
            Some(op) => Ok(Some(op)),
            None => Err(file.malformed(
                "record header",
                format!("the record at {} has no `op` field", place()),
            )),
        }
    }

    fn u32(&self, file: &RecordingFile, name: &'static str) -> Result<u32, RosError> {
        self.get(name)
            .and_then(|v| v.try_into().ok())
            .map(u32::from_le_bytes)
            .ok_or_else(|| file.malformed("record header", format!("no 4-byte `{name}` field")))
    }

    fn u64(&self, file: &RecordingFile, name: &'static str) -> Result<u64, RosError> {
        self.get(name)
            .and_then(|v| v.try_into().ok())
            .map(u64::from_le_bytes)
            .ok_or_else(|| file.malformed("record header", format!("no 8-byte `{name}` field")))
    }

    fn text(&self, name: &str) -> String {
        String::from_utf8_lossy(self.get(name).unwrap_or_default()).into_owned()
    }
}

fn split_u32(bytes: &[u8]) -> Option<(u32, &[u8])> {
    let (head, rest) = bytes.split_first_chunk::<4>()?;
    Some((u32::from_le_bytes(*head), rest))
}

/// A record read from the file: its header bytes and where its data lies.
struct FileRecord {
    header: Vec<u8>,
    data_offset: u64,
    data_len: u64,
}

impl FileRecord {
    fn end(&self) -> u64 {
        self.data_offset + self.data_len
    }
}

fn read_record(
    file: &RecordingFile,
    offset: u64,
    what: &'static str,
) -> Result<FileRecord, RosError> {
    let len = |bytes: Vec<u8>| bytes.try_into().map(u32::from_le_bytes).unwrap_or(0);
    let header_len = u64::from(len(file.read_at(offset, 4, what)?));
    // Record headers are a few named fields; a longer one is damage, not a reason to read
    // up to 4 GiB.
    let header_len = file.bounded("record header", header_len, MAX_HEADER_BYTES)?;
    let header = file.read_at(offset + 4, header_len, what)?;
    let data_len_at = offset + 4 + header_len;
    let data_len = u64::from(len(file.read_at(data_len_at, 4, what)?));
    let data_offset = data_len_at + 4;
    if data_offset + data_len > file.size {
        return Err(file.truncated(what));
    }
    Ok(FileRecord {
        header,
        data_offset,
        data_len,
    })
}

/// A record inside a decompressed chunk: its header and data.
fn record_in(bytes: &[u8], offset: usize) -> Option<(&[u8], &[u8])> {
    let (header_len, rest) = split_u32(bytes.get(offset..)?)?;
    let header = rest.get(..header_len as usize)?;
    let (data_len, rest) = split_u32(&rest[header_len as usize..])?;
    let data = rest.get(..data_len as usize)?;
    Some((header, data))
}

/// A connection: a topic and its message type.
#[derive(Clone, Debug)]
pub(crate) struct Connection {
    pub id: u32,
    pub topic: String,
    pub type_name: String,
}

/// A chunk of a bag: where it is, the log times of its first and last messages (when the
/// index or its records tell) and the connections with messages in it.
#[derive(Clone, Debug)]
pub(crate) struct ChunkInfo {
    pub pos: u64,
    pub times: Option<(i64, i64)>,
    pub connections: Vec<u32>,
}

/// An opened bag: its connections and chunks, from its index (or, for a bag without a
/// usable index, from reading its chunks in order, as `rosbag reindex` does).
#[derive(Debug)]
pub(crate) struct Bag {
    pub file: RecordingFile,
    pub connections: Vec<Connection>,
    /// In file order.
    pub chunks: Vec<ChunkInfo>,
    /// For a bag read without its index: each chunk's messages with their connection.
    scanned: Option<Vec<Vec<(u32, BagMessage)>>>,
    /// Chunks that could not be read while scanning a bag without its index (only with
    /// `skip_bad`; otherwise opening fails), and why.
    pub damaged: Vec<(ChunkInfo, RosError)>,
    /// What the reader tolerated (a missing or cut index).
    pub warnings: Vec<String>,
}

/// One message of a bag: its log time and where its record is.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BagMessage {
    pub log_ns: i64,
    pub chunk_pos: u64,
    pub offset: u32,
}

/// A ROS time field (`u32` seconds, `u32` nanoseconds) as nanoseconds.
fn time_ns(bytes: &[u8]) -> Option<i64> {
    let secs = u32::from_le_bytes(bytes.get(..4)?.try_into().ok()?);
    let nsecs = u32::from_le_bytes(bytes.get(4..8)?.try_into().ok()?);
    Some(i64::from(secs) * 1_000_000_000 + i64::from(nsecs))
}

impl Bag {
    /// Opens a bag from its index; a bag without one (not closed by its recorder, or cut)
    /// is read chunk by chunk up to the first incomplete record, with a warning saying what
    /// was lost. A chunk that does not read during that scan fails the opening, or with
    /// `skip_bad` is left out and listed in [`Bag::damaged`].
    pub fn open(path: &Path, limit: u64, skip_bad: bool) -> Result<Self, RosError> {
        let file = RecordingFile::open(path)?;
        if file.read_at(0, MAGIC.len() as u64, "bag magic")? != MAGIC {
            return Err(file.malformed("bag", "it does not start with `#ROSBAG V2.0`"));
        }
        let header = read_record(&file, MAGIC.len() as u64, "bag header")?;
        let fields = Fields::parse(&file, &header.header)?;
        if fields.op() != Some(OP_BAG_HEADER) {
            return Err(file.malformed("bag header", "the first record is not the bag header"));
        }
        let index_pos = fields.u64(&file, "index_pos")?;
        let mut bag = Bag {
            file,
            connections: Vec::new(),
            chunks: Vec::new(),
            scanned: None,
            damaged: Vec::new(),
            warnings: Vec::new(),
        };
        let why = if index_pos == 0 {
            "the bag has no index (its recorder did not close it)".to_string()
        } else if index_pos < header.end() || index_pos >= bag.file.size {
            format!(
                "its index should start at byte {index_pos}, outside the file of {} bytes (a cut bag?)",
                bag.file.size
            )
        } else {
            match bag.read_index(index_pos) {
                Ok(()) => return Ok(bag),
                Err(e) => format!(
                    "its index does not read ({})",
                    froctomap_core::error_message(&e)
                ),
            }
        };
        bag.connections.clear();
        bag.chunks.clear();
        bag.scan(header.end(), limit, skip_bad, &why)?;
        Ok(bag)
    }

    /// Reads the connection and chunk info records of the index at `index_pos`.
    fn read_index(&mut self, index_pos: u64) -> Result<(), RosError> {
        let mut pos = index_pos;
        while pos < self.file.size {
            let record = read_record(&self.file, pos, "index record")?;
            let fields = Fields::parse(&self.file, &record.header)?;
            match fields.required_op(&self.file, || format!("byte {pos}"))? {
                Some(OP_CONNECTION) => {
                    let data =
                        self.file
                            .read_at(record.data_offset, record.data_len, "connection")?;
                    self.connections.push(self.connection(&fields, &data)?);
                }
                Some(OP_CHUNK_INFO) => {
                    let data =
                        self.file
                            .read_at(record.data_offset, record.data_len, "chunk info")?;
                    let connections = data
                        .chunks_exact(8)
                        .filter_map(|pair| pair[..4].try_into().ok().map(u32::from_le_bytes))
                        .collect();
                    let start = fields.get("start_time").and_then(time_ns);
                    let end = fields.get("end_time").and_then(time_ns);
                    self.chunks.push(ChunkInfo {
                        pos: fields.u64(&self.file, "chunk_pos")?,
                        times: start.zip(end),
                        connections,
                    });
                }
                _ => {}
            }
            pos = record.end();
        }
        self.chunks.sort_by_key(|c| c.pos);
        Ok(())
    }

    fn connection(&self, fields: &Fields<'_>, data: &[u8]) -> Result<Connection, RosError> {
        let connection = Fields::parse(&self.file, data)?;
        Ok(Connection {
            id: fields.u32(&self.file, "conn")?,
            topic: fields.text("topic"),
            type_name: connection.text("type"),
        })
    }

    /// Reads the records from `pos` in order, as `rosbag reindex` does: each chunk is
    /// decompressed for its connections and messages. Stops at the first record that the
    /// file cuts off (what follows is lost, and said so in a warning) or whose header does
    /// not read (nothing after it can be found).
    fn scan(
        &mut self,
        mut pos: u64,
        limit: u64,
        skip_bad: bool,
        why: &str,
    ) -> Result<(), RosError> {
        let mut scanned = Vec::new();
        let mut messages = 0usize;
        let stop = loop {
            if pos >= self.file.size {
                break None;
            }
            let record = match read_record(&self.file, pos, "record") {
                Ok(record) => record,
                Err(RosError::Truncated { .. }) => break Some("is cut off".to_string()),
                Err(e) => {
                    break Some(format!(
                        "does not read ({})",
                        froctomap_core::error_message(&e)
                    ))
                }
            };
            let fields = match Fields::parse(&self.file, &record.header) {
                Ok(fields) => fields,
                Err(e) => {
                    break Some(format!(
                        "does not read ({})",
                        froctomap_core::error_message(&e)
                    ))
                }
            };
            match fields.required_op(&self.file, || format!("byte {pos}"))? {
                Some(OP_CHUNK) => match self.scan_chunk(pos, limit) {
                    Ok((info, found, connections)) => {
                        for connection in connections {
                            if !self.connections.iter().any(|c| c.id == connection.id) {
                                self.connections.push(connection);
                            }
                        }
                        messages += found.len();
                        self.chunks.push(info);
                        scanned.push(found);
                    }
                    Err(problem) => {
                        let info = ChunkInfo {
                            pos,
                            times: self.index_times(record.end()),
                            connections: Vec::new(),
                        };
                        if !skip_bad {
                            return Err(RosError::DamagedChunk {
                                offset: pos,
                                topic: None,
                                times: info.times.map(span),
                                problem: Box::new(problem),
                            });
                        }
                        self.damaged.push((info, problem));
                    }
                },
                // The index of a bag whose index position was not written.
                Some(OP_CONNECTION) => {
                    if let Ok(data) =
                        self.file
                            .read_at(record.data_offset, record.data_len, "connection")
                    {
                        if let Ok(connection) = self.connection(&fields, &data) {
                            if !self.connections.iter().any(|c| c.id == connection.id) {
                                self.connections.push(connection);
                            }
                        }
                    }
                }
                _ => {}
            }
            pos = record.end();
        };
        let read = format!(
            "{} chunk(s) with {messages} message(s) read in order",
            self.chunks.len()
        );
        self.warnings.push(match stop {
            None => format!("{why}; {read}, to the end of the file (`rosbag reindex` writes the index)"),
            Some(how) => format!(
                "{why}; {read}; the record at byte {pos} {how}, so its last {} of {} bytes are not read (`rosbag reindex` recovers the same)",
                self.file.size - pos,
                self.file.size
            ),
        });
        self.scanned = Some(scanned);
        Ok(())
    }

    /// A chunk read while scanning: its info, its messages and the connections in it.
    #[allow(clippy::type_complexity)]
    fn scan_chunk(
        &self,
        pos: u64,
        limit: u64,
    ) -> Result<(ChunkInfo, Vec<(u32, BagMessage)>, Vec<Connection>), RosError> {
        let chunk = self.chunk(pos, limit)?;
        let mut found = Vec::new();
        let mut connections = Vec::new();
        let mut offset = 0usize;
        while offset < chunk.len() {
            let (header, data) = record_in(&chunk, offset)
                .ok_or_else(|| self.file.malformed("chunk", "a record runs past its chunk"))?;
            let fields = Fields::parse(&self.file, header)?;
            match fields.required_op(&self.file, || {
                format!("byte {offset} of the chunk at byte {pos}")
            })? {
                Some(OP_CONNECTION) => connections.push(self.connection(&fields, data)?),
                Some(OP_MESSAGE) => {
                    let log_ns = fields
                        .get("time")
                        .and_then(time_ns)
                        .ok_or_else(|| self.file.malformed("message", "no 8-byte `time` field"))?;
                    let at = u32::try_from(offset)
                        .map_err(|_| self.file.malformed("chunk", "more than 4 GiB"))?;
                    found.push((
                        fields.u32(&self.file, "conn")?,
                        BagMessage {
                            log_ns,
                            chunk_pos: pos,
                            offset: at,
                        },
                    ));
                }
                _ => {}
            }
            offset += 8 + header.len() + data.len();
        }
        let first = found.iter().map(|(_, m)| m.log_ns).min();
        let last = found.iter().map(|(_, m)| m.log_ns).max();
        let mut present: Vec<u32> = found.iter().map(|(c, _)| *c).collect();
        present.sort_unstable();
        present.dedup();
        let info = ChunkInfo {
            pos,
            times: first.zip(last),
            connections: present,
        };
        Ok((info, found, connections))
    }

    /// The log times of the first and last messages the index data records from `pos` (after
    /// a chunk) list, if they read.
    fn index_times(&self, mut pos: u64) -> Option<(i64, i64)> {
        let mut times: Option<(i64, i64)> = None;
        while pos < self.file.size {
            let record = read_record(&self.file, pos, "index data").ok()?;
            let fields = Fields::parse(&self.file, &record.header).ok()?;
            if fields.op() != Some(OP_INDEX) {
                break;
            }
            let data = self
                .file
                .read_at(record.data_offset, record.data_len, "index data")
                .ok()?;
            for entry in data.chunks_exact(12) {
                let t = time_ns(entry)?;
                times = Some(times.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            }
            pos = record.end();
        }
        times
    }

    /// The messages of `connections` in the chunk `info`, from the index data after it (no
    /// chunk is decompressed), or from the scan of a bag without an index.
    pub fn chunk_messages(
        &self,
        info: &ChunkInfo,
        connections: &[u32],
    ) -> Result<Vec<BagMessage>, RosError> {
        if let Some(scanned) = &self.scanned {
            let i = self
                .chunks
                .iter()
                .position(|c| c.pos == info.pos)
                .ok_or_else(|| self.file.malformed("chunk", "no such chunk"))?;
            return Ok(scanned
                .get(i)
                .into_iter()
                .flatten()
                .filter(|(c, _)| connections.contains(c))
                .map(|(_, m)| *m)
                .collect());
        }
        let mut out = Vec::new();
        let chunk = read_record(&self.file, info.pos, "chunk")?;
        let mut pos = chunk.end();
        while pos < self.file.size {
            let record = read_record(&self.file, pos, "index data")?;
            let fields = Fields::parse(&self.file, &record.header)?;
            // A record without a kind is damage, not the end of the index data: stopping
            // there would drop the chunk's messages without a word.
            if fields.required_op(&self.file, || format!("byte {pos}"))? != Some(OP_INDEX) {
                break;
            }
            if connections.contains(&fields.u32(&self.file, "conn")?) {
                let data = self
                    .file
                    .read_at(record.data_offset, record.data_len, "index data")?;
                for entry in data.chunks_exact(12) {
                    let word = |i: usize| {
                        u32::from_le_bytes([entry[i], entry[i + 1], entry[i + 2], entry[i + 3]])
                    };
                    out.push(BagMessage {
                        log_ns: i64::from(word(0)) * 1_000_000_000 + i64::from(word(4)),
                        chunk_pos: info.pos,
                        offset: word(8),
                    });
                }
            }
            pos = record.end();
        }
        Ok(out)
    }

    /// A chunk's records, decompressed; refused above `limit` bytes.
    pub fn chunk(&self, chunk_pos: u64, limit: u64) -> Result<Vec<u8>, RosError> {
        let record = read_record(&self.file, chunk_pos, "chunk")?;
        let fields = Fields::parse(&self.file, &record.header)?;
        if fields.op() != Some(OP_CHUNK) {
            return Err(self
                .file
                .malformed("chunk", "the index points at another kind of record"));
        }
        let size = self.file.bounded(
            "uncompressed chunk",
            u64::from(fields.u32(&self.file, "size")?),
            limit,
        )?;
        let compression = fields.text("compression");
        // Compressed data may be a little longer than what it holds.
        self.file.bounded(
            "chunk",
            record.data_len,
            limit.saturating_add(limit / 64 + 4096),
        )?;
        let data = self
            .file
            .read_at(record.data_offset, record.data_len, "chunk")?;
        let mut out = Vec::new();
        let read = match compression.as_str() {
            "none" => {
                out = data;
                Ok(out.len())
            }
            // One byte more than announced, to notice a chunk longer than its `size`.
            "bz2" => bzip2::read::BzDecoder::new(data.as_slice())
                .take(size + 1)
                .read_to_end(&mut out),
            "lz4" => lz4::Decoder::new(data.as_slice())
                .and_then(|decoder| decoder.take(size + 1).read_to_end(&mut out)),
            _ => {
                return Err(RosError::UnsupportedCompression {
                    path: self.file.path.clone(),
                    name: compression,
                    supported: "none, bz2 and lz4",
                })
            }
        };
        read.map_err(|e| {
            self.file.malformed(
                "chunk",
                format!("{compression} data does not decompress: {e}"),
            )
        })?;
        if out.len() as u64 != size {
            return Err(self.file.malformed(
                "chunk",
                format!("{} bytes uncompressed, the header says {size}", out.len()),
            ));
        }
        Ok(out)
    }

    /// The serialised message whose record is at `offset` of a decompressed chunk.
    pub fn message_in<'c>(&self, chunk: &'c [u8], offset: u32) -> Result<&'c [u8], RosError> {
        let (header, data) = record_in(chunk, offset as usize).ok_or_else(|| {
            self.file
                .malformed("chunk", "an index entry points outside its chunk")
        })?;
        if Fields::parse(&self.file, header)?.op() != Some(OP_MESSAGE) {
            return Err(self.file.malformed(
                "chunk",
                "an index entry points at a record that is no message",
            ));
        }
        Ok(data)
    }
}
