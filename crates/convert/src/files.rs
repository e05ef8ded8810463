//! Plain file checks and places shared by the stages and the readers: special files refused
//! before they are opened, an input's bytes read within a limit, a FROctomap file's version
//! told from its preamble, and the directory an output is renamed into (and synced).

use crate::error::{ConvertError, SnapshotError};
use froctomap_formats::FormatError;
use std::path::Path;

/// What `path` is when it exists but is not a regular file (symbolic links followed).
pub(crate) fn special_kind(path: &Path) -> Option<&'static str> {
    let metadata = std::fs::metadata(path).ok()?;
    froctomap_formats::special_kind(metadata.file_type())
}

/// Refuses `path`, before it is opened, when it exists but is not a regular file (a FIFO
/// could block the read forever).
pub(crate) fn refuse_special_file(path: &Path) -> Result<(), ConvertError> {
    match special_kind(path) {
        None => Ok(()),
        Some(kind) => Err(ConvertError::NotAFile {
            path: path.to_path_buf(),
            kind,
        }),
    }
}

/// An input file's bytes, refused above `limit` bytes before reading them.
pub(crate) fn read_input(path: &Path, limit: u64) -> Result<Vec<u8>, SnapshotError> {
    let metadata = std::fs::metadata(path).map_err(SnapshotError::Io)?;
    refuse_special(path, &metadata)?;
    let bytes = metadata.len();
    if bytes > limit {
        return Err(SnapshotError::TooLarge { bytes, limit });
    }
    std::fs::read(path).map_err(SnapshotError::Io)
}

/// A FIFO or device is refused before it is opened (reading one may never end).
pub(crate) fn refuse_special(
    path: &Path,
    metadata: &std::fs::Metadata,
) -> Result<(), SnapshotError> {
    match froctomap_formats::special_kind(metadata.file_type()) {
        None => Ok(()),
        Some(kind) => Err(SnapshotError::Format(FormatError::NotAFile {
            path: path.to_path_buf(),
            kind,
        })),
    }
}

/// The directory an output goes into (`.` for a bare file name): where its temporary files,
/// spill data and spooled inputs go unless a directory is given.
///
/// ```
/// use std::path::Path;
/// assert_eq!(froctomap_convert::output_dir(Path::new("maps/a.froct")), Path::new("maps"));
/// assert_eq!(froctomap_convert::output_dir(Path::new("a.froct")), Path::new("."));
/// ```
pub fn output_dir(output: &Path) -> &Path {
    match output.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    }
}

/// `true` when the file at `path` is a format 2.0 file (its preamble's magic and major
/// version); `false` for any other file, including 1.x files and files too short to tell.
pub fn is_living_file(path: &Path) -> Result<bool, ConvertError> {
    use std::io::Read;
    // A FIFO is refused before it is opened (opening one may never return).
    refuse_special_file(path)?;
    let io = |source| {
        ConvertError::File(froctomap_file::FileError::Io {
            path: path.to_path_buf(),
            source,
        })
    };
    let mut head = Vec::with_capacity(12);
    std::fs::File::open(path)
        .map_err(io)?
        .take(12)
        .read_to_end(&mut head)
        .map_err(io)?;
    Ok(head.len() == 12
        && head[..8] == froctomap_file::MAGIC
        && u16::from_le_bytes([head[8], head[9]]) == froctomap_file::LIVING_MAJOR_VERSION)
}

/// Makes a rename in `path`'s directory durable (best effort: not every system can sync a
/// directory).
pub(crate) fn sync_parent(path: &Path) {
    let dir = output_dir(path);
    if let Ok(dir) = std::fs::File::open(dir) {
        let _ = dir.sync_all();
    }
}
