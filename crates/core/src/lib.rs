//! The map model shared by every froctomap crate.
//!
//! A [`Snapshot`] is one map at one instant: a resolution and the *known* space as
//! [`Leaf`]s (octree nodes without children, from single voxels up to large cubes), each with
//! an occupancy log-odds value. Space no leaf covers is unknown, never implicitly free.
//! Leaves are addressed by the [`MortonCode`] of their first voxel; Morton order equals
//! OctoMap's depth-first order, so a sorted snapshot streams straight into a `.bt` writer and
//! two snapshots can be merged voxel by voxel in one pass.
//!
//! ```
//! use froctomap_core::{Leaf, Snapshot, VoxelKey, Occupancy};
//! let key = VoxelKey::from_point([1.0, 2.0, 0.5], 0.05).unwrap();
//! let map = Snapshot::from_leaves(0.05, vec![Leaf::voxel(key, Occupancy::Occupied.log_odds())])?;
//! assert_eq!(map.voxels().next(), Some((key.morton(), Occupancy::Occupied)));
//! # Ok::<(), froctomap_core::MapError>(())
//! ```

mod atomic_file;
pub mod calendar;
mod change;
pub mod cleanup;
mod error;
mod error_chain;
mod key;
mod leaf;
mod named;
mod snapshot;
mod time;

pub use atomic_file::{
    is_stream_output, remove_stale_temporary_dirs, remove_stale_temporary_files, temporary_beside,
    temporary_dir_beside, temporary_dir_in, write_atomically, AtomicWriteError, TemporaryDir,
    TemporaryFile, STDOUT,
};
pub use change::{changes, push_merged, StateChange};
pub use error::MapError;
pub use error_chain::{error_chain, error_message, said_twice};
pub use key::{voxels_per_node, MortonCode, VoxelKey, KEY_ORIGIN, TREE_DEPTH};
pub use leaf::{
    defaults, free_log_odds, log_odds, occupied_log_odds, probability, Leaf, Occupancy,
};
pub use named::{parse_named, Named, UnknownName};
pub use snapshot::{validate_resolution, BoundingBox, Snapshot, SnapshotStats};
pub use time::Timestamp;
