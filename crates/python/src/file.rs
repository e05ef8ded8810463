//! `froctomap.open(path)`: a FROctomap file, its time axis and summary, and the maps in it.

use crate::errors::{froct_error_text, to_py};
use crate::map::Map;
use crate::times::time_query;
use froctomap_convert::{describe, resolve_observed_with, Pick, TimeQuery};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_file::FroctReader;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// Opens a FROctomap file (`.froct`): reads its header, time axis and index (a few small
/// reads); maps are decoded when asked for.
///
/// Raises FroctError (an OSError and a ValueError) when the file is missing, unreadable,
/// damaged or not a FROctomap file, with the message the command line prints.
#[pyfunction]
pub fn open(py: Python<'_>, path: PathBuf) -> PyResult<FroctFile> {
    let reader = py
        .detach(|| crate::context().open_froct(&path))
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
    reader: Mutex<Option<Arc<FroctReader>>>,
    path: PathBuf,
}

impl FroctFile {
    /// The reader, or an error once closed.
    pub(crate) fn reader(&self) -> PyResult<Arc<FroctReader>> {
        self.reader
            .lock()
            .ok()
            .and_then(|slot| slot.clone())
            .ok_or_else(|| {
                froct_error_text(format!("{}: the file is closed", self.path.display()))
            })
    }

    fn sample_times(&self) -> PyResult<Vec<Timestamp>> {
        let reader = self.reader()?;
        let axis = &reader.header().axis;
        Ok((0..axis.len())
            .map(|i| axis.time(i).unwrap_or(Timestamp(i64::MIN)))
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
            .map(Timestamp::as_secs_f64)
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
        let axis = &reader.header().axis;
        let mask: Vec<bool> = (0..axis.len()).map(|i| !axis.is_missing(i)).collect();
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
        let text = py
            .detach(|| {
                describe(crate::context(), &reader, count)
                    .map_err(|e| crate::errors::message(&e))
                    .and_then(|info| serde_json::to_string(&info).map_err(|e| e.to_string()))
            })
            .map_err(froct_error_text)?;
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
        let when = resolve_observed_with(&reader, query, pick).map_err(to_py)?;
        let axis = &reader.header().axis;
        if let TimeQuery::Instant(t) = query {
            if t > axis.end() || t < axis.start() {
                let message = format!(
                    "{} is outside the file's span {} .. {}; this is the {} snapshot as observed, not a prediction (see predict)",
                    iso8601(t),
                    iso8601(axis.start()),
                    iso8601(axis.end()),
                    if t > axis.end() { "last" } else { "first" }
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
        let axis = &reader.header().axis;
        let text = crate::times::time_text(t)?;
        let sample = match time_query(t)? {
            TimeQuery::Instant(t) => Ok(t),
            TimeQuery::Sample(s) => Err(Some(s)),
            TimeQuery::FromEnd(back) => Err(axis.len().checked_sub(back)),
        };
        let at = match sample {
            Ok(t) => t,
            Err(sample) => sample.and_then(|s| axis.time(s)).ok_or_else(|| {
                froct_error_text(format!(
                    "{text}: no such sample; {} has {} samples (index:0 .. index:{}, or index:-1 .. index:-{})",
                    self.path.display(),
                    axis.len(),
                    axis.len().saturating_sub(1),
                    axis.len()
                ))
            })?,
        };
        Ok(Map::predicted(reader.clone(), at))
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
        Ok(self.reader()?.header().axis.len() as usize)
    }

    fn __repr__(&self) -> String {
        match self.reader() {
            Ok(reader) => {
                let axis = &reader.header().axis;
                format!(
                    "<froctomap.FroctFile {:?}: {} samples, {} .. {}, {} m>",
                    self.path.display().to_string(),
                    axis.len(),
                    iso8601(axis.start()),
                    iso8601(axis.end()),
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

/// JSON text as Python values (`json.loads`).
pub(crate) fn json_value<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// `warnings.warn(message)`, which the CLI prints as `warning: …`.
fn warn(py: Python<'_>, message: &str) -> PyResult<()> {
    py.import("warnings")?
        .call_method1("warn", (message, py.get_type::<pyo3::exceptions::PyUserWarning>(), 2))?;
    Ok(())
}
