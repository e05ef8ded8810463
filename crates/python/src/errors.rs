//! Rust errors as `froctomap.FroctError` (a subclass of `OSError` and `ValueError`, defined in
//! Python), with the message the command-line tool prints for the same failure.

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyType;

/// The error and its causes on one line, each text once: what the command-line tool prints
/// for the same failure ([`froctomap_core::error_message`]).
pub(crate) fn message(error: &(dyn std::error::Error + 'static)) -> String {
    froctomap_core::error_message(error)
}

/// The operating system's error number of the first I/O error in the chain, if any (so that
/// `error.errno == errno.ENOENT` works for a missing file).
fn os_error_number(error: &(dyn std::error::Error + 'static)) -> Option<i32> {
    let mut cause = Some(error);
    while let Some(current) = cause {
        if let Some(io) = current.downcast_ref::<std::io::Error>() {
            if let Some(number) = io.raw_os_error() {
                return Some(number);
            }
        }
        // An input found missing before anything opened it (a path that is neither a file,
        // a directory nor a matching pattern) is the operating system's "not found" too.
        if let Some(froctomap_convert::ConvertError::NotFound { .. }) =
            current.downcast_ref::<froctomap_convert::ConvertError>()
        {
            return Some(ENOENT);
        }
        cause = current.source();
    }
    None
}

/// `errno.ENOENT`, the same number on every platform Python runs on.
const ENOENT: i32 = 2;

fn error_class(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    static CLASS: PyOnceLock<Py<PyType>> = PyOnceLock::new();
    CLASS.import(py, "froctomap._errors", "FroctError")
}

/// `FroctError(message)`, with `errno` set from an I/O cause.
pub(crate) fn froct_error(error: &(dyn std::error::Error + 'static)) -> PyErr {
    raise(&message(error), os_error_number(error))
}

/// `FroctError(text)` for a problem found by the binding itself.
pub(crate) fn froct_error_text(text: impl Into<String>) -> PyErr {
    raise(&text.into(), None)
}

fn raise(text: &str, errno: Option<i32>) -> PyErr {
    Python::attach(|py| {
        let made = error_class(py).and_then(|class| class.call1((text,)));
        match made {
            Ok(value) => {
                if let Some(number) = errno {
                    // Best effort: the message is what matters.
                    let _ = value.setattr("errno", number);
                }
                PyErr::from_value(value)
            }
            Err(import_failed) => import_failed,
        }
    })
}

/// `.map_err(to_py)` for any Rust error of the libraries.
pub(crate) fn to_py<E: std::error::Error + 'static>(error: E) -> PyErr {
    froct_error(&error)
}

/// A failure met without the interpreter (inside `Python::detach`): the message and the
/// operating system's error number of its cause, raised as `FroctError` once attached, so
/// that `errno` is set however far the error travelled.
#[derive(Debug)]
pub(crate) struct Failure {
    text: String,
    errno: Option<i32>,
}

impl<E: std::error::Error + 'static> From<E> for Failure {
    fn from(error: E) -> Self {
        Self {
            text: message(&error),
            errno: os_error_number(&error),
        }
    }
}

impl Failure {
    /// A failure found by the binding itself (no OS cause).
    pub(crate) fn text(text: impl Into<String>) -> Self {
        Self {
            text: text.into(),
            errno: None,
        }
    }
}

impl From<Failure> for PyErr {
    fn from(failure: Failure) -> Self {
        raise(&failure.text, failure.errno)
    }
}
