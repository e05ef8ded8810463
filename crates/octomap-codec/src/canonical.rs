//! The `.bt` file of a map's canonical split, written straight from states in Morton order,
//! one part of space at a time.
//!
//! [`encode_binary`](crate::encode_binary) of a snapshot reduced to maximum likelihood and
//! merged into its canonical split (every eight equal sibling leaves merged, at every depth)
//! gives the same bytes; this builder does it in one pass without the leaf buffers, and lets
//! disjoint parts of space be built on different threads and then joined. Upstream's partial
//! `prune()` (see [`BinaryEncoder`](crate::BinaryEncoder)) finds nothing to merge in a
//! canonical tree, so these are also the bytes upstream writes for the canonical tree.
//!
//! `.bt` is depth-first with each inner node's child codes before its children, so the bytes
//! of a subtree are contiguous: a node's record is reserved when it opens and filled in when
//! it closes; a node whose eight children closed as equal leaves is removed again (its
//! children left nothing after its record) and becomes a leaf of its parent.

use crate::encode::{binary_header, check_node, child_index, divergence_depth};
use crate::error::EncodeError;
use froctomap_core::{validate_resolution, voxels_per_node, MortonCode, TREE_DEPTH};

/// `.bt` child codes (2 bits per child).
const FREE: u8 = 1;
const OCCUPIED: u8 = 2;
const INNER: u8 = 3;

/// One node of the octree, built by a [`CanonicalBinaryBuilder`]: nothing known inside it, one
/// leaf, or an inner node with its `.bt` records.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BinaryPart {
    start: MortonCode,
    depth: u8,
    content: PartContent,
}

#[derive(Clone, Debug, PartialEq, Eq)]
enum PartContent {
    Empty,
    Leaf {
        occupied: bool,
    },
    Inner {
        body: Vec<u8>,
        nodes: u64,
        leaves: u64,
    },
}

impl BinaryPart {
    /// Tree nodes in the part (inner nodes and leaves, its own node included).
    pub fn nodes(&self) -> u64 {
        match &self.content {
            PartContent::Empty => 0,
            PartContent::Leaf { .. } => 1,
            PartContent::Inner { nodes, .. } => *nodes,
        }
    }

    /// Leaves in the part.
    pub fn leaves(&self) -> u64 {
        match &self.content {
            PartContent::Empty => 0,
            PartContent::Leaf { .. } => 1,
            PartContent::Inner { leaves, .. } => *leaves,
        }
    }

    /// The whole `.bt` file, for a part that is the whole tree (built from the root).
    pub fn into_file(self, resolution: f64) -> Result<Vec<u8>, EncodeError> {
        let resolution = validate_resolution(resolution)?;
        if self.depth != 0 {
            return Err(EncodeError::NotTheRoot { depth: self.depth });
        }
        let nodes = self.nodes();
        let mut file = binary_header(nodes, resolution).into_bytes();
        match self.content {
            PartContent::Empty => {}
            // A root that is one leaf: upstream writes its (empty) child codes.
            PartContent::Leaf { .. } => file.extend([0, 0]),
            PartContent::Inner { body, .. } => file.extend_from_slice(&body),
        }
        Ok(file)
    }
}

/// An inner node still receiving children.
#[derive(Clone, Copy, Debug)]
struct OpenNode {
    start: u64,
    /// Offset of its two code bytes in the body.
    slot: usize,
    codes: u16,
    children: u8,
    /// The code all children so far share when they are leaves of one state, else `INNER`.
    uniform: u8,
}

/// Builds the canonical `.bt` tree of the states inside one node of the octree (the root for
/// a whole map, or a tile), given in increasing Morton order without overlap; parts built
/// by other builders for disjoint nodes inside it can be added in their place.
///
/// ```
/// use froctomap_core::{Leaf, MortonCode, Occupancy, Snapshot, VoxelKey};
/// use froctomap_octomap_codec::{encode_binary, CanonicalBinaryBuilder};
/// // Eight free voxels of one 2x2x2 block and one occupied voxel elsewhere.
/// let mut leaves: Vec<Leaf> = (0..8u16)
///     .map(|i| Leaf::voxel(VoxelKey::new(i & 1, (i >> 1) & 1, (i >> 2) & 1), -2.0))
///     .collect();
/// leaves.push(Leaf::voxel(VoxelKey::new(9, 0, 0), 0.4));
/// let map = Snapshot::from_leaves(0.05, leaves)?;
///
/// let mut builder = CanonicalBinaryBuilder::new(MortonCode(0), 0)?;
/// for leaf in map.leaves() {
///     builder.push_state(leaf.start, leaf.depth, leaf.occupancy().is_occupied())?;
/// }
/// let bytes = builder.finish().into_file(0.05)?;
/// assert_eq!(bytes, encode_binary(&map.to_max_likelihood().canonical()));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct CanonicalBinaryBuilder {
    start: u64,
    depth: u8,
    body: Vec<u8>,
    nodes: u64,
    leaves: u64,
    /// Open inner nodes, one per depth from `depth` down.
    open: Vec<OpenNode>,
    /// First voxel a next item may start at.
    next_free: u64,
    /// The part when one item covered the whole node.
    whole: Option<PartContent>,
    /// Start of the last item.
    previous_start: Option<u64>,
}

