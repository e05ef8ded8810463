//! ROS 2 bags with sqlite3 storage (rosbag2's default up to Humble): one SQLite database per
//! split (`*.db3`), its `topics` and `messages` tables, read through `rusqlite` (SQLite
//! itself, bundled).
//!
//! * Compression as rosbag2 writes it (`metadata.yaml`): none, `message` (each message's
//!   data a zstd frame) or `file` (each database a zstd file `*.db3.zstd`, decompressed into
//!   a locked temporary directory, removed with the recording); any other mode or format is
//!   [`RosError::UnsupportedBagCompression`].
//! * Hostile databases: opened read-only and immutable (nothing beside them is created or
//!   changed), `messages` and `topics` must be tables with rosbag2's columns (a view could
//!   run any query), SQLite's own length limit is the largest map, and a message's data is
//!   read through incremental blob I/O after its declared length was checked against that
//!   limit and the database's size, so a declared length costs nothing until it is read.
//!   A compressed file decompresses to at most [`MAX_FILE_RATIO`] times its size.

use crate::bag_metadata::BagMetadata;
use crate::error::RosError;
use crate::message::{decode_stamp, Encoding, MessageType};
use crate::source::{message_map_file, select_topic, times, Damage, TopicEntry};
use crate::topic_counts::{Span, TopicKey};
use froctomap_core::calendar::iso8601;
use froctomap_core::{temporary_dir_in, Timestamp};
use froctomap_formats::{PluginError as Cause, RecordedMaps, Recording, RecordingOptions};
use rusqlite::limits::Limit;
use rusqlite::{Connection, OpenFlags};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// The most a `file`-compressed database may grow when decompressed (a zstd "bomb" of a few
/// kilobytes cannot fill the disk; SQLite pages of maps compress far less).
pub(crate) const MAX_FILE_RATIO: u64 = 1000;

/// Where `file`-compressed databases are decompressed (in the spool directory).
const SPOOL_PREFIX: &str = ".froct-bag-";

/// Enough of a message's start for its header stamp (CDR: encapsulation, sec, nanosec).
const STAMP_BYTES: u64 = 64;

/// How the bag's messages are compressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Compression {
    None,
    Message,
    File,
}

/// The compression `metadata` names, if this reader reads it.
fn compression(dir: &Path, metadata: &BagMetadata) -> Result<Compression, RosError> {
    let unsupported = || RosError::UnsupportedBagCompression {
        path: dir.to_path_buf(),
        mode: metadata.compression_mode.clone(),
        format: metadata.compression_format.clone(),
    };
    let zstd = metadata.compression_format == "zstd";
    match metadata.compression_mode.as_str() {
        "" => Ok(Compression::None),
        "message" if zstd => Ok(Compression::Message),
        "file" if zstd => Ok(Compression::File),
        _ => Err(unsupported()),
    }
}

/// One database of the bag.
pub(crate) struct Database {
    /// The storage file as the bag names it (`*.db3` or `*.db3.zstd`).
    path: PathBuf,
    /// Its (decompressed) size: no blob is longer.
    size: u64,
    connection: Mutex<Connection>,
}

impl std::fmt::Debug for Database {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Database")
            .field("path", &self.path)
            .finish()
    }
}

