//! Writing `.bt` and `.ot` files straight from leaves in Morton order, without a tree.
//!
//! The output is byte-identical to what upstream OctoMap 1.9.7 writes for the tree that holds
//! exactly these leaves (each leaf one node, inner nodes the maximum of their children):
//! `OcTree::writeBinary` for `.bt` and `AbstractOcTree::write` for `.ot`.
//!
//! * `.ot` needs no look-ahead: nodes are written depth-first as they open, and an inner
//!   node's value (the maximum of its children, folded in child order exactly as
//!   `getMaxChildLogOdds` does, starting from `-FLT_MAX` and keeping the first of equal
//!   values) is patched into its record when the node closes. Memory is the output itself.
//! * `.bt` output is pruned first, and upstream's `prune()` is not a full prune: it merges
//!   level by level from depth 15 up to depth 1 and stops at the first level where nothing
//!   merged (see [`BinaryEncoder`]). Which levels take part is only known at the end, so the
//!   encoder keeps the leaves that remain after the levels known so far to be pruned (8 bytes
//!   each) and renders the body in [`BinaryEncoder::finish`].
//!
//! The header is upstream's, with `res` printed as C++'s `operator<<(double)` prints it
//! (see [`format_resolution`]).

use crate::error::EncodeError;
use crate::header::OCTREE_ID;
use crate::kind::{BINARY_FIRST_LINE, FULL_FIRST_LINE};
use froctomap_core::{
    validate_resolution, voxels_per_node, Leaf, MapError, MortonCode, Occupancy, Snapshot,
    TREE_DEPTH,
};
use std::io::Write;

/// The comment lines upstream writes after the first line of both layouts.
const HEADER_COMMENT: &str =
    "# (feel free to add / change comments, but leave the first line as it is!)\n#\n";

/// Formats a resolution as upstream's header does: C++ `operator<<(double)` with the default
/// stream precision 6, i.e. C's `%g` (6 significant digits, trailing zeros removed,
/// exponent form below 1e-4 or from 1e6 on, exponent with at least two digits).
///
/// ```
/// use froctomap_octomap_codec::format_resolution;
/// assert_eq!(format_resolution(0.08), "0.08");
/// assert_eq!(format_resolution(0.1), "0.1");
/// assert_eq!(format_resolution(1e-5), "1e-05");
/// assert_eq!(format_resolution(123456.7), "123457");
/// assert_eq!(format_resolution(1234567.0), "1.23457e+06");
/// ```
pub fn format_resolution(value: f64) -> String {
    const PRECISION: i32 = 6;
    if !value.is_finite() {
        // Not reachable for a valid resolution; spelled as glibc spells them.
        return if value.is_nan() {
            "nan".to_string()
        } else if value > 0.0 {
            "inf".to_string()
        } else {
            "-inf".to_string()
        };
    }
    if value == 0.0 {
        return if value.is_sign_negative() { "-0" } else { "0" }.to_string();
    }
    // The exponent after rounding to 6 significant digits decides the style, as in C.
    // Rust rounds decimal conversions half to even on the exact binary value, as glibc does.
    let scientific = format!("{:.*e}", (PRECISION - 1) as usize, value);
    let (mantissa, exponent) = scientific.split_once('e').unwrap_or((&scientific, "0"));
    let exponent: i32 = exponent.parse().unwrap_or(0);
    if !(-4..PRECISION).contains(&exponent) {
        let sign = if exponent < 0 { '-' } else { '+' };
        format!(
            "{}e{sign}{:02}",
            strip_fraction_zeros(mantissa),
            exponent.abs()
        )
    } else {
        let decimals = usize::try_from(PRECISION - 1 - exponent).unwrap_or(0);
        strip_fraction_zeros(&format!("{value:.decimals$}")).to_string()
    }
}

/// `%g` drops trailing zeros of the fraction, and the point when nothing follows it.
fn strip_fraction_zeros(text: &str) -> &str {
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        text
    }
}

fn header(first_line: &str, node_count: u64, resolution: f64) -> String {
    format!(
        "{first_line}\n{HEADER_COMMENT}id {OCTREE_ID}\nsize {node_count}\nres {}\ndata\n",
        format_resolution(resolution)
    )
}

