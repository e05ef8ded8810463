//! Temporary files and directories to remove if the process is stopped by a signal.
//!
//! Temporary outputs ([`temporary_beside`](crate::temporary_beside)) and a build's spill
//! directory remove themselves when dropped, on success and on error. A signal such as
//! Ctrl-C (SIGINT) or SIGTERM ends the process without running destructors, so each of them
//! is also [`Registered`] here while it lives, and a front end's signal handler calls
//! [`remove_registered`] before the process ends. The library installs no handler itself:
//! what a signal means is the program's choice.
//!
//! ```
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("partial.tmp");
//! std::fs::write(&path, b"half")?;
//! let registered = froctomap_core::cleanup::Registered::new(&path);
//! // What a signal handler does:
//! froctomap_core::cleanup::remove_registered();
//! assert!(!path.exists());
//! drop(registered);
//! # Ok::<(), std::io::Error>(())
//! ```

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

/// The live temporary paths, by registration number.
static LIVE: Mutex<Vec<(u64, PathBuf)>> = Mutex::new(Vec::new());
static NEXT: AtomicU64 = AtomicU64::new(0);
/// Set by [`remove_registered`]: the process is ending, nothing more may be created.
static STOPPING: AtomicBool = AtomicBool::new(false);

fn live() -> MutexGuard<'static, Vec<(u64, PathBuf)>> {
    // A panic elsewhere while the list was held leaves it valid: go on with it.
    LIVE.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A temporary file or directory listed for [`remove_registered`] until dropped (dropping
/// it only takes it off the list; removing the path itself is its owner's job).
#[derive(Debug)]
pub struct Registered {
    id: u64,
}

impl Registered {
    /// Lists `path` (a file, or a directory removed with its contents).
    pub fn new(path: &Path) -> Self {
        let id = NEXT.fetch_add(1, Ordering::Relaxed);
        live().push((id, path.to_path_buf()));
        Self { id }
    }
}

/// Makes a temporary file or directory with `create` and registers the path `path_of` gives,
/// under the list's lock, so that a signal arriving meanwhile cannot miss it: either it is
/// registered before [`remove_registered`] runs (and removed by it), or it is never made
/// (an `Interrupted` error once the process is ending).
pub fn create_registered<T>(
    create: impl FnOnce() -> std::io::Result<T>,
    path_of: impl FnOnce(&T) -> &Path,
) -> std::io::Result<(T, Registered)> {
    let mut live = live();
    if STOPPING.load(Ordering::SeqCst) {
        return Err(std::io::Error::new(
            std::io::ErrorKind::Interrupted,
            "the process is ending (a signal was received)",
        ));
    }
    let made = create()?;
    let id = NEXT.fetch_add(1, Ordering::Relaxed);
    live.push((id, path_of(&made).to_path_buf()));
    Ok((made, Registered { id }))
}

impl Drop for Registered {
    fn drop(&mut self) {
        live().retain(|(id, _)| *id != self.id);
    }
}

/// Removes every registered file and directory (with its contents) that still exists, and
/// returns how many were removed. For a signal handler that is about to end the process;
/// it runs on an ordinary thread (not inside the handler itself), since it takes a lock.
pub fn remove_registered() -> usize {
    {
        let _live = live();
        STOPPING.store(true, Ordering::SeqCst);
    }
    remove_where(|_| true)
}

/// Removes the registered paths for which `chosen` is true.
fn remove_where(chosen: impl Fn(&Path) -> bool) -> usize {
    let mut live = live();
    let (remove, keep): (Vec<_>, Vec<_>) = live.drain(..).partition(|(_, p)| chosen(p));
    *live = keep;
    let mut removed = 0;
    for (_, path) in remove {
        // Other threads run on until the process ends and may still add a file to a
        // directory being removed (a spilling thread's first spill): try again then.
        for _ in 0..20 {
            let gone = match std::fs::symlink_metadata(&path) {
                Ok(meta) if meta.is_dir() => std::fs::remove_dir_all(&path).is_ok(),
                Ok(_) => std::fs::remove_file(&path).is_ok(),
                Err(_) => break,
            };
            if gone {
                removed += 1;
                break;
            }
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registered_paths_are_removed_until_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.tmp");
        let sub = dir.path().join("spill");
        std::fs::write(&file, b"x").unwrap();
        std::fs::create_dir(&sub).unwrap();
        std::fs::write(sub.join("part-0"), b"y").unwrap();
        let kept = dir.path().join("kept.tmp");
        std::fs::write(&kept, b"z").unwrap();
        let a = Registered::new(&file);
        let b = Registered::new(&sub);
        drop(Registered::new(&kept));
        // Other tests of this process register their own temporary files: only ours go.
        assert_eq!(remove_where(|p| p.starts_with(dir.path())), 2);
        assert!(!file.exists() && !sub.exists());
        assert!(kept.exists(), "a dropped registration is not removed");
        drop((a, b));
    }
}
