//! Pure-Rust reading and writing of OctoMap's `.bt` and `.ot` files, without building a tree.
//!
//! **Reading.** The parser accepts what upstream OctoMap 1.9.7 accepts (header keywords in any order,
//! comments, CRLF, a `size` that does not match, the pre-1.4 headerless `.bt`) and rejects
//! everything else with a [`CodecError`] that says what is wrong and where. Unlike upstream,
//! it never reads past the end of the data and never recurses deeper than the 16 levels a
//! tree has, so the FFI crate runs it before handing untrusted bytes to the C++ library.
//! It is also a reader in its own right: [`scan`] streams the leaves (coarse leaves as one
//! item with their depth) in Morton order straight from the bit stream, [`scan_runs`] merges
//! them into runs of equal state, [`decode`] collects them, and [`diff`] reads two files side
//! by side and streams only the ranges where the second differs from the first.
//!
//! **Writing.** [`encode_binary`] and [`encode_full`] (and their streaming forms
//! [`BinaryEncoder`] and [`FullEncoder`], fed leaf by leaf in Morton order) write the files
//! upstream writes for the same tree, byte for byte, including upstream's partial pruning
//! of `.bt` output and its `%g` formatting of the resolution.
//!
//! ```
//! use froctomap_octomap_codec::{decode, ReadLimits};
//! // A tree with one inner node per level down to a single occupied voxel at depth 16:
//! let mut file = b"# Octomap OcTree binary file\nid OcTree\nsize 17\nres 0.1\ndata\n".to_vec();
//! for _ in 0..15 { file.extend([0b11, 0]); } // child 0 has children
//! file.extend([0b10, 0]);                   // child 0 is an occupied leaf
//! let tree = decode(&file, None, ReadLimits::default())?;
//! assert_eq!(tree.node_count, 17);
//! assert_eq!(tree.leaves.len(), 1);
//! assert_eq!(tree.leaves[0].depth, 16);
//! assert!(tree.leaves[0].occupancy().is_occupied());
//! # Ok::<(), froctomap_octomap_codec::CodecError>(())
//! ```

mod body;
mod canonical;
mod diff;
mod encode;
mod error;
mod header;
mod kind;
mod runs;

pub use body::{walk_body, BodySummary, ReadLimits};
pub use canonical::{BinaryPart, CanonicalBinaryBuilder};
pub use diff::{diff, TreeIndex};
pub use encode::{encode_binary, encode_full, format_resolution, BinaryEncoder, FullEncoder};
pub use error::{CodecError, EncodeError};
pub use header::{
    detect_kind, looks_like_legacy_binary, parse_header, Header, HeaderLayout, OCTREE_ID,
};
pub use kind::{FileKind, TreeType, BINARY_FIRST_LINE, FULL_FIRST_LINE};
pub use runs::{merge_runs, scan_runs, RunMerger, VoxelRun};

use froctomap_core::Leaf;

/// A file read completely: header, leaves in Morton order, and what upstream would warn about.
#[derive(Clone, Debug, PartialEq)]
pub struct DecodedTree {
    /// The parsed header.
    pub header: Header,
    /// Every leaf, in Morton order.
    pub leaves: Vec<Leaf>,
    /// Nodes in the tree as upstream counts them (0 for an empty tree).
    pub node_count: u64,
    /// Offset one past the last byte of tree data.
    pub data_end: usize,
    /// Header warnings plus size mismatches and ignored trailing bytes.
    pub warnings: Vec<String>,
}

/// Decodes a whole file. `kind` forces a layout; `None` detects it from the first line
/// (falling back to the legacy headerless `.bt`).
pub fn decode(
    bytes: &[u8],
    kind: Option<FileKind>,
    limits: ReadLimits,
) -> Result<DecodedTree, CodecError> {
    let mut leaves = Vec::with_capacity(leaf_capacity_hint(bytes, kind, limits));
    let summary = scan(bytes, kind, limits, &mut |leaf| leaves.push(leaf))?;
    Ok(DecodedTree {
        header: summary.header,
        leaves,
        node_count: summary.node_count,
        data_end: summary.data_end,
        warnings: summary.warnings,
    })
}

