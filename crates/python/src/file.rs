//! `froctomap.open(path)`: a FROctomap file, its time axis and summary, and the maps in it.

use crate::arrays::{float_array, points_array};
use crate::errors::{froct_error_text, to_py, Failure};
use crate::map::Map;
use crate::times::instant;
use crate::times::time_query;
use froctomap_convert::tidy_float;
use froctomap_convert::{
    anomalies, describe_series, probabilities, probabilities_at_times, read_snapshot,
    read_time_from_file_name, resolve_observed_with, voxel_history, AnomalyOptions, AnomalyReport,
    Expectation, FroctFile as SeriesFile, HistorySample, Pick, SeriesRead, TimeQuery, VoxelHistory,
    Zone,
};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// Opens a FROctomap file (`.froct`, format 1.x or 2.0): reads its header, time axis and
/// index (a few small reads; for a 2.0 file its committed segments' records); maps are
/// decoded when asked for.
///
/// Raises FroctError (an OSError and a ValueError) when the file is missing, unreadable,
/// damaged or not a FROctomap file, with the message the command line prints.
#[pyfunction]
pub fn open(py: Python<'_>, path: PathBuf) -> PyResult<FroctFile> {
    let reader = py
        .detach(|| crate::plugins::context().open_series(&path))
        .map_err(to_py)?;
    Ok(FroctFile {
        reader: Mutex::new(Some(Arc::new(reader))),
        path,
    })
}

/// An open FROctomap file (from `froctomap.open`). Usable as a context manager; maps taken
/// from it stay usable after `close()`.
#[pyclass(module = "froctomap", frozen)]
pub struct FroctFile {
    reader: Mutex<Option<Arc<SeriesFile>>>,
    path: PathBuf,
}

impl FroctFile {
    /// The instant a `predict`-style time names: an instant, or the time of a sample.
    fn instant_of(&self, reader: &SeriesFile, t: &Bound<'_, PyAny>) -> PyResult<Timestamp> {
        let samples = reader.sample_count();
        let text = crate::times::time_text(t)?;
        let sample = match time_query(t)? {
            TimeQuery::Instant(t) => return Ok(t),
            TimeQuery::Sample(s) => Some(s),
            TimeQuery::FromEnd(back) => samples.checked_sub(back),
        };
        sample.and_then(|s| reader.sample_time(s)).ok_or_else(|| {
            froct_error_text(format!(
                "{text}: no such sample; {} has {} samples (index:0 .. index:{}, or index:-1 .. index:-{})",
                self.path.display(),
                samples,
                samples.saturating_sub(1),
                samples
            ))
        })
    }

    /// The reader, or an error once closed.
    pub(crate) fn reader(&self) -> PyResult<Arc<SeriesFile>> {
        self.reader
            .lock()
            .ok()
            .and_then(|slot| slot.clone())
            .ok_or_else(|| froct_error_text(format!("{}: the file is closed", self.path.display())))
    }

    fn sample_times(&self) -> PyResult<Vec<Timestamp>> {
        let reader = self.reader()?;
        Ok((0..reader.sample_count())
            .map(|i| reader.sample_time(i).unwrap_or(Timestamp(i64::MIN)))
            .collect())
    }
}

