//! The command line's other verbs as functions: `append`, `compact`, `convert`, `export`,
//! `info` (of any file) and `record`, each a thin layer over the library call the CLI makes,
//! returning the report `--json` prints (as a dict).

use crate::errors::{froct_error_text, message, Failure};
use crate::file::{json_value, report_json};
use crate::progress::{with_progress, SIGNAL_CHECKS};
use crate::series::{build_inputs, duration_ns, model_config_options, series_times, BuildInputs};
use crate::times::instant;
use froctomap_convert::{
    compact as compact_file, describe_map_file, describe_recording, describe_series,
    export as export_maps, ingest, is_living_file, refuse_overwriting_input, AppendReport,
    CollectedInputs, CommitEvery, CompactFormat, CompactOptions, Compaction, ExportMode,
    ExportOptions, IngestOptions, IngestTarget, RecordEvent, RecordOptions, Recorder,
    RecordingProfile, RecordingWriteOptions, SeriesInput, TimeSource, FROCT,
};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_file::ToggleLayout;
use froctomap_formats::{Identified, ReadOptions, WriteOptions};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver};

/// The warnings of collected inputs, as the reports list them.
fn input_warnings(collected: &CollectedInputs) -> Value {
    Value::from(
        collected
            .warnings
            .iter()
            .map(|w| Value::from(w.to_string()))
            .collect::<Vec<_>>(),
    )
}

/// Inputs and their time source, refusing times for maps that carry their own.
fn timed_inputs(
    inputs: &Bound<'_, PyAny>,
    spool_dir: &Path,
    times: TimeSource,
) -> PyResult<BuildInputs> {
    let inputs = build_inputs(inputs, Some(spool_dir))?;
    if matches!(inputs, BuildInputs::Maps(_)) && times != TimeSource::Auto {
        return Err(froct_error_text(
            "inputs: (time, bytes) pairs carry their own times; start/step, times_file and times_from_names apply to files only",
        ));
    }
    Ok(inputs)
}

/// Later snapshots added to a FROctomap file (`froctomap append --json`).
#[pyfunction]
#[pyo3(signature = (file, inputs, *, model_options = None, skip_bad = false, tags = None,
                    appended = None, format_version = None, memory = None, tmp_dir = None,
                    start = None, step = None, times_file = None, times_from_names = false,
                    progress = None))]
#[allow(clippy::too_many_arguments)]
pub fn append<'py>(
    py: Python<'py>,
    file: PathBuf,
    inputs: &Bound<'py, PyAny>,
    model_options: Option<&Bound<'py, PyDict>>,
    skip_bad: bool,
    tags: Option<&Bound<'py, PyDict>>,
    appended: Option<&Bound<'py, PyAny>>,
    format_version: Option<String>,
    memory: Option<u64>,
    tmp_dir: Option<PathBuf>,
    start: Option<&Bound<'py, PyAny>>,
    step: Option<&Bound<'py, PyAny>>,
    times_file: Option<PathBuf>,
    times_from_names: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let segment_asked = match format_version.as_deref() {
        None => false,
        Some("2.0") => true,
        Some(other) => {
            return Err(froct_error_text(format!(
                "format_version {other:?}: append writes \"2.0\" (segments) or, without it, rewrites a 1.x file"
            )))
        }
    };
    let spool_dir = tmp_dir
        .clone()
        .unwrap_or_else(|| froctomap_convert::output_dir(&file).to_path_buf());
    let times = series_times(start, step, times_file, times_from_names)?;
    let inputs = timed_inputs(inputs, &spool_dir, times.clone())?;
    let mut config = froctomap_temporal::ModelConfig::default();
    config.options = model_config_options(model_options)?;
    let options = IngestOptions {
        config,
        skip_bad,
        metadata: crate::series::tags_metadata(tags)?,
        time: appended.map(|t| instant(t, "appended")).transpose()?,
        memory: memory.unwrap_or(froctomap_convert::DEFAULT_BUILD_MEMORY),
        tmp_dir,
        ..IngestOptions::default()
    };
    let context = crate::plugins::context().clone().with_recording_options(
        froctomap_convert::RecordingOptions::default()
            .with_skip_bad(skip_bad)
            .with_spool_dir(Some(spool_dir)),
    );
    let report = with_progress(py, progress, |progress| {
        let collected = inputs.collect(&context, times)?;
        let living = is_living_file(&file)?;
        let target = if living || segment_asked {
            IngestTarget::Segment(&file)
        } else {
            IngestTarget::Rewrite(&file)
        };
        let report = ingest(&context, &collected, target, &options, progress)?;
        let mut value = serde_json::to_value(AppendReport::from(report))?;
        if let Value::Object(map) = &mut value {
            map.insert("input_warnings".into(), input_warnings(&collected));
        }
        report_json(&value)
    })?;
    json_value(py, &report)
}

