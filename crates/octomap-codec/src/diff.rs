//! The changes between two files of one layout, from their bytes, without decoding either.
//!
//! Both bodies list the same tree positions in the same depth-first order, so one walk can
//! read them side by side: where the two records of a node agree that a child is a leaf, the
//! child is equal and nothing is read; where both have a subtree, the previous file's bytes of
//! it (its length comes from the previous file's [`TreeIndex`]) are compared with as many
//! bytes of the current file, and equal bytes are the same subtree, skipped in both. Only
//! subtrees that differ are entered. Consecutive snapshots of a mapped building differ in a
//! few places, so a comparison costs a few `memcmp`s and the paths to the changes, where
//! decoding both files into leaf lists and comparing those costs tens of times more.
//!
//! The current file is checked as [`scan`](crate::scan) checks it (truncation, depth, node
//! limit, `size`, trailing bytes); the previous one is assumed to have been read before.

use crate::body::{record_at, BodySummary, ReadLimits};
use crate::error::CodecError;
use crate::header::{detect_kind, parse_header};
use crate::kind::{FileKind, TreeType};
use crate::{decode, scan, scan_with, ScanSummary};
use froctomap_core::{changes, voxels_per_node, Occupancy, StateChange, TREE_DEPTH};

/// Streams the ranges where `current` differs from `previous` (`None`: a map where nothing is
/// known) to `on_change`, in Morton order and maximal per new state: the same list
/// [`froctomap_core::changes`] gives for the two files' leaves. `kind` forces the layout of
/// both files; `None` detects it from `current`'s first line.
///
/// ```
/// use froctomap_octomap_codec::{diff, ReadLimits};
/// let head = b"# Octomap OcTree binary file\nid OcTree\nsize 3\nres 0.1\ndata\n";
/// let before = [&head[..], &[0b1001, 0]].concat(); // child 0 free, child 1 occupied
/// let after = [&head[..], &[0b0101, 0]].concat(); // both free
/// let mut changes = Vec::new();
/// diff(Some((&before, None)), &after, None, ReadLimits::default(), &mut |c| changes.push(c))?;
/// assert_eq!(changes.len(), 1);
/// assert_eq!(changes[0].end - changes[0].start, 1 << 45); // child 1 of the root: 8^15 voxels
/// # Ok::<(), froctomap_octomap_codec::CodecError>(())
/// ```
pub fn diff<F: FnMut(StateChange) + ?Sized>(
    previous: Option<(&[u8], Option<&TreeIndex>)>,
    current: &[u8],
    kind: Option<FileKind>,
    limits: ReadLimits,
    on_change: &mut F,
) -> Result<(ScanSummary, TreeIndex), CodecError> {
    let kind = kind
        .or_else(|| detect_kind(current))
        .unwrap_or(FileKind::Binary);
    let (old, old_tree) = match previous {
        Some((bytes, index)) => {
            let header = parse_header(bytes, kind)?;
            let body = match header.declared_size {
                // Upstream reads no data when the header says `size 0`: nothing known.
                0 => &[][..],
                _ => bytes.get(header.body_offset..).unwrap_or_default(),
            };
            let tree = body_tree(kind, &header.tree_id)?;
            ((body, header.body_offset, index), Some(tree))
        }
        None => ((&[][..], 0, None), None),
    };
    if let Some(old_tree) = old_tree {
        let current_tree = body_tree(kind, &parse_header(current, kind)?.tree_id)?;
        if old_tree != current_tree {
            // Nodes of two layouts cannot be compared record by record: compare the leaves.
            return diff_decoded(previous, current, kind, limits, on_change);
        }
    }
    let compare =
        |tree: TreeType, current: Option<(&[u8], usize)>, on_change: &mut F| match (kind, tree) {
            (FileKind::Binary, _) => diff_bodies::<Binary, F>(old, current, limits, on_change),
            (FileKind::Full, TreeType::OcTree) => diff_bodies::<
                Full<{ TreeType::OcTree.full_record_len() }>,
                F,
            >(old, current, limits, on_change),
            (FileKind::Full, TreeType::ColorOcTree) => {
                diff_bodies::<Full<{ TreeType::ColorOcTree.full_record_len() }>, F>(
                    old, current, limits, on_change,
                )
            }
        };
    let mut index = TreeIndex::default();
    let mut tree = TreeType::OcTree;
    let summary = scan_with(current, Some(kind), |_, current_tree, body, body_offset| {
        tree = current_tree;
        let (summary, current_index) = compare(tree, Some((body, body_offset)), on_change)?;
        index = current_index;
        Ok(summary)
    })?;
    if summary.header.declared_size == 0 {
        // The body was not read: everything known before is unknown now.
        let tree = body_tree(kind, &summary.header.tree_id)?;
        compare(tree, None, on_change)?;
    }
    Ok((summary, index))
}

