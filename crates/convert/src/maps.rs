//! Maps out of a FROctomap file: retrieved (as observed), predicted (any instant), exported.

use crate::context::Context;
use crate::error::ConvertError;
use crate::inputs::{manifest_text, SeriesInput, MANIFEST_NAME};
use crate::outputs::{refuse_non_empty_dir, refuse_overwriting_input};
use crate::progress::Progress;
use crate::series_file::SeriesRead;
use crate::time::{check_range, parse_time, read_time, Zone};
use froctomap_core::calendar::iso8601_basic;
use froctomap_core::{
    defaults, log_odds, write_atomically, Leaf, MortonCode, Occupancy, Snapshot, Timestamp,
};
use froctomap_formats::{Backend, MapFormat, RecordingWriteOptions, WriteOptions};
use froctomap_octomap_codec::{CanonicalBinaryBuilder, EncodeError};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// A time as a user gives it for `retrieve`/`predict`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeQuery {
    /// An instant.
    Instant(Timestamp),
    /// A sample index of the file's time axis.
    Sample(u32),
    /// A sample counted back from the end of the axis: 1 is the last (`index:-1`, `last`).
    FromEnd(u32),
}

impl std::str::FromStr for TimeQuery {
    type Err = ConvertError;

    /// `index:42` is a sample index, `index:-1` (or `last`) the last sample; anything else
    /// is Unix seconds or ISO 8601.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        if text.trim().eq_ignore_ascii_case("last") {
            return Ok(TimeQuery::FromEnd(1));
        }
        if let Some(index) = text.trim().strip_prefix("index:") {
            let bad = || ConvertError::BadSampleIndex {
                text: text.to_string(),
            };
            return match index.trim().strip_prefix('-') {
                Some(back) => match back.parse() {
                    Ok(0) | Err(_) => Err(bad()),
                    Ok(back) => Ok(TimeQuery::FromEnd(back)),
                },
                None => index
                    .trim()
                    .parse()
                    .map(TimeQuery::Sample)
                    .map_err(|_| bad()),
            };
        }
        Ok(TimeQuery::Instant(parse_time(text)?))
    }
}

impl TimeQuery {
    /// [`str::parse`], reading a time without zone in `zone`; the flag says whether it had
    /// none.
    pub fn read(text: &str, zone: &Zone) -> Result<(Self, bool), ConvertError> {
        if text.trim().starts_with("index:") || text.trim().eq_ignore_ascii_case("last") {
            return text.parse().map(|query| (query, false));
        }
        let read = read_time(text, zone)?;
        Ok((TimeQuery::Instant(read.time), read.zoneless))
    }
}

/// A snapshot sample chosen for a retrieval.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ResolvedSample {
    /// The sample.
    pub sample: u32,
    /// Its time.
    pub time: Timestamp,
    /// `false` when the query fell between samples and the last earlier one was taken.
    pub exact: bool,
}

/// Which snapshot an instant between snapshots takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Pick {
    /// The last snapshot at or before it: the map as it was known then (the default).
    #[default]
    AtOrBefore,
    /// The closest snapshot, earlier or later (the earlier on a tie); an instant before
    /// the first snapshot takes the first.
    Nearest,
}

/// The sample of the map as observed at `query`: the sample itself, or the last snapshot at
/// or before an instant. Instants before the first snapshot, sample indices beyond the axis
/// and samples without a snapshot are errors.
pub fn resolve_observed(
    reader: &dyn SeriesRead,
    query: TimeQuery,
) -> Result<ResolvedSample, ConvertError> {
    resolve_observed_with(reader, query, Pick::AtOrBefore)
}

