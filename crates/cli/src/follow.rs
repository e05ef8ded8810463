//! `record --follow DIR`: what appears in a directory while `record` runs, watched with the
//! `notify` crate (inotify on Linux).
//!
//! A map file is *ready* once its writer closed it after writing, or once it was renamed
//! (moved) into the directory: the usual ways of writing a file others read, in place then
//! close, or under a temporary name then rename. Before that it is never read, so a file
//! still being written is never taken for a bad map. Hidden files (a leading `.`) and
//! files without a map extension are ignored, so a temporary name such as `map.bt.tmp` or
//! `.map.bt` is only seen once renamed into place.

use anyhow::{Context as _, Result};
use notify::event::{AccessKind, AccessMode, ModifyKind, RenameMode};
use notify::{EventKind, RecommendedWatcher, RecursiveMode, Watcher};
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// What the watcher tells about the directory.
#[derive(Debug)]
pub(crate) enum DirEvent {
    /// A file closed after writing, or renamed into the directory.
    Ready(PathBuf),
    /// A file was created or written to (not yet ready).
    Written,
    /// Events were lost (the kernel's queue overflowed): the directory must be listed
    /// again.
    Rescan,
    /// The watch failed.
    Failed(String),
}

/// Checks that `dir` is a directory that can be listed, for `--follow`.
pub(crate) fn check_dir(dir: &Path) -> Result<()> {
    let metadata = std::fs::metadata(dir).with_context(|| {
        format!(
            "--follow {}: no such directory",
            crate::ui::escaped(dir.display())
        )
    })?;
    if !metadata.is_dir() {
        anyhow::bail!(
            "--follow {}: not a directory (--follow watches a directory for new map files or bag splits; give a file as a SOURCE)",
            crate::ui::escaped(dir.display())
        );
    }
    std::fs::read_dir(dir)
        .with_context(|| format!("--follow {}", crate::ui::escaped(dir.display())))?;
    Ok(())
}

/// Watches `dir` (not its subdirectories), calling `on_event` on the watcher's thread with
/// each [`DirEvent`] until the returned watcher is dropped.
pub(crate) fn watch(
    dir: &Path,
    mut on_event: impl FnMut(DirEvent) + Send + 'static,
) -> Result<RecommendedWatcher> {
    let mut watcher = notify::recommended_watcher(move |event: notify::Result<notify::Event>| {
        let event = match event {
            Ok(event) => event,
            Err(error) => return on_event(DirEvent::Failed(error.to_string())),
        };
        if event.need_rescan() {
            return on_event(DirEvent::Rescan);
        }
        let ready = matches!(
            event.kind,
            EventKind::Access(AccessKind::Close(AccessMode::Write))
                // `Both` repeats a `To` with both names: the `To` alone is taken.
                | EventKind::Modify(ModifyKind::Name(RenameMode::To))
        );
        let written = matches!(
            event.kind,
            EventKind::Create(_) | EventKind::Modify(ModifyKind::Data(_))
        );
        if written {
            return on_event(DirEvent::Written);
        }
        for path in event.paths.into_iter().filter(|_| ready) {
            on_event(DirEvent::Ready(path));
        }
    })
    .context("--follow: cannot start watching")?;
    watcher
        .watch(dir, RecursiveMode::NonRecursive)
        .with_context(|| {
            format!(
                "--follow {}: cannot watch it",
                crate::ui::escaped(dir.display())
            )
        })?;
    Ok(watcher)
}

/// Whether `path` names a file `--follow` takes: not hidden, with one of `extensions`
/// (lower case, without the dot).
pub(crate) fn is_followed(path: &Path, extensions: &[&str]) -> bool {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return false;
    };
    !name.starts_with('.')
        && path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| extensions.iter().any(|k| k.eq_ignore_ascii_case(e)))
}

/// The files of `dir` that `--follow` takes ([`is_followed`]), in natural name order.
pub(crate) fn listed(dir: &Path, extensions: &[&str]) -> Result<Vec<PathBuf>> {
    let what = || format!("--follow {}", crate::ui::escaped(dir.display()));
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).with_context(what)? {
        let path = entry.with_context(what)?.path();
        if is_followed(&path, extensions) && path.is_file() {
            files.push(path);
        }
    }
    files.sort_by(|a, b| froctomap_formats::natural_cmp(a, b));
    Ok(files)
}

/// How long a reader waits for the directory to change before it looks again (events may
/// be lost when their queue is full).
const POLL: Duration = Duration::from_millis(200);

