//! Errors of the generator.

use froctomap_core::MapError;
use froctomap_formats::FormatError;
use std::path::PathBuf;

/// Why a series could not be specified, generated or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SynthError {
    /// A [`SeriesSpec`](crate::SeriesSpec) field is out of its valid range.
    #[error("invalid series spec: {field}: {reason}")]
    InvalidSpec {
        /// The field.
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// The base map knows no voxel at all, so nothing can be placed in it.
    #[error("the base map is empty (no known voxels)")]
    EmptyBase,
    /// A door series file could not be read.
    #[error("{}: cannot read door series", path.display())]
    DoorSeriesIo {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A door series file is malformed.
    #[error("{source_name}: line {line}: {reason}")]
    DoorSeriesParse {
        /// The file (or the name given to in-memory text).
        source_name: String,
        /// 1-based line number (0 when the problem is the file as a whole).
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A frame index at or beyond the spec's `count`.
    #[error("frame {index} does not exist (the series has {count} grid frames)")]
    FrameOutOfRange {
        /// The index asked for.
        index: u64,
        /// Grid frames in the series.
        count: u64,
    },
    /// A grid frame the spec drops as missed (`missed_frames`).
    #[error("frame {index} is a missed frame (absent from the series)")]
    MissedFrame {
        /// The index asked for.
        index: u64,
    },
    /// A generated map failed validation (a bug in the generator, reported rather than hidden).
    #[error("generated map is invalid")]
    Map(#[from] MapError),
    /// Writing a frame through the format registry failed.
    #[error(transparent)]
    Format(#[from] FormatError),
    /// The sink of [`encode_series`](crate::encode_series) refused a frame (writing a
    /// stream failed).
    #[error("writing the series")]
    Sink(#[source] Box<dyn std::error::Error + Send + Sync>),
    /// A scenario file that is not a serialised [`SeriesSpec`](crate::SeriesSpec).
    #[error("{}: not a scenario", path.display())]
    SpecJson {
        /// The file.
        path: PathBuf,
        /// What the JSON parser refused.
        #[source]
        source: serde_json::Error,
    },
    /// A file or directory could not be created or written.
    #[error("{}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The output file-name pattern cannot name the frames.
    #[error("invalid file name pattern {pattern:?}: {reason}")]
    InvalidPattern {
        /// The pattern.
        pattern: String,
        /// What is wrong.
        reason: String,
    },
    /// A `manifest.csv` is malformed.
    #[error("{}: line {line}: {reason}", path.display())]
    Manifest {
        /// The manifest.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The worker thread pool could not be started.
    #[error("cannot start worker threads: {0}")]
    ThreadPool(String),
}