impl Database {
    fn sqlite_error(&self) -> impl Fn(rusqlite::Error) -> RosError + '_ {
        |source| RosError::Sqlite {
            path: self.path.clone(),
            source,
        }
    }

    /// Opens `file` (the database itself, perhaps decompressed from `path`) read-only.
    fn open(path: &Path, file: &Path, limit: u64) -> Result<Self, RosError> {
        let sqlite = |source| RosError::Sqlite {
            path: path.to_path_buf(),
            source,
        };
        let size = std::fs::metadata(file)
            .map_err(|source| RosError::Io {
                path: path.to_path_buf(),
                source,
            })?
            .len();
        // `immutable`: no lock, journal or WAL file is looked for or made beside the input.
        let connection = Connection::open_with_flags(
            immutable_uri(file),
            OpenFlags::SQLITE_OPEN_READ_ONLY
                | OpenFlags::SQLITE_OPEN_URI
                | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(sqlite)?;
        let longest = i32::try_from(limit.saturating_add(STAMP_BYTES)).unwrap_or(i32::MAX);
        connection
            .set_limit(Limit::SQLITE_LIMIT_LENGTH, longest)
            .map_err(sqlite)?;
        connection
            .execute_batch("PRAGMA trusted_schema = OFF; PRAGMA cell_size_check = ON;")
            .map_err(sqlite)?;
        let database = Self {
            path: path.to_path_buf(),
            size,
            connection: Mutex::new(connection),
        };
        database.check_schema()?;
        Ok(database)
    }

    fn connection(&self) -> std::sync::MutexGuard<'_, Connection> {
        self.connection.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// `topics` and `messages` are tables with the columns rosbag2 writes (every schema
    /// version has these).
    fn check_schema(&self) -> Result<(), RosError> {
        let connection = self.connection();
        for (table, wanted) in [
            (
                "topics",
                &["id", "name", "type", "serialization_format"][..],
            ),
            ("messages", &["topic_id", "timestamp", "data"][..]),
        ] {
            let kind: Option<String> = connection
                .query_row(
                    "SELECT type FROM sqlite_master WHERE name = ?1",
                    [table],
                    |row| row.get(0),
                )
                .map(Some)
                .or_else(|e| match e {
                    rusqlite::Error::QueryReturnedNoRows => Ok(None),
                    e => Err(e),
                })
                .map_err(self.sqlite_error())?;
            let malformed = |problem: String| RosError::Malformed {
                path: self.path.clone(),
                what: "rosbag2 sqlite3 storage",
                problem,
            };
            if kind.as_deref() != Some("table") {
                return Err(malformed(format!(
                    "no table `{table}` (not a rosbag2 database)"
                )));
            }
            let mut columns = connection
                .prepare("SELECT name FROM pragma_table_info(?1)")
                .map_err(self.sqlite_error())?;
            let columns: Vec<String> = columns
                .query_map([table], |row| row.get(0))
                .and_then(|rows| rows.collect())
                .map_err(self.sqlite_error())?;
            if let Some(missing) = wanted.iter().find(|c| !columns.iter().any(|n| n == *c)) {
                return Err(malformed(format!(
                    "table `{table}` has no column `{missing}` (not a rosbag2 database)"
                )));
            }
        }
        Ok(())
    }

    /// The topics: id, name, type, serialization format.
    fn topics(&self) -> Result<Vec<(i64, String, String, String)>, RosError> {
        let connection = self.connection();
        let mut statement = connection
            .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
            .map_err(self.sqlite_error())?;
        let rows = statement
            .query_map([], |row| {
                Ok((row.get(0)?, row.get(1)?, row.get(2)?, row.get(3)?))
            })
            .and_then(|rows| rows.collect())
            .map_err(self.sqlite_error());
        rows
    }

    /// Every topic with its message count and first and last log times: name, type,
    /// serialization format, count, span.
    pub(crate) fn topic_counts(&self) -> Result<Vec<(TopicKey, u64, Span)>, RosError> {
        let connection = self.connection();
        let mut statement = connection
            .prepare(
                "SELECT topics.name, topics.type, topics.serialization_format, count(messages.topic_id), \
                 min(messages.timestamp), max(messages.timestamp) \
                 FROM topics LEFT JOIN messages ON messages.topic_id = topics.id GROUP BY topics.id",
            )
            .map_err(self.sqlite_error())?;
        let rows = statement
            .query_map([], |row| {
                let first: Option<i64> = row.get(4)?;
                let last: Option<i64> = row.get(5)?;
                Ok((
                    (row.get(0)?, row.get(1)?, row.get(2)?),
                    row.get::<_, i64>(3)?.max(0) as u64,
                    first.zip(last),
                ))
            })
            .and_then(|rows| rows.collect())
            .map_err(self.sqlite_error());
        rows
    }

    /// The messages of the topics `ids`: row id and log time, in log-time order.
    fn messages(&self, ids: &[i64]) -> Result<Vec<(i64, i64)>, RosError> {
        let connection = self.connection();
        let marks = vec!["?"; ids.len()].join(",");
        let mut statement = connection
            .prepare(&format!(
                "SELECT rowid, timestamp FROM messages WHERE topic_id IN ({marks}) ORDER BY timestamp, rowid"
            ))
            .map_err(self.sqlite_error())?;
        let rows = statement
            .query_map(rusqlite::params_from_iter(ids), |row| {
                Ok((row.get(0)?, row.get(1)?))
            })
            .and_then(|rows| rows.collect())
            .map_err(self.sqlite_error());
        rows
    }

    /// The first `most` bytes of message `rowid`'s data, decompressed when `compressed` (a
    /// whole message: `most` is the largest map).
    fn data(
        &self,
        rowid: i64,
        compressed: bool,
        most: u64,
        whole: bool,
    ) -> Result<Vec<u8>, RosError> {
        let connection = self.connection();
        let blob = connection
            .blob_open(rusqlite::MAIN_DB, "messages", "data", rowid, true)
            .map_err(self.sqlite_error())?;
        let declared = blob.len() as u64;
        if declared > self.size {
            return Err(RosError::Malformed {
                path: self.path.clone(),
                what: "message",
                problem: format!(
                    "its data claims {declared} bytes, more than the database's {}",
                    self.size
                ),
            });
        }
        let io = |source| RosError::Io {
            path: self.path.clone(),
            source,
        };
        if !compressed {
            if whole && declared > most {
                return Err(RosError::TooLarge {
                    path: self.path.clone(),
                    what: "map message",
                    bytes: declared,
                    limit: most,
                });
            }
            let mut out = Vec::new();
            blob.take(most).read_to_end(&mut out).map_err(io)?;
            return Ok(out);
        }
        let mut out = Vec::new();
        let read = zstd::stream::read::Decoder::new(blob)
            .and_then(|decoder| decoder.take(most.saturating_add(1)).read_to_end(&mut out));
        match read {
            // A start is all that was wanted: a frame cut after it does not matter here.
            Err(_) if !whole && out.len() as u64 >= most => {}
            Err(e) => {
                return Err(RosError::Malformed {
                    path: self.path.clone(),
                    what: "message",
                    problem: format!("its zstd data does not decompress: {e}"),
                })
            }
            Ok(_) => {}
        }
        if out.len() as u64 > most {
            if whole {
                return Err(RosError::TooLarge {
                    path: self.path.clone(),
                    what: "decompressed map message",
                    bytes: out.len() as u64,
                    limit: most,
                });
            }
            out.truncate(usize::try_from(most).unwrap_or(usize::MAX));
        }
        Ok(out)
    }
}