#[pymethods]
impl FroctFile {
    /// The file's path, as given to `open`.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// Unix seconds of every sample of the time axis (numpy float64, one per sample,
    /// `"index:N"` is `times[N]`); samples without a snapshot are included (see `observed`).
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let times: Vec<f64> = self
            .sample_times()?
            .into_iter()
            .map(crate::times::unix_seconds)
            .collect();
        Ok(times.into_pyarray(py))
    }

    /// Nanoseconds since 1970 of every sample (numpy int64): `times` without rounding.
    #[getter]
    fn times_ns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let times: Vec<i64> = self.sample_times()?.into_iter().map(|t| t.0).collect();
        Ok(times.into_pyarray(py))
    }

    /// For every sample, whether the file holds a snapshot there (numpy bool; a regular axis
    /// may have missing samples).
    #[getter]
    fn observed<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let reader = self.reader()?;
        let mask: Vec<bool> = (0..reader.sample_count())
            .map(|i| !reader.is_missing(i))
            .collect();
        Ok(mask.into_pyarray(py))
    }

    /// Voxel edge length, metres.
    #[getter]
    fn resolution(&self) -> PyResult<f64> {
        Ok(self.reader()?.header().resolution)
    }

    /// The file described: the same fields as `froctomap info --json` (a dict).
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.describe(py, false)
    }

    /// `info`, with `count=True` recounting the cells from every tile instead of trusting the
    /// summary written at build time (`froctomap info --count --json`).
    #[pyo3(signature = (count = false))]
    fn describe<'py>(&self, py: Python<'py>, count: bool) -> PyResult<Bound<'py, PyAny>> {
        let reader = self.reader()?;
        let text = py.detach(|| -> Result<String, Failure> {
            let info = describe_series(crate::plugins::context(), &reader, count)?;
            report_json(&info)
        })?;
        json_value(py, &text)
    }

    /// The map as observed at `t` (exact in lossless files): the snapshot at `t`, or the last
    /// one before it (the closest one with `nearest=True`).
    ///
    /// `t`: Unix seconds, a datetime (naive ones are UTC), an ISO 8601 string, or
    /// `"index:N"` (`"index:-1"`/`"last"`: the last sample). A time after the last snapshot
    /// gives the last one, with a warning (that is not a prediction: see `predict`); a time
    /// before the first snapshot or an index beyond the axis raises FroctError.
    #[pyo3(signature = (t, nearest = false))]
    fn retrieve(&self, py: Python<'_>, t: &Bound<'_, PyAny>, nearest: bool) -> PyResult<Map> {
        let reader = self.reader()?;
        let query = time_query(t)?;
        let pick = if nearest {
            Pick::Nearest
        } else {
            Pick::AtOrBefore
        };
        let when = resolve_observed_with(&*reader, query, pick).map_err(to_py)?;
        let (start, end) = (reader.first_instant(), reader.last_instant());
        if let TimeQuery::Instant(t) = query {
            if t > end || t < start {
                let message = format!(
                    "{} is outside the file's span {} .. {}; this is the {} snapshot as observed, not a prediction (see predict)",
                    iso8601(t),
                    iso8601(start),
                    iso8601(end),
                    if t > end { "last" } else { "first" }
                );
                warn(py, &message)?;
            }
        }
        Ok(Map::observed(reader, when.sample, when.time))
    }

    /// The map predicted for `t`, any instant, past or future: every cell with its
    /// probability p(t) (as log-odds in `.ot` bytes; thresholded at 0.5 in `.bt` bytes).
    /// `t` as for `retrieve` (`"index:N"` predicts at that sample's time).
    fn predict(&self, t: &Bound<'_, PyAny>) -> PyResult<Map> {
        let reader = self.reader()?;
        let at = self.instant_of(&reader, t)?;
        Ok(Map::predicted(reader, at))
    }

    /// The model's occupancy probability p(t) at each of `points` (an (N, 3) array of
    /// metres, the map's frame): a numpy float64 array of shape (N,), NaN where the file has
    /// no cell (never observed, or outside the map). `t` as for `predict`: any instant; or
    /// several instants (a list, tuple or numpy array of them, T in all): an array of shape
    /// (T, N), row i at `t[i]`, computed in one pass over the tiles holding the points.
    fn probability<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let reader = self.reader()?;
        let points = points_array(py, points)?;
        let several = !t.is_instance_of::<pyo3::types::PyString>()
            && (t.is_instance_of::<pyo3::types::PyList>()
                || t.is_instance_of::<pyo3::types::PyTuple>()
                || t.hasattr("ndim")? && t.getattr("ndim")?.extract::<usize>()? > 0);
        if !several {
            let at = self.instant_of(&reader, t)?;
            let p = py
                .detach(|| probabilities(reader.whole_history()?, at, &points))
                .map_err(to_py)?;
            return Ok(p.into_pyarray(py).into_any());
        }
        let times = t
            .try_iter()?
            .map(|item| self.instant_of(&reader, &item?))
            .collect::<PyResult<Vec<_>>>()?;
        let p = py
            .detach(|| probabilities_at_times(reader.whole_history()?, &times, &points))
            .map_err(to_py)?;
        let rows = Array2::from_shape_vec((times.len(), points.len()), p)
            .map_err(|e| froct_error_text(e.to_string()))?;
        Ok(rows.into_pyarray(py).into_any())
    }

    /// One voxel's story: the cell holding `point` (x, y, z in metres), its class and model,
    /// and for every sample (between `start` and `end`, inclusive, when given) its time, the
    /// observed state and the model's p there, plus the samples where they disagree (the
    /// outliers). A dict:
    ///
    /// * `point`, `cell` (`key`, `depth`, `center`, `size`, `min`, `max`), `class`
    ///   (`"static_free"`, `"static_occupied"`, `"noisy"`, `"dynamic"`), `sometimes_unknown`;
    /// * `model`: `None`, or `{"mean": m, "periodic": [{"period_seconds", "amplitude",
    ///   "phase_turns"}, ...]}` for a dynamic cell;
    /// * `samples` (int64), `times` (Unix seconds), `states` (1.0 occupied, 0.0 free, NaN
    ///   unknown), `p` (float64): numpy arrays, one entry per sample;
    /// * `outlier_samples`, `outlier_times`: numpy arrays.
    ///
    /// A point without a cell raises FroctError naming the map's extent.
    #[pyo3(signature = (point, start = None, end = None))]
    fn history<'py>(
        &self,
        py: Python<'py>,
        point: &Bound<'py, PyAny>,
        start: Option<&Bound<'py, PyAny>>,
        end: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let reader = self.reader()?;
        let values = float_array(py, point)?;
        let values = values.as_slice()?;
        let point: [f64; 3] = values.try_into().map_err(|_| {
            PyValueError::new_err(format!(
                "point must be (x, y, z), not {} values",
                values.len()
            ))
        })?;
        let range = match (start, end) {
            (None, None) => None,
            (start, end) => Some((
                start.map_or(Ok(reader.first_instant()), |t| instant(t, "start"))?,
                end.map_or(Ok(reader.last_instant()), |t| instant(t, "end"))?,
            )),
        };
        let story = py
            .detach(|| voxel_history(reader.whole_history()?, point, range))
            .map_err(to_py)?;
        history_dict(py, &story)
    }

    /// What is unusual in `snapshot` (an OctoMap `.bt`/`.ot` file of the file's resolution)
    /// at time `t` (any form `retrieve` takes; default: the time in the snapshot's file
    /// name), as `froctomap anomalies --json` reports it: every observed voxel scored by
    /// its surprise under `expect` (`"model"`, `"static-mean"` or `"last-seen"`), the
    /// surprising ones grouped into connected regions, most surprising first. A dict with
    /// `time` (ISO 8601), `unix_time`, `scored_voxels`, `surprising_voxels` and `regions`
    /// (each `min`, `max` in metres, `voxels`, `score` in nats, `kind` `"appeared"` or
    /// `"vanished"`).
    #[pyo3(signature = (snapshot, t=None, expect="model"))]
    fn anomalies<'py>(
        &self,
        py: Python<'py>,
        snapshot: PathBuf,
        t: Option<&Bound<'py, PyAny>>,
        expect: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let reader = self.reader()?;
        let mut options = AnomalyOptions::default();
        options.expectation = expect
            .parse::<Expectation>()
            .map_err(|e| PyValueError::new_err(format!("expect: {e}")))?;
        let at = match t {
            Some(t) => self.instant_of(&reader, t)?,
            None => {
                let name = snapshot
                    .file_name()
                    .map(|n| n.to_string_lossy().to_string())
                    .unwrap_or_default();
                read_time_from_file_name(&name, &Zone::utc())
                    .map(|read| read.time)
                    .ok_or_else(|| {
                        froct_error_text(format!(
                            "{}: no time in the file name; give t=",
                            snapshot.display()
                        ))
                    })?
            }
        };
        let report = py
            .detach(|| {
                let whole = reader.whole_history()?;
                let map = read_snapshot(crate::plugins::context(), whole, &snapshot)?;
                anomalies(whole, &map, at, &options)
            })
            .map_err(to_py)?;
        anomaly_dict(py, &report)
    }

    /// Sees what was committed to a format 2.0 file since it was opened (or last
    /// refreshed): `True` when there is something new. Maps taken before keep the view they
    /// were taken from. A 1.x file never changes in place (`append` renames a new file over
    /// it), so refreshing it reads nothing; open it again to follow such a change. While
    /// maps of this file are alive the file is opened again instead of refreshed in place,
    /// which also follows a `compact` that replaced it.
    fn refresh(&self, py: Python<'_>) -> PyResult<bool> {
        let mut slot = self.reader.lock().map_err(|_| {
            froct_error_text(format!("{}: the file is unusable", self.path.display()))
        })?;
        let Some(held) = slot.as_mut() else {
            return Err(froct_error_text(format!(
                "{}: the file is closed",
                self.path.display()
            )));
        };
        if let Some(reader) = Arc::get_mut(held) {
            return py.detach(|| reader.refresh()).map_err(to_py);
        }
        if matches!(**held, SeriesFile::Flat(_)) {
            return Ok(false);
        }
        let seen = held.living().map(|l| l.root());
        let path = &self.path;
        let reopened = py
            .detach(|| crate::plugins::context().open_series(path))
            .map_err(to_py)?;
        let changed = reopened.living().map(|l| l.root()) != seen;
        *held = Arc::new(reopened);
        Ok(changed)
    }

    /// The format version, as `"major.minor"` (`"2.0"` for a living map).
    #[getter]
    fn version(&self) -> PyResult<String> {
        let (major, minor) = self.reader()?.version();
        Ok(format!("{major}.{minor}"))
    }

    /// Committed segments after the base (format 2.0; 0 for 1.x files).
    #[getter]
    fn segments(&self) -> PyResult<usize> {
        Ok(self.reader()?.segment_count())
    }

    /// Closes the file (maps taken from it stay usable).
    fn close(&self) {
        if let Ok(mut slot) = self.reader.lock() {
            slot.take();
        }
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, _args: &Bound<'_, pyo3::types::PyTuple>) -> bool {
        self.close();
        false
    }

    /// Samples of the time axis.
    fn __len__(&self) -> PyResult<usize> {
        Ok(self.reader()?.sample_count() as usize)
    }

    fn __repr__(&self) -> String {
        match self.reader() {
            Ok(reader) => {
                format!(
                    "<froctomap.FroctFile {:?}: {} samples, {} .. {}, {} m>",
                    self.path.display().to_string(),
                    reader.sample_count(),
                    iso8601(reader.first_instant()),
                    iso8601(reader.last_instant()),
                    reader.header().resolution
                )
            }
            Err(_) => format!(
                "<froctomap.FroctFile {:?} (closed)>",
                self.path.display().to_string()
            ),
        }
    }
}

