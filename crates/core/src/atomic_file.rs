//! Outputs that appear whole or not at all, and never replace anything but a regular file.
//!
//! Every froctomap output goes through this module ([`write_atomically`], or
//! [`temporary_beside`] and [`TemporaryFile::persist`] for outputs written in several
//! steps):
//!
//! * a regular file (or a new one) is written to a temporary file in the destination
//!   directory and renamed over the destination only once complete and synced, so an
//!   interrupted run never leaves a half-written map behind (rename within one directory is
//!   atomic on POSIX file systems);
//! * a character device or a FIFO (`/dev/null`, a named pipe) is written into directly, as
//!   `cp` does: it is never replaced;
//! * [`STDOUT`] (`-`) is standard output;
//! * anything else (a directory, a block device, a socket) is refused before anything is
//!   written.
//!
//! A temporary file is held under an advisory lock (`flock`) while its writer lives, and
//! the kernel drops the lock when the process ends, however it ends (`kill -9` too). Before
//! making a temporary file, the next writer in the directory removes the temporary files of
//! its kind that nobody locks: the leftovers of a killed writer, never a live writer's
//! (recognised by its lock, never by a process id). A directory lock, shared by writers
//! while they create and lock their file and taken exclusively by that removal, closes the
//! window between a file's creation and its lock.

use std::io::{self, BufWriter, Seek, Write};
use std::path::{Path, PathBuf};

/// The output path that means standard output.
pub const STDOUT: &str = "-";

/// Where an output path leads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Destination {
    /// A regular file or nothing yet: written beside and renamed over.
    Regular,
    /// A character device or a FIFO: written into.
    Stream,
    /// Standard output.
    Stdout,
}

/// What `path` is, or an error for what an output must never be written to.
fn destination(path: &Path) -> io::Result<Destination> {
    if path.as_os_str() == STDOUT {
        return Ok(Destination::Stdout);
    }
    // Following symbolic links: a link to /dev/null is written into, a link to a regular
    // file is replaced as before.
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(Destination::Regular);
    };
    let kind = meta.file_type();
    if kind.is_file() {
        return Ok(Destination::Regular);
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_char_device() || kind.is_fifo() {
            return Ok(Destination::Stream);
        }
        let what = if kind.is_dir() {
            "a directory"
        } else if kind.is_block_device() {
            "a block device"
        } else if kind.is_socket() {
            "a socket"
        } else {
            "not a regular file"
        };
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "it is {what}: outputs are regular files (written beside and renamed), \
                 character devices such as /dev/null, FIFOs, or `-` for standard output"
            ),
        ))
    }
    #[cfg(not(unix))]
    Err(io::Error::new(
        io::ErrorKind::InvalidInput,
        "not a regular file",
    ))
}

/// Whether `path` is standard output or a device or FIFO written into (not a file that
/// appears atomically): for callers that print what they wrote.
pub fn is_stream_output(path: &Path) -> bool {
    matches!(
        destination(path),
        Ok(Destination::Stream | Destination::Stdout)
    )
}

/// Opens a stream destination for writing (never creating or truncating anything).
fn open_stream(path: &Path, destination: Destination) -> io::Result<Box<dyn Write>> {
    Ok(match destination {
        Destination::Stdout => Box::new(io::stdout().lock()),
        _ => Box::new(std::fs::OpenOptions::new().write(true).open(path)?),
    })
}

/// Writing `path` failed; nothing was left at `path` (a previous file there is untouched).
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}", path.display())]
pub struct AtomicWriteError {
    /// Destination that was being written.
    pub path: PathBuf,
    /// What went wrong.
    #[source]
    pub source: io::Error,
}

/// Writes an output atomically: `fill` writes the content into a buffered temporary file next
/// to `path`, which is flushed, synced and renamed over `path` only if `fill` succeeds. A
/// character device or FIFO at `path` is written into instead, `-` ([`STDOUT`]) is standard
/// output, and anything else that is not a regular file is refused (module docs).
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
    let destination = destination(path).map_err(fail)?;
    if destination != Destination::Regular {
        let mut out = BufWriter::new(open_stream(path, destination).map_err(fail)?);
        fill(&mut out).map_err(fail)?;
        return out.flush().map_err(fail);
    }
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
    temp.persist(path).map_err(fail)?;
    Ok(())
}

