//! `build`: a series of maps → one FROctomap file, streaming, with bounded memory.

use crate::context::Context;
use crate::error::{ConvertError, SnapshotError};
use crate::history::SeriesHistory;
use crate::inputs::SeriesInput;
use crate::outputs::refuse_overwriting_input;
use crate::progress::Progress;
use crate::snapshot_changes::{Accepted, ChangeReader, Refusal};
use froctomap_core::calendar::iso8601;
use froctomap_core::{MortonCode, Occupancy, StateChange, Timestamp};
use froctomap_file::{
    encode_tile, mask_from_ranges, Cell, CellContent, Codec, EncodedTile, FroctWriter, Header,
    TileLayout, ToggleLayout, WrittenFile,
};
use froctomap_formats::{Backend, FormatError, ReadOptions, PROBE_BYTES};
use froctomap_octomap_codec::{detect_kind, parse_header, FileKind};
use froctomap_temporal::{ModelConfig, OutlierMode, PreparedModel, TimeAxis, VoxelObservations};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::mpsc::SyncSender;
use std::sync::Arc;
use std::thread::ScopedJoinHandle;
use std::time::Instant;

/// How to build.
#[derive(Clone, Debug)]
pub struct BuildOptions {
    /// Temporal model name (see `froctomap_temporal::ModelRegistry`). Default `fremen-periods`,
    /// which works on any time axis.
    pub model: String,
    /// Model settings: lossless/lossy, and the model's own options (see its descriptor).
    pub config: ModelConfig,
    /// Depth of the tiles of the output (default 10: cubes of 64 voxels per edge).
    pub tile_depth: u8,
    /// Tile codec (default zstd level 19).
    pub codec: Codec,
    /// How toggle lists are stored (default: blocks of 256 samples, format 1.1, so that a
    /// query at one sample reads one block).
    pub toggles: ToggleLayout,
    /// Leave unreadable files and files of another resolution out (listed in the report)
    /// instead of stopping.
    pub skip_bad: bool,
    /// Force the input map format.
    pub input_format: Option<String>,
    /// Preferred implementation for reading maps.
    pub backend: Option<Backend>,
    /// Extra metadata stored in the file header (e.g. `tags`, `source`).
    pub metadata: Map<String, Value>,
    /// Files decoded in parallel per batch (bounds memory; default 8 × threads).
    pub batch: usize,
    /// Creation time stored in the metadata (`created`), to the second; `None`: now. A fixed
    /// time makes the file reproducible (the build's timings are then not stored either): the
    /// same inputs and options give the same bytes.
    pub created: Option<Timestamp>,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            model: "fremen-periods".to_string(),
            config: ModelConfig::default(),
            tile_depth: 10,
            codec: Codec::default(),
            toggles: ToggleLayout::DEFAULT,
            skip_bad: false,
            input_format: None,
            backend: None,
            metadata: Map::new(),
            batch: 8 * rayon::current_num_threads().max(1),
            created: None,
        }
    }
}

/// Cell and voxel counts by class.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ClassCounts {
    /// Always observed free.
    pub static_free: u64,
    /// Always observed occupied.
    pub static_occupied: u64,
    /// Changed state at least once (carry a model).
    pub dynamic: u64,
    /// Unobserved at some sample of the series (carry an observation mask).
    pub unknown_sometimes: u64,
}

impl ClassCounts {
    /// Adds another count (saturating: counts read from a file may be anything).
    pub fn add(&mut self, other: &ClassCounts) {
        self.static_free = self.static_free.saturating_add(other.static_free);
        self.static_occupied = self.static_occupied.saturating_add(other.static_occupied);
        self.dynamic = self.dynamic.saturating_add(other.dynamic);
        self.unknown_sometimes = self
            .unknown_sometimes
            .saturating_add(other.unknown_sometimes);
    }

    /// All cells (or voxels), saturating at `u64::MAX` rather than wrapping when the counts
    /// come from a hostile file's summary.
    ///
    /// ```
    /// use froctomap_convert::ClassCounts;
    /// let forged = ClassCounts { static_free: u64::MAX, dynamic: 2, ..ClassCounts::default() };
    /// assert_eq!(forged.total(), u64::MAX);
    /// ```
    pub fn total(&self) -> u64 {
        self.static_free
            .saturating_add(self.static_occupied)
            .saturating_add(self.dynamic)
    }
}

