//! One map at one instant: resolution plus the known leaves, in Morton order.

use crate::error::MapError;
use crate::key::{voxels_per_node, MortonCode, TREE_DEPTH};
use crate::leaf::{Leaf, Occupancy};

/// A map at one instant: the resolution and every known leaf; space not covered by a leaf is
/// unknown. Leaves are kept sorted in Morton order and never overlap, so iterating them is
/// OctoMap's depth-first order.
///
/// ```
/// use froctomap_core::{Leaf, Occupancy, Snapshot, VoxelKey};
/// let snapshot = Snapshot::from_leaves(0.1, vec![
///     Leaf::voxel(VoxelKey::new(32768, 32768, 32768), 3.5),
///     Leaf::containing(VoxelKey::new(0, 0, 0), 14, -2.0), // a 4x4x4 block of free voxels
/// ])?;
/// assert_eq!(snapshot.leaves()[0].depth, 14); // Morton order, not insertion order
/// let stats = snapshot.stats();
/// assert_eq!((stats.occupied_voxels, stats.free_voxels), (1, 64));
/// assert_eq!(snapshot.state_at(VoxelKey::new(1, 2, 3).morton()), Some(Occupancy::Free));
/// assert_eq!(snapshot.state_at(VoxelKey::new(9, 9, 9).morton()), None);
/// # Ok::<(), froctomap_core::MapError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    resolution: f64,
    leaves: Vec<Leaf>,
}

/// Counts describing a snapshot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SnapshotStats {
    /// Leaves whose state is occupied.
    pub occupied_leaves: u64,
    /// Leaves whose state is free.
    pub free_leaves: u64,
    /// Finest-level voxels covered by occupied leaves.
    pub occupied_voxels: u64,
    /// Finest-level voxels covered by free leaves.
    pub free_voxels: u64,
}

/// An axis-aligned metric box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundingBox {
    /// Minimum corner (x, y, z) in metres.
    pub min: [f64; 3],
    /// Maximum corner (x, y, z) in metres.
    pub max: [f64; 3],
}

impl BoundingBox {
    fn grow(self, other: BoundingBox) -> BoundingBox {
        let mut merged = self;
        for axis in 0..3 {
            merged.min[axis] = merged.min[axis].min(other.min[axis]);
            merged.max[axis] = merged.max[axis].max(other.max[axis]);
        }
        merged
    }
}

/// Checks that a resolution is usable: finite and positive.
pub fn validate_resolution(resolution: f64) -> Result<f64, MapError> {
    if resolution.is_finite() && resolution > 0.0 {
        Ok(resolution)
    } else {
        Err(MapError::InvalidResolution(resolution))
    }
}

impl Snapshot {
    /// An empty map (everything unknown).
    pub fn empty(resolution: f64) -> Result<Self, MapError> {
        Ok(Self {
            resolution: validate_resolution(resolution)?,
            leaves: Vec::new(),
        })
    }

    /// Builds a snapshot from leaves in any order. Fails on an invalid resolution, a depth
    /// greater than 16, a
    /// start code not aligned to its depth, a NaN value or overlapping leaves. A depth-0 leaf
    /// is the root without children: all space at one value (OctoMap can read such a tree).
    pub fn from_leaves(resolution: f64, mut leaves: Vec<Leaf>) -> Result<Self, MapError> {
        validate_resolution(resolution)?;
        // One pass validates every leaf and, for the usual already-sorted input (every
        // reader produces Morton order), also proves order and disjointness.
        let mut sorted_disjoint = true;
        let mut previous_end = 0u64;
        for (i, leaf) in leaves.iter().enumerate() {
            validate_leaf(leaf)?;
            if i > 0 && leaf.start.0 < previous_end {
                sorted_disjoint = false;
            }
            previous_end = leaf.end();
        }
        if !sorted_disjoint {
            leaves.sort_unstable_by_key(|l| l.start);
            if let Some(pair) = leaves.windows(2).find(|p| p[0].end() > p[1].start.0) {
                return Err(MapError::OverlappingLeaves {
                    first: pair[0].min_key(),
                    first_depth: pair[0].depth,
                    second: pair[1].min_key(),
                    second_depth: pair[1].depth,
                });
            }
        }
        Ok(Self { resolution, leaves })
    }