impl CanonicalBinaryBuilder {
    /// A builder for the node of depth `depth` whose first voxel is `start`.
    pub fn new(start: MortonCode, depth: u8) -> Result<Self, EncodeError> {
        check_node(start.0, depth)?;
        Ok(Self {
            start: start.0,
            depth,
            body: Vec::new(),
            nodes: 0,
            leaves: 0,
            open: Vec::with_capacity(usize::from(TREE_DEPTH - depth)),
            next_free: start.0,
            whole: None,
            previous_start: None,
        })
    }

    /// Adds a leaf of the given state: the node of depth `depth` starting at `start`.
    #[inline]
    pub fn push_state(
        &mut self,
        start: MortonCode,
        depth: u8,
        occupied: bool,
    ) -> Result<(), EncodeError> {
        let code = if occupied { OCCUPIED } else { FREE };
        // Most leaves follow a sibling: same parent, already open, nothing to close or open.
        // The checks are those of `place` for that case (a child of an open node, aligned,
        // after the previous item, lies inside this builder's node).
        if let Some(parent) = self.open.last() {
            let parent_depth = self.depth + self.open.len() as u8 - 1;
            if depth == parent_depth + 1
                && depth <= TREE_DEPTH
                && start.0 >= self.next_free
                && start.0 & !(voxels_per_node(parent_depth) - 1) == parent.start
                && start.0 & (voxels_per_node(depth) - 1) == 0
            {
                self.next_free = start.0 + voxels_per_node(depth);
                self.previous_start = Some(start.0);
                self.nodes += 1;
                self.leaves += 1;
                self.add_child(start.0, depth, code);
                return Ok(());
            }
        }
        if self.place(start.0, depth)? {
            self.whole = Some(PartContent::Leaf { occupied });
            return Ok(());
        }
        self.nodes += 1;
        self.leaves += 1;
        self.add_child(start.0, depth, code);
        Ok(())
    }

    /// Adds a part built by another builder for a node inside this one.
    pub fn push_part(&mut self, part: BinaryPart) -> Result<(), EncodeError> {
        if part.content == PartContent::Empty {
            return Ok(());
        }
        let (start, depth) = (part.start.0, part.depth);
        if self.place(start, depth)? {
            self.whole = Some(part.content);
            return Ok(());
        }
        let code = match part.content {
            PartContent::Empty => return Ok(()),
            PartContent::Leaf { occupied } => {
                self.nodes += 1;
                self.leaves += 1;
                if occupied {
                    OCCUPIED
                } else {
                    FREE
                }
            }
            PartContent::Inner {
                body,
                nodes,
                leaves,
            } => {
                self.body.extend_from_slice(&body);
                self.nodes += nodes;
                self.leaves += leaves;
                INNER
            }
        };
        self.add_child(start, depth, code);
        Ok(())
    }

    /// Checks that the node `(start, depth)` lies inside this builder's node after what came
    /// before, then makes its parent the deepest open node. `true` when it is the builder's
    /// node itself.
    #[inline]
    fn place(&mut self, start: u64, depth: u8) -> Result<bool, EncodeError> {
        check_node(start, depth)?;
        let end = start + voxels_per_node(depth);
        if depth < self.depth
            || end > self.start + voxels_per_node(self.depth)
            || start < self.start
        {
            return Err(EncodeError::OutsidePart {
                node: MortonCode(start).key(),
                depth,
                part: MortonCode(self.start).key(),
                part_depth: self.depth,
            });
        }
        if start < self.next_free {
            return Err(EncodeError::OutOfOrder {
                previous: MortonCode(self.next_free - 1).key(),
                previous_depth: TREE_DEPTH,
                next: MortonCode(start).key(),
                next_depth: depth,
            });
        }
        self.next_free = end;
        if depth == self.depth {
            return Ok(true);
        }
        // Keep the open nodes that also contain the previous item's start down to where the
        // two paths part, close the deeper ones, open new ones down to this item's parent.
        if let Some(previous) = self.previous_start {
            let shared = divergence_depth(previous, start);
            let keep = usize::from(shared.saturating_sub(self.depth)) + 1;
            while self.open.len() > keep {
                self.close_deepest();
            }
        }
        self.previous_start = Some(start);
        for node_depth in self.depth + self.open.len() as u8..depth {
            self.open.push(OpenNode {
                start: start & !(voxels_per_node(node_depth) - 1),
                slot: self.body.len(),
                codes: 0,
                children: 0,
                uniform: 0,
            });
            self.body.extend([0, 0]);
        }
        Ok(false)
    }

