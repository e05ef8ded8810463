//! Errors of reading and writing FROctomap files.

use froctomap_core::MapError;
use froctomap_temporal::TemporalError;
use std::path::PathBuf;

/// What is wrong with a file's bytes, independent of where the file is.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FormatViolation {
    /// Bytes were damaged: a checksum does not match.
    #[error("checksum mismatch in the {0} (the file is damaged)")]
    Checksum(&'static str),
    /// The structure is invalid (bad magic, impossible value, truncated part).
    #[error("corrupt {what}: {detail}")]
    Corrupt {
        /// Which part of the file.
        what: &'static str,
        /// What is wrong with it.
        detail: String,
    },
    /// A count or length beyond a configured maximum.
    #[error("limit exceeded: {what} is {value}, at most {limit} allowed (see ReadLimits)")]
    Limit {
        /// Which quantity.
        what: &'static str,
        /// Its value in the file.
        value: u64,
        /// The maximum.
        limit: u64,
    },
    /// A major version this reader does not understand.
    #[error(
        "unsupported FROctomap version {major}.{minor} (this reader understands {supported}.x)"
    )]
    UnsupportedVersion {
        /// Major version found.
        major: u16,
        /// Minor version found.
        minor: u16,
        /// Major version supported.
        supported: u16,
    },
    /// A critical section or value this reader does not implement.
    #[error("unsupported feature: {0} (written by a newer froctomap?)")]
    UnsupportedFeature(String),
    /// The temporal model could not be set up or decode a cell.
    ///
    /// The model's error is this violation's own detail (shown in its message, not a cause
    /// of the chain), as the violation is [`FileError::Invalid`]'s.
    #[error("temporal model: {0}")]
    Model(TemporalError),
}

impl From<TemporalError> for FormatViolation {
    fn from(error: TemporalError) -> Self {
        Self::Model(error)
    }
}

pub(crate) fn corrupt(what: &'static str, detail: impl Into<String>) -> FormatViolation {
    FormatViolation::Corrupt {
        what,
        detail: detail.into(),
    }
}

/// Why reading or writing a FROctomap file failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FileError {
    /// The operating system refused an operation on the file.
    #[error("{}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The file's content is invalid.
    ///
    /// The violation is this error's own detail, shown in its message and returned by
    /// [`violation`](Self::violation), not a separate cause: a chain of causes prints it
    /// once.
    #[error("{}: {violation}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        violation: FormatViolation,
    },
    /// The header handed to a writer holds a value no file may hold.
    #[error("{}", path.display())]
    Header {
        /// The file being written.
        path: PathBuf,
        /// What is wrong with the header.
        #[source]
        source: HeaderError,
    },
    /// A tile was asked for that the file does not have.
    #[error("{}: no tile {tile} (the file has {tiles})", path.display())]
    NoTile {
        /// The file.
        path: PathBuf,
        /// The tile asked for.
        tile: usize,
        /// Tiles in the file.
        tiles: usize,
    },
    /// A segment was asked for that the file (as the reader sees it) does not have.
    #[error("{}: no segment {segment} (the reader sees {segments})", path.display())]
    NoSegment {
        /// The file.
        path: PathBuf,
        /// The segment asked for.
        segment: usize,
        /// Segments the reader sees.
        segments: usize,
    },
    /// Tiles were handed to a writer out of Morton order.
    #[error("{}: tiles must be written in increasing Morton order ({code:#x} after {previous:#x})", path.display())]
    TileOrder {
        /// The file being written.
        path: PathBuf,
        /// Morton code of the tile handed in.
        code: u64,
        /// Morton code of the tile before it.
        previous: u64,
    },
    /// Another writer holds the file (format 2.0 files have one writer at a time).
    #[error("{}: another writer holds this file's lock (an `append` or `record` still running?)", path.display())]
    Locked {
        /// The file.
        path: PathBuf,
    },
    /// Cells could not be encoded as a tile.
    #[error("{}", path.display())]
    TileEncode {
        /// The file being written.
        path: PathBuf,
        /// Why.
        #[source]
        source: TileEncodeError,
    },
    /// The file a writer holds is no longer the one its path names (removed, or replaced
    /// by another): what it committed would be lost with it.
    #[error("{}: the file was removed or replaced while it was open for writing; nothing more is written to it", path.display())]
    Replaced {
        /// The file.
        path: PathBuf,
    },
    /// A segment's samples must come after every sample of the file.
    #[error("{}: a segment starting at {first} does not follow the file's last sample at {last}", path.display())]
    SegmentTime {
        /// The file.
        path: PathBuf,
        /// The segment's first instant.
        first: froctomap_core::Timestamp,
        /// The file's last instant.
        last: froctomap_core::Timestamp,
    },
    /// More samples or segments than a reader accepts ([`ReadLimits`](crate::ReadLimits)).
    #[error("{}: {what} would be {value}, at most {limit} (see ReadLimits)", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Which quantity.
        what: &'static str,
        /// Its value after the write.
        value: u64,
        /// The maximum.
        limit: u64,
    },
    /// A stored tile too large for the index's 32-bit lengths.
    #[error("{}: a stored tile of {len} bytes exceeds 4 GiB", path.display())]
    TileTooLarge {
        /// The file being written.
        path: PathBuf,
        /// Its stored length.
        len: usize,
    },
}