/// The node layout of a body of `kind` whose header names `tree_id` (a `.bt` has one
/// layout whatever the type).
fn body_tree(kind: FileKind, tree_id: &str) -> Result<TreeType, CodecError> {
    match kind {
        FileKind::Binary => Ok(TreeType::OcTree),
        FileKind::Full => TreeType::from_id(tree_id)
            .ok_or_else(|| CodecError::UnsupportedTreeType(tree_id.into())),
    }
}

/// [`diff`] of two files whose nodes have different layouts (an `OcTree` and a
/// `ColorOcTree` `.ot`): both decoded, their leaves compared.
fn diff_decoded<F: FnMut(StateChange) + ?Sized>(
    previous: Option<(&[u8], Option<&TreeIndex>)>,
    current: &[u8],
    kind: FileKind,
    limits: ReadLimits,
    on_change: &mut F,
) -> Result<(ScanSummary, TreeIndex), CodecError> {
    let old = match previous {
        Some((bytes, _)) => decode(bytes, Some(kind), limits)?.leaves,
        None => Vec::new(),
    };
    let mut leaves = Vec::new();
    let summary = scan(current, Some(kind), limits, &mut |leaf| leaves.push(leaf))?;
    for change in changes(&old, &leaves) {
        on_change(change);
    }
    let index = TreeIndex::of(current, kind)?;
    Ok((summary, index))
}

/// The size of every subtree of a file's tree, which lets [`diff`] skip a subtree stored with
/// the same bytes in the next file by one comparison of bytes. [`diff`] makes it for the
/// current file as it goes; it is only valid with that file.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TreeIndex {
    /// Records in the subtree of each record, in file order.
    subtree_records: Vec<u32>,
}

impl TreeIndex {
    /// The index of a file that was read before, found from its bytes in two passes over its
    /// records.
    pub fn of(bytes: &[u8], kind: FileKind) -> Result<TreeIndex, CodecError> {
        let header = parse_header(bytes, kind)?;
        if header.declared_size == 0 {
            return Ok(TreeIndex::default());
        }
        let body = bytes.get(header.body_offset..).unwrap_or_default();
        Ok(match (kind, body_tree(kind, &header.tree_id)?) {
            (FileKind::Binary, _) => index_of_body::<Binary>(body, header.body_offset)?,
            (FileKind::Full, TreeType::OcTree) => index_of_body::<
                Full<{ TreeType::OcTree.full_record_len() }>,
            >(body, header.body_offset)?,
            (FileKind::Full, TreeType::ColorOcTree) => index_of_body::<
                Full<{ TreeType::ColorOcTree.full_record_len() }>,
            >(body, header.body_offset)?,
        })
    }
}

fn index_of_body<L: Layout>(body: &[u8], body_offset: usize) -> Result<TreeIndex, CodecError> {
    // Without the bytes after the tree, which would otherwise pass for records.
    let records = tree_records::<L>(body, body_offset)?;
    Ok(TreeIndex {
        subtree_records: subtree_records::<L>(&body[..records * L::RECORD]),
    })
}

type Previous<'a> = (&'a [u8], usize, Option<&'a TreeIndex>);

