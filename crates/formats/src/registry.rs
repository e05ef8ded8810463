//! Map formats as data, and the registry that picks one for a file.

use crate::error::{DuplicateName, FormatError, PluginError};
use crate::file_kind::check_regular_file;
use crate::hooks::{MapHeader, TiledMapWriter};
use crate::probe::{file_head, Confidence};
use crate::recording::RecordingFormat;
use froctomap_core::{write_atomically, Snapshot, StateChange};
use std::io::Write;
use std::path::Path;

/// A map read from a file, with what is worth telling the user about it.
#[derive(Clone, Debug)]
pub struct ReadMap {
    /// The map.
    pub snapshot: Snapshot,
    /// Nodes of the stored tree (inner and leaf), as the format counts them.
    pub node_count: u64,
    /// Things the reader tolerated (e.g. a size mismatch) but the user may want to know.
    pub warnings: Vec<String>,
}

/// Decodes a format's bytes into a map.
pub trait MapReader: Send + Sync {
    /// Reads a whole file's content.
    fn read(&self, bytes: &[u8]) -> Result<ReadMap, PluginError>;
}

/// What a [`MapDiffer`] keeps about a file it compared, to compare the next file with it
/// faster (its own type; other differs ignore it).
pub type DiffState = Box<dyn std::any::Any + Send + Sync>;

/// A file compared before, as the next comparison sees it.
#[derive(Clone, Copy, Debug)]
pub struct PreviousFile<'a> {
    /// Its content.
    pub bytes: &'a [u8],
    /// What the differ kept when it compared this file ([`MapDiff::state`]), if at hand.
    pub state: Option<&'a DiffState>,
}

/// What a [`MapDiffer`] learnt about the current file while comparing it.
#[derive(Debug)]
pub struct MapDiff {
    /// Voxel edge length of the current file, in metres.
    pub resolution: f64,
    /// Nodes of its stored tree, as the format counts them.
    pub node_count: u64,
    /// What a [`MapReader`] would have warned about.
    pub warnings: Vec<String>,
    /// Kept to compare the next file with this one ([`PreviousFile::state`]).
    pub state: Option<DiffState>,
}

/// Compares two files of a format straight from their bytes, without decoding either: the
/// fast path for consecutive snapshots of a series, which differ in few places.
pub trait MapDiffer: Send + Sync {
    /// Checks `current` as [`MapReader::read`] would and streams, in Morton order and maximal
    /// per new state, the ranges where its map differs from `previous`'s (a file of the same
    /// format that was read before; `None`: a map where nothing is known): the list
    /// [`froctomap_core::changes`] gives for the two maps' leaves.
    fn diff(
        &self,
        previous: Option<PreviousFile<'_>>,
        current: &[u8],
        on_change: &mut dyn FnMut(StateChange),
    ) -> Result<MapDiff, PluginError>;
}

/// Encodes a map into a format's bytes.
pub trait MapWriter: Send + Sync {
    /// Writes the map to `out`.
    fn write(&self, snapshot: &Snapshot, out: &mut dyn Write) -> Result<(), PluginError>;
}

/// Which implementation stands behind a format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Backend {
    /// The upstream OctoMap C++ library.
    Octomap,
    /// froctomap's own Rust code.
    Native,
}

impl Backend {
    /// Name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Backend::Octomap => "octomap",
            Backend::Native => "native",
        }
    }
}

impl froctomap_core::Named for Backend {
    const ALL: &'static [Self] = &[Self::Octomap, Self::Native];
    const WHAT: &'static str = "backend";

    fn name(self) -> &'static str {
        Backend::name(self)
    }

    fn description(self) -> &'static str {
        match self {
            Self::Octomap => "The upstream OctoMap C++ library (liboctomap)",
            Self::Native => "froctomap's own Rust codec (the default; faster)",
        }
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(Backend::name(*self))
    }
}

impl std::str::FromStr for Backend {
    type Err = froctomap_core::UnknownName;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        froctomap_core::parse_named(name)
    }
}

/// A format's header hook ([`MapFormat::header`]): the header a file's first bytes give.
pub type ReadHeader = fn(&[u8]) -> Option<MapHeader>;