/// How long a split that has no footer, with a later split beside it, may stay unchanged
/// before it is taken as cut (its writer died) when no close was seen: a split's writer
/// closes it (footer and summary written) right after opening the next one.
const SPLIT_QUIET: Duration = Duration::from_secs(2);

/// The splits (`.mcap`) of the bag `dir`, not hidden, in natural name order.
fn splits(dir: &Path) -> Result<Vec<PathBuf>> {
    listed(dir, &["mcap"])
}

/// The first split of `dir` after `last` (natural name order), waiting for one to appear;
/// `None` once `stop` is set.
pub(crate) fn next_split(
    dir: &Path,
    last: Option<&Path>,
    woken: &Receiver<DirEvent>,
    stop: &AtomicBool,
) -> Result<Option<PathBuf>> {
    loop {
        let next = splits(dir)?.into_iter().find(|split| {
            last.is_none_or(|last| {
                froctomap_formats::natural_cmp(split, last) == std::cmp::Ordering::Greater
            })
        });
        if next.is_some() {
            return Ok(next);
        }
        if stop.load(Ordering::SeqCst) {
            return Ok(None);
        }
        wait(woken);
    }
}

/// Waits for an event of the directory, at most [`POLL`]; what it is does not matter.
fn wait(woken: &Receiver<DirEvent>) -> Option<DirEvent> {
    match woken.recv_timeout(POLL) {
        Ok(event) => Some(event),
        Err(RecvTimeoutError::Timeout) => None,
        Err(RecvTimeoutError::Disconnected) => {
            std::thread::sleep(POLL);
            None
        }
    }
}

/// A split being written, read as a stream that waits for the file to grow: a read at its
/// end waits until more bytes come, and returns 0 (the stream's end) only when `stop` is
/// set or the split is over — a later split exists and this one was closed by its writer
/// or stayed unchanged for [`SPLIT_QUIET`]. An MCAP reader given it therefore reads each
/// record once it is complete, and a split whose footer never comes (its writer died)
/// ends as a cut stream once the bag moved on.
pub(crate) struct GrowingSplit<'a> {
    file: File,
    path: PathBuf,
    dir: PathBuf,
    woken: &'a Receiver<DirEvent>,
    stop: &'a AtomicBool,
    /// Its writer closed it after writing (all its bytes are there).
    closed: bool,
    /// Since when reads found no new byte.
    idle_since: Option<Instant>,
}

impl<'a> GrowingSplit<'a> {
    pub(crate) fn open(
        path: &Path,
        woken: &'a Receiver<DirEvent>,
        stop: &'a AtomicBool,
    ) -> Result<Self> {
        let file = File::open(path)
            .with_context(|| format!("cannot open {}", crate::ui::escaped(path.display())))?;
        Ok(Self {
            file,
            path: path.to_path_buf(),
            dir: path.parent().unwrap_or(Path::new(".")).to_path_buf(),
            woken,
            stop,
            closed: false,
            idle_since: None,
        })
    }

    /// Whether the bag has a split after this one.
    fn superseded(&self) -> bool {
        splits(&self.dir).is_ok_and(|splits| {
            splits.iter().any(|split| {
                froctomap_formats::natural_cmp(split, &self.path) == std::cmp::Ordering::Greater
            })
        })
    }
}

impl Read for GrowingSplit<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        loop {
            let read = self.file.read(buf)?;
            if read > 0 || buf.is_empty() {
                self.idle_since = None;
                return Ok(read);
            }
            if self.stop.load(Ordering::SeqCst) {
                return Ok(0);
            }
            let idle = *self.idle_since.get_or_insert_with(Instant::now);
            if (self.closed || idle.elapsed() >= SPLIT_QUIET) && self.superseded() {
                return Ok(0);
            }
            if let Some(DirEvent::Ready(path)) = wait(self.woken) {
                self.closed |= path == self.path;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_and_hidden_names_are_not_followed() {
        let bt = ["bt", "ot"];
        assert!(is_followed(Path::new("d/map_2024-01-01.bt"), &bt));
        assert!(is_followed(Path::new("d/MAP.BT"), &bt));
        assert!(!is_followed(Path::new("d/map.bt.tmp"), &bt));
        assert!(!is_followed(Path::new("d/.map.bt"), &bt));
        assert!(!is_followed(Path::new("d/manifest.csv"), &bt));
    }
}
