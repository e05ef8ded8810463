//! Probing: how sure a format is that bytes are its own, and the bytes a probe sees.

use crate::error::FormatError;
use crate::file_kind::check_regular_file;
use std::path::Path;

/// How sure a probe is that bytes are of its format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Confidence {
    /// Not this format.
    No,
    /// Could be (a weak signature, e.g. a headerless legacy layout).
    Weak,
    /// The format's own signature.
    Certain,
}

/// How many bytes of a file [`FormatRegistry::identify_file`](crate::FormatRegistry::identify_file) reads: every probe needs at
/// most the first line of a header.
pub const PROBE_BYTES: u64 = 4096;

/// The first [`PROBE_BYTES`] of a regular file, for the probes.
pub(crate) fn file_head(path: &Path) -> Result<Vec<u8>, FormatError> {
    use std::io::Read;
    check_regular_file(path)?;
    let mut head = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(PROBE_BYTES).read_to_end(&mut head))
        .map_err(|source| FormatError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    Ok(head)
}
