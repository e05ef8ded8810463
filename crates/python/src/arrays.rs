//! Arrays from Python: anything numpy reads, as contiguous float64 data.

use numpy::{PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// Points as an (N, 3) array of metres (anything numpy reads as one).
pub(crate) fn points_array(py: Python<'_>, points: &Bound<'_, PyAny>) -> PyResult<Vec<[f64; 3]>> {
    let points = float_array(py, points)?;
    let shape = points.shape().to_vec();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "points must have shape (N, 3), not {shape:?}"
        )));
    }
    let flat = points.as_slice()?;
    Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// `numpy.ascontiguousarray(value, dtype=float64)`, read-only.
pub(crate) fn float_array<'py>(
    py: Python<'py>,
    value: &Bound<'py, PyAny>,
) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let array = py
        .import("numpy")?
        .call_method1("ascontiguousarray", (value, "float64"))?;
    array.extract::<PyReadonlyArrayDyn<'py, f64>>()
}
