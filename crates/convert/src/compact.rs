//! `compact`: a FROctomap file's base and segments rewritten as one base, every cell refitted
//! on its whole history through the build's own stages, so that the result equals a
//! [`build`] of the same maps apart from metadata.
//!
//! The file feeds the build as a recording would ([`RecordedMaps`]): each sample with a map
//! is one input whose bytes are the canonical `.bt` of the map observed there (what
//! `retrieve` writes), made when the build's extraction asks for it. So compaction reads no
//! input but the file, holds what a build holds (bounded by [`CompactOptions::memory`]),
//! and needs no path of its own through the pipeline. The result is written into a
//! temporary directory beside the output, then put in place atomically: converted to
//! format 2.0 without segments (the default) by [`LivingWriter::convert`], or renamed as a
//! 1.x file. Compacting a 2.0 file in place holds its writer lock from before the maps are
//! read until the new file is in place, so no segment is committed meanwhile and lost.

use crate::build::{ingest, IngestOptions, IngestTarget, DEFAULT_BUILD_MEMORY};
use crate::context::Context;
use crate::error::ConvertError;
use crate::inputs::SeriesInput;
use crate::maps::observed_bt;
use crate::outputs::refuse_overwriting_input;
use crate::progress::Progress;
use crate::recording::RecordedMap;
use crate::series_file::{FroctFile, SeriesRead};
use froctomap_core::Timestamp;
use froctomap_file::{LivingWriter, ToggleLayout};
use froctomap_formats::{PluginError, RecordedMaps};
use froctomap_temporal::{ModelConfig, ModelOptions};
use serde::Serialize;
use serde_json::Map;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// The prefix of the hidden directory a compaction works in, beside its output.
pub(crate) const COMPACT_PREFIX: &str = ".froct-compact-";

/// The format `compact` writes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum CompactFormat {
    /// Format 2.0 with no segment (its base is the compacted history): `append` and
    /// `record` can add segments to it.
    #[default]
    Living,
    /// A 1.x file with this toggle layout (1.2: [`ToggleLayout::Coded`], 1.1:
    /// [`ToggleLayout::Blocked`], 1.0: [`ToggleLayout::Whole`]), for older readers; `None`:
    /// the layout of the file's base.
    Flat(Option<ToggleLayout>),
}

/// How to compact.
#[derive(Clone, Debug)]
pub struct CompactOptions {
    /// The model's own options for the refit (`key=value`), as for `append`: a file does not
    /// record the options it was built with. The model and lossless/lossy come from the
    /// file.
    pub model_options: ModelOptions,
    /// Output format.
    pub format: CompactFormat,
    /// Creation time stored in the metadata; `None`: now (see [`IngestOptions::time`]).
    pub created: Option<Timestamp>,
    /// Memory budget of the accumulated histories ([`IngestOptions::memory`]).
    pub memory: u64,
    /// Where spill data goes; `None`: beside the output (where the intermediate file always
    /// goes, in a hidden `.froct-compact-*` directory).
    pub tmp_dir: Option<PathBuf>,
    /// Maps decoded in parallel per batch.
    pub batch: usize,
}

impl Default for CompactOptions {
    fn default() -> Self {
        Self {
            model_options: ModelOptions::new(),
            format: CompactFormat::default(),
            created: None,
            memory: DEFAULT_BUILD_MEMORY,
            tmp_dir: None,
            batch: 8 * rayon::current_num_threads().max(1),
        }
    }
}

/// What a compaction did.
#[derive(Clone, Debug, Serialize)]
#[non_exhaustive]
pub struct CompactReport {
    /// The file compacted.
    pub file: PathBuf,
    /// The file written (the same path when compacted in place).
    pub output: PathBuf,
    /// Format version of the input.
    pub version_before: String,
    /// Format version written.
    pub version: String,
    /// Segments the input had.
    pub segments_before: usize,
    /// Samples of the series (missing ones included).
    pub samples: u32,
    /// Maps (samples with a map) refitted.
    pub maps: usize,
    /// Bytes of the input (committed).
    pub bytes_before: u64,
    /// Bytes written.
    pub bytes: u64,
    /// Outlier toggles stored (lossless).
    pub toggles: u64,
    /// Seconds the whole compaction took.
    pub seconds: f64,
}

