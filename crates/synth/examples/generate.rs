//! Generates a realistic series of OctoMap snapshots from a real base map.
//!
//! ```sh
//! cargo run --release -p froctomap-synth --example generate -- \
//!     --days 2 --step-min 10 -o /tmp/series \
//!     --real-doors ../shared/data/greg_door_2016_min/training_data.txt
//! ```
//!
//! Writes `frame_<time>.bt` files and `manifest.csv` into the output directory and prints
//! what was placed, what changed and how long it took.

use clap::Parser;
use froctomap_formats::{FormatRegistry, ReadOptions};
use froctomap_synth::calendar::{format_utc, parse_utc};
use froctomap_synth::{frames_for, write_series, Generator, SeriesSpec, WriteSeriesOptions};
use std::path::PathBuf;
use std::time::Instant;

/// Generates a deterministic series of OctoMap snapshots with doors, people, chairs,
/// objects, machines, surface noise and partial views.
#[derive(Parser, Debug)]
struct Args {
    /// Base map (.bt or .ot).
    #[arg(
        long,
        default_value = "/usr/share/doc/liboctomap-dev/examples/data/geb079.bt"
    )]
    base: PathBuf,
    /// Output directory (created if missing).
    #[arg(short, long)]
    out: PathBuf,
    /// Length of the series in days.
    #[arg(long, default_value_t = 2.0)]
    days: f64,
    /// Minutes between frames.
    #[arg(long, default_value_t = 10.0)]
    step_min: f64,
    /// Number of grid frames (overrides --days).
    #[arg(long)]
    count: Option<u64>,
    /// Time of the first frame, UTC (e.g. 2016-01-04T00:00:00Z).
    #[arg(long)]
    start: Option<String>,
    /// Seed of all random choices.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Uniform jitter of each frame time, in seconds (less than half a step).
    #[arg(long, default_value_t = 0.0)]
    jitter: f64,
    /// Probability that a frame is missed.
    #[arg(long, default_value_t = 0.0)]
    missed: f64,
    /// Real door series (`unix_time state` per line, 1 = open).
    #[arg(long)]
    real_doors: Option<PathBuf>,
    /// How many doors follow the real series.
    #[arg(long)]
    real_door_count: Option<usize>,
    /// Doors.
    #[arg(long)]
    doors: Option<usize>,
    /// People.
    #[arg(long)]
    people: Option<usize>,
    /// Chairs.
    #[arg(long)]
    chairs: Option<usize>,
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
    /// Unobserved fraction of the horizontal extent in a partial view.
    #[arg(long)]
    partial_extent: Option<f64>,
    /// A JSON SeriesSpec to start from (command-line options override it).
    #[arg(long)]
    spec: Option<PathBuf>,
    /// Output map format (registry name).
    #[arg(long, default_value = "bt")]
    format: String,
    /// File name pattern ({time}, {index}, {ext}).
    #[arg(long, default_value = "frame_{time}.{ext}")]
    pattern: String,
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// The argument-to-spec mapping (a CLI subcommand can reuse it as is).
fn spec_from_args(args: &Args) -> Result<SeriesSpec, Box<dyn std::error::Error>> {
    let mut spec = match &args.spec {
        Some(path) => serde_json::from_str(&std::fs::read_to_string(path)?)
            .map_err(|e| format!("{}: {e}", path.display()))?,
        None => SeriesSpec::default(),
    };
    spec.step_secs = args.step_min * 60.0;
    spec.count = args
        .count
        .unwrap_or_else(|| frames_for(args.days, spec.step_secs));
    if let Some(start) = &args.start {
        spec.start = parse_utc(start).ok_or_else(|| format!("--start: cannot read {start:?}"))?;
    }
    spec.seed = args.seed;
    spec.jitter_secs = args.jitter;
    spec.missed_frames = args.missed;
    if args.real_doors.is_some() {
        spec.door_file.clone_from(&args.real_doors);
    }
    let set = |field: &mut usize, value: Option<usize>| {
        if let Some(v) = value {
            *field = v;
        }
    };
    set(&mut spec.real_doors, args.real_door_count);
    set(&mut spec.doors, args.doors);
    set(&mut spec.people, args.people);
    set(&mut spec.chairs, args.chairs);
    set(&mut spec.objects, args.objects);
    set(&mut spec.machines, args.machines);
    let set_f = |field: &mut f64, value: Option<f64>| {
        if let Some(v) = value {
            *field = v;
        }
    };
    set_f(&mut spec.surface_noise, args.noise);
    set_f(&mut spec.partial_probability, args.partial);
    set_f(&mut spec.partial_extent, args.partial_extent);
    spec.validate()?;
    Ok(spec)
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<(), Box<dyn std::error::Error>> {
    let spec = spec_from_args(&args)?;
    let started = Instant::now();
    let base = FormatRegistry::with_default_formats()
        .read_file(&args.base, ReadOptions::default())?
        .map
        .snapshot;
    let read_time = started.elapsed();

    let placing = Instant::now();
    let generator = Generator::new(&base, spec, None)?;
    let place_time = placing.elapsed();
    for warning in generator.warnings() {
        eprintln!("warning: {warning}");
    }
    let spec = generator.spec();
    println!(
        "base:      {} ({} leaves, {} m), read in {:.0?}",
        args.base.display(),
        base.leaves().len(),
        base.resolution(),
        read_time
    );
    if let Some(door) = generator.door_series() {
        println!(
            "doors:     real series {} ({} samples, {} weeks, open {:.1} % of the time)",
            door.source(),
            door.samples(),
            door.weeks(),
            100.0 * door.open_fraction()
        );
    }
    println!("placed in {place_time:.0?}:");
    for element in generator.elements() {
        println!(
            "  {} {}: {} ({} voxels)",
            element.kind,
            element.index,
            element.description,
            element.voxels.len()
        );
    }

    let writing = Instant::now();
    let options = WriteSeriesOptions {
        format: args.format.clone(),
        file_pattern: args.pattern.clone(),
        threads: args.threads,
    };
    let last_report = std::sync::Mutex::new(Instant::now());
    let manifest = write_series(&generator, &args.out, &options, &|done, total| {
        if let Ok(mut last) = last_report.lock() {
            if last.elapsed().as_secs_f64() >= 2.0 || done == total {
                eprintln!("  {done}/{total} frames written");
                *last = Instant::now();
            }
        }
    })?;
    let write_time = writing.elapsed();

    let frames = manifest.entries.len() as u64;
    let summary = generator.change_summary();
    println!(
        "series:    {frames} frames of {} grid frames, {} to {}, every {} s",
        spec.count,
        manifest
            .entries
            .first()
            .map_or_else(String::new, |e| format_utc(e.time)),
        manifest
            .entries
            .last()
            .map_or_else(String::new, |e| format_utc(e.time)),
        spec.step_secs
    );
    println!(
        "written:   {} ({} bytes, {} bytes/frame) in {:.1?}: {:.1} frames/s",
        manifest.manifest_path().display(),
        manifest.total_bytes,
        manifest.total_bytes / frames.max(1),
        write_time,
        frames as f64 / write_time.as_secs_f64()
    );
    println!("changes (distinct voxels over the series; voxel-frames; mean per frame):");
    for kind in &summary.kinds {
        let total = manifest.changes.of(kind.kind);
        println!(
            "  {:<8} {:>2} of {:>2} placed  {:>8} voxels  {:>12} voxel-frames  {:>8.1}/frame",
            kind.kind.name(),
            kind.placed,
            kind.requested,
            kind.voxels,
            total,
            total as f64 / frames.max(1) as f64
        );
    }
    println!(
        "  noise    {:>8} surface voxels  {:>12} flips         {:>8.1}/frame",
        summary.noise_candidates,
        manifest.changes.noise,
        manifest.changes.noise as f64 / frames.max(1) as f64
    );
    let partial_frames = manifest
        .entries
        .iter()
        .filter_map(|e| e.index)
        .filter(|&i| generator.unobserved_region(i).is_some())
        .count();
    println!(
        "  partial  {partial_frames} frames with an unobserved region, {} known voxels hidden in all",
        manifest.changes.unobserved
    );
    println!("total time {:.1?}", started.elapsed());
    Ok(())
}
