//! `render`: a picture of a FROctomap file (froctomap-render).

use crate::ui::{escaped, Ui};
use anyhow::Result;
use clap::Args;
use froctomap_core::calendar::iso8601;
use froctomap_render::{render_dynamics, render_map, MapTime, View, DEFAULT_WIDTH};
use std::path::PathBuf;

#[derive(Args)]
pub struct RenderArgs {
    /// The FROctomap file.
    file: PathBuf,
    /// When: Unix seconds, ISO 8601 or a sample index (`index:42`, `last`). Inside the
    /// file's span the map is the snapshot observed then (the last one at or before it);
    /// outside it, the prediction (p(t) > 0.5).
    #[arg(long, value_name = "TIME", required_unless_present = "dynamics")]
    time: Option<String>,
    /// The PNG picture to write.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// A horizontal cut at a height in metres instead of the view from above, e.g. z=0.5.
    #[arg(long, value_name = "z=HEIGHT", conflicts_with = "dynamics")]
    slice: Option<String>,
    /// Where the world changes instead of the map at one time: per column, the strongest
    /// period of its modelled voxels as colour (day, week, shift…) and the fraction of time
    /// they are occupied as its strength; static structure in grey.
    #[arg(long, conflicts_with = "time")]
    dynamics: bool,
    /// Picture width in pixels (the height follows the map's shape).
    #[arg(long, default_value_t = DEFAULT_WIDTH, value_name = "PIXELS")]
    width: u32,
}

pub fn render_command(ui: &Ui, args: &RenderArgs) -> Result<()> {
    let view = match &args.slice {
        Some(text) => View::slice(text)?,
        None => View::TopDown,
    };
    let file = ui.context.open_series(&args.file)?;
    let reader = file.whole_history()?;
    let (picture, what) = match &args.time {
        Some(time) if !args.dynamics => {
            let when = MapTime::choose(reader, ui.time_query(time)?)?;
            let picture = render_map(reader, when, view, args.width)?;
            let what = match when {
                MapTime::Retrieved { sample, time, .. } => {
                    format!("map retrieved at {} (sample {sample})", iso8601(time))
                }
                MapTime::Predicted(t) => {
                    format!("map predicted for {} (outside the file's span)", iso8601(t))
                }
                _ => "map".to_string(),
            };
            (picture, what)
        }
        _ => (
            render_dynamics(reader, args.width)?,
            "where the world changes".to_string(),
        ),
    };
    picture.write_png(&args.output, &[args.file.as_path()])?;
    ui.note(&format!(
        "{}: {what}, {} x {} px",
        escaped(args.output.display()),
        picture.image().width(),
        picture.image().height()
    ));
    Ok(())
}