/// [`resolve_observed`], choosing between snapshots by `pick`.
pub fn resolve_observed_with(
    reader: &dyn SeriesRead,
    query: TimeQuery,
    pick: Pick,
) -> Result<ResolvedSample, ConvertError> {
    let samples = reader.sample_count();
    let t = match query {
        TimeQuery::Instant(t) => t,
        TimeQuery::Sample(sample) => return stored_sample(reader, sample),
        TimeQuery::FromEnd(back) => {
            let sample = samples
                .checked_sub(back)
                .ok_or(ConvertError::SampleBeforeAxis {
                    back,
                    samples,
                    start: reader.first_instant(),
                    end: reader.last_instant(),
                })?;
            return stored_sample(reader, sample);
        }
    };
    let before = reader.sample_at_or_before(t);
    if let Some(sample) = before.filter(|&s| reader.sample_time(s) == Some(t)) {
        return Ok(ResolvedSample {
            sample,
            time: t,
            exact: true,
        });
    }
    let after = || {
        let mut i = before.map_or(0, |b| b.saturating_add(1));
        while i < samples && reader.is_missing(i) {
            i += 1;
        }
        (i < samples).then_some(i)
    };
    let sample = match (pick, before) {
        (Pick::AtOrBefore, before) => before,
        (Pick::Nearest, None) => after(),
        (Pick::Nearest, Some(before)) => Some(match after() {
            Some(after) => {
                let distance = |s: u32| {
                    reader
                        .sample_time(s)
                        .map(|u| (i128::from(u.0) - i128::from(t.0)).abs())
                };
                if distance(after) < distance(before) {
                    after
                } else {
                    before
                }
            }
            None => before,
        }),
    }
    .ok_or_else(|| ConvertError::BeforeFirstSnapshot {
        path: reader.path().to_path_buf(),
        time: t,
        first: (0..samples)
            .find(|&s| !reader.is_missing(s))
            .and_then(|s| reader.sample_time(s)),
        start: reader.first_instant(),
        end: reader.last_instant(),
    })?;
    let time = reader.sample_time(sample).unwrap_or(t);
    Ok(ResolvedSample {
        sample,
        time,
        exact: false,
    })
}

/// A sample asked for by index: it must lie on the axis and hold a snapshot.
fn stored_sample(reader: &dyn SeriesRead, sample: u32) -> Result<ResolvedSample, ConvertError> {
    let time = reader
        .sample_time(sample)
        .ok_or(ConvertError::SampleBeyondAxis {
            sample,
            samples: reader.sample_count(),
            start: reader.first_instant(),
            end: reader.last_instant(),
        })?;
    if reader.is_missing(sample) {
        return Err(ConvertError::NoSnapshotAtSample { sample, time });
    }
    Ok(ResolvedSample {
        sample,
        time,
        exact: true,
    })
}

/// The map as observed at a sample (exact in lossless files): one leaf per observed cell,
/// in Morton order. Tiles are streamed in parallel without building cells; call
/// [`Snapshot::canonical`] (or [`write_map`], which does) for OctoMap's split.
pub fn observed_map(reader: &dyn SeriesRead, sample: u32) -> Result<Snapshot, ConvertError> {
    let tiles: Vec<usize> = reader
        .observed_tiles(sample)
        .iter()
        .map(|t| t.cell_count as usize)
        .collect();
    collect_tiles(reader, &tiles, |tile, out| {
        reader.visit_observed(sample, tile, &mut |start, depth, state| {
            out.push(Leaf {
                start,
                depth,
                log_odds: state.log_odds(),
            })
        })
    })
}

/// The predicted map at any instant: every cell with log-odds of its probability `p(t)`
/// ([`probability_log_odds`]), in Morton order, tiles streamed in parallel.
pub fn predicted_map(reader: &dyn SeriesRead, t: Timestamp) -> Result<Snapshot, ConvertError> {
    let seconds = t.secs_since(reader.header().axis.start());
    let tiles = reader.predicted_tiles();
    let cells: Vec<usize> = tiles.iter().map(|&(_, cells)| cells).collect();
    collect_tiles(reader, &cells, |tile, out| {
        reader.predicted_leaves(tiles[tile].0, seconds, &probability_log_odds, out)
    })
}

