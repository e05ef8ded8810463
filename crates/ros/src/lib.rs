//! Reads maps recorded by robots: `octomap_msgs/Octomap` messages (as `octomap_server`
//! publishes on `/octomap_binary` and `/octomap_full`) from ROS 1 bags, MCAP files and ROS 2
//! bag directories (MCAP storage), as timed snapshots of a froctomap series.
//!
//! The crate is a plugin: [`register`] adds its [`RecordingFormat`]s (and, for `identify`,
//! their [`SeriesFormat`]s) to a [`Context`], after which
//! [`collect_inputs`](froctomap_convert::collect_inputs) expands a recording into one input
//! per map and `build` reads it like a directory of `.bt` files.
//!
//! * Which topic: [`RecordingOptions::topic`](froctomap_convert::RecordingOptions), else the
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
//! use froctomap_convert::Context;
//! let mut context = Context::with_default_plugins();
//! froctomap_ros::register(&mut context);
//! assert!(context.recording_formats().iter().any(|f| f.name == "rosbag"));
//! ```

mod bag;
mod encode;
mod error;
mod foxglove;
mod io;
mod mcap_export;
mod mcap_file;
mod mcap_lengths;
mod message;
mod source;

pub use encode::{
    encode_octomap_cdr, encode_point_cloud2_cdr, PointFieldSpec, OCTOMAP_ROS2MSG, OCTOMAP_TYPE,
    POINT_CLOUD2_ROS2MSG, POINT_CLOUD2_TYPE,
};
pub use error::{McapWriteError, MessageError, RosError};
pub use foxglove::{MAX_POINTS, POINT_CLOUD_JSON_SCHEMA, POINT_CLOUD_SCHEMA};
pub use mcap_export::{FRAME_ID, OCTOMAP_TOPIC, POINT_CLOUD2_TOPIC, POINT_CLOUD_TOPIC};
pub use message::{decode_message, decode_stamp, Encoding, MessageType, OctomapMessage};

use froctomap_convert::{Context, Recording, RecordingFormat, RecordingOptions};
use froctomap_formats::{Confidence, SeriesFormat};
use std::path::{Path, PathBuf};

/// ROS 1 bags (format 2.0; chunks uncompressed, bz2 or lz4).
pub const ROSBAG: RecordingFormat = RecordingFormat {
    name: "rosbag",
    description: "ROS 1 bag",
    probe: |path| path.is_file() && io::starts_with(path, bag::MAGIC),
    open: |path, options, limit| Ok(source::open_bag(path, options, limit)?),
    extensions: &["bag"],
    create: None,
};

/// MCAP files (ROS 2 `cdr` or ROS 1 `ros1` messages; chunks uncompressed, zstd or lz4).
/// Written by `export --format mcap`: the maps as `octomap_msgs/msg/Octomap` (CDR) on
/// [`OCTOMAP_TOPIC`] and their occupied voxels as a `foxglove.PointCloud` (JSON) on
/// [`POINT_CLOUD_TOPIC`] and as a `sensor_msgs/msg/PointCloud2` (CDR) on
/// [`POINT_CLOUD2_TOPIC`].
pub const MCAP: RecordingFormat = RecordingFormat {
    name: "mcap",
    description: "MCAP recording",
    probe: |path| path.is_file() && io::starts_with(path, mcap_file::MAGIC),
    open: |path, options, limit| {
        Ok(source::open_mcap(
            path,
            &[path.to_path_buf()],
            options,
            limit,
        )?)
    },
    extensions: &["mcap"],
    create: Some(mcap_export::create),
};

/// ROS 2 bag directories (`metadata.yaml` beside the storage files) with MCAP storage.
pub const ROS2_BAG: RecordingFormat = RecordingFormat {
    name: "ros2bag",
    description: "ROS 2 bag directory",
    probe: |path| path.is_dir() && path.join("metadata.yaml").is_file(),
    open: |path, options, limit| Ok(open_ros2_bag(path, options, limit)?),
    extensions: &[],
    create: None,
};

/// The recording formats for [`SeriesFormat`] identification (so that other commands say
/// what a bag is rather than "unknown format").
pub const ROSBAG_SERIES: SeriesFormat = SeriesFormat {
    name: "rosbag",
    description: "ROS 1 bag",
    extensions: &["bag"],
    probe: |bytes| confidence(bytes.starts_with(bag::MAGIC)),
};

/// MCAP for [`SeriesFormat`] identification.
pub const MCAP_SERIES: SeriesFormat = SeriesFormat {
    name: "mcap",
    description: "MCAP recording",
    extensions: &["mcap"],
    probe: |bytes| confidence(bytes.starts_with(mcap_file::MAGIC)),
};

fn confidence(certain: bool) -> Confidence {
    if certain {
        Confidence::Certain
    } else {
        Confidence::No
    }
}

/// Registers the recording formats of this crate in `context`.
pub fn register(context: &mut Context) {
    for format in [ROSBAG, MCAP, ROS2_BAG] {
        context.register_recording(format);
    }
    for series in [ROSBAG_SERIES, MCAP_SERIES] {
        context.formats_mut().register_series(series);
    }
}

/// A ROS 2 bag directory: its `.mcap` files in name order, read as one recording.
fn open_ros2_bag(
    path: &Path,
    options: &RecordingOptions,
    limit: u64,
) -> Result<Recording, RosError> {
    let io = |source| RosError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut files: Vec<PathBuf> = Vec::new();
    let mut sqlite = false;
    for entry in std::fs::read_dir(path).map_err(io)? {
        let file = entry.map_err(io)?.path();
        match file.extension().and_then(|e| e.to_str()) {
            Some("mcap") if file.is_file() => files.push(file),
            Some("db3") => sqlite = true,
            _ => {}
        }
    }
    if files.is_empty() {
        return Err(RosError::NoMcapInBag {
            path: path.to_path_buf(),
            sqlite,
        });
    }
    files.sort_by(|a, b| froctomap_convert::natural_cmp(a, b));
    source::open_mcap(path, &files, options, limit)
}
