//! The registry of map formats froctomap reads and writes.
//!
//! Each format is a [`MapFormat`]: plain data naming it, listing its extensions, telling how
//! to recognise its content and how to make a reader and a writer. Formats are chosen by
//! *content* when reading (OctoMap's first line tells `.bt` from `.ot`; extensions lie in the
//! wild) and by `--format` or the output extension when writing.
//!
//! A format may also offer a [`MapDiffer`], which compares two files straight from their
//! bytes ([`FormatRegistry::diff_bytes`]); building a series from consecutive snapshots uses
//! it to skip decoding what did not change. Two more optional hooks let the converters
//! treat every format alike: a [`header`](MapFormat::header) read from a file's first bytes
//! ([`MapHeader`]: its resolution, checked for every input before any is decoded), and a
//! [`TiledMapWriter`] that writes a map of states from parts built on several threads
//! (retrieval writes a FROctomap file's map tile by tile with it).
//!
//! Adding a format is one module defining a `MapFormat` constant plus one line in
//! [`register_default_formats`] (or, for a format of one program, one
//! [`FormatRegistry::register`] call on the registry that program hands to the converters).
//! What callers may rely on beyond reading and writing is data on the descriptor
//! ([`Capabilities`]), never a check of its name. Files that hold a *series* of maps are
//! recognised by the same probe through [`SeriesFormat`] descriptors
//! ([`FormatRegistry::identify`]); *recordings* of timed maps (ROS bags, MCAP…) are plugins
//! of their own ([`RecordingFormat`]: one descriptor recognises, opens and optionally writes
//! a container), registered here too. Every `register…` call returns a `Result` and refuses
//! a name already registered ([`DuplicateName`]). A format may have several implementations (backends) under
//! one name: OctoMap's `.bt`/`.ot` are read and written by the native Rust codec
//! ([`octomap_native`], the default) or by the upstream C++ library (`octomap_upstream`,
//! chosen with [`Backend::Octomap`] in [`ReadOptions`]/[`WriteOptions`]).
//!
//! ```no_run
//! use froctomap_formats::{FormatRegistry, ReadOptions, WriteOptions};
//! use std::path::Path;
//!
//! let registry = FormatRegistry::with_default_formats();
//! let read = registry.read_file(Path::new("map.bt"), ReadOptions::default())?;
//! println!("{} voxels known", read.map.snapshot.voxels().count());
//! registry.write_file(&read.map.snapshot, Path::new("map.ot"), WriteOptions::default())?;
//! # Ok::<(), froctomap_formats::FormatError>(())
//! ```

mod defaults;
mod error;
mod file_kind;
mod hooks;
mod natural;
pub mod octomap_native;
#[cfg(feature = "octomap-upstream")]
pub mod octomap_upstream;
mod probe;
mod recording;
mod registry;
mod spool;

pub use defaults::register_default_formats;
pub use error::{DuplicateName, FormatError, PluginError};
pub use file_kind::special_kind;
pub use hooks::{MapHeader, MapPartWriter, TiledMapWriter, WrittenPart};
pub use natural::natural_cmp;
pub use probe::{Confidence, PROBE_BYTES};
pub use recording::{
    CellShade, CreateRecording, CreateRecordingDir, DescribeRecording, ExportedKind, ExportedMap,
    OccupiedCell, OpenStream, RecordedMaps, RecordedTime, RecordedTopic, Recording, RecordingDir,
    RecordingFormat, RecordingOptions, RecordingProfile, RecordingSink, RecordingSummary,
    RecordingWriteOptions, RecordingWriter,
};
pub use registry::{
    Backend, Capabilities, DiffOutcome, DiffState, FormatKind, FormatListing, FormatRegistry,
    Identified, MapDiff, MapDiffer, MapFormat, MapReader, MapWriter, PreviousFile, ReadHeader,
    ReadMap, ReadOptions, ReadOutcome, SeriesFormat, WriteOptions,
};
pub use spool::{MapSpool, SpoolError, SPOOL_PREFIX};