/// The header of a `.bt` file of `node_count` nodes.
pub(crate) fn binary_header(node_count: u64, resolution: f64) -> String {
    header(BINARY_FIRST_LINE, node_count, resolution)
}

/// Depth of the deepest node containing both codes (`a != b`): the depth at which their
/// child indices first differ.
pub(crate) fn divergence_depth(a: u64, b: u64) -> u8 {
    let differing = a ^ b;
    if differing == 0 {
        return TREE_DEPTH - 1;
    }
    let top_bit = 63 - differing.leading_zeros();
    // Bits 3·(15 − d) .. 3·(15 − d) + 2 hold the child index taken at depth d.
    TREE_DEPTH - 1 - (top_bit / 3) as u8
}

/// Index (0..8) of the child of the depth-`depth` node that contains `start`.
pub(crate) fn child_index(start: u64, depth: u8) -> usize {
    ((start >> (3 * u32::from(TREE_DEPTH - 1 - depth))) & 7) as usize
}

/// Checks that `(start, depth)` names a node of the octree: depth at most 16, `start` inside
/// the key space and aligned to the node's size.
pub(crate) fn check_node(start: u64, depth: u8) -> Result<(), EncodeError> {
    if depth > TREE_DEPTH {
        return Err(MapError::DepthOutOfRange { depth }.into());
    }
    if start >= MortonCode::END || start & (voxels_per_node(depth) - 1) != 0 {
        return Err(MapError::MisalignedLeaf { code: start, depth }.into());
    }
    Ok(())
}

/// Checks what a streaming encoder is given: valid leaves, strictly increasing, no overlap.
#[derive(Clone, Debug, Default)]
struct OrderCheck {
    previous: Option<(u64, u8)>,
    next_free: u64,
}

impl OrderCheck {
    fn check(&mut self, leaf: &Leaf) -> Result<(), EncodeError> {
        check_node(leaf.start.0, leaf.depth)?;
        if leaf.log_odds.is_nan() {
            return Err(MapError::NanLogOdds {
                key: leaf.min_key(),
            }
            .into());
        }
        if let Some((start, depth)) = self.previous {
            if leaf.start.0 < self.next_free {
                return Err(EncodeError::OutOfOrder {
                    previous: MortonCode(start).key(),
                    previous_depth: depth,
                    next: leaf.min_key(),
                    next_depth: leaf.depth,
                });
            }
        }
        self.previous = Some((leaf.start.0, leaf.depth));
        self.next_free = leaf.end();
        Ok(())
    }
}

/// A leaf of the `.bt` encoder's buffer packed into one `u64`: start code (48 bits), depth
/// (5 bits), occupied flag (1 bit). Packed values sort like their start codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Packed(u64);

impl Packed {
    fn new(start: u64, depth: u8, occupied: bool) -> Self {
        Packed(start << 6 | u64::from(depth) << 1 | u64::from(occupied))
    }
    fn start(self) -> u64 {
        self.0 >> 6
    }
    fn depth(self) -> u8 {
        ((self.0 >> 1) & 0x1F) as u8
    }
    fn occupied(self) -> bool {
        self.0 & 1 == 1
    }
}

