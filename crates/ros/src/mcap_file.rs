//! MCAP files, read through the `mcap` crate: the summary section (channels, schemas, chunk
//! indexes) found from the footer (or, without one, the records in order), then one chunk
//! at a time.

use crate::error::RosError;
use crate::io::RecordingFile;
use mcap::records::Record;
use std::io::Read;
use std::path::Path;

/// The first bytes of an MCAP file.
pub(crate) const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// A channel: a topic, its schema name and message encoding.
#[derive(Clone, Debug)]
pub(crate) struct McapChannel {
    pub id: u16,
    pub topic: String,
    pub schema: String,
    pub encoding: String,
}

/// Reads a message's header stamp from its log time and data: `None` leaves the message
/// out, `Some(None)` keeps it without a stamp (not wanted).
pub(crate) type StampReader<'a> =
    dyn FnMut(i64, &[u8]) -> Result<Option<Option<i64>>, RosError> + 'a;

/// A chunk of an MCAP file.
#[derive(Clone, Debug)]
pub(crate) struct McapChunk {
    /// Where the chunk record starts, and its length with opcode and length.
    start: u64,
    length: u64,
    /// Its records' bytes, as the index says (0: not known, the chunk's header tells).
    uncompressed: u64,
    /// The channels the file's message indexes list in it (empty: not indexed).
    channels: Vec<u16>,
    /// Log times of its first and last messages, when known.
    pub times: Option<(i64, i64)>,
}

impl McapChunk {
    pub fn offset(&self) -> u64 {
        self.start
    }

    /// Whether the chunk may hold messages of `channels`.
    pub fn may_hold(&self, channels: &[u16]) -> bool {
        self.channels.is_empty() || self.channels.iter().any(|c| channels.contains(c))
    }
}

/// An opened MCAP file.
#[derive(Debug)]
pub(crate) struct McapFile {
    pub file: RecordingFile,
    pub channels: Vec<McapChannel>,
    /// In file order.
    pub chunks: Vec<McapChunk>,
    /// Chunks that did not read while scanning a file without a summary (with `skip_bad`;
    /// otherwise opening fails), and why.
    pub damaged: Vec<(McapChunk, RosError)>,
    /// What the reader tolerated (a missing summary).
    pub warnings: Vec<String>,
}

/// One message of an MCAP file: its log time, where it is, and its first bytes.
#[derive(Clone, Debug)]
pub(crate) struct McapMessage {
    pub log_ns: i64,
    /// Index of its chunk in the file's chunk list.
    pub chunk: usize,
    /// Its place among the chunk's records.
    pub record: usize,
}

fn mcap_error(path: &Path) -> impl Fn(mcap::McapError) -> RosError + '_ {
    move |source| RosError::Mcap {
        path: path.to_path_buf(),
        source,
    }
}

/// What a scan of the records learns of channels: schema names by id, and channels.
#[derive(Default)]
struct Found {
    schemas: Vec<(u16, String)>,
    channels: Vec<(u16, String, u16, String)>,
}

impl Found {
    fn add(&mut self, record: &Record<'_>) {
        match record {
            Record::Schema { header, .. }
                if !self.schemas.iter().any(|(id, _)| *id == header.id) =>
            {
                self.schemas.push((header.id, header.name.clone()));
            }
            Record::Channel(c) if !self.channels.iter().any(|(id, ..)| *id == c.id) => {
                self.channels.push((
                    c.id,
                    c.topic.clone(),
                    c.schema_id,
                    c.message_encoding.clone(),
                ));
            }
            _ => {}
        }
    }

    /// The channels found, by id, with their schemas' names.
    fn channels(self) -> Vec<McapChannel> {
        let mut channels: Vec<McapChannel> = self
            .channels
            .into_iter()
            .map(|(id, topic, schema_id, encoding)| McapChannel {
                id,
                topic,
                schema: self
                    .schemas
                    .iter()
                    .find(|(s, _)| *s == schema_id)
                    .map(|(_, name)| name.clone())
                    .unwrap_or_default(),
                encoding,
            })
            .collect();
        channels.sort_by_key(|c| c.id);
        channels
    }
}

