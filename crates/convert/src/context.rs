//! What every conversion consults and a program may extend: the registries of plugins and
//! the limits on what is read. Built once by a program (or test) and handed to each call,
//! as Symphonia hands its probe to callers, so a format or model registered by the program
//! reaches every path.

use crate::error::ConvertError;
use crate::series_file::FroctFile;
use froctomap_file::{FroctReader, LivingReader, ReadLimits};
use froctomap_formats::RecordingOptions;
use froctomap_formats::{Confidence, FormatRegistry, Identified, SeriesFormat};
use froctomap_temporal::{ModelDescriptor, ModelRegistry};
use std::path::Path;

/// Resource bounds of a conversion: checked before the work they bound is started, so a
/// hostile or mistyped input fails cleanly instead of exhausting memory or disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct Limits {
    /// Largest map file read whole into memory (an input snapshot or ground truth), bytes.
    pub max_map_file_bytes: u64,
    /// Most maps one export may write (a guard against a mistyped interval).
    pub max_exports: u64,
    /// Most tiles of the build's tile depth the known space of one input snapshot may
    /// cover (default 2^20: at tile depth 10 and 5 cm voxels, 3.2 m tiles, about 3·10^7 m³).
    /// Each tile a snapshot covers holds at least one cell of the build (a leaf coarser than
    /// a tile is split into the tiles it covers), so a few bytes of coarse leaves cannot
    /// make a build split space into billions of cells; the cells inside the tiles are
    /// bounded by the snapshot's leaves, that is by its bytes.
    pub max_snapshot_tiles: u64,
    /// Ground-truth leaves [`evaluate`](crate::evaluate) holds while it walks the file once,
    /// bytes (default 256 MiB: about 16 maps of a building floor at 5 cm, 1 M leaves each).
    /// Each walk decodes the whole file, which on a long history costs far more than
    /// comparing one more map; at least as many maps as threads are held whatever this says.
    pub eval_group_bytes: usize,
    /// What a FROctomap file may make its reader allocate ([`Context::open_froct`]).
    pub froct: ReadLimits,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            // Far above any OctoMap scan seen (a building floor at 5 cm is tens of MB).
            max_map_file_bytes: 4 << 30,
            max_exports: 1_000_000,
            max_snapshot_tiles: 1 << 20,
            eval_group_bytes: 256 << 20,
            froct: ReadLimits::default(),
        }
    }
}

/// Registries and limits handed to the converters — and nothing opened: a series collected
/// with one context owns its inputs and may be built with another ([`build`](crate::build),
/// [`export`](crate::export), [`evaluate`](crate::evaluate), [`collect_inputs`](crate::collect_inputs), the map writers).
/// Library code never builds default registries itself.
///
/// ```
/// use froctomap_convert::{Context, Limits};
/// use froctomap_formats::{octomap_native, MapFormat};
///
/// // A program's own format: the native `.bt` codec under another name and extension.
/// let mut context = Context::with_default_plugins();
/// context.formats_mut().register(MapFormat { name: "tree", extensions: &["tree"], ..octomap_native::BINARY })?;
/// // Every registry refuses a name it holds.
/// assert!(context.formats_mut().register(octomap_native::BINARY).is_err());
/// assert!(context.formats().by_name("tree", None).is_ok());
///
/// let mut limits = Limits::default();
/// limits.max_exports = 100;
/// let context = context.with_limits(limits);
/// assert_eq!(context.limits().max_exports, 100);
/// # Ok::<(), froctomap_formats::DuplicateName>(())
/// ```
#[derive(Clone, Debug)]
pub struct Context {
    formats: FormatRegistry,
    models: ModelRegistry,
    limits: Limits,
    recording_options: RecordingOptions,
}

impl Context {
    /// A context of these registries, with default limits.
    pub fn new(formats: FormatRegistry, models: ModelRegistry) -> Self {
        Self {
            formats,
            models,
            limits: Limits::default(),
            recording_options: RecordingOptions::default(),
        }
    }

    /// Every map format and temporal model enabled at compile time, plus the `.froct` series
    /// format ([`FROCT`]), with default limits: what binaries, tests and examples start from.
    pub fn with_default_plugins() -> Self {
        let mut formats = FormatRegistry::with_default_formats();
        // The built-in formats do not use this name (a test registers it twice).
        let _ = formats.register_series(FROCT);
        Self::new(formats, ModelRegistry::with_default_models())
    }