/// What a build did.
#[derive(Clone, Debug, Serialize)]
pub struct BuildReport {
    /// The file written.
    pub output: PathBuf,
    /// Snapshots given.
    pub inputs: usize,
    /// Snapshots used.
    pub used: usize,
    /// Files left out with `skip_bad`, and why.
    pub skipped: Vec<(PathBuf, String)>,
    /// Reader warnings (file, message), e.g. tolerated header problems.
    pub warnings: Vec<(PathBuf, String)>,
    /// Total bytes of the input files used.
    pub input_bytes: u64,
    /// Samples of the time axis.
    pub samples: u32,
    /// `true` for a regular axis.
    pub regular_axis: bool,
    /// Cells by class.
    pub cells: ClassCounts,
    /// Voxels by class.
    pub voxels: ClassCounts,
    /// Outlier toggles stored (lossless).
    pub toggles: u64,
    /// Observed cell-samples the model gets wrong without outliers (lossy files store no
    /// outliers, so these are their reconstruction errors).
    pub model_errors: u64,
    /// Voxel-samples whose state changed between consecutive snapshots.
    pub changed_voxels: u64,
    /// Bytes of the output, by part.
    pub file_bytes: u64,
    /// Header bytes.
    pub header_bytes: u64,
    /// Index and footer bytes.
    pub index_bytes: u64,
    /// Stored tile bytes.
    pub tile_bytes: u64,
    /// Seconds spent reading and accumulating the inputs.
    pub read_seconds: f64,
    /// Of those, seconds spent applying changes to the cells (the part that is sequential).
    pub accumulate_seconds: f64,
    /// Seconds spent fitting, encoding and writing.
    pub model_seconds: f64,
}

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

/// An input file's bytes, refused above `limit` bytes before reading them.
pub(crate) fn read_input(path: &Path, limit: u64) -> Result<Vec<u8>, SnapshotError> {
    let metadata = std::fs::metadata(path).map_err(SnapshotError::Io)?;
    refuse_special(path, &metadata)?;
    let bytes = metadata.len();
    if bytes > limit {
        return Err(SnapshotError::TooLarge { bytes, limit });
    }
    std::fs::read(path).map_err(SnapshotError::Io)
}

/// A FIFO or device is refused before it is opened (reading one may never end).
fn refuse_special(path: &Path, metadata: &std::fs::Metadata) -> Result<(), SnapshotError> {
    match froctomap_formats::special_kind(metadata.file_type()) {
        None => Ok(()),
        Some(kind) => Err(SnapshotError::Format(FormatError::NotAFile {
            path: path.to_path_buf(),
            kind,
        })),
    }
}

fn gcd(a: i64, b: i64) -> i64 {
    if b == 0 {
        a.abs()
    } else {
        gcd(b, a % b)
    }
}

/// A file's resolution from its first bytes, when its format is OctoMap's.
fn header_resolution(path: &Path) -> Result<Option<f64>, SnapshotError> {
    use std::io::Read;
    let metadata = std::fs::metadata(path).map_err(SnapshotError::Io)?;
    refuse_special(path, &metadata)?;
    let mut head = Vec::with_capacity(PROBE_BYTES as usize);
    std::fs::File::open(path)
        .and_then(|f| f.take(PROBE_BYTES).read_to_end(&mut head))
        .map_err(SnapshotError::Io)?;
    if head.is_empty() {
        return Err(SnapshotError::Empty);
    }
    let kind = detect_kind(&head).unwrap_or(FileKind::Binary);
    match parse_header(&head, kind) {
        Ok(header) => Ok(Some(header.resolution)),
        // Not an OctoMap header (another format, or a long header): the full read decides.
        Err(_) => Ok(None),
    }
}

