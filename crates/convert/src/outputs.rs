//! Guards run before an output is written: an output never replaces one of the inputs it is
//! made from, and an export never mixes its maps into a directory that holds other files.

use crate::error::ConvertError;
use std::path::Path;

/// Refuses `output` when it is one of `inputs`: the same path, or the same file reached
/// through a symbolic or hard link (same device and inode). An output that does not exist
/// yet cannot be an input.
///
/// ```
/// use froctomap_convert::{refuse_overwriting_input, ConvertError};
/// let dir = tempfile::tempdir()?;
/// let input = dir.path().join("a.bt");
/// std::fs::write(&input, b"map")?;
/// assert!(matches!(
///     refuse_overwriting_input(&input, [input.as_path()]),
///     Err(ConvertError::OutputIsInput { .. })
/// ));
/// assert!(refuse_overwriting_input(&dir.path().join("b.bt"), [input.as_path()]).is_ok());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn refuse_overwriting_input<'a>(
    output: &Path,
    inputs: impl IntoIterator<Item = &'a Path>,
) -> Result<(), ConvertError> {
    let Ok(written) = std::fs::metadata(output) else {
        return Ok(());
    };
    for input in inputs {
        if input == output || std::fs::metadata(input).is_ok_and(|read| same_file(&read, &written))
        {
            return Err(ConvertError::OutputIsInput {
                output: output.to_path_buf(),
                input: input.to_path_buf(),
            });
        }
    }
    Ok(())
}

#[cfg(unix)]
fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
fn same_file(_: &std::fs::Metadata, _: &std::fs::Metadata) -> bool {
    // Without inode numbers only the paths are compared (above).
    false
}

/// Refuses to export into `dir` when it exists and holds anything, unless `overwrite`: the
/// export's manifest and maps would replace files of the same names.
pub(crate) fn refuse_non_empty_dir(dir: &Path, overwrite: bool) -> Result<(), ConvertError> {
    if overwrite {
        return Ok(());
    }
    let holds_files = std::fs::read_dir(dir).is_ok_and(|mut entries| entries.next().is_some());
    if holds_files {
        return Err(ConvertError::DirectoryNotEmpty {
            dir: dir.to_path_buf(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_to_an_input_are_the_input() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("a.bt");
        std::fs::write(&input, b"map").unwrap();
        let hard = dir.path().join("hard.bt");
        std::fs::hard_link(&input, &hard).unwrap();
        let refused = |output: &Path| {
            matches!(
                refuse_overwriting_input(output, [input.as_path()]),
                Err(ConvertError::OutputIsInput { .. })
            )
        };
        assert!(refused(&input));
        assert!(refused(&hard));
        assert!(refused(&dir.path().join(".").join("a.bt")));
        #[cfg(unix)]
        {
            let soft = dir.path().join("soft.bt");
            std::os::unix::fs::symlink(&input, &soft).unwrap();
            assert!(refused(&soft));
        }
        let other = dir.path().join("b.bt");
        std::fs::write(&other, b"map").unwrap();
        assert!(!refused(&other));
        assert!(!refused(&dir.path().join("new.bt")));
    }

    #[test]
    fn only_empty_or_missing_directories_take_an_export() {
        let dir = tempfile::tempdir().unwrap();
        assert!(refuse_non_empty_dir(&dir.path().join("new"), false).is_ok());
        assert!(refuse_non_empty_dir(dir.path(), false).is_ok());
        std::fs::write(dir.path().join("manifest.csv"), b"path,time\n").unwrap();
        assert!(matches!(
            refuse_non_empty_dir(dir.path(), false),
            Err(ConvertError::DirectoryNotEmpty { .. })
        ));
        assert!(refuse_non_empty_dir(dir.path(), true).is_ok());
    }
}
