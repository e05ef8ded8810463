//! Safe bindings to the upstream OctoMap C++ library (Debian's `liboctomap-dev` 1.9.7).
//!
//! OctoMap is almost entirely templates, so this crate binds a thin C++ shim of plain
//! functions over `octomap::OcTree` (`shim/octomap_shim.{h,cc}`) with `cxx`. The shim
//! catches every C++ exception and turns it into an [`OctomapError`]; the bytes of every file
//! are first checked by the pure-Rust parser of `froctomap-octomap-codec`, because upstream's
//! readers recurse without bound and read past the end of truncated data (undefined
//! behaviour, in practice a crash), which no exception handler can catch.
//!
//! Upstream quirks handled deliberately:
//! * `writeBinary` mutates the tree (maximum likelihood, then `prune()`).
//!   [`OcTree::write_binary`] does the same, so its output matches upstream tools byte for
//!   byte; [`OcTree::write_binary_unchanged`] writes without touching the tree.
//! * `readBinary` reports failure when the header's `size` disagrees with the data but
//!   leaves the tree fully loaded. Such files exist in the wild (`size 1` from ROS scripts),
//!   so when the data itself is complete the tree is accepted with a warning.
//! * The Debian build prints debug lines to stderr. The shim redirects C `stderr` and
//!   `std::cerr` (process-wide, once, on first use) into per-thread buffers: the text never
//!   reaches the terminal and is attached to errors as the library's own explanation.
//!
//! ```
//! use froctomap_octomap_ffi::OcTree;
//! use froctomap_core::{Leaf, Snapshot, VoxelKey};
//!
//! let snapshot = Snapshot::from_leaves(0.1, vec![
//!     Leaf::voxel(VoxelKey::new(32768, 32768, 32768), 3.5),
//!     Leaf::containing(VoxelKey::new(32000, 32000, 32000), 13, -2.0),
//! ])?;
//! let tree = OcTree::from_snapshot(&snapshot)?;
//! assert_eq!(tree.leaf_count(), 2);
//! let bytes = tree.write_full()?;                // a .ot file, as upstream writes it
//! let loaded = OcTree::read_full(&bytes)?;       // read back by upstream
//! assert_eq!(loaded.tree.to_snapshot()?, snapshot);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

// The cxx bridge is the one place that needs `unsafe`: declaring the C++ functions.
#[allow(unsafe_code)]
mod bridge;

use bridge::ffi;
use cxx::UniquePtr;
use froctomap_core::{write_atomically, AtomicWriteError, Leaf, MapError, Snapshot, VoxelKey};
use froctomap_octomap_codec::{CodecError, FileKind, ReadLimits};
use std::path::Path;

pub use bridge::ffi::{LeafRecord, OccupancyParameters};

/// Why an OctoMap operation failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OctomapError {
    /// The bytes are not a readable OctoMap file (found before calling the library).
    #[error(transparent)]
    Malformed(#[from] CodecError),
    /// The C++ library reported an error or threw.
    #[error("{message}{}", library_note(output))]
    Library {
        /// What failed.
        message: String,
        /// What the library printed meanwhile (its own explanation), possibly empty.
        output: String,
    },
    /// Leaves that do not form a valid tree.
    #[error("invalid map")]
    InvalidMap(#[from] MapError),
    /// An argument out of range.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// Reading a file failed.
    #[error("cannot read {}", path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// Writing a file failed.
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
}

fn library_note(output: &str) -> String {
    let lines: Vec<&str> = output
        .lines()
        .map(str::trim)
        .filter(|line| line.starts_with("ERROR") || line.starts_with("WARNING"))
        .collect();
    if lines.is_empty() {
        String::new()
    } else {
        format!(" (OctoMap says: {})", lines.join("; "))
    }
}

/// A tree just read, with what is worth telling the user about the file.
pub struct LoadedTree {
    /// The tree.
    pub tree: OcTree,
    /// Things upstream would warn about or silently tolerate (size mismatch, trailing bytes,
    /// unknown header keywords, legacy header).
    pub warnings: Vec<String>,
}

impl std::fmt::Debug for LoadedTree {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadedTree")
            .field("tree", &self.tree)
            .field("warnings", &self.warnings)
            .finish()
    }
}

/// An `octomap::OcTree` owned by Rust.
pub struct OcTree {
    inner: UniquePtr<ffi::ShimTree>,
}

impl std::fmt::Debug for OcTree {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OcTree")
            .field("resolution", &self.resolution())
            .field("nodes", &self.node_count())
            .finish()
    }
}

