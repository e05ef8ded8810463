//! One voxel over time: its model's `p(t)` as lines, its states as points at 0 (free) and
//! 1 (occupied), its outliers ringed, and an optional vertical marker (end of training).

use crate::error::{draw_error, RenderError};
use crate::font::ensure_font;
use crate::picture::Picture;
use plotters::prelude::*;

/// One named line of `(x, y)` points.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Line {
    /// Legend.
    pub name: String,
    /// Points.
    pub points: Vec<(f64, f64)>,
}

/// What a voxel plot shows; x is any unit (days, hours) named by `x_label`.
#[derive(Clone, Copy, Debug, Default)]
pub struct VoxelPlot<'a> {
    /// Title.
    pub title: &'a str,
    /// X axis label.
    pub x_label: &'a str,
    /// `p(t)` curves.
    pub curves: &'a [Line],
    /// Observed states (1 = occupied, 0 = free).
    pub observed: &'a [(f64, f64)],
    /// Legend of `observed` (default "observed").
    pub observed_label: &'a str,
    /// Further states, e.g. ground truth of held-out days.
    pub truth: &'a [(f64, f64)],
    /// Legend of `truth` (default "ground truth").
    pub truth_label: &'a str,
    /// Observed states the model alone gets wrong (the outliers a lossless file stores).
    pub outliers: &'a [(f64, f64)],
    /// A vertical dashed line, e.g. where training ends.
    pub marker: Option<f64>,
}

/// Picture size of a voxel plot.
pub const SIZE: (u32, u32) = (1000, 620);

fn colour(i: usize) -> RGBColor {
    const PALETTE: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    PALETTE[i % PALETTE.len()]
}

/// Draws a [`VoxelPlot`].
pub fn voxel_plot(plot: &VoxelPlot<'_>) -> Result<Picture, RenderError> {
    ensure_font()?;
    let xs = plot
        .curves
        .iter()
        .flat_map(|c| c.points.iter().map(|p| p.0))
        .chain(plot.observed.iter().map(|p| p.0))
        .chain(plot.truth.iter().map(|p| p.0))
        .filter(|x| x.is_finite());
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let (x0, x1) = if x0.is_finite() && x1 > x0 {
        (x0, x1)
    } else if x0.is_finite() {
        (x0 - 0.5, x0 + 0.5)
    } else {
        (0.0, 1.0)
    };
    let mut buffer = vec![255u8; SIZE.0 as usize * SIZE.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, SIZE).into_drawing_area();
        let mut chart = ChartBuilder::on(&root)
            .caption(plot.title, ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, -0.08f64..1.3f64)
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .x_desc(plot.x_label)
            .y_desc("p(occupied)")
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(draw_error)?;
        for (i, curve) in plot.curves.iter().enumerate() {
            let c = colour(i);
            chart
                .draw_series(LineSeries::new(
                    curve.points.iter().copied(),
                    c.stroke_width(2),
                ))
                .map_err(draw_error)?
                .label(curve.name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
                });
        }
        let points = [
            (plot.observed, plot.observed_label, "observed"),
            (plot.truth, plot.truth_label, "ground truth"),
        ];
        for (k, (states, label, default)) in points.into_iter().enumerate() {
            if states.is_empty() {
                continue;
            }
            let c = colour(plot.curves.len() + k);
            let label = if label.is_empty() { default } else { label };
            chart
                .draw_series(
                    states
                        .iter()
                        .map(|&(x, y)| Circle::new((x, y), 2, c.filled())),
                )
                .map_err(draw_error)?
                .label(label)
                .legend(move |(x, y)| Circle::new((x + 10, y), 4, c.filled()));
        }
        if !plot.outliers.is_empty() {
            let c = RGBColor(0, 0, 0);
            chart
                .draw_series(
                    plot.outliers
                        .iter()
                        .map(|&(x, y)| Circle::new((x, y), 6, c.stroke_width(1))),
                )
                .map_err(draw_error)?
                .label("outliers (stored exactly)")
                .legend(move |(x, y)| Circle::new((x + 10, y), 6, c.stroke_width(1)));
        }
        if let Some(x) = plot.marker {
            chart
                .draw_series(DashedLineSeries::new(
                    [(x, -0.08), (x, 1.3)],
                    6,
                    4,
                    BLACK.stroke_width(1),
                ))
                .map_err(draw_error)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(draw_error)?;
        root.present().map_err(draw_error)?;
    }
    Picture::from_rgb(SIZE.0, SIZE.1, buffer)
}
