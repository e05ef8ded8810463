//! What a map format may offer beyond reading, writing and comparing whole files: its header
//! read from a file's first bytes ([`MapFormat::header`](crate::MapFormat::header)), and a
//! writer fed the map a part at a time ([`MapFormat::tiled_writer`](crate::MapFormat::tiled_writer)),
//! so that the converters check inputs and write large maps in parallel without knowing the
//! format (as zarrs makes partial decoding a method of the codec).

use crate::error::PluginError;
use froctomap_core::{MortonCode, Occupancy};
use std::io::Write;

/// What a map file's header says before its body is read: enough to refuse a file of
/// another resolution before decoding it.
///
/// ```
/// use froctomap_formats::MapHeader;
/// assert_eq!(MapHeader::new(0.05).resolution, 0.05);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct MapHeader {
    /// Voxel edge length, in metres, as the header gives it (not yet validated).
    pub resolution: f64,
}

impl MapHeader {
    /// A header giving this resolution (for plugins outside this crate, which cannot build a
    /// non-exhaustive struct).
    pub const fn new(resolution: f64) -> Self {
        Self { resolution }
    }
}

/// A part of a map finished by a [`MapPartWriter`], kept in the writer's own type until
/// [`TiledMapWriter::join`] puts it in place (other writers ignore it).
pub type WrittenPart = Box<dyn std::any::Any + Send>;

/// Writes the part of a map inside one node of the octree.
pub trait MapPartWriter: Send {
    /// Adds a leaf of state `state`: the node of depth `depth` starting at `start`. Leaves
    /// come in increasing Morton order, without overlap, inside the part's node; anything
    /// else is refused.
    fn push(&mut self, start: MortonCode, depth: u8, state: Occupancy) -> Result<(), PluginError>;

    /// The finished part.
    fn finish(self: Box<Self>) -> Result<WrittenPart, PluginError>;
}

/// Writes a map of occupancy states a part at a time: the parts of disjoint nodes (a
/// FROctomap file's tiles) filled on several threads, then joined into the file. The bytes
/// are those the format's [`MapWriter`](crate::MapWriter) writes for the map of these states
/// reduced to maximum likelihood and in its canonical split ([`froctomap_core::Snapshot::canonical`]),
/// so a caller may choose either way to write a file.
pub trait TiledMapWriter: Send + Sync {
    /// A writer of the part inside the node of depth `depth` starting at `start`.
    fn part(&self, start: MortonCode, depth: u8) -> Result<Box<dyn MapPartWriter>, PluginError>;

    /// Writes the file of a map of voxel edge `resolution` made of `parts` (finished by this
    /// writer's part writers, for disjoint nodes, in Morton order) to `out`; gives the
    /// number of leaves written.
    fn join(
        &self,
        resolution: f64,
        parts: Vec<WrittenPart>,
        out: &mut dyn Write,
    ) -> Result<u64, PluginError>;
}