/// The maps of an open file, as a recording whose map `i` is the `i`-th sample with a map,
/// as the canonical `.bt` observed there.
struct FileMaps {
    file: FroctFile,
    samples: Vec<u32>,
    topic: String,
}

impl std::fmt::Debug for FileMaps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FileMaps")
            .field("file", &self.file.path())
            .field("maps", &self.samples.len())
            .finish()
    }
}

impl RecordedMaps for FileMaps {
    fn map_bytes(&self, index: usize, _limit: u64) -> Result<Vec<u8>, PluginError> {
        // The map is made from the file's cells, whose size the reader bounded at open.
        let sample = *self.samples.get(index).ok_or_else(|| {
            PluginError::from(format!(
                "{}: no map {index} among its {} maps",
                self.file.path().display(),
                self.samples.len()
            ))
        })?;
        observed_bt(&self.file, sample).map_err(PluginError::from)
    }

    fn topic(&self) -> &str {
        &self.topic
    }
}

/// Rewrites `file`'s base and segments as one base: into `output`, or in place (replacing
/// `file` atomically) when `output` is `None`. Every cell is refitted on its whole history
/// by [`build`], which reads the file as a recording of its maps (each sample's canonical
/// `.bt`), in the build's bounded memory; the result equals a build of the same maps apart
/// from metadata. In place, a 2.0 file's writer lock is held from before its maps are read
/// until the result replaces it.
///
/// ```no_run
/// use froctomap_convert::*;
/// use std::path::Path;
///
/// let context = Context::with_default_plugins();
/// let report = compact(&context, Path::new("office.froct"), None, &CompactOptions::default(), &Silent)?;
/// println!("{} segments → 1 base, {} → {} bytes", report.segments_before, report.bytes_before, report.bytes);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn compact(
    context: &Context,
    file: &Path,
    output: Option<&Path>,
    options: &CompactOptions,
    progress: &dyn Progress,
) -> Result<CompactReport, ConvertError> {
    if let Some(output) = output {
        refuse_overwriting_input(output, [file])?;
    }
    // In place, the writer lock of a 2.0 file is taken before its state is read and held
    // until the new file replaces it.
    let writer = match (output, crate::files::is_living_file(file)?) {
        (None, true) => Some(LivingWriter::open_with_limits(
            file,
            context.limits().froct,
            context.models(),
        )?),
        _ => None,
    };
    compact_with(context, file, output, writer, options, progress)
}

/// [`compact`] of the 2.0 file whose writer the caller holds, in place (how `record`
/// compacts between commits): the lock is held until the result replaces the file, then
/// released with `writer`, which the caller opens again.
pub(crate) fn compact_held(
    context: &Context,
    writer: LivingWriter,
    options: &CompactOptions,
    progress: &dyn Progress,
) -> Result<CompactReport, ConvertError> {
    let file = writer.reader().path().to_path_buf();
    compact_with(context, &file, None, Some(writer), options, progress)
}

