//! Timed maps handed over one at a time by a source that cannot be read twice (a Python
//! iterable, a generator), kept on disk until the series is built: a [`MapSpool`] appends
//! each map's bytes to a file in a locked temporary directory and becomes a [`Recording`]
//! whose maps are read back from it, so memory does not grow with the maps.

use crate::error::PluginError;
use crate::recording::{RecordedMaps, Recording};
use froctomap_core::{temporary_dir_in, TemporaryDir, Timestamp};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Why spooled maps could not be kept or read back.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SpoolError {
    /// The spool could not be made, written or read.
    #[error("{}: spooled maps", path.display())]
    Io {
        /// The spool's directory.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A map larger than the largest map read whole.
    #[error("{name}: map {index} of {bytes} bytes is more than the limit of {limit} bytes")]
    TooLarge {
        /// The source's name.
        name: String,
        /// The map's place in the source.
        index: usize,
        /// Its bytes.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// A map the spool does not hold.
    #[error("{name}: no map {index}")]
    NoMap {
        /// The source's name.
        name: String,
        /// The index asked for.
        index: usize,
    },
}

/// The prefix of spool directories.
pub const SPOOL_PREFIX: &str = ".froct-maps-";

/// Maps being spooled, in the order they come.
///
/// ```
/// use froctomap_core::Timestamp;
/// use froctomap_formats::MapSpool;
/// let dir = tempfile::tempdir()?;
/// let mut spool = MapSpool::new(Some(dir.path()), "maps")?;
/// spool.push(Timestamp::from_secs(60), b"second map")?;
/// spool.push(Timestamp::from_secs(0), b"first map")?;
/// let recording = spool.into_recording()?;
/// assert_eq!(recording.times, [Timestamp::from_secs(60), Timestamp::from_secs(0)]);
/// assert_eq!(recording.maps.map_bytes(1, 1 << 20)?, b"first map");
/// drop(recording); // the spool goes with it
/// assert_eq!(std::fs::read_dir(dir.path())?.count(), 0);
/// # Ok::<(), Box<dyn std::error::Error + Send + Sync>>(())
/// ```
pub struct MapSpool {
    maps: SpooledMaps,
    times: Vec<Timestamp>,
    written: u64,
    out: BufWriter<File>,
}

#[derive(Debug)]
struct SpooledMaps {
    name: String,
    file: File,
    /// (offset, length) of each map.
    spans: Vec<(u64, u64)>,
    /// Removed (with the file) when the recording is dropped.
    dir: TemporaryDir,
}

impl MapSpool {
    /// A new spool in a locked temporary directory made in `parent` (the system's
    /// temporary directory when `None`); `name` names the source in messages.
    pub fn new(parent: Option<&Path>, name: &str) -> Result<Self, SpoolError> {
        let parent = parent.map_or_else(std::env::temp_dir, Path::to_path_buf);
        let io = |source| SpoolError::Io {
            path: parent.clone(),
            source,
        };
        let dir = temporary_dir_in(&parent, SPOOL_PREFIX.as_ref()).map_err(io)?;
        let file = File::options()
            .read(true)
            .write(true)
            .create_new(true)
            .open(dir.path().join("maps"))
            .map_err(io)?;
        let out = BufWriter::new(file.try_clone().map_err(io)?);
        Ok(Self {
            maps: SpooledMaps {
                name: name.to_string(),
                file,
                spans: Vec::new(),
                dir,
            },
            times: Vec::new(),
            written: 0,
            out,
        })
    }

    /// Appends one map taken at `time`.
    pub fn push(&mut self, time: Timestamp, map: &[u8]) -> Result<(), SpoolError> {
        self.out.write_all(map).map_err(|e| self.maps.io(e))?;
        let len = map.len() as u64;
        self.maps.spans.push((self.written, len));
        self.times.push(time);
        self.written += len;
        Ok(())
    }

    /// How many maps it holds.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// `true` before the first map.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// The maps as a recording (in the order they came), read back from the spool, which
    /// is removed when the recording is dropped.
    pub fn into_recording(mut self) -> Result<Recording, SpoolError> {
        self.out.flush().map_err(|e| self.maps.io(e))?;
        drop(self.out);
        Ok(Recording::new(self.times, Vec::new(), Arc::new(self.maps)))
    }
}

impl SpooledMaps {
    fn io(&self, source: std::io::Error) -> SpoolError {
        SpoolError::Io {
            path: self.dir.path().to_path_buf(),
            source,
        }
    }

    fn read(&self, index: usize, limit: u64) -> Result<Vec<u8>, SpoolError> {
        let &(offset, len) = self.spans.get(index).ok_or_else(|| SpoolError::NoMap {
            name: self.name.clone(),
            index,
        })?;
        let too_large = || SpoolError::TooLarge {
            name: self.name.clone(),
            index,
            bytes: len,
            limit,
        };
        if len > limit {
            return Err(too_large());
        }
        let mut bytes = vec![0u8; usize::try_from(len).map_err(|_| too_large())?];
        self.file
            .read_exact_at(&mut bytes, offset)
            .map_err(|e| self.io(e))?;
        Ok(bytes)
    }
}

impl RecordedMaps for SpooledMaps {
    fn map_bytes(&self, index: usize, limit: u64) -> Result<Vec<u8>, PluginError> {
        Ok(self.read(index, limit)?)
    }

    fn topic(&self) -> &str {
        &self.name
    }
}