/// One map format plugin, described by data (like Symphonia's probe descriptors).
#[derive(Clone, Copy)]
pub struct MapFormat {
    /// Short name, as used with `--format` (e.g. `bt`).
    pub name: &'static str,
    /// One line for listings.
    pub description: &'static str,
    /// Implementation behind it.
    pub backend: Backend,
    /// File extensions, lower case, without dot; the first one is used for output names.
    pub extensions: &'static [&'static str],
    /// Recognises the format from the first bytes of a file (at least the first line).
    pub probe: fn(&[u8]) -> Confidence,
    /// Creates a reader, if the format can be read.
    pub reader: Option<fn() -> Box<dyn MapReader>>,
    /// Creates a writer, if the format can be written.
    pub writer: Option<fn() -> Box<dyn MapWriter>>,
    /// Creates a differ, if two files of the format can be compared without decoding them.
    pub differ: Option<fn() -> Box<dyn MapDiffer>>,
    /// Reads the header from a file's first [`PROBE_BYTES`](crate::PROBE_BYTES), if the
    /// format has one: `None` when those bytes do not give it (damaged, or a header longer
    /// than that), and the full read decides. Converters check every input's header before
    /// decoding any, so a file of another resolution is refused early.
    pub header: Option<ReadHeader>,
    /// Creates a writer fed the map a part at a time, in parallel, if the format stores
    /// states only ([`Capabilities::states_only`]; ignored otherwise): converters then write
    /// a FROctomap file's map tile by tile without holding it whole ([`Self::states_tiled_writer`]).
    pub tiled_writer: Option<fn() -> Box<dyn TiledMapWriter>>,
    /// What callers may rely on beyond reading and writing (consulted instead of names).
    pub capabilities: Capabilities,
}

/// Properties of a format that change how callers prepare or produce its files: data on the
/// descriptor, so that code never branches on a format's name.
///
/// ```
/// use froctomap_formats::Capabilities;
/// let states = Capabilities::NONE.with_states_only();
/// assert!(states.states_only && !Capabilities::NONE.states_only);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Capabilities {
    /// The format stores occupancy states only, no probabilities (OctoMap's `.bt`): a map is
    /// reduced to maximum likelihood before it is written, so that nodes merge as the stored
    /// states allow.
    pub states_only: bool,
}

impl Capabilities {
    /// Nothing beyond reading and writing.
    pub const NONE: Capabilities = Capabilities { states_only: false };

    /// These capabilities and [`states_only`](Self::states_only) (for plugins outside this
    /// crate, which cannot name every field of a non-exhaustive struct).
    pub const fn with_states_only(mut self) -> Self {
        self.states_only = true;
        self
    }
}

/// A format of files that hold a series of timed maps rather than one map (froctomap's own
/// `.froct`; later recordings such as ROS bags). The registry only recognises such files, so
/// that one probe tells a caller what any file is; opening them is the business of the crate
/// that registered the descriptor.
#[derive(Clone, Copy, Debug)]
pub struct SeriesFormat {
    /// Short name (e.g. `froct`).
    pub name: &'static str,
    /// One line for listings.
    pub description: &'static str,
    /// File extensions, lower case, without dot.
    pub extensions: &'static [&'static str],
    /// Recognises the format from the first bytes of a file.
    pub probe: fn(&[u8]) -> Confidence,
}

/// What the registry's probe found a file to be.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub enum Identified<'a> {
    /// One map, readable through the registry.
    Map(&'a MapFormat),
    /// A series of maps, of a format registered with [`FormatRegistry::register_series`].
    Series(&'a SeriesFormat),
    /// A recording of timed maps (a ROS bag…), of a format registered with
    /// [`FormatRegistry::register_recording`].
    Recording(&'a RecordingFormat),
}

impl Identified<'_> {
    /// The format's short name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Map(f) => f.name,
            Self::Series(f) => f.name,
            Self::Recording(f) => f.name,
        }
    }

    /// The format's one-line description.
    pub fn description(&self) -> &'static str {
        match self {
            Self::Map(f) => f.description,
            Self::Series(f) => f.description,
            Self::Recording(f) => f.description,
        }
    }
}