/// Compares a previous body with the current one (`None`: a tree without nodes).
fn diff_bodies<L: Layout, F: FnMut(StateChange) + ?Sized>(
    (old_body, old_offset, old_index): Previous<'_>,
    current: Option<(&[u8], usize)>,
    limits: ReadLimits,
    on_change: &mut F,
) -> Result<(BodySummary, TreeIndex), CodecError> {
    let (body, body_offset) = current.unwrap_or((&[], 0));
    let computed;
    let old_index = match old_index {
        Some(index) => index,
        None if old_body.is_empty() => {
            computed = TreeIndex::default();
            &computed
        }
        None => {
            computed = index_of_body::<L>(old_body, old_offset)?;
            &computed
        }
    };
    let mut old = Stream::new(old_body, old_offset, &old_index.subtree_records);
    let mut new = Stream::new(body, body_offset, &[]);
    new.sizes = Some(Vec::with_capacity(old_index.subtree_records.len()));
    let mut merger = Merger {
        pending: None,
        on_change,
    };
    let a = if old_body.is_empty() {
        View::Known(None)
    } else {
        L::root(&mut old)?
    };
    let b = match current {
        Some(_) => L::root(&mut new)?,
        None => View::Known(None),
    };
    diff_node::<L, F>(&mut old, &mut new, 0, 0, a, b, &mut merger)?;
    merger.flush();
    // Every record read (or skipped as equal to a valid one) is a node, and its children
    // are the nodes below it.
    let tree = &body[..new.pos];
    let nodes = u64::from(current.is_some())
        + tree
            .chunks_exact(L::RECORD)
            .map(|record| u64::from(L::children(record)))
            .sum::<u64>();
    if nodes > limits.max_nodes {
        return Err(CodecError::TooManyNodes {
            limit: limits.max_nodes,
        });
    }
    Ok((
        BodySummary {
            node_count: nodes,
            len: new.pos,
        },
        TreeIndex {
            subtree_records: new.sizes.unwrap_or_default(),
        },
    ))
}

/// Where a tree's records end: depth-first order makes the tree end where the records read
/// so far announce no more children.
fn tree_records<L: Layout>(body: &[u8], body_offset: usize) -> Result<usize, CodecError> {
    let (mut needed, mut read) = (1usize, 0usize);
    while read < needed {
        let at = read * L::RECORD;
        let record = body.get(at..at + L::RECORD).ok_or(CodecError::Truncated {
            offset: body_offset + at,
            needed: L::RECORD,
            available: body.len().saturating_sub(at),
        })?;
        needed += L::records_below(record) as usize;
        read += 1;
    }
    Ok(read)
}

/// The number of records in the subtree of every record of a (valid) body: in reverse file
/// order every subtree is complete before its parent, whose children's sizes are the last
/// ones found.
fn subtree_records<L: Layout>(body: &[u8]) -> Vec<u32> {
    let count = body.len() / L::RECORD;
    let mut sizes = vec![0u32; count];
    let mut pending: Vec<u32> = Vec::new();
    for (i, record) in body[..count * L::RECORD]
        .chunks_exact(L::RECORD)
        .enumerate()
        .rev()
    {
        let mut size = 1u32;
        for _ in 0..L::records_below(record) {
            size = size.saturating_add(pending.pop().unwrap_or(0));
        }
        sizes[i] = size;
        pending.push(size);
    }
    sizes
}

/// What a file says about one tree position.
#[derive(Clone, Copy, Debug, PartialEq)]
enum View {
    /// A leaf, or no node (`None`: unknown): the whole cube has this state.
    Known(Option<Occupancy>),
    /// A node with children: its child record (`.bt` codes or `.ot` mask) and the index
    /// of its record in the body.
    Inner(u16, usize),
}

