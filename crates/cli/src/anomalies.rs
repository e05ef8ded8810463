//! `anomalies`: what a snapshot shows that the file's model did not expect at its time.

use crate::plugins::named;
use crate::ui::{escaped, Ui};
use anyhow::{bail, Context as _, Result};
use clap::Args;
use froctomap_convert::{
    anomalies, collect_inputs, read_snapshot, read_time_from_file_name, refuse_overwriting_input,
    write_owned_map, AnomalyKind, AnomalyOptions, AnomalyReport, Expectation, TimeSource,
    MANIFEST_NAME,
};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_formats::WriteOptions;
use serde_json::json;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct AnomaliesArgs {
    /// The FROctomap file (the model).
    file: PathBuf,
    /// The snapshot to score (.bt/.ot), of the file's resolution.
    snapshot: PathBuf,
    /// The snapshot's time: Unix seconds or ISO 8601. Default: from its file name (as
    /// `build` reads names), else from a manifest.csv beside it that lists it.
    #[arg(long, value_name = "TIME")]
    time: Option<String>,
    /// Print the regions as JSON.
    #[arg(long)]
    json: bool,
    /// Write the anomalous voxels of the reported regions as an OctoMap file (.bt/.ot) for
    /// rviz or octovis, every voxel occupied (appeared and vanished alike).
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Draw the map at the snapshot's time from above (as `render` does) with each reported
    /// region's footprint outlined: red appeared, blue vanished.
    #[arg(long, value_name = "FILE")]
    png: Option<PathBuf>,
    /// Width of the --png picture, pixels.
    #[arg(long, value_name = "PIXELS", default_value_t = froctomap_render::DEFAULT_WIDTH)]
    width: u32,
    /// How often a static cell's stored state is taken to be wrong (and how close to 0 or
    /// 1 a model's p may get).
    #[arg(long, value_name = "RATE", default_value_t = AnomalyOptions::default().error_rate)]
    error_rate: f64,
    /// A voxel is surprising when the model gave its observed state less than this
    /// probability.
    #[arg(long, value_name = "P", default_value_t = (-AnomalyOptions::default().voxel_threshold).exp())]
    voxel_probability: f64,
    /// Regions whose total surprise (nats, −ln p summed over their voxels) is below this
    /// are not reported.
    #[arg(long, value_name = "NATS", default_value_t = AnomalyOptions::default().min_region_score)]
    min_score: f64,
    /// What the snapshot is compared with: the model at its time, or a baseline (each
    /// cell's mean over the history; the last snapshot at or before the time).
    #[arg(long, value_parser = named::<Expectation>(), default_value_t = Expectation::Model)]
    expect: Expectation,
    /// Print at most this many regions (all of them with --json or 0).
    #[arg(long, value_name = "N", default_value_t = 20)]
    top: usize,
}

impl AnomaliesArgs {
    fn options(&self) -> Result<AnomalyOptions> {
        if !(self.voxel_probability > 0.0 && self.voxel_probability < 1.0) {
            bail!(
                "--voxel-probability {}: give a probability between 0 and 1 (exclusive)",
                self.voxel_probability
            );
        }
        let mut options = AnomalyOptions::default();
        options.error_rate = self.error_rate;
        options.voxel_threshold = -self.voxel_probability.ln();
        options.min_region_score = self.min_score;
        options.expectation = self.expect;
        Ok(options)
    }
}

pub fn anomalies_command(ui: &Ui, args: &AnomaliesArgs) -> Result<()> {
    let options = args.options()?;
    let file = ui.context.open_series(&args.file)?;
    let reader = file.whole_history()?;
    let t = snapshot_time(ui, args)?;
    let snapshot = read_snapshot(ui.context, reader, &args.snapshot)?;
    let axis = &reader.header().axis;
    if t > axis.end() {
        ui.note(&format!(
            "note: {} is after the file's span {} .. {}: the snapshot is scored against the model's prediction",
            iso8601(t),
            iso8601(axis.start()),
            iso8601(axis.end())
        ));
    }
    let report = anomalies(reader, &snapshot, t, &options)?;
    if let Some(output) = &args.output {
        refuse_overwriting_input(output, [args.file.as_path(), args.snapshot.as_path()])?;
        let map = report.to_map(reader.header().resolution)?;
        let written = write_owned_map(
            ui.context,
            map,
            output,
            WriteOptions {
                format: None,
                backend: Some(ui.backend),
            },
        )?;
        ui.note(&format!(
            "{} ({}): the anomalous voxels of {} region(s)",
            escaped(output.display()),
            written.format.name,
            report.regions.len()
        ));
    }
    if let Some(png) = &args.png {
        write_overlay(reader, &report, t, png, args)?;
        ui.note(&format!(
            "{}: the map at {} with {} region(s) outlined",
            escaped(png.display()),
            iso8601(t),
            report.regions.len()
        ));
    }
    if args.json {
        outln!("{}", crate::ui::json_report(&report_json(args, &report))?)?;
    } else {
        print_table(args, &report)?;
    }
    Ok(())
}

/// `--time`, else the snapshot's file name, else a manifest beside it.
fn snapshot_time(ui: &Ui, args: &AnomaliesArgs) -> Result<Timestamp> {
    if let Some(text) = &args.time {
        return ui.time(text, "--time");
    }
    let name = args
        .snapshot
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    if let Some(read) = read_time_from_file_name(&name, &ui.zone) {
        ui.read_zoneless(read.zoneless);
        return Ok(read.time);
    }
    if let Some(t) = time_from_manifest(ui, &args.snapshot)? {
        return Ok(t);
    }
    bail!(
        "{}: no time in the file name, and no {MANIFEST_NAME} beside it lists it; give --time",
        escaped(args.snapshot.display())
    )
}