impl std::fmt::Debug for MapFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MapFormat")
            .field("name", &self.name)
            .field("backend", &self.backend)
            .field("extensions", &self.extensions)
            .finish()
    }
}

impl MapFormat {
    /// `true` when `path` ends in one of this format's extensions (case-insensitive).
    pub fn matches_extension(&self, path: &Path) -> bool {
        extension_of(path).is_some_and(|ext| self.extensions.contains(&ext.as_str()))
    }

    /// A writer fed a map of states a part at a time, when the format offers one and stores
    /// states only (a part writer sees no probabilities, so only then are its bytes the
    /// [`MapWriter`]'s).
    ///
    /// ```
    /// use froctomap_formats::octomap_native;
    /// assert!(octomap_native::BINARY.states_tiled_writer().is_some());
    /// assert!(octomap_native::FULL.states_tiled_writer().is_none()); // .ot keeps log-odds
    /// ```
    pub fn states_tiled_writer(&self) -> Option<Box<dyn TiledMapWriter>> {
        self.tiled_writer
            .filter(|_| self.capabilities.states_only)
            .map(|make| make())
    }
}

fn extension_of(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

/// How a file should be read.
#[derive(Clone, Copy, Debug, Default)]
pub struct ReadOptions<'a> {
    /// Force this format instead of detecting it from the content.
    pub format: Option<&'a str>,
    /// Prefer this backend where a format has several.
    pub backend: Option<Backend>,
}

/// How a file should be written.
#[derive(Clone, Copy, Debug, Default)]
pub struct WriteOptions<'a> {
    /// Use this format instead of the one the output extension names.
    pub format: Option<&'a str>,
    /// Prefer this backend where a format has several.
    pub backend: Option<Backend>,
}

/// A file read through the registry.
#[derive(Clone, Debug)]
pub struct ReadOutcome {
    /// The map and its warnings.
    pub map: ReadMap,
    /// The format that read it.
    pub format: MapFormat,
}

/// Two files compared through the registry.
#[derive(Debug)]
pub struct DiffOutcome {
    /// What the differ learnt about the current file, with the registry's warnings.
    pub diff: MapDiff,
    /// The format that compared them.
    pub format: MapFormat,
}

/// The formats known to a program. Formats registered earlier win ties, so the preferred
/// backend of a format is registered first.
///
/// ```
/// use froctomap_formats::FormatRegistry;
/// let registry = FormatRegistry::with_default_formats();
/// let format = registry.probe(b"# Octomap OcTree binary file\n...").unwrap();
/// assert_eq!(format.name, "bt");
/// assert!(registry.by_name("ot", None).is_ok());
/// ```
#[derive(Clone, Debug, Default)]
pub struct FormatRegistry {
    formats: Vec<MapFormat>,
    series: Vec<SeriesFormat>,
    recordings: Vec<RecordingFormat>,
}

impl FormatRegistry {
    /// A registry without formats.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a format. Several backends may share a name (OctoMap's `bt` is native or
    /// upstream); a name and backend already registered are refused.
    pub fn register(&mut self, format: MapFormat) -> Result<(), DuplicateName> {
        if self
            .formats
            .iter()
            .any(|f| f.name == format.name && f.backend == format.backend)
        {
            return Err(DuplicateName {
                kind: "map format",
                name: format!("{} (backend {})", format.name, format.backend.name()),
            });
        }
        self.formats.push(format);
        Ok(())
    }

    /// Every registered format, in registration order.
    pub fn formats(&self) -> &[MapFormat] {
        &self.formats
    }

    /// Adds a format of series files, so that [`identify`](Self::identify) recognises them;
    /// a name already registered (as a series or recording format) is refused.
    pub fn register_series(&mut self, format: SeriesFormat) -> Result<(), DuplicateName> {
        self.refuse_taken("series format", format.name)?;
        self.series.push(format);
        Ok(())
    }

    /// Adds a format of recordings (ROS bags…), which input collection then expands into
    /// their maps and [`identify`](Self::identify) recognises; a name already registered
    /// (as a series or recording format) is refused.
    pub fn register_recording(&mut self, format: RecordingFormat) -> Result<(), DuplicateName> {
        self.refuse_taken("recording format", format.name)?;
        self.recordings.push(format);
        Ok(())
    }

