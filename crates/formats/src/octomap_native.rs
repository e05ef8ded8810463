//! OctoMap `.bt` and `.ot` through froctomap's own Rust codec (`froctomap-octomap-codec`):
//! the default backend.
//!
//! Reading streams the file's leaves straight from its bit stream into a [`Snapshot`];
//! writing emits the bytes upstream would write for the same tree (including upstream's
//! partial pruning of `.bt` output). Both are checked against the upstream plugins
//! ([`crate::octomap_upstream`]) leaf for leaf and byte for byte by the differential tests,
//! and give the same warnings and error messages.

use crate::error::PluginError;
use crate::probe::Confidence;
use crate::registry::{
    Backend, Capabilities, MapDiff, MapDiffer, MapFormat, MapReader, MapWriter, PreviousFile,
    ReadMap,
};
use froctomap_core::{validate_resolution, MapError, Snapshot, StateChange};
use froctomap_octomap_codec::{
    decode, detect_kind, diff, encode_binary, encode_full, looks_like_legacy_binary, CodecError,
    FileKind, ReadLimits, TreeIndex,
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
    capabilities: Capabilities::NONE
        .with_states_only()
        .with_canonical_binary_writer(),
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