/// `tile_budget` as the command line takes it: a positive size, or `None`.
fn positive_tile_budget(tile_budget: Option<u64>) -> PyResult<()> {
    match tile_budget {
        Some(0) => Err(froct_error_text(
            "tile_budget: a positive number of bytes, or None",
        )),
        _ => Ok(()),
    }
}

/// A FROctomap file's base and segments rewritten as one base (`froctomap compact --json`).
#[pyfunction]
#[pyo3(signature = (file, output = None, *, format_version = "2.0".to_string(),
                    model_options = None, created = None, memory = None, tmp_dir = None,
                    lossy = false, tile_depth = None,
                    tile_budget = Some(froctomap_convert::DEFAULT_TILE_BUDGET), progress = None))]
#[allow(clippy::too_many_arguments)]
pub fn compact<'py>(
    py: Python<'py>,
    file: PathBuf,
    output: Option<PathBuf>,
    format_version: String,
    model_options: Option<&Bound<'py, PyDict>>,
    created: Option<&Bound<'py, PyAny>>,
    memory: Option<u64>,
    tmp_dir: Option<PathBuf>,
    lossy: bool,
    tile_depth: Option<u8>,
    tile_budget: Option<u64>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    positive_tile_budget(tile_budget)?;
    let layout: Option<fn(u32) -> ToggleLayout> = match format_version.as_str() {
        "2.0" => None,
        "1.2" => Some(ToggleLayout::Coded),
        "1.1" => Some(ToggleLayout::Blocked),
        other => {
            return Err(froct_error_text(format!(
                "format_version {other:?}: expected \"2.0\", \"1.2\" or \"1.1\""
            )))
        }
    };
    let mut options = CompactOptions {
        model_options: model_config_options(model_options)?,
        created: created.map(|t| instant(t, "created")).transpose()?,
        memory: memory.unwrap_or(froctomap_convert::DEFAULT_BUILD_MEMORY),
        tmp_dir,
        lossy,
        tile_depth,
        tile_budget,
        ..CompactOptions::default()
    };
    let report = with_progress(py, progress, |progress| {
        let context = crate::plugins::context();
        options.format = match layout {
            None => CompactFormat::Living,
            Some(layout) => {
                // The base's block length, as the command line keeps it; only the layout
                // changes.
                let opened = context.open_series(&file)?;
                let samples = froctomap_convert::SeriesRead::header(&opened)
                    .toggles
                    .block_len()
                    .unwrap_or(256);
                CompactFormat::Flat(Some(layout(samples)))
            }
        };
        let report = compact_file(context, &file, output.as_deref(), &options, progress)?;
        report_json(&report)
    })?;
    json_value(py, &report)
}

/// One map converted to another format (`froctomap convert`).
#[pyfunction]
#[pyo3(signature = (input, output, *, format = None, input_format = None))]
pub fn convert<'py>(
    py: Python<'py>,
    input: PathBuf,
    output: PathBuf,
    format: Option<String>,
    input_format: Option<String>,
) -> PyResult<Bound<'py, PyAny>> {
    let report = py.detach(|| -> Result<String, Failure> {
        refuse_overwriting_input(&output, [input.as_path()])?;
        let registry = crate::plugins::context().formats();
        let write = WriteOptions {
            format: format.as_deref(),
            backend: None,
        };
        // A bad output name fails before any work, as on the command line.
        registry.output_format(&output, write)?;
        let read = registry.read_file(
            &input,
            ReadOptions {
                format: input_format.as_deref(),
                backend: None,
            },
        )?;
        let written = registry.write_file(&read.map.snapshot, &output, write)?;
        report_json(&json!({
            "input": input,
            "input_format": read.format.name,
            "output": output,
            "output_format": written.name,
            "leaves": read.map.snapshot.leaves().len(),
            "warnings": read.map.warnings,
        }))
    });
    json_value(py, &report?)
}