/// Streams leaves in Morton order into a `.bt` file identical to upstream's `writeBinary`
/// for the tree made of those leaves.
///
/// Upstream's `writeBinary` first sets every node to the clamping bound of its state
/// (`toMaxLikelihood`), then calls `prune()`, which for depth 15, 14, …, 1 merges every node
/// whose eight children all exist, are leaves and have equal values, and **stops at the first
/// depth where nothing merged** (it never merges into the root). So eight equal depth-14
/// leaves stay split unless some merge happened at depth 15 first. The encoder reproduces this
/// exactly: it tracks the depth `s` whose pass has merged nothing so far, applies merges at
/// depths below `s` as soon as the eighth sibling arrives, and when a merge at depth `s`
/// itself appears (so upstream's pass `s` would not stop), it re-runs the pass for `s − 1`
/// over what it holds, as upstream would. At most 15 such re-runs happen per file.
///
/// Memory: 8 bytes per leaf left after the pruning known so far (a small multiple of the
/// output size); nothing per voxel.
///
/// ```
/// use froctomap_core::{Leaf, Occupancy, VoxelKey};
/// use froctomap_octomap_codec::{decode, BinaryEncoder, ReadLimits};
/// let mut encoder = BinaryEncoder::new(0.1)?;
/// // Eight occupied voxels of one 2x2x2 block, in Morton order: pruned into one leaf.
/// for i in 0..8u16 {
///     let key = VoxelKey::new(i & 1, (i >> 1) & 1, (i >> 2) & 1);
///     encoder.push(Leaf::voxel(key, Occupancy::Occupied.log_odds()))?;
/// }
/// let bytes = encoder.finish_to_vec();
/// let tree = decode(&bytes, None, ReadLimits::default())?;
/// assert_eq!(tree.leaves.len(), 1);
/// assert_eq!(tree.leaves[0].depth, 15);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct BinaryEncoder {
    resolution: f64,
    leaves: Vec<Packed>,
    /// Upstream's pass at this depth has merged nothing so far; deeper passes are in effect.
    stop_depth: u8,
    order: OrderCheck,
}

impl BinaryEncoder {
    /// An encoder for a map of the given resolution (metres per voxel).
    pub fn new(resolution: f64) -> Result<Self, EncodeError> {
        Ok(Self {
            resolution: validate_resolution(resolution)?,
            leaves: Vec::new(),
            stop_depth: TREE_DEPTH - 1,
            order: OrderCheck::default(),
        })
    }

    /// Adds the next leaf. Leaves must come in increasing Morton order without overlapping;
    /// only their state (occupied when log-odds ≥ 0) is stored, as in a `.bt` file.
    pub fn push(&mut self, leaf: Leaf) -> Result<(), EncodeError> {
        self.order.check(&leaf)?;
        self.push_trusted(leaf.start.0, leaf.depth, leaf.occupancy());
        Ok(())
    }

    /// Adds the next leaf given by its state: `start` and `depth` as in [`Leaf`].
    pub fn push_state(
        &mut self,
        start: MortonCode,
        depth: u8,
        state: Occupancy,
    ) -> Result<(), EncodeError> {
        self.push(Leaf {
            start,
            depth,
            log_odds: state.log_odds(),
        })
    }

    /// Adds a leaf known to be valid and in order (from a [`Snapshot`]).
    fn push_trusted(&mut self, start: u64, depth: u8, state: Occupancy) {
        self.leaves
            .push(Packed::new(start, depth, state.is_occupied()));
        self.collapse_tail();
    }

    /// Merges the eight siblings at the end of the buffer into their parent while they form
    /// a prunable group at a depth whose pass upstream runs.
    fn collapse_tail(&mut self) {
        while let Some(&last) = self.leaves.last() {
            let child_depth = last.depth();
            // Upstream's passes cover parents at depth 1..=15: never the root.
            if child_depth < 2 || child_depth - 1 < self.stop_depth.max(1) {
                return;
            }
            let parent_depth = child_depth - 1;
            if child_index(last.start(), parent_depth) != 7 {
                return;
            }
            let Some(group_at) = self.leaves.len().checked_sub(8) else {
                return;
            };
            let Some(merged) = merged_group(&self.leaves[group_at..], parent_depth) else {
                return;
            };
            self.leaves.truncate(group_at);
            self.leaves.push(merged);
            if parent_depth == self.stop_depth {
                // Upstream's pass at this depth merges something, so it goes on one level up.
                self.continue_passes_from(parent_depth - 1);
                return;
            }
        }
    }

    /// Runs upstream's passes for `depth`, `depth − 1`, … over the whole buffer until one
    /// merges nothing; that depth becomes the new stop depth.
    fn continue_passes_from(&mut self, mut depth: u8) {
        while depth >= 1 {
            if merge_level(&mut self.leaves, depth) == 0 {
                break;
            }
            depth -= 1;
        }
        self.stop_depth = depth;
    }

    /// Number of leaves held so far (after the pruning known so far).
    pub fn buffered_leaves(&self) -> usize {
        self.leaves.len()
    }

