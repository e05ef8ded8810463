//! The tree data after the header, walked without building a tree.
//!
//! Both layouts list nodes depth-first from the root, children in index order 0..8, which
//! is Morton order; the walk therefore yields leaves already sorted.
//!
//! * `.bt`: every inner node is 2 bytes, 2 bits per child (`(byte >> 2i) & 3` for child `i`
//!   of its byte; children 0–3 in the first byte, 4–7 in the second): 0 unknown, 1 free leaf,
//!   2 occupied leaf, 3 inner node whose own 2 bytes follow (after its earlier siblings'
//!   subtrees). Upstream gives free/occupied leaves the clamping bounds as log-odds. An inner
//!   node whose 8 codes are all 0 becomes, in upstream's tree, a childless node with value
//!   `-FLT_MAX` (the maximum over no children), i.e. a free leaf; a childless root keeps the
//!   occupied value upstream gives every node before reading its children.
//! * `.ot`: every node is its `f32` log-odds (little-endian), its tree type's other data
//!   (a `ColorOcTree`'s three colour bytes; nothing for an `OcTree`), then a child-mask byte;
//!   set bits are followed by those children's subtrees. Nodes without children are leaves.
//!
//! Upstream recurses without a depth bound and reads past the end of truncated data; this
//! walk stops at depth 16 and checks every length, so it can vouch for a stream before the
//! C++ library sees it.

use crate::error::CodecError;
use crate::kind::{FileKind, TreeType};
use froctomap_core::{free_log_odds, occupied_log_odds, Leaf, MortonCode, TREE_DEPTH};

/// Resource bounds for reading untrusted files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadLimits {
    /// Maximum number of tree nodes (inner and leaf). Upstream OctoMap needs about
    /// 80 bytes per node, so the default of 100 million bounds it to about 8 GB.
    pub max_nodes: u64,
}

impl Default for ReadLimits {
    fn default() -> Self {
        Self {
            max_nodes: 100_000_000,
        }
    }
}

/// What a walk of the body found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BodySummary {
    /// Nodes in the tree, counted as upstream's `size()` counts them.
    pub node_count: u64,
    /// Body bytes the tree occupies; anything after is ignored by upstream.
    pub len: usize,
}

/// Walks a body, calling `on_leaf` for every leaf in Morton order.
///
/// `body_offset` is only used to report file offsets in errors.
pub fn walk_body<F: FnMut(Leaf) + ?Sized>(
    kind: FileKind,
    tree: TreeType,
    body: &[u8],
    body_offset: usize,
    limits: ReadLimits,
    on_leaf: &mut F,
) -> Result<BodySummary, CodecError> {
    let mut walk = Walk {
        body,
        pos: 0,
        body_offset,
        nodes: 1,
        limits,
        on_leaf,
        free: free_log_odds(),
        occupied: occupied_log_odds(),
    };
    match kind {
        FileKind::Binary => walk.binary_node(0, 0)?,
        FileKind::Full => match tree {
            TreeType::OcTree => walk.full_node::<{ TreeType::OcTree.full_record_len() }>(0, 0)?,
            TreeType::ColorOcTree => {
                walk.full_node::<{ TreeType::ColorOcTree.full_record_len() }>(0, 0)?
            }
        },
    }
    Ok(BodySummary {
        node_count: walk.nodes,
        len: walk.pos,
    })
}

/// The `N` bytes of the node record at `pos` of a body, or how it is truncated.
pub(crate) fn record_at<const N: usize>(
    body: &[u8],
    pos: usize,
    body_offset: usize,
) -> Result<[u8; N], CodecError> {
    body.get(pos..pos + N)
        .and_then(|b| <[u8; N]>::try_from(b).ok())
        .ok_or(CodecError::Truncated {
            offset: body_offset + pos,
            needed: N,
            available: body.len().saturating_sub(pos),
        })
}

struct Walk<'a, 'f, F: FnMut(Leaf) + ?Sized> {
    body: &'a [u8],
    pos: usize,
    body_offset: usize,
    nodes: u64,
    limits: ReadLimits,
    on_leaf: &'f mut F,
    free: f32,
    occupied: f32,
}

impl<F: FnMut(Leaf) + ?Sized> Walk<'_, '_, F> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], CodecError> {
        let bytes = record_at(self.body, self.pos, self.body_offset)?;
        self.pos += N;
        Ok(bytes)
    }

    fn count_node(&mut self) -> Result<(), CodecError> {
        self.nodes += 1;
        if self.nodes > self.limits.max_nodes {
            return Err(CodecError::TooManyNodes {
                limit: self.limits.max_nodes,
            });
        }
        Ok(())
    }

    fn emit(&mut self, start: u64, depth: u8, log_odds: f32) {
        (self.on_leaf)(Leaf {
            start: MortonCode(start),
            depth,
            log_odds,
        });
    }

    /// Reads one `.bt` inner node at `depth` whose first voxel is `start`.
    fn binary_node(&mut self, depth: u8, start: u64) -> Result<(), CodecError> {
        let offset = self.body_offset + self.pos;
        let [low, high] = self.take::<2>()?;
        let codes = u16::from_le_bytes([low, high]);
        if codes == 0 {
            let value = if depth == 0 { self.occupied } else { -f32::MAX };
            self.emit(start, depth, value);
            return Ok(());
        }
        let child_depth = depth + 1;
        let child_shift = 3 * u32::from(TREE_DEPTH - child_depth);
        // Visit only the children that exist: the low bit of each non-zero 2-bit code.
        let mut present = (codes | codes >> 1) & 0x5555;
        while present != 0 {
            let bit = present.trailing_zeros();
            present &= present - 1;
            self.count_node()?;
            let child_start = start + (u64::from(bit / 2) << child_shift);
            match (codes >> bit) & 3 {
                1 => self.emit(child_start, child_depth, self.free),
                2 => self.emit(child_start, child_depth, self.occupied),
                _ if child_depth >= TREE_DEPTH => return Err(CodecError::TooDeep { offset }),
                _ => self.binary_node(child_depth, child_start)?,
            }
        }
        Ok(())
    }

    /// Reads one `.ot` node of `R` bytes (its log-odds first, its child mask last) at
    /// `depth` whose first voxel is `start`.
    fn full_node<const R: usize>(&mut self, depth: u8, start: u64) -> Result<(), CodecError> {
        let offset = self.body_offset + self.pos;
        let record = self.take::<R>()?;
        let value = f32::from_le_bytes([record[0], record[1], record[2], record[3]]);
        let mask = record[R - 1];
        if mask == 0 {
            self.emit(start, depth, value);
            return Ok(());
        }
        if depth >= TREE_DEPTH {
            return Err(CodecError::TooDeep { offset });
        }
        let child_depth = depth + 1;
        let child_shift = 3 * u32::from(TREE_DEPTH - child_depth);
        let mut present = mask;
        while present != 0 {
            let child = present.trailing_zeros();
            present &= present - 1;
            self.count_node()?;
            self.full_node::<R>(child_depth, start + (u64::from(child) << child_shift))?;
        }
        Ok(())
    }
}
