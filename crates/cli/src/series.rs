//! The spatio-temporal commands: build, retrieve, predict, export, eval, and `info` for
//! FROctomap files. Each is a thin layer over `froctomap-convert`.

use crate::froct_info::class_counts;
use crate::plugins::{context, export_format, named, recording_format_of, writable_format};
use crate::progress::{peak_memory_bytes, Bars};
use crate::ui::{escaped, Ui};
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use froctomap_convert::{
    check_range, collect_inputs_explained, evaluate, export, ingest, parse_duration,
    resolve_observed_with, write_observed_map, write_predicted_map, EvalReport, ExportMode,
    ExportOptions, IngestOptions, IngestTarget, Pick, RecordedTime, RecordingOptions,
    RecordingProfile, RecordingWriteOptions, SeriesInput, TimeQuery, TimeSource,
};
use froctomap_convert::{group_thousands, IngestReport, SeriesRead, SkippedInput};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_file::{Codec, ToggleLayout};
use froctomap_formats::{ReadOptions, WriteOptions};
use froctomap_temporal::{ModelConfig, ModelRegistry, OutlierMode};
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How the inputs of a series get their times (shared by `build`, `append` and `eval`).
#[derive(Args, Clone)]
pub struct TimeArgs {
    /// Time of the first file (Unix seconds or ISO 8601), for a plain list of files without
    /// times in their names; needs --step.
    #[arg(long, value_name = "TIME", requires = "step")]
    start: Option<String>,
    /// Time between consecutive files (e.g. 10min, 600, 1.5h), with --start.
    #[arg(long, value_name = "DURATION", requires = "start")]
    step: Option<String>,
    /// Take times from the file names even where a manifest gives them.
    #[arg(long, conflicts_with = "start")]
    times_from_names: bool,
    /// A file of times, one per line (Unix seconds or ISO 8601), for the files in the order
    /// given (directories and globs in natural order: map_2 before map_10).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["start", "times_from_names"])]
    times_file: Option<PathBuf>,
    /// Recordings (ROS 1 .bag, .mcap, ROS 2 bag directories): the topic to read. Default: the
    /// one topic of type octomap_msgs/Octomap.
    #[arg(long, value_name = "NAME")]
    topic: Option<String>,
    /// Recordings: which time a map gets, its message's header stamp (zero stamps take the
    /// log time, with a warning) or the time it was logged.
    #[arg(long, value_name = "SOURCE", value_parser = named::<RecordedTime>(),
          default_value_t = RecordedTime::Header)]
    time_source: RecordedTime,
}

/// The format version `build` writes (`--toggle-block 0` writes 1.0 whatever it says).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum FormatVersionArg {
    /// Range-coded toggle blocks.
    #[value(name = "1.2")]
    V1_2,
    /// Toggle blocks as varints under zstd.
    #[value(name = "1.1")]
    V1_1,
}

impl TimeArgs {
    /// The program's context reading recordings as `--topic` and `--time-source` say,
    /// leaving their damaged chunks out with `skip_bad`.
    /// A stream on standard input (`-`) is spooled in `spool_dir` (else the system's
    /// temporary directory).
    pub(crate) fn context(
        &self,
        ui: &Ui,
        skip_bad: bool,
        spool_dir: Option<PathBuf>,
    ) -> froctomap_convert::Context {
        ui.context.clone().with_recording_options(
            RecordingOptions::new(self.topic.clone(), self.time_source)
                .with_skip_bad(skip_bad)
                .with_spool_dir(spool_dir),
        )
    }

    /// `inputs` as a series read through `context` with these times, their warnings and
    /// zoneless times told.
    pub(crate) fn collect(
        &self,
        ui: &Ui,
        context: &froctomap_convert::Context,
        inputs: &[PathBuf],
    ) -> Result<froctomap_convert::CollectedInputs> {
        let collected = collect_inputs_explained(context, inputs, self.source(ui)?, &ui.zone)?;
        ui.read_zoneless(collected.zoneless);
        for warning in &collected.warnings {
            ui.note(&format!("warning: {}", escaped(warning)));
        }
        Ok(collected)
    }

    pub(crate) fn source(&self, ui: &Ui) -> Result<TimeSource> {
        if let Some(list) = &self.times_file {
            return Ok(TimeSource::TimesFile(list.clone()));
        }
        Ok(match (&self.start, &self.step) {
            (Some(start), Some(step)) => TimeSource::StartStep {
                start: ui.time(start, "--start")?,
                step_ns: parse_duration(step)?,
            },
            _ if self.times_from_names => TimeSource::FileNames,
            _ => TimeSource::Auto,
        })
    }
}

