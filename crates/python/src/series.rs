//! `froctomap.build` and `froctomap.evaluate`: series of maps in, a file or error tables out.

use crate::errors::{froct_error_text, to_py};
use crate::file::{json_value, report_json};
use crate::progress::with_progress;
use crate::times::instant;
use froctomap_convert::{
    collect_inputs_explained, collect_recording, evaluate as evaluate_file, ingest, parse_duration,
    IngestOptions, IngestTarget, RecordedTime, RecordingOptions, TimeSource, Zone,
};
use froctomap_core::Timestamp;
use froctomap_file::{Codec, ToggleLayout};
use froctomap_formats::ReadOptions;
use froctomap_temporal::{ModelConfig, OutlierMode};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How the inputs of a series get their times, as on the command line (`--start/--step`,
/// `--times-file`, `--times-from-names`; manifests and file names otherwise).
pub(crate) fn series_times(
    start: Option<&Bound<'_, PyAny>>,
    step: Option<&Bound<'_, PyAny>>,
    times_file: Option<PathBuf>,
    times_from_names: bool,
) -> PyResult<TimeSource> {
    if let Some(list) = times_file {
        return Ok(TimeSource::TimesFile(list));
    }
    match (start, step) {
        (Some(start), Some(step)) => Ok(TimeSource::StartStep {
            start: instant(start, "start")?,
            step_ns: duration_ns(step)?,
        }),
        (None, None) if times_from_names => Ok(TimeSource::FileNames),
        (None, None) => Ok(TimeSource::Auto),
        _ => Err(froct_error_text("start and step go together")),
    }
}

/// A duration: seconds as a number, or text such as `10min`, `1.5h`.
pub(crate) fn duration_ns(value: &Bound<'_, PyAny>) -> PyResult<i64> {
    let text = match value.extract::<String>() {
        Ok(text) => text,
        Err(_) => format!("{}", value.extract::<f64>()?),
    };
    parse_duration(&text).map_err(to_py)
}

/// The input paths: one path or a list of them.
pub(crate) fn paths(value: &Bound<'_, PyAny>) -> PyResult<Vec<PathBuf>> {
    if let Ok(path) = value.extract::<PathBuf>() {
        return Ok(vec![path]);
    }
    value
        .try_iter()?
        .map(|item| item?.extract::<PathBuf>())
        .collect()
}

/// What `build` was given: paths, or maps handed over as `(time, bytes)` pairs.
pub(crate) enum BuildInputs {
    Paths(Vec<PathBuf>),
    /// The pairs, spooled to disk as they came.
    Maps(froctomap_formats::Recording),
}

impl BuildInputs {
    /// The inputs with their times, as the command line collects its arguments.
    pub(crate) fn collect(
        self,
        context: &froctomap_convert::Context,
        source: TimeSource,
    ) -> Result<froctomap_convert::CollectedInputs, froctomap_convert::ConvertError> {
        match self {
            Self::Paths(inputs) => collect_inputs_explained(context, &inputs, source, &Zone::utc()),
            Self::Maps(recording) => collect_recording(PathBuf::from(PAIRS_NAME), recording),
        }
    }
}

/// How messages name maps handed over as `(time, bytes)` pairs.
pub(crate) const PAIRS_NAME: &str = "<maps>";

/// `inputs` of `build`: a path, an iterable of paths, or an iterable of `(time, bytes)`
/// pairs (any iterable, a generator too), each map spooled into a locked temporary
/// directory in `spool_dir` as it comes, so memory does not hold the maps.
pub(crate) fn build_inputs(
    value: &Bound<'_, PyAny>,
    spool_dir: Option<&Path>,
) -> PyResult<BuildInputs> {
    if let Ok(path) = value.extract::<PathBuf>() {
        return Ok(BuildInputs::Paths(vec![path]));
    }
    let mut paths = Vec::new();
    let mut spool: Option<froctomap_formats::MapSpool> = None;
    let mixed = || froct_error_text("inputs: give paths or (time, bytes) pairs, not both");
    for (index, item) in value.try_iter()?.enumerate() {
        let item = item?;
        if let Ok(path) = item.extract::<PathBuf>() {
            if spool.is_some() {
                return Err(mixed());
            }
            paths.push(path);
            continue;
        }
        let pair = || {
            froct_error_text(format!(
                "inputs[{index}]: expected a path or a (time, bytes) pair"
            ))
        };
        let (time, map): (Bound<'_, PyAny>, Bound<'_, PyAny>) =
            item.extract().map_err(|_| pair())?;
        let map = map.cast::<pyo3::types::PyBytes>().map_err(|_| pair())?;
        if !paths.is_empty() {
            return Err(mixed());
        }
        let time = instant(&time, &format!("inputs[{index}]"))?;
        let spool = match &mut spool {
            Some(spool) => spool,
            None => {
                spool.insert(froctomap_formats::MapSpool::new(spool_dir, "map").map_err(to_py)?)
            }
        };
        spool.push(time, map.as_bytes()).map_err(to_py)?;
    }
    match spool {
        Some(spool) => Ok(BuildInputs::Maps(spool.into_recording().map_err(to_py)?)),
        None => Ok(BuildInputs::Paths(paths)),
    }
}

/// The model's settings from the keyword arguments, checked by the model (`--model`,
/// `--model-option`, `--order`, `--max-order`, `--periods`, `--lossy`).
pub(crate) fn model_config(
    model: &str,
    lossy: bool,
    order: Option<&Bound<'_, PyAny>>,
    max_order: Option<u8>,
    periods: Option<&Bound<'_, PyAny>>,
    model_options: Option<&Bound<'_, PyDict>>,
) -> PyResult<ModelConfig> {
    let models = crate::plugins::context().models();
    let descriptor = models.by_name(model).ok_or_else(|| {
        let known: Vec<&str> = models.iter().map(|d| d.name).collect();
        froct_error_text(format!(
            "unknown model {model:?} (registered: {})",
            known.join(", ")
        ))
    })?;
    let mut config = ModelConfig::default().with_outliers(if lossy {
        OutlierMode::Lossy
    } else {
        OutlierMode::Lossless
    });
    config.options = model_config_options(model_options)?;
    let has = |key: &str| descriptor.options.iter().any(|o| o.key == key);
    let order = match order {
        None => None,
        Some(value) => match value.extract::<String>() {
            Ok(text) => Some(text),
            Err(_) => Some(value.extract::<u32>()?.to_string()),
        },
    };
    // The default order ("auto") means nothing to a model without orders.
    let order = order.filter(|o| has("order") || o != "auto");
    let periods = match periods {
        None => None,
        Some(values) => {
            let mut seconds = Vec::new();
            for value in values.try_iter()? {
                seconds.push((duration_ns(&value?)? as f64 / 1e9).to_string());
            }
            (!seconds.is_empty()).then(|| seconds.join(","))
        }
    };
    for (argument, key, value) in [
        ("order", "order", order),
        ("max_order", "max-order", max_order.map(|n| n.to_string())),
        ("periods", "periods", periods),
    ] {
        let Some(value) = value else { continue };
        if !has(key) {
            return Err(froct_error_text(format!(
                "{argument}: model {} has no option {key}",
                descriptor.name
            )));
        }
        config.options.set(key, value);
    }
    descriptor
        .create()
        .check_options(&config.options)
        .map_err(to_py)?;
    Ok(config)
}

/// `model_options={"key": value}` as the model's options (`--model-option KEY=VALUE`).
pub(crate) fn model_config_options(
    model_options: Option<&Bound<'_, PyDict>>,
) -> PyResult<froctomap_temporal::ModelOptions> {
    let mut options = froctomap_temporal::ModelOptions::new();
    if let Some(given) = model_options {
        for (key, value) in given.iter() {
            let key: String = key.extract()?;
            options.set(&key, value.str()?.to_string());
        }
    }
    Ok(options)
}

/// `created`, else SOURCE_DATE_EPOCH (whole Unix seconds), as the command line reads them.
pub(crate) fn creation_time(created: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Timestamp>> {
    if let Some(value) = created {
        return instant(value, "created").map(Some);
    }
    let Some(epoch) = std::env::var_os("SOURCE_DATE_EPOCH") else {
        return Ok(None);
    };
    let seconds = epoch
        .to_str()
        .and_then(|text| text.trim().parse::<i64>().ok())
        .ok_or_else(|| {
            froct_error_text(format!(
                "SOURCE_DATE_EPOCH={epoch:?} is not a whole number of seconds"
            ))
        })?;
    let created = Timestamp::from_secs(seconds);
    froctomap_convert::check_range("SOURCE_DATE_EPOCH", created).map_err(to_py)?;
    Ok(Some(created))
}

/// `tags` as the header metadata (`{"tags": {...}}`, as `--tag KEY=VALUE`).
pub(crate) fn tags_metadata(tags: Option<&Bound<'_, PyDict>>) -> PyResult<Map<String, Value>> {
    let mut metadata = Map::new();
    let Some(tags) = tags else {
        return Ok(metadata);
    };
    let mut pairs = Map::new();
    for (key, value) in tags.iter() {
        pairs.insert(
            key.str()?.to_string(),
            Value::from(value.str()?.to_string()),
        );
    }
    if !pairs.is_empty() {
        metadata.insert("tags".into(), Value::Object(pairs));
    }
    Ok(metadata)
}

/// Builds a FROctomap file from a series of OctoMap snapshots (`froctomap build`).
///
/// See the package's `build` for the arguments. Returns the report of `build --json`.
#[pyfunction]
#[pyo3(signature = (
    inputs, output, *, lossy = false, order = None, model = None,
    model_options = None, max_order = None, periods = None, tile_depth = 10, zstd_level = 19,
    toggle_block = 256, skip_bad = false, resolution = None, allow_mostly_skipped = false,
    tags = None, created = None, memory = None, tmp_dir = None, start = None, step = None,
    times_file = None, times_from_names = false, topic = None, time_source = "header".to_string(),
    progress = None
))]
#[allow(clippy::too_many_arguments)]
pub fn build<'py>(
    py: Python<'py>,
    inputs: &Bound<'py, PyAny>,
    output: PathBuf,
    lossy: bool,
    order: Option<&Bound<'py, PyAny>>,
    model: Option<String>,
    model_options: Option<&Bound<'py, PyDict>>,
    max_order: Option<u8>,
    periods: Option<&Bound<'py, PyAny>>,
    tile_depth: u8,
    zstd_level: i8,
    toggle_block: u32,
    skip_bad: bool,
    resolution: Option<f64>,
    allow_mostly_skipped: bool,
    tags: Option<&Bound<'py, PyDict>>,
    created: Option<&Bound<'py, PyAny>>,
    memory: Option<u64>,
    tmp_dir: Option<PathBuf>,
    start: Option<&Bound<'py, PyAny>>,
    step: Option<&Bound<'py, PyAny>>,
    times_file: Option<PathBuf>,
    times_from_names: bool,
    topic: Option<String>,
    time_source: String,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let started = Instant::now();
    if !(1..=16).contains(&tile_depth) {
        return Err(froct_error_text("tile_depth must be 1 ..= 16"));
    }
    if !(0..=22).contains(&zstd_level) {
        return Err(froct_error_text("zstd_level must be 0 ..= 22"));
    }
    let recorded: RecordedTime = time_source
        .parse()
        .map_err(|e| froct_error_text(format!("time_source: {e}")))?;
    let spool_dir = tmp_dir
        .clone()
        .or_else(|| Some(froctomap_convert::output_dir(&output).to_path_buf()));
    let inputs = build_inputs(inputs, spool_dir.as_deref())?;
    let source = series_times(start, step, times_file, times_from_names)?;
    // `None`: the library's default, named in one place.
    let model = model.unwrap_or_else(|| froctomap_temporal::models::DEFAULT_MODEL.to_string());
    let options = IngestOptions {
        model: model.clone(),
        config: model_config(&model, lossy, order, max_order, periods, model_options)?,
        tile_depth,
        codec: if zstd_level == 0 {
            Codec::Raw
        } else {
            Codec::Zstd { level: zstd_level }
        },
        toggles: ToggleLayout::blocks_of(toggle_block),
        skip_bad,
        resolution,
        allow_mostly_skipped,
        metadata: tags_metadata(tags)?,
        time: creation_time(created)?,
        memory: memory.unwrap_or(froctomap_convert::DEFAULT_BUILD_MEMORY),
        tmp_dir,
        ..IngestOptions::default()
    };
    let context = crate::plugins::context().clone().with_recording_options(
        RecordingOptions::new(topic, recorded)
            .with_skip_bad(skip_bad)
            .with_spool_dir(spool_dir),
    );
    if matches!(inputs, BuildInputs::Maps(_)) && source != TimeSource::Auto {
        return Err(froct_error_text(
            "inputs: (time, bytes) pairs carry their own times; start/step, times_file and times_from_names apply to files only",
        ));
    }
    let report = with_progress(py, progress, |progress| {
        let collected = inputs.collect(&context, source)?;
        let target = IngestTarget::NewFile(&output);
        let report = ingest(&context, &collected, target, &options, progress)?;
        let mut value = serde_json::to_value(&report)?;
        if let Value::Object(map) = &mut value {
            let warnings: Vec<Value> = collected
                .warnings
                .iter()
                .map(|w| Value::from(w.to_string()))
                .collect();
            map.insert("input_warnings".into(), Value::from(warnings));
            map.insert(
                "seconds".into(),
                Value::from(started.elapsed().as_secs_f64()),
            );
        }
        report_json(&value)
    })?;
    json_value(py, &report)
}

