//! Errors of reading and writing map files.

use std::path::PathBuf;

/// A plugin's own error, kept as its typed value behind a trait object so new plugins
/// need no change here.
pub type PluginError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a map file could not be read or written. Every variant that concerns a file names it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FormatError {
    /// The file could not be opened or read.
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A FIFO, device, socket or directory where a map file is expected: refused before
    /// opening (reading a FIFO would wait for a writer forever).
    #[error("{}: {kind}, not a regular file; map files must be regular files", path.display())]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What it is instead (`"a FIFO"`, `"a directory"`…).
        kind: &'static str,
    },
    /// No registered format recognises the content.
    #[error("{}: not a map file of any known format ({reason})", path.display())]
    Unrecognized {
        /// The file.
        path: PathBuf,
        /// What was found instead.
        reason: String,
    },
    /// The file holds a series of maps (a registered [`crate::SeriesFormat`]), not one map.
    #[error("{}: a {description} ({format}), not a single map", path.display())]
    SeriesNotMap {
        /// The file.
        path: PathBuf,
        /// Name of its series format.
        format: &'static str,
        /// What that format is.
        description: &'static str,
    },
    /// The content was recognised (or forced) but is malformed.
    #[error("{}: {source}", path.display())]
    Decode {
        /// The file.
        path: PathBuf,
        /// Format that tried to read it.
        format: &'static str,
        /// What is wrong.
        #[source]
        source: PluginError,
    },
    /// Encoding or writing failed.
    #[error("{}: cannot write {format}: {source}", path.display())]
    Encode {
        /// The destination.
        path: PathBuf,
        /// Format being written.
        format: &'static str,
        /// What went wrong.
        #[source]
        source: PluginError,
    },
    /// A format name that no registered format has.
    #[error("unknown map format `{name}` (known: {known})")]
    UnknownFormat {
        /// The name given.
        name: String,
        /// Registered names.
        known: String,
    },
    /// The output format could not be chosen from the file name.
    #[error("{}: cannot tell the output format from the extension (known: {known})", path.display())]
    UnknownExtension {
        /// The destination.
        path: PathBuf,
        /// Registered extensions.
        known: String,
    },
    /// The chosen format cannot be read or written.
    #[error("format `{format}` cannot be {action}")]
    Unsupported {
        /// The format.
        format: &'static str,
        /// "read" or "written".
        action: &'static str,
    },
}

/// A plugin registered under a name its registry already holds: every registry
/// (map formats, series and recording formats, map sources) refuses it rather than let one
/// plugin shadow another.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("a {kind} named `{name}` is already registered")]
pub struct DuplicateName {
    /// What the registry holds ("map format", "recording format"…).
    pub kind: &'static str,
    /// The name (for a map format, with its backend).
    pub name: String,
}
