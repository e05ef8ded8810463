//! The options that pick a benchmark series, shared by `run`, `anomalies` and `floor`, and
//! the one way they become a generator and files on disk.

use crate::dataset::{self, Written};
use crate::generate::{door_file, step_seconds, DEFAULT_BASE};
use crate::size::{plan, Plan};
use anyhow::{bail, Context, Result};
use clap::Args;
use froctomap_core::Snapshot;
use froctomap_formats::{FormatRegistry, ReadOptions};
use froctomap_synth::{Generator, SeriesSpec};
use std::path::{Path, PathBuf};

/// Which series: size, sampling, seed, base map and door recording.
#[derive(Args, Debug, Clone)]
pub struct SeriesArgs {
    /// Training span: ci (2 days, 1 held out), week, 4weeks, `<n>weeks`, `<n>d`, or days.
    #[arg(long, default_value = "ci")]
    pub size: String,
    /// Time between snapshots (e.g. 10min, 600, 1h).
    #[arg(long, default_value = "10min")]
    pub step: String,
    /// Held-out days after the training span (default 1 for ci, else 2).
    #[arg(long)]
    pub heldout_days: Option<f64>,
    /// Seed of the generator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Base map (.bt or .ot).
    #[arg(long, default_value = DEFAULT_BASE)]
    pub base: PathBuf,
    /// Real door series (default: shared/data/greg_door_2016_min/training_data.txt beside
    /// the checkout).
    #[arg(long)]
    pub real_doors: Option<PathBuf>,
}

/// A series ready to measure: its plan, generator and files.
pub struct Series {
    /// The real door recording used.
    pub doors: PathBuf,
    /// The base map (maximum-likelihood states are the generator's).
    pub base: Snapshot,
    /// The generator.
    pub generator: Generator,
    /// Training frames (grid frames `0..train_count`).
    pub train_count: u64,
    /// The files.
    pub written: Written,
}

impl SeriesArgs {
    /// The plan and step these options stand for (checked before any work).
    pub fn plan(&self) -> Result<(Plan, f64)> {
        let plan = plan(&self.size, self.heldout_days)?;
        let step = step_seconds(plan.step.unwrap_or(&self.step))?;
        Ok((plan, step))
    }

    /// The generator of the series (placement done, nothing written), the base map, the
    /// door recording and the number of training frames.
    pub fn generator(&self) -> Result<(Generator, Snapshot, PathBuf, u64)> {
        let (plan, step) = self.plan()?;
        let doors = door_file(self.real_doors.as_deref())?;
        let base = FormatRegistry::with_default_formats()
            .read_file(&self.base, ReadOptions::default())
            .with_context(|| format!("reading the base map {}", self.base.display()))?
            .map
            .snapshot;
        let spec = SeriesSpec {
            seed: self.seed,
            door_file: Some(doors.clone()),
            ..SeriesSpec::with_duration(plan.train_days + plan.heldout_days, step)
        };
        let train_count = froctomap_synth::frames_for(plan.train_days, step);
        if train_count >= spec.count {
            bail!("the held-out span is shorter than one step");
        }
        let generator = Generator::new(&base, spec, None)?;
        for warning in generator.warnings() {
            eprintln!("warning: {warning}");
        }
        Ok((generator, base, doors, train_count))
    }

    /// Generates the series under `root`, or reuses it when `root` already holds it.
    pub fn prepare(&self, root: &Path, progress: &dyn Fn(&str)) -> Result<Series> {
        let (generator, base, doors, train_count) = self.generator()?;
        std::fs::create_dir_all(root).with_context(|| format!("creating {}", root.display()))?;
        let written = dataset::write(&generator, &self.base, train_count, root, progress)?;
        Ok(Series {
            doors,
            base,
            generator,
            train_count,
            written,
        })
    }
}