    fn refuse_taken(&self, kind: &'static str, name: &str) -> Result<(), DuplicateName> {
        let taken = self.series.iter().any(|f| f.name == name)
            || self.recordings.iter().any(|f| f.name == name);
        if taken {
            return Err(DuplicateName {
                kind,
                name: name.to_string(),
            });
        }
        Ok(())
    }

    /// Every registered recording format, in registration order.
    pub fn recording_formats(&self) -> &[RecordingFormat] {
        &self.recordings
    }

    /// The recording format that recognises `path` (a file by its first bytes, a directory
    /// by its layout), if any.
    pub fn recording_for(&self, path: &Path) -> Option<&RecordingFormat> {
        if path.is_dir() {
            return self
                .recordings
                .iter()
                .find(|f| f.probe_dir.is_some_and(|probe| probe(path)));
        }
        if self.recordings.is_empty() {
            return None;
        }
        let head = file_head(path).ok()?;
        // The most confident; the earliest registered on ties.
        let best = self
            .recordings
            .iter()
            .map(|f| (f.probe)(&head))
            .max()
            .filter(|&c| c > Confidence::No)?;
        self.recordings.iter().find(|f| (f.probe)(&head) == best)
    }

    /// The recording format named `name`, if it can be written.
    pub fn writable_recording(&self, name: &str) -> Option<&RecordingFormat> {
        self.recordings
            .iter()
            .find(|f| f.name == name && f.writable())
    }

    /// The writable recording format whose extension `path` has (`out.mcap`: MCAP, `out.bag`:
    /// a ROS 1 bag when the ROS plugins are registered), for an export's default format.
    pub fn writable_recording_for(&self, path: &std::path::Path) -> Option<&RecordingFormat> {
        let extension = path.extension()?.to_str()?;
        self.recordings.iter().find(|f| {
            f.writable()
                && f.extensions
                    .iter()
                    .any(|e| e.eq_ignore_ascii_case(extension))
        })
    }

    /// Every registered series format, in registration order.
    pub fn series_formats(&self) -> &[SeriesFormat] {
        &self.series
    }

    /// What is registered, a row per format: the map formats (per backend), then the series
    /// and the recording formats, each in registration order. What `froctomap formats`
    /// prints and Python's `formats()` returns.
    ///
    /// ```
    /// use froctomap_formats::{FormatKind, FormatRegistry};
    /// let listing = FormatRegistry::with_default_formats().listing();
    /// let bt = listing.iter().find(|f| f.name == "bt").unwrap();
    /// assert_eq!((bt.kind, bt.read, bt.write), (FormatKind::Map, true, true));
    /// // This crate registers map formats; the series and recording formats come from the
    /// // crates that implement them (froctomap_convert's `Context` has them all).
    /// assert!(listing.iter().all(|f| f.kind == FormatKind::Map));
    /// ```
    pub fn listing(&self) -> Vec<FormatListing> {
        let maps = self.formats.iter().map(|f| FormatListing {
            name: f.name,
            kind: FormatKind::Map,
            backend: Some(f.backend),
            extensions: f.extensions,
            read: f.reader.is_some(),
            write: f.writer.is_some(),
            description: f.description,
        });
        let series = self.series.iter().map(|f| FormatListing {
            name: f.name,
            kind: FormatKind::Series,
            backend: None,
            extensions: f.extensions,
            read: true,
            write: true,
            description: f.description,
        });
        let recordings = self.recordings.iter().map(|f| FormatListing {
            name: f.name,
            kind: FormatKind::Recording,
            backend: None,
            extensions: f.extensions,
            read: true,
            write: f.writable(),
            description: f.description,
        });
        maps.chain(series).chain(recordings).collect()
    }
}

/// What a registered format is (a row of [`FormatRegistry::listing`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum FormatKind {
    /// One map a file (OctoMap `.bt`, `.ot`).
    Map,
    /// A spatio-temporal series file (`.froct`).
    Series,
    /// A recording of map messages (ROS bags, MCAP).
    Recording,
}