    /// Writes the whole `.bt` file to `out` and returns the number of tree nodes (the
    /// header's `size`).
    pub fn finish<W: Write + ?Sized>(self, out: &mut W) -> std::io::Result<u64> {
        let (bytes, nodes) = render_binary(&self.leaves, self.resolution);
        out.write_all(&bytes)?;
        Ok(nodes)
    }

    /// The whole `.bt` file in memory.
    pub fn finish_to_vec(self) -> Vec<u8> {
        render_binary(&self.leaves, self.resolution).0
    }
}

/// The parent leaf of `group` when it is the eight children of one depth-`parent_depth` node,
/// all leaves of one state (what upstream's `isNodeCollapsible` accepts after
/// `toMaxLikelihood`).
fn merged_group(group: &[Packed], parent_depth: u8) -> Option<Packed> {
    let first = *group.first()?;
    let child_size = voxels_per_node(parent_depth + 1);
    let parent = first.start();
    if group.len() < 8 || parent & (voxels_per_node(parent_depth) - 1) != 0 {
        return None;
    }
    let occupied = first.occupied();
    let mut expected = parent;
    for &child in &group[..8] {
        if child != Packed::new(expected, parent_depth + 1, occupied) {
            return None;
        }
        expected += child_size;
    }
    Some(Packed::new(parent, parent_depth, occupied))
}

/// One pass of upstream's `prune()` at `parent_depth` over a sorted buffer: merges every
/// prunable group of eight, in place. Returns how many merged.
fn merge_level(leaves: &mut Vec<Packed>, parent_depth: u8) -> usize {
    let mut merged = 0;
    let mut write = 0;
    let mut read = 0;
    while read < leaves.len() {
        let candidate = leaves[read];
        let replacement = if candidate.depth() == parent_depth + 1 {
            merged_group(&leaves[read..], parent_depth)
        } else {
            None
        };
        match replacement {
            Some(parent) => {
                leaves[write] = parent;
                read += 8;
                merged += 1;
            }
            None => {
                leaves[write] = candidate;
                read += 1;
            }
        }
        write += 1;
    }
    leaves.truncate(write);
    merged
}

/// Nodes of the tree made of these leaves (sorted, non-overlapping `(start, depth)`): the
/// root, every inner node on a path to a leaf, and the leaves.
fn count_nodes(leaves: impl Iterator<Item = (u64, u8)>) -> u64 {
    let mut nodes = 0u64;
    let mut previous = None;
    for (start, depth) in leaves {
        if depth == 0 {
            return 1;
        }
        let shared = match previous {
            None => {
                nodes += 1; // the root
                0
            }
            Some(previous) => divergence_depth(previous, start),
        };
        // Inner nodes at depths shared + 1 .. depth − 1 open for this leaf, then the leaf.
        nodes += u64::from(depth - shared);
        previous = Some(start);
    }
    nodes
}

/// The `.bt` file of a tree whose leaves are `leaves` (sorted, non-overlapping), and its node
/// count. The node count comes first (the header needs it), so the file is built in one
/// buffer of the exact size. Each inner node is written as its two code bytes when it opens
/// (depth-first order is opening order); its codes are filled in as its children appear.
fn render_binary(leaves: &[Packed], resolution: f64) -> (Vec<u8>, u64) {
    let nodes = count_nodes(leaves.iter().map(|l| (l.start(), l.depth())));
    let header = binary_header(nodes, resolution);
    let inner_nodes = usize::try_from(nodes)
        .unwrap_or(usize::MAX)
        .saturating_sub(leaves.len());
    let mut bytes = Vec::with_capacity(header.len() + 2 * inner_nodes.max(1));
    bytes.extend_from_slice(header.as_bytes());
    let Some(first) = leaves.first() else {
        return (bytes, nodes);
    };
    // Offset of the code bytes of the open inner node at each depth.
    let mut slots = [0usize; TREE_DEPTH as usize];
    slots[0] = bytes.len();
    bytes.extend([0, 0]);
    if first.depth() == 0 {
        // A root without children: upstream writes its (empty) child codes.
        return (bytes, nodes);
    }
    let mut previous: Option<u64> = None;
    for leaf in leaves {
        let (start, depth) = (leaf.start(), leaf.depth());
        let shared = match previous {
            None => 0,
            Some(previous) => divergence_depth(previous, start),
        };
        for inner in shared + 1..depth {
            set_code(
                &mut bytes,
                slots[usize::from(inner - 1)],
                start,
                inner - 1,
                3,
            );
            slots[usize::from(inner)] = bytes.len();
            bytes.extend([0, 0]);
        }
        let code = if leaf.occupied() { 2 } else { 1 };
        set_code(
            &mut bytes,
            slots[usize::from(depth - 1)],
            start,
            depth - 1,
            code,
        );
        previous = Some(start);
    }
    (bytes, nodes)
}

