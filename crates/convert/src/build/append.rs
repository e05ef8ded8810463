//! `append`: later snapshots added to an existing FROctomap file, at a cost that grows with
//! the file and the new snapshots, never with the snapshots the file was built from (they
//! may be gone).
//!
//! The ingest of [`IngestTarget::Rewrite`]: the build's stages, wired around the file:
//!
//! 1. The file's header gives the resolution, tile depth, model, codec and toggle layout;
//!    the new time axis is the old one extended by the new times ([`extended_axis`]).
//! 2. The inputs are checked and extracted as in a build, the first one compared with the
//!    file's last observed map, which also starts the accumulation (at the file's last
//!    observed sample) so that the new histories continue the old ones.
//! 3. The file's cells are decoded tile by tile into their observed runs on the new axis
//!    ([`OldTiles`]) and merged with the accumulated tiles ([`merge`](super::merge)).
//! 4. Every cell is fitted again on the whole history and the file is written beside the
//!    old one and renamed over it: an append that fails leaves the old file as it was.
//!
//! A lossy file knows its past only as the model's reconstruction: that reconstruction is
//! taken as what was observed, and the result is lossy too.

use super::accumulate::{pack, ObservedCell, TileHistory};
use super::axis::axis_for_times;
use super::counts::ClassCounts;
use super::counts::TileStats;
use super::extract::SampleChanges;
use super::fit::{cells_of_tiles, fit_and_write, TileFitter};
use super::ingest::{as_iso8601, stamp, Extended, IngestOptions, IngestReport, Intake, Run};
use super::merge::merge_tiles;
use super::write::{TileEncoder, TileWriter};
use crate::error::ConvertError;
use crate::files::output_dir;
use crate::history::PackedCell;
use crate::inputs::SeriesInput;
use crate::maps::observed_map;
use crate::skip::SkippedInput;
use crate::snapshot_changes::Accepted;
use froctomap_core::{Occupancy, Timestamp};
use froctomap_file::{Cell, CellContent, FroctReader, Header};
use froctomap_temporal::{ModelConfig, OutlierMode, PreparedModel, TimeAxis};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How to append: the options of [`ingest`](crate::ingest), kept under their old name
/// (`model_options` is now `config.options`, `appended` is `time`).
pub type AppendOptions = IngestOptions;

/// What an append did, as `froctomap append --json` prints it: the
/// [`IngestReport`] of an ingest into an existing file, under the names appends had.
#[derive(Clone, Debug, Serialize)]
pub struct AppendReport {
    /// The file appended to.
    pub file: PathBuf,
    /// Snapshots given.
    pub inputs: usize,
    /// Snapshots added.
    pub added: usize,
    /// Files left out with `skip_bad`, and why.
    pub skipped: Vec<SkippedInput>,
    /// Reader warnings (file, message).
    pub warnings: Vec<(PathBuf, String)>,
    /// Total bytes of the input files added.
    pub input_bytes: u64,
    /// Samples of the time axis before the append.
    pub samples_before: u32,
    /// Samples of the time axis now.
    pub samples: u32,
    /// `true` for a regular axis.
    pub regular_axis: bool,
    /// First instant of the file.
    #[serde(serialize_with = "as_iso8601")]
    pub start: Timestamp,
    /// Last instant before the append.
    #[serde(serialize_with = "as_iso8601")]
    pub end_before: Timestamp,
    /// Last instant now.
    #[serde(serialize_with = "as_iso8601")]
    pub end: Timestamp,
    /// Cells by class.
    pub cells: ClassCounts,
    /// Voxels by class.
    pub voxels: ClassCounts,
    /// Outlier toggles stored (lossless).
    pub toggles: u64,
    /// Observed cell-samples the model gets wrong without outliers.
    pub model_errors: u64,
    /// `true` when the file keeps every observed state exactly.
    pub lossless: bool,
    /// Bytes of the file before the append.
    pub bytes_before: u64,
    /// Bytes of the file now.
    pub file_bytes: u64,
    /// Seconds spent reading and accumulating the new snapshots.
    pub read_seconds: f64,
    /// Seconds spent merging, fitting, encoding and writing.
    pub model_seconds: f64,
    /// Segments of a format 2.0 file after the append (`None`: a 1.x file, rewritten).
    pub segments: Option<usize>,
}