/// `file:PATH?immutable=1`, the path percent-encoded (any byte but unreserved ones and `/`).
fn immutable_uri(path: &Path) -> String {
    use std::os::unix::ffi::OsStrExt;
    let mut uri = String::from("file:");
    for &byte in path.as_os_str().as_bytes() {
        if byte.is_ascii_alphanumeric() || b"/-._~".contains(&byte) {
            uri.push(char::from(byte));
        } else {
            uri.push_str(&format!("%{byte:02X}"));
        }
    }
    uri.push_str("?immutable=1");
    uri
}

/// Decompresses the zstd file `path` into `dir`, refusing more than [`MAX_FILE_RATIO`] times
/// its size.
fn decompress_file(path: &Path, dir: &Path, index: usize) -> Result<PathBuf, RosError> {
    let io = |source| RosError::Io {
        path: path.to_path_buf(),
        source,
    };
    let input = std::fs::File::open(path).map_err(io)?;
    let size = input.metadata().map_err(io)?.len();
    let most = size.saturating_mul(MAX_FILE_RATIO).saturating_add(1 << 20);
    let out_path = dir.join(format!("{index}.db3"));
    let mut out = std::fs::File::create(&out_path).map_err(|source| RosError::Io {
        path: out_path.clone(),
        source,
    })?;
    let copied = zstd::stream::read::Decoder::new(input)
        .and_then(|decoder| std::io::copy(&mut decoder.take(most + 1), &mut out))
        .map_err(|e| RosError::Malformed {
            path: path.to_path_buf(),
            what: "zstd-compressed database",
            problem: format!("it does not decompress: {e}"),
        })?;
    if copied > most {
        return Err(RosError::TooLarge {
            path: path.to_path_buf(),
            what: "decompressed database",
            bytes: copied,
            limit: most,
        });
    }
    Ok(out_path)
}