    /// Builds a snapshot of single voxels from `(code, state)` pairs, in any order.
    pub fn from_voxel_states(
        resolution: f64,
        voxels: impl IntoIterator<Item = (MortonCode, Occupancy)>,
    ) -> Result<Self, MapError> {
        let leaves = voxels
            .into_iter()
            .map(|(code, state)| Leaf {
                start: code,
                depth: TREE_DEPTH,
                log_odds: state.log_odds(),
            })
            .collect();
        Self::from_leaves(resolution, leaves)
    }

    /// Edge length of one voxel in metres.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// The leaves, sorted in Morton order.
    pub fn leaves(&self) -> &[Leaf] {
        &self.leaves
    }

    /// Consumes the snapshot and returns its leaves.
    pub fn into_leaves(self) -> Vec<Leaf> {
        self.leaves
    }

    /// `true` when nothing is known.
    pub fn is_empty(&self) -> bool {
        self.leaves.is_empty()
    }

    /// Every known voxel with its state, coarse leaves expanded, in Morton order.
    ///
    /// Coarse free leaves can cover millions of voxels; this iterator is lazy.
    pub fn voxels(&self) -> impl Iterator<Item = (MortonCode, Occupancy)> + '_ {
        self.leaves.iter().flat_map(|leaf| {
            let state = leaf.occupancy();
            leaf.voxel_codes().map(move |code| (code, state))
        })
    }

    /// The leaf containing a voxel, if that voxel is known.
    pub fn leaf_at(&self, code: MortonCode) -> Option<&Leaf> {
        let after = self.leaves.partition_point(|l| l.start <= code);
        let leaf = self.leaves.get(after.checked_sub(1)?)?;
        (code.0 < leaf.end()).then_some(leaf)
    }

    /// State of one voxel, `None` when unknown.
    pub fn state_at(&self, code: MortonCode) -> Option<Occupancy> {
        self.leaf_at(code).map(Leaf::occupancy)
    }

    /// Leaf and voxel counts by state.
    pub fn stats(&self) -> SnapshotStats {
        let mut stats = SnapshotStats::default();
        for leaf in &self.leaves {
            match leaf.occupancy() {
                Occupancy::Occupied => {
                    stats.occupied_leaves += 1;
                    stats.occupied_voxels += leaf.voxel_count();
                }
                Occupancy::Free => {
                    stats.free_leaves += 1;
                    stats.free_voxels += leaf.voxel_count();
                }
            }
        }
        stats
    }

    /// Metric bounds of all known space (`None` when empty).
    pub fn known_bounds(&self) -> Option<BoundingBox> {
        self.bounds_of(|_| true)
    }

    /// Metric bounds of occupied space (`None` when nothing is occupied).
    pub fn occupied_bounds(&self) -> Option<BoundingBox> {
        self.bounds_of(|leaf| leaf.occupancy().is_occupied())
    }

    fn bounds_of(&self, include: impl Fn(&Leaf) -> bool) -> Option<BoundingBox> {
        self.leaves
            .iter()
            .filter(|leaf| include(leaf))
            .map(|leaf| {
                let (min, max) = leaf.bounds(self.resolution);
                BoundingBox { min, max }
            })
            .reduce(BoundingBox::grow)
    }

    /// The same map with every leaf at its binary state's `.bt` value (clamping min/max):
    /// what a `.bt` file can represent.
    pub fn to_max_likelihood(&self) -> Snapshot {
        Snapshot {
            resolution: self.resolution,
            leaves: self
                .leaves
                .iter()
                .map(|leaf| Leaf {
                    log_odds: leaf.occupancy().log_odds(),
                    ..*leaf
                })
                .collect(),
        }
    }

    /// The canonical split: every 8 sibling leaves with bit-identical values merged into
    /// their parent, repeatedly, bottom-up (never into the root, as upstream's `prune()`).
    /// This is what upstream OctoMap writes for a fully expanded tree, and the coarsest
    /// split of the same map; it does not depend on how the input happened to be split.
    ///
    /// ```
    /// use froctomap_core::{Leaf, Snapshot, VoxelKey};
    /// let block = Leaf::containing(VoxelKey::new(0, 0, 0), 14, -2.0);
    /// let voxels = Snapshot::from_voxel_states(0.1, Snapshot::from_leaves(0.1, vec![block])?.voxels())?;
    /// assert_eq!(voxels.leaves().len(), 64);
    /// assert_eq!(voxels.canonical().leaves(), &[Leaf { log_odds: froctomap_core::free_log_odds(), ..block }]);
    /// # Ok::<(), froctomap_core::MapError>(())
    /// ```
    pub fn canonical(&self) -> Snapshot {
        self.clone().into_canonical()
    }

    /// [`canonical`](Self::canonical) in place, without a second leaf buffer.
    pub fn into_canonical(mut self) -> Snapshot {
        // The merged prefix `leaves[..len]` never overtakes the read position `i`, so the
        // merge can share the buffer.
        let mut len = 0usize;
        for i in 0..self.leaves.len() {
            self.leaves[len] = self.leaves[i];
            len += 1;
            // Merge while the last eight entries are the complete, equal children of one node.
            while let Some(parent) = complete_family(&self.leaves[..len]) {
                len -= 7;
                self.leaves[len - 1] = parent;
            }
        }
        self.leaves.truncate(len);
        self
    }

    /// [`to_max_likelihood`](Self::to_max_likelihood) in place.
    pub fn into_max_likelihood(mut self) -> Snapshot {
        for leaf in &mut self.leaves {
            leaf.log_odds = leaf.occupancy().log_odds();
        }
        self
    }

    /// `true` when both snapshots know exactly the same voxels with the same states, however
    /// they are split into leaves (a coarse leaf equals its eight equal children).
    pub fn same_voxel_states(&self, other: &Snapshot) -> bool {
        self.resolution == other.resolution && runs(&self.leaves).eq(runs(&other.leaves))
    }
}