impl From<IngestReport> for AppendReport {
    fn from(report: IngestReport) -> Self {
        let before = report.extended.unwrap_or_default();
        Self {
            file: report.output,
            inputs: report.inputs,
            added: report.used,
            skipped: report.skipped,
            warnings: report.warnings,
            input_bytes: report.input_bytes,
            samples_before: before.samples_before,
            samples: report.samples,
            regular_axis: report.regular_axis,
            start: before.start,
            end_before: before.end_before,
            end: before.end,
            cells: report.cells,
            voxels: report.voxels,
            toggles: report.toggles,
            model_errors: report.model_errors,
            lossless: before.lossless,
            bytes_before: before.bytes_before,
            file_bytes: report.file_bytes,
            read_seconds: report.read_seconds,
            model_seconds: report.model_seconds,
            segments: before.segments,
        }
    }
}

/// An existing file rewritten: the plan (the file's settings, its axis extended by the new
/// times, its last observed map to continue from), the intake, then the file's cells
/// merged with the new ones and every cell refitted.
pub(super) fn rewrite(run: &Run<'_>, file: &Path) -> Result<IngestReport, ConvertError> {
    let Run {
        context,
        inputs,
        options,
        progress,
        ..
    } = *run;
    let first = inputs.first().ok_or(ConvertError::NoInputs)?;
    let reader = context.open_froct(file)?;
    let old = reader.header().clone();
    let old_axis = &old.axis;
    if first.time <= old_axis.end() {
        return Err(refuse_overlap(file, inputs, old_axis.end()));
    }
    let model = context.model_of(&old)?.create();
    let mut config = ModelConfig::default().with_outliers(reader.model().outlier_mode());
    config.options = options.config.options.clone();
    let new_times: Vec<Timestamp> = inputs.iter().map(|i| i.time).collect();
    let axis = extended_axis(old_axis, &new_times)?;
    // Fail on a bad model/axis combination before reading anything.
    model.prepare(&axis, &config)?;

    let (start, previous) = continue_from_last_map(&reader, &axis)?;

    // The file fixes the series' resolution: inputs of another one are refused (or left
    // out with `skip_bad`), whatever most of them give.
    let intaken = Intake {
        axis,
        tile_depth: old.tile_depth,
        file: Some((file, old.resolution)),
        seed: Some((start, previous)),
        spill_dir: output_dir(file),
    }
    .run(run)?;
    let axis = &intaken.axis;
    let prepared = model.prepare(axis, &config)?;

    let modelling = Instant::now();
    let mut header = Header::new(
        old.resolution,
        old.tile_depth,
        axis.clone(),
        model.id(),
        prepared.encode_parameters(),
        old.codec,
    );
    header.toggles = old.toggles;
    header.metadata = metadata(&old, intaken.used, intaken.input_bytes, options);
    let mut writer = TileWriter::create(file, &header)?;
    let accumulated = intaken.accumulated;
    let old_cells: u64 = reader.tiles().iter().map(|t| u64::from(t.cell_count)).sum();
    progress.stage(
        "modelling cells",
        old_cells + accumulated.cell_count() as u64,
    );
    let accumulate_seconds = accumulated.busy_seconds();
    let (spilled_bytes, spills) = (accumulated.spilled_bytes(), accumulated.spills());
    let samples = SampleMap::new(old_axis, axis);
    let old_tiles = OldTiles::new(&reader, &samples);
    let new_tiles = accumulated.into_tiles(axis.len(), &intaken.absent);
    let tiles = merge_tiles(old_tiles, new_tiles, old.tile_depth);
    let fitter = TileFitter::new(axis, prepared.as_ref());
    let encoder = TileEncoder::new(header.tile_layout(), prepared.as_ref());
    let cells = cells_of_tiles(tiles);
    fit_and_write(
        cells,
        old.tile_depth,
        &fitter,
        &encoder,
        &mut writer,
        progress,
    )?;
    let model_seconds = modelling.elapsed().as_secs_f64();
    let stats = writer.stats().clone();
    let lossless = config.outliers == OutlierMode::Lossless;
    let added = Added {
        used: intaken.used as u64,
        skipped: intaken.skipped.len() as u64,
        input_bytes: intaken.input_bytes,
        changed_voxels: intaken.changed_voxels,
    };
    let seconds = options
        .time
        .is_none()
        .then_some((intaken.read_seconds, model_seconds));
    let summary = added.summary(reader.summary(), &stats, lossless, seconds);
    let bytes_before = reader.file_len();
    let written = writer.finish(summary)?;
    Ok(IngestReport {
        output: file.to_path_buf(),
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
        extended: Some(Extended {
            samples_before: old_axis.len(),
            start: axis.start(),
            end_before: old_axis.end(),
            end: axis.end(),
            lossless,
            bytes_before,
            segments: None,
            converted: false,
        }),
    })
}