/// [`compact`] with the writer lock of an in-place 2.0 compaction taken (`writer`).
fn compact_with(
    context: &Context,
    file: &Path,
    output: Option<&Path>,
    writer: Option<LivingWriter>,
    options: &CompactOptions,
    progress: &dyn Progress,
) -> Result<CompactReport, ConvertError> {
    let started = Instant::now();
    let target = output.unwrap_or(file);
    let series = context.open_series(file)?;
    let version_before = version_text(series.version());
    let segments_before = series.segment_count();
    let bytes_before = match &series {
        FroctFile::Flat(reader) => reader.file_len(),
        FroctFile::Living(living) => living.root().committed_len,
    };
    let header = series.header().clone();
    let body = match &series {
        FroctFile::Flat(reader) => reader,
        FroctFile::Living(living) => living.base(),
    };
    let model = context
        .models()
        .by_id(header.model_id)
        .ok_or(ConvertError::internal(
            "the model of an opened file is not registered",
        ))?;
    let mut config = ModelConfig::default().with_outliers(body.model().outlier_mode());
    config.options = options.model_options.clone();
    let mut metadata = Map::new();
    if let Some(tags) = header.metadata.get("tags") {
        metadata.insert("tags".to_string(), tags.clone());
    }
    metadata.insert(
        "compacted_from".to_string(),
        serde_json::json!({ "version": version_before, "segments": segments_before }),
    );
    let toggles = match options.format {
        CompactFormat::Flat(Some(layout)) => layout,
        _ => header.toggles,
    };
    let build_options = IngestOptions {
        model: model.name.to_string(),
        config,
        tile_depth: header.tile_depth,
        codec: header.codec,
        toggles,
        resolution: Some(header.resolution),
        metadata,
        batch: options.batch,
        time: options.created,
        memory: options.memory,
        tmp_dir: options.tmp_dir.clone(),
        ..IngestOptions::default()
    };

    let samples: Vec<u32> = (0..series.sample_count())
        .filter(|&s| !series.is_missing(s))
        .collect();
    let times: Vec<Timestamp> = samples
        .iter()
        .map(|&s| {
            series
                .sample_time(s)
                .ok_or(ConvertError::internal("a sample without a time"))
        })
        .collect::<Result<_, _>>()?;
    let sample_count = series.sample_count();
    let maps: Arc<dyn RecordedMaps> = Arc::new(FileMaps {
        file: series,
        samples,
        topic: "compact".to_string(),
    });
    let inputs: Vec<SeriesInput> = times
        .iter()
        .enumerate()
        .map(|(i, &time)| {
            SeriesInput::recorded_map(
                file.to_path_buf(),
                time,
                RecordedMap::new(Arc::clone(&maps), i),
            )
        })
        .collect();

    // Beside the output, so that the result is renamed into place on one file system (spill
    // data goes to `tmp_dir` when given).
    let temp_parent = crate::build::output_dir(target).to_path_buf();
    let temp = froctomap_core::temporary_dir_in(&temp_parent, std::ffi::OsStr::new(COMPACT_PREFIX))
        .map_err(|source| froctomap_core::AtomicWriteError {
            path: temp_parent.clone(),
            source,
        })?;
    // The build locks the directory it writes into (shared) while the temporary directory is
    // locked exclusively: it writes into a directory of its own inside.
    let work = temp.path().join("build");
    std::fs::create_dir(&work).map_err(|source| froctomap_core::AtomicWriteError {
        path: work.clone(),
        source,
    })?;
    let built = work.join("compacted.froct");
    let report = ingest(
        context,
        &inputs,
        IngestTarget::NewFile(&built),
        &build_options,
        progress,
    )?;
    drop(inputs);
    drop(maps);
    progress.stage("writing the compacted file", 1);
    let version = match options.format {
        CompactFormat::Living => {
            match writer {
                Some(writer) => writer.replace_with_base(&built)?,
                None => LivingWriter::convert(&built, target)?,
            };
            version_text((
                froctomap_file::LIVING_MAJOR_VERSION,
                froctomap_file::LIVING_MINOR_VERSION,
            ))
        }
        CompactFormat::Flat(_) => {
            // The lock (if any) is held until the rename has replaced the file.
            std::fs::rename(&built, target).map_err(|source| froctomap_core::AtomicWriteError {
                path: target.to_path_buf(),
                source,
            })?;
            crate::files::sync_parent(target);
            drop(writer);
            version_text(froctomap_file::FroctReader::open(target)?.header().version)
        }
    };
    progress.advance(1);
    let bytes = std::fs::metadata(target).map_or(0, |m| m.len());
    Ok(CompactReport {
        file: file.to_path_buf(),
        output: target.to_path_buf(),
        version_before,
        version,
        segments_before,
        samples: sample_count,
        maps: report.used,
        bytes_before,
        bytes,
        toggles: report.toggles,
        seconds: started.elapsed().as_secs_f64(),
    })
}

fn version_text((major, minor): (u16, u16)) -> String {
    format!("{major}.{minor}")
}
