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
    #[error("{}: cannot read", path.display())]
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
    #[error("{}", path.display())]
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
    #[error("{}: cannot write {format}", path.display())]
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

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::said_twice;

    /// Every variant, as its chain prints: no text repeats another and none is empty.
    #[test]
    fn every_error_is_said_once() {
        let path = || PathBuf::from("a.bt");
        let cause = || -> PluginError { Box::new(std::io::Error::other("disk full")) };
        let all = [
            FormatError::Io {
                path: path(),
                source: std::io::Error::other("disk full"),
            },
            FormatError::NotAFile {
                path: path(),
                kind: "a FIFO",
            },
            FormatError::Unrecognized {
                path: path(),
                reason: "it starts with 00".into(),
            },
            FormatError::SeriesNotMap {
                path: path(),
                format: "froct",
                description: "FROctomap series",
            },
            FormatError::Decode {
                path: path(),
                format: "octomap-binary",
                source: cause(),
            },
            FormatError::Encode {
                path: path(),
                format: "octomap-binary",
                source: cause(),
            },
            FormatError::UnknownFormat {
                name: "ply".into(),
                known: "bt, ot".into(),
            },
            FormatError::UnknownExtension {
                path: path(),
                known: ".bt, .ot".into(),
            },
            FormatError::Unsupported {
                format: "ot",
                action: "written",
            },
        ];
        for e in &all {
            match e {
                FormatError::Io { .. }
                | FormatError::NotAFile { .. }
                | FormatError::Unrecognized { .. }
                | FormatError::SeriesNotMap { .. }
                | FormatError::Decode { .. }
                | FormatError::Encode { .. }
                | FormatError::UnknownFormat { .. }
                | FormatError::UnknownExtension { .. }
                | FormatError::Unsupported { .. } => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        let spool = [
            crate::SpoolError::Io {
                path: path(),
                source: std::io::Error::other("disk full"),
            },
            crate::SpoolError::TooLarge {
                name: "spool".into(),
                index: 1,
                bytes: 9,
                limit: 8,
            },
            crate::SpoolError::NoMap {
                name: "spool".into(),
                index: 1,
            },
        ];
        for e in &spool {
            match e {
                crate::SpoolError::Io { .. }
                | crate::SpoolError::TooLarge { .. }
                | crate::SpoolError::NoMap { .. } => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        // The native OctoMap reader's errors, on their own and as a file's decoding error.
        use crate::octomap_native::NativeError;
        let native = || {
            [
                NativeError::Malformed(froctomap_octomap_codec::CodecError::Empty),
                NativeError::InvalidMap(froctomap_core::MapError::InvalidResolution(0.0)),
            ]
        };
        for e in native() {
            match e {
                NativeError::Malformed(_) | NativeError::InvalidMap(_) => {}
            }
            let decode = FormatError::Decode {
                path: path(),
                format: "bt",
                source: Box::new(e),
            };
            assert_eq!(said_twice(&decode), None, "{decode:?}");
        }
        for e in native() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        let duplicate = DuplicateName {
            kind: "map format",
            name: "bt".into(),
        };
        assert_eq!(said_twice(&duplicate), None);
    }
}
