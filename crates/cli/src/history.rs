//! `history`: one voxel's observed states over time, its model's p(t), its outliers and its
//! class, as a table, JSON or a plot.

use crate::ui::{escaped, Ui};
use anyhow::Result;
use clap::Args;
use froctomap_convert::{group_thousands, period_text, voxel_history, VoxelHistory};
use froctomap_core::calendar::iso8601;
use froctomap_core::Occupancy;
use froctomap_render::{voxel_plot, Line, VoxelPlot};
use serde_json::{json, Value};
use std::path::PathBuf;

#[derive(Args)]
pub struct HistoryArgs {
    /// The FROctomap file.
    file: PathBuf,
    /// The point, metres in the map's frame: X,Y,Z (e.g. --at=-5.6,0.2,1.0).
    #[arg(long, value_name = "X,Y,Z", value_parser = point, allow_hyphen_values = true)]
    at: Point,
    /// First instant shown (Unix seconds or ISO 8601; default: the file's first sample).
    #[arg(long, value_name = "TIME")]
    from: Option<String>,
    /// Last instant shown, inclusive (default: the file's last sample).
    #[arg(long, value_name = "TIME")]
    to: Option<String>,
    /// Also draw the history as a PNG plot (p(t), observed states, outliers).
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// `--at X,Y,Z`.
#[derive(Clone, Copy, Debug)]
pub struct Point([f64; 3]);

fn point(text: &str) -> Result<Point, String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| "expected X,Y,Z in metres, e.g. 1.5,-2,0.4".to_string())?;
    match values[..] {
        [x, y, z] if values.iter().all(|v| v.is_finite()) => Ok(Point([x, y, z])),
        _ => Err("expected three finite numbers X,Y,Z in metres, e.g. 1.5,-2,0.4".to_string()),
    }
}

fn class_name(history: &VoxelHistory) -> String {
    history.class.name().replace('_', " ")
}

fn state_name(state: Option<Occupancy>) -> &'static str {
    match state {
        Some(Occupancy::Occupied) => "occupied",
        Some(Occupancy::Free) => "free",
        None => "unknown",
    }
}

pub fn history_command(ui: &Ui, args: &HistoryArgs) -> Result<()> {
    let file = ui.context.open_series(&args.file)?;
    let reader = file.whole_history()?;
    let axis = &reader.header().axis;
    let from = args
        .from
        .as_deref()
        .map(|text| ui.time(text, "--from"))
        .transpose()?;
    let to = args
        .to
        .as_deref()
        .map(|text| ui.time(text, "--to"))
        .transpose()?;
    // A missing end is the file's, widened so that a range wholly outside the file's span
    // is reported as such rather than as reversed.
    let range = match (from, to) {
        (None, None) => None,
        (Some(from), None) => Some((from, axis.end().max(from))),
        (None, Some(to)) => Some((axis.start().min(to), to)),
        (Some(from), Some(to)) => Some((from, to)),
    };
    let history = voxel_history(reader, args.at.0, range)?;
    if let Some(output) = &args.output {
        plot(&history, output, &args.file)?;
    }
    if args.json {
        outln!(
            "{}",
            crate::ui::json_report(&as_json(&history, &args.file))?
        )?;
    } else {
        print_table(&history, &args.file)?;
    }
    if let Some(output) = &args.output {
        ui.note(&format!(
            "{}: plot of the history",
            escaped(output.display())
        ));
    }
    Ok(())
}

fn as_json(history: &VoxelHistory, file: &std::path::Path) -> Value {
    let outliers: std::collections::HashSet<u32> =
        history.outliers.iter().map(|s| s.sample).collect();
    json!({
        "file": file,
        "point": history.point,
        "cell": {
            "center": history.cell.center,
            "size": history.cell.size,
            "depth": history.cell.depth,
            "min": history.cell.min,
            "max": history.cell.max,
        },
        "class": history.class,
        "sometimes_unknown": history.sometimes_unknown,
        "model": history.model.as_ref().map(|m| json!({
            "mean": m.mean,
            "periodic": m.periodic.iter().map(|t| json!({
                "period_seconds": t.period_seconds,
                "period": period_text(t.period_seconds),
                "amplitude": t.amplitude,
                "phase_turns": t.phase_turns,
            })).collect::<Vec<_>>(),
        })),
        "samples": history.samples.iter().map(|s| json!({
            "sample": s.sample,
            "time": iso8601(s.time),
            "state": s.state.map(|state| state_name(Some(state))),
            "p": s.p,
            "outlier": outliers.contains(&s.sample),
        })).collect::<Vec<_>>(),
        "outliers": history.outliers.iter().map(|s| iso8601(s.time)).collect::<Vec<_>>(),
    })
}

