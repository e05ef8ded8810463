//! Occupancy leaves: one node of an octree with no children, possibly coarser than a voxel.

use crate::key::{voxels_per_node, MortonCode, VoxelKey, TREE_DEPTH};
use std::fmt;

/// OctoMap's default occupancy parameters, as probabilities. A file does not store them, so
/// every reader and writer uses these (they are what `liboctomap` sets in its constructor).
pub mod defaults {
    /// Occupancy threshold: a node is occupied when its probability is at least this.
    pub const OCCUPANCY_THRESHOLD: f64 = 0.5;
    /// Probability of a sensor hit.
    pub const PROB_HIT: f64 = 0.7;
    /// Probability of a sensor miss.
    pub const PROB_MISS: f64 = 0.4;
    /// Lower clamping bound; free leaves of a `.bt` file read back with this value.
    pub const CLAMPING_MIN: f64 = 0.1192;
    /// Upper clamping bound; occupied leaves of a `.bt` file read back with this value.
    pub const CLAMPING_MAX: f64 = 0.971;
}

/// Log-odds of a probability, computed exactly as OctoMap does (in `f64`, stored as `f32`).
///
/// ```
/// assert_eq!(froctomap_core::log_odds(0.5), 0.0);
/// ```
pub fn log_odds(probability: f64) -> f32 {
    (probability / (1.0 - probability)).ln() as f32
}

/// Probability of a log-odds value (OctoMap's `probability()`).
pub fn probability(log_odds: f32) -> f64 {
    1.0 - 1.0 / (1.0 + f64::from(log_odds).exp())
}

/// Log-odds value a `.bt` reader gives free leaves: `log_odds(CLAMPING_MIN)`.
pub fn free_log_odds() -> f32 {
    log_odds(defaults::CLAMPING_MIN)
}

/// Log-odds value a `.bt` reader gives occupied leaves: `log_odds(CLAMPING_MAX)`.
pub fn occupied_log_odds() -> f32 {
    log_odds(defaults::CLAMPING_MAX)
}

/// The binary state of known space.
///
/// ```
/// use froctomap_core::Occupancy;
/// assert_eq!(Occupancy::from(true), Occupancy::Occupied);
/// assert_eq!(!Occupancy::Occupied, Occupancy::Free);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Occupancy {
    /// Observed empty.
    Free,
    /// Observed occupied.
    Occupied,
}

impl Occupancy {
    /// The state OctoMap assigns a log-odds value (`isNodeOccupied`: at or above threshold 0).
    pub fn from_log_odds(log_odds: f32) -> Self {
        Occupancy::from(log_odds >= 0.0)
    }

    /// The log-odds value a `.bt` file gives this state when read.
    pub fn log_odds(self) -> f32 {
        match self {
            Occupancy::Free => free_log_odds(),
            Occupancy::Occupied => occupied_log_odds(),
        }
    }

    /// `true` for [`Occupancy::Occupied`].
    pub fn is_occupied(self) -> bool {
        self == Occupancy::Occupied
    }
}

impl From<bool> for Occupancy {
    /// `true` is [`Occupancy::Occupied`], `false` [`Occupancy::Free`].
    fn from(occupied: bool) -> Self {
        if occupied {
            Occupancy::Occupied
        } else {
            Occupancy::Free
        }
    }
}

impl std::ops::Not for Occupancy {
    type Output = Occupancy;

    /// The other state.
    fn not(self) -> Occupancy {
        match self {
            Occupancy::Free => Occupancy::Occupied,
            Occupancy::Occupied => Occupancy::Free,
        }
    }
}

impl fmt::Display for Occupancy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Occupancy::Free => "free",
            Occupancy::Occupied => "occupied",
        })
    }
}

/// A node without children: the cube of `8^(16 - depth)` voxels starting at `start`, all
/// with the same log-odds value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leaf {
    /// Morton code of the node's first voxel (its minimum corner).
    pub start: MortonCode,
    /// Depth below the root, 0..=16 (16 = one voxel, 0 = the root without children).
    pub depth: u8,
    /// Occupancy log-odds shared by every voxel of the node.
    pub log_odds: f32,
}

impl Leaf {
    /// A single finest-level voxel.
    pub fn voxel(key: VoxelKey, log_odds: f32) -> Self {
        Self {
            start: key.morton(),
            depth: TREE_DEPTH,
            log_odds,
        }
    }

    /// A leaf from a key inside it (any key of the node, e.g. OctoMap's centre key) and its depth.
    pub fn containing(key: VoxelKey, depth: u8, log_odds: f32) -> Self {
        Self {
            start: key.morton().node_start(depth.min(TREE_DEPTH)),
            depth,
            log_odds,
        }
    }

    /// Binary state of the leaf.
    pub fn occupancy(&self) -> Occupancy {
        Occupancy::from_log_odds(self.log_odds)
    }

    /// Number of voxels the leaf covers.
    pub fn voxel_count(&self) -> u64 {
        voxels_per_node(self.depth)
    }

    /// One past the Morton code of the last voxel.
    pub fn end(&self) -> u64 {
        self.start.0 + self.voxel_count()
    }

    /// Minimum-corner key of the node.
    pub fn min_key(&self) -> VoxelKey {
        self.start.key()
    }

    /// Edge length of the node, in voxels.
    pub fn edge_voxels(&self) -> u32 {
        1 << (TREE_DEPTH - self.depth)
    }

    /// Metric minimum and maximum corners of the cube.
    pub fn bounds(&self, resolution: f64) -> ([f64; 3], [f64; 3]) {
        let min = self
            .min_key()
            .center(resolution)
            .map(|c| c - resolution / 2.0);
        let edge = f64::from(self.edge_voxels()) * resolution;
        (min, min.map(|c| c + edge))
    }

    /// Morton codes of every voxel of the leaf, in order.
    pub fn voxel_codes(&self) -> impl Iterator<Item = MortonCode> {
        (self.start.0..self.end()).map(MortonCode)
    }
}
