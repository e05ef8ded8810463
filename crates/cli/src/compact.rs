//! `froctomap compact`: a FROctomap file's base and segments rewritten as one base, a thin
//! layer over `froctomap_convert::compact`.

use crate::progress::Bars;
use crate::series::{SpillArgs, TileBudgetArgs};
use crate::ui::{escaped, Ui};
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use froctomap_convert::{compact, group_thousands, CompactFormat, CompactOptions};
use froctomap_file::ToggleLayout;
use froctomap_temporal::ModelOptions;
use std::path::PathBuf;

/// `--format-version` of `compact`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum CompactVersionArg {
    /// A living map without segments (append and record add segments to it).
    #[value(name = "2.0")]
    V2_0,
    /// Range-coded toggle blocks, for readers of 1.2.
    #[value(name = "1.2")]
    V1_2,
    /// Toggle blocks as varints under zstd, for readers of 1.1.
    #[value(name = "1.1")]
    V1_1,
}

#[derive(Args)]
pub struct CompactArgs {
    /// The FROctomap file to compact (format 2.0, or 1.x to rebuild it). Without -o it is
    /// replaced atomically, and a compaction that fails or is interrupted leaves it as it
    /// was; a 2.0 file is also held under its writer lock meanwhile, so an append to it
    /// fails instead of committing a segment the result would lose (a 1.x file has no lock).
    #[arg(value_name = "FILE")]
    file: PathBuf,
    /// Write the compacted file here instead of replacing FILE.
    #[arg(short, long, value_name = "OUT")]
    output: Option<PathBuf>,
    /// Format of the result: 2.0 (a living map with one base, no segment) or a 1.x file for
    /// older readers.
    #[arg(long, value_enum, default_value = "2.0", value_name = "VERSION")]
    format_version: CompactVersionArg,
    /// A model option the file was built with (repeatable): every model is refitted on the
    /// whole history, and a file does not record the options of its build (as for append).
    #[arg(long, value_name = "KEY=VALUE")]
    model_option: Vec<String>,
    /// Creation time stored in the file (Unix seconds or ISO 8601) instead of now, for
    /// reproducible files.
    #[arg(long, value_name = "TIME")]
    created: Option<String>,
    #[command(flatten)]
    spill: SpillArgs,
    /// Write the models without the outlier set, as `build --lossy` (the paper's compact
    /// file: its past is the models' reconstruction); only into another file (-o), the
    /// file itself is left whole.
    #[arg(long)]
    lossy: bool,
    /// Tiles of the result: cubes of 2^(16 − depth) voxels per edge; the file's depth or
    /// deeper (default: the file's, or one deeper as --tile-budget decides). Compacting (and building) holds one tile's whole
    /// history at a time, which grows with the history: a file that grows for months keeps
    /// its compactions' memory down in smaller tiles (each level deeper: an eighth of the
    /// volume). The result equals a build at that depth.
    #[arg(long, value_name = "DEPTH", value_parser = clap::value_parser!(u8).range(1..=16))]
    tile_depth: Option<u8>,
    #[command(flatten)]
    tile_budget: TileBudgetArgs,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

pub fn compact_command(ui: &Ui, args: &CompactArgs) -> Result<()> {
    if let Some((limit, default)) = args.spill.max_memory.limit() {
        crate::memory_guard::watch(limit, default, "compact");
    }
    let mut model_options = ModelOptions::new();
    for assignment in &args.model_option {
        model_options
            .set_assignment(assignment)
            .context("--model-option")?;
    }
    let block = |layout: fn(u32) -> ToggleLayout| {
        // The base's block length; only the layout changes.
        let file = ui.context.open_series(&args.file)?;
        let samples = froctomap_convert::SeriesRead::header(&file)
            .toggles
            .block_len()
            .unwrap_or(256);
        anyhow::Ok(Some(layout(samples)))
    };
    let format = match args.format_version {
        CompactVersionArg::V2_0 => CompactFormat::Living,
        CompactVersionArg::V1_2 => CompactFormat::Flat(block(ToggleLayout::Coded)?),
        CompactVersionArg::V1_1 => CompactFormat::Flat(block(ToggleLayout::Blocked)?),
    };
    let options = CompactOptions {
        model_options,
        format,
        created: args
            .created
            .as_deref()
            .map(|text| ui.time(text, "--created"))
            .transpose()?,
        memory: args.spill.memory,
        tmp_dir: args.spill.tmp_dir.clone(),
        lossy: args.lossy,
        tile_depth: args.tile_depth,
        tile_budget: args.tile_budget.tile_budget.0,
        ..CompactOptions::default()
    };
    ui.note(&format!("compacting {}", escaped(args.file.display())));
    let bars = Bars::new(ui.quiet);
    let report = compact(
        ui.context,
        &args.file,
        args.output.as_deref(),
        &options,
        &bars,
    )?;
    drop(bars);
    if report.version_before.starts_with("1.") && report.version.starts_with("2.") {
        ui.note(&format!(
            "note: {} is now FROctomap {} (it was {}); for readers of 1.x only, compact with --format-version 1.2 (or 1.1)",
            escaped(report.output.display()),
            report.version,
            report.version_before,
        ));
    }
    if args.json {
        outln!("{}", crate::ui::json_report(&report)?)?;
        return Ok(());
    }
    if ui.quiet {
        return Ok(());
    }
    let n = group_thousands;
    outln!(
        "compacted {} (format {}, {} segment(s)) into {} (format {}, one base)",
        escaped(report.file.display()),
        report.version_before,
        report.segments_before,
        escaped(report.output.display()),
        report.version
    )?;
    outln!(
        "maps:        {} refitted ({} samples)",
        n(report.maps as u64),
        n(u64::from(report.samples))
    )?;
    outln!(
        "size:        {} bytes (was {})",
        n(report.bytes),
        n(report.bytes_before)
    )?;
    if report.tile_depth != report.tile_depth_before {
        outln!(
            "tiles:       depth {} (was {}){}",
            report.tile_depth,
            report.tile_depth_before,
            match args.tile_depth {
                Some(_) => "",
                None => ": the largest tile's history passed --tile-budget",
            }
        )?;
    }
    outln!("time:        {:.1} s", report.seconds)?;
    Ok(())
}
