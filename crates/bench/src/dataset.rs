//! The benchmark series on disk: training snapshots as the sensor saw them, and ground-truth
//! maps of the held-out days that follow, both from one generator.

use anyhow::{Context, Result};
use froctomap_convert::{manifest_text, SeriesInput};
use froctomap_core::{Snapshot, Timestamp};
use froctomap_formats::{FormatRegistry, WriteOptions};
use froctomap_synth::{Generator, SeriesSpec};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where a run's series lives.
#[derive(Clone, Debug)]
pub struct SeriesDirs {
    /// Training snapshots (`frame_*.bt` and `manifest.csv`).
    pub train: PathBuf,
    /// Held-out ground truth (`truth_*.bt` and `manifest.csv`).
    pub heldout: PathBuf,
}

impl SeriesDirs {
    /// The layout under `root`.
    pub fn under(root: &Path) -> Self {
        Self {
            train: root.join("train"),
            heldout: root.join("heldout"),
        }
    }
}

/// Name of the file recording which spec a series directory holds.
const SPEC_FILE: &str = "spec.json";

/// What [`write`](fn@write) wrote.
#[derive(Clone, Debug)]
pub struct Written {
    /// Training snapshots, in time order.
    pub train: Vec<SeriesInput>,
    /// Held-out ground-truth maps, in time order, with their grid indices.
    pub heldout: Vec<(SeriesInput, u64)>,
    /// Seconds spent (0 when an existing series was reused).
    pub seconds: f64,
    /// `true` when an existing, complete series of the same spec was reused.
    pub reused: bool,
}

/// The spec and split a series directory records, as text.
fn fingerprint(spec: &SeriesSpec, train_count: u64, base: &Path) -> Result<String> {
    Ok(serde_json::to_string_pretty(&serde_json::json!({
        "spec": spec,
        "train_count": train_count,
        "base": base.display().to_string(),
    }))?)
}

/// Writes the frames `< train_count` (as observed: noise, partial views) into `dirs.train`
/// and the ground truth of the frames `>= train_count` into `dirs.heldout`, in parallel
/// batches (memory: a few frames). A directory that already holds the same series (same
/// spec, split and base map, complete manifests) is reused as it is.
pub fn write(
    generator: &Generator,
    base_path: &Path,
    train_count: u64,
    root: &Path,
    progress: &dyn Fn(&str),
) -> Result<Written> {
    let dirs = SeriesDirs::under(root);
    let fingerprint = fingerprint(generator.spec(), train_count, base_path)?;
    let spec_path = root.join(SPEC_FILE);
    let frames: Vec<(u64, Timestamp)> = generator.frames().map(|f| (f.index, f.time)).collect();
    let name = |dir: &Path, prefix: &str, t: Timestamp| {
        dir.join(format!(
            "{prefix}_{}.bt",
            froctomap_core::calendar::iso8601_basic(t)
        ))
    };
    let train: Vec<SeriesInput> = frames
        .iter()
        .filter(|(i, _)| *i < train_count)
        .map(|&(_, time)| SeriesInput::new(name(&dirs.train, "frame", time), time))
        .collect();
    let heldout: Vec<(SeriesInput, u64)> = frames
        .iter()
        .filter(|(i, _)| *i >= train_count)
        .map(|&(i, time)| {
            (
                SeriesInput::new(name(&dirs.heldout, "truth", time), time),
                i,
            )
        })
        .collect();
    let complete = std::fs::read_to_string(&spec_path).is_ok_and(|s| s == fingerprint)
        && dirs.train.join("manifest.csv").is_file()
        && dirs.heldout.join("manifest.csv").is_file()
        && train.iter().all(|i| i.path.is_file())
        && heldout.iter().all(|(i, _)| i.path.is_file());
    if complete {
        return Ok(Written {
            train,
            heldout,
            seconds: 0.0,
            reused: true,
        });
    }
    let started = Instant::now();
    for dir in [&dirs.train, &dirs.heldout] {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    // A stale fingerprint must not survive a partial rewrite.
    let _ = std::fs::remove_file(&spec_path);
    let registry = FormatRegistry::with_default_formats();
    let options = WriteOptions {
        format: Some("bt"),
        backend: None,
    };
    let jobs: Vec<(u64, &Path, bool)> = frames
        .iter()
        .map(|&(i, _)| i)
        .zip(
            train
                .iter()
                .map(|s| (s.path.as_path(), false))
                .chain(heldout.iter().map(|(s, _)| (s.path.as_path(), true))),
        )
        .map(|(i, (p, truth))| (i, p, truth))
        .collect();
    let batch = 8 * rayon::current_num_threads().max(1);
    let mut last_report = Instant::now();
    for (k, chunk) in jobs.chunks(batch).enumerate() {
        chunk
            .par_iter()
            .map(|&(index, path, truth)| -> Result<()> {
                let snapshot: Snapshot = if truth {
                    generator.truth_frame(index)?
                } else {
                    generator.frame(index)?
                };
                registry
                    .write_file(&snapshot, path, options)
                    .with_context(|| format!("writing {}", path.display()))?;
                Ok(())
            })
            .collect::<Result<Vec<()>>>()?;
        let done = ((k + 1) * batch).min(jobs.len());
        if last_report.elapsed().as_secs_f64() >= 10.0 || done == jobs.len() {
            progress(&format!("generated {done}/{} frames", jobs.len()));
            last_report = Instant::now();
        }
    }
    let heldout_inputs: Vec<SeriesInput> = heldout.iter().map(|(s, _)| s.clone()).collect();
    for (dir, entries) in [(&dirs.train, &train), (&dirs.heldout, &heldout_inputs)] {
        let path = dir.join("manifest.csv");
        std::fs::write(&path, manifest_text(dir, entries))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    std::fs::write(&spec_path, fingerprint)
        .with_context(|| format!("writing {}", spec_path.display()))?;
    Ok(Written {
        train,
        heldout,
        seconds: started.elapsed().as_secs_f64(),
        reused: false,
    })
}

/// Writes a manifest of the first `count` training snapshots (the shorter series of the
/// memory comparison) beside the training directory.
pub fn prefix_manifest(train: &[SeriesInput], dir: &Path, count: usize) -> Result<PathBuf> {
    let count = count.clamp(1, train.len().max(1));
    let path = dir.join(format!("manifest-first-{count}.csv"));
    let entries = &train[..count.min(train.len())];
    std::fs::write(&path, manifest_text(dir, entries))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// `count` indices spread evenly over `0..len` (all of them when `len <= count`).
pub fn spread(len: usize, count: usize) -> Vec<usize> {
    if count == 0 || len == 0 {
        return Vec::new();
    }
    if len <= count {
        return (0..len).collect();
    }
    let mut out: Vec<usize> = (0..count)
        .map(|k| (k * (len - 1)) / (count - 1).max(1))
        .collect();
    out.dedup();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_is_even_and_bounded() {
        assert_eq!(spread(0, 5), Vec::<usize>::new());
        assert_eq!(spread(3, 5), vec![0, 1, 2]);
        assert_eq!(spread(10, 3), vec![0, 4, 9]);
        assert_eq!(spread(100, 1), vec![0]);
        let s = spread(4032, 48);
        assert_eq!(s.len(), 48);
        assert_eq!((s[0], s[47]), (0, 4031));
        assert!(s.windows(2).all(|w| w[0] < w[1]));
    }
}