/// The registered formats (`froctomap formats --json`): a dict per format.
#[pyfunction]
pub fn formats(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    let rows = froctomap_convert::format_listing(crate::plugins::context());
    json_value(py, &report_json(&rows)?)
}

/// Any file described (`froctomap info --json`): a FROctomap file, one map file, or a
/// recording (ROS 1 bag, MCAP file, ROS 2 bag directory: its topics).
#[pyfunction]
#[pyo3(signature = (path, *, count = false, input_format = None))]
pub fn info<'py>(
    py: Python<'py>,
    path: PathBuf,
    count: bool,
    input_format: Option<String>,
) -> PyResult<Bound<'py, PyAny>> {
    let report = py.detach(|| -> Result<String, Failure> {
        let context = crate::plugins::context();
        if input_format.is_none() {
            if let Some(recording) = describe_recording(context, &path)? {
                return report_json(&recording);
            }
            let identified = context
                .formats()
                .identify_file(&path)
                .map_err(froctomap_convert::ConvertError::Read)?;
            if let Some(Identified::Series(format)) = identified {
                if format.name == FROCT.name {
                    let file = context.open_series(&path)?;
                    let info = describe_series(context, &file, count)?;
                    return report_json(&info);
                }
            }
        }
        let info = describe_map_file(
            context,
            &path,
            ReadOptions {
                format: input_format.as_deref(),
                backend: None,
            },
        )?;
        report_json(&info)
    })?;
    json_value(py, &report)
}

/// Maps of a FROctomap file at regular instants (`froctomap export`).
#[pyfunction]
#[pyo3(signature = (file, output, *, start, end, every, mode = "predict".to_string(),
                    format = None, prefix = "map".to_string(), overwrite = false,
                    profile = "ros2".to_string(), frame_id = "map".to_string(),
                    topic_prefix = String::new(), threshold = 0.5, progress = None))]
#[allow(clippy::too_many_arguments)]
pub fn export<'py>(
    py: Python<'py>,
    file: PathBuf,
    output: PathBuf,
    start: &Bound<'py, PyAny>,
    end: &Bound<'py, PyAny>,
    every: &Bound<'py, PyAny>,
    mode: String,
    format: Option<String>,
    prefix: String,
    overwrite: bool,
    profile: String,
    frame_id: String,
    topic_prefix: String,
    threshold: f64,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let profile: RecordingProfile = profile
        .parse()
        .map_err(|e| froct_error_text(format!("profile: {e}")))?;
    let mode: ExportMode = mode
        .parse()
        .map_err(|e| froct_error_text(format!("mode: {e}")))?;
    // `out.mcap`, `out.bag`: the recording format of that extension; else `.bt` files. A
    // ROS 2 bag directory only by `format="ros2bag"`, as `--format ros2bag`.
    let recording = crate::plugins::context()
        .formats()
        .writable_recording_for(&output)
        .map(|f| f.name);
    let options = ExportOptions {
        from: instant(start, "start")?,
        to: instant(end, "end")?,
        every_ns: duration_ns(every)?,
        mode,
        format: format.unwrap_or_else(|| recording.unwrap_or("bt").to_string()),
        backend: None,
        prefix,
        overwrite,
        recording: RecordingWriteOptions::default()
            .with_profile(profile)
            .with_frame_id(frame_id)
            .with_topic_prefix(topic_prefix)
            .with_threshold(threshold),
    };
    let report = with_progress(py, progress, |progress| {
        let context = crate::plugins::context();
        let reader = context.open_series(&file)?;
        let report = export_maps(context, &reader, &output, &options, progress)?;
        let files: Vec<Value> = report
            .files
            .iter()
            .map(|input| json!([input.path, iso8601(input.time)]))
            .collect();
        report_json(&json!({
            "output": output,
            "format": options.format,
            "files": files,
            "manifest": report.manifest,
            "bytes": report.bytes,
        }))
    })?;
    json_value(py, &report)
}

