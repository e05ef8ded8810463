//! Reads maps recorded by robots: `octomap_msgs/Octomap` messages (as `octomap_server`
//! publishes on `/octomap_binary` and `/octomap_full`) from ROS 1 bags, MCAP files and ROS 2
//! bag directories (MCAP storage), as timed snapshots of a froctomap series.
//!
//! The crate is a plugin: [`register`] adds its [`RecordingFormat`]s to a
//! [`FormatRegistry`] (one descriptor per container recognises, opens and writes it: ROS 1
//! bags and MCAP files as one file, ROS 2 bags as a directory), after which froctomap's input collection expands a recording into one input per map
//! and `build` reads it like a directory of `.bt` files.
//!
//! * Which topic: [`RecordingOptions::topic`], else the
//!   one topic of type `octomap_msgs/Octomap` (`octomap_msgs/msg/Octomap`) or
//!   `OctomapWithPose`; none or several are errors that list the topics.
//! * Which time: the header stamp (default; zero stamps take the log time, with a warning)
//!   or the log time.
//! * Streaming: a recording is opened from its index (bag index records, the MCAP summary);
//!   maps are fetched one message at a time, so memory holds a few chunks, never the file.
//! * Each message becomes the map file it stands for ([`OctomapMessage::map_file`]): the
//!   `.bt` body of `binary` messages, the `.ot` body of others, or a whole file with its
//!   header when a publisher put one in `data`.
//!
//! ```
//! use froctomap_formats::FormatRegistry;
//! let mut registry = FormatRegistry::with_default_formats();
//! froctomap_ros::register(&mut registry)?;
//! assert!(registry.recording_formats().iter().any(|f| f.name == "rosbag"));
//! // Registered once: a second registration is refused.
//! assert!(froctomap_ros::register(&mut registry).is_err());
//! # Ok::<(), froctomap_formats::DuplicateName>(())
//! ```

mod bag;
mod bag_export;
mod bag_metadata;
mod describe;
mod encode;
mod error;
mod foxglove;
mod io;
mod markers;
mod mcap_export;
mod mcap_file;
mod mcap_lengths;
mod message;
mod ros2bag_export;
mod source;
mod sqlite_bag;
mod stream;
mod topic_counts;
mod topics;

pub use encode::{
    encode_octomap_cdr, encode_octomap_ros1, encode_point_cloud2_cdr, PointFieldSpec,
    MARKER_ARRAY_ROS2MSG, OCTOMAP_ROS1_DEFINITION, OCTOMAP_ROS1_MD5, OCTOMAP_ROS1_TYPE,
    OCTOMAP_ROS2MSG, OCTOMAP_TYPE, POINT_CLOUD2_ROS2MSG, POINT_CLOUD2_TYPE,
};
pub use error::{BagWriteError, McapWriteError, MessageError, RosError};
pub use foxglove::{
    kind_name, point_cloud_json, scene_update_json, MAX_POINTS, POINT_CLOUD_JSON_SCHEMA,
    POINT_CLOUD_SCHEMA, SCENE_ENTITY_ID, SCENE_UPDATE_JSON_SCHEMA, SCENE_UPDATE_SCHEMA,
};
pub use markers::{
    encode_occupied_marker_array_cdr, CUBE_LIST, MARKER_ARRAY_TYPE, MARKER_DELETE, MARKER_NAMESPACE,
};
pub use mcap_export::{McapMapStream, MAP_METADATA};
pub use message::{decode_message, decode_stamp, Encoding, MessageType, OctomapMessage};
pub use stream::{McapStreamMaps, StreamedMap};
pub use topics::{
    CLOCK_TOPIC, DYNAMIC_TOPIC, FRAME_ID, GET_OCTOMAP_AT_SERVICE, OCCUPIED_CELLS_TOPIC,
    OCTOMAP_TOPIC, POINT_CLOUD2_TOPIC, POINT_CLOUD_TOPIC, PREDICTED_TOPIC, PROBABILITY_AT_SERVICE,
    SCENE_TOPIC,
};

use froctomap_formats::{
    Confidence, DuplicateName, FormatRegistry, Recording, RecordingFormat, RecordingOptions,
    RecordingSummary,
};
use std::path::{Path, PathBuf};

/// ROS 1 bags (format 2.0; chunks uncompressed, bz2 or lz4). Written by `export --format
/// rosbag` (`-o maps.bag`): the maps as `octomap_msgs/Octomap` on [`OCTOMAP_TOPIC`], one
/// uncompressed chunk each.
pub const ROSBAG: RecordingFormat = RecordingFormat {
    name: "rosbag",
    description: "ROS 1 bag",
    extensions: &["bag"],
    probe: |head| confidence(head.starts_with(bag::MAGIC)),
    probe_dir: None,
    open: |path, options, limit| Ok(source::open_bag(path, options, limit)?),
    open_stream: None,
    create: Some(bag_export::create),
    create_dir: None,
    describe: Some(|path, limit| Ok(describe::describe_bag(path, limit)?)),
};