fn time_from_manifest(ui: &Ui, snapshot: &Path) -> Result<Option<Timestamp>> {
    let dir = snapshot.parent().filter(|d| !d.as_os_str().is_empty());
    let manifest = dir.unwrap_or(Path::new(".")).join(MANIFEST_NAME);
    if !manifest.is_file() {
        return Ok(None);
    }
    let inputs = collect_inputs(
        ui.context,
        std::slice::from_ref(&manifest),
        TimeSource::Auto,
    )
    .with_context(|| format!("reading the time of {}", escaped(snapshot.display())))?;
    let wanted = std::fs::canonicalize(snapshot).ok();
    Ok(inputs
        .iter()
        .find(|input| std::fs::canonicalize(&input.path).ok() == wanted && wanted.is_some())
        .map(|input| input.time))
}

fn report_json(args: &AnomaliesArgs, report: &AnomalyReport) -> serde_json::Value {
    json!({
        "file": args.file.display().to_string(),
        "snapshot": args.snapshot.display().to_string(),
        "time": iso8601(report.time),
        "unix_time": report.time.as_secs_f64(),
        "scored_voxels": report.scored_voxels,
        "surprising_voxels": report.surprising_voxels,
        "regions": report.regions,
    })
}

fn print_table(args: &AnomaliesArgs, report: &AnomalyReport) -> Result<()> {
    outln!(
        "{} scored against {} at {}: {} region(s) of {} observed voxels",
        escaped(args.snapshot.display()),
        escaped(args.file.display()),
        iso8601(report.time),
        report.regions.len(),
        report.scored_voxels
    )?;
    if report.regions.is_empty() {
        return Ok(());
    }
    outln!(
        "{:>4}  {:<8}  {:>9}  {:>7}  {:<26}  {:<26}",
        "rank",
        "kind",
        "score",
        "voxels",
        "min (m)",
        "max (m)"
    )?;
    let shown = if args.top == 0 {
        report.regions.len()
    } else {
        args.top
    };
    let corner = |c: [f64; 3]| format!("({:.2}, {:.2}, {:.2})", c[0], c[1], c[2]);
    for (rank, region) in report.regions.iter().take(shown).enumerate() {
        let kind = region.kind.name();
        outln!(
            "{:>4}  {:<8}  {:>9.1}  {:>7}  {:<26}  {:<26}",
            rank + 1,
            kind,
            region.score,
            region.voxels,
            corner(region.min),
            corner(region.max)
        )?;
    }
    if report.regions.len() > shown {
        outln!(
            "… and {} more (--top 0 shows all)",
            report.regions.len() - shown
        )?;
    }
    Ok(())
}

/// Appeared regions' outline colour.
const APPEARED: [u8; 3] = [220, 20, 60];
/// Vanished regions' outline colour.
const VANISHED: [u8; 3] = [30, 100, 255];

/// `--png`: the top-down map at `t` (retrieved inside the file's span, predicted outside)
/// with each region's footprint outlined, written atomically.
fn write_overlay(
    reader: &froctomap_file::FroctReader,
    report: &AnomalyReport,
    t: Timestamp,
    path: &Path,
    args: &AnomaliesArgs,
) -> Result<()> {
    use froctomap_render::{render_map, MapTime, View};
    refuse_overwriting_input(path, [args.file.as_path(), args.snapshot.as_path()])?;
    let when = MapTime::choose(reader, froctomap_convert::TimeQuery::Instant(t))?;
    let picture = render_map(reader, when, View::TopDown, args.width)?;
    let mut image = picture.image().clone();
    if let Some(frame) = picture.frame() {
        // Most surprising last, so that it is drawn on top.
        for region in report.regions.iter().rev() {
            let colour = match region.kind {
                AnomalyKind::Vanished => VANISHED,
                _ => APPEARED,
            };
            let column = |x: f64| {
                let px = ((x - frame.min_x) * frame.pixels_per_metre).floor();
                frame.left + px.clamp(0.0, f64::from(frame.width - 1)) as u32
            };
            let row = |y: f64| {
                let py = ((frame.max_y - y) * frame.pixels_per_metre).floor();
                frame.top + py.clamp(0.0, f64::from(frame.height - 1)) as u32
            };
            let (x0, x1) = (column(region.min[0]), column(region.max[0]));
            let (y0, y1) = (row(region.max[1]), row(region.min[1]));
            // At least a few pixels across, so that a small region stays visible.
            let (x0, x1) = (x0.saturating_sub(2), (x1 + 2).min(image.width() - 1));
            let (y0, y1) = (y0.saturating_sub(2), (y1 + 2).min(image.height() - 1));
            for x in x0..=x1 {
                for y in [y0, y0 + 1, y1.saturating_sub(1), y1] {
                    image.put_pixel(x, y.min(image.height() - 1), image::Rgb(colour));
                }
            }
            for y in y0..=y1 {
                for x in [x0, x0 + 1, x1.saturating_sub(1), x1] {
                    image.put_pixel(x.min(image.width() - 1), y, image::Rgb(colour));
                }
            }
        }
    }
    let mut bytes = Vec::new();
    {
        use image::codecs::png::{CompressionType, FilterType, PngEncoder};
        use image::ImageEncoder as _;
        PngEncoder::new_with_quality(&mut bytes, CompressionType::Best, FilterType::Adaptive)
            .write_image(
                image.as_raw(),
                image.width(),
                image.height(),
                image::ColorType::Rgb8,
            )?;
    }
    froctomap_core::write_atomically(path, |out| out.write_all(&bytes))?;
    Ok(())
}
