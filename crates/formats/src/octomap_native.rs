//! OctoMap `.bt` and `.ot` through froctomap's own Rust codec (`froctomap-octomap-codec`):
//! the default backend.
//!
//! Reading streams the file's leaves straight from its bit stream into a [`Snapshot`];
//! writing emits the bytes upstream would write for the same tree (including upstream's
//! partial pruning of `.bt` output). Both are checked against the upstream plugins
//! ([`crate::octomap_upstream`]) leaf for leaf and byte for byte by the differential tests,
//! and give the same warnings and error messages.

use crate::error::PluginError;
use crate::hooks::{MapHeader, MapPartWriter, TiledMapWriter, WrittenPart};
use crate::probe::Confidence;
use crate::registry::{
    Backend, Capabilities, MapDiff, MapDiffer, MapFormat, MapReader, MapWriter, PreviousFile,
    ReadMap,
};
use froctomap_core::{validate_resolution, MapError, MortonCode, Occupancy, Snapshot, StateChange};
use froctomap_octomap_codec::{
    decode, detect_kind, diff, encode_binary, encode_full, looks_like_legacy_binary, parse_header,
    BinaryPart, CanonicalBinaryBuilder, CodecError, FileKind, ReadLimits, TreeIndex,
};
use std::io::Write;

/// OctoMap binary (`.bt`): occupied/free states, read and written in Rust.
pub const BINARY: MapFormat = MapFormat {
    name: "bt",
    description: "OctoMap binary tree (.bt): maximum-likelihood states, native Rust codec",
    backend: Backend::Native,
    extensions: &["bt"],
    probe: probe_binary,
    reader: Some(|| Box::new(NativeReader(FileKind::Binary))),
    writer: Some(|| Box::new(NativeWriter(FileKind::Binary))),
    differ: Some(|| Box::new(NativeDiffer(FileKind::Binary))),
    header: Some(header_binary),
    tiled_writer: Some(|| Box::new(CanonicalBinaryWriter)),
    capabilities: Capabilities::NONE.with_states_only(),
};

/// OctoMap full (`.ot`): log-odds per node, read and written in Rust.
pub const FULL: MapFormat = MapFormat {
    name: "ot",
    description: "OctoMap full tree (.ot): log-odds occupancy per node, native Rust codec",
    backend: Backend::Native,
    extensions: &["ot"],
    probe: probe_full,
    reader: Some(|| Box::new(NativeReader(FileKind::Full))),
    writer: Some(|| Box::new(NativeWriter(FileKind::Full))),
    differ: Some(|| Box::new(NativeDiffer(FileKind::Full))),
    header: Some(header_full),
    tiled_writer: None,
    capabilities: Capabilities::NONE,
};

/// Recognises a `.bt` by its first line, or weakly by the pre-1.4 headerless layout.
pub(crate) fn probe_binary(bytes: &[u8]) -> Confidence {
    match detect_kind(bytes) {
        Some(FileKind::Binary) => Confidence::Certain,
        None if looks_like_legacy_binary(bytes) => Confidence::Weak,
        _ => Confidence::No,
    }
}

/// Recognises a `.ot` by its first line.
pub(crate) fn probe_full(bytes: &[u8]) -> Confidence {
    match detect_kind(bytes) {
        Some(FileKind::Full) => Confidence::Certain,
        _ => Confidence::No,
    }
}

/// The header of a `.bt` (or of a pre-1.4 headerless one), when the first bytes hold it.
pub(crate) fn header_binary(bytes: &[u8]) -> Option<MapHeader> {
    header_of(bytes, FileKind::Binary)
}

/// The header of a `.ot`, when the first bytes hold it.
pub(crate) fn header_full(bytes: &[u8]) -> Option<MapHeader> {
    header_of(bytes, FileKind::Full)
}

fn header_of(bytes: &[u8], kind: FileKind) -> Option<MapHeader> {
    let header = parse_header(bytes, kind).ok()?;
    Some(MapHeader::new(header.resolution))
}