/// The file's last observed map, which starts the new histories at its sample on the new
/// `axis`: its changes from nothing there, and the map as the intake's previous one.
fn continue_from_last_map(
    reader: &FroctReader,
    axis: &TimeAxis,
) -> Result<(SampleChanges, Accepted), ConvertError> {
    let old_axis = &reader.header().axis;
    let last_observed = (0..old_axis.len())
        .rev()
        .find(|&s| !old_axis.is_missing(s))
        .ok_or(ConvertError::internal("a file without a snapshot"))?;
    let seam = old_axis
        .time(last_observed)
        .and_then(|t| axis.index_of(t))
        .ok_or(ConvertError::internal(
            "the file's last sample is not on the new axis",
        ))?;
    let last_map = observed_map(reader, last_observed)?;
    let start = SampleChanges {
        sample: seam,
        changes: froctomap_core::changes(&[], last_map.leaves()),
    };
    Ok((start, Accepted::from_map(last_map)))
}

/// What an append adds to the counts of the file's summary.
struct Added {
    used: u64,
    skipped: u64,
    input_bytes: u64,
    changed_voxels: u64,
}

impl Added {
    /// The rewritten file's summary: the write's statistics, the counts of the file before
    /// (`previously`) plus these, and `seconds` (reading, modelling) unless the times are
    /// to be left out.
    fn summary(
        self,
        previously: &Map<String, Value>,
        stats: &TileStats,
        lossless: bool,
        seconds: Option<(f64, f64)>,
    ) -> Map<String, Value> {
        let previously = |key: &str| previously.get(key).and_then(Value::as_u64).unwrap_or(0);
        let mut summary = stats.summary(lossless);
        let mut put = |key: &str, value: Value| summary.insert(key.to_string(), value);
        put(
            "snapshots_used",
            json!(previously("snapshots_used") + self.used),
        );
        put(
            "snapshots_skipped",
            json!(previously("snapshots_skipped") + self.skipped),
        );
        put(
            "input_bytes",
            json!(previously("input_bytes") + self.input_bytes),
        );
        put(
            "changed_voxels",
            json!(previously("changed_voxels") + self.changed_voxels),
        );
        put("appends", json!(previously("appends") + 1));
        if let Some((read_seconds, model_seconds)) = seconds {
            put("read_seconds", json!(read_seconds));
            put("model_seconds", json!(model_seconds));
        }
        summary
    }
}

/// The refusal of inputs not all after `last`, the file's last instant: names the last
/// input at or before it.
pub(crate) fn refuse_overlap(file: &Path, inputs: &[SeriesInput], last: Timestamp) -> ConvertError {
    let input = inputs
        .iter()
        .rev()
        .find(|i| i.time <= last)
        .or(inputs.first());
    ConvertError::AppendOverlap {
        file: file.to_path_buf(),
        last,
        input: input.map(|i| i.path.clone()).unwrap_or_default(),
        time: input.map_or(last, |i| i.time),
    }
}

