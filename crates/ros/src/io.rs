//! Positioned reads of a recording, every length checked against the file's size first.

use crate::error::RosError;
use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// A recording file open for positioned reads.
#[derive(Debug)]
pub(crate) struct RecordingFile {
    pub path: PathBuf,
    file: File,
    pub size: u64,
}

impl RecordingFile {
    pub fn open(path: &Path) -> Result<Self, RosError> {
        let io = |source| RosError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = File::open(path).map_err(io)?;
        let size = file.metadata().map_err(io)?.len();
        Ok(Self {
            path: path.to_path_buf(),
            file,
            size,
        })
    }

    /// `len` bytes at `offset`; a range past the end is [`RosError::Truncated`] (checked
    /// before allocating, so a hostile length costs nothing).
    pub fn read_at(&self, offset: u64, len: u64, what: &'static str) -> Result<Vec<u8>, RosError> {
        if offset.checked_add(len).is_none_or(|end| end > self.size) {
            return Err(self.truncated(what));
        }
        let mut out = vec![0u8; usize::try_from(len).map_err(|_| self.truncated(what))?];
        self.file
            .read_exact_at(&mut out, offset)
            .map_err(|source| RosError::Io {
                path: self.path.clone(),
                source,
            })?;
        Ok(out)
    }

    pub fn truncated(&self, what: &'static str) -> RosError {
        RosError::Truncated {
            path: self.path.clone(),
            what,
        }
    }

    pub fn malformed(&self, what: &'static str, problem: impl Into<String>) -> RosError {
        RosError::Malformed {
            path: self.path.clone(),
            what,
            problem: problem.into(),
        }
    }

    /// Refuses `bytes` above `limit` for `what`.
    pub fn bounded(&self, what: &'static str, bytes: u64, limit: u64) -> Result<u64, RosError> {
        if bytes > limit {
            return Err(RosError::TooLarge {
                path: self.path.clone(),
                what,
                bytes,
                limit,
            });
        }
        Ok(bytes)
    }
}