impl froctomap_core::Named for FormatKind {
    const ALL: &'static [Self] = &[Self::Map, Self::Series, Self::Recording];
    const WHAT: &'static str = "format kind";

    fn name(self) -> &'static str {
        match self {
            Self::Map => "map",
            Self::Series => "series",
            Self::Recording => "recording",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Self::Map => "one map a file",
            Self::Series => "a spatio-temporal series file",
            Self::Recording => "a recording of map messages",
        }
    }
}

/// A registered format as [`FormatRegistry::listing`] lists it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct FormatListing {
    /// Its name (`--format`, `format=`).
    pub name: &'static str,
    /// What it is.
    pub kind: FormatKind,
    /// A map format's implementation; `None` for the others.
    pub backend: Option<Backend>,
    /// File name extensions, without the dot (none for a directory format).
    pub extensions: &'static [&'static str],
    /// Whether froctomap reads it.
    pub read: bool,
    /// Whether froctomap writes it.
    pub write: bool,
    /// One line.
    pub description: &'static str,
}

impl FormatRegistry {
    /// What `bytes` (the start of a file) are: the most confident of the readable map
    /// formats, the series and the recording formats (map formats win ties).
    ///
    /// ```
    /// use froctomap_formats::{Confidence, FormatRegistry, Identified, SeriesFormat};
    /// let mut registry = FormatRegistry::with_default_formats();
    /// registry.register_series(SeriesFormat {
    ///     name: "demo",
    ///     description: "a demo series",
    ///     extensions: &["demo"],
    ///     probe: |bytes| if bytes.starts_with(b"DEMO") { Confidence::Certain } else { Confidence::No },
    /// })?;
    /// assert!(matches!(registry.identify(b"DEMO..."), Some(Identified::Series(f)) if f.name == "demo"));
    /// assert!(matches!(registry.identify(b"# Octomap OcTree binary file\n"), Some(Identified::Map(_))));
    /// # Ok::<(), froctomap_formats::DuplicateName>(())
    /// ```
    pub fn identify(&self, bytes: &[u8]) -> Option<Identified<'_>> {
        let map = self
            .probe_with(bytes, None)
            .map(|f| (Identified::Map(f), (f.probe)(bytes)));
        let mut best = map;
        let series = self
            .series
            .iter()
            .map(|f| (Identified::Series(f), (f.probe)(bytes)));
        let recordings = self
            .recordings
            .iter()
            .map(|f| (Identified::Recording(f), (f.probe)(bytes)));
        for (identified, confidence) in series.chain(recordings) {
            if confidence > Confidence::No && best.as_ref().is_none_or(|(_, c)| confidence > *c) {
                best = Some((identified, confidence));
            }
        }
        best.map(|(identified, _)| identified)
    }

    /// [`identify`](Self::identify) on the first [`PROBE_BYTES`] of a file.
    pub fn identify_file(&self, path: &Path) -> Result<Option<Identified<'_>>, FormatError> {
        Ok(self.identify(&file_head(path)?))
    }

    /// Formats of the preferred backend first, then the rest, each in registration order.
    fn ordered(&self, backend: Option<Backend>) -> impl Iterator<Item = &MapFormat> {
        let preferred = self
            .formats
            .iter()
            .filter(move |f| backend.is_none_or(|b| f.backend == b));
        let others = self
            .formats
            .iter()
            .filter(move |f| backend.is_some_and(|b| f.backend != b));
        preferred.chain(others)
    }

    /// The format with this name, preferring `backend` when given.
    pub fn by_name(&self, name: &str, backend: Option<Backend>) -> Result<&MapFormat, FormatError> {
        self.ordered(backend)
            .find(|f| f.name.eq_ignore_ascii_case(name))
            .ok_or_else(|| FormatError::UnknownFormat {
                name: name.to_string(),
                known: self.known_names(),
            })
    }

    /// The format a file name's extension suggests.
    pub fn by_extension(&self, path: &Path, backend: Option<Backend>) -> Option<&MapFormat> {
        self.ordered(backend).find(|f| f.matches_extension(path))
    }

    /// The readable format that recognises `bytes` most confidently.
    pub fn probe(&self, bytes: &[u8]) -> Option<&MapFormat> {
        self.probe_with(bytes, None)
    }

    fn probe_with(&self, bytes: &[u8], backend: Option<Backend>) -> Option<&MapFormat> {
        let mut best: Option<(&MapFormat, Confidence)> = None;
        for format in self.ordered(backend).filter(|f| f.reader.is_some()) {
            let confidence = (format.probe)(bytes);
            if confidence > Confidence::No && best.is_none_or(|(_, c)| confidence > c) {
                best = Some((format, confidence));
            }
        }
        best.map(|(format, _)| format)
    }

    /// Names of the formats that can be written, each once (several backends may share a
    /// name), in registration order: the values a `--format` option accepts.
    pub fn writable_names(&self) -> Vec<&'static str> {
        let mut names: Vec<&'static str> = Vec::new();
        for format in self.formats.iter().filter(|f| f.writer.is_some()) {
            if !names.contains(&format.name) {
                names.push(format.name);
            }
        }
        names
    }

    /// Registered names, each once (several backends may share a name), in order.
    fn known_names(&self) -> String {
        let mut names: Vec<&str> = Vec::new();
        for format in &self.formats {
            if !names.contains(&format.name) {
                names.push(format.name);
            }
        }
        names.join(", ")
    }

    fn known_extensions(&self) -> String {
        let mut extensions: Vec<String> = Vec::new();
        for extension in self.formats.iter().flat_map(|f| f.extensions) {
            let dotted = format!(".{extension}");
            if !extensions.contains(&dotted) {
                extensions.push(dotted);
            }
        }
        extensions.join(", ")
    }

    /// The format that reads `bytes` (forced or detected), and a reader for it.
    fn reader_for(
        &self,
        path: &Path,
        bytes: &[u8],
        options: ReadOptions<'_>,
    ) -> Result<(MapFormat, Box<dyn MapReader>), FormatError> {
        let format = self.format_of(path, bytes, options)?;
        let make_reader = format.reader.ok_or(FormatError::Unsupported {
            format: format.name,
            action: "read",
        })?;
        Ok((format, make_reader()))
    }

    /// The format that reads `bytes`: the one forced in `options`, else the one detected.
    pub fn format_of(
        &self,
        path: &Path,
        bytes: &[u8],
        options: ReadOptions<'_>,
    ) -> Result<MapFormat, FormatError> {
        Ok(match options.format {
            Some(name) => *self.by_name(name, options.backend)?,
            None => match self.probe_with(bytes, options.backend) {
                Some(format) => *format,
                None => return Err(self.not_a_map(path, bytes)),
            },
        })
    }

    /// Why `bytes` cannot be read as a map: a series file, or nothing known.
    fn not_a_map(&self, path: &Path, bytes: &[u8]) -> FormatError {
        match self.identify(bytes) {
            Some(series @ (Identified::Series(_) | Identified::Recording(_))) => {
                FormatError::SeriesNotMap {
                    path: path.to_path_buf(),
                    format: series.name(),
                    description: series.description(),
                }
            }
            _ => FormatError::Unrecognized {
                path: path.to_path_buf(),
                reason: describe_start(bytes),
            },
        }
    }

    /// The warning due when the content's format contradicts the file name.
    fn extension_warning(
        path: &Path,
        format: &MapFormat,
        options: ReadOptions<'_>,
    ) -> Option<String> {
        (options.format.is_none()
            && extension_of(path).is_some()
            && !format.matches_extension(path))
        .then(|| {
            format!(
                "the content is a .{} file despite the file name; read as such",
                format.extensions.first().copied().unwrap_or(format.name)
            )
        })
    }

    /// Runs `read` with the right reader, naming the file in errors and warning when the
    /// detected format contradicts the file name.
    fn read_with<T>(
        &self,
        path: &Path,
        bytes: &[u8],
        options: ReadOptions<'_>,
        read: impl FnOnce(&dyn MapReader) -> Result<T, PluginError>,
        warnings: impl FnOnce(&mut T) -> &mut Vec<String>,
    ) -> Result<(T, MapFormat), FormatError> {
        let (format, reader) = self.reader_for(path, bytes, options)?;
        let mut value = read(reader.as_ref()).map_err(|source| FormatError::Decode {
            path: path.to_path_buf(),
            format: format.name,
            source,
        })?;
        if let Some(warning) = Self::extension_warning(path, &format, options) {
            warnings(&mut value).push(warning);
        }
        Ok((value, format))
    }

    /// Compares `current` with `previous` (a file read or compared before with the same
    /// options; `None`: nothing known) from their bytes, streaming the ranges where `current`'s map differs,
    /// when `current`'s format has a [`MapDiffer`] and `previous` is of the same format.
    /// `Ok(None)` otherwise: read both and compare their leaves with
    /// [`froctomap_core::changes`] instead. `path` (of `current`) is only used in messages.
    ///
    /// ```
    /// use froctomap_formats::{FormatRegistry, ReadOptions};
    /// use std::path::Path;
    /// let registry = FormatRegistry::with_default_formats();
    /// let file = b"# Octomap OcTree binary file\nid OcTree\nsize 3\nres 0.1\ndata\n\x09\x00";
    /// let mut changes = Vec::new();
    /// let outcome = registry
    ///     .diff_bytes(Path::new("a.bt"), None, file, ReadOptions::default(), &mut |c| changes.push(c))?
    ///     .expect("the native .bt format compares files without decoding them");
    /// assert_eq!((outcome.diff.resolution, changes.len()), (0.1, 2)); // a free and an occupied octant
    /// # Ok::<(), froctomap_formats::FormatError>(())
    /// ```
    pub fn diff_bytes(
        &self,
        path: &Path,
        previous: Option<PreviousFile<'_>>,
        current: &[u8],
        options: ReadOptions<'_>,
        on_change: &mut dyn FnMut(StateChange),
    ) -> Result<Option<DiffOutcome>, FormatError> {
        let format = self.format_of(path, current, options)?;
        let Some(make_differ) = format.differ else {
            return Ok(None);
        };
        if let Some(previous) = previous {
            match self.format_of(path, previous.bytes, options) {
                Ok(f) if f.name == format.name && f.backend == format.backend => {}
                _ => return Ok(None),
            }
        }
        let mut diff = make_differ()
            .diff(previous, current, on_change)
            .map_err(|source| FormatError::Decode {
                path: path.to_path_buf(),
                format: format.name,
                source,
            })?;
        if let Some(warning) = Self::extension_warning(path, &format, options) {
            diff.warnings.push(warning);
        }
        Ok(Some(DiffOutcome { diff, format }))
    }

    /// Reads a map from bytes already in memory; `path` is only used in messages.
    pub fn read_bytes(
        &self,
        path: &Path,
        bytes: &[u8],
        options: ReadOptions<'_>,
    ) -> Result<ReadOutcome, FormatError> {
        let (map, format) =
            self.read_with(path, bytes, options, |r| r.read(bytes), |m| &mut m.warnings)?;
        Ok(ReadOutcome { map, format })
    }

    /// Reads a map file, detecting its format from the content unless one is forced.
    pub fn read_file(
        &self,
        path: &Path,
        options: ReadOptions<'_>,
    ) -> Result<ReadOutcome, FormatError> {
        check_regular_file(path)?;
        let bytes = std::fs::read(path).map_err(|source| FormatError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        self.read_bytes(path, &bytes, options)
    }

    /// The format a map written to `path` gets: `options.format`, else the extension's.
    pub fn output_format(
        &self,
        path: &Path,
        options: WriteOptions<'_>,
    ) -> Result<&MapFormat, FormatError> {
        let format = match options.format {
            Some(name) => self.by_name(name, options.backend)?,
            None => self
                .ordered(options.backend)
                .find(|f| f.writer.is_some() && f.matches_extension(path))
                .ok_or_else(|| FormatError::UnknownExtension {
                    path: path.to_path_buf(),
                    known: self.known_extensions(),
                })?,
        };
        if format.writer.is_none() {
            return Err(FormatError::Unsupported {
                format: format.name,
                action: "written",
            });
        }
        Ok(format)
    }

    /// Writes a map to `path` atomically (temporary file, then rename): on any error the
    /// destination is left as it was.
    pub fn write_file(
        &self,
        snapshot: &Snapshot,
        path: &Path,
        options: WriteOptions<'_>,
    ) -> Result<MapFormat, FormatError> {
        let format = *self.output_format(path, options)?;
        let make_writer = format.writer.ok_or(FormatError::Unsupported {
            format: format.name,
            action: "written",
        })?;
        let writer = make_writer();
        // Encode into memory first so an encoder error cannot be confused with an I/O error.
        let mut bytes = Vec::new();
        writer
            .write(snapshot, &mut bytes)
            .map_err(|source| FormatError::Encode {
                path: path.to_path_buf(),
                format: format.name,
                source,
            })?;
        write_atomically(path, |out| out.write_all(&bytes)).map_err(|e| FormatError::Encode {
            path: path.to_path_buf(),
            format: format.name,
            source: Box::new(e.source),
        })?;
        Ok(format)
    }
}

