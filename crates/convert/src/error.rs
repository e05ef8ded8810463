//! Errors of the converters.

use crate::time::format_iso;
use froctomap_core::Timestamp;
use std::path::PathBuf;

/// Why a conversion failed. Messages name the files involved.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConvertError {
    /// The command-line inputs do not describe a series.
    #[error("{0}")]
    Inputs(String),
    /// Two files claim the same time.
    #[error("{} and {} have the same time {}", first.display(), second.display(), format_iso(*time))]
    DuplicateTime {
        /// One file.
        first: PathBuf,
        /// The other.
        second: PathBuf,
        /// Their time.
        time: Timestamp,
    },
    /// Snapshots of different resolutions.
    #[error("{} has resolution {second_resolution} m but {} has {first_resolution} m; a series must have one resolution (use --skip-bad to leave such files out)", second.display(), first.display())]
    MixedResolution {
        /// A file with the series' resolution.
        first: PathBuf,
        /// Its resolution.
        first_resolution: f64,
        /// A file with another.
        second: PathBuf,
        /// That one.
        second_resolution: f64,
    },
    /// A map file could not be read.
    #[error("{0} (use --skip-bad to leave unreadable files out)")]
    Read(froctomap_formats::FormatError),
    /// A map could not be written.
    #[error(transparent)]
    Write(froctomap_formats::FormatError),
    /// A FROctomap file could not be read or written.
    #[error(transparent)]
    File(#[from] froctomap_file::FileError),
    /// The temporal model refused its configuration or data.
    #[error("temporal model: {0}")]
    Model(#[from] froctomap_temporal::TemporalError),
    /// A requested time cannot be served.
    #[error("{0}")]
    Time(String),
    /// Writing an output failed.
    #[error(transparent)]
    Output(#[from] froctomap_core::AtomicWriteError),
    /// Every input was unreadable or skipped.
    #[error("no readable snapshots: {0}")]
    NothingToBuild(String),
}