    /// The same context with other limits.
    pub fn with_limits(mut self, limits: Limits) -> Self {
        self.limits = limits;
        self
    }

    /// The map formats.
    pub fn formats(&self) -> &FormatRegistry {
        &self.formats
    }

    /// The map formats, to register more.
    pub fn formats_mut(&mut self) -> &mut FormatRegistry {
        &mut self.formats
    }

    /// The temporal models.
    pub fn models(&self) -> &ModelRegistry {
        &self.models
    }

    /// The temporal models, to register more.
    pub fn models_mut(&mut self) -> &mut ModelRegistry {
        &mut self.models
    }

    /// The model of a file opened with this context (opening checks it is registered).
    pub(crate) fn model_of(
        &self,
        header: &froctomap_file::Header,
    ) -> Result<&ModelDescriptor, ConvertError> {
        self.models
            .by_id(header.model_id)
            .ok_or(ConvertError::internal(
                "the model of an opened file is not registered",
            ))
    }

    /// The resource bounds.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// The same context reading recordings with these options (topic, time).
    pub fn with_recording_options(mut self, options: RecordingOptions) -> Self {
        self.recording_options = options;
        self
    }

    /// How recordings are read.
    pub fn recording_options(&self) -> &RecordingOptions {
        &self.recording_options
    }

    /// Opens a FROctomap file of any version (1.0–1.2 or 2.0, told by its preamble) as
    /// [`open_froct`](Self::open_froct) does: what retrieval, prediction, export and `info`
    /// read. Whole-history analyses take [`FroctFile::whole_history`].
    pub fn open_series(&self, path: &Path) -> Result<FroctFile, ConvertError> {
        crate::files::refuse_special_file(path)?;
        if crate::files::is_living_file(path)? {
            return LivingReader::open_with_limits(path, self.limits.froct, &self.models)
                .map(FroctFile::Living)
                .map_err(ConvertError::File);
        }
        self.open_froct(path).map(FroctFile::Flat)
    }

    /// Opens a FROctomap 1.x file with this context's models (so a model the program
    /// registered decodes its cells) and read limits (2.0 files are refused by their version:
    /// see [`open_series`](Self::open_series)). A map file of a registered format (a `.bt`
    /// snapshot, say) is refused as such rather than as a damaged series file.
    pub fn open_froct(&self, path: &Path) -> Result<FroctReader, ConvertError> {
        crate::files::refuse_special_file(path)?;
        FroctReader::open_with_limits(path, self.limits.froct, &self.models).map_err(|error| {
            match self.formats.identify_file(path) {
                Ok(Some(Identified::Map(format))) => ConvertError::MapNotSeries {
                    path: path.to_path_buf(),
                    format: format.name,
                },
                _ => ConvertError::File(error),
            }
        })
    }
}

/// froctomap's own series file, as the format registry's probe recognises it (by its magic,
/// see `docs/FORMAT.md`).
pub const FROCT: SeriesFormat = SeriesFormat {
    name: "froct",
    description: "FROctomap spatio-temporal series file",
    extensions: &["froct"],
    probe: probe_froct,
};

fn probe_froct(bytes: &[u8]) -> Confidence {
    if bytes.starts_with(&froctomap_file::MAGIC) {
        Confidence::Certain
    } else {
        Confidence::No
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn froct_files_are_identified_by_the_registry_probe() {
        let context = Context::with_default_plugins();
        let mut head = froctomap_file::MAGIC.to_vec();
        head.extend_from_slice(b"rest of a header");
        assert!(matches!(
            context.formats().identify(&head),
            Some(Identified::Series(f)) if f.name == FROCT.name
        ));
        // Without the descriptor the same bytes are nothing known.
        let bare = Context::new(FormatRegistry::with_default_formats(), ModelRegistry::new());
        assert!(bare.formats().identify(&head).is_none());
        assert!(context.formats().identify(&head[..4]).is_none());
        // Registered once only.
        let mut formats = context.formats().clone();
        assert!(formats.register_series(FROCT).is_err());
    }
}
