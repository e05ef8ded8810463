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
    let file_name = path.file_name().ok_or_else(|| {
        fail(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a file name",
        ))
    })?;
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(file_name);
    prefix.push(".");
    let temp = temporary_beside(path, &prefix).map_err(fail)?;
    let mut writer = BufWriter::new(temp);
    fill(&mut writer).map_err(fail)?;
    let temp = writer.into_inner().map_err(|e| fail(e.into_error()))?;
    temp.as_file().sync_all().map_err(fail)?;
    temp.persist(path).map_err(|e| fail(e.error))?;
    Ok(())
}

/// A temporary output file: removed when dropped unless [`persist`](Self::persist)ed, and
/// listed for removal on a signal while it lives ([`crate::cleanup`]).
#[derive(Debug)]
pub struct TemporaryFile {
    file: tempfile::NamedTempFile,
    _registered: crate::cleanup::Registered,
}

impl TemporaryFile {
    /// The open file.
    pub fn as_file(&self) -> &std::fs::File {
        self.file.as_file()
    }

    /// Where it is.
    pub fn path(&self) -> &Path {
        self.file.path()
    }

    /// Renames it over `path` (atomically on POSIX file systems within one directory).
    pub fn persist(self, path: &Path) -> Result<std::fs::File, tempfile::PersistError> {
        self.file.persist(path)
    }
}

impl Write for TemporaryFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.file.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file.flush()
    }
}

/// A temporary file in `path`'s directory (named `prefix…tmp`) for an output that will be
/// renamed over `path`. Its permissions are those the output would get from a plain
/// `File::create(path)`, as upstream OctoMap's tools give theirs: the mode of the file it
/// replaces, else `0666` less the process's umask (a temporary file alone would be `0600`).
pub fn temporary_beside(path: &Path, prefix: &std::ffi::OsStr) -> io::Result<TemporaryFile> {
    let dir = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // Created with 0666: open(2) applies the umask, as for any new file.
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let (temp, registered) =
        crate::cleanup::create_registered(|| builder.tempfile_in(dir), |temp| temp.path())?;
    if let Ok(replaced) = std::fs::metadata(path) {
        // A replaced file keeps its mode (set without the umask, as truncating it would).
        temp.as_file().set_permissions(replaced.permissions())?;
    }
    Ok(TemporaryFile {
        file: temp,
        _registered: registered,
    })
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    fn mode(path: &Path) -> u32 {
        std::fs::metadata(path).map_or(0, |m| m.permissions().mode() & 0o777)
    }

    #[test]
    fn outputs_get_the_mode_a_plain_create_gives_or_keep_the_replaced_one() {
        let dir = tempfile::tempdir().unwrap();
        // What this process's umask makes of a new file.
        let plain = dir.path().join("plain");
        std::fs::File::create(&plain).unwrap();
        let new = dir.path().join("new.bt");
        write_atomically(&new, |out| out.write_all(b"x")).unwrap();
        assert_eq!(mode(&new), mode(&plain));
        assert_ne!(
            mode(&new),
            0o600,
            "not a temporary file's mode (umask 077 aside)"
        );

        for kept in [0o644, 0o640, 0o600] {
            let replaced = dir.path().join(format!("replaced-{kept:o}.bt"));
            std::fs::write(&replaced, b"old").unwrap();
            std::fs::set_permissions(&replaced, std::fs::Permissions::from_mode(kept)).unwrap();
            write_atomically(&replaced, |out| out.write_all(b"new")).unwrap();
            assert_eq!(mode(&replaced), kept);
            assert_eq!(std::fs::read(&replaced).unwrap(), b"new");
        }
    }
}