/// The time axis of a file's samples followed by later `times` (sorted): the file's grid
/// when the new times lie on it (its missing samples stay missing, the grid's unused
/// instants between become missing), by the rule of [`axis_for_times`] (at most as many
/// gaps as snapshots); otherwise the axis [`axis_for_times`] gives for every instant with a
/// snapshot, which is the axis a build of all the snapshots has.
pub(crate) fn extended_axis(old: &TimeAxis, times: &[Timestamp]) -> Result<TimeAxis, ConvertError> {
    let present = (0..old.len()).filter(|&s| !old.is_missing(s));
    if let (Some(step), Some(last)) = (old.step_ns(), times.last()) {
        let on_grid = |t: &Timestamp| (t.0 - old.start().0) % step == 0;
        let count = (last.0 - old.start().0) / step + 1;
        let snapshots = present.clone().count() + times.len();
        if times.iter().all(on_grid)
            && count <= 2 * snapshots as i64
            && count <= i64::from(u32::MAX)
        {
            let mut missing: Vec<u32> = old.missing().to_vec();
            let mut next = times
                .iter()
                .map(|t| (t.0 - old.start().0) / step)
                .peekable();
            for i in i64::from(old.len())..count {
                if next.peek() == Some(&i) {
                    next.next();
                } else {
                    missing.push(i as u32);
                }
            }
            return TimeAxis::regular(old.start(), step, count as u32, missing)
                .map_err(ConvertError::TimeAxis);
        }
    }
    let mut all: Vec<Timestamp> = present.filter_map(|s| old.time(s)).collect();
    all.extend_from_slice(times);
    axis_for_times(&all)
}

/// Where the samples of a file's axis are on the axis that extends it.
pub(crate) struct SampleMap<'a> {
    old: &'a TimeAxis,
    new: &'a TimeAxis,
    /// Every sample keeps its index (the same grid, or the same list of instants).
    same_indices: bool,
}

impl<'a> SampleMap<'a> {
    pub fn new(old: &'a TimeAxis, new: &'a TimeAxis) -> Self {
        let same_grid = old.step_ns().is_some() && old.step_ns() == new.step_ns();
        let both_lists = old.step_ns().is_none() && new.step_ns().is_none();
        Self {
            old,
            new,
            same_indices: old.start() == new.start() && (same_grid || both_lists),
        }
    }

    /// Appends to `out` the runs on the new axis of the old samples `[first, end)` observed in
    /// `state`, without the old axis' missing samples.
    pub(super) fn push_run(
        &self,
        first: u32,
        end: u32,
        state: Occupancy,
        out: &mut Vec<(u32, u32, Occupancy)>,
    ) -> Result<(), ConvertError> {
        let missing = self.old.missing();
        let from = missing.partition_point(|&m| m < first);
        let to = missing.partition_point(|&m| m < end);
        let mut cursor = first;
        for &hole in missing[from..to].iter().chain(std::iter::once(&end)) {
            if hole > cursor {
                self.push_present(cursor, hole, state, out)?;
            }
            cursor = hole.saturating_add(1);
        }
        Ok(())
    }

    /// [`push_run`](Self::push_run) for samples `[first, end)` that all have a snapshot.
    fn push_present(
        &self,
        first: u32,
        end: u32,
        state: Occupancy,
        out: &mut Vec<(u32, u32, Occupancy)>,
    ) -> Result<(), ConvertError> {
        if self.same_indices {
            out.push((first, end - first, state));
            return Ok(());
        }
        let index = |s: u32| {
            self.old
                .time(s)
                .and_then(|t| self.new.index_of(t))
                .ok_or(ConvertError::internal(
                    "an old sample is not on the new axis",
                ))
        };
        let (a, b) = (index(first)?, index(end - 1)?);
        if b.checked_sub(a) == Some(end - 1 - first) {
            out.push((a, end - first, state));
        } else {
            // The new grid is finer: each old sample on its own.
            for s in first..end {
                out.push((index(s)?, 1, state));
            }
        }
        Ok(())
    }
}

