//! Progress of long calls, handed to a Python callable `callback(stage, done, total)`.
//!
//! The work runs on Rust threads with the interpreter released; the callback is called with
//! the interpreter attached, at most about ten times a second (and at every stage's start and
//! end), so that a progress bar costs nothing noticeable. The package's `progress=True`
//! passes a callback that draws tqdm bars.

use crate::errors::Failure;
use froctomap_convert::Progress;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, RecvTimeoutError};
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

    /// Whether the callback raised (the work then stops at its next batch).
    fn failed(&self) -> bool {
        self.state
            .lock()
            .map_or(true, |state| state.failed.is_some())
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

/// How often a long call looks for Ctrl-C (signals reach Python only through the thread
/// that holds the interpreter, which waits meanwhile).
pub(crate) const SIGNAL_CHECKS: Duration = Duration::from_millis(100);

/// The [`Progress`] handed to the library: the callback's, and a stop asked for by Ctrl-C
/// or by a callback that raised.
struct Interruptible<'a> {
    callback: Option<&'a Callback>,
    stop: &'a AtomicBool,
}

impl Progress for Interruptible<'_> {
    fn stage(&self, name: &str, total: u64) {
        if let Some(callback) = self.callback {
            callback.stage(name, total);
        }
    }

    fn advance(&self, units: u64) {
        if let Some(callback) = self.callback {
            callback.advance(units);
        }
    }

    fn cancelled(&self) -> bool {
        self.stop.load(Ordering::Relaxed) || self.callback.is_some_and(Callback::failed)
    }
}

/// Runs `work` on a thread of its own without the interpreter, reporting progress to the
/// callable `progress` (if any), while this thread looks for signals every
/// [`SIGNAL_CHECKS`]: Ctrl-C (or an exception in the callback) asks the work to stop at
/// its next batch, and is raised once it stopped, with nothing written. Otherwise raises
/// what the callback raised, else what `work` failed with.
pub(crate) fn with_progress<T: Send>(
    py: Python<'_>,
    progress: Option<Py<PyAny>>,
    work: impl FnOnce(&dyn Progress) -> Result<T, Failure> + Send,
) -> PyResult<T> {
    let callback = progress.map(Callback::new);
    let stop = AtomicBool::new(false);
    let watched = Interruptible {
        callback: callback.as_ref(),
        stop: &stop,
    };
    let (outcome, interrupted) = std::thread::scope(|scope| {
        let (done, finished) = sync_channel::<()>(1);
        let watched = &watched;
        let worker = scope.spawn(move || {
            let outcome = work(watched);
            let _ = done.send(());
            outcome
        });
        let mut interrupted = None;
        let mut finished = finished;
        loop {
            // The receiver goes to the detached closure and back (it is Send, not Sync).
            let (waited, back) =
                py.detach(move || (finished.recv_timeout(SIGNAL_CHECKS), finished));
            finished = back;
            match waited {
                Err(RecvTimeoutError::Timeout) => {}
                Ok(()) | Err(RecvTimeoutError::Disconnected) => break,
            }
            if interrupted.is_none() {
                if let Err(signal) = py.check_signals() {
                    stop.store(true, Ordering::Relaxed);
                    interrupted = Some(signal);
                }
            }
        }
        let outcome = py
            .detach(|| worker.join())
            .unwrap_or_else(|_| Err(Failure::text("internal error: the work panicked")));
        (outcome, interrupted)
    });
    if let Some(signal) = interrupted {
        return Err(signal);
    }
    if let Some(callback) = callback {
        callback.finish()?;
    }
    Ok(outcome?)
}
