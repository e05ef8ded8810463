//! `build`: a series of maps → one FROctomap file, streaming, as a pipeline of stages, each
//! a type in a module of its own with its own tests:
//!
//! 1. [`check`] — `InputCheck`: every header, in parallel; unreadable files and mixed
//!    resolutions stop the build (or are skipped) before anything is decoded.
//!    → `CheckedInputs` (which inputs go on, the series' resolution).
//! 2. [`extract`] — `ChangeExtractor`: an iterator of `ChangeBatch`es, the accepted
//!    snapshots of each batch of files as `SampleChanges { sample, changes }` (where each
//!    differs from the one before), read and compared in parallel; then `Extracted`, the
//!    tally (used, skipped, warnings, resolution).
//! 3. [`accumulate`] — `Accumulator`: the batches applied in time order to the cells'
//!    histories, on threads split by space; → `Accumulated`, whose `into_cells` streams the
//!    cells with their observations in Morton order, tile after tile.
//!    Within a memory budget ([`IngestOptions::memory`]), what grows with the series is
//!    spilled to files in a temporary directory ([`spill`]) and read back tile by tile.
//! 4. [`fit`] — `TileFitter`: a `TileHistory` → a `FittedTile` (cells as stored, counts by
//!    class); `fit_and_write` drives stages 4 and 5 over the cell stream in parallel steps
//!    of bounded chunks of cells (both cores within one tile; memory bounded per step).
//! 5. [`write`](mod@write) — `TileEncoder` (fitted cells pushed into their tile's streams as
//!    their chunk is fitted, complete tiles compressed in parallel) and `TileWriter` (the
//!    tiles in order into the file, atomically, summing the counts).
//!
//! [`ingest`](mod@ingest) wires them for every target (plan → intake, stages 1–3, shared →
//! write): the stages pass values, never reach into each other, and report typed errors
//! ([`ConvertError`], [`SnapshotError`]). A new file ([`build()`]) is written by stages 4
//! and 5; an existing file is rewritten ([`append()`](append::append)) with [`merge`]
//! joining its cells to the new ones before them, or given a [`segment`].

mod accumulate;
mod append;
mod axis;
mod check;
mod compacted;
mod counts;
mod extract;
mod fit;
mod ingest;
mod merge;
mod segment;
mod spill;
#[cfg(test)]
mod test_support;
mod write;

use crate::context::Context;
use crate::error::ConvertError;
pub use crate::files::{is_living_file, output_dir};
use crate::inputs::SeriesInput;
use crate::outputs::refuse_overwriting_input;
use crate::progress::Progress;
pub use append::{AppendOptions, AppendReport};
pub use axis::axis_for_times;
pub(crate) use compacted::{merge_into, MergeSettings};
pub use counts::ClassCounts;
pub(crate) use counts::LARGEST_TILE_HISTORY_KEY;
use fit::{fit_and_write, TileFitter};
use froctomap_core::Timestamp;
use froctomap_file::{Header, LivingWriter, WrittenFile};
use froctomap_temporal::OutlierMode;
pub(crate) use ingest::stamp;
pub use ingest::{
    Extended, IngestInputs, IngestOptions, IngestReport, IngestTarget, DEFAULT_BUILD_MEMORY,
};
use ingest::{Intake, Run};
pub use segment::refuse_growing_fixed_span;
use serde_json::{json, Map, Value};
use std::path::Path;
use std::time::Instant;
use write::{TileEncoder, TileWriter};

/// How to build: the options of [`ingest`], kept under their old name.
pub type BuildOptions = IngestOptions;

/// What a build did: the report of [`ingest`], kept under its old name.
pub type BuildReport = IngestReport;

/// Builds a FROctomap file from snapshots (sorted by time, distinct times): [`ingest`]
/// into [`IngestTarget::NewFile`].
///
/// Reads the inputs in batches, turns each into its changes from the one before (from the
/// bytes where the format allows, see `FormatRegistry::diff_bytes`; else by decoding) and
/// accumulates the changes in time order (memory grows with the cells and their changes,
/// not with the number of snapshots), then fits a model per dynamic cell and writes the file
/// tile by tile, atomically. Input formats and the model are looked up in `context`.
///
/// Inputs are map files with their times ([`collect_inputs`](crate::collect_inputs));
/// recorded maps (ROS bags, MCAP) are entries of that series like files.
pub fn build(
    context: &Context,
    inputs: &[SeriesInput],
    output: &Path,
    options: &BuildOptions,
    progress: &dyn Progress,
) -> Result<BuildReport, ConvertError> {
    ingest(
        context,
        inputs,
        IngestTarget::NewFile(output),
        options,
        progress,
    )
}

