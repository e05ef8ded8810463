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
use crate::progress::Progress;
use accumulate::{Accumulated, Accumulator};
pub use append::{append, AppendOptions, AppendReport};
pub(crate) use compacted::{merge_into, MergeSettings};
pub use counts::ClassCounts;
use extract::ChangeExtractor;
use fit::{fit_and_write, TileFitter};
use froctomap_core::Timestamp;
use froctomap_file::{Header, WrittenFile};
use froctomap_temporal::{OutlierMode, TimeAxis};
pub(crate) use ingest::stamp;
pub use ingest::{ingest, Extended, IngestInputs, IngestOptions, IngestReport, IngestTarget};
use ingest::{Intake, Run};
pub use segment::{append_living, append_segment, refuse_growing_fixed_span};
use serde_json::{json, Map, Value};
use spill::SpillPlace;
use std::path::Path;
use std::time::Instant;
use write::{TileEncoder, TileWriter};

/// How to build: the options of [`ingest`], kept under their old name.
pub type BuildOptions = IngestOptions;

/// The default [`IngestOptions::memory`]: 64 MiB. Small enough that peak memory stops growing
/// with the series within hours of 5 s snapshots (on the benchmark's map a quarter of a day's
/// histories take about 80 MiB), at the price of writing the histories to disk once; series
/// whose histories fit in it never spill.
pub const DEFAULT_BUILD_MEMORY: u64 = 64 << 20;

/// What a build did: the report of [`ingest`], kept under its old name.
pub type BuildReport = IngestReport;

/// The time axis of sorted, distinct instants: a regular grid (with missing samples) when
/// the instants lie on one with at most as many gaps as snapshots, else an explicit list.
pub fn axis_for_times(times: &[Timestamp]) -> Result<TimeAxis, ConvertError> {
    let first = *times.first().ok_or(ConvertError::NoInputs)?;
    let invalid = ConvertError::TimeAxis;
    if times.len() == 1 {
        return TimeAxis::regular(first, 1_000_000_000, 1, Vec::new()).map_err(invalid);
    }
    let gcd = times.windows(2).fold(0i64, |g, w| gcd(g, w[1].0 - w[0].0));
    let span = times[times.len() - 1].0 - first.0;
    let count = span / gcd.max(1) + 1;
    if gcd > 0 && count <= 2 * times.len() as i64 && count <= i64::from(u32::MAX) {
        let present: Vec<i64> = times.iter().map(|t| (t.0 - first.0) / gcd).collect();
        let mut missing = Vec::new();
        let mut next = 0usize;
        for i in 0..count {
            if present.get(next) == Some(&i) {
                next += 1;
            } else {
                missing.push(i as u32);
            }
        }
        return TimeAxis::regular(first, gcd, count as u32, missing).map_err(invalid);
    }
    TimeAxis::explicit(times.to_vec()).map_err(invalid)
}

fn gcd(a: i64, b: i64) -> i64 {
    if b == 0 {
        a.abs()
    } else {
        gcd(b, a % b)
    }
}

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
        .ok_or_else(|| {
            let known: Vec<&str> = models.iter().map(|d| d.name).collect();
            ConvertError::UnknownModel {
                name: options.model.clone(),
                known: known.join(", "),
            }
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
    let summary = json!({
        "cell_classes": stats.cells,
        "voxel_classes": stats.voxels,
        "toggles": stats.toggles,
        "model_errors": stats.model_errors,
        "outliers": if options.config.outliers == OutlierMode::Lossless { "lossless" } else { "lossy" },
        "snapshots_used": intaken.used,
        "snapshots_skipped": intaken.skipped.len(),
        "input_bytes": intaken.input_bytes,
        "changed_voxels": intaken.changed_voxels,
        "read_seconds": intaken.read_seconds,
        "model_seconds": model_seconds,
    });
    let Value::Object(mut summary) = summary else {
        unreachable!("json! of an object literal")
    };
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

/// Runs extraction and accumulation side by side: changes are extracted in parallel batches
/// while the accumulating threads apply the previous batch's.
fn accumulate_series(
    extractor: &mut ChangeExtractor<'_>,
    tile_depth: u8,
    (spill_place, memory): (&SpillPlace, u64),
    progress: &dyn Progress,
) -> Result<Accumulated, ConvertError> {
    let budget = usize::try_from(memory).unwrap_or(usize::MAX);
    let parts = rayon::current_num_threads().clamp(1, 8);
    std::thread::scope(|scope| {
        let mut accumulator =
            Accumulator::new(scope, tile_depth, parts, progress).spill_into(spill_place, budget);
        let produced = (|| -> Result<(), ConvertError> {
            for batch in extractor.by_ref() {
                crate::progress::stop_if_cancelled(progress)?;
                if !accumulator.push(batch?) {
                    // An accumulating thread stopped on an error, which `finish` reports.
                    break;
                }
            }
            Ok(())
        })();
        let accumulated = accumulator.finish()?;
        produced?;
        Ok(accumulated)
    })
}

/// A regular axis with the samples in `absent` (sorted, including its own gaps) missing,
/// when some snapshots were left out; `None` when nothing changes (an explicit axis keeps
/// the instants, with nothing observed at them).
fn with_absent_missing(axis: &TimeAxis, absent: &[u32]) -> Result<Option<TimeAxis>, ConvertError> {
    match axis.step_ns() {
        Some(step) if absent.len() > axis.missing().len() => {
            TimeAxis::regular(axis.start(), step, axis.len(), absent.to_vec())
                .map(Some)
                .map_err(ConvertError::TimeAxis)
        }
        _ => Ok(None),
    }
}

/// The samples without a snapshot (sorted): the axis' own gaps and the inputs left out by
/// the check (`usable`) or by extraction (`refused`).
fn samples_left_out(
    axis: &TimeAxis,
    inputs: &[SeriesInput],
    usable: &[bool],
    refused: &[u32],
) -> Vec<u32> {
    let mut absent: Vec<u32> = axis.missing().to_vec();
    absent.extend_from_slice(refused);
    absent.extend(
        inputs
            .iter()
            .zip(usable)
            .filter(|(_, &usable)| !usable)
            .filter_map(|(input, _)| axis.index_of(input.time)),
    );
    absent.sort_unstable();
    absent.dedup();
    absent
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