fn print_table(history: &VoxelHistory, file: &std::path::Path) -> std::io::Result<()> {
    let [x, y, z] = history.point;
    let cell = &history.cell;
    let [cx, cy, cz] = cell.center;
    outln!("file:      {}", escaped(file.display()))?;
    outln!(
        "voxel:     ({x}, {y}, {z}) m, in a cell centred at ({cx:.3}, {cy:.3}, {cz:.3}) m, {:.3} m wide (depth {})",
        cell.size,
        cell.depth
    )?;
    outln!(
        "class:     {}{}",
        class_name(history),
        if history.sometimes_unknown {
            ", sometimes unknown"
        } else {
            ""
        }
    )?;
    if let Some(model) = &history.model {
        let terms: Vec<String> = model
            .periodic
            .iter()
            .map(|t| {
                format!(
                    "{} (amplitude {:.3}, phase {:.3} turns)",
                    period_text(t.period_seconds),
                    t.amplitude,
                    t.phase_turns
                )
            })
            .collect();
        outln!(
            "model:     mean {:.3}; {}",
            model.mean,
            if terms.is_empty() {
                "no periodic terms".to_string()
            } else {
                format!("periods, strongest first: {}", terms.join(", "))
            }
        )?;
    }
    let count =
        |want: Option<Occupancy>| history.samples.iter().filter(|s| s.state == want).count();
    outln!(
        "samples:   {} ({} occupied, {} free, {} unknown), {} outliers",
        group_thousands(history.samples.len() as u64),
        count(Some(Occupancy::Occupied)),
        count(Some(Occupancy::Free)),
        count(None),
        history.outliers.len()
    )?;
    outln!()?;
    outln!("{:<7} {:<22} {:<9} {:>6}", "sample", "time", "state", "p")?;
    let outliers: std::collections::HashSet<u32> =
        history.outliers.iter().map(|s| s.sample).collect();
    for s in &history.samples {
        outln!(
            "{:<7} {:<22} {:<9} {:>6.3}{}",
            s.sample,
            iso8601(s.time),
            state_name(s.state),
            s.p,
            if outliers.contains(&s.sample) {
                "  outlier"
            } else {
                ""
            }
        )?;
    }
    Ok(())
}

fn plot(history: &VoxelHistory, output: &std::path::Path, file: &std::path::Path) -> Result<()> {
    let Some(first) = history.samples.first() else {
        return Ok(());
    };
    let from = first.time;
    let days = |t: froctomap_core::Timestamp| t.secs_since(from) / 86_400.0;
    let curve = Line {
        name: "p(t), the model".to_string(),
        points: history
            .samples
            .iter()
            .map(|s| (days(s.time), s.p))
            .collect(),
    };
    let value = |state: Occupancy| f64::from(u8::from(state.is_occupied()));
    let observed: Vec<(f64, f64)> = history
        .samples
        .iter()
        .filter_map(|s| Some((days(s.time), value(s.state?))))
        .collect();
    let outliers: Vec<(f64, f64)> = history
        .outliers
        .iter()
        .filter_map(|s| Some((days(s.time), value(s.state?))))
        .collect();
    let [x, y, z] = history.point;
    let period = history
        .model
        .as_ref()
        .and_then(|m| m.periodic.first())
        .map_or_else(String::new, |t| {
            format!(", strongest period {}", period_text(t.period_seconds))
        });
    let title = format!(
        "voxel at ({x}, {y}, {z}) m: {}{period}",
        class_name(history)
    );
    let x_label = format!("days since {}", iso8601(from));
    let picture = voxel_plot(&VoxelPlot {
        title: &title,
        x_label: &x_label,
        curves: std::slice::from_ref(&curve),
        observed: &observed,
        observed_label: "observed state (1 occupied, 0 free)",
        outliers: &outliers,
        ..VoxelPlot::default()
    })?;
    picture.write_png(output, &[file])?;
    Ok(())
}