fn diff_node<L: Layout, F: FnMut(StateChange) + ?Sized>(
    old: &mut Stream<'_>,
    new: &mut Stream<'_>,
    depth: u8,
    start: u64,
    a: View,
    b: View,
    out: &mut Merger<'_, F>,
) -> Result<(), CodecError> {
    let mut visit = match (a, b) {
        (View::Known(x), View::Known(y)) => {
            if x != y {
                out.push(StateChange {
                    start,
                    end: start + voxels_per_node(depth),
                    new: y,
                });
            }
            return Ok(());
        }
        (View::Inner(p, i), View::Inner(q, j)) => {
            // A subtree stored with the same bytes is the same subtree: skip both.
            if let Some(&records) = old.subtree_records.get(i) {
                let len = records as usize * L::RECORD;
                let (from, to) = (i * L::RECORD, j * L::RECORD);
                let same = matches!(
                    (old.body.get(from..from + len), new.body.get(to..to + len)),
                    (Some(a), Some(b)) if a == b
                );
                if same {
                    old.pos = from + len;
                    new.pos = to + len;
                    if let (Some(sizes), Some(same)) = (
                        &mut new.sizes,
                        old.subtree_records.get(i..i + records as usize),
                    ) {
                        sizes.truncate(j);
                        sizes.extend_from_slice(same);
                    }
                    return Ok(());
                }
            }
            L::children_to_visit(p, q)
        }
        _ => 0xff,
    };
    let child_depth = depth + 1;
    let child_shift = 3 * u32::from(TREE_DEPTH - child_depth);
    while visit != 0 {
        let child = visit.trailing_zeros();
        visit &= visit - 1;
        let a = match a {
            View::Inner(record, _) => L::child(old, record, child, child_depth)?,
            known => known,
        };
        let b = match b {
            View::Inner(record, _) => L::child(new, record, child, child_depth)?,
            known => known,
        };
        let child_start = start + (u64::from(child) << child_shift);
        diff_node::<L, F>(old, new, child_depth, child_start, a, b, out)?;
    }
    if let (View::Inner(_, j), Some(sizes)) = (b, &mut new.sizes) {
        if let Some(size) = sizes.get_mut(j) {
            *size = u32::try_from(new.pos / L::RECORD - j).unwrap_or(u32::MAX);
        }
    }
    Ok(())
}

/// Joins changes that continue each other with the same new state.
struct Merger<'f, F: FnMut(StateChange) + ?Sized> {
    pending: Option<StateChange>,
    on_change: &'f mut F,
}

impl<F: FnMut(StateChange) + ?Sized> Merger<'_, F> {
    fn push(&mut self, change: StateChange) {
        match &mut self.pending {
            Some(p) if p.end == change.start && p.new == change.new => p.end = change.end,
            pending => {
                if let Some(done) = pending.replace(change) {
                    (self.on_change)(done);
                }
            }
        }
    }

    fn flush(&mut self) {
        if let Some(done) = self.pending.take() {
            (self.on_change)(done);
        }
    }
}

/// One body being read.
struct Stream<'a> {
    body: &'a [u8],
    pos: usize,
    body_offset: usize,
    /// Records in the subtree of each record (the previous file's index).
    subtree_records: &'a [u32],
    /// The same, found while reading (the current file's): 1 when a record is read, its
    /// subtree's size once that is read.
    sizes: Option<Vec<u32>>,
}

impl<'a> Stream<'a> {
    fn new(body: &'a [u8], body_offset: usize, subtree_records: &'a [u32]) -> Self {
        Self {
            body,
            pos: 0,
            body_offset,
            subtree_records,
            sizes: None,
        }
    }

    /// The next record and its index.
    fn take<const N: usize>(&mut self) -> Result<([u8; N], usize), CodecError> {
        let bytes = record_at(self.body, self.pos, self.body_offset)?;
        let index = self.pos / N;
        self.pos += N;
        if let Some(sizes) = &mut self.sizes {
            sizes.push(1);
        }
        Ok((bytes, index))
    }

    fn offset(&self) -> usize {
        self.body_offset + self.pos
    }
}