/// What the thread that feeds the recorder sends it.
enum Feed {
    /// A source path (a map file, a directory, a manifest, a recording), collected there.
    Source(PathBuf),
    /// A map's bytes and its time.
    Map(Timestamp, Vec<u8>),
}

/// Maps added to a FROctomap 2.0 file as they come, one segment per `commit_every` maps or
/// seconds (`froctomap record`).
#[pyfunction]
#[pyo3(signature = (file, sources, *, commit_every = None, skip_bad = false,
                    model_options = None, auto_compact = None, memory = None,
                    tmp_dir = None, tile_depth = None,
                    tile_budget = Some(froctomap_convert::DEFAULT_TILE_BUDGET)))]
#[allow(clippy::too_many_arguments)]
pub fn record<'py>(
    py: Python<'py>,
    file: PathBuf,
    sources: &Bound<'py, PyAny>,
    commit_every: Option<&Bound<'py, PyAny>>,
    skip_bad: bool,
    model_options: Option<&Bound<'py, PyDict>>,
    auto_compact: Option<&Bound<'py, PyAny>>,
    memory: Option<u64>,
    tmp_dir: Option<PathBuf>,
    tile_depth: Option<u8>,
    tile_budget: Option<u64>,
) -> PyResult<Bound<'py, PyAny>> {
    if tile_depth.is_some_and(|d| !(1..=16).contains(&d)) {
        return Err(froct_error_text("tile_depth: 1 to 16"));
    }
    positive_tile_budget(tile_budget)?;
    let commit_every = match commit_every {
        None => CommitEvery::default(),
        Some(value) => match value.extract::<usize>() {
            Ok(0) => return Err(froct_error_text("commit_every: at least 1 map")),
            Ok(maps) => CommitEvery::Maps(maps),
            Err(_) => {
                let ns = duration_ns(value)?;
                if ns <= 0 {
                    return Err(froct_error_text("commit_every: a positive duration"));
                }
                CommitEvery::Time(std::time::Duration::from_nanos(ns.unsigned_abs()))
            }
        },
    };
    let spool_dir = tmp_dir
        .clone()
        .unwrap_or_else(|| froctomap_convert::output_dir(&file).to_path_buf());
    let mut options = RecordOptions {
        commit_every,
        append: IngestOptions {
            skip_bad,
            allow_mostly_skipped: true,
            memory: memory.unwrap_or(froctomap_convert::DEFAULT_BUILD_MEMORY),
            tmp_dir,
            tile_depth: tile_depth.unwrap_or(IngestOptions::default().tile_depth),
            ..IngestOptions::default()
        },
        spool_dir: Some(spool_dir.clone()),
        compact: compaction(auto_compact)?,
        tile_budget,
    };
    options.append.config.options = model_config_options(model_options)?;
    let context = crate::plugins::context().clone().with_recording_options(
        froctomap_convert::RecordingOptions::default()
            .with_skip_bad(skip_bad)
            .with_spool_dir(Some(spool_dir)),
    );
    let (sender, feed) = sync_channel::<Feed>(2);
    // Set by Ctrl-C: the recorder ends at once, abandoning a background compaction, as
    // `froctomap record` does at a signal.
    let stop = AtomicBool::new(false);
    let report = std::thread::scope(|scope| -> PyResult<String> {
        let (context, file, stop) = (&context, &file, &stop);
        let worker = scope.spawn(move || run_recorder(context, file, options, feed, stop));
        let fed = feed_recorder(py, sources, &sender);
        if fed
            .as_ref()
            .is_err_and(|e| e.is_instance_of::<PyKeyboardInterrupt>(py))
        {
            stop.store(true, Ordering::SeqCst);
        }
        drop(sender);
        // The end may wait for a compaction: Ctrl-C still reaches Python meanwhile.
        let mut interrupted = None;
        while !worker.is_finished() {
            py.detach(|| std::thread::sleep(SIGNAL_CHECKS));
            if let Err(signal) = py.check_signals() {
                stop.store(true, Ordering::SeqCst);
                interrupted.get_or_insert(signal);
            }
        }
        let recorded = match worker.join() {
            Ok(recorded) => recorded,
            Err(_) => Err(Failure::text(
                "internal error: the recording thread panicked",
            )),
        };
        // A failure of the feed (a bad item, Ctrl-C) is raised after the maps taken before
        // it were committed; the recorder's own failure comes first.
        let recorded = recorded?;
        fed?;
        if let Some(signal) = interrupted {
            return Err(signal);
        }
        Ok(recorded)
    })?;
    json_value(py, &report)
}