/// Checks one leaf's depth, alignment and value.
fn validate_leaf(leaf: &Leaf) -> Result<(), MapError> {
    if leaf.depth > TREE_DEPTH {
        return Err(MapError::DepthOutOfRange { depth: leaf.depth });
    }
    if leaf.start.0 >= MortonCode::END || leaf.start.0 & (voxels_per_node(leaf.depth) - 1) != 0 {
        return Err(MapError::MisalignedLeaf {
            code: leaf.start.0,
            depth: leaf.depth,
        });
    }
    if leaf.log_odds.is_nan() {
        return Err(MapError::NanLogOdds {
            key: leaf.min_key(),
        });
    }
    Ok(())
}

/// The parent of the last eight leaves, when they are its eight children with one value.
fn complete_family(leaves: &[Leaf]) -> Option<Leaf> {
    let family = leaves.get(leaves.len().checked_sub(8)?..)?;
    let first = family[0];
    if first.depth < 2 {
        return None;
    }
    let parent_depth = first.depth - 1;
    if first.start.node_start(parent_depth) != first.start {
        return None;
    }
    let size = first.voxel_count();
    let same = family.iter().enumerate().all(|(i, leaf)| {
        leaf.depth == first.depth
            && leaf.log_odds.to_bits() == first.log_odds.to_bits()
            && leaf.start.0 == first.start.0 + i as u64 * size
    });
    same.then_some(Leaf {
        start: first.start,
        depth: parent_depth,
        log_odds: first.log_odds,
    })
}