/// A temporary output file: removed when dropped unless [`persist`](Self::persist)ed, and
/// listed for removal on a signal while it lives ([`crate::cleanup`]).
#[derive(Debug)]
pub struct TemporaryFile {
    file: tempfile::NamedTempFile,
    _registered: crate::cleanup::Registered,
}

/// The suffix of every temporary output.
const TEMP_SUFFIX: &str = ".tmp";

impl TemporaryFile {
    /// The open file.
    pub fn as_file(&self) -> &std::fs::File {
        self.file.as_file()
    }

    /// Where it is.
    pub fn path(&self) -> &Path {
        self.file.path()
    }

    /// Makes it the output `path`: renames it over a regular file (atomically on POSIX file
    /// systems within one directory), or copies it into a character device, a FIFO or
    /// standard output and removes it; refuses anything else (module docs).
    pub fn persist(self, path: &Path) -> io::Result<()> {
        let destination = destination(path)?;
        if destination == Destination::Regular {
            self.file.persist(path).map_err(|e| e.error)?;
            return Ok(());
        }
        let mut file = self.file.reopen()?;
        file.rewind()?;
        let mut out = open_stream(path, destination)?;
        io::copy(&mut file, &mut out)?;
        out.flush()
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
/// renamed over `path` (in the system's temporary directory when `path` is standard output,
/// a device or a FIFO, which are written into, never replaced). Its permissions are those
/// the output would get from a plain `File::create(path)`, as upstream OctoMap's tools give
/// theirs: the mode of the file it replaces, else `0666` less the process's umask (a
/// temporary file alone would be `0600`). It is locked while it lives, and the unlocked
/// temporary files `prefix…tmp` that killed writers left in the directory are removed
/// first (module docs).
pub fn temporary_beside(path: &Path, prefix: &std::ffi::OsStr) -> io::Result<TemporaryFile> {
    let dir = match destination(path)? {
        Destination::Regular => match path.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
            _ => PathBuf::from("."),
        },
        Destination::Stream | Destination::Stdout => std::env::temp_dir(),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(prefix).suffix(TEMP_SUFFIX);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // Created with 0666: open(2) applies the umask, as for any new file.
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let directory_lock = std::fs::File::open(&dir).ok();
    remove_stale(&dir, prefix, Leftover::File, directory_lock.as_ref());
    // Shared while creating and locking (released when `directory_lock` closes).
    if let Some(directory) = &directory_lock {
        let _ = lock(directory, rustix::fs::FlockOperation::LockShared);
    }
    let (temp, registered) =
        crate::cleanup::create_registered(|| builder.tempfile_in(&dir), |temp| temp.path())?;
    // Held until the file is dropped or persisted, and by the kernel until the process ends.
    lock(temp.as_file(), rustix::fs::FlockOperation::LockExclusive)?;
    drop(directory_lock);
    if let Ok(replaced) = std::fs::metadata(path) {
        if replaced.is_file() {
            // A replaced file keeps its mode (set without the umask, as truncating it would).
            temp.as_file().set_permissions(replaced.permissions())?;
        }
    }
    Ok(TemporaryFile {
        file: temp,
        _registered: registered,
    })
}

/// A temporary directory made by [`temporary_dir_in`]: removed with its contents when
/// dropped, locked while it lives.
#[derive(Debug)]
pub struct TemporaryDir {
    // Dropped in this order: the directory goes before its lock is released.
    dir: tempfile::TempDir,
    _lock: std::fs::File,
    _registered: crate::cleanup::Registered,
}

impl TemporaryDir {
    /// Where it is.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    /// Makes it the new directory `path`: syncs the files it holds (not its
    /// subdirectories) and itself, then renames it to `path` unless something is there
    /// already (an error of kind [`io::ErrorKind::AlreadyExists`], the directory left
    /// to be removed on drop), atomically where the system can (`renameat2` with
    /// `RENAME_NOREPLACE`), and syncs `path`'s parent.
    pub fn persist_new(self, path: &Path) -> io::Result<()> {
        for entry in std::fs::read_dir(self.path())? {
            let entry = entry?;
            if entry.file_type()?.is_file() {
                std::fs::File::open(entry.path())?.sync_all()?;
            }
        }
        std::fs::File::open(self.path())?.sync_all()?;
        rename_new(self.path(), path)?;
        // Renamed: nothing to remove any more.
        let Self {
            dir, _registered, ..
        } = self;
        let _ = dir.keep();
        drop(_registered);
        let parent = match path.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => Path::new("."),
        };
        std::fs::File::open(parent)?.sync_all()
    }
}

/// Renames `from` to `to` unless `to` exists (`AlreadyExists`).
fn rename_new(from: &Path, to: &Path) -> io::Result<()> {
    let exists = || {
        io::Error::new(
            io::ErrorKind::AlreadyExists,
            "it already exists, and is not replaced",
        )
    };
    #[cfg(any(target_os = "linux", target_os = "android", target_os = "macos"))]
    {
        use rustix::fs::{renameat_with, RenameFlags, CWD};
        match renameat_with(CWD, from, CWD, to, RenameFlags::NOREPLACE) {
            Ok(()) => return Ok(()),
            Err(rustix::io::Errno::EXIST) => return Err(exists()),
            // A file system without RENAME_NOREPLACE: checked, then renamed below.
            Err(rustix::io::Errno::INVAL | rustix::io::Errno::NOSYS) => {}
            Err(e) => return Err(e.into()),
        }
    }
    if to.symlink_metadata().is_ok() {
        return Err(exists());
    }
    std::fs::rename(from, to)
}

/// A new temporary directory `prefix…` in `parent` (a build's spill files), removed when
/// dropped and registered for removal on a signal ([`crate::cleanup`]). As the files of
/// [`temporary_beside`], it is locked (`flock`) while its writer lives, and the unlocked
/// directories `prefix…` that killed writers left in `parent` are removed first.
pub fn temporary_dir_in(parent: &Path, prefix: &std::ffi::OsStr) -> io::Result<TemporaryDir> {
    make_temporary_dir(parent, prefix, false)
}

/// A new temporary directory in `path`'s parent directory (named `.NAME.…`, `NAME` being
/// `path`'s file name), for an output that is a directory (a ROS 2 bag): filled, then
/// renamed into place by [`TemporaryDir::persist_new`]. Its permissions are those of a
/// plain `mkdir` (`0777` less the umask); it is locked and cleaned up as
/// [`temporary_dir_in`]'s.
pub fn temporary_dir_beside(path: &Path) -> io::Result<TemporaryDir> {
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a directory name"))?;
    let parent = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(name);
    prefix.push(".");
    make_temporary_dir(parent, &prefix, true)
}

fn make_temporary_dir(
    parent: &Path,
    prefix: &std::ffi::OsStr,
    as_mkdir: bool,
) -> io::Result<TemporaryDir> {
    let directory_lock = std::fs::File::open(parent).ok();
    remove_stale(parent, prefix, Leftover::Directory, directory_lock.as_ref());
    if let Some(directory) = &directory_lock {
        let _ = lock(directory, rustix::fs::FlockOperation::LockShared);
    }
    let mut builder = tempfile::Builder::new();
    builder.prefix(prefix);
    #[cfg(unix)]
    if as_mkdir {
        use std::os::unix::fs::PermissionsExt;
        // mkdir(2) applies the umask.
        builder.permissions(std::fs::Permissions::from_mode(0o777));
    }
    #[cfg(not(unix))]
    let _ = as_mkdir;
    let (dir, registered) =
        crate::cleanup::create_registered(|| builder.tempdir_in(parent), |dir| dir.path())?;
    let held = std::fs::File::open(dir.path())?;
    lock(&held, rustix::fs::FlockOperation::LockExclusive)?;
    drop(directory_lock);
    Ok(TemporaryDir {
        dir,
        _lock: held,
        _registered: registered,
    })
}

/// Removes the directories `prefix…` in `parent` that killed writers of
/// [`temporary_dir_in`] left (unlocked), without making one: for a writer that may never
/// need its own (a build that stays within its memory budget). Best effort.
pub fn remove_stale_temporary_dirs(parent: &Path, prefix: &std::ffi::OsStr) {
    let directory_lock = std::fs::File::open(parent).ok();
    remove_stale(parent, prefix, Leftover::Directory, directory_lock.as_ref());
}

/// Removes the temporary files `prefix…tmp` in `parent` that a killed writer of
/// [`temporary_beside`] left (unlocked), without making one: for a writer whose next
/// outputs do not go through a temporary file (a living file's commits). Best effort.
pub fn remove_stale_temporary_files(parent: &Path, prefix: &std::ffi::OsStr) {
    let directory_lock = std::fs::File::open(parent).ok();
    remove_stale(parent, prefix, Leftover::File, directory_lock.as_ref());
}

fn lock(file: &std::fs::File, operation: rustix::fs::FlockOperation) -> io::Result<()> {
    rustix::fs::flock(file, operation).map_err(io::Error::from)
}

/// What a writer keeps in a directory while it lives: a temporary file `prefix…tmp` or a
/// temporary directory `prefix…`.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Leftover {
    File,
    Directory,
}