/// How a layout stores nodes: one fixed-size record per node, depth-first.
trait Layout {
    /// Bytes of a record.
    const RECORD: usize;
    /// Records that follow a record for its children's subtrees (children with children).
    fn records_below(record: &[u8]) -> u32;
    /// Children the record lists (nodes of the tree, as upstream's `size()` counts them).
    fn children(record: &[u8]) -> u32;
    /// Reads the root node.
    fn root(stream: &mut Stream<'_>) -> Result<View, CodecError>;
    /// The view of child `child` of a node with child record `record`, reading the child's
    /// own record when it has one.
    fn child(
        stream: &mut Stream<'_>,
        record: u16,
        child: u32,
        child_depth: u8,
    ) -> Result<View, CodecError>;
    /// Children (bit per child index) that may differ between two nodes with these records,
    /// or that hold data to be read past; the others are equal in both and take no bytes.
    fn children_to_visit(a: u16, b: u16) -> u16;
}

/// `.bt`: a node is two bytes of 2-bit child codes (0 unknown, 1 free, 2 occupied, 3 inner).
struct Binary;

impl Binary {
    /// Reads a node's codes; a node whose codes are all 0 is a leaf in upstream's tree
    /// (`value`: the root keeps the occupied value it starts with, others get `-FLT_MAX`).
    fn node(stream: &mut Stream<'_>, value: Occupancy) -> Result<View, CodecError> {
        let (bytes, index) = stream.take::<2>()?;
        let codes = u16::from_le_bytes(bytes);
        if codes == 0 {
            return Ok(View::Known(Some(value)));
        }
        Ok(View::Inner(codes, index))
    }

    fn codes(record: &[u8]) -> u16 {
        match record {
            [low, high, ..] => u16::from_le_bytes([*low, *high]),
            _ => 0,
        }
    }
}

impl Layout for Binary {
    const RECORD: usize = 2;

    #[inline]
    fn records_below(record: &[u8]) -> u32 {
        let codes = Binary::codes(record);
        (codes & codes >> 1 & 0x5555).count_ones()
    }

    #[inline]
    fn children(record: &[u8]) -> u32 {
        let codes = Binary::codes(record);
        ((codes | codes >> 1) & 0x5555).count_ones()
    }

    fn root(stream: &mut Stream<'_>) -> Result<View, CodecError> {
        Binary::node(stream, Occupancy::Occupied)
    }

    #[inline]
    fn child(
        stream: &mut Stream<'_>,
        record: u16,
        child: u32,
        child_depth: u8,
    ) -> Result<View, CodecError> {
        Ok(match (record >> (2 * child)) & 3 {
            0 => View::Known(None),
            1 => View::Known(Some(Occupancy::Free)),
            2 => View::Known(Some(Occupancy::Occupied)),
            _ if child_depth >= TREE_DEPTH => {
                return Err(CodecError::TooDeep {
                    offset: stream.offset(),
                })
            }
            _ => Binary::node(stream, Occupancy::Free)?,
        })
    }

    #[inline]
    fn children_to_visit(a: u16, b: u16) -> u16 {
        let differ = a ^ b;
        // The low bit of each 2-bit field that differs or is 3 (inner) in either record.
        let fields = ((differ | differ >> 1) | (a & a >> 1) | (b & b >> 1)) & 0x5555;
        // One bit per child: squeeze the even bits together.
        let x = (fields | fields >> 1) & 0x3333;
        let x = (x | x >> 2) & 0x0f0f;
        (x | x >> 4) & 0x00ff
    }
}

/// `.ot`: a node is `R` bytes, its `f32` log-odds first and a child mask last (a tree type's
/// other data between, [`TreeType::full_record_len`]); nodes without children are leaves.
struct Full<const R: usize>;

impl<const R: usize> Full<R> {
    fn node(stream: &mut Stream<'_>, depth: u8) -> Result<View, CodecError> {
        let offset = stream.offset();
        let (record, index) = stream.take::<R>()?;
        let mask = record[R - 1];
        if mask == 0 {
            let value = f32::from_le_bytes([record[0], record[1], record[2], record[3]]);
            if value.is_nan() {
                return Err(CodecError::NotANumber { offset });
            }
            return Ok(View::Known(Some(Occupancy::from_log_odds(value))));
        }
        if depth >= TREE_DEPTH {
            return Err(CodecError::TooDeep { offset });
        }
        Ok(View::Inner(u16::from(mask), index))
    }

    fn mask(record: &[u8]) -> u8 {
        record.get(R - 1).copied().unwrap_or(0)
    }
}

impl<const R: usize> Layout for Full<R> {
    const RECORD: usize = R;

    #[inline]
    fn records_below(record: &[u8]) -> u32 {
        Self::mask(record).count_ones()
    }

    #[inline]
    fn children(record: &[u8]) -> u32 {
        Self::mask(record).count_ones()
    }

    fn root(stream: &mut Stream<'_>) -> Result<View, CodecError> {
        Self::node(stream, 0)
    }