/// An [`AnomalyReport`] as the dict `FroctFile.anomalies` documents (the CLI's JSON).
fn anomaly_dict<'py>(py: Python<'py>, report: &AnomalyReport) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("time", iso8601(report.time))?;
    dict.set_item(
        "unix_time",
        tidy_float(crate::times::unix_seconds(report.time)),
    )?;
    dict.set_item("scored_voxels", report.scored_voxels)?;
    dict.set_item("surprising_voxels", report.surprising_voxels)?;
    let regions = pyo3::types::PyList::empty(py);
    for region in &report.regions {
        let item = PyDict::new(py);
        item.set_item("min", region.min.map(tidy_float).to_vec())?;
        item.set_item("max", region.max.map(tidy_float).to_vec())?;
        item.set_item("voxels", region.voxels)?;
        item.set_item("score", tidy_float(region.score))?;
        item.set_item("kind", region.kind.name())?;
        regions.append(item)?;
    }
    dict.set_item("regions", regions)?;
    Ok(dict)
}

/// A [`VoxelHistory`] as the dict `FroctFile.history` documents.
fn history_dict<'py>(py: Python<'py>, story: &VoxelHistory) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("point", story.point.to_vec())?;
    let cell = PyDict::new(py);
    let key = story.cell.key;
    cell.set_item("key", (key.x, key.y, key.z))?;
    cell.set_item("depth", story.cell.depth)?;
    cell.set_item("center", story.cell.center.to_vec())?;
    cell.set_item("size", story.cell.size)?;
    cell.set_item("min", story.cell.min.to_vec())?;
    cell.set_item("max", story.cell.max.to_vec())?;
    dict.set_item("cell", cell)?;
    dict.set_item("class", story.class.name())?;
    dict.set_item("sometimes_unknown", story.sometimes_unknown)?;
    match &story.model {
        None => dict.set_item("model", py.None())?,
        Some(model) => {
            let described = PyDict::new(py);
            described.set_item("mean", model.mean)?;
            let terms = model
                .periodic
                .iter()
                .map(|term| {
                    let entry = PyDict::new(py);
                    entry.set_item("period_seconds", term.period_seconds)?;
                    entry.set_item("amplitude", term.amplitude)?;
                    entry.set_item("phase_turns", term.phase_turns)?;
                    Ok(entry)
                })
                .collect::<PyResult<Vec<_>>>()?;
            described.set_item("periodic", terms)?;
            dict.set_item("model", described)?;
        }
    }
    let samples = &story.samples;
    set_sample_columns(&dict, "", samples)?;
    let column = |f: &dyn Fn(&HistorySample) -> f64| samples.iter().map(f).collect::<Vec<f64>>();
    dict.set_item(
        "states",
        column(&|s| {
            s.state
                .map_or(f64::NAN, |o| f64::from(u8::from(o.is_occupied())))
        })
        .into_pyarray(py),
    )?;
    dict.set_item("p", column(&|s| s.p).into_pyarray(py))?;
    set_sample_columns(&dict, "outlier_", &story.outliers)?;
    Ok(dict)
}

