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

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::said_twice;

    fn io() -> std::io::Error {
        std::io::Error::other("disk full")
    }

    /// Every variant, as its chain prints: no text repeats another of the chain (a cause is
    /// printed once, after the error naming the file) and none is empty.
    #[test]
    fn every_error_is_said_once() {
        let path = || PathBuf::from("doors.txt");
        let all = [
            SynthError::InvalidSpec {
                field: "count",
                reason: "must be at least 1".into(),
            },
            SynthError::EmptyBase,
            SynthError::DoorSeriesIo {
                path: path(),
                source: io(),
            },
            SynthError::DoorSeriesParse {
                source_name: "doors.txt".into(),
                line: 2,
                reason: "state \"2\" is neither 0 (closed) nor 1 (open)".into(),
            },
            SynthError::FrameOutOfRange { index: 9, count: 8 },
            SynthError::MissedFrame { index: 3 },
            SynthError::Map(MapError::InvalidResolution(0.0)),
            SynthError::Format(FormatError::Io {
                path: "frame.bt".into(),
                source: io(),
            }),
            SynthError::Sink(Box::new(io())),
            SynthError::SpecJson {
                path: "scenario.json".into(),
                source: serde_json::from_str::<u8>("x").unwrap_err(),
            },
            SynthError::Io {
                path: "out".into(),
                source: io(),
            },
            SynthError::InvalidPattern {
                pattern: "frame.bt".into(),
                reason: "no {index} or {time}".into(),
            },
            SynthError::Manifest {
                path: "manifest.csv".into(),
                line: 2,
                reason: "not path,time".into(),
            },
            SynthError::ThreadPool("out of threads".into()),
        ];
        for e in &all {
            // Fails to compile when a variant is added and not listed above.
            match e {
                SynthError::InvalidSpec { .. }
                | SynthError::EmptyBase
                | SynthError::DoorSeriesIo { .. }
                | SynthError::DoorSeriesParse { .. }
                | SynthError::FrameOutOfRange { .. }
                | SynthError::MissedFrame { .. }
                | SynthError::Map(_)
                | SynthError::Format(_)
                | SynthError::Sink(_)
                | SynthError::SpecJson { .. }
                | SynthError::Io { .. }
                | SynthError::InvalidPattern { .. }
                | SynthError::Manifest { .. }
                | SynthError::ThreadPool(_) => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        assert_eq!(
            froctomap_core::error_message(&all[2]),
            "doors.txt: cannot read door series: disk full"
        );
    }
}