/// Builds a FROctomap file from snapshots (sorted by time, distinct times).
///
/// Reads the inputs in batches, turns each into its changes from the one before (from the
/// bytes where the format allows, see `FormatRegistry::diff_bytes`; else by decoding) and
/// accumulates the changes in time order (memory grows with the cells and their changes,
/// not with the number of snapshots), then fits a model per dynamic cell and writes the file
/// tile by tile, atomically. Input formats and the model are looked up in `context`.
///
/// Inputs are map files with their times ([`collect_inputs`](crate::collect_inputs)); other
/// kinds of sources of timed snapshots (recordings such as ROS bags) are to be expanded into
/// such a series before they reach `build`, which then needs no case of its own for them.
pub fn build(
    context: &Context,
    inputs: &[SeriesInput],
    output: &Path,
    options: &BuildOptions,
    progress: &dyn Progress,
) -> Result<BuildReport, ConvertError> {
    let started = Instant::now();
    refuse_overwriting_input(output, inputs.iter().map(|i| i.path.as_path()))?;
    let registry = context.formats();
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

    // Pass 1: headers only, to fail fast on unreadable files and mixed resolutions.
    progress.stage("checking inputs", inputs.len() as u64);
    let resolutions: Vec<Result<Option<f64>, SnapshotError>> = inputs
        .par_iter()
        .map(|input| {
            let r = header_resolution(&input.path);
            progress.advance(1);
            r
        })
        .collect();
    let mut skipped: Vec<(PathBuf, String)> = Vec::new();
    let mut usable = vec![true; inputs.len()];
    let mut series_resolution: Option<(f64, usize)> = None;
    for (i, r) in resolutions.into_iter().enumerate() {
        match r {
            Err(reason) if options.skip_bad => {
                skipped.push((inputs[i].path.clone(), reason.to_string()));
                usable[i] = false;
            }
            Err(reason) => {
                return Err(ConvertError::Snapshot {
                    path: inputs[i].path.clone(),
                    source: Arc::new(reason),
                })
            }
            Ok(Some(res)) => match series_resolution {
                None => series_resolution = Some((res, i)),
                Some((first, _)) if first == res => {}
                Some((first, j)) => {
                    if !options.skip_bad {
                        return Err(ConvertError::MixedResolution {
                            first: inputs[j].path.clone(),
                            first_resolution: first,
                            second: inputs[i].path.clone(),
                            second_resolution: res,
                        });
                    }
                    skipped.push((
                        inputs[i].path.clone(),
                        format!("resolution {res} m differs from the series' {first} m"),
                    ));
                    usable[i] = false;
                }
            },
            Ok(None) => {}
        }
    }

    // Pass 2: decode and compare with the predecessor in parallel batches, while a second
    // thread accumulates the previous batch's differences in time order.
    progress.stage("reading snapshots", inputs.len() as u64);
    let read_options = ReadOptions {
        format: options.input_format.as_deref(),
        backend: options.backend,
    };
    let mut warnings = Vec::new();
    let mut input_bytes = 0u64;
    let mut used = 0usize;
    let mut absent: Vec<u32> = axis.missing().to_vec();
    let mut resolution = series_resolution.map(|(r, _)| r);
    let first_path = series_resolution.map(|(_, i)| inputs[i].path.clone());
    let batch = options.batch.max(1);
    // Space is split into ranges (at tile boundaries, which no cell straddles) accumulated
    // by one thread each; the ranges are chosen from the first batch's changes.
    let parts = rayon::current_num_threads().clamp(1, 8);
    let (histories, accumulate_seconds) =
        std::thread::scope(|scope| -> Result<(Vec<SeriesHistory>, f64), ConvertError> {
            type Batch = Arc<Vec<(u32, Vec<StateChange>)>>;
            let mut workers: Vec<(SyncSender<Batch>, ScopedJoinHandle<'_, Accumulated>)> =
                Vec::new();
            // The last snapshot accepted, which the next one is compared with.
            let mut previous: Option<Accepted> = None;
            let produced = (|| -> Result<(), ConvertError> {
                for chunk_start in (0..inputs.len()).step_by(batch) {
                    let chunk: Vec<usize> = (chunk_start..(chunk_start + batch).min(inputs.len()))
                        .filter(|&i| usable[i])
                        .collect();
                    let limit = context.limits().max_map_file_bytes;
                    let raw: Vec<Result<Vec<u8>, Refusal>> = chunk
                        .par_iter()
                        .map(|&i| read_input(&inputs[i].path, limit).map_err(Arc::new))
                        .collect();
                    // When the series' resolution is not known from the headers, the first file sets it.
                    if resolution.is_none() {
                        if let (Some(&i), Some(Ok(bytes))) = (chunk.first(), raw.first()) {
                            if let Ok(read) =
                                registry.read_bytes(&inputs[i].path, bytes, read_options)
                            {
                                resolution = Some(read.map.snapshot.resolution());
                            }
                        }
                    }
                    let reader = ChangeReader {
                        registry,
                        options: read_options,
                        resolution,
                    };
                    let paths: Vec<&Path> =
                        chunk.iter().map(|&i| inputs[i].path.as_path()).collect();
                    let outcomes = reader.batch(&paths, &raw, &mut previous);
                    let mut accepted = Vec::with_capacity(outcomes.len());
                    for (k, outcome) in outcomes.into_iter().enumerate() {
                        let input = &inputs[chunk[k]];
                        let sample = axis
                            .index_of(input.time)
                            .ok_or_else(|| ConvertError::internal("a time not on the axis"))?;
                        match outcome {
                            Ok(read) => {
                                warnings.extend(
                                    read.warnings.into_iter().map(|w| (input.path.clone(), w)),
                                );
                                input_bytes += raw[k].as_ref().map_or(0, |b| b.len() as u64);
                                used += 1;
                                accepted.push((sample, read.changes));
                            }
                            Err(reason) if options.skip_bad => {
                                skipped.push((input.path.clone(), reason.to_string()));
                                absent.push(sample);
                                progress.advance(1);
                            }
                            Err(reason) => {
                                return Err(match (reason.resolution_mismatch(), &first_path) {
                                    (Some((series, found)), Some(first)) => {
                                        ConvertError::MixedResolution {
                                            first: first.clone(),
                                            first_resolution: series,
                                            second: input.path.clone(),
                                            second_resolution: found,
                                        }
                                    }
                                    _ => ConvertError::Snapshot {
                                        path: input.path.clone(),
                                        source: reason,
                                    },
                                });
                            }
                        }
                    }
                    if workers.is_empty() {
                        let bounds = split_points(&accepted, parts, options.tile_depth);
                        for (part, range) in ranges(&bounds).into_iter().enumerate() {
                            let (sender, receiver) = std::sync::mpsc::sync_channel::<Batch>(1);
                            // One thread reports progress for all.
                            let report = part == 0;
                            let worker = scope.spawn(move || -> Accumulated {
                                let mut history = SeriesHistory::new(options.tile_depth);
                                let mut busy = 0.0;
                                for batch in receiver {
                                    let started = Instant::now();
                                    for (sample, changes) in batch.iter() {
                                        history.apply_changes(*sample, &clip(changes, range))?;
                                        if report {
                                            progress.advance(1);
                                        }
                                    }
                                    busy += started.elapsed().as_secs_f64();
                                }
                                Ok((history, busy))
                            });
                            workers.push((sender, worker));
                        }
                    }
                    let batch: Batch = Arc::new(accepted);
                    if workers
                        .iter()
                        .any(|(sender, _)| sender.send(batch.clone()).is_err())
                    {
                        // An accumulator stopped on an error, which `join` reports.
                        break;
                    }
                }
                Ok(())
            })();
            let mut histories = Vec::with_capacity(workers.len());
            let mut busy = 0.0f64;
            for (sender, worker) in workers {
                drop(sender);
                let (history, seconds) = worker
                    .join()
                    .map_err(|_| ConvertError::internal("an accumulating thread panicked"))??;
                histories.push(history);
                busy = busy.max(seconds);
            }
            produced?;
            Ok((histories, busy))
        })?;
    for (i, &u) in usable.iter().enumerate() {
        if !u {
            if let Some(sample) = axis.index_of(inputs[i].time) {
                absent.push(sample);
            }
        }
    }
    absent.sort_unstable();
    absent.dedup();
    let resolution = resolution.ok_or(ConvertError::NothingToBuild {
        inputs: inputs.len(),
    })?;
    let read_seconds = started.elapsed().as_secs_f64();
    let changed_voxels = histories.iter().map(SeriesHistory::changed_voxels).sum();
    // Snapshots left out become missing samples of a regular axis, so the file says there
    // is no snapshot at their time (an explicit axis keeps the instant, with nothing
    // observed at it).
    let (axis, prepared) = match axis.step_ns() {
        Some(step) if absent.len() > axis.missing().len() => {
            let regular = TimeAxis::regular(axis.start(), step, axis.len(), absent.clone())
                .map_err(ConvertError::TimeAxis)?;
            let prepared = model.prepare(&regular, &options.config)?;
            (regular, prepared)
        }
        _ => (axis, prepared),
    };

    // Pass 3: fit, encode and write, tile by tile.
    let modelling = Instant::now();
    let mut header = Header::new(
        resolution,
        options.tile_depth,
        axis.clone(),
        model.id(),
        prepared.encode_parameters(),
        options.codec,
    );
    header.toggles = options.toggles;
    header.metadata = metadata(inputs, used, input_bytes, options);
    let layout = header.tile_layout();
    let mut writer = FroctWriter::create(output, &header)?;
    let cell_count: usize = histories.iter().map(SeriesHistory::cell_count).sum();
    progress.stage("modelling cells", cell_count as u64);
    let axis_len = axis.len();
    let mut stats = TileStats::default();
    let flush = |tiles: &mut Vec<Vec<(MortonCode, u8, VoxelObservations)>>,
                 writer: &mut FroctWriter,
                 stats: &mut TileStats|
     -> Result<(), ConvertError> {
        let encoded: Vec<Result<(EncodedTile, TileStats), ConvertError>> = tiles
            .par_iter()
            .map(|cells| {
                let r = encode_cells(cells, &axis, prepared.as_ref(), &layout);
                progress.advance(cells.len() as u64);
                r
            })
            .collect();
        for result in encoded {
            let (tile, tile_stats) = result?;
            writer.write_tile(&tile)?;
            stats.add(&tile_stats);
        }
        tiles.clear();
        Ok(())
    };
    // Tiles are fitted in parallel batches; a batch ends at a few tiles per thread or at a
    // bound on the runs it holds (cells' observations are unpacked here, and a long series
    // with partial views gives every cell many runs), whichever comes first. A thread of
    // its own walks the cells and gathers the next batch while one is fitted, so up to three
    // batches exist at once (4-week series: peak 401 MiB with 4 Mi runs, 300 with 1 Mi).
    const BATCH_RUNS: usize = 1 << 20;
    type TileBatch = Vec<Vec<(MortonCode, u8, VoxelObservations)>>;
    std::thread::scope(|scope| -> Result<(), ConvertError> {
        let (sender, receiver) =
            std::sync::mpsc::sync_channel::<Result<TileBatch, ConvertError>>(0);
        let absent = &absent;
        scope.spawn(move || {
            let mut pending: Vec<(MortonCode, u8, VoxelObservations)> = Vec::new();
            let mut tiles: TileBatch = Vec::new();
            let mut batch_runs = 0usize;
            let cells = histories
                .into_iter()
                .flat_map(|history| history.finish(axis_len, absent));
            for item in cells {
                let cell = match item {
                    Ok(cell) => cell,
                    Err(e) => {
                        let _ = sender.send(Err(e.into()));
                        return;
                    }
                };
                if pending.first().is_some_and(|p| {
                    p.0.node_start(options.tile_depth) != cell.0.node_start(options.tile_depth)
                }) {
                    tiles.push(std::mem::take(&mut pending));
                    if tiles.len() >= 4 * rayon::current_num_threads().max(1)
                        || batch_runs >= BATCH_RUNS
                    {
                        if sender.send(Ok(std::mem::take(&mut tiles))).is_err() {
                            // The writer stopped on an error.
                            return;
                        }
                        batch_runs = 0;
                    }
                }
                batch_runs += cell.2.runs().len();
                pending.push(cell);
            }
            if !pending.is_empty() {
                tiles.push(pending);
            }
            let _ = sender.send(Ok(tiles));
        });
        for batch in receiver {
            flush(&mut batch?, &mut writer, &mut stats)?;
        }
        Ok(())
    })?;
    let model_seconds = modelling.elapsed().as_secs_f64();
    let summary = json!({
        "cell_classes": stats.cells,
        "voxel_classes": stats.voxels,
        "toggles": stats.toggles,
        "model_errors": stats.model_errors,
        "outliers": if options.config.outliers == OutlierMode::Lossless { "lossless" } else { "lossy" },
        "snapshots_used": used,
        "snapshots_skipped": skipped.len(),
        "input_bytes": input_bytes,
        "changed_voxels": changed_voxels,
        "read_seconds": read_seconds,
        "model_seconds": model_seconds,
    });
    let Value::Object(mut summary) = summary else {
        unreachable!("json! of an object literal")
    };
    if options.created.is_some() {
        // A reproducible file: no wall-clock measurement in it (the report keeps them).
        summary.remove("read_seconds");
        summary.remove("model_seconds");
    }
    let written: WrittenFile = writer.finish(summary)?;
    Ok(BuildReport {
        output: output.to_path_buf(),
        inputs: inputs.len(),
        used,
        skipped,
        warnings,
        input_bytes,
        samples: axis.len(),
        regular_axis: axis.step_ns().is_some(),
        cells: stats.cells,
        voxels: stats.voxels,
        toggles: stats.toggles,
        model_errors: stats.model_errors,
        changed_voxels,
        file_bytes: written.file_bytes,
        header_bytes: written.header_bytes,
        index_bytes: written.index_bytes,
        tile_bytes: written.tile_bytes,
        read_seconds,
        accumulate_seconds,
        model_seconds,
    })
}

/// What an accumulating thread hands back: its part of the history and its busy seconds.
type Accumulated = Result<(SeriesHistory, f64), ConvertError>;

/// Up to `parts - 1` increasing tile boundaries that split the changes of a batch into parts
/// of about as many changes (the first snapshot, which is all new, is left out when others
/// follow: later snapshots change where the scene moves).
fn split_points(batch: &[(u32, Vec<StateChange>)], parts: usize, tile_depth: u8) -> Vec<u64> {
    let sample = match batch {
        [_, rest @ ..] if rest.iter().any(|(_, c)| !c.is_empty()) => rest,
        all => all,
    };
    let mut starts: Vec<u64> = sample
        .iter()
        .flat_map(|(_, changes)| changes.iter().map(|c| c.start))
        .collect();
    starts.sort_unstable();
    let mut bounds: Vec<u64> = (1..parts)
        .filter_map(|i| starts.get(starts.len() * i / parts))
        .map(|&at| MortonCode(at).node_start(tile_depth).0)
        .filter(|&at| at > 0)
        .collect();
    bounds.dedup();
    bounds
}

/// The ranges `[from, to)` between consecutive bounds, covering all space.
fn ranges(bounds: &[u64]) -> Vec<(u64, u64)> {
    let mut edges = vec![0];
    edges.extend_from_slice(bounds);
    edges.push(MortonCode::END);
    edges.windows(2).map(|w| (w[0], w[1])).collect()
}

/// The changes (sorted, disjoint) inside `[from, to)`, cut at its ends.
fn clip(changes: &[StateChange], (from, to): (u64, u64)) -> Cow<'_, [StateChange]> {
    let first = changes.partition_point(|c| c.end <= from);
    let last = changes.partition_point(|c| c.start < to).max(first);
    let inside = &changes[first..last];
    match (inside.first(), inside.last()) {
        (Some(a), Some(b)) if a.start < from || b.end > to => inside
            .iter()
            .map(|c| StateChange {
                start: c.start.max(from),
                end: c.end.min(to),
                new: c.new,
            })
            .collect(),
        _ => Cow::Borrowed(inside),
    }
}

