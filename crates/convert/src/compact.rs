//! `compact`: a FROctomap file's base and segments rewritten as one base, every cell refitted
//! on its whole history, so that the result equals a [`build`](crate::build) of the same maps
//! at the tile depth written (the file's, or deeper: [`CompactOptions::tile_budget`]) apart
//! from metadata.
//!
//! No map is retrieved: each cell's history is read where it is stored (the base's cells on
//! the base axis, each segment's cells on its own axis piece, inherited cells and patch
//! remainders through the base's frozen prediction), the histories are joined tile by tile
//! in time order and brought to the build's cells, then fitted and written by the build's
//! own stages (`build::compacted`). Memory holds one tile of each part (base, segments) and
//! the fit's chunks, whatever the number of maps. The result is written into a temporary
//! directory beside the output, then put in place atomically: converted to format 2.0
//! without segments (the default) by [`LivingWriter::convert`], or renamed as a 1.x file.
//! Compacting a 2.0 file in place holds its writer lock from before the file is read until
//! the new file is in place, so no segment is committed meanwhile and lost.

use crate::build::{merge_into, MergeSettings, DEFAULT_BUILD_MEMORY};
use crate::context::Context;
use crate::error::ConvertError;
use crate::outputs::refuse_overwriting_input;
use crate::progress::Progress;
use crate::series_file::{FroctFile, SeriesRead};
use froctomap_core::Timestamp;
use froctomap_file::{FroctReader, LivingWriter, ToggleLayout};
use froctomap_temporal::{ModelConfig, ModelOptions, OutlierMode};
use serde::Serialize;
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};
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
    /// Creation time stored in the metadata; `None`: now (see
    /// [`IngestOptions::time`](crate::IngestOptions::time)).
    pub created: Option<Timestamp>,
    /// Memory budget of a rebuild from maps. Unused since compaction merges histories
    /// (it holds one tile per part of the file); kept so that callers keep compiling.
    pub memory: u64,
    /// Where a rebuild from maps spilled. Unused since compaction merges histories (the
    /// intermediate file goes beside the output, in a hidden `.froct-compact-*`
    /// directory); kept so that callers keep compiling.
    pub tmp_dir: Option<PathBuf>,
    /// Maps decoded in parallel per batch by a rebuild from maps. Unused since compaction
    /// merges histories; kept so that callers keep compiling.
    pub batch: usize,
    /// Write the models without the outlier set (as `build --lossy`): tiny, and its past is
    /// the models' reconstruction. Only into another file
    /// ([`ConvertError::LossyInPlace`]).
    pub lossy: bool,
    /// Tile depth of the result; `None`: the file's, or one deeper as
    /// [`tile_budget`](Self::tile_budget) decides. Deeper (smaller tiles) only
    /// ([`ConvertError::CoarserTiles`]): compacting and building hold one tile's whole
    /// history, which grows with the history, so a file meant to grow for months is
    /// better kept in smaller tiles. The result equals a build at that depth.
    pub tile_depth: Option<u8>,
    /// When [`tile_depth`](Self::tile_depth) is `None`: the history (bytes of observation
    /// runs, packed) past which the result's tiles go one level deeper (an eighth of the
    /// volume, down to [`AUTOMATIC_TILE_DEPTH_LIMIT`]), so that the compactions of a file
    /// that grows for months hold bounded memory. What is compared is the largest tile's
    /// history of the last build or compaction (in the base's summary) scaled by the maps
    /// added since. A target for the compactions after this one, not a bound on it: this
    /// one still merges the tiles it reads, at their depth. One level per compaction, since
    /// a busy spot does not shrink with the volume and the summary is only advice; the
    /// file grows for it (1.06× at one level deeper, 1.21× at two, on 32 hours of the
    /// generated office). `None`: the file's depth. A file whose summary does not say
    /// (written before this was recorded) keeps its depth once, and says it after.
    pub tile_budget: Option<u64>,
}

/// [`CompactOptions::tile_budget`]'s default: 32 MiB of packed runs, about 12 million
/// observation runs; a compaction holds a few times that at its peak.
pub const DEFAULT_TILE_BUDGET: u64 = 32 << 20;

/// The deepest tiles a [`CompactOptions::tile_budget`] chooses: cubes of 2 voxels an edge,
/// whose history is at most 8 voxels' (a few bytes a map each), under any sensible budget
/// for millions of maps.
pub const AUTOMATIC_TILE_DEPTH_LIMIT: u8 = froctomap_core::TREE_DEPTH - 1;