/// MCAP files (ROS 2 `cdr` or ROS 1 `ros1` messages; chunks uncompressed, zstd or lz4),
/// also as a stream on standard input (`-`; read to its end, the maps spooled to disk).
/// Written by `export --format mcap`: by default only CDR messages with their `ros2msg`
/// schemas, the maps as `octomap_msgs/msg/Octomap` on [`OCTOMAP_TOPIC`], their occupied
/// voxels as a `sensor_msgs/msg/PointCloud2` on [`POINT_CLOUD2_TOPIC`] and their occupied
/// cells as a `visualization_msgs/msg/MarkerArray` on [`OCCUPIED_CELLS_TOPIC`]; with
/// [`RecordingProfile::Foxglove`](froctomap_formats::RecordingProfile) also a
/// `foxglove.PointCloud` on [`POINT_CLOUD_TOPIC`] and `foxglove.SceneUpdate` cubes on
/// [`SCENE_TOPIC`] (JSON).
pub const MCAP: RecordingFormat = RecordingFormat {
    name: "mcap",
    description: "MCAP recording",
    extensions: &["mcap"],
    probe: |head| confidence(head.starts_with(mcap_file::MAGIC)),
    probe_dir: None,
    open: |path, options, limit| {
        Ok(source::open_mcap(
            path,
            &[path.to_path_buf()],
            options,
            limit,
        )?)
    },
    open_stream: Some(|input, options, limit| Ok(stream::open_mcap_stream(input, options, limit)?)),
    create: Some(mcap_export::create),
    create_dir: None,
    describe: Some(|path, limit| Ok(describe::describe_mcap(path, &[path.to_path_buf()], limit)?)),
};

/// ROS 2 bag directories: `metadata.yaml` beside the storage files, MCAP storage or sqlite3
/// storage (uncompressed, or zstd per message or per file); or, while `ros2 bag record` is
/// writing an MCAP bag (it writes `metadata.yaml` when it ends), a directory `NAME` holding
/// its first split `NAME_0.mcap`. MCAP splits are read in name order (`NAME_2` before
/// `NAME_10`), each up to its last complete chunk when it has no summary yet (the split
/// being written). Written by `export --format ros2bag` (`-o maps_bag`, a new directory):
/// `maps_bag/maps_bag_0.mcap`, the messages of an MCAP export (profile ros2 only: a bag holds
/// CDR), and `maps_bag/metadata.yaml` (rosbag2's version 8) with every topic's real message
/// count and the span of the maps' times.
pub const ROS2_BAG: RecordingFormat = RecordingFormat {
    name: "ros2bag",
    description: "ROS 2 bag directory",
    extensions: &[],
    probe: |_| Confidence::No,
    probe_dir: Some(|path| path.join("metadata.yaml").is_file() || has_first_split(path)),
    open: |path, options, limit| Ok(open_ros2_bag(path, options, limit)?),
    open_stream: None,
    create: None,
    create_dir: Some(ros2bag_export::create),
    describe: Some(|path, limit| Ok(describe_ros2_bag(path, limit)?)),
};

/// Whether the directory `NAME` holds `NAME_0.mcap`, the first split `ros2 bag record`
/// writes into it.
fn has_first_split(dir: &Path) -> bool {
    dir.file_name()
        .and_then(|name| name.to_str())
        .is_some_and(|name| dir.join(format!("{name}_0.mcap")).is_file())
}

fn confidence(certain: bool) -> Confidence {
    if certain {
        Confidence::Certain
    } else {
        Confidence::No
    }
}

/// Registers the recording formats of this crate in `registry` (refused, like every
/// registration, when one of their names is taken).
pub fn register(registry: &mut FormatRegistry) -> Result<(), DuplicateName> {
    for format in [ROSBAG, MCAP, ROS2_BAG] {
        registry.register_recording(format)?;
    }
    Ok(())
}

/// A ROS 2 bag directory: sqlite3 storage (its databases), or MCAP storage (its `.mcap`
/// files in name order), read as one recording.
fn open_ros2_bag(
    path: &Path,
    options: &RecordingOptions,
    limit: u64,
) -> Result<Recording, RosError> {
    let metadata = bag_metadata::BagMetadata::read(path)?;
    if sqlite_bag::is_sqlite_bag(path, &metadata) {
        return sqlite_bag::open(path, &metadata, options, limit);
    }
    refuse_mcap_compression(path, metadata)?;
    source::open_mcap(path, &mcap_files(path)?, options, limit)
}

/// MCAP storage with rosbag2 compression is not read.
fn refuse_mcap_compression(
    path: &Path,
    metadata: bag_metadata::BagMetadata,
) -> Result<(), RosError> {
    if !metadata.compression_mode.is_empty() {
        return Err(RosError::UnsupportedBagCompression {
            path: path.to_path_buf(),
            mode: metadata.compression_mode,
            format: metadata.compression_format,
        });
    }
    Ok(())
}

/// The `.mcap` files of a ROS 2 bag directory with MCAP storage, in name order.
fn mcap_files(path: &Path) -> Result<Vec<PathBuf>, RosError> {
    let io = |source| RosError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut files: Vec<PathBuf> = Vec::new();
    for entry in std::fs::read_dir(path).map_err(io)? {
        let file = entry.map_err(io)?.path();
        if file.extension().is_some_and(|e| e == "mcap") && file.is_file() {
            files.push(file);
        }
    }
    if files.is_empty() {
        return Err(RosError::NoStorageInBag {
            path: path.to_path_buf(),
        });
    }
    files.sort_by(|a, b| froctomap_formats::natural_cmp(a, b));
    Ok(files)
}

/// The topics of a ROS 2 bag directory (`info`).
fn describe_ros2_bag(path: &Path, limit: u64) -> Result<RecordingSummary, RosError> {
    let metadata = bag_metadata::BagMetadata::read(path)?;
    if sqlite_bag::is_sqlite_bag(path, &metadata) {
        return describe::describe_sqlite(path, &metadata, limit);
    }
    refuse_mcap_compression(path, metadata)?;
    describe::describe_mcap(path, &mcap_files(path)?, limit)
}