impl McapFile {
    /// Opens an MCAP file from its summary; a file without one (its writer did not finish,
    /// or it is cut) is read chunk by chunk up to the first incomplete record, with a
    /// warning saying what was lost. A chunk that does not read during that scan fails the
    /// opening, or with `skip_bad` is left out and listed in [`McapFile::damaged`].
    pub fn open(path: &Path, limit: u64, skip_bad: bool) -> Result<Self, RosError> {
        let file = RecordingFile::open(path)?;
        if file.read_at(0, MAGIC.len() as u64, "MCAP magic")? != MAGIC {
            return Err(file.malformed("MCAP file", "it does not start with the MCAP magic"));
        }
        let mut mcap = Self {
            file,
            channels: Vec::new(),
            chunks: Vec::new(),
            damaged: Vec::new(),
            warnings: Vec::new(),
        };
        let why = match read_summary(&mcap.file, limit) {
            Ok(Some(summary)) => {
                mcap.read_summary_index(summary)?;
                return Ok(mcap);
            }
            Ok(None) => "no summary (its writer did not finish it, or it is cut)".to_string(),
            Err(RosError::Mcap { source, .. }) => {
                format!("its summary does not read ({source})")
            }
            Err(e) => format!(
                "its summary does not read ({})",
                froctomap_core::error_message(&e)
            ),
        };
        mcap.scan(limit, skip_bad, &why)?;
        Ok(mcap)
    }

    /// Channels and chunks from the summary.
    fn read_summary_index(&mut self, summary: Summary) -> Result<(), RosError> {
        self.channels = summary.found.channels();
        self.chunks = summary
            .chunks
            .iter()
            .map(|c| McapChunk {
                start: c.chunk_start_offset,
                length: c.chunk_length,
                uncompressed: c.uncompressed_size,
                channels: c.message_index_offsets.keys().copied().collect(),
                times: i64::try_from(c.message_start_time)
                    .ok()
                    .zip(i64::try_from(c.message_end_time).ok()),
            })
            .collect();
        self.chunks.sort_by_key(|c| c.start);
        if self.chunks.is_empty() && summary.message_count.is_some_and(|n| n > 0) {
            return Err(self
                .file
                .malformed("MCAP file", "messages outside chunks are not indexed"));
        }
        Ok(())
    }