/// Sets `{prefix}samples` (sample indices) and `{prefix}times` (Unix seconds) of `dict`,
/// in one pass over `samples`.
fn set_sample_columns(
    dict: &Bound<'_, PyDict>,
    prefix: &str,
    samples: &[HistorySample],
) -> PyResult<()> {
    let py = dict.py();
    let (indices, times): (Vec<i64>, Vec<f64>) = samples
        .iter()
        .map(|s| (i64::from(s.sample), crate::times::unix_seconds(s.time)))
        .unzip();
    dict.set_item(format!("{prefix}samples"), indices.into_pyarray(py))?;
    dict.set_item(format!("{prefix}times"), times.into_pyarray(py))?;
    Ok(())
}

/// A report as JSON text, its floats tidied as the command line's `--json` prints them
/// ([`froctomap_convert::tidy_floats`]).
pub(crate) fn report_json(report: &impl serde::Serialize) -> Result<String, Failure> {
    let mut value = serde_json::to_value(report)?;
    froctomap_convert::tidy_floats(&mut value);
    Ok(serde_json::to_string(&value)?)
}

/// JSON text as Python values (`json.loads`).
pub(crate) fn json_value<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// `warnings.warn(message)`, which the CLI prints as `warning: …`.
fn warn(py: Python<'_>, message: &str) -> PyResult<()> {
    py.import("warnings")?.call_method1(
        "warn",
        (message, py.get_type::<pyo3::exceptions::PyUserWarning>(), 2),
    )?;
    Ok(())
}