/// Maximal runs of consecutive voxels with one state: a canonical form for comparisons.
fn runs(leaves: &[Leaf]) -> impl Iterator<Item = (u64, u64, Occupancy)> + '_ {
    let mut iter = leaves.iter().peekable();
    std::iter::from_fn(move || {
        let first = iter.next()?;
        let state = first.occupancy();
        let mut end = first.end();
        while let Some(next) = iter.peek() {
            if next.start.0 == end && next.occupancy() == state {
                end = next.end();
                iter.next();
            } else {
                break;
            }
        }
        Some((first.start.0, end, state))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::key::VoxelKey;

    #[test]
    fn rejects_overlap_and_misalignment() {
        let a = Leaf::containing(VoxelKey::new(0, 0, 0), 14, 1.0);
        let b = Leaf::voxel(VoxelKey::new(1, 1, 1), 1.0);
        assert!(matches!(
            Snapshot::from_leaves(0.1, vec![b, a]),
            Err(MapError::OverlappingLeaves { .. })
        ));
        let misaligned = Leaf {
            start: VoxelKey::new(1, 0, 0).morton(),
            depth: 15,
            log_odds: 0.0,
        };
        assert!(matches!(
            Snapshot::from_leaves(0.1, vec![misaligned]),
            Err(MapError::MisalignedLeaf { .. })
        ));
        assert!(Snapshot::from_leaves(0.0, vec![]).is_err());
        assert!(Snapshot::from_leaves(f64::NAN, vec![]).is_err());
        let too_deep = Leaf {
            start: MortonCode(0),
            depth: 17,
            log_odds: 0.0,
        };
        assert!(Snapshot::from_leaves(0.1, vec![too_deep]).is_err());
    }

    #[test]
    fn coarse_leaf_equals_its_children() {
        let coarse = Snapshot::from_leaves(
            0.1,
            vec![Leaf::containing(VoxelKey::new(2, 2, 2), 15, -2.0)],
        )
        .unwrap();
        let fine = Snapshot::from_voxel_states(0.1, coarse.voxels()).unwrap();
        assert_eq!(fine.leaves().len(), 8);
        assert!(coarse.same_voxel_states(&fine));
        let mut changed: Vec<_> = fine.voxels().collect();
        changed[3].1 = Occupancy::Occupied;
        let changed = Snapshot::from_voxel_states(0.1, changed).unwrap();
        assert!(!coarse.same_voxel_states(&changed));
    }

    #[test]
    fn canonical_merges_recursively_but_never_into_the_root() {
        // All 8 depth-1 children: complete, but upstream never merges into the root.
        let top: Vec<Leaf> = (0..8u64)
            .map(|i| Leaf {
                start: MortonCode(i << 45),
                depth: 1,
                log_odds: 1.0,
            })
            .collect();
        let s = Snapshot::from_leaves(0.1, top).unwrap();
        assert_eq!(s.canonical().leaves().len(), 8);
        // Eight voxels merge, completing eight depth-15 leaves, which merge once more.
        let mut leaves: Vec<Leaf> = (1..8u64)
            .map(|i| Leaf {
                start: MortonCode(i * 8),
                depth: 15,
                log_odds: 1.0,
            })
            .collect();
        leaves.extend((0..8u64).map(|i| Leaf {
            start: MortonCode(i),
            depth: 16,
            log_odds: 1.0,
        }));
        let s = Snapshot::from_leaves(0.1, leaves).unwrap();
        let c = s.canonical();
        assert_eq!(
            c.leaves(),
            &[Leaf {
                start: MortonCode(0),
                depth: 14,
                log_odds: 1.0
            }]
        );
        assert!(c.same_voxel_states(&s));
        // Different values do not merge.
        let mut mixed: Vec<Leaf> = (0..8u64)
            .map(|i| Leaf {
                start: MortonCode(i),
                depth: 16,
                log_odds: 1.0,
            })
            .collect();
        mixed[3].log_odds = 2.0;
        assert_eq!(
            Snapshot::from_leaves(0.1, mixed)
                .unwrap()
                .canonical()
                .leaves()
                .len(),
            8
        );
    }

    #[test]
    fn bounds_cover_leaf_cubes() {
        let s = Snapshot::from_leaves(
            0.5,
            vec![
                Leaf::voxel(VoxelKey::new(32768, 32768, 32768), 1.0),
                Leaf::containing(VoxelKey::new(32766, 32768, 32768), 15, -1.0),
            ],
        )
        .unwrap();
        let known = s.known_bounds().unwrap();
        assert_eq!(known.min, [-1.0, 0.0, 0.0]);
        assert_eq!(known.max, [0.5, 1.0, 1.0]);
        let occupied = s.occupied_bounds().unwrap();
        assert_eq!(occupied.min, [0.0, 0.0, 0.0]);
        assert_eq!(occupied.max, [0.5, 0.5, 0.5]);
    }

    proptest::proptest! {
        /// Voxels of a small block (so that complete families are common), each occupied,
        /// free or unknown: the canonical split keeps every voxel's state, leaves no
        /// mergeable family behind and is its own canonical split.
        #[test]
        fn canonical_split_keeps_states_and_is_final(
            states in proptest::collection::vec(0u8..3, 512),
        ) {
            let voxels = states.iter().enumerate().filter_map(|(i, &state)| {
                let state = match state {
                    0 => Occupancy::Free,
                    1 => Occupancy::Occupied,
                    _ => return None,
                };
                Some((MortonCode(i as u64), state))
            });
            let fine = Snapshot::from_voxel_states(0.1, voxels).unwrap();
            let canonical = fine.canonical();
            proptest::prop_assert!(canonical.same_voxel_states(&fine));
            let leaves = canonical.leaves();
            for end in 8..=leaves.len() {
                proptest::prop_assert!(complete_family(&leaves[..end]).is_none());
            }
            proptest::prop_assert_eq!(canonical.clone().into_canonical(), canonical);
        }
    }
}