impl FileError {
    /// The format violation, if that is what this error is.
    pub fn violation(&self) -> Option<&FormatViolation> {
        match self {
            FileError::Invalid { violation, .. } => Some(violation),
            _ => None,
        }
    }
}

/// Why a header cannot be written ([`Header::validate`](crate::Header::validate)).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum HeaderError {
    /// The voxel edge length is not a positive finite number.
    #[error(transparent)]
    Resolution(MapError),
    /// Tiles must be octree nodes of depth 1 to 16.
    #[error("tile depth {0} is outside 1..=16")]
    TileDepth(u8),
    /// Toggle blocks of zero samples.
    #[error("toggle blocks must hold at least one sample")]
    EmptyToggleBlocks,
}

/// Why cells cannot be encoded as a tile ([`encode_tile`](crate::encode_tile)).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TileEncodeError {
    /// A tile holds at least one cell.
    #[error("a tile needs at least one cell")]
    NoCells,
    /// A cell deeper than the tree, shallower than the tile, or not aligned to its depth.
    #[error("cell {start:#x} at depth {depth} is not a valid cell of a depth-{tile_depth} tile")]
    InvalidCell {
        /// Morton code of the cell's first voxel.
        start: u64,
        /// The cell's depth.
        depth: u8,
        /// The tiles' depth.
        tile_depth: u8,
    },
    /// Cells must be sorted, disjoint and inside the tile of the first.
    #[error("cell {start:#x} is out of order, overlapping or outside its tile")]
    OutOfPlace {
        /// Morton code of the cell's first voxel.
        start: u64,
    },
    /// A toggle list (an observation mask, outliers or exceptions) reaches past the axis.
    #[error("cell {start:#x}: {list} beyond the time axis")]
    BeyondAxis {
        /// Morton code of the cell's first voxel.
        start: u64,
        /// Which list.
        list: &'static str,
    },
    /// A cell whose mask never observes it has nothing to store.
    #[error("cell {start:#x} is never observed (a cell must be observed at least once)")]
    NeverObserved {
        /// Morton code of the cell's first voxel.
        start: u64,
    },
    /// More than the index's 32-bit counts and lengths can describe.
    #[error("{0} exceeds what a tile can hold (4 GiB, 2^32 cells)")]
    TooLarge(&'static str),
    /// A patch tile needs a base tile with its code.
    #[error("patch tile {code:#x} has no base tile with its code")]
    NoBaseTile {
        /// The tile's code.
        code: u64,
    },
    /// A patch tile's remainder mask with no position would observe the remainder at no
    /// sample; the format reads an empty mask as "every sample" (FORMAT.md §10.6).
    #[error(
        "patch tile {code:#x}: an empty remainder mask observes nothing (None means every sample)"
    )]
    EmptyRemainderMask {
        /// The tile's code.
        code: u64,
    },
    /// A patch tile's remainder runs must be sorted, disjoint and non-empty, and name masks
    /// it has and cells of its base tile (FORMAT.md §10.7).
    #[error("patch tile {code:#x}: remainder runs out of order, empty, or naming a mask or base cell that does not exist")]
    BadRemainderRuns {
        /// The tile's code.
        code: u64,
    },
    /// The compressor failed.
    #[error("zstd compression failed")]
    Compression(#[source] std::io::Error),
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::said_twice;

    fn io() -> std::io::Error {
        std::io::Error::other("disk full")
    }

    fn violations() -> Vec<FormatViolation> {
        let all = vec![
            FormatViolation::Checksum("index"),
            corrupt("header", "bad magic"),
            FormatViolation::Limit {
                what: "tiles",
                value: 9,
                limit: 8,
            },
            FormatViolation::UnsupportedVersion {
                major: 9,
                minor: 0,
                supported: 2,
            },
            FormatViolation::UnsupportedFeature("section 77".into()),
            FormatViolation::Model(TemporalError::Malformed("parameters")),
        ];
        for v in &all {
            match v {
                FormatViolation::Checksum(_)
                | FormatViolation::Corrupt { .. }
                | FormatViolation::Limit { .. }
                | FormatViolation::UnsupportedVersion { .. }
                | FormatViolation::UnsupportedFeature(_)
                | FormatViolation::Model(_) => {}
            }
        }
        all
    }

    fn header_errors() -> Vec<HeaderError> {
        let all = vec![
            HeaderError::Resolution(MapError::InvalidResolution(0.0)),
            HeaderError::TileDepth(17),
            HeaderError::EmptyToggleBlocks,
        ];
        for e in &all {
            match e {
                HeaderError::Resolution(_)
                | HeaderError::TileDepth(_)
                | HeaderError::EmptyToggleBlocks => {}
            }
        }
        all
    }

    fn tile_errors() -> Vec<TileEncodeError> {
        let all = vec![
            TileEncodeError::NoCells,
            TileEncodeError::InvalidCell {
                start: 1,
                depth: 3,
                tile_depth: 4,
            },
            TileEncodeError::OutOfPlace { start: 1 },
            TileEncodeError::BeyondAxis {
                start: 1,
                list: "outliers",
            },
            TileEncodeError::NeverObserved { start: 1 },
            TileEncodeError::TooLarge("the cells"),
            TileEncodeError::NoBaseTile { code: 1 },
            TileEncodeError::EmptyRemainderMask { code: 1 },
            TileEncodeError::BadRemainderRuns { code: 1 },
            TileEncodeError::Compression(io()),
        ];
        for e in &all {
            match e {
                TileEncodeError::NoCells
                | TileEncodeError::InvalidCell { .. }
                | TileEncodeError::OutOfPlace { .. }
                | TileEncodeError::BeyondAxis { .. }
                | TileEncodeError::NeverObserved { .. }
                | TileEncodeError::TooLarge(_)
                | TileEncodeError::NoBaseTile { .. }
                | TileEncodeError::EmptyRemainderMask { .. }
                | TileEncodeError::BadRemainderRuns { .. }
                | TileEncodeError::Compression(_) => {}
            }
        }
        all
    }

    fn file_errors() -> Vec<FileError> {
        let path = || PathBuf::from("a.froct");
        let t = froctomap_core::Timestamp(0);
        let mut all = vec![
            FileError::Io {
                path: path(),
                source: io(),
            },
            FileError::NoTile {
                path: path(),
                tile: 3,
                tiles: 2,
            },
            FileError::NoSegment {
                path: path(),
                segment: 3,
                segments: 2,
            },
            FileError::TileOrder {
                path: path(),
                code: 1,
                previous: 2,
            },
            FileError::Locked { path: path() },
            FileError::Replaced { path: path() },
            FileError::SegmentTime {
                path: path(),
                first: t,
                last: t,
            },
            FileError::TooLarge {
                path: path(),
                what: "segments",
                value: 9,
                limit: 8,
            },
            FileError::TileTooLarge {
                path: path(),
                len: 1 << 33,
            },
        ];
        all.extend(
            violations()
                .into_iter()
                .map(|violation| FileError::Invalid {
                    path: path(),
                    violation,
                }),
        );
        all.extend(header_errors().into_iter().map(|source| FileError::Header {
            path: path(),
            source,
        }));
        all.extend(
            tile_errors()
                .into_iter()
                .map(|source| FileError::TileEncode {
                    path: path(),
                    source,
                }),
        );
        for e in &all {
            match e {
                FileError::Io { .. }
                | FileError::Invalid { .. }
                | FileError::Header { .. }
                | FileError::NoTile { .. }
                | FileError::NoSegment { .. }
                | FileError::TileOrder { .. }
                | FileError::Locked { .. }
                | FileError::Replaced { .. }
                | FileError::TileEncode { .. }
                | FileError::SegmentTime { .. }
                | FileError::TooLarge { .. }
                | FileError::TileTooLarge { .. } => {}
            }
        }
        all
    }

    /// Every variant of every error of this crate, each on its own and as a file's error.
    #[test]
    fn every_error_is_said_once() {
        for e in violations() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        for e in header_errors() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        for e in tile_errors() {
            assert_eq!(said_twice(&e), None, "{e:?}");
        }
        for e in file_errors() {
            assert_eq!(said_twice(&e), None, "{e:?}");
            assert!(froctomap_core::error_message(&e).starts_with("a.froct"));
        }
    }
}