    #[inline]
    fn child(
        stream: &mut Stream<'_>,
        record: u16,
        child: u32,
        child_depth: u8,
    ) -> Result<View, CodecError> {
        if record >> child & 1 == 0 {
            return Ok(View::Known(None));
        }
        Self::node(stream, child_depth)
    }

    #[inline]
    fn children_to_visit(a: u16, b: u16) -> u16 {
        // A leaf's value is only known once read, so every child present in either is read.
        a | b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{decode, scan};
    use froctomap_core::changes;
    use proptest::prelude::*;

    /// A random tree node, decided by a hash of its position so that two trees made with the
    /// same seed agree wherever neither is mutated.
    #[derive(Clone, Debug)]
    enum Node {
        Unknown,
        Leaf(f32),
        Inner(f32, Vec<Node>),
    }

    fn hash(seed: u64, depth: u8, start: u64, salt: u64) -> u64 {
        let mut z = seed ^ start.rotate_left(7) ^ (u64::from(depth) << 58) ^ salt;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A tree whose child `i` at `depth` is a leaf, nothing or a subtree; `mutation` (seed,
    /// per-mille rate) redraws some positions.
    fn tree(seed: u64, mutation: (u64, u64), depth: u8, start: u64) -> Node {
        let draw = |salt| {
            let h = hash(seed, depth, start, salt);
            if hash(mutation.0, depth, start, salt) % 1000 < mutation.1 {
                h.rotate_left(17) ^ mutation.0
            } else {
                h
            }
        };
        let value = [-2.0f32, -0.4, 0.0, 0.7, 3.5][(draw(1) % 5) as usize];
        if depth == TREE_DEPTH {
            return Node::Leaf(value);
        }
        // Shallow levels: one path down (child 0) and rare side branches, so the trees reach
        // depth 16 with a few hundred nodes.
        let inner_per_mille = if depth < 12 { 20 } else { 350 };
        let children = (0..8u64)
            .map(|i| {
                let child_start = start + (i << (3 * u32::from(TREE_DEPTH - depth - 1)));
                let r = draw(10 + i) % 1000;
                if (depth < 12 && i == 0) || r < inner_per_mille {
                    tree(seed, mutation, depth + 1, child_start)
                } else if r < 600 {
                    Node::Unknown
                } else {
                    Node::Leaf([-2.0f32, 0.5, 2.0][(r % 3) as usize])
                }
            })
            .collect::<Vec<_>>();
        // Now and then a node with no children at all.
        if draw(2) % 50 == 0 {
            Node::Inner(value, vec![Node::Unknown; 8])
        } else {
            Node::Inner(value, children)
        }
    }

    fn nodes(node: &Node) -> u32 {
        match node {
            Node::Unknown => 0,
            Node::Leaf(_) => 1,
            Node::Inner(_, children) => 1 + children.iter().map(nodes).sum::<u32>(),
        }
    }

    fn binary_body(node: &Node, out: &mut Vec<u8>) {
        let Node::Inner(_, children) = node else {
            return;
        };
        let mut codes = 0u16;
        for (i, child) in children.iter().enumerate() {
            let code = match child {
                Node::Unknown => 0,
                Node::Leaf(v) if *v < 0.0 => 1,
                Node::Leaf(_) => 2,
                Node::Inner(..) => 3,
            };
            codes |= code << (2 * i);
        }
        out.extend(codes.to_le_bytes());
        for child in children {
            binary_body(child, out);
        }
    }

    fn full_body(node: &Node, out: &mut Vec<u8>) {
        let (value, children) = match node {
            Node::Unknown => return,
            Node::Leaf(v) => (*v, &[][..]),
            Node::Inner(v, children) => (*v, &children[..]),
        };
        let mask = children
            .iter()
            .enumerate()
            .filter(|(_, c)| !matches!(c, Node::Unknown))
            .fold(0u8, |m, (i, _)| m | 1 << i);
        out.extend(value.to_le_bytes());
        out.push(mask);
        for child in children {
            full_body(child, out);
        }
    }

    fn file(root: &Node, kind: FileKind) -> Vec<u8> {
        let mut out = format!(
            "{}\nid OcTree\nsize {}\nres 0.1\ndata\n",
            kind.first_line(),
            nodes(root)
        )
        .into_bytes();
        match kind {
            FileKind::Binary => binary_body(root, &mut out),
            FileKind::Full => full_body(root, &mut out),
        }
        out
    }

    /// The changes and summary, checking that the previous file's index (given or found)
    /// makes no difference and that the index made for `current` is its own.
    fn collect(previous: Option<&[u8]>, current: &[u8]) -> (Vec<StateChange>, ScanSummary) {
        let run = |previous: Option<(&[u8], Option<&TreeIndex>)>| {
            let mut out = Vec::new();
            let (summary, index) = diff(previous, current, None, ReadLimits::default(), &mut |c| {
                out.push(c)
            })
            .unwrap();
            (out, summary, index)
        };
        let (out, summary, index) = run(previous.map(|p| (p, None)));
        let kind = detect_kind(current).unwrap();
        assert_eq!(index, TreeIndex::of(current, kind).unwrap());
        if let Some(previous) = previous {
            let previous_index = TreeIndex::of(previous, kind).unwrap();
            assert_eq!(
                run(Some((previous, Some(&previous_index)))),
                (out.clone(), summary.clone(), index)
            );
        }
        (out, summary)
    }

    fn expected(previous: Option<&[u8]>, current: &[u8]) -> Vec<StateChange> {
        let leaves = |bytes: &[u8]| decode(bytes, None, ReadLimits::default()).unwrap().leaves;
        changes(&previous.map(leaves).unwrap_or_default(), &leaves(current))
    }

    proptest! {
        #[test]
        fn byte_diff_equals_the_diff_of_the_decoded_leaves(
            seed in any::<u64>(),
            mutation_seed in any::<u64>(),
            rate in 0u64..300,
        ) {
            let a = tree(seed, (0, 0), 0, 0);
            let b = tree(seed, (mutation_seed, rate), 0, 0);
            for (kind, trailing) in [(FileKind::Binary, 0), (FileKind::Full, 0), (FileKind::Binary, 3), (FileKind::Full, 7)] {
                // Bytes after the tree, ignored by readers, must not pass for records.
                let junk = [0xffu8; 8];
                let (a, b) = (
                    [&file(&a, kind)[..], &junk[..trailing]].concat(),
                    [&file(&b, kind)[..], &junk[..trailing]].concat(),
                );
                for (previous, current) in [(Some(&a[..]), &b[..]), (Some(&b), &a), (None, &b), (Some(&a), &a)] {
                    let (got, summary) = collect(previous, current);
                    prop_assert_eq!(&got, &expected(previous, current), "{:?}", kind);
                    // The same checks and counts as a full read of `current`.
                    let scanned = scan(current, None, ReadLimits::default(), &mut |_| {}).unwrap();
                    prop_assert_eq!(summary, scanned);
                }
            }
        }
    }

    /// A `ColorOcTree` `.ot` of the tree: each node's log-odds, three colour bytes (made
    /// from the node's position in the file, so that equal subtrees may differ in colour),
    /// then its child mask.
    fn color_file(root: &Node, tint: u8) -> Vec<u8> {
        fn body(node: &Node, tint: u8, out: &mut Vec<u8>) {
            let (value, children) = match node {
                Node::Unknown => return,
                Node::Leaf(v) => (*v, &[][..]),
                Node::Inner(v, children) => (*v, &children[..]),
            };
            let mask = children
                .iter()
                .enumerate()
                .filter(|(_, c)| !matches!(c, Node::Unknown))
                .fold(0u8, |m, (i, _)| m | 1 << i);
            let n = out.len() as u8;
            out.extend(value.to_le_bytes());
            out.extend([n ^ tint, n.wrapping_mul(3), tint]);
            out.push(mask);
            for child in children {
                body(child, tint, out);
            }
        }
        let mut out = format!(
            "{}\nid ColorOcTree\nsize {}\nres 0.1\ndata\n",
            FileKind::Full.first_line(),
            nodes(root)
        )
        .into_bytes();
        body(root, tint, &mut out);
        out
    }

    #[test]
    fn color_trees_read_and_compare_as_their_occupancy() {
        for seed in 0..24u64 {
            let a = tree(seed, (0, 0), 0, 0);
            let b = tree(seed, (seed + 1, 150), 0, 0);
            let (plain_a, plain_b) = (file(&a, FileKind::Full), file(&b, FileKind::Full));
            let (color_a, color_b) = (color_file(&a, 7), color_file(&b, 9));
            let read = |bytes: &[u8]| decode(bytes, None, ReadLimits::default()).unwrap();
            let (got, want) = (read(&color_a), read(&plain_a));
            assert_eq!(got.leaves, want.leaves);
            assert_eq!(got.node_count, want.node_count);
            assert!(
                got.warnings
                    .iter()
                    .any(|w| w.contains("`ColorOcTree` read as a plain OcTree")),
                "{:?}",
                got.warnings
            );
            // Colour files compared from their bytes (colours differ everywhere), and files
            // of the two layouts compared through their leaves.
            for (previous, current) in [
                (Some(&color_a[..]), &color_b[..]),
                (Some(&color_b), &color_a),
                (None, &color_b),
                (Some(&color_a), &color_a),
                (Some(&plain_a), &color_b),
                (Some(&color_a), &plain_b),
            ] {
                let (got, summary) = collect(previous, current);
                assert_eq!(got, expected(previous, current), "seed {seed}");
                let scanned = scan(current, None, ReadLimits::default(), &mut |_| {}).unwrap();
                assert_eq!(summary, scanned);
            }
        }
        // Other tree types, whose node layouts froctomap does not know, are refused.
        let plain = file(&tree(3, (0, 0), 0, 0), FileKind::Full);
        let at = plain.windows(9).position(|w| w == b"id OcTree").unwrap() + 9;
        let stamped = [&plain[..at], b"Stamped", &plain[at..]].concat();
        let got = diff(None, &stamped, None, ReadLimits::default(), &mut |_| {});
        assert!(
            matches!(&got, Err(CodecError::UnsupportedTreeType(id)) if id == "OcTreeStamped"),
            "{got:?}"
        );
    }

    #[test]
    fn a_file_whose_header_says_size_0_is_an_empty_map() {
        for kind in [FileKind::Binary, FileKind::Full] {
            let previous = file(&tree(5, (0, 0), 0, 0), kind);
            // Upstream skips whatever follows `size 0`.
            let empty = format!(
                "{}\nid OcTree\nsize 0\nres 0.1\ndata\n\x0f\x00",
                kind.first_line()
            );
            let (got, summary) = collect(Some(&previous), empty.as_bytes());
            assert!(!got.is_empty() && got.iter().all(|c| c.new.is_none()));
            assert_eq!(got, expected(Some(&previous), empty.as_bytes()));
            assert_eq!(summary.node_count, 0);
        }
    }

    #[test]
    fn a_broken_current_file_is_rejected_like_a_read_rejects_it() {
        let a = file(&tree(7, (0, 0), 0, 0), FileKind::Binary);
        let b = file(&tree(7, (9, 100), 0, 0), FileKind::Binary);
        let body = parse_header(&b, FileKind::Binary).unwrap().body_offset;
        for cut in body..b.len() {
            let mut sink = |_| {};
            let got = diff(
                Some((&a, None)),
                &b[..cut],
                None,
                ReadLimits::default(),
                &mut sink,
            );
            assert!(
                matches!(got, Err(CodecError::Truncated { .. })),
                "cut at {cut}: {got:?}"
            );
        }
        let limits = ReadLimits { max_nodes: 10 };
        let got = diff(Some((&a, None)), &b, None, limits, &mut |_| {});
        assert_eq!(got.map(|_| ()), Err(CodecError::TooManyNodes { limit: 10 }));
        // A NaN leaf in a .ot.
        let nan = file(
            &Node::Inner(0.0, vec![Node::Leaf(f32::NAN)]),
            FileKind::Full,
        );
        let got = diff(None, &nan, None, ReadLimits::default(), &mut |_| {});
        assert!(matches!(got, Err(CodecError::NotANumber { .. })), "{got:?}");
    }
}