/// `--model`: a name of the registry's models.
fn model_name(name: &str) -> Result<String, String> {
    let registry = context().models();
    match registry.by_name(name) {
        Some(descriptor) => Ok(descriptor.name.to_string()),
        None => Err(format!(
            "unknown model (registered: {})",
            registry
                .iter()
                .map(|d| d.name)
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// `--help` for `--model`: every registered model with its description and options.
fn models_help() -> String {
    let mut help = String::from(
        "Temporal model of dynamic voxels, and the options each accepts \
         (--model-option KEY=VALUE; default in brackets):\n",
    );
    for d in context().models().iter() {
        help.push_str(&format!("\n{}: {}\n", d.name, d.description));
        for o in d.options {
            help.push_str(&format!("    {} [{}]: {}\n", o.key, o.default, o.help));
        }
    }
    help
}

#[derive(Args)]
pub struct BuildArgs {
    /// Snapshots: directories (their manifest.csv, else every .bt/.ot file), glob patterns,
    /// manifest CSV files (`path,time`), single files, recordings (ROS 1 .bag, .mcap, ROS 2
    /// bag directories), or `-`: an MCAP stream on standard input (`froctomap generate
    /// --stream | froctomap build - -o f.froct`), read to its end first, its maps spooled
    /// into --tmp-dir or the output's directory, never held in memory.
    #[arg(required = true, value_name = "INPUT")]
    inputs: Vec<PathBuf>,
    /// The FROctomap file to write (not needed with --dry-run).
    #[arg(short, long, value_name = "FILE", required_unless_present = "dry_run")]
    output: Option<PathBuf>,
    #[command(flatten)]
    times: TimeArgs,
    /// Temporal model of dynamic voxels (`--help` lists the models and their options).
    #[arg(long, default_value = froctomap_temporal::models::DEFAULT_MODEL, value_name = "NAME",
          value_parser = model_name, long_help = models_help())]
    model: String,
    /// A model option (repeatable; `--help` on --model lists them).
    #[arg(long, value_name = "KEY=VALUE")]
    model_option: Vec<String>,
    /// Shorthand for `--model-option order=…`: spectral components per voxel, a number, or
    /// `auto` to choose per voxel up to --max-order (the default).
    #[arg(long, value_name = "N|auto")]
    order: Option<String>,
    /// Shorthand for `--model-option max-order=…`: highest order `--order auto` tries (default 8; above 5 only where validated).
    #[arg(long, value_name = "N")]
    max_order: Option<u8>,
    /// Shorthand for `--model-option criterion=…`: how `--order auto` chooses,
    /// `prediction` (the order that predicts held-out samples best; the default) or `size`
    /// (the smallest encoding, lossless only).
    #[arg(long, value_name = "prediction|size")]
    criterion: Option<String>,
    /// Keep every observed state exactly (the default).
    #[arg(long, conflicts_with = "lossy")]
    lossless: bool,
    /// Keep only the models: much smaller, states approximate (the error is reported).
    #[arg(long)]
    lossy: bool,
    /// Shorthand for `--model-option periods=…`: extra candidate periods, in seconds or with
    /// units (e.g. 1d,8h,45min).
    #[arg(long, value_delimiter = ',', value_name = "DURATION")]
    periods: Vec<String>,
    /// Tile depth: tiles are cubes of 2^(16 - depth) voxels per edge.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u8).range(1..=16))]
    tile_depth: u8,
    /// zstd level for tiles (1-22; 0 stores tiles uncompressed).
    #[arg(long, default_value_t = 19, value_parser = clap::value_parser!(i8).range(0..=22))]
    zstd_level: i8,
    /// Samples per block of stored toggles (format 1.1 and later): a retrieval reads one
    /// block, so smaller blocks make it faster and the file slightly larger. 0 stores whole
    /// toggle lists (format 1.0, for readers that only know that version).
    #[arg(long, default_value_t = 256, value_name = "SAMPLES")]
    toggle_block: u32,
    /// Format version to write: 1.2 range codes the toggle blocks (the smallest files);
    /// 1.1 stores them as varints under zstd, for readers that only know 1.1.
    #[arg(long, value_enum, default_value = "1.2", value_name = "VERSION")]
    format_version: FormatVersionArg,
    /// Leave unreadable files, files of another resolution and damaged chunks of recordings
    /// out (listed at the end) instead of stopping.
    #[arg(long)]
    skip_bad: bool,
    /// The series' resolution in metres; inputs of another resolution are refused (or left
    /// out with --skip-bad). Default: the resolution most inputs have.
    #[arg(long, value_name = "METRES")]
    resolution: Option<f64>,
    /// With --skip-bad, build even when more than half of the inputs are left out.
    #[arg(long, requires = "skip_bad")]
    allow_mostly_skipped: bool,
    /// Force the input map format instead of detecting it.
    #[arg(long, value_name = "FORMAT")]
    input_format: Option<String>,
    /// A key=value tag stored in the file's metadata (repeatable).
    #[arg(long, value_name = "KEY=VALUE")]
    tag: Vec<String>,
    /// Creation time stored in the file (Unix seconds or ISO 8601) instead of now, for
    /// reproducible files; SOURCE_DATE_EPOCH (Unix seconds) does the same when this is not
    /// given.
    #[arg(long, value_name = "TIME")]
    created: Option<String>,
    #[command(flatten)]
    spill: SpillArgs,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// List each input with its time and where the time came from, then stop without
    /// writing anything.
    #[arg(long)]
    dry_run: bool,
}

/// Where and beyond how much memory a build or an append spills the accumulated histories.
#[derive(Args, Debug)]
pub(crate) struct SpillArgs {
    /// Memory for the accumulated histories (e.g. 64MiB, 2GiB, 4G, or bytes). What grows
    /// with the number of snapshots is spilled to disk beyond it and read back tile by tile,
    /// so long series build in bounded memory; the file is the same whatever the budget.
    /// Reading and fitting need memory on top of it.
    #[arg(long, value_name = "SIZE", default_value = "64MiB", value_parser = byte_size)]
    pub(crate) memory: u64,
    /// The most resident memory the whole command may use (reading, accumulating, fitting;
    /// e.g. 2GiB): past it, it stops with an error and writes nothing, instead of failing
    /// an allocation. Default `auto`: three quarters of the physical memory, or half of the
    /// address-space limit (`ulimit -v`) when that is less; `none` (or 0): no bound beyond
    /// the system's.
    #[arg(long, value_name = "SIZE", default_value = "auto", value_parser = max_memory)]
    pub(crate) max_memory: MaxMemory,
    /// Directory for the spill data (default: the output's directory). It goes into a
    /// hidden .froct-spill-* directory there, removed when the build ends, fails or is
    /// stopped by Ctrl-C/SIGTERM.
    #[arg(long, value_name = "DIR")]
    pub(crate) tmp_dir: Option<PathBuf>,
}

/// `--memory`: bytes, or a number with a unit (K/M/G/T, binary whatever the spelling:
/// `512M`, `512MiB` and `512MB` are all 512 × 2^20 bytes).
/// `--max-memory`: a size, the default bound from the machine, or none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MaxMemory {
    Auto,
    Unbounded,
    Bytes(u64),
}

impl MaxMemory {
    /// The bound in bytes, and whether it is the default one.
    pub(crate) fn limit(self) -> Option<(u64, bool)> {
        match self {
            Self::Auto => crate::memory_guard::default_limit().map(|limit| (limit, true)),
            Self::Unbounded => None,
            Self::Bytes(limit) => Some((limit, false)),
        }
    }
}

fn max_memory(text: &str) -> Result<MaxMemory, String> {
    match text.trim() {
        "auto" => Ok(MaxMemory::Auto),
        "none" => Ok(MaxMemory::Unbounded),
        size => Ok(match byte_size(size)? {
            0 => MaxMemory::Unbounded,
            bytes => MaxMemory::Bytes(bytes),
        }),
    }
}

/// `--tile-budget` of the verbs that compact (`compact`, `record`).
#[derive(Args, Clone, Debug)]
pub(crate) struct TileBudgetArgs {
    /// The history (its cells' observation runs, packed; e.g. 32MiB, the default) past which
    /// a compaction writes tiles one level deeper (an eighth of the volume; down to depth
    /// 15), or `none`. Compared with the largest tile's history as the last build or
    /// compaction measured it, grown with the maps since: the compactions after the one that
    /// deepens hold smaller tiles, so their memory stays bounded however long the file grows,
    /// for a larger file (1.06× one level deeper, 1.21× two, on 32 h of the generated
    /// office). `compact --tile-depth` chooses instead. `none`: keep the file's depth.
    #[arg(long, value_name = "SIZE", default_value = "32MiB", value_parser = tile_budget)]
    pub(crate) tile_budget: TileBudget,
}

/// A tile budget, or none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct TileBudget(pub(crate) Option<u64>);

/// `--tile-budget` (and the node's `tile_budget` parameter): a size, or `none`.
pub(crate) fn tile_budget(text: &str) -> Result<TileBudget, String> {
    match text.trim() {
        "none" => Ok(TileBudget(None)),
        text => match byte_size(text)? {
            0 => Err("a positive size, or none".into()),
            bytes => Ok(TileBudget(Some(bytes))),
        },
    }
}

pub(crate) fn byte_size(text: &str) -> Result<u64, String> {
    let text = text.trim();
    let digits = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(digits);
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        _ => return Err("expected bytes or a size such as 512MiB, 2GiB, 4G".into()),
    };
    let value: f64 = number
        .parse()
        .map_err(|_| "expected a number of bytes, e.g. 512MiB or 2GiB".to_string())?;
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 0.0 && bytes < u64::MAX as f64) {
        return Err("out of range".into());
    }
    Ok(bytes as u64)
}

