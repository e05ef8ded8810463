//! The subcommands: thin layers over the library crates.

use crate::ui::{escaped, Ui};
use anyhow::Result;
use clap::Args;
use froctomap_convert::{
    describe_map_file, describe_recording, group_thousands, refuse_overwriting_input, MapFileInfo,
    MetricBounds, RecordingInfo, FROCT,
};
use froctomap_core::Snapshot;
use froctomap_formats::{FormatKind, Identified, ReadOptions, WriteOptions};
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct InfoArgs {
    /// The map file: an OctoMap file or a FROctomap file (for format 2.0 also its
    /// segments, their samples and the committed length); or a recording (ROS 1 bag, MCAP
    /// file, ROS 2 bag directory): its topics, types, message counts and log-time spans.
    file: PathBuf,
    /// For a FROctomap file: recount cells from every tile's cell classes instead of
    /// trusting the summary written at build time.
    #[arg(long)]
    count: bool,
    /// Force the input format (see `froctomap formats`) instead of detecting it.
    #[arg(long, value_name = "FORMAT")]
    input_format: Option<String>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

pub fn info(ui: &Ui, args: &InfoArgs) -> Result<()> {
    let registry = ui.context.formats();
    if args.input_format.is_none() {
        if let Some(recording) = describe_recording(ui.context, &args.file)? {
            if args.json {
                outln!("{}", crate::ui::json_report(&recording)?)?;
            } else {
                ui.warn(&args.file, &recording.warnings);
                print_recording(&recording)?;
            }
            return Ok(());
        }
        if let Some(Identified::Series(format)) = registry.identify_file(&args.file)? {
            if format.name == FROCT.name {
                return crate::froct_info::froct_info(ui, &args.file, args.json, args.count);
            }
        }
    }
    let info = describe_map_file(
        ui.context,
        &args.file,
        ReadOptions {
            format: args.input_format.as_deref(),
            backend: Some(ui.backend),
        },
    )?;
    if args.json {
        outln!("{}", crate::ui::json_report(&info)?)?;
    } else {
        ui.warn(&args.file, &info.warnings);
        print_info(&info)?;
    }
    Ok(())
}

/// A recording as `ros2 bag info` shows one: span, messages, then each topic.
fn print_recording(info: &RecordingInfo) -> std::io::Result<()> {
    let n = group_thousands;
    outln!("file:      {}", escaped(info.file.display()))?;
    outln!("format:    {} ({})", info.format, info.format_description)?;
    if let (Some(start), Some(end), Some(duration)) = (&info.start, &info.end, info.duration_s) {
        outln!("start:     {start}")?;
        outln!("end:       {end}")?;
        outln!("duration:  {duration:.3} s")?;
    }
    outln!("messages:  {}", n(info.messages))?;
    outln!("topics:    {}", info.topics.len())?;
    for topic in &info.topics {
        let span = match (&topic.first, &topic.last) {
            (Some(first), Some(last)) if first == last => format!(", at {first}"),
            (Some(first), Some(last)) => format!(", {first} .. {last}"),
            _ => String::new(),
        };
        outln!(
            "  {} [{}, {}]: {} message(s){span}",
            escaped(&topic.topic),
            escaped(&topic.type_name),
            escaped(&topic.encoding),
            n(topic.messages)
        )?;
    }
    Ok(())
}

fn print_info(info: &MapFileInfo) -> std::io::Result<()> {
    let n = group_thousands;
    outln!(
        "file:            {} ({} bytes)",
        escaped(info.file.display()),
        n(info.file_bytes)
    )?;
    outln!(
        "format:          {} ({})",
        info.format,
        info.format_description
    )?;
    outln!("resolution:      {} m", info.resolution_m)?;
    outln!("nodes:           {}", n(info.nodes))?;
    outln!(
        "leaves:          {} (occupied {}, free {})",
        n(info.leaves),
        n(info.occupied_leaves),
        n(info.free_leaves)
    )?;
    outln!(
        "known voxels:    {} (occupied {}, free {})",
        n(info.voxels),
        n(info.occupied_voxels),
        n(info.free_voxels)
    )?;
    let show = |label: &str, bounds: &Option<MetricBounds>| match bounds {
        Some(b) => outln!(
            "{label}x [{:.3}, {:.3}]  y [{:.3}, {:.3}]  z [{:.3}, {:.3}] m",
            b.min[0],
            b.max[0],
            b.min[1],
            b.max[1],
            b.min[2],
            b.max[2]
        ),
        None => outln!("{label}none"),
    };
    show("known bounds:    ", &info.known_bounds_m)?;
    show("occupied bounds: ", &info.occupied_bounds_m)
}

#[derive(Args)]
pub struct ConvertArgs {
    /// The map to read.
    input: PathBuf,
    /// Where to write; its extension chooses the format unless --format is given.
    output: PathBuf,
    /// Output format (see `froctomap formats`).
    #[arg(short, long, value_name = "FORMAT")]
    format: Option<String>,
    /// Force the input format instead of detecting it from the content.
    #[arg(long, value_name = "FORMAT")]
    input_format: Option<String>,
}

pub fn convert(ui: &Ui, args: &ConvertArgs) -> Result<()> {
    refuse_overwriting_input(&args.output, [args.input.as_path()])?;
    let registry = ui.context.formats();
    // Resolve the output format first so a bad output name fails before any work.
    registry.output_format(
        &args.output,
        WriteOptions {
            format: args.format.as_deref(),
            backend: Some(ui.backend),
        },
    )?;
    let read = registry.read_file(
        &args.input,
        ReadOptions {
            format: args.input_format.as_deref(),
            backend: Some(ui.backend),
        },
    )?;
    ui.warn(&args.input, &read.map.warnings);
    let written = registry.write_file(
        &read.map.snapshot,
        &args.output,
        WriteOptions {
            format: args.format.as_deref(),
            backend: Some(ui.backend),
        },
    )?;
    ui.note(&summary(
        &args.input,
        read.format.name,
        &args.output,
        written.name,
        &read.map.snapshot,
    ));
    Ok(())
}

fn summary(input: &Path, from: &str, output: &Path, to: &str, snapshot: &Snapshot) -> String {
    format!(
        "{} ({from}) -> {} ({to}): {} leaves",
        escaped(input.display()),
        escaped(output.display()),
        group_thousands(snapshot.leaves().len() as u64)
    )
}

#[derive(Args)]
pub struct FormatsArgs {
    /// Print JSON: a list of `{name, kind, backend, extensions, read, write, description}`
    /// (what Python's `froctomap.formats()` returns).
    #[arg(long)]
    json: bool,
}

pub fn formats(ui: &Ui, args: &FormatsArgs) -> Result<()> {
    let listing = ui.context.formats().listing();
    if args.json {
        let rows = froctomap_convert::format_listing(ui.context);
        outln!("{}", crate::ui::json_report(&rows)?)?;
        return Ok(());
    }
    outln!(
        "{:<7} {:<8} {:<12} {:<6} description",
        "name",
        "backend",
        "extensions",
        "modes"
    )?;
    for format in &listing {
        let modes = match (format.kind, format.read, format.write) {
            (FormatKind::Series, ..) => "series",
            (FormatKind::Recording, _, true) => "rec,w",
            (FormatKind::Recording, ..) => "rec",
            (_, true, true) => "rw",
            (_, true, false) => "r",
            (_, false, true) => "w",
            (_, false, false) => "-",
        };
        let extensions: Vec<String> = format.extensions.iter().map(|e| format!(".{e}")).collect();
        outln!(
            "{:<7} {:<8} {:<12} {:<6} {}",
            format.name,
            format.backend.map_or("-", |b| b.name()),
            extensions.join(","),
            modes,
            format.description
        )?;
    }
    Ok(())
}