/// Sets the 2-bit code of the child containing `start` in the code bytes at `slot` of its
/// depth-`parent_depth` parent: children 0–3 in the first byte, 4–7 in the second, child `i`
/// at bits `2(i mod 4)`.
fn set_code(body: &mut [u8], slot: usize, start: u64, parent_depth: u8, code: u8) {
    let child = child_index(start, parent_depth);
    if let Some(byte) = body.get_mut(slot + child / 4) {
        *byte |= code << (2 * (child % 4));
    }
}

/// Streams leaves in Morton order into a `.ot` file identical to upstream's
/// `AbstractOcTree::write` for the tree made of those leaves: every node's `f32` log-odds
/// (little-endian) and child mask, depth-first; inner nodes carry the maximum of their
/// children as upstream's `updateInnerOccupancy` computes it. Nothing is pruned.
///
/// Memory: the output body (5 bytes per node) and 16 open nodes.
///
/// ```
/// use froctomap_core::{Leaf, VoxelKey};
/// use froctomap_octomap_codec::{decode, FullEncoder, ReadLimits};
/// let mut encoder = FullEncoder::new(0.05)?;
/// encoder.push(Leaf::voxel(VoxelKey::new(0, 0, 0), 0.4))?;
/// encoder.push(Leaf::containing(VoxelKey::new(0, 0, 8), 13, -1.5))?;
/// let bytes = encoder.finish_to_vec();
/// assert!(bytes.starts_with(b"# Octomap OcTree file\n"));
/// let tree = decode(&bytes, None, ReadLimits::default())?;
/// assert_eq!(tree.leaves.len(), 2);
/// assert_eq!((tree.leaves[1].depth, tree.leaves[1].log_odds), (13, -1.5));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct FullEncoder {
    resolution: f64,
    /// The output so far: the header too when it was written up front (`header_written`),
    /// otherwise only the tree data.
    body: Vec<u8>,
    header_written: bool,
    /// Open inner nodes by depth: offset of their record and the maximum of their children
    /// so far.
    open: [(usize, f32); TREE_DEPTH as usize],
    open_count: usize,
    nodes: u64,
    previous: Option<u64>,
    order: OrderCheck,
}

impl FullEncoder {
    /// An encoder for a map of the given resolution (metres per voxel).
    pub fn new(resolution: f64) -> Result<Self, EncodeError> {
        Ok(Self {
            resolution: validate_resolution(resolution)?,
            body: Vec::new(),
            header_written: false,
            open: [(0, -f32::MAX); TREE_DEPTH as usize],
            open_count: 0,
            nodes: 0,
            previous: None,
            order: OrderCheck::default(),
        })
    }

    /// An encoder whose output buffer starts with room for `nodes` nodes.
    pub fn with_capacity(resolution: f64, nodes: usize) -> Result<Self, EncodeError> {
        let mut encoder = Self::new(resolution)?;
        encoder.body.reserve(nodes.saturating_mul(5));
        Ok(encoder)
    }

    /// Adds the next leaf. Leaves must come in increasing Morton order without overlapping.
    pub fn push(&mut self, leaf: Leaf) -> Result<(), EncodeError> {
        self.order.check(&leaf)?;
        self.push_trusted(leaf.start.0, leaf.depth, leaf.log_odds);
        Ok(())
    }