fn model_config(args: &BuildArgs, models: &ModelRegistry) -> Result<ModelConfig> {
    let descriptor = models
        .by_name(&args.model)
        .with_context(|| format!("--model {}: not a registered model", args.model))?;
    let mut config = ModelConfig::default().with_outliers(if args.lossy {
        OutlierMode::Lossy
    } else {
        OutlierMode::Lossless
    });
    for assignment in &args.model_option {
        config
            .options
            .set_assignment(assignment)
            .context("--model-option")?;
    }
    let periods = args
        .periods
        .iter()
        .map(|p| parse_duration(p).map(|ns| (ns as f64 / 1e9).to_string()))
        .collect::<Result<Vec<_>, _>>()?;
    let shorthands = [
        ("--order", "order", args.order.clone()),
        (
            "--max-order",
            "max-order",
            args.max_order.map(|n| n.to_string()),
        ),
        ("--criterion", "criterion", args.criterion.clone()),
        (
            "--periods",
            "periods",
            (!periods.is_empty()).then(|| periods.join(",")),
        ),
    ];
    for (flag, key, value) in shorthands {
        let Some(value) = value else { continue };
        if !descriptor.options.iter().any(|o| o.key == key) {
            anyhow::bail!(
                "{flag}: model {} has no option {key} (see --help on --model)",
                descriptor.name
            );
        }
        config.options.set(key, value);
    }
    descriptor.create().check_options(&config.options)?;
    Ok(config)
}

/// `--created`, else SOURCE_DATE_EPOCH (reproducible-builds.org: whole Unix seconds).
fn creation_time(ui: &Ui, args: &BuildArgs) -> Result<Option<Timestamp>> {
    if let Some(text) = &args.created {
        return Ok(Some(ui.time(text, "--created")?));
    }
    let Some(epoch) = std::env::var_os("SOURCE_DATE_EPOCH") else {
        return Ok(None);
    };
    let seconds = epoch
        .to_str()
        .and_then(|text| text.trim().parse::<i64>().ok())
        .with_context(|| format!("SOURCE_DATE_EPOCH={epoch:?} is not a whole number of seconds"))?;
    let created = Timestamp::from_secs(seconds);
    check_range("SOURCE_DATE_EPOCH", created)?;
    Ok(Some(created))
}

/// Says that a stream among `inputs` is read to its end before anything else happens
/// (which may take as long as its writer runs).
pub(crate) fn note_stream(ui: &Ui, inputs: &[PathBuf], spool: Option<&Path>) {
    if inputs
        .iter()
        .any(|i| i.as_os_str() == froctomap_convert::STDIN_INPUT)
    {
        let spool = spool.map_or_else(std::env::temp_dir, Path::to_path_buf);
        ui.note(&format!(
            "reading the stream on standard input to its end (its maps spooled in {})",
            escaped(spool.display())
        ));
    }
}

/// Where a stream on standard input is spooled: `--tmp-dir`, else the output's directory
/// (the system's temporary directory when the output is a stream itself).
pub(crate) fn spool_dir(tmp_dir: Option<&Path>, output: Option<&Path>) -> Option<PathBuf> {
    if let Some(dir) = tmp_dir {
        return Some(dir.to_path_buf());
    }
    let output = output.filter(|o| !froctomap_core::is_stream_output(o))?;
    Some(froctomap_convert::output_dir(output).to_path_buf())
}

fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
}

pub fn build_command(ui: &Ui, args: &BuildArgs) -> Result<()> {
    let started = Instant::now();
    if let Some((limit, default)) = args.spill.max_memory.limit() {
        crate::memory_guard::watch(limit, default, "build");
    }
    // Recordings among the inputs are read back through the context that expanded them.
    let spool = spool_dir(args.spill.tmp_dir.as_deref(), args.output.as_deref());
    note_stream(ui, &args.inputs, spool.as_deref());
    let series_context = &args.times.context(ui, args.skip_bad, spool);
    let collected = args.times.collect(ui, series_context, &args.inputs)?;
    if args.dry_run {
        for (input, origin) in collected.series.iter().zip(&collected.origins) {
            outln!(
                "{}  {:<12}  {}",
                iso8601(input.time),
                origin.to_string(),
                escaped(input.path.display())
            )?;
        }
        return Ok(());
    }
    let inputs = &collected.series;
    let output = args
        .output
        .as_deref()
        .context("--output is required to build")?;
    let options = build_options(ui, args)?;
    ui.note(&format!(
        "building {} from {} snapshots ({} .. {})",
        escaped(output.display()),
        inputs.len(),
        inputs.first().map_or_else(String::new, |i| iso8601(i.time)),
        inputs.last().map_or_else(String::new, |i| iso8601(i.time)),
    ));
    let bars = Bars::new(ui.quiet);
    let target = IngestTarget::NewFile(output);
    let report = ingest(series_context, &collected, target, &options, &bars)?;
    drop(bars);
    let peak = peak_memory_bytes();
    if args.json {
        let mut value = serde_json::to_value(&report)?;
        if let Value::Object(map) = &mut value {
            map.insert("peak_memory_bytes".into(), Value::from(peak));
            map.insert(
                "seconds".into(),
                Value::from(started.elapsed().as_secs_f64()),
            );
        }
        outln!("{}", crate::ui::json_report(&value)?)?;
    } else if !ui.quiet {
        print_built(args, &report, peak)?;
    }
    print_input_notes(ui, &report.warnings, &report.skipped);
    Ok(())
}

/// `build`'s settings from its command line.
fn build_options(ui: &Ui, args: &BuildArgs) -> Result<IngestOptions> {
    let metadata = tags_metadata(&args.tag)?;
    Ok(IngestOptions {
        model: args.model.clone(),
        config: model_config(args, context().models())?,
        tile_depth: args.tile_depth,
        codec: if args.zstd_level == 0 {
            Codec::Raw
        } else {
            Codec::Zstd {
                level: args.zstd_level,
            }
        },
        toggles: match (args.toggle_block, args.format_version) {
            (0, _) => ToggleLayout::Whole,
            (samples, FormatVersionArg::V1_1) => ToggleLayout::Blocked(samples),
            (samples, FormatVersionArg::V1_2) => ToggleLayout::Coded(samples),
        },
        skip_bad: args.skip_bad,
        resolution: args.resolution,
        allow_mostly_skipped: args.allow_mostly_skipped,
        input_format: args.input_format.clone(),
        backend: Some(ui.backend),
        metadata,
        time: creation_time(ui, args)?,
        memory: args.spill.memory,
        tmp_dir: args.spill.tmp_dir.clone(),
        ..IngestOptions::default()
    })
}

/// The report of a build, for people: what was written, from what, and what it cost.
fn print_built(args: &BuildArgs, report: &IngestReport, peak: Option<u64>) -> Result<()> {
    let n = group_thousands;
    outln!(
        "wrote {} ({} bytes)",
        escaped(report.output.display()),
        n(report.file_bytes)
    )?;
    outln!(
        "snapshots:   {} used of {} ({} samples, {} axis)",
        report.used,
        report.inputs,
        report.samples,
        if report.regular_axis {
            "regular"
        } else {
            "explicit"
        }
    )?;
    outln!("cells:       {}", class_counts(&report.cells))?;
    outln!(
        "voxels:      {} ({} dynamic)",
        n(report.voxels.total()),
        n(report.voxels.dynamic)
    )?;
    outln!(
        "size:        {} bytes from {} input bytes: {}",
        n(report.file_bytes),
        n(report.input_bytes),
        size_ratio(report.file_bytes, report.input_bytes)
    )?;
    if args.lossy {
        outln!(
            "model error: {} observed cell-samples differ from the input (lossy)",
            n(report.model_errors)
        )?;
    } else {
        outln!(
            "outliers:    {} toggles stored (lossless)",
            n(report.toggles)
        )?;
    }
    outln!(
        "time:        {:.1} s reading, {:.1} s modelling{}",
        report.read_seconds,
        report.model_seconds,
        peak.map_or_else(String::new, |p| format!("; peak memory {}", mib(p)))
    )?;
    if report.spilled_bytes > 0 {
        outln!(
            "spilled:     {} of history to disk to stay within --memory ({} spills)",
            mib(report.spilled_bytes),
            report.spills
        )?;
    }
    Ok(())
}

/// How the output's size compares with the inputs': `4.2x smaller`, or, for a series too
/// small for the file's own structure to pay off, `3.9x larger`.
fn size_ratio(output: u64, inputs: u64) -> String {
    if output <= inputs {
        format!("{:.1}x smaller", inputs as f64 / output.max(1) as f64)
    } else {
        format!("{:.1}x larger", output as f64 / inputs.max(1) as f64)
    }
}

#[derive(Args)]
pub struct RetrieveArgs {
    /// The FROctomap file.
    file: PathBuf,
    /// When: Unix seconds, ISO 8601 (`2016-01-04T08:30:00Z`), a sample index (`index:42`,
    /// `index:-1` or `last` for the last). Between snapshots, the last earlier one is used
    /// (see --nearest).
    #[arg(long, value_name = "TIME")]
    time: String,
    /// Between snapshots, take the closest one, earlier or later (before the first, the
    /// first).
    #[arg(long)]
    nearest: bool,
    #[command(flatten)]
    output: MapOutput,
}

