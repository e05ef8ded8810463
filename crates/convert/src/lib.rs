//! Converters between OctoMap series and FROctomap files — the library behind every
//! `froctomap` command.
//!
//! * [`collect_inputs`] turns directories, globs, manifests and files into a time-sorted
//!   series; [`build`] streams it into one FROctomap file (memory grows with the map's cells
//!   and their changes, not with the number of snapshots).
//! * [`observed_map`] gives the map as observed at a sample (bit-exact in lossless files),
//!   [`predicted_map`] the predicted map at any instant, both streaming the file's tiles in
//!   parallel; [`write_map`] writes either as `.bt`/`.ot` atomically; [`export`] writes a
//!   range of them with a manifest. [`LoadedMap`] decodes every cell once, for evaluation.
//! * [`evaluate`] compares a file with ground-truth maps against the static-mean and
//!   last-seen baselines; [`describe`] summarises a file.
//!
//! ```no_run
//! use froctomap_convert::*;
//! use froctomap_formats::FormatRegistry;
//! use std::path::{Path, PathBuf};
//!
//! let registry = FormatRegistry::with_default_formats();
//! let series = collect_inputs(&[PathBuf::from("maps/")], TimeSource::Auto, &registry)?;
//! let report = build(&series, Path::new("office.froct"), &BuildOptions::default(), &Silent)?;
//! println!("{} snapshots → {} bytes", report.used, report.file_bytes);
//!
//! let reader = froctomap_file::FroctReader::open(Path::new("office.froct"))?;
//! let when = resolve_observed(&reader, "2016-01-05T12:00:00Z".parse()?)?;
//! write_map(&observed_map(&reader, when.sample)?, Path::new("noon.bt"), None, None)?;
//! write_map(&predicted_map(&reader, parse_time("2016-02-01T12:00:00Z")?)?, Path::new("future.ot"), None, None)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod build;
mod error;
mod eval;
mod history;
mod info;
mod inputs;
mod maps;
mod progress;
mod snapshot_changes;
mod text;
mod time;

pub use build::{axis_for_times, build, BuildOptions, BuildReport, ClassCounts};
pub use error::ConvertError;
pub use eval::{evaluate, ErrorRates, EvalReport, Rate, METHODS};
pub use froctomap_core::calendar::unix_seconds;
pub use history::SeriesHistory;
pub use info::{describe, AxisInfo, FroctInfo, SizeInfo};
pub use inputs::{collect_inputs, manifest_text, SeriesInput, TimeSource, MANIFEST_NAME};
pub use maps::{
    export, observed_map, predicted_map, probability_log_odds, resolve_observed, write_map,
    write_observed_map, write_owned_map, write_predicted_map, ExportMode, ExportOptions,
    ExportReport, LoadedMap, ResolvedSample, TimeQuery, WrittenMap, MAX_EXPORTS,
};
pub use progress::{Progress, Silent};
pub use text::group_thousands;
pub use time::{
    check_range, format_compact, format_iso, parse_duration, parse_time, time_from_file_name,
    TimeError, EARLIEST, LATEST,
};