impl Default for CompactOptions {
    fn default() -> Self {
        Self {
            model_options: ModelOptions::new(),
            format: CompactFormat::default(),
            created: None,
            memory: DEFAULT_BUILD_MEMORY,
            tmp_dir: None,
            batch: 8 * rayon::current_num_threads().max(1),
            lossy: false,
            tile_depth: None,
            tile_budget: Some(DEFAULT_TILE_BUDGET),
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
    /// Tile depth of the input.
    pub tile_depth_before: u8,
    /// Tile depth written: deeper than the input's when asked
    /// ([`CompactOptions::tile_depth`]) or when the largest tile's history passed
    /// [`CompactOptions::tile_budget`].
    pub tile_depth: u8,
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
    /// Maps a recorder committed to the file while it was compacted in the background,
    /// added to the result before it replaced the file ([`Compaction::Background`]); 0
    /// otherwise (and then not in the JSON).
    ///
    /// [`Compaction::Background`]: crate::Compaction::Background
    #[serde(skip_serializing_if = "is_zero")]
    pub maps_added_meanwhile: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// Rewrites `file`'s base and segments as one base: into `output`, or in place (replacing
/// `file` atomically) when `output` is `None`. Every cell's history is merged from the base
/// and the segments, without retrieving any map, and refitted; the result equals a
/// [`build`](crate::build) of the same maps at the tile depth written apart from metadata.
/// Memory holds a tile of each part of the file at a time, and the merged tile's history
/// (which [`CompactOptions::tile_budget`] keeps bounded over a file's compactions). In place, a 2.0 file's writer lock is held from before the
/// file is read until the result replaces it.
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
    match output {
        Some(output) => refuse_overwriting_input(output, [file])?,
        None if options.lossy => {
            return Err(ConvertError::LossyInPlace {
                file: file.to_path_buf(),
            })
        }
        None => {}
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
    let series = context.open_series(file)?;
    compact_series(context, series, file, output, writer, options, progress)
}

/// [`compact`] of `series`, opened from `file` (the state it saw then is what is
/// compacted, whatever is committed meanwhile), into `output`: how a background compaction
/// compacts a file that a recorder keeps appending to.
pub(crate) fn compact_opened(
    context: &Context,
    series: FroctFile,
    file: &Path,
    output: &Path,
    options: &CompactOptions,
    progress: &dyn Progress,
) -> Result<CompactReport, ConvertError> {
    refuse_overwriting_input(output, [file])?;
    compact_series(context, series, file, Some(output), None, options, progress)
}

/// The result's tile depth: the one `options` ask for (the file's, `file_depth`, or deeper),
/// or, with none asked, the file's or deeper as [`CompactOptions::tile_budget`] decides from
/// `base`'s largest tile history, measured over `base_maps` and grown to `maps`.
fn written_tile_depth(
    file: &Path,
    file_depth: u8,
    (base, base_maps, maps): (&FroctReader, usize, usize),
    options: &CompactOptions,
) -> Result<u8, ConvertError> {
    let Some(tile_depth) = options.tile_depth else {
        let largest = base
            .summary()
            .get(crate::build::LARGEST_TILE_HISTORY_KEY)
            .and_then(Value::as_u64);
        return Ok(match (options.tile_budget, largest) {
            (Some(budget), Some(largest)) if base_maps > 0 => {
                let grown = u128::from(largest) * maps as u128 / base_maps as u128;
                deeper_for(grown, budget, file_depth)
            }
            _ => file_depth,
        });
    };
    if (file_depth..=froctomap_core::TREE_DEPTH).contains(&tile_depth) {
        Ok(tile_depth)
    } else {
        Err(ConvertError::CoarserTiles {
            file: file.to_path_buf(),
            tile_depth,
            file_depth,
        })
    }
}

/// `depth`, or the next one when `largest` (the largest tile's history at `depth`) passes
/// `budget`; never past [`AUTOMATIC_TILE_DEPTH_LIMIT`].
fn deeper_for(largest: u128, budget: u64, depth: u8) -> u8 {
    if largest > u128::from(budget) && depth < AUTOMATIC_TILE_DEPTH_LIMIT {
        depth + 1
    } else {
        depth
    }
}

/// The metadata of the compaction of `file` (whose header is `header`, `maps` maps, its
/// version and segments `before`), as a build of the file's maps writes it (its inputs
/// being the file).
fn compacted_metadata(
    file: &Path,
    header: &froctomap_file::Header,
    maps: usize,
    options: &CompactOptions,
    (version_before, segments_before): (&str, usize),
) -> Map<String, Value> {
    let mut metadata = Map::new();
    metadata.insert(
        "creator".into(),
        Value::from(format!("froctomap {}", env!("CARGO_PKG_VERSION"))),
    );
    metadata.insert("created".into(), crate::build::stamp(options.created));
    metadata.insert(
        "source".into(),
        Value::from(crate::build::output_dir(file).display().to_string()),
    );
    // The bytes of the maps read are known for the base's maps only: segments do not
    // record theirs, and a sum of part of them beside the count of all would be a wrong
    // compression ratio.
    let base_sources = header.metadata.get("sources").and_then(Value::as_u64);
    if let Some(bytes) = header.metadata.get("input_bytes") {
        if base_sources == Some(maps as u64) {
            metadata.insert("input_bytes".into(), bytes.clone());
        }
    }
    metadata.insert("sources".into(), Value::from(maps));
    if let Some(tags) = header.metadata.get("tags") {
        metadata.insert("tags".to_string(), tags.clone());
    }
    metadata.insert(
        "compacted_from".to_string(),
        serde_json::json!({ "version": version_before, "segments": segments_before }),
    );
    metadata
}

fn compact_series(
    context: &Context,
    series: FroctFile,
    file: &Path,
    output: Option<&Path>,
    writer: Option<LivingWriter>,
    options: &CompactOptions,
    progress: &dyn Progress,
) -> Result<CompactReport, ConvertError> {
    let started = Instant::now();
    let target = output.unwrap_or(file);
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
    let model = context.model_of(&header)?;
    let outliers = if options.lossy {
        OutlierMode::Lossy
    } else {
        body.model().outlier_mode()
    };
    let mut config = ModelConfig::default().with_outliers(outliers);
    config.options = options.model_options.clone();
    // The maps of the series, and of its base, which measured the largest tile.
    let maps = (0..series.sample_count())
        .filter(|&s| !series.is_missing(s))
        .count();
    let base_maps = (0..body.header().axis.len())
        .filter(|&s| !body.header().axis.is_missing(s))
        .count();
    let tile_depth = written_tile_depth(file, header.tile_depth, (body, base_maps, maps), options)?;
    let metadata = compacted_metadata(
        file,
        &header,
        maps,
        options,
        (&version_before, segments_before),
    );
    let toggles = match options.format {
        CompactFormat::Flat(Some(layout)) => layout,
        _ => header.toggles,
    };
    // Beside the output, so that the result is renamed into place on one file system.
    let temp_parent = crate::build::output_dir(target).to_path_buf();
    let temp = froctomap_core::temporary_dir_in(&temp_parent, std::ffi::OsStr::new(COMPACT_PREFIX))
        .map_err(|source| froctomap_core::AtomicWriteError {
            path: temp_parent.clone(),
            source,
        })?;
    // The writer locks the directory it writes into (shared) while the temporary directory
    // is locked exclusively: it writes into a directory of its own inside.
    let work = temp.path().join("build");
    std::fs::create_dir(&work).map_err(|source| froctomap_core::AtomicWriteError {
        path: work.clone(),
        source,
    })?;
    let built = work.join("compacted.froct");
    let sample_count = series.sample_count();
    let (base, living) = match &series {
        FroctFile::Flat(reader) => (reader, None),
        FroctFile::Living(living) => (living.base(), Some(living)),
    };
    let settings = MergeSettings {
        model: model.create(),
        config: &config,
        tile_depth,
        toggles,
        metadata,
        reproducible: options.created.is_some(),
    };
    let merged = merge_into(base, living, &built, settings, progress)?;
    drop(series);
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
        tile_depth_before: header.tile_depth,
        tile_depth,
        samples: sample_count,
        maps: merged.maps,
        bytes_before,
        bytes,
        toggles: merged.toggles,
        seconds: started.elapsed().as_secs_f64(),
        maps_added_meanwhile: 0,
    })
}

fn version_text((major, minor): (u16, u16)) -> String {
    format!("{major}.{minor}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_passed_takes_the_next_level() {
        let budget = 1000;
        assert_eq!(deeper_for(1000, budget, 10), 10, "at the budget: kept");
        assert_eq!(deeper_for(1001, budget, 10), 11);
        assert_eq!(deeper_for(u128::MAX, budget, 10), 11, "one level at a time");
        let limit = AUTOMATIC_TILE_DEPTH_LIMIT;
        assert_eq!(deeper_for(u128::MAX, budget, limit), limit);
        assert_eq!(deeper_for(u128::MAX, budget, 16), 16, "never shallower");
    }
}