/// A short description of unrecognised content for error messages.
fn describe_start(bytes: &[u8]) -> String {
    if bytes.is_empty() {
        return "the file is empty".to_string();
    }
    let line = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
    let shown: String = String::from_utf8_lossy(&line[..line.len().min(40)])
        .chars()
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    format!("it starts with {shown:?}")
}

#[cfg(all(test, feature = "octomap-upstream"))]
mod tests {
    use super::*;

    #[test]
    fn native_is_the_default_and_octomap_is_selectable() {
        let registry = FormatRegistry::with_default_formats();
        let bt = b"# Octomap OcTree binary file\n";
        let probed = |backend| {
            registry
                .probe_with(bt, backend)
                .map(|f| (f.name, f.backend))
        };
        assert_eq!(probed(None), Some(("bt", Backend::Native)));
        assert_eq!(
            probed(Some(Backend::Octomap)),
            Some(("bt", Backend::Octomap))
        );
        for backend in [Backend::Native, Backend::Octomap] {
            let format = registry.by_name("ot", Some(backend)).map(|f| f.backend);
            assert_eq!(format.ok(), Some(backend));
            let by_extension = registry.by_extension(Path::new("x.BT"), Some(backend));
            assert_eq!(by_extension.map(|f| f.backend), Some(backend));
        }
        // Names and extensions shared by several backends are listed once.
        assert_eq!(registry.known_names(), "bt, ot");
        assert_eq!(registry.known_extensions(), ".bt, .ot");
    }
}

