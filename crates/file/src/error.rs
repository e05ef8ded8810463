//! Errors of reading and writing FROctomap files.

use froctomap_temporal::TemporalError;
use std::path::PathBuf;

/// What is wrong with a file's bytes, independent of where the file is.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FormatViolation {
    /// Bytes were damaged: a checksum does not match.
    #[error("checksum mismatch in the {0} (the file is damaged)")]
    Checksum(&'static str),
    /// The structure is invalid (bad magic, impossible value, truncated part).
    #[error("corrupt {what}: {detail}")]
    Corrupt {
        /// Which part of the file.
        what: &'static str,
        /// What is wrong with it.
        detail: String,
    },
    /// A count or length beyond a configured maximum.
    #[error("limit exceeded: {what} is {value}, at most {limit} allowed (see ReadLimits)")]
    Limit {
        /// Which quantity.
        what: &'static str,
        /// Its value in the file.
        value: u64,
        /// The maximum.
        limit: u64,
    },
    /// A major version this reader does not understand.
    #[error(
        "unsupported FROctomap version {major}.{minor} (this reader understands {supported}.x)"
    )]
    UnsupportedVersion {
        /// Major version found.
        major: u16,
        /// Minor version found.
        minor: u16,
        /// Major version supported.
        supported: u16,
    },
    /// A critical section or value this reader does not implement.
    #[error("unsupported feature: {0} (written by a newer froctomap?)")]
    UnsupportedFeature(String),
    /// The temporal model could not be set up or decode a cell.
    #[error("temporal model: {0}")]
    Model(#[from] TemporalError),
}

pub(crate) fn corrupt(what: &'static str, detail: impl Into<String>) -> FormatViolation {
    FormatViolation::Corrupt {
        what,
        detail: detail.into(),
    }
}

/// Why reading or writing a FROctomap file failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FileError {
    /// The operating system refused an operation on the file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The file's content is invalid.
    #[error("{}: {violation}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        #[source]
        violation: FormatViolation,
    },
    /// The caller asked for something impossible (e.g. tiles out of order).
    #[error("{0}")]
    Usage(String),
}

impl FileError {
    /// The format violation, if that is what this error is.
    pub fn violation(&self) -> Option<&FormatViolation> {
        match self {
            FileError::Invalid { violation, .. } => Some(violation),
            _ => None,
        }
    }
}
