//! MCAP files, read through the `mcap` crate: the summary section (channels, schemas, chunk
//! indexes) found from the footer, then one chunk at a time, so memory holds one chunk.

use crate::error::RosError;
use crate::io::RecordingFile;
use mcap::records::Record;
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use std::io::{Read, Seek};
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

/// Reads a message's header stamp from its log time and data (`None`: not wanted).
pub(crate) type StampReader<'a> = dyn FnMut(i64, &[u8]) -> Result<Option<i64>, RosError> + 'a;

/// An opened MCAP file.
#[derive(Debug)]
pub(crate) struct McapFile {
    pub file: RecordingFile,
    pub channels: Vec<McapChannel>,
    /// (chunk start offset, chunk record length, uncompressed size, channels indexed in it
    /// — empty when the file has no message indexes), in file order.
    chunks: Vec<(u64, u64, u64, Vec<u16>)>,
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

impl McapFile {
    pub fn open(path: &Path) -> Result<Self, RosError> {
        let file = RecordingFile::open(path)?;
        if file.read_at(0, MAGIC.len() as u64, "MCAP magic")? != MAGIC {
            return Err(file.malformed("MCAP file", "it does not start with the MCAP magic"));
        }
        let summary = read_summary(&file)?.ok_or_else(|| RosError::NoSummary {
            path: path.to_path_buf(),
        })?;
        let mut channels: Vec<McapChannel> = summary
            .channels
            .values()
            .map(|c| McapChannel {
                id: c.id,
                topic: c.topic.clone(),
                schema: c
                    .schema
                    .as_ref()
                    .map(|s| s.name.clone())
                    .unwrap_or_default(),
                encoding: c.message_encoding.clone(),
            })
            .collect();
        channels.sort_by_key(|c| c.id);
        let mut chunks: Vec<(u64, u64, u64, Vec<u16>)> = summary
            .chunk_indexes
            .iter()
            .map(|c| {
                let indexed = c.message_index_offsets.keys().copied().collect();
                (
                    c.chunk_start_offset,
                    c.chunk_length,
                    c.uncompressed_size,
                    indexed,
                )
            })
            .collect();
        chunks.sort_by_key(|c| c.0);
        if chunks.is_empty() && summary.stats.is_some_and(|s| s.message_count > 0) {
            return Err(file.malformed("MCAP file", "messages outside chunks are not indexed"));
        }
        Ok(Self {
            file,
            channels,
            chunks,
        })
    }

    /// The messages of `channels`, in file order, with the header stamp `stamp` reads from
    /// each one's data (decompressing one chunk at a time).
    pub fn messages(
        &self,
        channels: &[u16],
        limit: u64,
        stamp: &mut StampReader<'_>,
    ) -> Result<Vec<(McapMessage, Option<i64>)>, RosError> {
        let mut out = Vec::new();
        for (i, (_, _, _, indexed)) in self.chunks.iter().enumerate() {
            if !indexed.is_empty() && !indexed.iter().any(|c| channels.contains(c)) {
                continue;
            }
            self.each_record(i, limit, &mut |record, index| {
                if let Record::Message { header, data } = record {
                    if channels.contains(&header.channel_id) {
                        let log_ns = i64::try_from(header.log_time).map_err(|_| {
                            self.file
                                .malformed("message", "a log time past the year 2262")
                        })?;
                        let found = McapMessage {
                            log_ns,
                            chunk: i,
                            record: index,
                        };
                        out.push((found, stamp(log_ns, &data)?));
                    }
                }
                Ok(true)
            })?;
        }
        Ok(out)
    }

    /// The data of the message at `found`.
    pub fn message(&self, found: &McapMessage, limit: u64) -> Result<Vec<u8>, RosError> {
        let mut data = None;
        self.each_record(found.chunk, limit, &mut |record, index| {
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

    /// Calls `on_record` with each record of chunk `i` and its place, while it returns `true`.
    fn each_record(
        &self,
        i: usize,
        limit: u64,
        on_record: &mut dyn FnMut(Record<'_>, usize) -> Result<bool, RosError>,
    ) -> Result<(), RosError> {
        let Some(&(start, length, uncompressed, _)) = self.chunks.get(i) else {
            return Err(self.file.malformed("chunk index", "no such chunk"));
        };
        self.file
            .bounded("uncompressed chunk", uncompressed, limit)?;
        let bytes = self.file.read_at(start, length, "chunk")?;
        let body = bytes
            .get(9..)
            .filter(|_| bytes.first() == Some(&mcap::records::op::CHUNK))
            .ok_or_else(|| {
                self.file
                    .malformed("chunk index", "it does not point at a chunk")
            })?;
        let to_error = mcap_error(&self.file.path);
        let Record::Chunk { header, data } =
            mcap::parse_record(mcap::records::op::CHUNK, body).map_err(&to_error)?
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
            let record = mcap::parse_record(opcode, body).map_err(&to_error)?;
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

/// The summary section, found from the footer; `None` when the file has none.
fn read_summary(file: &RecordingFile) -> Result<Option<mcap::Summary>, RosError> {
    let to_error = mcap_error(&file.path);
    let io = |source| RosError::Io {
        path: file.path.clone(),
        source,
    };
    let mut reader = SummaryReader::new_with_options(
        SummaryReaderOptions::default()
            .with_file_size(file.size)
            .with_record_length_limit(usize::try_from(file.size).unwrap_or(usize::MAX)),
    );
    let mut handle = file.file();
    while let Some(event) = reader.next_event() {
        match event.map_err(&to_error)? {
            SummaryReadEvent::ReadRequest(need) => {
                let read = handle.read(reader.insert(need)).map_err(io)?;
                reader.notify_read(read);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let pos = handle.seek(to).map_err(io)?;
                reader.notify_seeked(pos);
            }
        }
    }
    Ok(reader.finish())
}
