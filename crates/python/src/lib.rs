//! `froctomap._native`: the Python extension module behind the `froctomap` package.
//!
//! Every function is a thin layer over `froctomap-convert`, as the command-line tool is: the
//! same context of formats and models, the same time parsing, the same writers (so a map's
//! bytes are the CLI's bytes), and the same error messages, raised as `froctomap.FroctError`.
//! Rust work runs with the interpreter released (`Python::detach`), so other Python threads
//! run meanwhile; arrays are handed over as numpy arrays without copying.
//!
//! The pure-Python part of the package (`crates/python/python/froctomap/`) defines the
//! exception class, the progress bars and the stubs; see `docs/PYTHON.md`.

mod arrays;
mod errors;
mod file;
mod map;
mod message;
mod plugins;
mod progress;
mod series;
mod times;
mod verbs;

use pyo3::prelude::*;

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<file::FroctFile>()?;
    m.add_class::<map::Map>()?;
    m.add_function(wrap_pyfunction!(file::open, m)?)?;
    m.add_function(wrap_pyfunction!(series::build, m)?)?;
    m.add_function(wrap_pyfunction!(series::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(series::parse_time, m)?)?;
    m.add_function(wrap_pyfunction!(message::octomap_message_fields, m)?)?;
    m.add_function(wrap_pyfunction!(message::octomap_message_file, m)?)?;
    m.add_function(wrap_pyfunction!(verbs::append, m)?)?;
    m.add_function(wrap_pyfunction!(verbs::compact, m)?)?;
    m.add_function(wrap_pyfunction!(verbs::convert, m)?)?;
    m.add_function(wrap_pyfunction!(verbs::export, m)?)?;
    m.add_function(wrap_pyfunction!(verbs::formats, m)?)?;
    m.add_function(wrap_pyfunction!(verbs::info, m)?)?;
    m.add_function(wrap_pyfunction!(verbs::record, m)?)?;
    m.add_function(wrap_pyfunction!(verbs::render, m)?)?;
    m.add_function(wrap_pyfunction!(verbs::generate, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "_DEFAULT_TILE_BUDGET",
        froctomap_convert::DEFAULT_TILE_BUDGET,
    )?;
    Ok(())
}