/// Adds a time-sorted series of maps to `target`: builds a new file, rewrites an existing
/// one with every cell refitted, or adds the maps to a format 2.0 file as one segment.
///
/// The stages are the same for every target (plan → input check → change extraction →
/// accumulation → write, see the module `build`); what is written is atomic: on any error
/// a new file does not appear, an existing one is left as it was. The report's `skipped`
/// lists the parts of recordings left out while collecting (`inputs.left_out`), then the
/// inputs left out with `skip_bad`. Maps added to an existing file
/// must all be later than its last sample and of its resolution
/// ([`ConvertError::AppendOverlap`], [`ConvertError::MixedResolution`] naming the file).
///
/// ```no_run
/// use froctomap_convert::*;
/// use std::path::{Path, PathBuf};
/// let context = Context::with_default_plugins();
/// let options = IngestOptions::default();
/// let monday = collect_inputs_explained(&context, &[PathBuf::from("maps/monday/")], TimeSource::Auto, &Zone::utc())?;
/// let built = ingest(&context, &monday, IngestTarget::NewFile(Path::new("office.froct")), &options, &Silent)?;
/// let tuesday = collect_inputs(&context, &[PathBuf::from("maps/tuesday/")], TimeSource::Auto)?;
/// let added = ingest(&context, &tuesday, IngestTarget::Segment(Path::new("office.froct")), &options, &Silent)?;
/// println!("{} + {} snapshots, {} bytes", built.used, added.used, added.file_bytes);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn ingest<'a>(
    context: &Context,
    inputs: impl Into<IngestInputs<'a>>,
    target: IngestTarget<'_>,
    options: &IngestOptions,
    progress: &dyn Progress,
) -> Result<IngestReport, ConvertError> {
    let started = Instant::now();
    let inputs = inputs.into();
    let maps = inputs.maps;
    let file = match &target {
        IngestTarget::NewFile(path) | IngestTarget::Rewrite(path) | IngestTarget::Segment(path) => {
            path.to_path_buf()
        }
        IngestTarget::Writer(writer) => writer.reader().path().to_path_buf(),
    };
    refuse_overwriting_input(&file, maps.iter().map(|i| i.path.as_path()))?;
    let run = Run {
        context,
        inputs: maps,
        options,
        progress,
        started,
    };
    let mut report = match target {
        IngestTarget::NewFile(path) => new_file(&run, path)?,
        IngestTarget::Rewrite(path) => append::rewrite(&run, path)?,
        IngestTarget::Segment(path) => segment::into_living(&run, path)?,
        IngestTarget::Writer(writer) => segment::add_segment(&run, writer)?,
    };
    // Left out before the pipeline saw their maps: listed first.
    report.skipped.splice(0..0, inputs.left_out.iter().cloned());
    Ok(report)
}

/// Appends snapshots later than the last sample of the FROctomap file `file` to it.
///
/// Inputs are a time-sorted series as for [`build`](crate::build()) (from
/// [`collect_inputs`](crate::collect_inputs)), all later than the file's last sample and of
/// its resolution; otherwise the append is refused ([`ConvertError::AppendOverlap`],
/// [`ConvertError::MixedResolution`] naming the file) before anything is written. The work
/// reads the file and the new snapshots only: the snapshots the file was built from are
/// not needed. Every earlier and every new observed state is kept (exactly, in a lossless
/// file; a lossy file's past is its reconstruction), and every cell's model is refitted on
/// the whole history, so the file is what a build of all the snapshots would give, up to its
/// metadata. The file is replaced atomically: on any error it is left as it was.
///
/// ```no_run
/// use froctomap_convert::*;
/// use std::path::{Path, PathBuf};
/// let context = Context::with_default_plugins();
/// let tonight = collect_inputs(&context, &[PathBuf::from("maps/today/")], TimeSource::Auto)?;
/// let report = append(&context, Path::new("office.froct"), &tonight, &AppendOptions::default(), &Silent)?;
/// println!("{} snapshots added, {} → {} bytes", report.added, report.bytes_before, report.file_bytes);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn append(
    context: &Context,
    file: &Path,
    inputs: &[SeriesInput],
    options: &AppendOptions,
    progress: &dyn Progress,
) -> Result<AppendReport, ConvertError> {
    ingest(
        context,
        inputs,
        IngestTarget::Rewrite(file),
        options,
        progress,
    )
    .map(AppendReport::from)
}