/// One map: its database, row and log time.
#[derive(Clone, Copy, Debug)]
struct SqliteMap {
    database: usize,
    rowid: i64,
    log_ns: i64,
}

/// The maps of one topic of a sqlite3 bag.
#[derive(Debug)]
struct SqliteMaps {
    path: PathBuf,
    topic: String,
    kind: MessageType,
    compressed: bool,
    databases: Vec<Database>,
    maps: Vec<SqliteMap>,
    /// Holds the decompressed databases of a `file`-compressed bag (removed when dropped,
    /// after the connections).
    _spool: Option<froctomap_core::TemporaryDir>,
}

impl SqliteMaps {
    fn fetch(&self, index: usize, limit: u64) -> Result<Vec<u8>, RosError> {
        let map = self.maps.get(index).ok_or_else(|| RosError::Malformed {
            path: self.path.clone(),
            what: "recording",
            problem: format!("no map {index}"),
        })?;
        let database = self
            .databases
            .get(map.database)
            .ok_or_else(|| RosError::Malformed {
                path: self.path.clone(),
                what: "recording",
                problem: "no such database".into(),
            })?;
        let data = database.data(map.rowid, self.compressed, limit, true)?;
        message_map_file(
            &database.path,
            &self.topic,
            self.kind,
            map.log_ns,
            &data,
            Encoding::Cdr,
            limit,
        )
    }
}

impl RecordedMaps for SqliteMaps {
    fn map_bytes(&self, index: usize, limit: u64) -> Result<Vec<u8>, Cause> {
        Ok(self.fetch(index, limit)?)
    }

    fn topic(&self) -> &str {
        &self.topic
    }
}

/// The storage files of a sqlite3 bag: those `metadata.yaml` lists, else its `.db3` (and
/// `.db3.zstd`) files in name order.
fn storage_files(dir: &Path, metadata: &BagMetadata) -> Result<Vec<PathBuf>, RosError> {
    let listed = metadata.file_paths(dir);
    if !listed.is_empty() {
        return Ok(listed);
    }
    let io = |source| RosError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let file = entry.map_err(io)?.path();
        let name = file.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if name.ends_with(".db3") || name.ends_with(".db3.zstd") {
            files.push(file);
        }
    }
    files.sort_by(|a, b| froctomap_formats::natural_cmp(a, b));
    Ok(files)
}

/// Whether the bag directory `dir` holds sqlite3 storage: `metadata.yaml` says so, or
/// (saying nothing) `.db3` files are there.
pub(crate) fn is_sqlite_bag(dir: &Path, metadata: &BagMetadata) -> bool {
    match metadata.storage.as_str() {
        "sqlite3" => true,
        "" => storage_files(dir, metadata).is_ok_and(|files| {
            files.iter().any(|f| {
                f.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.ends_with(".db3") || n.ends_with(".db3.zstd"))
            })
        }),
        _ => false,
    }
}

/// The opened databases of a sqlite3 bag, and the temporary directory holding decompressed
/// ones.
pub(crate) struct OpenedBag {
    pub databases: Vec<Database>,
    spool: Option<froctomap_core::TemporaryDir>,
    compressed: bool,
}