#[cfg(test)]
mod registration_tests {
    use super::*;
    use crate::{octomap_native, RecordingFormat};

    #[test]
    fn every_registration_refuses_a_taken_name() {
        let mut registry = FormatRegistry::with_default_formats();
        let before = registry.formats().len();
        // The defaults are distinct, so registering them again is refused at the first.
        let again = crate::register_default_formats(&mut registry).unwrap_err();
        assert_eq!(again.name, "bt (backend native)");
        assert_eq!(registry.formats().len(), before);
        // Another backend of a name is a new registration, a new name too.
        let renamed = MapFormat {
            name: "tree",
            ..octomap_native::BINARY
        };
        registry.register(renamed).unwrap();
        assert!(registry.register(renamed).is_err());

        let series = SeriesFormat {
            name: "demo",
            description: "a demo series",
            extensions: &["demo"],
            probe: |_| Confidence::No,
        };
        let recording = RecordingFormat {
            name: "demo",
            description: "a demo recording",
            extensions: &["demo"],
            probe: |_| Confidence::No,
            probe_dir: None,
            open: |_, _, _| Err("not opened".into()),
            open_stream: None,
            create: None,
            create_dir: None,
            describe: None,
        };
        registry.register_series(series).unwrap();
        // Series and recordings share one namespace: `identify` names either.
        let taken = registry.register_recording(recording).unwrap_err();
        assert_eq!(
            taken.to_string(),
            "a recording format named `demo` is already registered"
        );
        assert!(registry.register_series(series).is_err());
        registry
            .register_recording(RecordingFormat {
                name: "demo2",
                ..recording
            })
            .unwrap();
        assert_eq!(registry.recording_formats().len(), 1);
    }
}