/// The most leaves of a whole map [`collect_tiles`] reserves before seeing them (256 MiB of
/// leaves); the default read limits allow 2^26 cells in a file.
const MAX_LEAVES_HINT: usize = 1 << 24;
/// The most leaves of one tile [`collect_tiles`] reserves before seeing them.
const MAX_TILE_LEAVES_HINT: usize = 1 << 20;

/// The leaves of tiles `0..cells.len()` (each with at most about `cells[i]` leaves) in
/// order.
fn collect_tiles(
    reader: &dyn SeriesRead,
    cells: &[usize],
    leaves_of: impl Fn(usize, &mut Vec<Leaf>) -> Result<(), froctomap_file::FileError> + Sync,
) -> Result<Snapshot, ConvertError> {
    // A tile yields at most one leaf per cell, so every buffer is sized once: growing them
    // (copies and fresh pages) cost more than the walk itself on large maps. The counts are
    // only hints: a 2.0 file's predicted tile sums the base's and every segment's count, each
    // bounded alone by the reader's limits, so a hostile file's sum can reach 2^42; the hints
    // are clamped, and a larger map grows its buffers. Tiles are decoded a few at a time so
    // that the map is held once, not twice.
    let total = cells
        .iter()
        .fold(0usize, |sum, &count| sum.saturating_add(count));
    let mut leaves: Vec<Leaf> = Vec::with_capacity(total.min(MAX_LEAVES_HINT));
    let chunk = 4 * rayon::current_num_threads().max(1);
    for (first, counts) in cells.chunks(chunk).enumerate() {
        let per_tile = counts
            .par_iter()
            .enumerate()
            .map(|(i, &count)| {
                let mut out = Vec::with_capacity(count.min(MAX_TILE_LEAVES_HINT));
                leaves_of(first * chunk + i, &mut out).map(|()| out)
            })
            .collect::<Result<Vec<_>, _>>()?;
        for tile_leaves in per_tile {
            leaves.extend_from_slice(&tile_leaves);
        }
    }
    Snapshot::from_leaves(reader.header().resolution, leaves)
        .map_err(|e| inconsistent_cells(reader, e))
}

/// A file whose cells do not make a map (overlapping, out of order): only a damaged or
/// foreign writer's file gets past the reader's checks this way.
fn inconsistent_cells(
    reader: &dyn SeriesRead,
    e: impl std::error::Error + Send + Sync + 'static,
) -> ConvertError {
    ConvertError::InconsistentCells {
        path: reader.path().to_path_buf(),
        source: Box::new(e),
    }
}

/// Log-odds for a predicted probability: clamped to OctoMap's bounds, and strictly negative
/// at `p ≤ 0.5` (OctoMap calls log-odds 0 occupied; froctomap's threshold is `p > 0.5`).
pub fn probability_log_odds(p: f64) -> f32 {
    let clamped = p.clamp(defaults::CLAMPING_MIN, defaults::CLAMPING_MAX);
    let value = log_odds(clamped);
    if p > 0.5 {
        value.max(f32::MIN_POSITIVE)
    } else {
        value.min(-f32::MIN_POSITIVE)
    }
}

/// Writes a map to `path` in the format of `context` that its extension (or
/// `options.format`) names, atomically, in the canonical split ([`Snapshot::canonical`]). A
/// format that stores states only (`.bt`, [`Capabilities::states_only`]) gets the map
/// reduced to maximum likelihood first. [`write_owned_map`] does the same without copying
/// the map.
///
/// [`Capabilities::states_only`]: froctomap_formats::Capabilities::states_only
pub fn write_map(
    context: &Context,
    snapshot: &Snapshot,
    path: &Path,
    options: WriteOptions<'_>,
) -> Result<WrittenMap, ConvertError> {
    write_owned_map(context, snapshot.clone(), path, options)
}

