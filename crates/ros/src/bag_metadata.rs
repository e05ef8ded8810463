//! What a ROS 2 bag directory's `metadata.yaml` says about its storage: the storage plugin,
//! the compression and the storage files in order.
//!
//! The file is read with `yaml-rust2`'s event parser, keeping only the few scalars wanted:
//! aliases are never expanded (a hostile file cannot multiply itself), and the file is
//! refused above [`MAX_BYTES`] before it is read.

use crate::error::RosError;
use std::path::{Path, PathBuf};
use yaml_rust2::parser::{Event, EventReceiver, Parser};

/// The largest `metadata.yaml` read (rosbag2 writes a few kilobytes per topic and file).
pub(crate) const MAX_BYTES: u64 = 16 << 20;

/// The storage of a ROS 2 bag as its `metadata.yaml` describes it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct BagMetadata {
    /// `storage_identifier`: `sqlite3`, `mcap` (empty: not said).
    pub storage: String,
    /// `compression_mode`: empty, `file` or `message` (rosbag2 writes `NONE`, `FILE`,
    /// `MESSAGE` in some versions: kept lower case).
    pub compression_mode: String,
    /// `compression_format`: empty or `zstd`.
    pub compression_format: String,
    /// `relative_file_paths`, in order (empty: not said).
    pub files: Vec<String>,
}

impl BagMetadata {
    /// Reads `dir/metadata.yaml`.
    ///
    /// A bag that `ros2 bag record` is still writing has no `metadata.yaml` yet (it is
    /// written when the recording ends): its metadata is then empty (MCAP splits found by
    /// name, no compression).
    pub fn read(dir: &Path) -> Result<Self, RosError> {
        let path = dir.join("metadata.yaml");
        if !path.exists() {
            return Ok(Self::default());
        }
        let io = |source| RosError::Io {
            path: path.clone(),
            source,
        };
        let size = std::fs::metadata(&path).map_err(io)?.len();
        if size > MAX_BYTES {
            return Err(RosError::TooLarge {
                path,
                what: "metadata.yaml",
                bytes: size,
                limit: MAX_BYTES,
            });
        }
        let text = std::fs::read(&path).map_err(io)?;
        let text = String::from_utf8(text).map_err(|_| RosError::Malformed {
            path: path.clone(),
            what: "metadata.yaml",
            problem: "it is not UTF-8 text".into(),
        })?;
        Self::parse(&text).map_err(|problem| RosError::Malformed {
            path,
            what: "metadata.yaml",
            problem,
        })
    }

    /// The metadata in `text`, or why it is not YAML.
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut wanted = Wanted::default();
        Parser::new_from_str(text)
            .load(&mut wanted, false)
            .map_err(|e| e.to_string())?;
        let mut metadata = wanted.metadata;
        metadata.compression_mode = metadata.compression_mode.to_ascii_lowercase();
        metadata.compression_format = metadata.compression_format.to_ascii_lowercase();
        if metadata.compression_mode == "none" {
            metadata.compression_mode.clear();
        }
        Ok(metadata)
    }

    /// The storage files named in the metadata, in the bag directory (only their names are
    /// taken, as rosbag2's readers do: older versions prefixed the bag's own directory).
    pub fn file_paths(&self, dir: &Path) -> Vec<PathBuf> {
        self.files
            .iter()
            .filter_map(|f| Path::new(f).file_name())
            .map(|name| dir.join(name))
            .collect()
    }
}

/// The events' receiver: tracks the keys leading to each node and keeps the wanted scalars
/// of `rosbag2_bagfile_information`.
#[derive(Default)]
struct Wanted {
    metadata: BagMetadata,
    /// One entry per open collection: for a mapping, its current key (`None`: expecting a
    /// key); for a sequence, `Some("-")`.
    path: Vec<Frame>,
}

/// A wanted scalar.
enum Field {
    Storage,
    Mode,
    Format,
    File,
}

enum Frame {
    Mapping(Option<String>),
    Sequence,
}

impl Wanted {
    /// The keys leading to the node now read (sequences as `-`).
    fn keys(&self) -> Vec<&str> {
        self.path
            .iter()
            .map(|frame| match frame {
                Frame::Mapping(key) => key.as_deref().unwrap_or(""),
                Frame::Sequence => "-",
            })
            .collect()
    }

    /// A node (scalar or collection) was read as a value: its mapping expects a key again.
    fn value_done(&mut self) {
        if let Some(Frame::Mapping(key)) = self.path.last_mut() {
            *key = None;
        }
    }

    fn scalar(&mut self, value: String) {
        if let Some(Frame::Mapping(key @ None)) = self.path.last_mut() {
            *key = Some(value);
            return;
        }
        let field = match self.keys().as_slice() {
            ["rosbag2_bagfile_information", "storage_identifier"] => Some(Field::Storage),
            ["rosbag2_bagfile_information", "compression_mode"] => Some(Field::Mode),
            ["rosbag2_bagfile_information", "compression_format"] => Some(Field::Format),
            ["rosbag2_bagfile_information", "relative_file_paths", "-"] => Some(Field::File),
            _ => None,
        };
        let metadata = &mut self.metadata;
        match field {
            Some(Field::Storage) => metadata.storage = value,
            Some(Field::Mode) => metadata.compression_mode = value,
            Some(Field::Format) => metadata.compression_format = value,
            Some(Field::File) => metadata.files.push(value),
            None => {}
        }
        self.value_done();
    }
}

impl EventReceiver for Wanted {
    fn on_event(&mut self, event: Event) {
        match event {
            Event::Scalar(value, ..) => self.scalar(value),
            Event::MappingStart(..) => self.path.push(Frame::Mapping(None)),
            Event::SequenceStart(..) => self.path.push(Frame::Sequence),
            Event::MappingEnd | Event::SequenceEnd => {
                self.path.pop();
                self.value_done();
            }
            // An alias stands for a node read earlier: its value is not wanted here.
            Event::Alias(_) => self.scalar(String::new()),
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_what_rosbag2_writes() {
        let text = "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: sqlite3\n  \
            relative_file_paths:\n    - bag/bag_0.db3.zstd\n    - bag_1.db3.zstd\n  \
            topics_with_message_count:\n    - topic_metadata:\n        name: /x\n        \
            type: a/msg/B\n      message_count: 3\n  compression_format: zstd\n  \
            compression_mode: FILE\n  files:\n  - path: bag_0.db3.zstd\n";
        let metadata = BagMetadata::parse(text).unwrap_or_default();
        assert_eq!(metadata.storage, "sqlite3");
        assert_eq!(metadata.compression_mode, "file");
        assert_eq!(metadata.compression_format, "zstd");
        assert_eq!(metadata.files, ["bag/bag_0.db3.zstd", "bag_1.db3.zstd"]);
        assert_eq!(
            metadata.file_paths(Path::new("/d")),
            [
                Path::new("/d/bag_0.db3.zstd"),
                Path::new("/d/bag_1.db3.zstd")
            ]
        );
        assert!(BagMetadata::parse("a: [").is_err());
        // Aliases are not expanded: a "billion laughs" costs what it is.
        let laughs = "a: &a [x, x]\nb: &b [*a, *a]\nc: &c [*b, *b]\nd: [*c, *c]\n";
        assert_eq!(BagMetadata::parse(laughs), Ok(BagMetadata::default()));
    }
}