/// Where a map goes and in which format (shared by `retrieve` and `predict`).
#[derive(Args)]
pub struct MapOutput {
    /// The map to write; its extension names the format unless --format does (.bt: the
    /// states; .ot: log-odds, for `predict` those of p(t)).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Output format instead of the one the extension names (see `froctomap formats`).
    #[arg(long, value_parser = writable_format())]
    format: Option<String>,
    /// Print what was written as JSON (on standard error when the map goes to standard
    /// output, `-o -`).
    #[arg(long)]
    json: bool,
}

impl MapOutput {
    fn options(&self, ui: &Ui) -> WriteOptions<'_> {
        WriteOptions {
            format: self.format.as_deref(),
            backend: Some(ui.backend),
        }
    }
}

pub fn retrieve_command(ui: &Ui, args: &RetrieveArgs) -> Result<()> {
    let reader = ui.context.open_series(&args.file)?;
    let query = ui.time_query(&args.time)?;
    let pick = if args.nearest {
        Pick::Nearest
    } else {
        Pick::AtOrBefore
    };
    let when = resolve_observed_with(&reader, query, pick)?;
    let (start, end) = (reader.first_instant(), reader.last_instant());
    if let TimeQuery::Instant(t) = query {
        if t > end || t < start {
            ui.note(&format!(
                "warning: {} is outside the file's span {} .. {}; this is the {} snapshot as observed, not a prediction (see `froctomap predict`)",
                iso8601(t),
                iso8601(start),
                iso8601(end),
                if t > end { "last" } else { "first" }
            ));
        } else if !when.exact {
            ui.note(&format!(
                "no snapshot at {}; using the {}, at {}",
                escaped(&args.time),
                if args.nearest {
                    "nearest one"
                } else {
                    "last one before it"
                },
                iso8601(when.time)
            ));
        }
    }
    let output = &args.output.output;
    let written = write_observed_map(
        ui.context,
        &reader,
        when.sample,
        output,
        args.output.options(ui),
    )?;
    if args.output.json {
        outln!(
            "{}",
            crate::ui::json_report(&serde_json::json!({
                "output": output,
                "format": written.format.name,
                "kind": "observed",
                "time": iso8601(when.time),
                "sample": when.sample,
                "exact": when.exact,
                "leaves": written.leaves,
            }))?
        )?;
        return Ok(());
    }
    ui.note(&format!(
        "{} ({}): map observed at {} (sample {}), {} leaves",
        escaped(output.display()),
        written.format.name,
        iso8601(when.time),
        when.sample,
        group_thousands(written.leaves as u64)
    ));
    Ok(())
}

#[derive(Args)]
pub struct PredictArgs {
    /// The FROctomap file.
    file: PathBuf,
    /// When: Unix seconds or ISO 8601, past or future.
    #[arg(long, value_name = "TIME")]
    time: String,
    #[command(flatten)]
    output: MapOutput,
}

pub fn predict_command(ui: &Ui, args: &PredictArgs) -> Result<()> {
    let reader = ui.context.open_series(&args.file)?;
    let samples = reader.sample_count();
    let sample = match ui.time_query(&args.time)? {
        TimeQuery::Instant(t) => Ok(t),
        TimeQuery::Sample(s) => Err(Some(s)),
        TimeQuery::FromEnd(back) => Err(samples.checked_sub(back)),
    };
    let t = match sample {
        Ok(t) => t,
        Err(sample) => sample.and_then(|s| reader.sample_time(s)).with_context(|| {
            format!(
                "{}: no such sample; {} has {} samples (index:0 .. index:{}, or index:-1 .. index:-{})",
                escaped(&args.time),
                escaped(args.file.display()),
                samples,
                samples.saturating_sub(1),
                samples
            )
        })?,
    };
    let output = &args.output.output;
    let written = write_predicted_map(ui.context, &reader, t, output, args.output.options(ui))?;
    let (start, end) = (reader.first_instant(), reader.last_instant());
    let relation = if t > end {
        format!(
            "{:.1} days after the last snapshot",
            t.secs_since(end) / 86_400.0
        )
    } else if t < start {
        format!(
            "{:.1} days before the first snapshot",
            start.secs_since(t) / 86_400.0
        )
    } else {
        "within the modelled span".to_string()
    };
    if args.output.json {
        outln!(
            "{}",
            crate::ui::json_report(&serde_json::json!({
                "output": output,
                "format": written.format.name,
                "kind": "predicted",
                "time": iso8601(t),
                "within_span": t >= start && t <= end,
                "leaves": written.leaves,
            }))?
        )?;
        return Ok(());
    }
    ui.note(&format!(
        "{} ({}): map predicted for {} ({relation}), {} leaves",
        escaped(output.display()),
        written.format.name,
        iso8601(t),
        group_thousands(written.leaves as u64)
    ));
    Ok(())
}