/// Runs a shim call, turning its exception and captured output into an [`OctomapError`].
fn call<T>(
    what: &str,
    f: impl FnOnce(&mut Vec<u8>) -> Result<T, cxx::Exception>,
) -> Result<T, OctomapError> {
    let mut log = Vec::new();
    f(&mut log).map_err(|exception| OctomapError::Library {
        message: format!("{what}: {}", exception.what()),
        output: String::from_utf8_lossy(&log).into_owned(),
    })
}

fn non_null(tree: UniquePtr<ffi::ShimTree>, what: &str) -> Result<OcTree, OctomapError> {
    if tree.is_null() {
        return Err(OctomapError::Library {
            message: format!("{what}: the shim returned no tree"),
            output: String::new(),
        });
    }
    Ok(OcTree { inner: tree })
}

fn check_resolution(resolution: f64) -> Result<f64, OctomapError> {
    Ok(froctomap_core::validate_resolution(resolution)?)
}

impl OcTree {
    /// An empty tree.
    pub fn new(resolution: f64) -> Result<Self, OctomapError> {
        let resolution = check_resolution(resolution)?;
        let tree = call("creating a tree", |log| ffi::new_tree(resolution, log))?;
        non_null(tree, "creating a tree")
    }

    /// A deep copy.
    pub fn try_clone(&self) -> Result<Self, OctomapError> {
        let tree = call("copying a tree", |log| ffi::clone_tree(self.tree(), log))?;
        non_null(tree, "copying a tree")
    }

    /// Reads a `.bt` file's bytes with `OcTree::readBinary`.
    pub fn read_binary(bytes: &[u8]) -> Result<LoadedTree, OctomapError> {
        Self::read_binary_with_limits(bytes, ReadLimits::default())
    }

    /// [`OcTree::read_binary`] with explicit resource limits.
    pub fn read_binary_with_limits(
        bytes: &[u8],
        limits: ReadLimits,
    ) -> Result<LoadedTree, OctomapError> {
        let checked = check_stream(bytes, FileKind::Binary, limits)?;
        let mut complete = false;
        let tree = call("OctoMap could not read the .bt data", |log| {
            ffi::read_binary(bytes, log, &mut complete)
        })?;
        let tree = non_null(tree, "reading .bt data")?;
        // The data was checked to be complete, so a `false` here can only be the size
        // mismatch the checker already reported; anything else is a disagreement.
        if !complete && checked.node_count == u64::from(checked.header.declared_size) {
            return Err(OctomapError::Library {
                message: "OctoMap rejected .bt data that froctomap's parser accepted".into(),
                output: String::new(),
            });
        }
        Self::confirm_node_count(&tree, checked.node_count)?;
        Ok(LoadedTree {
            tree,
            warnings: checked.warnings,
        })
    }

    /// Reads a `.ot` file's bytes as upstream's `AbstractOcTree::read` does (OcTree only).
    pub fn read_full(bytes: &[u8]) -> Result<LoadedTree, OctomapError> {
        Self::read_full_with_limits(bytes, ReadLimits::default())
    }

    /// [`OcTree::read_full`] with explicit resource limits.
    pub fn read_full_with_limits(
        bytes: &[u8],
        limits: ReadLimits,
    ) -> Result<LoadedTree, OctomapError> {
        let checked = check_stream(bytes, FileKind::Full, limits)?;
        let tree = call("OctoMap could not read the .ot data", |log| {
            ffi::read_full(bytes, log)
        })?;
        let tree = non_null(tree, "reading .ot data")?;
        Self::confirm_node_count(&tree, checked.node_count)?;
        Ok(LoadedTree {
            tree,
            warnings: checked.warnings,
        })
    }

    /// Reads `.bt` or `.ot` bytes, telling them apart by the first line (never by name).
    pub fn read(bytes: &[u8]) -> Result<LoadedTree, OctomapError> {
        match froctomap_octomap_codec::detect_kind(bytes) {
            Some(FileKind::Full) => Self::read_full(bytes),
            _ => Self::read_binary(bytes),
        }
    }

