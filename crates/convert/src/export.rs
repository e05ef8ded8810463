//! `export`: maps of a FROctomap file at a range of instants, into a directory of map files
//! (with a manifest that `build` accepts) or into one recording; above both `maps`
//! (which makes each map) and `recording_export` (which writes a recording).

use crate::context::Context;
use crate::error::ConvertError;
use crate::inputs::{manifest_text, SeriesInput, MANIFEST_NAME};
use crate::maps::{resolve_observed, write_observed_map, write_predicted_map, TimeQuery};
use crate::outputs::refuse_non_empty_dir;
use crate::progress::Progress;
use crate::series_file::SeriesRead;
use crate::time::check_range;
use froctomap_core::calendar::iso8601_basic;
use froctomap_core::{write_atomically, Timestamp};
use froctomap_formats::{Backend, RecordingWriteOptions, WriteOptions};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

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

impl froctomap_core::Named for ExportMode {
    const ALL: &'static [Self] = &[Self::Predict, Self::Retrieve, Self::Auto];
    const WHAT: &'static str = "export mode";

    fn name(self) -> &'static str {
        match self {
            Self::Predict => "predict",
            Self::Retrieve => "retrieve",
            Self::Auto => "auto",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Self::Predict => "Predicted maps (any instant)",
            Self::Retrieve => "The last observed snapshot at or before each instant",
            Self::Auto => "Retrieved inside the file's span, predicted outside it",
        }
    }
}

impl std::fmt::Display for ExportMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(froctomap_core::Named::name(*self))
    }
}

impl std::str::FromStr for ExportMode {
    type Err = froctomap_core::UnknownName;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        froctomap_core::parse_named(name)
    }
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
    /// file holding every map, or `ros2bag`, a new directory holding them).
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
/// of the context that can be written ([`RecordingFormat::create`], e.g. `mcap`, or
/// [`RecordingFormat::create_dir`], e.g. `ros2bag`, whose `output` must not exist), into
/// `output` as one recording, written atomically, one map at a time. A failure leaves only
/// complete files behind. At most [`Limits::max_exports`](crate::Limits) maps are written.
///
/// [`RecordingFormat::create`]: froctomap_formats::RecordingFormat::create
/// [`RecordingFormat::create_dir`]: froctomap_formats::RecordingFormat::create_dir
pub fn export(
    context: &Context,
    reader: &dyn SeriesRead,
    output: &Path,
    options: &ExportOptions,
    progress: &dyn Progress,
) -> Result<ExportReport, ConvertError> {
    let recording = context.formats().writable_recording(&options.format);
    if froctomap_core::is_stream_output(output) && recording.is_none_or(|f| f.create.is_none()) {
        return Err(ConvertError::StreamNotADirectory {
            path: output.to_path_buf(),
            format: options.format.clone(),
        });
    }
    let (times, samples) = export_instants(context, reader, options)?;
    if let Some(format) = recording {
        let (files, bytes) = crate::recording_export::export_recording(
            reader,
            output,
            format,
            &options.recording,
            &times,
            &samples,
            progress,
        )?;
        return Ok(ExportReport {
            files,
            manifest: None,
            bytes,
        });
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
    let files: Vec<(SeriesInput, u64)> = if format.states_tiled_writer().is_some() {
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
