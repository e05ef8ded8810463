//! A compaction on a thread of its own while a [`Recorder`](crate::Recorder) keeps
//! committing ([`Compaction::Background`](crate::Compaction::Background)), so that a live
//! source's maps are taken meanwhile instead of waiting for as long as a build of the whole
//! history takes.
//!
//! Three stages: the file as committed when the compaction starts (a reader opened by the
//! recorder before it commits again) is compacted into a locked temporary directory beside
//! the file; the maps committed to the file since are added to the result as a segment
//! (retrieved from the file, so exactly as they were taken), once on the thread and once
//! more by the recorder, at the commit where it finds the thread done; then the result is
//! renamed over the file with both writer locks held ([`LivingWriter::replace_with`]).
//! Until that rename the file is untouched, and a process killed at any instant leaves it
//! with every commit and, at most, the temporary directory, which the next writer removes.

use crate::build::{append_segment, output_dir, AppendOptions};
use crate::compact::{compact_opened, CompactOptions, CompactReport, COMPACT_PREFIX};
use crate::context::Context;
use crate::error::ConvertError;
use crate::inputs::SeriesInput;
use crate::maps::observed_bt;
use crate::progress::Progress;
use crate::series_file::{FroctFile, SeriesRead};
use froctomap_core::{temporary_dir_in, AtomicWriteError, TemporaryDir, Timestamp};
use froctomap_file::LivingWriter;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Instant;

/// A compaction running on its own thread; dropped unfinished, it is cancelled (its
/// temporary directory removed) and waited for.
pub(crate) struct BackgroundCompaction {
    cancel: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<Compacted, ConvertError>>>,
}

/// A finished background compaction: the compacted file (2.0, the maps committed while it
/// ran added), its writer holding its lock, waiting to replace the recorded file.
pub(crate) struct Compacted {
    pub(crate) writer: LivingWriter,
    pub(crate) report: CompactReport,
    pub(crate) started: Instant,
    /// Holds the compacted file; removed with it unless it was renamed away first.
    _dir: TemporaryDir,
}

impl BackgroundCompaction {
    /// Starts compacting `series` (opened from `file` by the caller, so what is compacted
    /// is the state it saw, whatever is committed after) on a new thread.
    pub(crate) fn start(
        context: &Context,
        series: FroctFile,
        file: &Path,
        options: CompactOptions,
        append: AppendOptions,
    ) -> Result<Self, ConvertError> {
        let cancel = Arc::new(AtomicBool::new(false));
        let flag = CancelFlag(Arc::clone(&cancel));
        let context = context.clone();
        let path = file.to_path_buf();
        let thread = std::thread::Builder::new()
            .name("froctomap-compaction".into())
            .spawn(move || compact_beside(&context, series, &path, &options, &append, &flag))
            .map_err(|source| written(output_dir(file), source))?;
        Ok(Self {
            cancel,
            thread: Some(thread),
        })
    }

    /// Whether the thread has ended (successfully or not).
    pub(crate) fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// Waits for the thread and gives what it made.
    pub(crate) fn join(mut self) -> Result<Compacted, ConvertError> {
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) | None => Err(ConvertError::internal(
                "the background compaction's thread panicked",
            )),
        }
    }
}

impl Drop for BackgroundCompaction {
    fn drop(&mut self) {
        if let Some(thread) = self.thread.take() {
            self.cancel.store(true, Ordering::Relaxed);
            let _ = thread.join();
        }
    }
}

/// The cancellation a dropped [`BackgroundCompaction`] asks for, as the build's loops ask
/// for it.
struct CancelFlag(Arc<AtomicBool>);

impl Progress for CancelFlag {
    fn cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// The thread's work: `series` compacted into a new temporary directory beside `file`,
/// then what was committed to `file` meanwhile added.
fn compact_beside(
    context: &Context,
    series: FroctFile,
    file: &Path,
    options: &CompactOptions,
    append: &AppendOptions,
    progress: &CancelFlag,
) -> Result<Compacted, ConvertError> {
    let started = Instant::now();
    let parent = output_dir(file);
    let dir = temporary_dir_in(parent, COMPACT_PREFIX.as_ref())
        .map_err(|source| written(parent, source))?;
    // The temporary directory is locked exclusively while it lives, and writers lock the
    // directory they write into (shared): they write into one of its own inside.
    let work = dir.path().join("work");
    std::fs::create_dir(&work).map_err(|source| written(&work, source))?;
    let compacted = work.join("compacted.froct");
    let report = compact_opened(context, series, file, &compacted, options, progress)?;
    let writer =
        LivingWriter::open_with_limits(&compacted, context.limits().froct, context.models())
            .map_err(ConvertError::from)?;
    let mut compacted = Compacted {
        writer,
        report,
        started,
        _dir: dir,
    };
    compacted.catch_up(context, file, append, progress)?;
    Ok(compacted)
}

impl Compacted {
    /// Adds to the compacted file, as one segment, the maps committed to `file` after its
    /// last sample, retrieved from `file` as committed now; the number added.
    pub(crate) fn catch_up(
        &mut self,
        context: &Context,
        file: &Path,
        append: &AppendOptions,
        progress: &dyn Progress,
    ) -> Result<usize, ConvertError> {
        let source = context.open_series(file)?;
        let after = self.writer.reader().last_instant();
        let mut later: Vec<(u32, Timestamp)> = Vec::new();
        for sample in (0..source.sample_count()).rev() {
            match source.sample_time(sample) {
                Some(time) if time > after => {
                    if !source.is_missing(sample) {
                        later.push((sample, time));
                    }
                }
                _ => break,
            }
        }
        if later.is_empty() {
            return Ok(0);
        }
        later.reverse();
        // Each map as the `.bt` file it retrieves as, in the work directory until the
        // compaction's directory goes.
        let work = self._dir.path().join("work");
        let mut series = Vec::with_capacity(later.len());
        for &(sample, time) in &later {
            crate::progress::stop_if_cancelled(progress)?;
            let path = work.join(format!("caught-up-{sample}.bt"));
            std::fs::write(&path, observed_bt(&source, sample)?)
                .map_err(|source| written(&path, source))?;
            series.push(SeriesInput::new(path, time));
        }
        drop(source);
        append_segment(context, &mut self.writer, &series, append, progress)?;
        self.report.maps_added_meanwhile += later.len();
        Ok(later.len())
    }
}

/// The compaction's work beside the file could not be made or written.
fn written(path: &Path, source: std::io::Error) -> ConvertError {
    ConvertError::from(AtomicWriteError {
        path: path.to_path_buf(),
        source,
    })
}
