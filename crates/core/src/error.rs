//! Errors of the map model.

use crate::key::VoxelKey;

/// Why a set of leaves is not a valid map.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum MapError {
    /// Resolution not finite and positive.
    #[error("invalid resolution {0} (must be a positive number of metres)")]
    InvalidResolution(f64),
    /// A leaf depth greater than 16.
    #[error("leaf depth {depth} is greater than 16")]
    DepthOutOfRange {
        /// The offending depth.
        depth: u8,
    },
    /// A leaf whose start code is not the first voxel of a node at its depth.
    #[error("leaf start code {code:#x} is not aligned to a node at depth {depth}")]
    MisalignedLeaf {
        /// Morton code given as start.
        code: u64,
        /// Depth given.
        depth: u8,
    },
    /// A leaf value that is not a number.
    #[error("leaf at key {key} has a NaN log-odds value")]
    NanLogOdds {
        /// Minimum key of the leaf.
        key: VoxelKey,
    },
    /// Two leaves covering a common voxel.
    #[error("leaves overlap: depth-{first_depth} leaf at key {first} and depth-{second_depth} leaf at key {second}")]
    OverlappingLeaves {
        /// Minimum key of the first leaf.
        first: VoxelKey,
        /// Its depth.
        first_depth: u8,
        /// Minimum key of the second leaf.
        second: VoxelKey,
        /// Its depth.
        second_depth: u8,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::said_twice;

    /// Every variant (the match fails to compile when one is added and not listed here).
    fn every_variant() -> Vec<MapError> {
        let key = VoxelKey::new(1, 2, 3);
        let all = vec![
            MapError::InvalidResolution(0.0),
            MapError::DepthOutOfRange { depth: 17 },
            MapError::MisalignedLeaf { code: 3, depth: 15 },
            MapError::NanLogOdds { key },
            MapError::OverlappingLeaves {
                first: key,
                first_depth: 15,
                second: key,
                second_depth: 16,
            },
        ];
        for error in &all {
            match error {
                MapError::InvalidResolution(_)
                | MapError::DepthOutOfRange { .. }
                | MapError::MisalignedLeaf { .. }
                | MapError::NanLogOdds { .. }
                | MapError::OverlappingLeaves { .. } => {}
            }
        }
        all
    }

    #[test]
    fn every_error_is_said_once() {
        for error in every_variant() {
            assert_eq!(said_twice(&error), None, "{error:?}");
        }
        let write = crate::AtomicWriteError {
            path: "a.froct".into(),
            source: std::io::Error::other("disk full"),
        };
        assert_eq!(said_twice(&write), None);
    }
}