/// Compares a FROctomap file with ground-truth maps (`froctomap eval --json`); `stride`
/// compares every `stride`th of them in time order (`eval --stride`).
#[pyfunction]
#[pyo3(signature = (path, against, *, start = None, step = None, times_file = None,
                    times_from_names = false, stride = 1, progress = None))]
#[allow(clippy::too_many_arguments)]
pub fn evaluate<'py>(
    py: Python<'py>,
    path: PathBuf,
    against: &Bound<'py, PyAny>,
    start: Option<&Bound<'py, PyAny>>,
    step: Option<&Bound<'py, PyAny>>,
    times_file: Option<PathBuf>,
    times_from_names: bool,
    stride: usize,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    if stride == 0 {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "stride must be at least 1",
        ));
    }
    let against = paths(against)?;
    let source = series_times(start, step, times_file, times_from_names)?;
    let report = with_progress(py, progress, |progress| {
        let context = crate::plugins::context();
        let file = context.open_series(&path)?;
        let reader = file.whole_history()?;
        let collected = collect_inputs_explained(context, &against, source, &Zone::utc())?;
        let truths: Vec<_> = collected.series.into_iter().step_by(stride).collect();
        let report = evaluate_file(context, reader, &truths, ReadOptions::default(), progress)?;
        report_json(&report)
    })?;
    json_value(py, &report)
}

/// Reads a time as the command line does (`--time`): Unix seconds (float) of an instant, or
/// a sample query (`"index:N"`) as `("index", N)` / `("from_end", N)`.
#[pyfunction]
pub fn parse_time<'py>(py: Python<'py>, t: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    use froctomap_convert::TimeQuery;
    Ok(match crate::times::time_query(t)? {
        TimeQuery::Instant(time) => crate::times::unix_seconds(time)
            .into_pyobject(py)?
            .into_any(),
        TimeQuery::Sample(sample) => ("index", i64::from(sample)).into_pyobject(py)?.into_any(),
        TimeQuery::FromEnd(back) => ("from_end", i64::from(back)).into_pyobject(py)?.into_any(),
    })
}