/// Appends later maps to the format 2.0 file `writer` holds as one segment, committed once.
///
/// Inputs are a time-sorted series as for [`append`](crate::append()), all later than the
/// file's last sample and of its resolution; otherwise nothing is written
/// ([`ConvertError::AppendOverlap`], [`ConvertError::MixedResolution`]). Only the new maps
/// and the base tiles they touch are read: neither the earlier segments nor the base's
/// masks and toggles, so the cost follows the new maps. Every earlier and every new
/// observed state is kept exactly; the base's models stay frozen (no refit: compaction
/// refits). Files of `fremen-regular` are refused ([`ConvertError::ModelCannotGrow`]).
///
/// ```no_run
/// use froctomap_convert::*;
/// use froctomap_file::LivingWriter;
/// use std::path::{Path, PathBuf};
/// let context = Context::with_default_plugins();
/// let mut writer = LivingWriter::open(Path::new("office.froct"))?;
/// let tonight = collect_inputs(&context, &[PathBuf::from("maps/today/")], TimeSource::Auto)?;
/// let report = append_segment(&context, &mut writer, &tonight, &AppendOptions::default(), &Silent)?;
/// println!("{} maps added as segment {:?}", report.added, report.segments);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn append_segment(
    context: &Context,
    writer: &mut LivingWriter,
    inputs: &[SeriesInput],
    options: &AppendOptions,
    progress: &dyn Progress,
) -> Result<AppendReport, ConvertError> {
    ingest(
        context,
        inputs,
        IngestTarget::Writer(writer),
        options,
        progress,
    )
    .map(AppendReport::from)
}

/// Appends later maps to the file at `path` as one segment of format 2.0: a 2.0 file gets a
/// segment ([`append_segment`], under its writer's lock); a 1.x file is first converted
/// (its tiles copied, [`LivingWriter::convert`]) into a file beside it, the segment appended
/// there, and that file renamed over `path` only once committed, so a failed append leaves
/// the 1.x file as it was. Returns the report and whether the file was converted.
pub fn append_living(
    context: &Context,
    path: &Path,
    inputs: &[SeriesInput],
    options: &AppendOptions,
    progress: &dyn Progress,
) -> Result<(AppendReport, bool), ConvertError> {
    let report = ingest(
        context,
        inputs,
        IngestTarget::Segment(path),
        options,
        progress,
    )?;
    let converted = report.extended.as_ref().is_some_and(|e| e.converted);
    Ok((AppendReport::from(report), converted))
}

/// A new file: the plan (the model, and the axis of the inputs' times, refused before
/// anything is read when they do not go together), the intake, then every cell fitted
/// and written.
fn new_file(run: &Run<'_>, output: &Path) -> Result<IngestReport, ConvertError> {
    let Run {
        context,
        inputs,
        options,
        progress,
        ..
    } = *run;
    let models = context.models();
    let model = models
        .by_name(&options.model)
        .ok_or_else(|| ConvertError::UnknownModel {
            name: options.model.clone(),
            known: models.names(),
        })?
        .create();
    let times: Vec<Timestamp> = inputs.iter().map(|i| i.time).collect();
    let axis = axis_for_times(&times)?;
    // Fail on a bad model/axis combination before reading anything.
    let prepared = model.prepare(&axis, &options.config)?;
    if let Some(r) = options.resolution {
        froctomap_core::validate_resolution(r).map_err(|source| ConvertError::BadResolution {
            resolution: r,
            source,
        })?;
    }

    let intaken = Intake {
        axis,
        tile_depth: options.tile_depth,
        file: None,
        seed: None,
        spill_dir: output_dir(output),
    }
    .run(run)?;
    let axis = &intaken.axis;
    let prepared = if intaken.regridded {
        model.prepare(axis, &options.config)?
    } else {
        prepared
    };

    let modelling = Instant::now();
    let mut header = Header::new(
        intaken.resolution,
        options.tile_depth,
        axis.clone(),
        model.id(),
        prepared.encode_parameters(),
        options.codec,
    );
    header.toggles = options.toggles;
    header.metadata = metadata(inputs, intaken.used, intaken.input_bytes, options);
    let mut writer = TileWriter::create(output, &header)?;
    let accumulated = intaken.accumulated;
    progress.stage("modelling cells", accumulated.cell_count() as u64);
    let accumulate_seconds = accumulated.busy_seconds();
    let (spilled_bytes, spills) = (accumulated.spilled_bytes(), accumulated.spills());
    let tile_depth = accumulated.tile_depth();
    let cells = accumulated.into_cells(axis.len(), &intaken.absent);
    let fitter = TileFitter::new(axis, prepared.as_ref());
    let encoder = TileEncoder::new(header.tile_layout(), prepared.as_ref());
    fit_and_write(cells, tile_depth, &fitter, &encoder, &mut writer, progress)?;
    let model_seconds = modelling.elapsed().as_secs_f64();
    let stats = writer.stats().clone();
    let mut summary = stats.summary(options.config.outliers == OutlierMode::Lossless);
    let mut put = |key: &str, value: Value| summary.insert(key.to_string(), value);
    put("snapshots_used", json!(intaken.used));
    put("snapshots_skipped", json!(intaken.skipped.len()));
    put("input_bytes", json!(intaken.input_bytes));
    put("changed_voxels", json!(intaken.changed_voxels));
    put("read_seconds", json!(intaken.read_seconds));
    put("model_seconds", json!(model_seconds));
    if options.time.is_some() {
        // A reproducible file: no wall-clock measurement in it (the report keeps them).
        summary.remove("read_seconds");
        summary.remove("model_seconds");
    }
    let written: WrittenFile = writer.finish(summary)?;
    Ok(IngestReport {
        output: output.to_path_buf(),
        inputs: inputs.len(),
        used: intaken.used,
        skipped: intaken.skipped,
        warnings: intaken.warnings,
        input_bytes: intaken.input_bytes,
        samples: axis.len(),
        regular_axis: axis.step_ns().is_some(),
        cells: stats.cells,
        voxels: stats.voxels,
        toggles: stats.toggles,
        model_errors: stats.model_errors,
        changed_voxels: intaken.changed_voxels,
        file_bytes: written.file_bytes,
        header_bytes: written.header_bytes,
        index_bytes: written.index_bytes,
        tile_bytes: written.tile_bytes,
        read_seconds: intaken.read_seconds,
        accumulate_seconds,
        model_seconds,
        spilled_bytes,
        spills,
        extended: None,
    })
}

