//! Where a reader's bytes come from: a file, memory, or anything that can read a byte range.
//!
//! A [`FroctReader`](crate::FroctReader) reads a file in a few positioned reads — preamble,
//! header, footer and index when it opens, then one range per tile — so any store that can
//! serve a byte range serves a reader: implement [`ByteSource`] for it (an HTTP client with
//! `Range` requests, an object store, a memory map) and hand it to
//! [`FroctReader::from_source`](crate::FroctReader::from_source).

use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Bytes a reader can fetch by range. Reads may come from several threads at once.
///
/// Every length and offset a reader asks for has been checked against [`size`](Self::size)
/// and the [`ReadLimits`](crate::ReadLimits) first, so a source need not guard against
/// hostile sizes itself.
///
/// A remote store plugs in by answering range requests; here one that fetches from an
/// in-memory "server" and counts the requests:
///
/// ```
/// use froctomap_file::{ByteSource, FroctReader, ReadLimits};
/// use froctomap_temporal::ModelRegistry;
/// use std::path::Path;
/// use std::sync::atomic::{AtomicUsize, Ordering};
///
/// struct Remote { object: Vec<u8>, requests: AtomicUsize }
///
/// impl ByteSource for Remote {
///     fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
///         self.requests.fetch_add(1, Ordering::Relaxed); // one `Range: bytes=…` request
///         let range = self.object.get(offset as usize..offset as usize + buf.len());
///         buf.copy_from_slice(range.ok_or(std::io::ErrorKind::UnexpectedEof)?);
///         Ok(())
///     }
///     fn size(&self) -> u64 { self.object.len() as u64 } // from a HEAD request
///     fn name(&self) -> &Path { Path::new("https://maps.example/office.froct") }
/// }
///
/// # let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/froct/golden-v1.1.froct");
/// let remote = std::sync::Arc::new(Remote {
///     object: std::fs::read(&path)?,
///     requests: AtomicUsize::new(0),
/// });
/// let models = ModelRegistry::with_default_models();
/// let reader = FroctReader::from_source(remote.clone(), ReadLimits::default(), &models)?;
/// // Opening asks for the preamble, the header, the footer and the index.
/// assert_eq!(remote.requests.load(Ordering::Relaxed), 4);
/// reader.read_tile(0)?; // then one range per tile
/// assert_eq!(remote.requests.load(Ordering::Relaxed), 5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub trait ByteSource: Send + Sync {
    /// Fills `buf` with the bytes at `offset..offset + buf.len()`, or fails (with
    /// [`io::ErrorKind::UnexpectedEof`] when the range runs past the end).
    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()>;

    /// Total length in bytes.
    fn size(&self) -> u64;

    /// The length now, for sources that grow (a format 2.0 file being appended to, read
    /// again by [`LivingReader::refresh`](crate::LivingReader::refresh)); by default
    /// [`size`](Self::size).
    fn current_size(&self) -> io::Result<u64> {
        Ok(self.size())
    }

    /// What errors name the bytes by: a file's path, a URL, a label.
    fn name(&self) -> &Path;
}

/// A shared source (one connection behind several readers) and a boxed one (chosen at run
/// time) serve as what they hold.
macro_rules! forward_byte_source {
    ($($holder:ident),*) => {$(
        impl<S: ByteSource + ?Sized> ByteSource for $holder<S> {
            fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
                (**self).read_exact_at(offset, buf)
            }

            fn size(&self) -> u64 {
                (**self).size()
            }

            fn current_size(&self) -> io::Result<u64> {
                (**self).current_size()
            }

            fn name(&self) -> &Path {
                (**self).name()
            }
        }
    )*};
}

forward_byte_source!(Arc, Box);

/// A file on disk, read with positioned reads.
#[derive(Debug)]
pub struct FileSource {
    path: PathBuf,
    size: u64,
    #[cfg(unix)]
    file: File,
    /// Elsewhere a seek and a read under a lock stand in for a positioned read.
    #[cfg(not(unix))]
    file: SeekSource<File>,
}

impl FileSource {
    /// Opens `path` for reading.
    pub fn open(path: &Path) -> io::Result<Self> {
        let file = File::open(path)?;
        let size = file.metadata()?.len();
        Ok(Self {
            path: path.to_path_buf(),
            size,
            #[cfg(unix)]
            file,
            #[cfg(not(unix))]
            file: SeekSource::new(file, path.to_path_buf())?,
        })
    }
}