/// [`write_map`] of a map no longer needed, reduced and merged in place.
pub fn write_owned_map(
    context: &Context,
    snapshot: Snapshot,
    path: &Path,
    options: WriteOptions<'_>,
) -> Result<WrittenMap, ConvertError> {
    let registry = context.formats();
    let chosen = *registry
        .output_format(path, options)
        .map_err(ConvertError::Write)?;
    let canonical = if chosen.capabilities.states_only {
        snapshot.into_max_likelihood().into_canonical()
    } else {
        snapshot.into_canonical()
    };
    let format = registry
        .write_file(&canonical, path, options)
        .map_err(ConvertError::Write)?;
    Ok(WrittenMap {
        format,
        leaves: canonical.leaves().len(),
    })
}

/// Writes the map as observed at `sample` to `path` (as [`write_owned_map`] of
/// [`observed_map`] would). An output format whose writer gives the canonical OctoMap
/// binary ([`Capabilities::writes_canonical_binary`], the native `.bt`) is built tile by
/// tile in parallel straight from the cells' states, without the map in memory.
///
/// [`Capabilities::writes_canonical_binary`]: froctomap_formats::Capabilities::writes_canonical_binary
pub fn write_observed_map(
    context: &Context,
    reader: &dyn SeriesRead,
    sample: u32,
    path: &Path,
    options: WriteOptions<'_>,
) -> Result<WrittenMap, ConvertError> {
    write_query(
        context,
        reader,
        StateQuery::Observed(sample),
        path,
        options,
        || observed_map(reader, sample),
    )
}

/// Writes the map predicted for `t` to `path` (as [`write_owned_map`] of [`predicted_map`]
/// would), a native `.bt` tile by tile as [`write_observed_map`] does.
pub fn write_predicted_map(
    context: &Context,
    reader: &dyn SeriesRead,
    t: Timestamp,
    path: &Path,
    options: WriteOptions<'_>,
) -> Result<WrittenMap, ConvertError> {
    let seconds = t.secs_since(reader.header().axis.start());
    write_query(
        context,
        reader,
        StateQuery::Predicted(seconds),
        path,
        options,
        || predicted_map(reader, t),
    )
}

/// The tiled canonical-binary writer where the output format allows it, else the map
/// `whole` builds, written whole.
fn write_query(
    context: &Context,
    reader: &dyn SeriesRead,
    query: StateQuery,
    path: &Path,
    options: WriteOptions<'_>,
    whole: impl FnOnce() -> Result<Snapshot, ConvertError>,
) -> Result<WrittenMap, ConvertError> {
    refuse_overwriting_input(path, [reader.path()])?;
    let chosen = *context
        .formats()
        .output_format(path, options)
        .map_err(ConvertError::Write)?;
    if chosen.capabilities.writes_canonical_binary {
        write_states_bt(reader, chosen, path, query)
    } else {
        write_owned_map(context, whole()?, path, options)
    }
}

/// Which states of the cells a `.bt` is written from.
#[derive(Clone, Copy)]
enum StateQuery {
    /// As observed at a sample.
    Observed(u32),
    /// As predicted at this many seconds after the first sample.
    Predicted(f64),
}

/// The canonical `.bt` of the cells' states: each tile's subtree built on its own thread
/// ([`CanonicalBinaryBuilder`]), then joined under the root and written atomically.
fn write_states_bt(
    reader: &dyn SeriesRead,
    format: MapFormat,
    path: &Path,
    query: StateQuery,
) -> Result<WrittenMap, ConvertError> {
    let (bytes, leaves) = states_bt(reader, query)?;
    write_atomically(path, |out| out.write_all(&bytes))?;
    Ok(WrittenMap { format, leaves })
}