/// How many leaves to reserve room for: the header's node count (an upper bound on the
/// leaves of a well-formed file), capped by what the body's length can hold and by the node
/// limit, so a lying header cannot cause a large allocation. Growing the vector instead
/// costs more than the walk itself on large files.
fn leaf_capacity_hint(bytes: &[u8], kind: Option<FileKind>, limits: ReadLimits) -> usize {
    let kind = kind
        .or_else(|| detect_kind(bytes))
        .unwrap_or(FileKind::Binary);
    let Ok(header) = parse_header(bytes, kind) else {
        return 0;
    };
    let body = bytes.len().saturating_sub(header.body_offset) as u64;
    let most_leaves = match kind {
        // Every 2 bytes describe at most 8 children.
        FileKind::Binary => body.saturating_mul(4),
        // Every node takes a record of its type's length.
        FileKind::Full => {
            body / TreeType::from_id(&header.tree_id).map_or(5, TreeType::full_record_len) as u64
        }
    };
    let hint = u64::from(header.declared_size)
        .min(most_leaves)
        .min(limits.max_nodes);
    usize::try_from(hint).unwrap_or(0)
}

/// What [`scan`] found, without the leaves.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanSummary {
    /// The parsed header.
    pub header: Header,
    /// Nodes in the tree as upstream counts them.
    pub node_count: u64,
    /// Offset one past the last byte of tree data.
    pub data_end: usize,
    /// Everything worth telling the user.
    pub warnings: Vec<String>,
}

/// Checks a whole file and streams its leaves to `on_leaf` without keeping them.
///
/// `on_leaf` may be a closure or a `&mut dyn FnMut(Leaf)`; a closure is inlined into the
/// walk, which is what makes streaming reads cheap.
///
/// ```
/// use froctomap_octomap_codec::{scan, ReadLimits};
/// let file = b"# Octomap OcTree binary file\nid OcTree\nsize 3\nres 0.1\ndata\n\x09\x00";
/// let mut states = Vec::new();
/// let summary = scan(file, None, ReadLimits::default(), &mut |leaf| states.push(leaf.occupancy()))?;
/// assert_eq!(summary.node_count, 3); // the root and two depth-1 leaves: child 0 free, 1 occupied
/// assert_eq!(states.len(), 2);
/// # Ok::<(), froctomap_octomap_codec::CodecError>(())
/// ```
pub fn scan<F: FnMut(Leaf) + ?Sized>(
    bytes: &[u8],
    kind: Option<FileKind>,
    limits: ReadLimits,
    on_leaf: &mut F,
) -> Result<ScanSummary, CodecError> {
    scan_with(bytes, kind, |kind, tree, body, body_offset| {
        walk_body(kind, tree, body, body_offset, limits, on_leaf)
    })
}

/// The header checks and warnings of [`scan`] around a walk of the body.
pub(crate) fn scan_with(
    bytes: &[u8],
    kind: Option<FileKind>,
    walk: impl FnOnce(FileKind, TreeType, &[u8], usize) -> Result<BodySummary, CodecError>,
) -> Result<ScanSummary, CodecError> {
    if bytes.is_empty() {
        return Err(CodecError::Empty);
    }
    let kind = kind
        .or_else(|| detect_kind(bytes))
        .unwrap_or(FileKind::Binary);
    let header = parse_header(bytes, kind)?;
    let tree = match (kind, TreeType::from_id(&header.tree_id)) {
        (FileKind::Full, None) => return Err(CodecError::UnsupportedTreeType(header.tree_id)),
        // A .bt node stores occupancy whatever the type.
        (FileKind::Binary, _) => TreeType::OcTree,
        (FileKind::Full, Some(tree)) => tree,
    };
    let mut warnings = header.warnings.clone();
    if header.tree_id != OCTREE_ID {
        warnings.push(match kind {
            FileKind::Binary => format!(
                "tree id `{}` read as a plain OcTree (a .bt file stores occupancy only)",
                header.tree_id
            ),
            FileKind::Full => format!(
                "tree id `{}` read as a plain OcTree (its occupancy; the rest of each node is skipped)",
                header.tree_id
            ),
        });
    }
    let body = bytes.get(header.body_offset..).unwrap_or_default();
    let (node_count, data_end) = if header.declared_size == 0 {
        // Upstream reads no data when the header says `size 0`.
        if !body.is_empty() {
            warnings.push(format!(
                "header says `size 0`, so the {} bytes after it are ignored (as OctoMap does)",
                body.len()
            ));
        }
        (0, header.body_offset)
    } else {
        let summary = walk(kind, tree, body, header.body_offset)?;
        if summary.node_count != u64::from(header.declared_size) {
            warnings.push(format!(
                "header says `size {}` but the tree has {} nodes; the tree data is complete, so it is used (OctoMap loads it too but reports failure)",
                header.declared_size, summary.node_count
            ));
        }
        (summary.node_count, header.body_offset + summary.len)
    };
    if data_end < bytes.len() {
        warnings.push(format!(
            "{} bytes after the end of the tree data are ignored",
            bytes.len() - data_end
        ));
    }
    Ok(ScanSummary {
        header,
        node_count,
        data_end,
        warnings,
    })
}
