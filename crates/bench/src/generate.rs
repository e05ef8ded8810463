//! `froctomap-bench generate`: the `froctomap-synth` generator on the command line.

use anyhow::{bail, Context, Result};
use clap::Args;
use froctomap_convert::{parse_duration, parse_time};
use froctomap_formats::{FormatRegistry, ReadOptions};
use froctomap_synth::{write_series, Generator, SeriesSpec, SpecOverrides, WriteSeriesOptions};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Debian's copy of the FR-079 corridor scan.
pub const DEFAULT_BASE: &str = "/usr/share/doc/liboctomap-dev/examples/data/geb079.bt";
/// The real door recording, relative to the checkout.
pub const DEFAULT_DOORS: &str = "../shared/data/greg_door_2016_min/training_data.txt";

/// The real door recording: `explicit` if given, else [`DEFAULT_DOORS`] relative to the
/// working directory, else relative to this crate's checkout.
pub fn door_file(explicit: Option<&Path>) -> Result<PathBuf> {
    if let Some(path) = explicit {
        if path.is_file() {
            return Ok(path.to_path_buf());
        }
        bail!("real door series {} not found", path.display());
    }
    let here = PathBuf::from(DEFAULT_DOORS);
    if here.is_file() {
        return Ok(here);
    }
    let checkout = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(DEFAULT_DOORS);
    if checkout.is_file() {
        return Ok(checkout);
    }
    bail!(
        "real door series not found at {DEFAULT_DOORS} (beside the checkout, in shared/); \
         pass --real-doors FILE"
    )
}

/// Options of `generate`.
#[derive(Args, Debug)]
pub struct GenerateArgs {
    /// Base map (.bt or .ot).
    #[arg(long, default_value = DEFAULT_BASE)]
    base: PathBuf,
    /// Output directory (created if missing).
    #[arg(short, long)]
    out: PathBuf,
    /// Length of the series in days.
    #[arg(long, default_value_t = 2.0)]
    days: f64,
    /// Time between frames (e.g. 10min, 600, 1h).
    #[arg(long, default_value = "10min")]
    step: String,
    /// Number of grid frames (overrides --days).
    #[arg(long)]
    count: Option<u64>,
    /// Time of the first frame (default Monday 2016-01-04 00:00 UTC, the door recording's start).
    #[arg(long)]
    start: Option<String>,
    /// Seed of all random choices.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Uniform jitter of each frame time, seconds (less than half a step).
    #[arg(long, default_value_t = 0.0)]
    jitter: f64,
    /// Probability that a frame is missed.
    #[arg(long, default_value_t = 0.0)]
    missed: f64,
    /// Real door series (`unix_time state` lines, 1 = open); default: the one in shared/.
    #[arg(long)]
    real_doors: Option<PathBuf>,
    /// Do not use a real door series (all doors follow schedules).
    #[arg(long, conflicts_with = "real_doors")]
    no_real_doors: bool,
    /// A JSON SeriesSpec to start from (the options above override it).
    #[arg(long)]
    spec: Option<PathBuf>,
    /// Doors.
    #[arg(long)]
    doors: Option<usize>,
    /// People.
    #[arg(long)]
    people: Option<usize>,
    /// Object slots.
    #[arg(long)]
    objects: Option<usize>,
    /// Machines.
    #[arg(long)]
    machines: Option<usize>,
    /// Per-frame flip probability of surface voxels.
    #[arg(long)]
    noise: Option<f64>,
    /// Probability of a partial view.
    #[arg(long)]
    partial: Option<f64>,
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// Seconds in a step given as a duration (`10min`, `600`, `1.5h`).
pub fn step_seconds(step: &str) -> Result<f64> {
    let ns = parse_duration(step).with_context(|| format!("--step {step:?}"))?;
    if ns <= 0 {
        bail!("--step {step:?}: must be positive");
    }
    Ok(ns as f64 / 1e9)
}

fn spec_from_args(args: &GenerateArgs) -> Result<SeriesSpec> {
    let scenario = match &args.spec {
        Some(path) => SeriesSpec::from_json_file(path)?,
        None => SeriesSpec::default(),
    };
    let overrides = SpecOverrides {
        step_secs: Some(step_seconds(&args.step)?),
        days: Some(args.days),
        count: args.count,
        start: args.start.as_deref().map(parse_time).transpose()?,
        seed: Some(args.seed),
        jitter_secs: Some(args.jitter),
        missed_frames: Some(args.missed),
        door_file: Some(if args.no_real_doors {
            None
        } else {
            Some(door_file(args.real_doors.as_deref())?)
        }),
        doors: args.doors,
        people: args.people,
        objects: args.objects,
        machines: args.machines,
        surface_noise: args.noise,
        partial_probability: args.partial,
    };
    Ok(overrides.apply(scenario)?)
}

/// Writes the series and prints what was placed and written.
pub fn generate(args: &GenerateArgs) -> Result<()> {
    let spec = spec_from_args(args)?;
    let started = Instant::now();
    let formats = FormatRegistry::with_default_formats();
    let base = formats
        .read_file(&args.base, ReadOptions::default())
        .with_context(|| format!("reading the base map {}", args.base.display()))?
        .map
        .snapshot;
    let generator = Generator::new(&base, spec, None)?;
    for warning in generator.warnings() {
        eprintln!("warning: {warning}");
    }
    for element in generator.elements() {
        println!(
            "{} {}: {} ({} voxels)",
            element.kind,
            element.index,
            element.description,
            element.voxels.len()
        );
    }
    let options = WriteSeriesOptions {
        threads: args.threads,
        ..WriteSeriesOptions::default()
    };
    let last = std::sync::Mutex::new(Instant::now());
    let manifest = write_series(&formats, &generator, &args.out, &options, &|done, total| {
        if let Ok(mut last) = last.lock() {
            if last.elapsed().as_secs_f64() >= 5.0 || done == total {
                eprintln!("  {done}/{total} frames written");
                *last = Instant::now();
            }
        }
    })?;
    println!(
        "wrote {} frames ({} bytes) and {} in {:.1} s",
        manifest.entries.len(),
        manifest.total_bytes,
        manifest.manifest_path().display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps() {
        assert_eq!(step_seconds("10min").unwrap(), 600.0);
        assert_eq!(step_seconds("1h").unwrap(), 3600.0);
        assert!(step_seconds("soon").is_err());
        assert!(step_seconds("0").is_err());
    }

    #[test]
    fn missing_door_file_is_named() {
        let err = door_file(Some(Path::new("/nonexistent/doors.txt"))).unwrap_err();
        assert!(err.to_string().contains("/nonexistent/doors.txt"));
    }
}