/// Hands the items of `sources` to the recorder's thread, one at a time: paths, `(time,
/// bytes)` pairs. Stops at the first bad item, a signal (Ctrl-C), or when the recorder
/// stopped taking.
fn feed_recorder(
    py: Python<'_>,
    sources: &Bound<'_, PyAny>,
    sender: &std::sync::mpsc::SyncSender<Feed>,
) -> PyResult<()> {
    if let Ok(path) = sources.extract::<PathBuf>() {
        let _ = py.detach(|| sender.send(Feed::Source(path)));
        return Ok(());
    }
    for (index, item) in sources.try_iter()?.enumerate() {
        let item = item?;
        let feed = if let Ok(path) = item.extract::<PathBuf>() {
            Feed::Source(path)
        } else {
            let bad = || {
                froct_error_text(format!(
                    "sources[{index}]: expected a path or a (time, bytes) pair"
                ))
            };
            let (time, map): (Bound<'_, PyAny>, Bound<'_, PyAny>) =
                item.extract().map_err(|_| bad())?;
            let map = map.cast::<PyBytes>().map_err(|_| bad())?;
            Feed::Map(
                instant(&time, &format!("sources[{index}]"))?,
                map.as_bytes().to_vec(),
            )
        };
        if py.detach(|| sender.send(feed)).is_err() {
            // The recorder stopped (its error is raised).
            return Ok(());
        }
        py.check_signals()?;
    }
    Ok(())
}

/// `record`'s `auto_compact`: `False` (or `None`), `True`, or `"background"`.
fn compaction(value: Option<&Bound<'_, PyAny>>) -> PyResult<Compaction> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(Compaction::Off);
    };
    if let Ok(on) = value.extract::<bool>() {
        return Ok(if on {
            Compaction::AfterCommit
        } else {
            Compaction::Off
        });
    }
    match value.extract::<String>().as_deref() {
        Ok("background") => Ok(Compaction::Background),
        _ => Err(froct_error_text(
            "auto_compact: False, True or \"background\"",
        )),
    }
}