/// The canonical `.bt` file of the cells' states and its leaf count, built tile by tile in
/// parallel.
fn states_bt(reader: &dyn SeriesRead, query: StateQuery) -> Result<(Vec<u8>, usize), ConvertError> {
    let inconsistent = |e: EncodeError| inconsistent_cells(reader, e);
    let tile_depth = reader.header().tile_depth;
    let tiles: Vec<MortonCode> = match query {
        StateQuery::Observed(sample) => reader
            .observed_tiles(sample)
            .iter()
            .map(|t| t.code)
            .collect(),
        StateQuery::Predicted(_) => reader
            .predicted_tiles()
            .into_iter()
            .map(|(code, _)| code)
            .collect(),
    };
    let parts = tiles
        .par_iter()
        .enumerate()
        .map(|(tile, &code)| {
            let mut builder =
                CanonicalBinaryBuilder::new(code, tile_depth).map_err(inconsistent)?;
            let mut refused = None;
            let mut push = |start: MortonCode, depth: u8, state: Occupancy| {
                if refused.is_none() {
                    if let Err(e) = builder.push_state(start, depth, state.is_occupied()) {
                        refused = Some(e);
                    }
                }
            };
            match query {
                StateQuery::Observed(sample) => reader.visit_observed(sample, tile, &mut push),
                StateQuery::Predicted(seconds) => reader.visit_predicted(code, seconds, &mut push),
            }?;
            match refused {
                Some(e) => Err(inconsistent(e)),
                None => Ok(builder.finish()),
            }
        })
        .collect::<Result<Vec<_>, ConvertError>>()?;
    let mut root = CanonicalBinaryBuilder::new(MortonCode(0), 0).map_err(inconsistent)?;
    for part in parts {
        root.push_part(part).map_err(inconsistent)?;
    }
    let whole = root.finish();
    let leaves = usize::try_from(whole.leaves()).unwrap_or(usize::MAX);
    let bytes = whole
        .into_file(reader.header().resolution)
        .map_err(inconsistent)?;
    Ok((bytes, leaves))
}

/// The canonical `.bt` file of the map observed at `sample` (the bytes
/// [`write_observed_map`] writes to a `.bt`), in memory: what the ROS 2 node's
/// `get_octomap_at` service answers.
pub fn observed_bt(reader: &dyn SeriesRead, sample: u32) -> Result<Vec<u8>, ConvertError> {
    states_bt(reader, StateQuery::Observed(sample)).map(|(bytes, _)| bytes)
}

/// The canonical `.bt` file of the map predicted for `t` (the bytes
/// [`write_predicted_map`] writes to a `.bt`), in memory: what the ROS 2 node publishes.
pub fn predicted_bt(reader: &dyn SeriesRead, t: Timestamp) -> Result<Vec<u8>, ConvertError> {
    let seconds = t.secs_since(reader.header().axis.start());
    states_bt(reader, StateQuery::Predicted(seconds)).map(|(bytes, _)| bytes)
}

/// What [`write_map`] wrote.
#[derive(Clone, Copy, Debug)]
pub struct WrittenMap {
    /// The format.
    pub format: MapFormat,
    /// Leaves in the file.
    pub leaves: usize,
}

/// What `export` produces at each instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ExportMode {
    /// The predicted map (any instant).
    #[default]
    Predict,
    /// The last observed snapshot at or before the instant: each snapshot once, named and
    /// listed in the manifest at its own time.
    Retrieve,
    /// Retrieved inside the file's span (as [`Retrieve`](Self::Retrieve)), predicted
    /// outside it.
    Auto,
}

/// Settings of an export.
#[derive(Clone, Debug)]
pub struct ExportOptions {
    /// First instant.
    pub from: Timestamp,
    /// Last instant, inclusive: a map is made at `to` when it lies on the grid
    /// `from + i · every`.
    pub to: Timestamp,
    /// Nanoseconds between instants.
    pub every_ns: i64,
    /// Predicted or retrieved maps.
    pub mode: ExportMode,
    /// Output format name: a writable map format of the context (e.g. `bt` or `ot`, one file
    /// per map in a directory) or a recording format that can be written (e.g. `mcap`, one
    /// file holding every map).
    pub format: String,
    /// Preferred writer implementation.
    pub backend: Option<Backend>,
    /// File name prefix.
    pub prefix: String,
    /// Write into a directory that already holds files (replacing those of the same names);
    /// otherwise such a directory is refused.
    pub overwrite: bool,
    /// How a recording format writes (its profile…); unused by map formats.
    pub recording: RecordingWriteOptions,
}