/// Opens the databases of the sqlite3 bag `dir`.
pub(crate) fn open_databases(
    dir: &Path,
    metadata: &BagMetadata,
    options: &RecordingOptions,
    limit: u64,
) -> Result<OpenedBag, RosError> {
    let compression = compression(dir, metadata)?;
    let files = storage_files(dir, metadata)?;
    if files.is_empty() {
        return Err(RosError::NoStorageInBag {
            path: dir.to_path_buf(),
        });
    }
    let mut spool = None;
    let mut databases = Vec::with_capacity(files.len());
    for (i, path) in files.iter().enumerate() {
        let compressed_file = path.extension().is_some_and(|e| e == "zstd");
        let file = if compressed_file {
            if compression != Compression::File {
                return Err(RosError::UnsupportedBagCompression {
                    path: path.clone(),
                    mode: metadata.compression_mode.clone(),
                    format: "zstd file without `compression_mode: file`".into(),
                });
            }
            if spool.is_none() {
                let parent = options.spool_dir.clone().unwrap_or_else(std::env::temp_dir);
                spool = Some(temporary_dir_in(&parent, SPOOL_PREFIX.as_ref()).map_err(
                    |source| RosError::Io {
                        path: parent.clone(),
                        source,
                    },
                )?);
            }
            let into = spool.as_ref().map(|s| s.path().to_path_buf());
            decompress_file(path, into.as_deref().unwrap_or(dir), i)?
        } else {
            path.clone()
        };
        databases.push(Database::open(path, &file, limit)?);
    }
    Ok(OpenedBag {
        databases,
        spool,
        compressed: compression == Compression::Message,
    })
}

/// Opens a ROS 2 bag directory with sqlite3 storage as a recording of its map topic.
pub(crate) fn open(
    dir: &Path,
    metadata: &BagMetadata,
    options: &RecordingOptions,
    limit: u64,
) -> Result<Recording, RosError> {
    let bag = open_databases(dir, metadata, options, limit)?;
    let mut topics = Vec::new();
    let mut per_database = Vec::with_capacity(bag.databases.len());
    for database in &bag.databases {
        let found = database.topics()?;
        topics.extend(found.iter().map(|(_, name, type_name, _)| TopicEntry {
            topic: name.clone(),
            type_name: type_name.clone(),
        }));
        per_database.push(found);
    }
    let (topic, kind) = select_topic(dir, &topics, options.topic.as_deref())?;
    let header = options.time == froctomap_formats::RecordedTime::Header;
    let mut skipped: Vec<Cause> = Vec::new();
    let mut damage = Damage {
        skip_bad: options.skip_bad,
        skipped: &mut skipped,
    };
    let mut maps = Vec::new();
    let mut stamps = Vec::new();
    for (i, (database, found)) in bag.databases.iter().zip(&per_database).enumerate() {
        let ids: Vec<i64> = found
            .iter()
            .filter(|(_, name, ..)| *name == topic)
            .map(|(id, ..)| *id)
            .collect();
        if ids.is_empty() {
            continue;
        }
        if let Some((.., format)) = found
            .iter()
            .find(|(_, name, _, format)| *name == topic && format != "cdr")
        {
            return Err(RosError::UnsupportedEncoding {
                path: database.path.clone(),
                topic,
                encoding: format.clone(),
            });
        }
        for (rowid, log_ns) in database.messages(&ids)? {
            let stamp = if header {
                let stamp = database
                    .data(rowid, bag.compressed, STAMP_BYTES, false)
                    .and_then(|start| {
                        decode_stamp(&start, Encoding::Cdr, kind).map_err(|problem| {
                            RosError::BadMessage {
                                path: database.path.clone(),
                                topic: topic.clone(),
                                time: iso8601(Timestamp(log_ns)),
                                problem: Box::new(problem),
                            }
                        })
                    });
                match stamp {
                    Ok(stamp) => Some(stamp),
                    Err(problem) => {
                        damage.left_out(problem)?;
                        continue;
                    }
                }
            } else {
                None
            };
            stamps.push((log_ns, stamp));
            maps.push(SqliteMap {
                database: i,
                rowid,
                log_ns,
            });
        }
    }
    let (times, warnings) = times(dir, &topic, &stamps, options.time)?;
    let maps = SqliteMaps {
        path: dir.to_path_buf(),
        topic,
        kind,
        compressed: bag.compressed,
        databases: bag.databases,
        maps,
        _spool: bag.spool,
    };
    Ok(Recording::new(times, warnings, Arc::new(maps)).with_skipped(skipped))
}
