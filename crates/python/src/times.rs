//! Times as Python gives them: Unix seconds (int or float), `datetime`/`date`, ISO 8601 text,
//! `numpy.datetime64`, or `"index:N"`/`"last"`. Everything is turned into text and read by
//! `froctomap-convert`'s own parser, so a time means exactly what it means on the command
//! line (`--time`): a time without a zone is UTC.

use crate::errors::to_py;
use froctomap_convert::{TimeQuery, Zone};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyString};

/// The text the command line would be given for `value`.
pub(crate) fn time_text(value: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(text) = value.cast::<PyString>() {
        return Ok(text.to_cow()?.into_owned());
    }
    if value.is_instance_of::<PyBool>() {
        return Err(PyTypeError::new_err("a time must not be a bool"));
    }
    let type_name = value.get_type().name()?.to_string();
    if type_name == "datetime64" {
        // numpy prints datetime64 as ISO 8601 without a zone: UTC, as numpy means it.
        return Ok(value.str()?.to_string());
    }
    if let Ok(seconds) = value.extract::<i64>() {
        return Ok(seconds.to_string());
    }
    if let Ok(seconds) = value.extract::<f64>() {
        if !seconds.is_finite() {
            return Err(crate::errors::froct_error_text(format!(
                "cannot read {seconds} as a time: not a finite number of seconds"
            )));
        }
        // Rust prints the shortest text that reads back as the same float, never in
        // exponent form: `1451865600.25` stays exact, as on the command line.
        return Ok(format!("{seconds}"));
    }
    if value.hasattr("isoformat")? {
        return value.call_method0("isoformat")?.extract();
    }
    Err(PyTypeError::new_err(format!(
        "a time is Unix seconds, a datetime, an ISO 8601 string or \"index:N\", not {type_name}"
    )))
}

/// A `--time` query from a Python value.
pub(crate) fn time_query(value: &Bound<'_, PyAny>) -> PyResult<TimeQuery> {
    let text = time_text(value)?;
    TimeQuery::read(&text, &Zone::utc())
        .map(|(query, _zoneless)| query)
        .map_err(to_py)
}

/// An instant (no sample index) from a Python value.
pub(crate) fn instant(value: &Bound<'_, PyAny>, what: &str) -> PyResult<froctomap_core::Timestamp> {
    let text = time_text(value)?;
    froctomap_convert::read_time(&text, &Zone::utc())
        .map(|read| read.time)
        .map_err(|e| {
            crate::errors::froct_error_text(format!("{what}: {}", crate::errors::message(&e)))
        })
}

/// Unix seconds of an instant as the nearest float: whole seconds and the fraction are
/// converted apart, so `1451865600.25` comes back as written (dividing the nanoseconds by
/// 1e9 in one go would round it to `1451865600.2499998`).
pub(crate) fn unix_seconds(t: froctomap_core::Timestamp) -> f64 {
    let whole = t.0.div_euclid(1_000_000_000);
    let nanos = t.0.rem_euclid(1_000_000_000);
    whole as f64 + nanos as f64 / 1e9
}