/// The recorder's thread: takes what the feed sends, commits when due and at the end;
/// returns the summary as JSON text.
fn run_recorder(
    context: &froctomap_convert::Context,
    file: &Path,
    options: RecordOptions,
    feed: Receiver<Feed>,
    stop: &AtomicBool,
) -> Result<String, Failure> {
    let commit_every = options.commit_every;
    let mut recorder = Recorder::open(context, file, options)?;
    let opened = format!("{:?}", recorder.opened()).to_lowercase();
    let events = std::rc::Rc::new(std::cell::RefCell::new(Vec::<Value>::new()));
    let seen = std::rc::Rc::clone(&events);
    recorder.on_event(move |event| {
        let value = match event {
            RecordEvent::Committed(commit) => json!({
                "event": "commit",
                "segment": commit.segment,
                "maps": commit.maps,
                "first": iso8601(commit.first),
                "last": iso8601(commit.last),
                "bytes_before": commit.bytes_before,
                "bytes": commit.bytes,
                "warnings": commit.warnings.iter().map(|(p, w)| format!("{}: {w}", p.display())).collect::<Vec<_>>(),
                "skipped": commit.skipped.iter().map(|s| json!({
                    "path": s.path.display().to_string(),
                    "code": s.code(),
                    "message": s.message,
                })).collect::<Vec<_>>(),
            }),
            RecordEvent::Compacted(report) => json!({
                "event": "compaction",
                "segments_before": report.segments_before,
                "bytes_before": report.bytes_before,
                "bytes": report.bytes,
                "tile_depth_before": report.tile_depth_before,
                "tile_depth": report.tile_depth,
                "maps_added_meanwhile": report.maps_added_meanwhile,
            }),
            RecordEvent::CompactionFailed(error) => json!({
                "event": "compaction_failed",
                "error": message(error),
            }),
            RecordEvent::LeftOut { maps, what, error } => json!({
                "event": "left_out",
                "maps": maps,
                "what": what,
                "error": message(error),
            }),
            RecordEvent::Retrying { maps, what, error } => json!({
                "event": "retrying",
                "maps": maps,
                "what": what,
                "error": message(error),
            }),
            _ => return,
        };
        seen.borrow_mut().push(value);
    });
    let taken = (|| -> Result<(), Failure> {
        loop {
            let next = match recorder.time_left() {
                Some(left) => match feed.recv_timeout(left) {
                    Ok(item) => Some(item),
                    Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                        recorder.commit()?;
                        continue;
                    }
                    Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => None,
                },
                None => feed.recv().ok(),
            };
            match next {
                None => return Ok(()),
                Some(Feed::Map(time, bytes)) => {
                    recorder.take_bytes(time, &bytes)?;
                }
                Some(Feed::Source(path)) => {
                    let collected = froctomap_convert::collect_inputs_explained(
                        context,
                        &[path],
                        TimeSource::Auto,
                        &froctomap_convert::Zone::utc(),
                    )?;
                    for input in collected.series {
                        take_file(&mut recorder, input)?;
                    }
                }
            }
        }
    })();
    // What was taken before a failure is committed, as `froctomap record` does, before
    // waiting for a background compaction (which Ctrl-C abandons).
    drop(feed);
    let committed = recorder.commit();
    while committed.is_ok() && recorder.compacting() && !stop.load(Ordering::SeqCst) {
        std::thread::sleep(SIGNAL_CHECKS);
    }
    let finished = committed.and_then(|()| {
        if stop.load(Ordering::SeqCst) {
            recorder.stop()
        } else {
            recorder.finish()
        }
    });
    taken?;
    let summary = finished?;
    let events = events.borrow().clone();
    report_json(&json!({
        "file": file,
        "opened": opened,
        "commit_every": match commit_every {
            CommitEvery::Maps(n) => json!({"maps": n}),
            CommitEvery::Time(t) => json!({"seconds": t.as_secs_f64()}),
        },
        "committed_maps": summary.committed_maps,
        "commits": summary.commits,
        "older": summary.older,
        "bad": summary.bad,
        "compactions": summary.compactions,
        "events": events,
    }))
}

fn take_file(recorder: &mut Recorder<'_>, input: SeriesInput) -> Result<(), Failure> {
    recorder.take_file(input)?;
    Ok(())
}

/// A picture of a FROctomap file (`froctomap render`): the map at `t` (retrieved inside the
/// file's span, predicted outside it) from above or as a horizontal `slice` (`"z=0.5"`),
/// or with `dynamics=True` where the world changes. `font`: the font file to use when
/// neither `$FROCTOMAP_FONT` nor a system DejaVu Sans is found (the package passes the
/// copy it ships). Returns what was drawn.
#[pyfunction]
#[pyo3(signature = (file, output, *, t = None, slice = None, dynamics = false,
                    width = froctomap_render::DEFAULT_WIDTH, font = None))]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    file: PathBuf,
    output: PathBuf,
    t: Option<&Bound<'py, PyAny>>,
    slice: Option<String>,
    dynamics: bool,
    width: u32,
    font: Option<PathBuf>,
) -> PyResult<Bound<'py, PyAny>> {
    use froctomap_render::{render_dynamics, render_map, MapTime, View};
    if let Some(font) = font {
        froctomap_render::set_fallback_font(font);
    }
    let query = match (t, dynamics) {
        (Some(_), true) => return Err(froct_error_text("give t or dynamics=True, not both")),
        (None, false) => return Err(froct_error_text("give t (a time) or dynamics=True")),
        (Some(t), false) => Some(crate::times::time_query(t)?),
        (None, true) => None,
    };
    let report = py.detach(|| -> Result<String, Failure> {
        let view = match &slice {
            Some(text) => View::slice(text)?,
            None => View::TopDown,
        };
        let opened = crate::plugins::context().open_series(&file)?;
        let reader = opened.whole_history()?;
        let (picture, kind, time) = match query {
            Some(query) => {
                let when = MapTime::choose(reader, query)?;
                let picture = render_map(reader, when, view, width)?;
                let (kind, time) = match when {
                    MapTime::Retrieved { time, .. } => ("retrieved", Some(iso8601(time))),
                    MapTime::Predicted(time) => ("predicted", Some(iso8601(time))),
                    _ => ("map", None),
                };
                (picture, kind, time)
            }
            None => (render_dynamics(reader, width)?, "dynamics", None),
        };
        picture.write_png(&output, &[file.as_path()])?;
        report_json(&json!({
            "output": output,
            "kind": kind,
            "time": time,
            "width": picture.image().width(),
            "height": picture.image().height(),
        }))
    })?;
    json_value(py, &report)
}