#[derive(Args)]
pub struct ExportArgs {
    /// The FROctomap file.
    file: PathBuf,
    /// First instant (Unix seconds or ISO 8601).
    #[arg(long, value_name = "TIME")]
    from: String,
    /// Last instant, inclusive: a map is written at --to itself when it lies on the grid
    /// --from + i × --every (later grid points are not).
    #[arg(long, value_name = "TIME")]
    to: String,
    /// Interval between maps (e.g. 1h, 10min, 600).
    #[arg(long, value_name = "DURATION")]
    every: String,
    /// Directory for the maps and manifest.csv (created if missing); for a recording format
    /// (--format mcap or rosbag, or an output named *.mcap or *.bag), the one file holding
    /// every map; for --format ros2bag, the ROS 2 bag directory to make (it must not exist).
    #[arg(short, long, value_name = "DIR|FILE")]
    output: PathBuf,
    /// Predicted maps (one per instant), retrieved snapshots (each snapshot seen at the
    /// instants once, named and listed at its own time), or auto: retrieved inside the
    /// file's span, predicted outside it.
    #[arg(long, value_parser = named::<ExportMode>(), default_value_t = ExportMode::Predict)]
    mode: ExportMode,
    /// Map format (see `froctomap formats`), or `mcap`: one MCAP file with the maps as
    /// octomap_msgs/msg/Octomap on /octomap_binary (for ros2 bag play), their occupied
    /// voxels as a sensor_msgs/msg/PointCloud2 on /froctomap/occupied_voxels_pc2 (for rviz2,
    /// Rerun) and their occupied cells as a visualization_msgs/msg/MarkerArray on
    /// /froctomap/occupied_cells_vis_array (CUBE_LIST per depth, for rviz2); see --profile.
    /// Or `rosbag`: a ROS 1 bag with the maps as octomap_msgs/Octomap on /octomap_binary (for
    /// rosbag play). Or `ros2bag`: a new ROS 2 bag directory OUT holding metadata.yaml and
    /// OUT_0.mcap (MCAP storage: the messages of `mcap`, ros2 profile only) for ros2 bag
    /// play/info. Default: mcap for an output named *.mcap, rosbag for *.bag, else bt (never
    /// ros2bag: a directory output is a directory of maps unless --format ros2bag).
    #[arg(long, value_parser = export_format())]
    format: Option<String>,
    /// File name prefix.
    #[arg(long, default_value = "map")]
    prefix: String,
    /// Which messages a recording holds: ros2, CDR only (every message decodes with
    /// ROS 2's tools and mcap-ros2-support); foxglove, also a foxglove.PointCloud on
    /// /froctomap/occupied_voxels and foxglove.SceneUpdate cubes sized by the cell on
    /// /froctomap/occupied_cubes (JSON, for Foxglove's 3D panel; MCAP files only).
    #[arg(long, value_parser = named::<RecordingProfile>(), default_value_t = RecordingProfile::Ros2)]
    profile: RecordingProfile,
    /// Recordings: the frame_id of every message (e.g. --frame-id odom).
    #[arg(long, value_name = "FRAME", default_value = "map")]
    frame_id: String,
    /// Recordings: put before every topic name, e.g. --topic-prefix /robot1 writes
    /// /robot1/octomap_binary, /robot1/froctomap/occupied_voxels_pc2…
    #[arg(long, value_name = "PREFIX", default_value = "")]
    topic_prefix: String,
    /// Recordings: draw a predicted cell (point clouds, markers, cubes) where its
    /// probability is above P, e.g. --threshold 0.2 to show uncertain space too; the maps
    /// themselves hold p > 0.5 as occupied.
    #[arg(long, value_name = "P", default_value_t = 0.5)]
    threshold: f64,
    /// Write into a directory that already holds files, replacing those of the same names.
    #[arg(long)]
    overwrite: bool,
    /// The most the export may write (e.g. 20GiB): an export whose estimated size is larger
    /// is refused before it starts (docs/LIMITS.md).
    #[arg(long, value_name = "SIZE", default_value = "2GiB", value_parser = byte_size)]
    max_output: u64,
    /// Print what was written as JSON: every map's path and time, the manifest, the bytes
    /// (on standard error when the maps go to standard output, `-o -`).
    #[arg(long)]
    json: bool,
}

/// A rough size of one exported map: a `.bt` costs about half a byte per leaf (the
/// file's cells are an upper bound on a map's leaves); an MCAP file adds the occupied
/// voxels' two point clouds (about five times the map in the generated office), and so does
/// a ROS 2 bag (an MCAP file inside).
fn estimated_map_bytes(reader: &dyn SeriesRead, format: &str) -> u64 {
    let cells: u64 = reader
        .predicted_tiles()
        .iter()
        .map(|&(_, cells)| cells as u64)
        .sum();
    let bt = cells / 2 + 64;
    if matches!(format, "mcap" | "ros2bag") {
        bt * 5
    } else {
        bt
    }
}

/// Refuses what cannot be exported: sqlite3 ROS 2 bags, and an export larger than `--max-output` or
/// than the free space where it goes. Says how many maps and about how many bytes first.
fn check_export(
    ui: &Ui,
    args: &ExportArgs,
    reader: &dyn SeriesRead,
    options: &ExportOptions,
) -> Result<()> {
    let extension = args
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if extension.as_deref() == Some("db3") {
        anyhow::bail!(
            "{}: froctomap does not write sqlite3 ROS 2 bags; export to a ROS 2 bag \
             directory with MCAP storage (--format ros2bag), a .mcap file (`ros2 bag play` \
             reads both), a ROS 1 .bag or a directory of maps",
            escaped(args.output.display())
        );
    }
    let span = options.to.secs_since(options.from).max(0.0);
    let every = options.every_ns.max(1) as f64 / 1e9;
    // Saturating: a span of centuries at 1 ns counts u64::MAX maps, and is refused.
    let maps = (span / every).floor() as u64 + 1;
    let bytes = maps.saturating_mul(estimated_map_bytes(reader, &options.format));
    // With --json the report says what was written; with `-o -` it shares standard error
    // with notes, and must be the whole of it.
    if !args.json {
        ui.note(&format!(
            "exporting up to {} maps, about {}",
            group_thousands(maps),
            mib(bytes)
        ));
    }
    if bytes > args.max_output {
        anyhow::bail!(
            "{}: the export would write about {} ({} maps), more than --max-output {}; \
             pass a larger --max-output, or a shorter span or longer --every",
            escaped(args.output.display()),
            mib(bytes),
            group_thousands(maps),
            mib(args.max_output)
        );
    }
    if !froctomap_core::is_stream_output(&args.output) {
        let dir = match args.output.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => std::path::Path::new("."),
        };
        if let Ok(stat) = rustix::fs::statvfs(dir) {
            let free = stat.f_bavail.saturating_mul(stat.f_frsize);
            if bytes > free {
                anyhow::bail!(
                    "{}: the export would write about {}, and {} holds {} free",
                    escaped(args.output.display()),
                    mib(bytes),
                    escaped(dir.display()),
                    mib(free)
                );
            }
        }
    }
    Ok(())
}