/// A new file's metadata.
fn metadata(
    inputs: &[SeriesInput],
    used: usize,
    input_bytes: u64,
    options: &IngestOptions,
) -> Map<String, Value> {
    let mut meta = Map::new();
    meta.insert(
        "creator".into(),
        Value::from(format!("froctomap {}", env!("CARGO_PKG_VERSION"))),
    );
    meta.insert("created".into(), ingest::stamp(options.time));
    if let Some(dir) = inputs.first().and_then(|i| i.path.parent()) {
        meta.insert("source".into(), Value::from(dir.display().to_string()));
    }
    meta.insert("sources".into(), Value::from(used));
    meta.insert("input_bytes".into(), Value::from(input_bytes));
    for (k, v) in &options.metadata {
        meta.insert(k.clone(), v.clone());
    }
    meta
}

#[cfg(test)]
mod tests {
    use super::axis::samples_left_out;
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn samples_left_out_join_the_axis_gaps_once_each() {
        let s = |v: i64| Timestamp::from_secs(v);
        let times = [s(0), s(10), s(20), s(40), s(50)];
        let axis = axis_for_times(&times).unwrap();
        assert_eq!(axis.missing(), &[3]);
        let inputs: Vec<SeriesInput> = times
            .iter()
            .map(|&time| SeriesInput::new(PathBuf::from("map.bt"), time))
            .collect();
        let usable = [true, false, true, true, true];
        // Sample 5 was refused by extraction, sample 1 by the check (and reported twice).
        assert_eq!(
            samples_left_out(&axis, &inputs, &usable, &[5, 1]),
            [1, 3, 5]
        );
    }

    #[test]
    fn regular_axes_are_recognised_with_gaps() {
        let s = |v: i64| Timestamp::from_secs(v);
        let axis = axis_for_times(&[s(0), s(600), s(1800), s(2400)]).unwrap();
        assert_eq!(axis.step_ns(), Some(600_000_000_000));
        assert_eq!(axis.len(), 5);
        assert_eq!(axis.missing(), &[2]);
        // Jittered times are explicit.
        let axis = axis_for_times(&[s(0), s(601), s(1199), s(1800)]).unwrap();
        assert_eq!(axis.step_ns(), None);
        assert_eq!(axis.len(), 4);
        // One long outage would need too many missing samples: explicit.
        let axis = axis_for_times(&[s(0), s(600), s(6_000_000)]).unwrap();
        assert_eq!(axis.step_ns(), None);
        assert_eq!(axis_for_times(&[s(5)]).unwrap().len(), 1);
    }
}
