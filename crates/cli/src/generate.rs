//! `froctomap generate`: a realistic, deterministic series of OctoMap snapshots from a real
//! base map (the sample data of the demo, the tests and the benchmarks).

use crate::progress::Bars;
use crate::ui::{escaped, Ui};
use anyhow::{Context as _, Result};
use clap::Args;
use froctomap_convert::group_thousands;
use froctomap_convert::{parse_duration, Progress};
use froctomap_core::calendar::iso8601;
use froctomap_formats::ReadOptions;
use froctomap_ros::McapMapStream;
use froctomap_synth::{
    encode_series, write_series, FrameStats, Generator, SeriesSpec, SpecOverrides, SynthError,
    WriteSeriesOptions,
};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

/// Where Debian's liboctomap-dev puts the FR-079 corridor scan.
pub const GEB079: &str = froctomap_synth::DEBIAN_GEB079;

#[derive(Args)]
pub struct GenerateArgs {
    /// Directory for the snapshots and manifest.csv (created if missing).
    #[arg(short, long, value_name = "DIR", required_unless_present = "stream")]
    output: Option<PathBuf>,
    /// Write no files: the series goes to standard output as an MCAP stream (each map an
    /// octomap_msgs/msg/Octomap message on /octomap_binary, CDR with its ros2msg schema,
    /// logged and stamped at the map's time, each in a chunk of its own flushed as it is
    /// written), for `froctomap build -` or `froctomap record FILE -`:
    /// `froctomap generate --days 1 --stream | froctomap build - -o day.froct`.
    #[arg(long, conflicts_with_all = ["output", "format"])]
    stream: bool,
    /// The real map the series is made from.
    #[arg(long, default_value = GEB079, value_name = "FILE")]
    base: PathBuf,
    /// Length of the series in days.
    #[arg(long, default_value_t = 2.0)]
    days: f64,
    /// Time between snapshots (e.g. 10min, 1h).
    #[arg(long, default_value = "10min", value_name = "DURATION")]
    step: String,
    /// Time of the first snapshot (default 2016-01-04T00:00:00Z, a Monday).
    #[arg(long, value_name = "TIME")]
    start: Option<String>,
    /// Make only the frames at or after TIME of the series: the same maps a run from the
    /// start gives from TIME on, without making the frames before (unlike --start, which
    /// moves the whole series). How a long `generate --stream | record` resumes: give the
    /// recorded file's last sample (`froctomap info`); `record` skips a map it already has.
    #[arg(long, value_name = "TIME")]
    from: Option<String>,
    /// Seed of every random choice; the same seed gives the same series.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Real door recordings (`unix_time state` per line, 1 = open) that drive some doors,
    /// e.g. ../shared/data/greg_door_2016_min/training_data.txt.
    #[arg(long, value_name = "FILE")]
    real_doors: Option<PathBuf>,
    /// Uniform jitter of each snapshot time, in seconds (irregular timestamps).
    #[arg(long, default_value_t = 0.0)]
    jitter: f64,
    /// Probability that a snapshot is missed entirely.
    #[arg(long, default_value_t = 0.0)]
    missed: f64,
    /// Per-snapshot flip probability of surface voxels (sensor noise).
    #[arg(long)]
    noise: Option<f64>,
    /// Probability that a snapshot leaves a region unobserved.
    #[arg(long)]
    partial: Option<f64>,
    /// A JSON scenario (a serialised SeriesSpec) to start from.
    #[arg(long, value_name = "FILE")]
    spec: Option<PathBuf>,
    /// Map format of the snapshots (default bt).
    #[arg(long, value_name = "FORMAT")]
    format: Option<String>,
}

impl GenerateArgs {
    /// `--stream`: the maps go to standard output (and the report to standard error).
    pub fn streams(&self) -> bool {
        self.stream
    }
}

fn spec(ui: &Ui, args: &GenerateArgs) -> Result<SeriesSpec> {
    let scenario = match &args.spec {
        Some(path) => SeriesSpec::from_json_file(path)?,
        None => SeriesSpec::default(),
    };
    let overrides = SpecOverrides {
        step_secs: Some(parse_duration(&args.step)? as f64 / 1e9),
        days: Some(args.days),
        start: args
            .start
            .as_deref()
            .map(|text| ui.time(text, "--start"))
            .transpose()?,
        seed: Some(args.seed),
        jitter_secs: Some(args.jitter),
        missed_frames: Some(args.missed),
        door_file: args.real_doors.clone().map(Some),
        surface_noise: args.noise,
        partial_probability: args.partial,
        ..SpecOverrides::default()
    };
    Ok(overrides.apply(scenario)?)
}