    /// Reads a `.bt` or `.ot` file (detected by content). Errors name the file.
    pub fn read_file(path: &Path) -> Result<LoadedTree, OctomapError> {
        let bytes = std::fs::read(path).map_err(|source| OctomapError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::read(&bytes)
    }

    fn confirm_node_count(tree: &OcTree, expected: u64) -> Result<(), OctomapError> {
        if tree.node_count() != expected {
            return Err(OctomapError::Library {
                message: format!(
                    "OctoMap loaded {} nodes where froctomap's parser counted {expected}",
                    tree.node_count()
                ),
                output: String::new(),
            });
        }
        Ok(())
    }

    /// Writes `.bt` bytes with upstream's `writeBinary`, which first converts the tree to
    /// maximum likelihood and prunes it, *changing this tree* exactly as upstream tools do.
    pub fn write_binary(&mut self) -> Result<Vec<u8>, OctomapError> {
        let tree = self.tree_mut()?;
        call("OctoMap could not write .bt data", |log| {
            ffi::write_binary(tree, log)
        })
    }

    /// Writes `.bt` bytes with `writeBinaryConst`: this tree is untouched, and the output is
    /// neither pruned nor converted (leaves keep their split; states are thresholded).
    pub fn write_binary_unchanged(&self) -> Result<Vec<u8>, OctomapError> {
        call("OctoMap could not write .bt data", |log| {
            ffi::write_binary_unchanged(self.tree(), log)
        })
    }

    /// Writes `.ot` bytes with `AbstractOcTree::write`.
    pub fn write_full(&self) -> Result<Vec<u8>, OctomapError> {
        call("OctoMap could not write .ot data", |log| {
            ffi::write_full(self.tree(), log)
        })
    }

    /// [`OcTree::write_binary`] to a file, atomically (temporary file, then rename).
    pub fn write_binary_file(&mut self, path: &Path) -> Result<(), OctomapError> {
        let bytes = self.write_binary()?;
        Ok(write_atomically(path, |out| out.write_all(&bytes))?)
    }

    /// [`OcTree::write_full`] to a file, atomically (temporary file, then rename).
    pub fn write_full_file(&self, path: &Path) -> Result<(), OctomapError> {
        let bytes = self.write_full()?;
        Ok(write_atomically(path, |out| out.write_all(&bytes))?)
    }

    /// Edge length of a voxel in metres.
    pub fn resolution(&self) -> f64 {
        ffi::resolution(self.tree())
    }

    /// Number of levels below the root (16 for every OcTree).
    pub fn tree_depth(&self) -> u32 {
        ffi::tree_depth(self.tree())
    }

    /// Number of nodes, inner and leaf (upstream's `size()`).
    pub fn node_count(&self) -> u64 {
        ffi::node_count(self.tree())
    }

    /// Number of leaves (upstream's `getNumLeafNodes()`).
    pub fn leaf_count(&self) -> u64 {
        ffi::leaf_count(self.tree())
    }

    /// Occupancy threshold, sensor model and clamping bounds.
    pub fn occupancy_parameters(&self) -> OccupancyParameters {
        ffi::occupancy_parameters(self.tree())
    }

    /// Sets the occupancy parameters; every probability must lie strictly between 0 and 1
    /// and the clamping bounds must be ordered.
    pub fn set_occupancy_parameters(
        &mut self,
        parameters: &OccupancyParameters,
    ) -> Result<(), OctomapError> {
        let p = parameters;
        let probabilities = [
            p.occupancy_threshold,
            p.prob_hit,
            p.prob_miss,
            p.clamping_min,
            p.clamping_max,
        ];
        if probabilities.iter().any(|v| !(*v > 0.0 && *v < 1.0)) || p.clamping_min > p.clamping_max
        {
            return Err(OctomapError::InvalidArgument(format!(
                "occupancy parameters must be probabilities in (0, 1) with clamping_min <= clamping_max: {p:?}"
            )));
        }
        let tree = self.tree_mut()?;
        call("setting occupancy parameters", |log| {
            ffi::set_occupancy_parameters(tree, parameters, log)
        })
    }

    /// Every leaf in Morton order, in one call.
    pub fn leaf_records(&self) -> Result<Vec<LeafRecord>, OctomapError> {
        call("exporting leaves", |log| {
            ffi::export_leaves(self.tree(), log)
        })
    }

    /// Builds a tree from leaves (any order). Inner nodes get the maximum of their children,
    /// as upstream's `.bt` reader sets them. The tree is neither pruned nor expanded: each
    /// leaf becomes exactly one node.
    pub fn from_leaf_records(resolution: f64, leaves: &[LeafRecord]) -> Result<Self, OctomapError> {
        let snapshot =
            Snapshot::from_leaves(resolution, leaves.iter().map(LeafRecord::to_leaf).collect())?;
        Self::from_snapshot(&snapshot)
    }

    /// Builds a tree holding exactly the snapshot's leaves.
    pub fn from_snapshot(snapshot: &Snapshot) -> Result<Self, OctomapError> {
        let resolution = check_resolution(snapshot.resolution())?;
        let records: Vec<LeafRecord> = snapshot
            .leaves()
            .iter()
            .map(LeafRecord::from_leaf)
            .collect();
        let tree = call("building a tree", |log| {
            ffi::build_tree(resolution, &records, log)
        })?;
        non_null(tree, "building a tree")
    }

    /// The tree as a snapshot: its resolution and every leaf with its log-odds value.
    pub fn to_snapshot(&self) -> Result<Snapshot, OctomapError> {
        let leaves = self
            .leaf_records()?
            .iter()
            .map(LeafRecord::to_leaf)
            .collect();
        Ok(Snapshot::from_leaves(self.resolution(), leaves)?)
    }

    /// Log-odds of the node containing a voxel, `None` when unknown (upstream's `search`).
    pub fn search(&self, key: VoxelKey) -> Option<f32> {
        let mut log_odds = 0.0;
        ffi::search(self.tree(), key.x, key.y, key.z, &mut log_odds).then_some(log_odds)
    }

    /// Upstream `prune()`: merges eight equal leaf children into their parent, level by level
    /// from the bottom, stopping at the first level where nothing merged.
    pub fn prune(&mut self) -> Result<(), OctomapError> {
        let tree = self.tree_mut()?;
        call("pruning", |log| ffi::prune(tree, log))
    }

    /// Upstream `expand()`: splits every coarse leaf down to single voxels. Refused when the
    /// result would exceed `max_leaves` (a coarse leaf near the root covers up to 2^45 voxels).
    pub fn expand(&mut self, max_leaves: u64) -> Result<(), OctomapError> {
        let voxels: u64 = self
            .leaf_records()?
            .iter()
            .map(|leaf| froctomap_core::voxels_per_node(leaf.depth.min(16)))
            .sum();
        if voxels > max_leaves {
            return Err(OctomapError::InvalidArgument(format!(
                "expanding would create {voxels} leaves, more than the limit of {max_leaves}"
            )));
        }
        let tree = self.tree_mut()?;
        call("expanding", |log| ffi::expand(tree, log))
    }

    /// Upstream `toMaxLikelihood()`: every node set to the clamping bound of its state.
    pub fn to_max_likelihood(&mut self) -> Result<(), OctomapError> {
        let tree = self.tree_mut()?;
        call("converting to maximum likelihood", |log| {
            ffi::to_max_likelihood(tree, log)
        })
    }

    /// Upstream `updateInnerOccupancy()`: inner nodes set to the maximum of their children.
    pub fn update_inner_occupancy(&mut self) -> Result<(), OctomapError> {
        let tree = self.tree_mut()?;
        call("updating inner nodes", |log| {
            ffi::update_inner_occupancy(tree, log)
        })
    }

    fn tree(&self) -> &ffi::ShimTree {
        // Every constructor checks for null, so the pointer is always valid.
        self.inner
            .as_ref()
            .unwrap_or_else(|| unreachable!("OcTree holds a null tree"))
    }

    fn tree_mut(&mut self) -> Result<std::pin::Pin<&mut ffi::ShimTree>, OctomapError> {
        self.inner.as_mut().ok_or_else(|| OctomapError::Library {
            message: "the tree is null".into(),
            output: String::new(),
        })
    }
}

/// Runs the pure-Rust parser over the whole file so that malformed data never reaches the
/// C++ reader.
fn check_stream(
    bytes: &[u8],
    kind: FileKind,
    limits: ReadLimits,
) -> Result<froctomap_octomap_codec::ScanSummary, OctomapError> {
    Ok(froctomap_octomap_codec::scan(
        bytes,
        Some(kind),
        limits,
        &mut |_| {},
    )?)
}

impl LeafRecord {
    /// The core leaf this record describes.
    pub fn to_leaf(&self) -> Leaf {
        Leaf::containing(
            VoxelKey::new(self.x, self.y, self.z),
            self.depth,
            self.log_odds,
        )
    }