/// The observations of a file's cell, on the new axis.
fn old_observations(
    cell: &Cell,
    model: &dyn PreparedModel,
    samples: &SampleMap<'_>,
) -> Result<ObservedCell, ConvertError> {
    let len = samples.old.len();
    let ranges: Vec<(u32, u32)> = match &cell.mask {
        None => vec![(0, len)],
        Some(mask) => mask
            .as_slice()
            .chunks(2)
            .map(|pair| (pair[0], pair.get(1).copied().unwrap_or(len).min(len)))
            .filter(|(a, b)| a < b)
            .collect(),
    };
    let mut runs: Vec<(u32, u32, Occupancy)> = Vec::new();
    for (first, end) in ranges {
        match &cell.content {
            CellContent::Constant(state) => samples.push_run(first, end, *state, &mut runs)?,
            CellContent::ConstantExcept { state, exceptions } => {
                let flips = exceptions.as_slice();
                let at = |s: u32| {
                    if exceptions.parity_at(s) {
                        !*state
                    } else {
                        *state
                    }
                };
                let mut cursor = first;
                let from = flips.partition_point(|&p| p <= first);
                for &flip in flips[from..].iter().take_while(|&&p| p < end) {
                    samples.push_run(cursor, flip, at(cursor), &mut runs)?;
                    cursor = flip;
                }
                samples.push_run(cursor, end, at(cursor), &mut runs)?;
            }
            CellContent::Modelled(voxel) => {
                let mut cursor = first;
                let mut current = model.state_at_sample(voxel, first);
                for s in first + 1..end {
                    let state = model.state_at_sample(voxel, s);
                    if state != current {
                        samples.push_run(cursor, s, current, &mut runs)?;
                        (cursor, current) = (s, state);
                    }
                }
                samples.push_run(cursor, end, current, &mut runs)?;
            }
        }
    }
    let observations = froctomap_temporal::VoxelObservations::from_runs(runs)?;
    Ok((cell.start, cell.depth, observations))
}

/// A file's tiles as [`TileHistory`] values on the new axis, in Morton order, decoded one
/// at a time (each tile's cells in parallel).
pub(super) struct OldTiles<'a> {
    reader: &'a FroctReader,
    samples: &'a SampleMap<'a>,
    next: usize,
}

impl<'a> OldTiles<'a> {
    pub(super) fn new(reader: &'a FroctReader, samples: &'a SampleMap<'a>) -> Self {
        Self {
            reader,
            samples,
            next: 0,
        }
    }
}

impl Iterator for OldTiles<'_> {
    type Item = Result<TileHistory, ConvertError>;

    // One tile at a time, its cells packed as they are made: a tile of a long series
    // unpacked takes hundreds of MB.
    fn next(&mut self) -> Option<Self::Item> {
        let i = self.next;
        if i >= self.reader.tiles().len() {
            return None;
        }
        self.next += 1;
        let (reader, samples) = (self.reader, self.samples);
        let model = reader.model();
        let tile = (|| {
            let cells = reader.read_tile(i)?;
            let cells = cells
                .par_iter()
                .map(|cell| {
                    let (start, depth, observations) = old_observations(cell, model, samples)?;
                    Ok((start, depth, pack(&observations)))
                })
                .collect::<Result<Vec<PackedCell>, ConvertError>>()?;
            Ok(TileHistory::from_packed(cells))
        })();
        Some(tile)
    }
}