fn metadata(
    inputs: &[SeriesInput],
    used: usize,
    input_bytes: u64,
    options: &BuildOptions,
) -> Map<String, Value> {
    let now = options.created.unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| Timestamp(i64::try_from(d.as_nanos()).unwrap_or(i64::MAX)))
            .unwrap_or_default()
    });
    let mut meta = Map::new();
    meta.insert(
        "creator".into(),
        Value::from(format!("froctomap {}", env!("CARGO_PKG_VERSION"))),
    );
    meta.insert(
        "created".into(),
        Value::from(iso8601(Timestamp(now.0 - now.0 % 1_000_000_000))),
    );
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

#[derive(Default)]
struct TileStats {
    cells: ClassCounts,
    voxels: ClassCounts,
    toggles: u64,
    model_errors: u64,
}

impl TileStats {
    fn add(&mut self, other: &TileStats) {
        self.cells.add(&other.cells);
        self.voxels.add(&other.voxels);
        self.toggles += other.toggles;
        self.model_errors += other.model_errors;
    }
}

/// `true` for a probability OctoMap would clamp (below 0.1192 or above 0.971).
fn outside_clamping(p: f64) -> bool {
    use froctomap_core::defaults::{CLAMPING_MAX, CLAMPING_MIN};
    !(CLAMPING_MIN..=CLAMPING_MAX).contains(&p)
}