impl ByteSource for FileSource {
    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        #[cfg(unix)]
        {
            std::os::unix::fs::FileExt::read_exact_at(&self.file, buf, offset)
        }
        #[cfg(not(unix))]
        {
            self.file.read_exact_at(offset, buf)
        }
    }

    fn size(&self) -> u64 {
        self.size
    }

    fn current_size(&self) -> io::Result<u64> {
        #[cfg(unix)]
        {
            Ok(self.file.metadata()?.len())
        }
        #[cfg(not(unix))]
        {
            let file = self
                .file
                .inner
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            Ok(file.metadata()?.len())
        }
    }

    fn name(&self) -> &Path {
        &self.path
    }
}

/// Bytes in memory: a `Vec<u8>`, an `Arc<[u8]>`, a `&'static [u8]`, or any owner of a slice.
///
/// ```
/// use froctomap_file::{ByteSource, MemorySource};
/// let source = MemorySource::new(vec![1u8, 2, 3, 4]).named("four.froct");
/// let mut buf = [0u8; 2];
/// source.read_exact_at(1, &mut buf)?;
/// assert_eq!(buf, [2, 3]);
/// assert!(source.read_exact_at(3, &mut buf).is_err()); // past the end
/// assert_eq!(source.name().to_str(), Some("four.froct"));
/// # Ok::<(), std::io::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct MemorySource<B> {
    bytes: B,
    name: PathBuf,
}

impl<B: AsRef<[u8]>> MemorySource<B> {
    /// Bytes named `memory` in errors.
    pub fn new(bytes: B) -> Self {
        Self {
            bytes,
            name: PathBuf::from("memory"),
        }
    }

    /// The same bytes named `name` in errors.
    pub fn named(self, name: impl Into<PathBuf>) -> Self {
        Self {
            name: name.into(),
            ..self
        }
    }
}

impl<B: AsRef<[u8]> + Send + Sync> ByteSource for MemorySource<B> {
    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let bytes = self.bytes.as_ref();
        let range = usize::try_from(offset)
            .ok()
            .and_then(|start| Some(start..start.checked_add(buf.len())?))
            .and_then(|range| bytes.get(range))
            .ok_or_else(|| {
                io::Error::new(
                    io::ErrorKind::UnexpectedEof,
                    format!(
                        "{} bytes at {offset} run past the end ({} bytes)",
                        buf.len(),
                        bytes.len()
                    ),
                )
            })?;
        buf.copy_from_slice(range);
        Ok(())
    }

    fn size(&self) -> u64 {
        self.bytes.as_ref().len() as u64
    }

    fn name(&self) -> &Path {
        &self.name
    }
}

/// Any `Read + Seek` (a file where positioned reads do not exist, a decompressing stream
/// with seeking), read one range at a time under a lock.
#[derive(Debug)]
pub struct SeekSource<R> {
    inner: std::sync::Mutex<R>,
    size: u64,
    name: PathBuf,
}

impl<R: io::Read + io::Seek> SeekSource<R> {
    /// Wraps `inner`, measuring its length by seeking to its end.
    pub fn new(mut inner: R, name: impl Into<PathBuf>) -> io::Result<Self> {
        let size = inner.seek(io::SeekFrom::End(0))?;
        Ok(Self {
            inner: std::sync::Mutex::new(inner),
            size,
            name: name.into(),
        })
    }
}

impl<R: io::Read + io::Seek + Send> ByteSource for SeekSource<R> {
    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        // A panic while reading leaves the stream at an unknown position: the next read
        // seeks first anyway, so a poisoned lock is safe to take over.
        let mut inner = self
            .inner
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        inner.seek(io::SeekFrom::Start(offset))?;
        inner.read_exact(buf)
    }

    fn size(&self) -> u64 {
        self.size
    }

    fn name(&self) -> &Path {
        &self.name
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_source_reads_the_same_ranges() {
        let bytes: Vec<u8> = (0..=255).collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bytes");
        std::fs::write(&path, &bytes).unwrap();
        let sources: [Box<dyn ByteSource>; 3] = [
            Box::new(FileSource::open(&path).unwrap()),
            Box::new(MemorySource::new(bytes.clone())),
            Box::new(SeekSource::new(io::Cursor::new(bytes.clone()), "cursor").unwrap()),
        ];
        for source in &sources {
            assert_eq!(source.size(), 256);
            let mut buf = [0u8; 4];
            source.read_exact_at(250, &mut buf).unwrap();
            assert_eq!(buf, [250, 251, 252, 253]);
            let err = source.read_exact_at(253, &mut buf).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::UnexpectedEof, "{err}");
            assert!(source.read_exact_at(u64::MAX, &mut buf).is_err());
        }
    }
}