    /// The record of a core leaf.
    pub fn from_leaf(leaf: &Leaf) -> Self {
        let key = leaf.min_key();
        Self {
            x: key.x,
            y: key.y,
            z: key.z,
            depth: leaf.depth,
            log_odds: leaf.log_odds,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::said_twice;

    /// Every variant, as its chain prints: no text repeats another of the chain and none is
    /// empty.
    #[test]
    fn every_error_is_said_once() {
        let io = || std::io::Error::other("disk full");
        let all = [
            OctomapError::Malformed(CodecError::Empty),
            OctomapError::Library {
                message: "readBinary failed".into(),
                output: "ERROR: data stream not readable\n".into(),
            },
            OctomapError::InvalidMap(MapError::InvalidResolution(0.0)),
            OctomapError::InvalidArgument("resolution -1".into()),
            OctomapError::Io {
                path: "a.bt".into(),
                source: io(),
            },
            OctomapError::Write(AtomicWriteError {
                path: "a.bt".into(),
                source: io(),
            }),
        ];
        for e in &all {
            // Fails to compile when a variant is added and not listed above.
            match e {
                OctomapError::Malformed(_)
                | OctomapError::Library { .. }
                | OctomapError::InvalidMap(_)
                | OctomapError::InvalidArgument(_)
                | OctomapError::Io { .. }
                | OctomapError::Write(_) => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        assert_eq!(
            froctomap_core::error_message(&all[4]),
            "cannot read a.bt: disk full"
        );
    }
}