pub fn generate_command(ui: &Ui, args: &GenerateArgs) -> Result<()> {
    if args.stream && std::io::IsTerminal::is_terminal(&std::io::stdout()) {
        anyhow::bail!(
            "--stream writes binary MCAP to standard output, which is a terminal; pipe it into `froctomap build - -o f.froct` or redirect it to a file"
        );
    }
    let spec = spec(ui, args)?;
    let base = ui
        .context
        .formats()
        .read_file(
            &args.base,
            ReadOptions {
                format: None,
                backend: Some(ui.backend),
            },
        )?
        .map
        .snapshot
        .to_max_likelihood();
    let mut generator = Generator::new(&base, spec, None)?;
    if let Some(from) = &args.from {
        generator = generator.with_frames_from(ui.time(from, "--from")?);
    }
    for warning in generator.warnings() {
        ui.note(&format!("warning: {warning}"));
    }
    let bars = Bars::new(ui.quiet);
    bars.stage("writing snapshots", generator.frames().count() as u64);
    // The generator reports totals done so far; the bar wants increments.
    let done_so_far = AtomicU64::new(0);
    let progress = |done: u64, _total: u64| {
        let before = done_so_far.fetch_max(done, Ordering::Relaxed);
        bars.advance(done.saturating_sub(before));
    };
    let Some(output) = &args.output else {
        let (frames, bytes, changes) = stream_series(ui, &generator, &progress)?;
        drop(bars);
        outln!(
            "streamed {} snapshots ({} bytes of maps) as MCAP on standard output",
            group_thousands(frames),
            group_thousands(bytes)
        )?;
        return print_changes(&generator, &changes);
    };
    let options = WriteSeriesOptions {
        format: args.format.clone().unwrap_or_else(|| "bt".to_string()),
        file_pattern: "frame_{time}.{ext}".to_string(),
        threads: 0,
    };
    let manifest = write_series(
        ui.context.formats(),
        &generator,
        output,
        &options,
        &progress,
    )?;
    drop(bars);
    let n = group_thousands;
    let frames = manifest.entries.len() as u64;
    outln!(
        "wrote {} snapshots ({} bytes) and {}",
        n(frames),
        n(manifest.total_bytes),
        escaped(manifest.manifest_path().display())
    )?;
    if let (Some(first), Some(last)) = (manifest.entries.first(), manifest.entries.last()) {
        outln!(
            "time:      {} .. {}",
            iso8601(first.time),
            iso8601(last.time)
        )?;
    }
    print_changes(&generator, &manifest.changes)
}

/// The elements placed and the changes they made.
fn print_changes(generator: &Generator, changes: &FrameStats) -> Result<()> {
    let n = group_thousands;
    let summary = generator.change_summary();
    for kind in &summary.kinds {
        outln!(
            "{:<10} {} placed, {} voxels, {} voxel-changes",
            kind.kind.name(),
            kind.placed,
            n(kind.voxels),
            n(changes.of(kind.kind))
        )?;
    }
    outln!(
        "{:<10} {} surface voxels, {} flips",
        "noise",
        n(summary.noise_candidates),
        n(changes.noise)
    )?;
    Ok(())
}

/// `--stream`: the frames as `.bt` maps in an MCAP stream on standard output; the frames,
/// the maps' bytes and the changes.
fn stream_series(
    ui: &Ui,
    generator: &Generator,
    progress: &dyn Fn(u64, u64),
) -> Result<(u64, u64, FrameStats)> {
    let stdout = std::io::stdout();
    let mut stream = McapMapStream::new(std::io::BufWriter::new(stdout.lock()))?;
    let (mut frames, mut bytes) = (0u64, 0u64);
    let mut changes = FrameStats::default();
    encode_series(
        ui.context.formats(),
        generator,
        "bt",
        0,
        progress,
        &mut |frame, bt, stats| {
            stream
                .write_map(frame.time, &bt)
                .map_err(|e| SynthError::Sink(Box::new(e)))?;
            frames += 1;
            bytes += bt.len() as u64;
            changes.add(&stats);
            Ok(())
        },
    )
    .context("writing the MCAP stream on standard output")?;
    stream
        .finish()
        .context("writing the MCAP stream on standard output")?;
    Ok((frames, bytes, changes))
}