/// What `export` wrote.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct ExportReport {
    /// Maps and their instants, in time order (for a recording, each map's path is the
    /// recording's).
    pub files: Vec<SeriesInput>,
    /// The manifest (`path,time`), which `build` accepts; `None` for a recording, which
    /// holds its maps' times itself.
    pub manifest: Option<PathBuf>,
    /// Bytes written.
    pub bytes: u64,
}

/// Writes one map per instant of `from..=to` (every `every_ns`): into `output`, a directory
/// (missing or empty, unless [`ExportOptions::overwrite`]), one file per map, each written
/// atomically, then a manifest; or, when [`ExportOptions::format`] names a recording format
/// of the context that can be written ([`RecordingFormat::create`], e.g. `mcap`), into
/// `output` as one recording, written atomically, one map at a time. A failure leaves only
/// complete files behind. At most [`Limits::max_exports`](crate::Limits) maps are written.
///
/// [`RecordingFormat::create`]: froctomap_formats::RecordingFormat::create
pub fn export(
    context: &Context,
    reader: &dyn SeriesRead,
    output: &Path,
    options: &ExportOptions,
    progress: &dyn Progress,
) -> Result<ExportReport, ConvertError> {
    let (times, samples) = export_instants(context, reader, options)?;
    if let Some(format) = context.formats().writable_recording(&options.format) {
        return crate::recording_export::export_recording(
            reader,
            output,
            format,
            &options.recording,
            &times,
            &samples,
            progress,
        );
    }
    let dir = output;
    let format = context
        .formats()
        .by_name(&options.format, options.backend)
        .map_err(ConvertError::Write)?;
    refuse_non_empty_dir(dir, options.overwrite)?;
    std::fs::create_dir_all(dir).map_err(|source| froctomap_core::AtomicWriteError {
        path: dir.to_path_buf(),
        source,
    })?;
    let extension = format.extensions.first().copied().unwrap_or(format.name);
    progress.stage("exporting maps", times.len() as u64);
    let write_one = |(&t, sample): (&Timestamp, &Option<u32>)| {
        crate::progress::stop_if_cancelled(progress)?;
        let path = dir.join(format!(
            "{}_{}.{extension}",
            options.prefix,
            iso8601_basic(t)
        ));
        let write = WriteOptions {
            format: Some(options.format.as_str()),
            backend: options.backend,
        };
        match sample {
            Some(s) => write_observed_map(context, reader, *s, &path, write)?,
            None => write_predicted_map(context, reader, t, &path, write)?,
        };
        let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
        progress.advance(1);
        Ok((SeriesInput::new(path, t), bytes))
    };
    // A format written tile by tile holds little of each map, so maps are made in
    // parallel; others hold a whole map while writing it, so one map at a time (each built
    // from tiles in parallel) keeps memory at one map.
    let files: Vec<(SeriesInput, u64)> = if format.capabilities.writes_canonical_binary {
        times
            .par_iter()
            .zip(samples.par_iter())
            .map(write_one)
            .collect::<Result<_, ConvertError>>()?
    } else {
        times
            .iter()
            .zip(samples.iter())
            .map(write_one)
            .collect::<Result<_, ConvertError>>()?
    };
    let bytes = files.iter().map(|(_, b)| b).sum();
    let files: Vec<SeriesInput> = files.into_iter().map(|(f, _)| f).collect();
    let manifest = dir.join(MANIFEST_NAME);
    let text = manifest_text(dir, &files);
    write_atomically(&manifest, |out| out.write_all(text.as_bytes()))?;
    Ok(ExportReport {
        files,
        manifest: Some(manifest),
        bytes,
    })
}