/// Removes the temporary files `prefix…tmp` (or directories `prefix…`) in `dir` that no
/// live writer locks (a killed writer's), under the directory's exclusive lock so that no
/// writer is between creating its file and locking it. Best effort: what cannot be opened,
/// locked or removed stays.
fn remove_stale(
    dir: &Path,
    prefix: &std::ffi::OsStr,
    kind: Leftover,
    directory_lock: Option<&std::fs::File>,
) {
    use rustix::fs::FlockOperation::{LockExclusive, NonBlockingLockExclusive};
    let Some(directory_lock) = directory_lock else {
        return;
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let prefix = prefix.as_encoded_bytes();
    let stale: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .filter(|entry| {
            let name = entry.file_name();
            let name = name.as_encoded_bytes();
            name.starts_with(prefix)
                && match kind {
                    Leftover::File => {
                        name.ends_with(TEMP_SUFFIX.as_bytes())
                            && entry.file_type().is_ok_and(|t| t.is_file())
                    }
                    Leftover::Directory => entry.file_type().is_ok_and(|t| t.is_dir()),
                }
        })
        .map(|entry| entry.path())
        .collect();
    if stale.is_empty() || lock(directory_lock, LockExclusive).is_err() {
        return;
    }
    for path in stale {
        let Ok(file) = std::fs::File::open(&path) else {
            continue;
        };
        // Locked: a live writer's. Unlocked: its writer is gone (a writer locks its file
        // before releasing its shared hold on the directory).
        if lock(&file, NonBlockingLockExclusive).is_ok() {
            let _ = match kind {
                Leftover::File => std::fs::remove_file(&path),
                Leftover::Directory => std::fs::remove_dir_all(&path),
            };
        }
    }
    let _ = lock(directory_lock, rustix::fs::FlockOperation::Unlock);
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    fn mode(path: &Path) -> u32 {
        std::fs::metadata(path).map_or(0, |m| m.permissions().mode() & 0o777)
    }

    /// A directory output appears whole under its name, with a plain mkdir's mode, and
    /// never replaces anything there (an empty directory, a file): the temporary one is
    /// removed instead.
    #[test]
    fn directory_outputs_are_renamed_into_place_never_over_anything() {
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain");
        std::fs::create_dir(&plain).unwrap();
        let bag = dir.path().join("bag");
        let temp = temporary_dir_beside(&bag).unwrap();
        std::fs::write(temp.path().join("a"), b"a").unwrap();
        temp.persist_new(&bag).unwrap();
        assert_eq!(std::fs::read(bag.join("a")).unwrap(), b"a");
        assert_eq!(mode(&bag), mode(&plain));
        for taken in [plain.clone(), bag.clone(), dir.path().join("file")] {
            if !taken.exists() {
                std::fs::write(&taken, b"kept").unwrap();
            }
            let temp = temporary_dir_beside(&taken).unwrap();
            std::fs::write(temp.path().join("b"), b"b").unwrap();
            let err = temp.persist_new(&taken).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::AlreadyExists, "{taken:?}");
        }
        let mut names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        assert_eq!(names, ["bag", "file", "plain"]);
        assert!(std::fs::read_dir(&plain).unwrap().next().is_none());
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

#[cfg(all(test, unix))]
#[allow(clippy::unwrap_used)] // tests fail by panicking
mod destination_tests {
    use super::*;
    use std::os::unix::fs::FileTypeExt;

    fn mkfifo(path: &Path) {
        let made = std::process::Command::new("mkfifo")
            .arg(path)
            .status()
            .unwrap();
        assert!(made.success());
    }

    #[test]
    fn a_fifo_is_written_into_never_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        mkfifo(&fifo);
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(fifo).unwrap())
        };
        write_atomically(&fifo, |out| out.write_all(b"through the pipe")).unwrap();
        assert_eq!(reader.join().unwrap(), b"through the pipe");
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
        // Written in several steps (a temporary file copied in at the end).
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(fifo).unwrap())
        };
        let mut temp = temporary_beside(&fifo, std::ffi::OsStr::new(".x-")).unwrap();
        temp.write_all(b"copied").unwrap();
        temp.persist(&fifo).unwrap();
        assert_eq!(reader.join().unwrap(), b"copied");
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(left.len(), 1, "no temporary file beside the FIFO");
    }

    #[test]
    fn dev_null_stays_a_device_and_other_special_files_are_refused() {
        let null = Path::new("/dev/null");
        write_atomically(null, |out| out.write_all(b"gone")).unwrap();
        let mut temp = temporary_beside(null, std::ffi::OsStr::new(".x-")).unwrap();
        assert!(
            !temp.path().starts_with("/dev"),
            "{}",
            temp.path().display()
        );
        temp.write_all(b"gone").unwrap();
        temp.persist(null).unwrap();
        assert!(std::fs::metadata(null)
            .unwrap()
            .file_type()
            .is_char_device());
        let dir = tempfile::tempdir().unwrap();
        // The reason is the cause (an io::Error), printed after the path by the chain.
        let err = write_atomically(dir.path(), |out| out.write_all(b"x")).unwrap_err();
        let message = crate::error_message(&err);
        assert_eq!(message.matches("a directory").count(), 1, "{message}");
        let socket = dir.path().join("socket");
        let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
        let err = write_atomically(&socket, |out| out.write_all(b"x")).unwrap_err();
        let message = crate::error_message(&err);
        assert_eq!(message.matches("a socket").count(), 1, "{message}");
        assert!(std::fs::metadata(&socket).unwrap().file_type().is_socket());
        assert!(is_stream_output(null) && is_stream_output(Path::new(STDOUT)));
        assert!(!is_stream_output(&dir.path().join("new.bt")));
    }

    #[test]
    fn unlocked_leftovers_are_removed_and_a_live_writers_file_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("map.bt");
        // What a killed writer left: unlocked.
        let stale = dir.path().join(".map.bt.killed.tmp");
        std::fs::write(&stale, b"half").unwrap();
        // A live writer's file (this test holds its lock).
        let live = temporary_beside(&out, std::ffi::OsStr::new(".map.bt.")).unwrap();
        assert!(!stale.exists(), "removed by the next writer");
        // Another writer's kind of temporary file is left alone.
        let other = dir.path().join(".other.bt.killed.tmp");
        std::fs::write(&other, b"half").unwrap();
        write_atomically(&out, |o| o.write_all(b"map")).unwrap();
        assert!(
            live.path().exists(),
            "a live writer's file is never removed"
        );
        assert!(other.exists());
        assert_eq!(std::fs::read(&out).unwrap(), b"map");
    }

    #[test]
    fn unlocked_leftover_directories_are_removed_and_a_live_writers_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let prefix = std::ffi::OsStr::new(".spill-");
        // What a killed writer left: unlocked, with a file in it.
        let stale = dir.path().join(".spill-killed");
        std::fs::create_dir(&stale).unwrap();
        std::fs::write(stale.join("part"), b"half").unwrap();
        let live = temporary_dir_in(dir.path(), prefix).unwrap();
        assert!(!stale.exists(), "removed by the next writer");
        assert!(live.path().is_dir());
        // Another kind of directory is left alone; a live writer's is never removed.
        let other = dir.path().join(".other-killed");
        std::fs::create_dir(&other).unwrap();
        remove_stale_temporary_dirs(dir.path(), prefix);
        let second = temporary_dir_in(dir.path(), prefix).unwrap();
        assert!(
            live.path().is_dir(),
            "a live writer's directory is never removed"
        );
        assert!(other.is_dir());
        let (first, second) = (live.path().to_path_buf(), second.path().to_path_buf());
        drop(live);
        assert!(!first.exists() && second.exists());
    }
}
