//! Why an OctoMap byte stream was rejected.

use crate::kind::FileKind;

/// A `.bt`/`.ot` stream that cannot be read. Offsets count bytes from the start of the file.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum CodecError {
    /// The file is empty.
    #[error("the file is empty")]
    Empty,
    /// The first line does not identify the expected layout.
    #[error("not an OctoMap .{} file: its first line is {found:?}, expected {:?}{hint}", kind.extension(), kind.first_line())]
    WrongFirstLine {
        /// Layout that was expected.
        kind: FileKind,
        /// Start of the first line actually found (control characters replaced).
        found: String,
        /// Extra advice, e.g. that the file is of the other layout.
        hint: String,
    },
    /// The header is malformed.
    #[error("malformed .{} header: {reason}", kind.extension())]
    BadHeader {
        /// Layout being read.
        kind: FileKind,
        /// What is wrong.
        reason: String,
    },
    /// A `.ot` file of a tree type whose node layout froctomap does not know (it reads
    /// `OcTree` and `ColorOcTree`, [`TreeType`](crate::TreeType)).
    #[error("unsupported tree type `{0}` (froctomap reads the occupancy of OcTree and ColorOcTree maps)")]
    UnsupportedTreeType(String),
    /// The body ends before the tree does.
    #[error("truncated: the tree data needs more bytes than the file has (a node at offset {offset} needs {needed} bytes, {available} remain)")]
    Truncated {
        /// Offset of the node being read.
        offset: usize,
        /// Bytes the node needs.
        needed: usize,
        /// Bytes left.
        available: usize,
    },
    /// A node at the finest depth (16) claims children.
    #[error(
        "corrupt tree data: a node at depth 16 (a single voxel) has children, at offset {offset}"
    )]
    TooDeep {
        /// Offset of the offending node's data.
        offset: usize,
    },
    /// A `.ot` leaf whose log-odds value is NaN, which no map can hold (reported by [`crate::diff`];
    /// [`crate::scan`] passes values through and the map built from them rejects it).
    #[error("corrupt tree data: a leaf's log-odds value is NaN, at offset {offset}")]
    NotANumber {
        /// Offset of the leaf's data.
        offset: usize,
    },
    /// A configured resource bound was hit.
    #[error("limit exceeded: the tree has more than {limit} nodes (raise the node limit if the file is genuine)")]
    TooManyNodes {
        /// The bound.
        limit: u64,
    },
}

/// Leaves that an encoder cannot turn into an OctoMap tree.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum EncodeError {
    /// The resolution or a leaf is invalid on its own (depth, alignment, NaN value).
    #[error("invalid map")]
    InvalidMap(#[from] froctomap_core::MapError),
    /// A leaf does not come strictly after the previous one in Morton order (it overlaps it
    /// or precedes it). Streaming encoders write depth-first, so order is required.
    #[error("leaves must be pushed in increasing Morton order without overlap: the depth-{next_depth} leaf at key {next} comes after the depth-{previous_depth} leaf at key {previous}")]
    OutOfOrder {
        /// Minimum key of the previous leaf.
        previous: froctomap_core::VoxelKey,
        /// Its depth.
        previous_depth: u8,
        /// Minimum key of the offending leaf.
        next: froctomap_core::VoxelKey,
        /// Its depth.
        next_depth: u8,
    },
    /// A leaf or part given to a [`CanonicalBinaryBuilder`](crate::CanonicalBinaryBuilder)
    /// lies outside the node it builds.
    #[error("the depth-{depth} node at key {node} lies outside the depth-{part_depth} node at key {part} being built")]
    OutsidePart {
        /// Minimum key of the offending node.
        node: froctomap_core::VoxelKey,
        /// Its depth.
        depth: u8,
        /// Minimum key of the node being built.
        part: froctomap_core::VoxelKey,
        /// Its depth.
        part_depth: u8,
    },
    /// Only a part built from the root is a whole `.bt` file.
    #[error("a .bt file is built from the root, not from a node of depth {depth}")]
    NotTheRoot {
        /// Depth of the part's node.
        depth: u8,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::{said_twice, MapError, VoxelKey};

    /// Every variant of both errors, as its chain prints: no text repeats another of the
    /// chain and none is empty (`EncodeError::InvalidMap` prints the map's error once, as its
    /// cause).
    #[test]
    fn every_error_is_said_once() {
        let codec = [
            CodecError::Empty,
            CodecError::WrongFirstLine {
                kind: FileKind::Full,
                found: "# Octomap OcTree binary file".into(),
                hint: " (this is a .bt file)".into(),
            },
            CodecError::BadHeader {
                kind: FileKind::Binary,
                reason: "no `res` line".into(),
            },
            CodecError::UnsupportedTreeType("OcTreeStamped".into()),
            CodecError::Truncated {
                offset: 9,
                needed: 2,
                available: 1,
            },
            CodecError::TooDeep { offset: 9 },
            CodecError::NotANumber { offset: 9 },
            CodecError::TooManyNodes { limit: 8 },
        ];
        for e in &codec {
            // Fails to compile when a variant is added and not listed above.
            match e {
                CodecError::Empty
                | CodecError::WrongFirstLine { .. }
                | CodecError::BadHeader { .. }
                | CodecError::UnsupportedTreeType(_)
                | CodecError::Truncated { .. }
                | CodecError::TooDeep { .. }
                | CodecError::NotANumber { .. }
                | CodecError::TooManyNodes { .. } => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        let key = VoxelKey::new(1, 2, 3);
        let encode = [
            EncodeError::InvalidMap(MapError::InvalidResolution(0.0)),
            EncodeError::OutOfOrder {
                previous: key,
                previous_depth: 16,
                next: key,
                next_depth: 16,
            },
            EncodeError::OutsidePart {
                node: key,
                depth: 16,
                part: key,
                part_depth: 4,
            },
            EncodeError::NotTheRoot { depth: 4 },
        ];
        for e in &encode {
            match e {
                EncodeError::InvalidMap(_)
                | EncodeError::OutOfOrder { .. }
                | EncodeError::OutsidePart { .. }
                | EncodeError::NotTheRoot { .. } => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        assert_eq!(
            froctomap_core::error_message(&encode[0]),
            "invalid map: invalid resolution 0 (must be a positive number of metres)"
        );
    }
}
