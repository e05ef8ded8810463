//! `froctomap append`: later snapshots added to a FROctomap file, a thin layer over
//! `froctomap_convert::ingest` (format 1.x: the file rewritten, `IngestTarget::Rewrite`;
//! format 2.0: one segment committed, `IngestTarget::Segment`).

use crate::progress::Bars;
use crate::series::{print_input_notes, tags_metadata, SpillArgs, TimeArgs};
use crate::ui::{escaped, Ui};
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use froctomap_convert::{
    group_thousands, ingest, is_living_file, AppendReport, IngestOptions, IngestTarget,
};
use froctomap_core::calendar::iso8601;
use froctomap_temporal::ModelConfig;
use froctomap_temporal::ModelOptions;
use std::path::PathBuf;

#[derive(Args)]
pub struct AppendArgs {
    /// The FROctomap file to extend (replaced atomically: an append that fails or is
    /// interrupted leaves it as it was).
    #[arg(value_name = "FILE")]
    file: PathBuf,
    /// Snapshots later than the file's last one, as for `build`: directories (their
    /// manifest.csv, else every .bt/.ot file), glob patterns, manifest CSV files
    /// (`path,time`), single files, recordings, or `-`: an MCAP stream on standard input
    /// (spooled into --tmp-dir or the file's directory).
    #[arg(required = true, value_name = "INPUT")]
    inputs: Vec<PathBuf>,
    #[command(flatten)]
    times: TimeArgs,
    /// A model option the file was built with (repeatable). A file does not record the
    /// options of its build, and every model is refitted on the whole history: give the
    /// same --model-option values (--order, --periods … as KEY=VALUE) as the build, or
    /// none for the model's defaults. The model and lossless/lossy come from the file.
    #[arg(long, value_name = "KEY=VALUE")]
    model_option: Vec<String>,
    /// Leave unreadable files, files of another resolution than the file's and damaged
    /// chunks of recordings out (listed at the end) instead of stopping; the first file
    /// whose header gives a resolution must have the file's.
    #[arg(long)]
    skip_bad: bool,
    /// With --skip-bad, append even when more than half of the new inputs are left out.
    #[arg(long, requires = "skip_bad")]
    allow_mostly_skipped: bool,
    /// Force the input map format instead of detecting it.
    #[arg(long, value_name = "FORMAT")]
    input_format: Option<String>,
    /// A key=value tag stored in the file's metadata (repeatable; replaces the file's tags).
    #[arg(long, value_name = "KEY=VALUE")]
    tag: Vec<String>,
    /// Time of the append stored in the file (Unix seconds or ISO 8601) instead of now, for
    /// reproducible files.
    #[arg(long, value_name = "TIME")]
    appended: Option<String>,
    /// Append as format 2.0: a 1.x file is converted first (said on stderr; older
    /// releases cannot read the result) and the snapshots are added as a segment. A 2.0
    /// file always gets a segment: one commit per call, whose cost follows the new
    /// snapshots (the base's models stay frozen, no refit; --model-option is not used), at
    /// times on or off the file's grid. Without it a 1.x file is rebuilt as before.
    #[arg(long, value_enum, value_name = "VERSION")]
    format_version: Option<AppendFormatArg>,
    #[command(flatten)]
    spill: SpillArgs,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// `--format-version` of `append`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum AppendFormatArg {
    /// Segments after a base, committed by a root slot (FORMAT.md §10).
    #[value(name = "2.0")]
    V2_0,
}

pub fn append_command(ui: &Ui, args: &AppendArgs) -> Result<()> {
    if let Some((limit, default)) = args.spill.max_memory.limit() {
        crate::memory_guard::watch(limit, default, "append");
    }
    // Recordings among the inputs are read back through the context that expanded them.
    let spool = crate::series::spool_dir(args.spill.tmp_dir.as_deref(), Some(&args.file));
    crate::series::note_stream(ui, &args.inputs, spool.as_deref());
    let context = &args.times.context(ui, args.skip_bad, spool);
    let collected = args.times.collect(ui, context, &args.inputs)?;
    let inputs = &collected.series;
    let mut model_options = ModelOptions::new();
    for assignment in &args.model_option {
        model_options
            .set_assignment(assignment)
            .context("--model-option")?;
    }
    let metadata = tags_metadata(&args.tag)?;
    let mut config = ModelConfig::default();
    config.options = model_options;
    let options = IngestOptions {
        config,
        skip_bad: args.skip_bad,
        allow_mostly_skipped: args.allow_mostly_skipped,
        input_format: args.input_format.clone(),
        backend: Some(ui.backend),
        metadata,
        time: args
            .appended
            .as_deref()
            .map(|text| ui.time(text, "--appended"))
            .transpose()?,
        memory: args.spill.memory,
        tmp_dir: args.spill.tmp_dir.clone(),
        ..IngestOptions::default()
    };
    ui.note(&format!(
        "appending {} snapshots ({} .. {}) to {}",
        inputs.len(),
        inputs.first().map_or_else(String::new, |i| iso8601(i.time)),
        inputs.last().map_or_else(String::new, |i| iso8601(i.time)),
        escaped(args.file.display()),
    ));
    let living = is_living_file(&args.file)?;
    let as_segment = living || args.format_version == Some(AppendFormatArg::V2_0);
    if as_segment && !args.model_option.is_empty() {
        ui.note("note: --model-option is not used: a segment keeps the base's models (no refit)");
    }
    if as_segment && (!args.tag.is_empty() || args.appended.is_some()) {
        ui.note("note: --tag and --appended are not used: a segment leaves the header as it is");
    }
    if as_segment && !living {
        ui.note(&format!(
            "converting {} to format 2.0 (older releases cannot read it); the snapshots become its first segment",
            escaped(args.file.display())
        ));
    }
    let bars = Bars::new(ui.quiet);
    let target = if as_segment {
        IngestTarget::Segment(&args.file)
    } else {
        IngestTarget::Rewrite(&args.file)
    };
    let report = AppendReport::from(ingest(context, &collected, target, &options, &bars)?);
    drop(bars);
    if args.json {
        outln!("{}", crate::ui::json_report(&report)?)?;
    } else if !ui.quiet {
        let n = group_thousands;
        outln!(
            "appended {} snapshots to {}{}",
            report.added,
            escaped(report.file.display()),
            report
                .segments
                .map_or_else(String::new, |k| format!(" as segment {k}"))
        )?;
        outln!(
            "span:        {} .. {} (was .. {}), {} samples (was {}), {} axis",
            iso8601(report.start),
            iso8601(report.end),
            iso8601(report.end_before),
            report.samples,
            report.samples_before,
            if report.regular_axis {
                "regular"
            } else {
                "explicit"
            }
        )?;
        outln!(
            "size:        {} bytes (was {})",
            n(report.file_bytes),
            n(report.bytes_before)
        )?;
        if report.segments.is_some() {
            outln!(
                "segment:     {} cells, {} toggles (exact: outliers from the base's models, exceptions)",
                n(report.cells.total()),
                n(report.toggles)
            )?;
        } else if report.lossless {
            outln!(
                "outliers:    {} toggles stored (lossless)",
                n(report.toggles)
            )?;
        } else {
            outln!(
                "model error: {} observed cell-samples differ from the input (lossy: the file's past is its reconstruction)",
                n(report.model_errors)
            )?;
        }
        outln!(
            "time:        {:.1} s reading, {:.1} s modelling",
            report.read_seconds,
            report.model_seconds
        )?;
    }
    print_input_notes(ui, &report.warnings, &report.skipped);
    Ok(())
}