    /// Adds a leaf known to be valid and in order (from a [`Snapshot`]).
    fn push_trusted(&mut self, start: u64, depth: u8, log_odds: f32) {
        if depth == 0 {
            // The root without children: the whole tree is this one node.
            self.body.extend(log_odds.to_le_bytes());
            self.body.push(0);
            self.nodes = 1;
            return;
        }
        let shared = match self.previous {
            None => {
                self.open_node(0);
                0
            }
            Some(previous) => divergence_depth(previous, start),
        };
        while self.open_count > usize::from(shared) + 1 {
            self.close_node();
        }
        for inner in shared + 1..depth {
            self.mark_child(inner - 1, start);
            self.open_node(inner);
        }
        self.mark_child(depth - 1, start);
        self.body.extend(log_odds.to_le_bytes());
        self.body.push(0);
        self.nodes += 1;
        self.fold_into(depth - 1, log_odds);
        self.previous = Some(start);
    }

    fn open_node(&mut self, depth: u8) {
        if let Some(slot) = self.open.get_mut(usize::from(depth)) {
            *slot = (self.body.len(), -f32::MAX);
        }
        self.body.extend([0; 5]);
        self.nodes += 1;
        self.open_count = usize::from(depth) + 1;
    }

    /// Writes the deepest open node's value and hands it to its parent.
    fn close_node(&mut self) {
        let Some(depth) = self.open_count.checked_sub(1) else {
            return;
        };
        let (offset, value) = self.open[depth];
        if let Some(record) = self.body.get_mut(offset..offset + 4) {
            record.copy_from_slice(&value.to_le_bytes());
        }
        self.open_count = depth;
        if let Some(parent) = depth.checked_sub(1) {
            self.fold_into(parent as u8, value);
        }
    }

    /// Upstream's `getMaxChildLogOdds`: strictly greater values replace the maximum.
    fn fold_into(&mut self, depth: u8, value: f32) {
        if let Some((_, max)) = self.open.get_mut(usize::from(depth)) {
            if value > *max {
                *max = value;
            }
        }
    }

    fn mark_child(&mut self, parent_depth: u8, start: u64) {
        let offset = self.open[usize::from(parent_depth)].0 + 4;
        if let Some(mask) = self.body.get_mut(offset) {
            *mask |= 1 << child_index(start, parent_depth);
        }
    }

    fn close_all(&mut self) {
        while self.open_count > 0 {
            self.close_node();
        }
    }

    /// Writes the whole `.ot` file to `out` and returns the number of tree nodes (the
    /// header's `size`).
    pub fn finish<W: Write + ?Sized>(mut self, out: &mut W) -> std::io::Result<u64> {
        self.close_all();
        if !self.header_written {
            out.write_all(header(FULL_FIRST_LINE, self.nodes, self.resolution).as_bytes())?;
        }
        out.write_all(&self.body)?;
        Ok(self.nodes)
    }

    /// The whole `.ot` file in memory.
    pub fn finish_to_vec(mut self) -> Vec<u8> {
        self.close_all();
        if !self.header_written {
            let header = header(FULL_FIRST_LINE, self.nodes, self.resolution);
            self.body.splice(0..0, header.into_bytes());
        }
        self.body
    }
}

/// The `.bt` file upstream writes for this snapshot: byte-identical to
/// `OcTree::from_snapshot(snapshot)?.write_binary()?` of `froctomap-octomap-ffi`
/// (maximum likelihood, upstream's partial `prune()`, then `writeBinary`).
///
/// ```
/// use froctomap_core::{Leaf, Snapshot, VoxelKey};
/// use froctomap_octomap_codec::{decode, encode_binary, ReadLimits};
/// let map = Snapshot::from_leaves(0.08, vec![Leaf::voxel(VoxelKey::new(32768, 32768, 32768), 0.7)])?;
/// let bytes = encode_binary(&map);
/// assert!(bytes.starts_with(b"# Octomap OcTree binary file\n"));
/// let back = decode(&bytes, None, ReadLimits::default())?;
/// // A chain of 16 inner nodes down to the one voxel.
/// assert_eq!((back.header.declared_size, back.node_count), (17, 17));
/// assert_eq!(Snapshot::from_leaves(0.08, back.leaves)?, map.to_max_likelihood());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn encode_binary(snapshot: &Snapshot) -> Vec<u8> {
    let mut encoder = BinaryEncoder {
        resolution: snapshot.resolution(),
        leaves: Vec::with_capacity(snapshot.leaves().len()),
        stop_depth: TREE_DEPTH - 1,
        order: OrderCheck::default(),
    };
    for leaf in snapshot.leaves() {
        encoder.push_trusted(leaf.start.0, leaf.depth, leaf.occupancy());
    }
    encoder.finish_to_vec()
}

