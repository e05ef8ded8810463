//! Progress of long calls, handed to a Python callable `callback(stage, done, total)`.
//!
//! The work runs on Rust threads with the interpreter released; the callback is called with
//! the interpreter attached, at most about ten times a second (and at every stage's start and
//! end), so that a progress bar costs nothing noticeable. The package's `progress=True`
//! passes a callback that draws tqdm bars.

use crate::errors::Failure;
use froctomap_convert::{Progress, Silent};
use pyo3::prelude::*;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Shortest time between two calls of the callback within a stage.
const INTERVAL: Duration = Duration::from_millis(100);

/// A [`Progress`] that calls a Python callable.
pub(crate) struct Callback {
    callable: Py<PyAny>,
    state: Mutex<State>,
}

struct State {
    stage: Option<String>,
    total: u64,
    done: u64,
    last_call: Instant,
    /// The first exception the callback raised; later calls are skipped and `finish`
    /// raises it.
    failed: Option<PyErr>,
}

impl Callback {
    pub(crate) fn new(callable: Py<PyAny>) -> Self {
        Self {
            callable,
            state: Mutex::new(State {
                stage: None,
                total: 0,
                done: 0,
                last_call: Instant::now(),
                failed: None,
            }),
        }
    }

    /// Reports the end of the last stage; raises what the callback raised, if anything.
    pub(crate) fn finish(self) -> PyResult<()> {
        let mut state = match self.state.into_inner() {
            Ok(state) => state,
            Err(poisoned) => poisoned.into_inner(),
        };
        if state.failed.is_none() {
            if let Some(stage) = state.stage.take() {
                let done = if state.total > 0 {
                    state.total
                } else {
                    state.done
                };
                call(&self.callable, &mut state, &stage, done);
            }
        }
        match state.failed {
            Some(error) => Err(error),
            None => Ok(()),
        }
    }
}

fn call(callable: &Py<PyAny>, state: &mut State, stage: &str, done: u64) {
    if state.failed.is_some() {
        return;
    }
    let total = state.total;
    let outcome = Python::attach(|py| callable.call1(py, (stage, done, total)).map(drop));
    state.last_call = Instant::now();
    if let Err(error) = outcome {
        state.failed = Some(error);
    }
}

impl Progress for Callback {
    fn stage(&self, name: &str, total: u64) {
        let Ok(mut state) = self.state.lock() else {
            return;
        };
        if let Some(previous) = state.stage.take() {
            let done = if state.total > 0 {
                state.total
            } else {
                state.done
            };
            call(&self.callable, &mut state, &previous, done);
        }
        state.stage = Some(name.to_string());
        state.total = total;
        state.done = 0;
        call(&self.callable, &mut state, name, 0);
    }

    fn advance(&self, units: u64) {
        let Ok(mut state) = self.state.lock() else {
            return;
        };
        state.done = state.done.saturating_add(units);
        if state.last_call.elapsed() >= INTERVAL {
            if let Some(stage) = state.stage.clone() {
                let done = state.done;
                call(&self.callable, &mut state, &stage, done);
            }
        }
    }
}

/// Runs `work` without the interpreter, reporting progress to the callable `progress` (if
/// any); then raises what the callback raised, else what `work` failed with.
pub(crate) fn with_progress<T: Send>(
    py: Python<'_>,
    progress: Option<Py<PyAny>>,
    work: impl FnOnce(&dyn Progress) -> Result<T, Failure> + Send,
) -> PyResult<T> {
    let callback = progress.map(Callback::new);
    let outcome = py.detach(|| match &callback {
        Some(callback) => work(callback),
        None => work(&Silent),
    });
    if let Some(callback) = callback {
        callback.finish()?;
    }
    Ok(outcome?)
}