/// A realistic, deterministic series of OctoMap snapshots made from a real base map
/// (`froctomap generate`): `.bt` (or `format`) files and a manifest in `output`. Returns the
/// snapshots' count, bytes and span, and the manifest's path.
#[pyfunction]
#[pyo3(signature = (output, *, base = None, days = 2.0, step = None, start = None, seed = 1,
                    real_doors = None, jitter = 0.0, missed = 0.0, noise = None,
                    partial = None, spec = None, format = None, progress = None))]
#[allow(clippy::too_many_arguments)]
pub fn generate<'py>(
    py: Python<'py>,
    output: PathBuf,
    base: Option<PathBuf>,
    days: f64,
    step: Option<&Bound<'py, PyAny>>,
    start: Option<&Bound<'py, PyAny>>,
    seed: u64,
    real_doors: Option<PathBuf>,
    jitter: f64,
    missed: f64,
    noise: Option<f64>,
    partial: Option<f64>,
    spec: Option<PathBuf>,
    format: Option<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    use froctomap_synth::{write_series, Generator, SeriesSpec, SpecOverrides, WriteSeriesOptions};
    // The package passes the Debian default when it exists; without it, a base is needed.
    let Some(base) = base else {
        return Err(froct_error_text(format!(
            "no base map: pass base= (an OctoMap .bt/.ot file of a real place, e.g. OctoMap's geb079.bt); the default, {}, comes with Debian's liboctomap-dev, which is not installed here",
            froctomap_synth::DEBIAN_GEB079
        )));
    };
    let step_ns = match step {
        Some(step) => duration_ns(step)?,
        None => froctomap_convert::parse_duration("10min").map_err(Failure::from)?,
    };
    let start = start.map(|t| instant(t, "start")).transpose()?;
    let report = with_progress(py, progress, |progress| {
        let scenario = match &spec {
            Some(path) => SeriesSpec::from_json_file(path)?,
            None => SeriesSpec::default(),
        };
        let overrides = SpecOverrides {
            step_secs: Some(step_ns as f64 / 1e9),
            days: Some(days),
            start,
            seed: Some(seed),
            jitter_secs: Some(jitter),
            missed_frames: Some(missed),
            door_file: real_doors.clone().map(Some),
            surface_noise: noise,
            partial_probability: partial,
            ..SpecOverrides::default()
        };
        let spec = overrides.apply(scenario)?;
        let context = crate::plugins::context();
        let map = context
            .formats()
            .read_file(&base, ReadOptions::default())?
            .map
            .snapshot
            .to_max_likelihood();
        let generator = Generator::new(&map, spec, None)?;
        progress.stage("writing snapshots", generator.frames().count() as u64);
        let done_so_far = std::sync::atomic::AtomicU64::new(0);
        let advance = |done: u64, _total: u64| {
            let before = done_so_far.fetch_max(done, std::sync::atomic::Ordering::Relaxed);
            progress.advance(done.saturating_sub(before));
        };
        let options = WriteSeriesOptions {
            format: format.clone().unwrap_or_else(|| "bt".to_string()),
            file_pattern: "frame_{time}.{ext}".to_string(),
            threads: 0,
        };
        let manifest = write_series(context.formats(), &generator, &output, &options, &advance)?;
        report_json(&json!({
            "output": output,
            "base": base,
            "snapshots": manifest.entries.len(),
            "bytes": manifest.total_bytes,
            "manifest": manifest.manifest_path(),
            "start": manifest.entries.first().map(|e| iso8601(e.time)),
            "end": manifest.entries.last().map(|e| iso8601(e.time)),
            "warnings": generator.warnings().iter().map(|w| w.to_string()).collect::<Vec<_>>(),
        }))
    })?;
    json_value(py, &report)
}
