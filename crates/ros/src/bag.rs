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

use crate::error::RosError;
use crate::io::RecordingFile;
use std::io::Read;
use std::path::Path;

/// The first bytes of a bag.
pub(crate) const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

const OP_MESSAGE: u8 = 0x02;
const OP_BAG_HEADER: u8 = 0x03;
const OP_INDEX: u8 = 0x04;
const OP_CHUNK: u8 = 0x05;
const OP_CHUNK_INFO: u8 = 0x06;
const OP_CONNECTION: u8 = 0x07;

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

/// An opened bag: its connections and chunks, from its index.
#[derive(Debug)]
pub(crate) struct Bag {
    pub file: RecordingFile,
    pub connections: Vec<Connection>,
    /// Chunk positions with the connections that have messages in them.
    chunks: Vec<(u64, Vec<u32>)>,
}

/// One message of a bag: its log time and where its record is.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BagMessage {
    pub log_ns: i64,
    pub chunk_pos: u64,
    pub offset: u32,
}

impl Bag {
    pub fn open(path: &Path) -> Result<Self, RosError> {
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
        if index_pos < header.end() || index_pos >= file.size {
            return Err(file.malformed(
                "bag header",
                format!("index position {index_pos} is outside the file (an unindexed bag: run `rosbag reindex`)"),
            ));
        }
        let mut bag = Bag {
            file,
            connections: Vec::new(),
            chunks: Vec::new(),
        };
        let mut pos = index_pos;
        while pos < bag.file.size {
            let record = read_record(&bag.file, pos, "index record")?;
            let fields = Fields::parse(&bag.file, &record.header)?;
            match fields.op() {
                Some(OP_CONNECTION) => {
                    let data =
                        bag.file
                            .read_at(record.data_offset, record.data_len, "connection")?;
                    let connection = Fields::parse(&bag.file, &data)?;
                    bag.connections.push(Connection {
                        id: fields.u32(&bag.file, "conn")?,
                        topic: fields.text("topic"),
                        type_name: connection.text("type"),
                    });
                }
                Some(OP_CHUNK_INFO) => {
                    let data =
                        bag.file
                            .read_at(record.data_offset, record.data_len, "chunk info")?;
                    let connections = data
                        .chunks_exact(8)
                        .filter_map(|pair| pair[..4].try_into().ok().map(u32::from_le_bytes))
                        .collect();
                    bag.chunks
                        .push((fields.u64(&bag.file, "chunk_pos")?, connections));
                }
                _ => {}
            }
            pos = record.end();
        }
        bag.chunks.sort_by_key(|(p, _)| *p);
        Ok(bag)
    }

    /// The messages of `connections`, from the index data after each chunk (no chunk is
    /// decompressed), in file order.
    pub fn messages(&self, connections: &[u32]) -> Result<Vec<BagMessage>, RosError> {
        let mut out = Vec::new();
        for (chunk_pos, present) in &self.chunks {
            if !present.iter().any(|c| connections.contains(c)) {
                continue;
            }
            let chunk = read_record(&self.file, *chunk_pos, "chunk")?;
            let mut pos = chunk.end();
            while pos < self.file.size {
                let record = read_record(&self.file, pos, "index data")?;
                let fields = Fields::parse(&self.file, &record.header)?;
                if fields.op() != Some(OP_INDEX) {
                    break;
                }
                if connections.contains(&fields.u32(&self.file, "conn")?) {
                    let data =
                        self.file
                            .read_at(record.data_offset, record.data_len, "index data")?;
                    for entry in data.chunks_exact(12) {
                        let word = |i: usize| {
                            u32::from_le_bytes([entry[i], entry[i + 1], entry[i + 2], entry[i + 3]])
                        };
                        out.push(BagMessage {
                            log_ns: i64::from(word(0)) * 1_000_000_000 + i64::from(word(4)),
                            chunk_pos: *chunk_pos,
                            offset: word(8),
                        });
                    }
                }
                pos = record.end();
            }
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