/// The `.ot` file upstream writes for this snapshot: byte-identical to
/// `OcTree::from_snapshot(snapshot)?.write_full()?` of `froctomap-octomap-ffi` (every leaf
/// with its log-odds, inner nodes the maximum of their children, no pruning).
///
/// ```
/// use froctomap_core::{Leaf, Snapshot, VoxelKey};
/// use froctomap_octomap_codec::{decode, encode_full, ReadLimits};
/// let map = Snapshot::from_leaves(0.1, vec![Leaf::voxel(VoxelKey::new(1, 2, 3), -0.25)])?;
/// let back = decode(&encode_full(&map), None, ReadLimits::default())?;
/// assert_eq!(Snapshot::from_leaves(0.1, back.leaves)?, map);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn encode_full(snapshot: &Snapshot) -> Vec<u8> {
    // Counting the nodes first lets the header go in front and the file be built in one
    // buffer of the exact size.
    let nodes = count_nodes(snapshot.leaves().iter().map(|l| (l.start.0, l.depth)));
    let header = header(FULL_FIRST_LINE, nodes, snapshot.resolution());
    let mut body =
        Vec::with_capacity(header.len() + usize::try_from(nodes).unwrap_or(0).saturating_mul(5));
    body.extend_from_slice(header.as_bytes());
    let mut encoder = FullEncoder {
        resolution: snapshot.resolution(),
        body,
        header_written: true,
        open: [(0, -f32::MAX); TREE_DEPTH as usize],
        open_count: 0,
        nodes: 0,
        previous: None,
        order: OrderCheck::default(),
    };
    for leaf in snapshot.leaves() {
        encoder.push_trusted(leaf.start.0, leaf.depth, leaf.log_odds);
    }
    encoder.finish_to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{decode, ReadLimits};
    use froctomap_core::VoxelKey;
    use proptest::prelude::*;

    #[test]
    fn resolution_formatting_follows_percent_g() {
        // Values chosen to exercise each branch of %g; the integration tests compare many
        // more against upstream's own header.
        for (value, text) in [
            (0.05, "0.05"),
            (0.25, "0.25"),
            (1.0, "1"),
            (2.5e-7, "2.5e-07"),
            (0.0001, "0.0001"),
            (0.00012345678, "0.000123457"),
            (999999.4, "999999"),
            (999999.5, "1e+06"),
            (1234565.0, "1.23456e+06"),
            (1e100, "1e+100"),
            (1.0 / 3.0, "0.333333"),
        ] {
            assert_eq!(format_resolution(value), text, "{value}");
        }
    }

    #[test]
    fn divergence_and_child_index_agree_with_morton_code() {
        let a = VoxelKey::new(0x8000, 0, 0).morton().0;
        let b = VoxelKey::new(0, 0, 0).morton().0;
        assert_eq!(divergence_depth(a, b), 0);
        let c = VoxelKey::new(1, 0, 0).morton().0;
        assert_eq!(divergence_depth(b, c), 15);
        assert_eq!(child_index(a, 0), 1);
        assert_eq!(child_index(c, 15), 1);
    }

    #[test]
    fn streaming_encoders_refuse_bad_order_and_bad_leaves() {
        let voxel = |x| Leaf::voxel(VoxelKey::new(x, 0, 0), 1.0);
        let mut bt = BinaryEncoder::new(0.1).unwrap();
        bt.push(voxel(2)).unwrap();
        assert!(matches!(
            bt.push(voxel(1)),
            Err(EncodeError::OutOfOrder { .. })
        ));
        assert!(matches!(
            bt.push(voxel(2)),
            Err(EncodeError::OutOfOrder { .. })
        ));
        let mut ot = FullEncoder::new(0.1).unwrap();
        ot.push(Leaf::containing(VoxelKey::new(0, 0, 0), 14, 1.0))
            .unwrap();
        assert!(ot.push(voxel(3)).is_err(), "inside the coarse leaf");
        assert!(ot
            .push(Leaf::voxel(VoxelKey::new(9, 9, 9), f32::NAN))
            .is_err());
        let misaligned = Leaf {
            start: VoxelKey::new(1, 0, 0).morton(),
            depth: 15,
            log_odds: 0.0,
        };
        assert!(FullEncoder::new(0.1).unwrap().push(misaligned).is_err());
        assert!(BinaryEncoder::new(0.0).is_err());
        assert!(FullEncoder::new(f64::INFINITY).is_err());
    }

    #[test]
    fn empty_and_root_only_trees() {
        let empty = Snapshot::empty(0.1).unwrap();
        let bt = encode_binary(&empty);
        assert!(bt.ends_with(b"size 0\nres 0.1\ndata\n"));
        let root = Snapshot::from_leaves(
            0.1,
            vec![Leaf {
                start: MortonCode(0),
                depth: 0,
                log_odds: -1.0,
            }],
        )
        .unwrap();
        let ot = encode_full(&root);
        let tree = decode(&ot, None, ReadLimits::default()).unwrap();
        assert_eq!((tree.node_count, tree.leaves.len()), (1, 1));
        assert_eq!(Snapshot::from_leaves(0.1, tree.leaves).unwrap(), root);
    }

    fn snapshot_strategy() -> impl Strategy<Value = Snapshot> {
        // Leaves in a small region, random depths, so siblings and coarse leaves collide.
        proptest::collection::vec((0u16..16, 0u16..16, 0u16..16, 12u8..=16, -3i8..4), 0..200)
            .prop_map(|raw| {
                let mut leaves: Vec<Leaf> = raw
                    .into_iter()
                    .map(|(x, y, z, depth, v)| {
                        Leaf::containing(VoxelKey::new(x, y, z), depth, f32::from(v) * 0.5)
                    })
                    .collect();
                leaves.sort_by_key(|l| (l.start, std::cmp::Reverse(l.depth)));
                let mut kept: Vec<Leaf> = Vec::new();
                for leaf in leaves {
                    if kept.last().is_none_or(|k| k.end() <= leaf.start.0) {
                        kept.push(leaf);
                    }
                }
                Snapshot::from_leaves(0.1, kept).unwrap()
            })
    }

    proptest! {
        #[test]
        fn encoded_files_decode_to_the_same_voxels(snapshot in snapshot_strategy()) {
            // No warnings: in particular the header's `size` is the node count.
            let full = decode(&encode_full(&snapshot), None, ReadLimits::default()).unwrap();
            prop_assert!(full.warnings.is_empty(), "{:?}", full.warnings);
            prop_assert_eq!(&Snapshot::from_leaves(0.1, full.leaves).unwrap(), &snapshot);
            let binary = decode(&encode_binary(&snapshot), None, ReadLimits::default()).unwrap();
            prop_assert!(binary.warnings.is_empty(), "{:?}", binary.warnings);
            let binary = Snapshot::from_leaves(0.1, binary.leaves).unwrap();
            prop_assert!(binary.same_voxel_states(&snapshot.to_max_likelihood()));
            prop_assert!(binary.leaves().len() <= snapshot.leaves().len());
        }

        #[test]
        fn streaming_equals_whole_snapshot_encoding(snapshot in snapshot_strategy()) {
            let mut bt = BinaryEncoder::new(0.1).unwrap();
            let mut ot = FullEncoder::new(0.1).unwrap();
            for leaf in snapshot.leaves() {
                bt.push(*leaf).unwrap();
                ot.push(*leaf).unwrap();
            }
            let mut bt_bytes = Vec::new();
            bt.finish(&mut bt_bytes).unwrap();
            prop_assert_eq!(bt_bytes, encode_binary(&snapshot));
            prop_assert_eq!(ot.finish_to_vec(), encode_full(&snapshot));
        }
    }
}