    /// Records a child of the deepest open node (which is its parent).
    #[inline]
    fn add_child(&mut self, start: u64, depth: u8, code: u8) {
        if let Some(parent) = self.open.last_mut() {
            let child = child_index(start, depth - 1);
            parent.codes |= u16::from(code) << (2 * child);
            parent.children += 1;
            parent.uniform = match (parent.children, code) {
                (_, INNER) => INNER,
                (1, _) => code,
                _ if parent.uniform == code => code,
                _ => INNER,
            };
        }
    }

    /// Closes the deepest open node: merged into a leaf when its eight children are leaves
    /// of one state (except the root), else its codes are written. The builder's own node closes last (in
    /// [`finish`](Self::finish)), since every item lies inside it.
    fn close_deepest(&mut self) {
        let Some(node) = self.open.pop() else {
            return;
        };
        let depth = self.depth + self.open.len() as u8;
        // The root is never merged, as upstream's `prune()` never merges into it.
        let merged = node.children == 8 && node.uniform != INNER && depth > 0;
        if merged {
            // All children are leaves: nothing of them follows the node's record.
            self.body.truncate(node.slot);
            self.nodes -= 8;
            self.leaves -= 8;
        } else {
            self.body[node.slot..node.slot + 2].copy_from_slice(&node.codes.to_le_bytes());
            self.nodes += 1;
        }
        if depth == self.depth {
            self.whole = Some(if merged {
                PartContent::Leaf {
                    occupied: node.uniform == OCCUPIED,
                }
            } else {
                PartContent::Inner {
                    body: std::mem::take(&mut self.body),
                    nodes: self.nodes,
                    leaves: self.leaves,
                }
            });
            return;
        }
        let code = if merged {
            self.nodes += 1;
            self.leaves += 1;
            node.uniform
        } else {
            INNER
        };
        self.add_child(node.start, depth, code);
    }

