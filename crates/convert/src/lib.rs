//! Converters between OctoMap series and FROctomap files — the library behind every
//! `froctomap` command.
//!
//! * [`collect_inputs`] turns directories, globs, manifests and files into a time-sorted
//!   series; [`ingest`] streams it into a FROctomap file: a new one ([`build`]; memory grows
//!   with the map's cells and their changes, not with the number of snapshots), or an
//!   existing one, from the file and the new snapshots alone ([`append`]: rewritten and
//!   refitted; [`append_segment`]: one format 2.0 segment).
//! * [`observed_map`] gives the map as observed at a sample (bit-exact in lossless files),
//!   [`predicted_map`] the predicted map at any instant, both streaming the file's tiles in
//!   parallel; [`write_map`] writes either as `.bt`/`.ot` atomically; [`export`] writes a
//!   range of them with a manifest.
//! * [`Context::open_series`] opens a file of any version as a [`FroctFile`] (1.x, or 2.0:
//!   a base and committed segments, [`FroctFile::refresh`] to see new commits); the queries
//!   above take its [`SeriesRead`] view. [`compact`] rewrites a 2.0 file's base and
//!   segments as one base, equal to a build of the same maps. A [`Recorder`] adds maps
//!   one at a time as they arrive, committing a segment every so many maps or seconds.
//! * [`evaluate`] compares a file with ground-truth maps against the static-mean and
//!   last-seen baselines, a tile at a time; [`describe`] summarises a file
//!   ([`describe_series`] any version). Whole-history analyses read one body of cells
//!   ([`FroctFile::whole_history`]).
//!
//! Every entry point takes a [`Context`]: the registries of map formats and temporal models
//! and the limits a program chose, built once (binaries and tests start from
//! [`Context::with_default_plugins`]) and handed in, so that a format or model the program
//! registers reaches every path. Progress is reported per call.
//!
//! ```no_run
//! use froctomap_convert::*;
//! use froctomap_formats::WriteOptions;
//! use std::path::{Path, PathBuf};
//!
//! let context = Context::with_default_plugins();
//! let series = collect_inputs(&context, &[PathBuf::from("maps/")], TimeSource::Auto)?;
//! let report = build(&context, &series, Path::new("office.froct"), &BuildOptions::default(), &Silent)?;
//! println!("{} snapshots → {} bytes", report.used, report.file_bytes);
//!
//! let reader = froctomap_file::FroctReader::open(Path::new("office.froct"))?;
//! let when = resolve_observed(&reader, "2016-01-05T12:00:00Z".parse()?)?;
//! write_map(&context, &observed_map(&reader, when.sample)?, Path::new("noon.bt"), WriteOptions::default())?;
//! let later = predicted_map(&reader, parse_time("2016-02-01T12:00:00Z")?)?;
//! write_map(&context, &later, Path::new("future.ot"), WriteOptions::default())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod anomaly;
mod background_compaction;
mod build;
mod compact;
mod context;
mod dynamics;
mod error;
mod eval;
mod export;
mod files;
mod glob_walk;
mod history;
mod info;
mod inputs;
mod maps;
mod outputs;
mod progress;
mod query;
mod record;
mod recording;
mod recording_export;
mod series_file;
mod skip;
mod snapshot_changes;
mod text;
mod time;

pub use anomaly::{
    anomalies, read_snapshot, AnomalyKind, AnomalyOptions, AnomalyRegion, AnomalyReport,
    Expectation,
};
pub use build::{
    append, append_living, append_segment, axis_for_times, build, ingest,
    refuse_growing_fixed_span, AppendOptions, AppendReport, BuildOptions, BuildReport, ClassCounts,
    Extended, IngestInputs, IngestOptions, IngestReport, IngestTarget, DEFAULT_BUILD_MEMORY,
};
pub use compact::{
    compact, CompactFormat, CompactOptions, CompactReport, AUTOMATIC_TILE_DEPTH_LIMIT,
    DEFAULT_TILE_BUDGET,
};
pub use context::{Context, Limits, FROCT};
pub use dynamics::{
    key_extent, period_text, summarize_dynamics, CellDynamics, DynamicRegion, DynamicsSummary,
    KeyExtent, MetricBox, PeriodCount,
};
pub use error::{Cause, ConvertError, ManifestProblem, SnapshotError};
pub use eval::{
    evaluate, log_loss, Calibration, CalibrationBin, ErrorRates, EvalReport, Rate,
    CALIBRATION_BINS, LOG_LOSS_EPSILON, METHODS,
};
pub use export::{export, ExportMode, ExportOptions, ExportReport};
pub use files::{is_living_file, output_dir};
pub use froctomap_core::calendar::unix_seconds;
pub use froctomap_formats::{
    natural_cmp, RecordedTime, RecordingOptions, RecordingProfile, RecordingWriteOptions,
};
pub use history::SeriesHistory;
pub use info::{
    describe, describe_map_file, describe_series, format_listing, AxisInfo, FroctInfo, LivingInfo,
    MapFileInfo, MetricBounds, SegmentInfo, SizeInfo, LARGEST_REGIONS,
};
pub use inputs::{
    collect_inputs, collect_inputs_explained, collect_recording, manifest_text, CollectedInputs,
    InputWarning, SeriesInput, TimeOrigin, TimeSource, MANIFEST_NAME, STDIN_INPUT,
};
pub use maps::{observed_bt, predicted_bt};
pub use maps::{
    observed_map, predicted_map, probability_log_odds, resolve_observed, resolve_observed_with,
    write_map, write_observed_map, write_owned_map, write_predicted_map, Pick, ResolvedSample,
    TimeQuery, WrittenMap,
};
pub use outputs::refuse_overwriting_input;
pub use progress::{Progress, Silent};
pub use query::{
    probabilities, probabilities_at_times, series_probabilities, voxel_history, CellClass,
    CellGeometry, HistorySample, VoxelHistory,
};
pub use record::{
    CommitEvery, CommitReport, Compaction, Opened, RecordError, RecordEvent, RecordOptions,
    RecordSummary, Recorder, ADDED_PER_BASE, SEGMENTS_PER_BASE, SEGMENT_LIMIT_SHARE, SPAN_GROWTH,
};
pub use recording::{describe_recording, RecordedMap, RecordedTopicInfo, RecordingInfo};
pub use recording_export::{occupied_cells_above, occupied_cells_at};
pub use series_file::{FroctFile, SeriesRead, StateVisit};
pub use skip::{SkipReason, SkippedInput};
pub use text::{group_thousands, tidy_float, tidy_floats};
pub use time::{
    check_range, parse_duration, parse_time, read_time, read_time_from_file_name,
    time_from_file_name, ReadTime, TimeError, Zone, EARLIEST, EARLIEST_IN_NAME, LATEST,
};
