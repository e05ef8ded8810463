//! Map files must be regular files: reading a FIFO blocks until a writer comes (forever,
//! for a stray `mkfifo`), and a device may never end. The kind is checked before opening.

use crate::error::FormatError;
use std::fs::FileType;
use std::path::Path;

/// What a file that is not a regular file is, for messages: `"a FIFO"`, `"a directory"`…
pub fn special_kind(file_type: FileType) -> Option<&'static str> {
    if file_type.is_file() {
        return None;
    }
    if file_type.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return Some("a FIFO");
        }
        if file_type.is_socket() {
            return Some("a socket");
        }
        if file_type.is_block_device() || file_type.is_char_device() {
            return Some("a device");
        }
    }
    Some("not a regular file")
}

/// Refuses `path` unless it is a regular file (symbolic links followed), without opening it.
pub(crate) fn check_regular_file(path: &Path) -> Result<(), FormatError> {
    let metadata = std::fs::metadata(path).map_err(|source| FormatError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    match special_kind(metadata.file_type()) {
        None => Ok(()),
        Some(kind) => Err(FormatError::NotAFile {
            path: path.to_path_buf(),
            kind,
        }),
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_pass() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.bt");
        std::fs::write(&file, b"# Octomap OcTree binary file\n").unwrap();
        assert!(check_regular_file(&file).is_ok());
        let err = check_regular_file(dir.path()).unwrap_err();
        assert!(
            matches!(
                err,
                FormatError::NotAFile {
                    kind: "a directory",
                    ..
                }
            ),
            "{err}"
        );
        let err = check_regular_file(Path::new("/dev/null")).unwrap_err();
        assert!(err.to_string().contains("a device"), "{err}");
    }
}