    /// The built node.
    pub fn finish(mut self) -> BinaryPart {
        while !self.open.is_empty() {
            self.close_deepest();
        }
        BinaryPart {
            start: MortonCode(self.start),
            depth: self.depth,
            content: self.whole.unwrap_or(PartContent::Empty),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode_binary;
    use froctomap_core::{Leaf, Snapshot, VoxelKey};
    use proptest::prelude::*;

    /// The reference: maximum likelihood, canonical split, upstream-identical encoder.
    fn reference(map: &Snapshot) -> Vec<u8> {
        encode_binary(&map.to_max_likelihood().canonical())
    }

    fn whole(map: &Snapshot) -> Vec<u8> {
        let mut builder = CanonicalBinaryBuilder::new(MortonCode(0), 0).unwrap();
        for leaf in map.leaves() {
            builder
                .push_state(leaf.start, leaf.depth, leaf.occupancy().is_occupied())
                .unwrap();
        }
        builder.finish().into_file(map.resolution()).unwrap()
    }

    /// Built per node of depth `part_depth`, then joined under the root.
    fn by_parts(map: &Snapshot, part_depth: u8) -> Vec<u8> {
        let mut root = CanonicalBinaryBuilder::new(MortonCode(0), 0).unwrap();
        let mut part: Option<CanonicalBinaryBuilder> = None;
        for leaf in map.leaves() {
            if leaf.depth < part_depth {
                if let Some(done) = part.take() {
                    root.push_part(done.finish()).unwrap();
                }
                root.push_state(leaf.start, leaf.depth, leaf.occupancy().is_occupied())
                    .unwrap();
                continue;
            }
            let node = leaf.start.node_start(part_depth);
            if part.as_ref().is_some_and(|p| p.start != node.0) {
                root.push_part(part.take().unwrap().finish()).unwrap();
            }
            part.get_or_insert_with(|| CanonicalBinaryBuilder::new(node, part_depth).unwrap())
                .push_state(leaf.start, leaf.depth, leaf.occupancy().is_occupied())
                .unwrap();
        }
        if let Some(done) = part {
            root.push_part(done.finish()).unwrap();
        }
        root.finish().into_file(map.resolution()).unwrap()
    }

    /// Trees over a depth-11 block grown from random choices: each node is absent, a leaf
    /// or split, with leaf states mostly shared by neighbours so that complete families of
    /// equal leaves (which merge) are common, and some leaves at depths above the parts.
    fn map_strategy() -> impl Strategy<Value = Snapshot> {
        (prop::collection::vec(any::<u8>(), 64..2048), 0u64..8).prop_map(|(choices, corner)| {
            let mut leaves = Vec::new();
            let mut next = choices.iter().cycle();
            let base = corner * voxels_per_node(11) + voxels_per_node(3) * 5;
            grow(base, 11, &mut leaves, &mut || *next.next().unwrap_or(&0));
            Snapshot::from_leaves(0.1, leaves).unwrap()
        })
    }

    fn grow(start: u64, depth: u8, leaves: &mut Vec<Leaf>, choice: &mut dyn FnMut() -> u8) {
        let c = choice();
        let split = depth < TREE_DEPTH && (depth < 13 || c % 4 != 0);
        if !split {
            if c % 16 == 4 {
                return; // unknown
            }
            let occupied = (start / voxels_per_node(14)) % 3 == 0 || c % 32 == 8;
            let log_odds = if occupied { 0.85 } else { -0.4 };
            leaves.push(Leaf {
                start: MortonCode(start),
                depth,
                log_odds,
            });
            return;
        }
        for child in 0..8 {
            grow(
                start + child * voxels_per_node(depth + 1),
                depth + 1,
                leaves,
                choice,
            );
        }
    }

    proptest! {
        #[test]
        fn builder_matches_canonical_encoding(map in map_strategy()) {
            let expected = reference(&map);
            prop_assert_eq!(&whole(&map), &expected);
            for part_depth in [1u8, 10, 12, 13, 14, 15] {
                prop_assert_eq!(&by_parts(&map, part_depth), &expected, "parts of depth {}", part_depth);
            }
        }
    }

    #[test]
    fn full_blocks_merge_across_parts_but_never_into_the_root() {
        // A whole depth-13 block free: built in depth-14 parts it still merges to one leaf.
        let leaves: Vec<Leaf> = (0..512u16)
            .map(|i| Leaf::voxel(VoxelKey::new(i & 7, (i >> 3) & 7, i >> 6), -1.0))
            .collect();
        let map = Snapshot::from_leaves(0.1, leaves).unwrap();
        assert_eq!(by_parts(&map, 14), reference(&map));
        // The whole tree as eight equal depth-1 leaves: the root stays an inner node.
        let eighth = voxels_per_node(1);
        let leaves: Vec<Leaf> = (0..8u64)
            .map(|i| Leaf {
                start: MortonCode(i * eighth),
                depth: 1,
                log_odds: 2.0,
            })
            .collect();
        let map = Snapshot::from_leaves(0.1, leaves).unwrap();
        assert_eq!(whole(&map), reference(&map));
        assert_eq!(by_parts(&map, 1), reference(&map));
        // Nothing at all.
        let empty = Snapshot::from_leaves(0.1, Vec::new()).unwrap();
        assert_eq!(whole(&empty), reference(&empty));
    }

    #[test]
    fn refuses_disorder_overlap_and_items_outside_the_part() {
        let mut builder = CanonicalBinaryBuilder::new(MortonCode(0), 15).unwrap();
        builder.push_state(MortonCode(1), 16, true).unwrap();
        assert!(matches!(
            builder.push_state(MortonCode(0), 16, true),
            Err(EncodeError::OutOfOrder { .. })
        ));
        assert!(matches!(
            builder.push_state(MortonCode(8), 16, true),
            Err(EncodeError::OutsidePart { .. })
        ));
        assert!(matches!(
            builder.push_state(MortonCode(3), 15, true),
            Err(EncodeError::InvalidMap(_))
        ));
        assert!(CanonicalBinaryBuilder::new(MortonCode(1), 15).is_err());
        let part = builder.finish();
        assert_eq!((part.nodes(), part.leaves()), (2, 1));
        assert!(matches!(
            part.into_file(0.1),
            Err(EncodeError::NotTheRoot { depth: 15 })
        ));
    }
}