pub fn export_command(ui: &Ui, args: &ExportArgs) -> Result<()> {
    let reader = ui.context.open_series(&args.file)?;
    let options = ExportOptions {
        from: ui.time(&args.from, "--from")?,
        to: ui.time(&args.to, "--to")?,
        every_ns: parse_duration(&args.every)?,
        mode: args.mode,
        format: args
            .format
            .clone()
            .or_else(|| recording_format_of(&args.output).map(str::to_string))
            .unwrap_or_else(|| "bt".to_string()),
        backend: Some(ui.backend),
        prefix: args.prefix.clone(),
        overwrite: args.overwrite,
        recording: RecordingWriteOptions::default()
            .with_profile(args.profile)
            .with_frame_id(args.frame_id.clone())
            .with_topic_prefix(args.topic_prefix.clone())
            .with_threshold(args.threshold),
    };
    check_export(ui, args, &reader, &options)?;
    let bars = Bars::new(ui.quiet);
    let report = export(ui.context, &reader, &args.output, &options, &bars)?;
    drop(bars);
    if args.json {
        let files: Vec<Value> = report
            .files
            .iter()
            .map(|input| serde_json::json!({"path": input.path, "time": iso8601(input.time)}))
            .collect();
        outln!(
            "{}",
            crate::ui::json_report(&serde_json::json!({
                "output": args.output,
                "format": options.format,
                "maps": files,
                "manifest": report.manifest,
                "bytes": report.bytes,
            }))?
        )?;
        return Ok(());
    }
    match &report.manifest {
        Some(manifest) => ui.note(&format!(
            "wrote {} maps ({} bytes) and {}",
            report.files.len(),
            group_thousands(report.bytes),
            escaped(manifest.display())
        )),
        None => ui.note(&format!(
            "wrote {} maps into {} ({}, {} bytes)",
            report.files.len(),
            escaped(args.output.display()),
            options.format,
            group_thousands(report.bytes)
        )),
    }
    Ok(())
}

#[derive(Args)]
pub struct EvalArgs {
    /// The FROctomap file.
    file: PathBuf,
    /// Ground-truth maps (directories, globs, manifests, files, recordings: ROS 1 bags,
    /// MCAP files, ROS 2 bag directories), e.g. later snapshots.
    #[arg(long, required = true, num_args = 1.., value_name = "INPUT")]
    against: Vec<PathBuf>,
    #[command(flatten)]
    times: TimeArgs,
    /// Compare every Nth ground-truth map in time order (the 1st, the N+1th, …): each map
    /// compared is held in memory and checked against every cell of the file (the file is
    /// walked once per 256 MiB of maps), so a long held-out series (days at 5 s) is better
    /// sampled. The others are still listed (a stream on standard input is read to its end).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    stride: u64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
    /// Also draw the reliability diagram of the dynamic voxels (observed occupied fraction
    /// per bin of p, per method; of the prediction maps, else of the reconstruction ones)
    /// into this PNG.
    #[arg(long, value_name = "PNG")]
    png: Option<PathBuf>,
}

pub fn eval_command(ui: &Ui, args: &EvalArgs) -> Result<()> {
    let file = ui.context.open_series(&args.file)?;
    let reader = file.whole_history()?;
    // Recordings among the ground truths are read with --topic/--time-source.
    let context = args.times.context(ui, false, None);
    let collected = args.times.collect(ui, &context, &args.against)?;
    // In time order: inputs are collected sorted by time.
    let stride = usize::try_from(args.stride).unwrap_or(usize::MAX);
    let truths: Vec<SeriesInput> = collected.series.into_iter().step_by(stride).collect();
    let bars = Bars::new(ui.quiet);
    let report = evaluate(
        &context,
        reader,
        &truths,
        ReadOptions {
            format: None,
            backend: Some(ui.backend),
        },
        &bars,
    )?;
    drop(bars);
    if let Some(png) = &args.png {
        let mut inputs: Vec<&std::path::Path> = vec![args.file.as_path()];
        inputs.extend(args.against.iter().map(PathBuf::as_path));
        reliability_diagram(&report)?.write_png(png, &inputs)?;
        ui.note(&format!("{}: reliability diagram", escaped(png.display())));
    }
    if args.json {
        outln!("{}", crate::ui::json_report(&report)?)?;
    } else {
        print_eval(&report)?;
    }
    Ok(())
}

/// The calibration of the prediction maps (of the reconstruction ones when there are none)
/// and its title.
fn calibration_shown(
    report: &EvalReport,
) -> (&'static str, &[(String, froctomap_convert::Calibration)]) {
    if report.outside > 0 {
        ("prediction", &report.prediction_calibration)
    } else {
        ("reconstruction", &report.reconstruction_calibration)
    }
}

/// Observed occupied fraction against mean p per non-empty bin, per method, with the
/// diagonal of perfect calibration.
fn reliability_diagram(report: &EvalReport) -> Result<froctomap_render::Picture> {
    use froctomap_render::{voxel_plot, Line, VoxelPlot};
    let (section, calibration) = calibration_shown(report);
    let mut curves = vec![Line {
        name: "perfectly calibrated".into(),
        points: vec![(0.0, 0.0), (1.0, 1.0)],
    }];
    curves.extend(calibration.iter().map(|(method, c)| {
        Line {
            name: method.clone(),
            points: c
                .bins()
                .iter()
                .filter_map(|b| Some((b.mean_p?, b.occupied_fraction?)))
                .collect(),
        }
    }));
    let title = format!("reliability of p, dynamic voxels, {section}");
    Ok(voxel_plot(&VoxelPlot {
        title: &title,
        x_label: "predicted p (mean of the bin)",
        curves: &curves,
        ..VoxelPlot::default()
    })?)
}

