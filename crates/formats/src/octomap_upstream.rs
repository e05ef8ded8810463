//! OctoMap `.bt` and `.ot` through the upstream C++ library (`froctomap-octomap-ffi`).

use crate::error::PluginError;
use crate::octomap_native::{header_binary, header_full, probe_binary, probe_full};
use crate::registry::{Backend, Capabilities, MapFormat, MapReader, MapWriter, ReadMap};
use froctomap_core::Snapshot;
use froctomap_octomap_codec::FileKind;
use froctomap_octomap_ffi::{LoadedTree, OcTree};
use std::io::Write;

/// OctoMap binary (`.bt`): occupied/free states, read and written by liboctomap.
pub const BINARY: MapFormat = MapFormat {
    name: "bt",
    description:
        "OctoMap binary tree (.bt): maximum-likelihood states, via the upstream C++ library",
    backend: Backend::Octomap,
    extensions: &["bt"],
    probe: probe_binary,
    reader: Some(|| Box::new(UpstreamReader(FileKind::Binary))),
    writer: Some(|| Box::new(UpstreamWriter(FileKind::Binary))),
    differ: None,
    header: Some(header_binary),
    // The bytes are the same as the native tiled writer's, but choosing this backend means
    // asking for liboctomap's writer, so froctomap does not write the file itself.
    tiled_writer: None,
    capabilities: Capabilities::NONE.with_states_only(),
};

/// OctoMap full (`.ot`): log-odds per node, read and written by liboctomap.
pub const FULL: MapFormat = MapFormat {
    name: "ot",
    description:
        "OctoMap full tree (.ot): log-odds occupancy per node, via the upstream C++ library",
    backend: Backend::Octomap,
    extensions: &["ot"],
    probe: probe_full,
    reader: Some(|| Box::new(UpstreamReader(FileKind::Full))),
    writer: Some(|| Box::new(UpstreamWriter(FileKind::Full))),
    differ: None,
    header: Some(header_full),
    tiled_writer: None,
    capabilities: Capabilities::NONE,
};

struct UpstreamReader(FileKind);

impl MapReader for UpstreamReader {
    fn read(&self, bytes: &[u8]) -> Result<ReadMap, PluginError> {
        let LoadedTree { tree, warnings } = match self.0 {
            FileKind::Binary => OcTree::read_binary(bytes)?,
            FileKind::Full => OcTree::read_full(bytes)?,
        };
        Ok(ReadMap {
            snapshot: tree.to_snapshot()?,
            node_count: tree.node_count(),
            warnings,
        })
    }
}

struct UpstreamWriter(FileKind);

impl MapWriter for UpstreamWriter {
    fn write(&self, snapshot: &Snapshot, out: &mut dyn Write) -> Result<(), PluginError> {
        let mut tree = OcTree::from_snapshot(snapshot)?;
        let bytes = match self.0 {
            // Upstream's writeBinary (maximum likelihood + prune): the canonical .bt that
            // upstream tools also produce for this tree.
            FileKind::Binary => tree.write_binary()?,
            FileKind::Full => tree.write_full()?,
        };
        out.write_all(&bytes)?;
        Ok(())
    }
}
