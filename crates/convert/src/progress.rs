//! Progress reporting for long operations, implemented by front ends (the CLI draws bars).

/// Receives progress of a long operation. All methods have empty defaults; implementations
/// must be `Sync` because work runs on several threads.
pub trait Progress: Sync {
    /// A new stage begins, with `total` units of work (0 if unknown).
    fn stage(&self, _name: &str, _total: u64) {}
    /// `units` more units of the current stage are done.
    fn advance(&self, _units: u64) {}
    /// Whether the caller wants the work stopped (Ctrl-C in an interpreter, a failed
    /// progress display): long loops ask between batches and then fail with
    /// [`ConvertError::Cancelled`](crate::ConvertError::Cancelled), writing nothing.
    fn cancelled(&self) -> bool {
        false
    }
}

/// [`ConvertError::Cancelled`](crate::ConvertError::Cancelled) when `progress` asks to stop.
pub(crate) fn stop_if_cancelled(progress: &dyn Progress) -> Result<(), crate::ConvertError> {
    if progress.cancelled() {
        Err(crate::ConvertError::Cancelled)
    } else {
        Ok(())
    }
}

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {}