fn encode_cells(
    cells: &[(MortonCode, u8, VoxelObservations)],
    axis: &TimeAxis,
    model: &dyn PreparedModel,
    layout: &TileLayout,
) -> Result<(EncodedTile, TileStats), ConvertError> {
    let mut stats = TileStats::default();
    let mut out = Vec::with_capacity(cells.len());
    for (start, depth, obs) in cells {
        let voxels = froctomap_core::voxels_per_node(*depth);
        let mask = mask_from_ranges(axis, &obs.observed_ranges());
        if mask.is_some() {
            stats.cells.unknown_sometimes += 1;
            stats.voxels.unknown_sometimes += voxels;
        }
        let content = match obs.is_constant() {
            Some(Occupancy::Free) => {
                stats.cells.static_free += 1;
                stats.voxels.static_free += voxels;
                CellContent::Constant(Occupancy::Free)
            }
            Some(Occupancy::Occupied) => {
                stats.cells.static_occupied += 1;
                stats.voxels.static_occupied += voxels;
                CellContent::Constant(Occupancy::Occupied)
            }
            None => {
                let fitted = model.fit(obs)?;
                stats.cells.dynamic += 1;
                stats.voxels.dynamic += voxels;
                stats.toggles += fitted.toggles().len() as u64;
                stats.model_errors += fitted.model_errors().unwrap_or(0);
                let lossless = model.outlier_mode() == OutlierMode::Lossless;
                let parameters = fitted.parameters();
                let mean = model.mean(parameters);
                if lossless && model.is_constant(parameters) && outside_clamping(mean) {
                    // A constant p no map can express (beyond the clamping bounds) adds
                    // nothing to the constant state; only the exceptions matter. (Lossy files
                    // keep the mean: without exceptions it is all they know of the changes.)
                    CellContent::ConstantExcept {
                        state: Occupancy::from(mean > 0.5),
                        exceptions: fitted.toggles().clone(),
                    }
                } else {
                    CellContent::Modelled(fitted)
                }
            }
        };
        out.push(Cell {
            start: *start,
            depth: *depth,
            mask,
            content,
        });
    }
    let tile = encode_tile(layout, &out, model).map_err(|e| ConvertError::Internal {
        what: "a tile could not be encoded",
        source: Some(e.into()),
    })?;
    Ok((tile, stats))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn changes_are_split_at_part_bounds_without_loss() {
        let change = |start, end| StateChange {
            start,
            end,
            new: Some(Occupancy::Occupied),
        };
        let changes = [change(0, 10), change(20, 40), change(50, 60)];
        let bounds = [30u64, 55];
        let parts = ranges(&bounds);
        assert_eq!(parts, [(0, 30), (30, 55), (55, MortonCode::END)]);
        let clipped: Vec<Vec<StateChange>> = parts
            .iter()
            .map(|&r| clip(&changes, r).into_owned())
            .collect();
        assert_eq!(clipped[0], [change(0, 10), change(20, 30)]);
        assert_eq!(clipped[1], [change(30, 40), change(50, 55)]);
        assert_eq!(clipped[2], [change(55, 60)]);
        // Changes inside one part are passed on as they are.
        assert!(matches!(clip(&changes[..1], parts[0]), Cow::Borrowed(_)));
        // Bounds are tile starts, increasing, from the changes after the first snapshot.
        let batch = vec![
            (0, vec![change(0, 1 << 40)]),
            (
                1,
                (0..100u64)
                    .map(|i| change(i << 34, (i << 34) + 1))
                    .collect(),
            ),
        ];
        let bounds = split_points(&batch, 2, 10);
        assert_eq!(bounds.len(), 1);
        assert_eq!(bounds[0] % froctomap_core::voxels_per_node(10), 0);
        assert!(bounds[0] > 40 << 34 && bounds[0] <= 50 << 34, "{bounds:?}");
        assert!(split_points(&[], 2, 10).is_empty());
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