fn print_eval(report: &EvalReport) -> std::io::Result<()> {
    let cell = |rate: &froctomap_convert::Rate| {
        rate.percent()
            .map_or_else(|| "-".to_string(), |p| format!("{p:.2} %"))
    };
    let scores = |rate: &froctomap_convert::Rate| match (rate.brier(), rate.log_loss()) {
        (Some(b), Some(l)) => format!("{b:.4} / {l:.4}"),
        _ => "-".to_string(),
    };
    outln!(
        "error rates (wrong voxels / compared voxels), then Brier score / log loss \
         (p clipped to [{e}, 1 - {e}]):\n",
        e = report.log_loss_epsilon
    )?;
    for (title, rows, n) in [
        (
            "reconstruction (inside the modelled span)",
            &report.reconstruction,
            report.inside,
        ),
        (
            "prediction (outside the modelled span)",
            &report.prediction,
            report.outside,
        ),
    ] {
        outln!("{title}: {n} ground-truth maps")?;
        if n == 0 {
            outln!()?;
            continue;
        }
        outln!("| method | all voxels | non-empty | dynamic |")?;
        outln!("| --- | ---: | ---: | ---: |")?;
        for (method, rates) in rows.iter() {
            outln!(
                "| {method} | {} | {} | {} |",
                cell(&rates.all),
                cell(&rates.non_empty),
                cell(&rates.dynamic)
            )?;
        }
        outln!()?;
        outln!("| method | Brier / log loss, all | non-empty | dynamic |")?;
        outln!("| --- | ---: | ---: | ---: |")?;
        for (method, rates) in rows.iter() {
            outln!(
                "| {method} | {} | {} | {} |",
                scores(&rates.all),
                scores(&rates.non_empty),
                scores(&rates.dynamic)
            )?;
        }
        outln!()?;
    }
    let (section, calibration) = calibration_shown(report);
    if report.inside + report.outside > 0 {
        outln!("calibration, {section}, dynamic voxels (mean p → occupied fraction, voxels):")?;
        let names: Vec<&str> = calibration.iter().map(|(m, _)| m.as_str()).collect();
        outln!("| p | {} |", names.join(" | "))?;
        outln!("| --- |{}", " ---: |".repeat(names.len()))?;
        let bins: Vec<_> = calibration.iter().map(|(_, c)| c.bins()).collect();
        for i in 0..froctomap_convert::CALIBRATION_BINS {
            let Some(first) = bins.first().and_then(|b| b.get(i)) else {
                break;
            };
            let row: Vec<String> = bins
                .iter()
                .filter_map(|b| b.get(i))
                .map(|b| match (b.mean_p, b.occupied_fraction) {
                    (Some(p), Some(f)) => {
                        format!("{p:.2} → {f:.2} ({})", group_thousands(b.voxels))
                    }
                    _ => "-".to_string(),
                })
                .collect();
            outln!(
                "| {:.1}-{:.1} | {} |",
                first.lower,
                first.upper,
                row.join(" | ")
            )?;
        }
        outln!()?;
    }
    if report.unmodelled_voxels > 0 {
        outln!(
            "{} ground-truth voxels were never observed in the file's data (not compared)",
            group_thousands(report.unmodelled_voxels)
        )?;
    }
    Ok(())
}

/// The readers' warnings (the first ten) and the files left out, after a build or an append.
pub(crate) fn print_input_notes(ui: &Ui, warnings: &[(PathBuf, String)], skipped: &[SkippedInput]) {
    if !warnings.is_empty() && !ui.quiet {
        for (path, warning) in warnings.iter().take(10) {
            eprintln!("warning: {}: {}", escaped(path.display()), escaped(warning));
        }
        if warnings.len() > 10 {
            eprintln!("warning: ... and {} more warnings", warnings.len() - 10);
        }
    }
    if !skipped.is_empty() {
        eprintln!("skipped {} file(s) or recorded map(s):", skipped.len());
        for input in skipped {
            eprintln!("  {}", escaped(input));
        }
    }
}

/// `--tag KEY=VALUE`s as the header metadata of a build or an append (`tags`: an object).
pub(crate) fn tags_metadata(tags: &[String]) -> Result<Map<String, Value>> {
    let mut metadata = Map::new();
    let mut pairs = Map::new();
    for tag in tags {
        let (k, v) = tag
            .split_once('=')
            .with_context(|| format!("--tag {tag:?}: expected KEY=VALUE"))?;
        pairs.insert(k.to_string(), Value::from(v));
    }
    if !pairs.is_empty() {
        metadata.insert("tags".into(), Value::Object(pairs));
    }
    Ok(metadata)
}

#[cfg(test)]
mod tests {
    use super::{byte_size, tile_budget, TileBudget};

    #[test]
    fn a_tile_budget_is_a_positive_size_or_none() {
        assert_eq!(tile_budget("32MiB"), Ok(TileBudget(Some(32 << 20))));
        assert_eq!(tile_budget(" none "), Ok(TileBudget(None)));
        assert!(tile_budget("0").unwrap_err().contains("or none"));
        assert!(tile_budget("lots").is_err());
    }

    #[test]
    fn memory_sizes_read_with_binary_units() {
        assert_eq!(byte_size("1GiB"), Ok(1 << 30));
        assert_eq!(byte_size("512M"), Ok(512 << 20));
        assert_eq!(byte_size("1.5 kb"), Ok(1536));
        assert_eq!(byte_size("0"), Ok(0));
        assert!(byte_size("lots").is_err());
        assert!(byte_size("5 parsecs").is_err());
        assert!(byte_size("99999999999T").is_err());
    }
}