/// Why the native codec could not read a file. The messages are those of the upstream
/// plugin's errors for the same causes, so switching backends never changes what users see.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NativeError {
    /// The bytes are not a readable OctoMap file.
    #[error(transparent)]
    Malformed(#[from] CodecError),
    /// The file is well-formed but its leaves are not a valid map (e.g. a NaN log-odds).
    #[error("invalid map")]
    InvalidMap(#[from] MapError),
}

struct NativeReader(FileKind);

impl MapReader for NativeReader {
    fn read(&self, bytes: &[u8]) -> Result<ReadMap, PluginError> {
        let tree = decode(bytes, Some(self.0), ReadLimits::default()).map_err(NativeError::from)?;
        let snapshot = Snapshot::from_leaves(tree.header.resolution, tree.leaves)
            .map_err(NativeError::from)?;
        Ok(ReadMap {
            snapshot,
            node_count: tree.node_count,
            warnings: tree.warnings,
        })
    }
}

struct NativeDiffer(FileKind);

impl MapDiffer for NativeDiffer {
    fn diff(
        &self,
        previous: Option<PreviousFile<'_>>,
        current: &[u8],
        on_change: &mut dyn FnMut(StateChange),
    ) -> Result<MapDiff, PluginError> {
        let previous = previous.map(|p| {
            let index = p.state.and_then(|s| s.downcast_ref::<TreeIndex>());
            (p.bytes, index)
        });
        let (summary, index) = diff(
            previous,
            current,
            Some(self.0),
            ReadLimits::default(),
            on_change,
        )
        .map_err(NativeError::from)?;
        let resolution =
            validate_resolution(summary.header.resolution).map_err(NativeError::from)?;
        Ok(MapDiff {
            resolution,
            node_count: summary.node_count,
            warnings: summary.warnings,
            state: Some(Box::new(index)),
        })
    }
}

struct NativeWriter(FileKind);

impl MapWriter for NativeWriter {
    fn write(&self, snapshot: &Snapshot, out: &mut dyn Write) -> Result<(), PluginError> {
        let bytes = match self.0 {
            // Byte-identical to upstream's writeBinary (maximum likelihood + its prune()).
            FileKind::Binary => encode_binary(snapshot),
            FileKind::Full => encode_full(snapshot),
        };
        out.write_all(&bytes)?;
        Ok(())
    }
}

/// The canonical `.bt` built a tile at a time ([`CanonicalBinaryBuilder`]): byte-identical
/// to [`encode_binary`] of the map reduced to maximum likelihood and made canonical.
struct CanonicalBinaryWriter;

impl TiledMapWriter for CanonicalBinaryWriter {
    fn part(&self, start: MortonCode, depth: u8) -> Result<Box<dyn MapPartWriter>, PluginError> {
        Ok(Box::new(CanonicalBinaryPart(CanonicalBinaryBuilder::new(
            start, depth,
        )?)))
    }

    fn join(
        &self,
        resolution: f64,
        parts: Vec<WrittenPart>,
        out: &mut dyn Write,
    ) -> Result<u64, PluginError> {
        let mut root = CanonicalBinaryBuilder::new(MortonCode(0), 0)?;
        for part in parts {
            let part = part
                .downcast::<BinaryPart>()
                .map_err(|_| "a part finished by another format's writer")?;
            root.push_part(*part)?;
        }
        let whole = root.finish();
        let leaves = whole.leaves();
        out.write_all(&whole.into_file(resolution)?)?;
        Ok(leaves)
    }
}

struct CanonicalBinaryPart(CanonicalBinaryBuilder);

impl MapPartWriter for CanonicalBinaryPart {
    #[inline]
    fn push(&mut self, start: MortonCode, depth: u8, state: Occupancy) -> Result<(), PluginError> {
        Ok(self.0.push_state(start, depth, state.is_occupied())?)
    }

    fn finish(self: Box<Self>) -> Result<WrittenPart, PluginError> {
        Ok(Box::new(self.0.finish()))
    }
}