    /// Reads the records after the magic in order (as `mcap recover` does): schemas and
    /// channels wherever they are, each chunk decompressed for the ones inside it and its
    /// messages' times. Stops at the data end or footer, or at the first record the file
    /// cuts off (what follows is lost, and said so in a warning).
    fn scan(&mut self, limit: u64, skip_bad: bool, why: &str) -> Result<(), RosError> {
        let mut found = Found::default();
        let mut pos = MAGIC.len() as u64;
        let mut unchunked = 0usize;
        let mut messages = 0usize;
        let stop = loop {
            if pos >= self.file.size {
                break Some(None);
            }
            let Ok(head) = self.file.read_at(pos, 9, "record") else {
                break Some(Some("is cut off".to_string()));
            };
            let opcode = head[0];
            let len = u64::from_le_bytes([
                head[1], head[2], head[3], head[4], head[5], head[6], head[7], head[8],
            ]);
            let Some(end) = (pos + 9)
                .checked_add(len)
                .filter(|&end| end <= self.file.size)
            else {
                break Some(Some("is cut off".to_string()));
            };
            match opcode {
                mcap::records::op::DATA_END | mcap::records::op::FOOTER => break None,
                mcap::records::op::SCHEMA | mcap::records::op::CHANNEL => {
                    let record = self
                        .file
                        .bounded("schema or channel record", len, limit)
                        .and_then(|len| self.file.read_at(pos + 9, len, "record"))
                        .and_then(|body| {
                            parse_record(&self.file, opcode, &body).map(|r| found.add(&r))
                        });
                    if let Err(e) = record {
                        break Some(Some(format!(
                            "does not read ({})",
                            froctomap_core::error_message(&e)
                        )));
                    }
                }
                mcap::records::op::MESSAGE => unchunked += 1,
                mcap::records::op::CHUNK => {
                    let mut chunk = McapChunk {
                        start: pos,
                        length: end - pos,
                        uncompressed: 0,
                        channels: Vec::new(),
                        times: None,
                    };
                    let mut times: Option<(i64, i64)> = None;
                    let mut count = 0usize;
                    let read = self.each_record(&chunk, limit, &mut |record, _| {
                        found.add(&record);
                        if let Record::Message { header, .. } = record {
                            count += 1;
                            if let Ok(t) = i64::try_from(header.log_time) {
                                times = Some(times.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
                            }
                        }
                        Ok(true)
                    });
                    chunk.times = times;
                    match read {
                        Ok(()) => {
                            messages += count;
                            self.chunks.push(chunk);
                        }
                        Err(problem) if skip_bad => self.damaged.push((chunk, problem)),
                        Err(problem) => {
                            return Err(RosError::DamagedChunk {
                                offset: pos,
                                topic: None,
                                times: None,
                                problem: Box::new(problem),
                            })
                        }
                    }
                }
                _ => {}
            }
            pos = end;
        };
        if unchunked > 0 {
            return Err(self
                .file
                .malformed("MCAP file", "messages outside chunks are not read"));
        }
        self.channels = found.channels();
        let read = format!(
            "{} chunk(s) with {messages} message(s) read in order",
            self.chunks.len()
        );
        self.warnings.push(match stop {
            None => format!("{why}; {read}, to the end of its data (`mcap recover` writes the summary)"),
            Some(None) => format!("{why}; {read}; it ends after them, without the summary (`mcap recover` writes it)"),
            Some(Some(how)) => format!(
                "{why}; {read}; the record at byte {pos} {how}, so its last {} of {} bytes are not read (`mcap recover` recovers the same)",
                self.file.size - pos,
                self.file.size
            ),
        });
        Ok(())
    }

    /// The messages of `channels` in chunk `i`, with the header stamp `stamp` reads from
    /// each one's data (`stamp` may leave a message out).
    pub fn chunk_messages(
        &self,
        i: usize,
        channels: &[u16],
        limit: u64,
        stamp: &mut StampReader<'_>,
    ) -> Result<Vec<(McapMessage, Option<i64>)>, RosError> {
        let mut out = Vec::new();
        let chunk = self
            .chunks
            .get(i)
            .ok_or_else(|| self.file.malformed("chunk index", "no such chunk"))?;
        self.each_record(chunk, limit, &mut |record, index| {
            if let Record::Message { header, data } = record {
                if channels.contains(&header.channel_id) {
                    let log_ns = i64::try_from(header.log_time).map_err(|_| {
                        self.file
                            .malformed("message", "a log time past the year 2262")
                    })?;
                    if let Some(stamp) = stamp(log_ns, &data)? {
                        let found = McapMessage {
                            log_ns,
                            chunk: i,
                            record: index,
                        };
                        out.push((found, stamp));
                    }
                }
            }
            Ok(true)
        })?;
        Ok(out)
    }

    /// The records of chunk `i`, decompressed and checked (its CRC), for
    /// [`McapFile::message_in`].
    pub fn records(&self, i: usize, limit: u64) -> Result<Vec<u8>, RosError> {
        let chunk = self
            .chunks
            .get(i)
            .ok_or_else(|| self.file.malformed("chunk index", "no such chunk"))?;
        self.chunk_records(chunk, limit)
    }

    /// The data of the message at `found` in `records`, its chunk's records.
    pub fn message_in(&self, records: &[u8], found: &McapMessage) -> Result<Vec<u8>, RosError> {
        let mut data = None;
        self.walk(records, &mut |record, index| {
            if index < found.record {
                return Ok(true);
            }
            if let Record::Message { data: bytes, .. } = record {
                data = Some(bytes.into_owned());
            }
            Ok(false)
        })?;
        data.ok_or_else(|| {
            self.file
                .malformed("chunk", "a message is missing from its chunk")
        })
    }

    /// Calls `on_record` with each record of `chunk` and its place, while it returns `true`.
    fn each_record(
        &self,
        chunk: &McapChunk,
        limit: u64,
        on_record: &mut dyn FnMut(Record<'_>, usize) -> Result<bool, RosError>,
    ) -> Result<(), RosError> {
        let records = self.chunk_records(chunk, limit)?;
        self.walk(&records, on_record)
    }

    /// The records of `chunk`, decompressed to the size its header gives (at most `limit`)
    /// and checked against its CRC.
    fn chunk_records(&self, chunk: &McapChunk, limit: u64) -> Result<Vec<u8>, RosError> {
        self.file
            .bounded("uncompressed chunk", chunk.uncompressed, limit)?;
        // Compressed data may be a little longer than what it holds.
        self.file.bounded(
            "chunk",
            chunk.length,
            limit.saturating_add(limit / 64 + 4096),
        )?;
        let bytes = self.file.read_at(chunk.start, chunk.length, "chunk")?;
        let body = bytes
            .get(9..)
            .filter(|_| bytes.first() == Some(&mcap::records::op::CHUNK))
            .ok_or_else(|| {
                self.file
                    .malformed("chunk index", "it does not point at a chunk")
            })?;
        let Record::Chunk { header, data } =
            parse_record(&self.file, mcap::records::op::CHUNK, body)?
        else {
            return Err(self.file.malformed("chunk", "not a chunk record"));
        };
        let size = self
            .file
            .bounded("uncompressed chunk", header.uncompressed_size, limit)?;
        let records = self.decompress(&header.compression, &data, size)?;
        if header.uncompressed_crc != 0 && crc32fast::hash(&records) != header.uncompressed_crc {
            return Err(self
                .file
                .malformed("chunk", "its records do not match their CRC"));
        }
        Ok(records)
    }

    /// Calls `on_record` with each of `records` and its place, while it returns `true`.
    fn walk(
        &self,
        records: &[u8],
        on_record: &mut dyn FnMut(Record<'_>, usize) -> Result<bool, RosError>,
    ) -> Result<(), RosError> {
        // The records, each length checked against the chunk before it is used.
        let mut pos = 0usize;
        let mut index = 0usize;
        while pos < records.len() {
            let (opcode, len) = records
                .get(pos..pos + 9)
                .map(|head| {
                    (
                        head[0],
                        u64::from_le_bytes([
                            head[1], head[2], head[3], head[4], head[5], head[6], head[7], head[8],
                        ]),
                    )
                })
                .ok_or_else(|| self.file.malformed("chunk", "a record header is cut off"))?;
            let body = usize::try_from(len)
                .ok()
                .and_then(|len| records.get(pos + 9..)?.get(..len))
                .ok_or_else(|| self.file.malformed("chunk", "a record runs past its chunk"))?;
            let record = parse_record(&self.file, opcode, body)?;
            if !on_record(record, index)? {
                break;
            }
            pos += 9 + body.len();
            index += 1;
        }
        Ok(())
    }
}

impl McapFile {
    /// A chunk's records, decompressed to exactly `size` bytes.
    fn decompress(&self, compression: &str, data: &[u8], size: u64) -> Result<Vec<u8>, RosError> {
        let bad = |e: std::io::Error| {
            self.file.malformed(
                "chunk",
                format!("{compression} data does not decompress: {e}"),
            )
        };
        let size_usize =
            usize::try_from(size).map_err(|_| self.file.malformed("chunk", "too large"))?;
        let out = match compression {
            "" => data.to_vec(),
            // Decompresses into at most `size` bytes: a longer chunk is an error.
            "zstd" => zstd::bulk::decompress(data, size_usize).map_err(bad)?,
            "lz4" => {
                let mut out = Vec::new();
                lz4::Decoder::new(data)
                    .and_then(|decoder| decoder.take(size + 1).read_to_end(&mut out))
                    .map_err(bad)?;
                out
            }
            other => {
                return Err(RosError::UnsupportedCompression {
                    path: self.file.path.clone(),
                    name: other.to_string(),
                    supported: "none, zstd and lz4",
                })
            }
        };
        if out.len() != size_usize {
            return Err(self.file.malformed(
                "chunk",
                format!("{} bytes uncompressed, the header says {size}", out.len()),
            ));
        }
        Ok(out)
    }
}

/// A record parsed by the `mcap` crate once every length it declares fits its bytes
/// ([`crate::mcap_lengths`]): the crate reserves declared lengths before reading them.
fn parse_record<'a>(
    file: &RecordingFile,
    opcode: u8,
    body: &'a [u8],
) -> Result<Record<'a>, RosError> {
    crate::mcap_lengths::check(opcode, body).map_err(|problem| {
        file.malformed("MCAP record", format!("record {opcode:#04x}: {problem}"))
    })?;
    mcap::parse_record(opcode, body).map_err(mcap_error(&file.path))
}

/// What the summary section says: channels (with their schema names), chunk indexes and
/// the message count.
#[derive(Default)]
struct Summary {
    found: Found,
    chunks: Vec<mcap::records::ChunkIndex>,
    message_count: Option<u64>,
}

/// The summary section, found from the footer (`None` when the file has none), its records
/// read one at a time with every length checked before the `mcap` crate parses it (at most
/// `limit` bytes in all).
fn read_summary(file: &RecordingFile, limit: u64) -> Result<Option<Summary>, RosError> {
    use mcap::records::op;
    // The footer record (opcode, length 20, body) before the closing magic.
    const FOOTER: u64 = 1 + 8 + 20;
    let tail = FOOTER + MAGIC.len() as u64;
    let footer_at = file
        .size
        .checked_sub(tail)
        .filter(|&at| at >= MAGIC.len() as u64)
        .ok_or_else(|| file.truncated("MCAP footer"))?;
    let footer = file.read_at(footer_at, tail, "MCAP footer")?;
    if footer[0] != op::FOOTER || footer[1..9] != 20u64.to_le_bytes() || footer[29..] != *MAGIC {
        return Err(file.malformed("MCAP footer", "the file does not end with one"));
    }
    let Record::Footer(f) = parse_record(file, op::FOOTER, &footer[9..29])? else {
        return Err(file.malformed("MCAP footer", "not a footer record"));
    };
    if f.summary_start == 0 {
        return Ok(None);
    }
    let len = footer_at
        .checked_sub(f.summary_start)
        .filter(|_| f.summary_start >= MAGIC.len() as u64)
        .ok_or_else(|| file.malformed("MCAP footer", "the summary starts after it"))?;
    let len = file.bounded("MCAP summary section", len, limit)?;
    let section = file.read_at(f.summary_start, len, "MCAP summary section")?;
    if f.summary_crc != 0 {
        let mut crc = crc32fast::Hasher::new();
        crc.update(&section);
        crc.update(&footer[..9 + 16]);
        if crc.finalize() != f.summary_crc {
            return Err(file.malformed("MCAP summary", "it does not match its CRC"));
        }
    }
    let mut summary = Summary::default();
    let mut rest = &section[..];
    while !rest.is_empty() {
        let (head, after) = rest
            .split_first_chunk::<9>()
            .ok_or_else(|| file.malformed("MCAP summary", "a record header is cut off"))?;
        let body = usize::try_from(u64::from_le_bytes([
            head[1], head[2], head[3], head[4], head[5], head[6], head[7], head[8],
        ]))
        .ok()
        .and_then(|len| after.get(..len))
        .ok_or_else(|| file.malformed("MCAP summary", "a record runs past the section"))?;
        rest = &after[body.len()..];
        match parse_record(file, head[0], body)? {
            Record::ChunkIndex(index) => summary.chunks.push(index),
            Record::Statistics(stats) => summary.message_count = Some(stats.message_count),
            record => summary.found.add(&record),
        }
    }
    Ok(Some(summary))
}