/// The instants of an export and, for each, the sample retrieved there (`None`: predicted).
/// Retrieval takes each snapshot once, at its own time (instants between snapshots would
/// otherwise give the same map again under other times).
type Instants = (Vec<Timestamp>, Vec<Option<u32>>);

fn export_instants(
    context: &Context,
    reader: &dyn SeriesRead,
    options: &ExportOptions,
) -> Result<Instants, ConvertError> {
    for (what, t) in [("from", options.from), ("to", options.to)] {
        check_range(what, t)?;
    }
    if options.to < options.from {
        return Err(ConvertError::EmptyRange {
            from: options.from,
            to: options.to,
        });
    }
    if options.every_ns <= 0 {
        return Err(ConvertError::NonPositiveInterval);
    }
    let count =
        (i128::from(options.to.0) - i128::from(options.from.0)) / i128::from(options.every_ns) + 1;
    let limit = context.limits().max_exports;
    if count > i128::from(limit) {
        return Err(ConvertError::TooManyMaps { count, limit });
    }
    let (start, end) = (reader.first_instant(), reader.last_instant());
    let mut instants: Vec<(Timestamp, Option<u32>)> = Vec::with_capacity(count as usize);
    for i in 0..count as i64 {
        let t = Timestamp(options.from.0 + i * options.every_ns);
        let retrieve = match options.mode {
            ExportMode::Predict => false,
            ExportMode::Retrieve => true,
            ExportMode::Auto => start <= t && t <= end,
        };
        if !retrieve {
            instants.push((t, None));
            continue;
        }
        let r = resolve_observed(reader, TimeQuery::Instant(t))?;
        if instants
            .last()
            .is_none_or(|&(_, last)| last != Some(r.sample))
        {
            instants.push((r.time, Some(r.sample)));
        }
    }
    Ok(instants.into_iter().unzip())
}

#[cfg(test)]
mod query_tests {
    use super::*;

    #[test]
    fn sample_queries_count_from_either_end() {
        assert_eq!(
            "index:3".parse::<TimeQuery>().unwrap(),
            TimeQuery::Sample(3)
        );
        assert_eq!(
            "index:-1".parse::<TimeQuery>().unwrap(),
            TimeQuery::FromEnd(1)
        );
        assert_eq!("LAST".parse::<TimeQuery>().unwrap(), TimeQuery::FromEnd(1));
        assert_eq!(
            " index:-12 ".parse::<TimeQuery>().unwrap(),
            TimeQuery::FromEnd(12)
        );
        for bad in ["index:-0", "index:", "index:-x", "index:1.5"] {
            let err = bad.parse::<TimeQuery>().unwrap_err();
            assert!(
                matches!(err, ConvertError::BadSampleIndex { .. }),
                "{bad}: {err}"
            );
        }
        let (query, zoneless) = TimeQuery::read("last", &Zone::utc()).unwrap();
        assert_eq!((query, zoneless), (TimeQuery::FromEnd(1), false));
    }
}

#[cfg(test)]
mod collect_tests {
    use super::*;

    /// A 2.0 file's predicted tiles sum the cell counts of the base and every segment, each
    /// bounded alone: a hostile file's sums must not become one allocation.
    #[test]
    fn cell_count_hints_beyond_memory_allocate_nothing_huge() {
        let golden =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/froct/golden-v2.0.froct");
        let reader = crate::FroctFile::open(&golden).unwrap();
        let hints = [1usize << 42, usize::MAX, 1 << 40];
        // Before the clamp, reserving the sum aborted the process (capacity overflow).
        let map = collect_tiles(&reader, &hints, |_, _| Ok(())).unwrap();
        assert!(map.is_empty());
    }
}