/// The file's metadata with the snapshots added counted in and the append's time.
fn metadata(
    old: &Header,
    used: usize,
    input_bytes: u64,
    options: &IngestOptions,
) -> Map<String, Value> {
    let mut meta = old.metadata.clone();
    let count = |key: &str| meta.get(key).and_then(Value::as_u64).unwrap_or(0);
    let sources = count("sources") + used as u64;
    let bytes = count("input_bytes") + input_bytes;
    meta.insert("sources".into(), Value::from(sources));
    meta.insert("input_bytes".into(), Value::from(bytes));
    meta.insert("appended".into(), stamp(options.time));
    for (k, v) in &options.metadata {
        meta.insert(k.clone(), v.clone());
    }
    meta
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(v: i64) -> Timestamp {
        Timestamp::from_secs(v)
    }

    #[test]
    fn a_cells_runs_come_from_its_mask_exceptions_and_model() {
        use froctomap_core::MortonCode;
        use froctomap_temporal::{Toggles, VoxelObservations};
        use std::sync::Arc;
        use Occupancy::{Free, Occupied};
        let setup = crate::build::test_support::default_model(8);
        let axis = setup.axis.clone();
        let samples = SampleMap::new(&axis, &axis);
        let runs = |cell: &Cell| {
            old_observations(cell, setup.model.as_ref(), &samples)
                .unwrap()
                .2
        };
        // Observed over samples 1..6 and from 7 on, free except at samples 3 and 7.
        let mask = Some(Arc::new(Toggles::new(vec![1, 6, 7]).unwrap()));
        let cell = Cell {
            start: MortonCode(0),
            depth: 16,
            mask: mask.clone(),
            content: CellContent::ConstantExcept {
                state: Free,
                exceptions: Toggles::new(vec![3, 4, 7]).unwrap(),
            },
        };
        let expected = [
            (1, 2, Free),
            (3, 1, Occupied),
            (4, 2, Free),
            (7, 1, Occupied),
        ];
        assert_eq!(runs(&cell), VoxelObservations::from_runs(expected).unwrap());
        // A modelled cell gives back what it was fitted on.
        let observed = VoxelObservations::from_runs(expected).unwrap();
        let cell = Cell {
            content: CellContent::Modelled(setup.model.fit(&observed).unwrap()),
            ..cell
        };
        assert_eq!(runs(&cell), observed);
        let constant = Cell {
            mask: None,
            content: CellContent::Constant(Occupied),
            ..cell
        };
        assert_eq!(
            runs(&constant),
            VoxelObservations::from_runs([(0, 8, Occupied)]).unwrap()
        );
    }

    #[test]
    fn a_grid_stays_a_grid_when_the_new_times_lie_on_it() {
        // Samples 0..4 every 10 s, sample 2 missing (a snapshot left out).
        let old = TimeAxis::regular(s(0), 10_000_000_000, 4, vec![2]).unwrap();
        let axis = extended_axis(&old, &[s(40), s(60)]).unwrap();
        assert_eq!(axis.step_ns(), Some(10_000_000_000));
        assert_eq!(axis.len(), 7);
        assert_eq!(axis.missing(), &[2, 5]);
        let map = SampleMap::new(&old, &axis);
        assert!(map.same_indices);
        let mut runs = Vec::new();
        map.push_run(0, 4, Occupancy::Free, &mut runs).unwrap();
        assert_eq!(runs, [(0, 2, Occupancy::Free), (3, 1, Occupancy::Free)]);
    }

    #[test]
    fn times_off_the_grid_make_the_axis_of_all_instants() {
        let old = TimeAxis::regular(s(0), 10_000_000_000, 3, vec![1]).unwrap();
        // Off the grid: the axis of the instants with a snapshot (0, 20, 25, 30), whose
        // grid is 5 s: old sample 2 (20 s) is new sample 4.
        let axis = extended_axis(&old, &[s(25), s(30)]).unwrap();
        assert_eq!(axis, axis_for_times(&[s(0), s(20), s(25), s(30)]).unwrap());
        let map = SampleMap::new(&old, &axis);
        let mut runs = Vec::new();
        map.push_run(0, 3, Occupancy::Occupied, &mut runs).unwrap();
        assert_eq!(
            runs,
            [(0, 1, Occupancy::Occupied), (4, 1, Occupancy::Occupied)]
        );
        // Jittered times: an explicit axis, samples renumbered.
        let axis = extended_axis(&old, &[s(31), s(44)]).unwrap();
        assert_eq!(axis.step_ns(), None);
        assert_eq!(axis.times().unwrap(), &[s(0), s(20), s(31), s(44)]);
        let map = SampleMap::new(&old, &axis);
        let mut runs = Vec::new();
        map.push_run(0, 3, Occupancy::Free, &mut runs).unwrap();
        // Old samples 0 and 2 (1 is missing) are new samples 0 and 1: one run.
        assert_eq!(
            froctomap_temporal::VoxelObservations::from_runs(runs).unwrap(),
            froctomap_temporal::VoxelObservations::from_runs([(0, 2, Occupancy::Free)]).unwrap()
        );
        // An explicit axis stays one, with the same indices.
        let old = TimeAxis::explicit(vec![s(0), s(7), s(9)]).unwrap();
        let axis = extended_axis(&old, &[s(20)]).unwrap();
        assert_eq!(axis.times().unwrap(), &[s(0), s(7), s(9), s(20)]);
        assert!(SampleMap::new(&old, &axis).same_indices);
    }
}
