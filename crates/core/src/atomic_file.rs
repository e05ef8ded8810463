//! Output files that appear whole or not at all.
//!
//! Every froctomap output is written to a temporary file in the destination directory and
//! renamed over the destination only once complete, so an interrupted run never leaves a
//! half-written map behind (rename within one directory is atomic on POSIX file systems).

use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writing `path` failed; nothing was left at `path` (a previous file there is untouched).
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}: {source}", path.display())]
pub struct AtomicWriteError {
    /// Destination that was being written.
    pub path: PathBuf,
    /// What went wrong.
    #[source]
    pub source: io::Error,
}

/// Writes a file atomically: `fill` writes the content into a buffered temporary file next to
/// `path`, which is flushed, synced and renamed over `path` only if `fill` succeeds.
///
/// ```
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("hello.txt");
/// froctomap_core::write_atomically(&path, |out| out.write_all(b"hello"))?;
/// assert_eq!(std::fs::read(&path)?, b"hello");
/// let failed = froctomap_core::write_atomically(&path, |_| Err(std::io::Error::other("stop")));
/// assert!(failed.is_err());
/// assert_eq!(std::fs::read(&path)?, b"hello"); // untouched
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), AtomicWriteError> {
    let fail = |source| AtomicWriteError {
        path: path.to_path_buf(),
        source,
    };
    let dir = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    let file_name = path.file_name().ok_or_else(|| {
        fail(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a file name",
        ))
    })?;
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(file_name);
    prefix.push(".");
    let temp = tempfile::Builder::new()
        .prefix(&prefix)
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(fail)?;
    let mut writer = BufWriter::new(temp);
    fill(&mut writer).map_err(fail)?;
    let temp = writer.into_inner().map_err(|e| fail(e.into_error()))?;
    temp.as_file().sync_all().map_err(fail)?;
    temp.persist(path).map_err(|e| fail(e.error))?;
    Ok(())
}
