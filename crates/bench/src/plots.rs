//! PNG plots (plotters, bitmap backend; text through `ab_glyph` with a TTF loaded at run
//! time, so no system font library is needed).

use anyhow::{anyhow, Result};
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::Path;

/// Registers the font as plotters' `sans-serif`. The bytes live for the whole process.
pub fn register_font(bytes: Vec<u8>) -> Result<()> {
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
        .map_err(|_| anyhow!("the plot font is not a TrueType font plotters can use"))
}

/// One named line of `(x, y)` points (shared with the voxel plot of `froctomap-render`).
pub use froctomap_render::Line;

/// A horizontal reference line.
#[derive(Clone, Debug)]
pub struct Level {
    /// Legend.
    pub name: String,
    /// Height.
    pub y: f64,
}

const SIZE: (u32, u32) = (1000, 620);

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

fn err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("plotting: {e}")
}

/// Lines over a numeric x axis with horizontal reference levels; `log_y` for sizes.
pub fn lines(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    lines: &[Line],
    levels: &[Level],
    log_y: bool,
) -> Result<()> {
    let xs = lines.iter().flat_map(|l| l.points.iter().map(|p| p.0));
    let ys: Vec<f64> = lines
        .iter()
        .flat_map(|l| l.points.iter().map(|p| p.1))
        .chain(levels.iter().map(|l| l.y))
        .filter(|y| y.is_finite() && (!log_y || *y > 0.0))
        .collect();
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let (x0, x1) = if x0.is_finite() && x1 > x0 {
        (x0, x1)
    } else {
        (0.0, 1.0)
    };
    let (y0, y1) = ys
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| {
            (a.min(y), b.max(y))
        });
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let pad_x = (x1 - x0) * 0.02;
    let x_range = (x0 - pad_x)..(x1 + pad_x);
    if log_y {
        let (lo, hi) = if y0.is_finite() && y0 > 0.0 {
            (y0 / 2.0, y1 * 2.0)
        } else {
            (1.0, 10.0)
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 24))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d(x_range, (lo..hi).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style(("sans-serif", 15))
            .x_labels(x_ticks(x0, x1))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| short_number(*v))
            .draw()
            .map_err(err)?;
        draw_series(&mut chart, lines, levels, (x0 - pad_x, x1 + pad_x))?;
        draw_legend(&mut chart, 15, SeriesLabelPosition::UpperRight)?;
    } else {
        let (lo, hi) = if y0.is_finite() && y1 >= y0 {
            (0.0f64.min(y0), (y1 * 1.15).max(y0 + 1e-9))
        } else {
            (0.0, 1.0)
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 24))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(x_range, lo..hi)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style(("sans-serif", 15))
            .x_labels(x_ticks(x0, x1))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(err)?;
        draw_series(&mut chart, lines, levels, (x0 - pad_x, x1 + pad_x))?;
        draw_legend(&mut chart, 15, SeriesLabelPosition::UpperRight)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// The legend of every labelled series, in a framed box.
fn draw_legend<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    font_size: u32,
    position: SeriesLabelPosition,
) -> Result<()>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", font_size))
        .position(position)
        .draw()
        .map_err(err)?;
    Ok(())
}

fn draw_series<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    lines: &[Line],
    levels: &[Level],
    x_span: (f64, f64),
) -> Result<()>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    for (i, line) in lines.iter().enumerate() {
        let c = colour(i);
        chart
            .draw_series(LineSeries::new(
                line.points.iter().copied(),
                c.stroke_width(3),
            ))
            .map_err(err)?
            .label(line.name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(3)));
        chart
            .draw_series(line.points.iter().map(|&p| Circle::new(p, 4, c.filled())))
            .map_err(err)?;
    }
    for (k, level) in levels.iter().enumerate() {
        let c = colour(lines.len() + k);
        let style = ShapeStyle {
            color: c.to_rgba(),
            filled: false,
            stroke_width: 2,
        };
        chart
            .draw_series(DashedLineSeries::new(
                [(x_span.0, level.y), (x_span.1, level.y)],
                8,
                6,
                style,
            ))
            .map_err(err)?
            .label(level.name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    Ok(())
}

/// One tick per integer of the x range (the x axes here are model orders).
fn x_ticks(x0: f64, x1: f64) -> usize {
    ((x1 - x0).round().max(1.0) as usize + 1).min(20)
}

/// `1.5M`, `230k`, `12`: axis labels of a log scale.
fn short_number(v: f64) -> String {
    if v >= 1e9 {
        format!("{:.3}G", v / 1e9)
    } else if v >= 1e6 {
        format!("{:.3}M", v / 1e6)
    } else if v >= 1e3 {
        format!("{:.3}k", v / 1e3)
    } else {
        format!("{v:.3}")
    }
    .replace(".000", "")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_numbers() {
        assert_eq!(short_number(2_430_000.0), "2.430M");
        assert_eq!(short_number(1_000_000.0), "1M");
        assert_eq!(short_number(845e6), "845M");
        assert_eq!(short_number(5.0), "5");
    }

    #[test]
    fn plots_are_written_when_the_font_exists() {
        let Ok(font) = std::fs::read(crate::system::FONT) else {
            return; // no font on this machine: main() refuses to start, nothing to test here
        };
        register_font(font).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let line = Line {
            name: "a".into(),
            points: vec![(0.0, 1.0), (1.0, 3.0), (2.0, 2.0)],
        };
        let level = Level {
            name: "b".into(),
            y: 2.5,
        };
        let png = dir.path().join("lines.png");
        let one_line = std::slice::from_ref(&line);
        lines(
            &png,
            "t",
            "x",
            "y",
            one_line,
            std::slice::from_ref(&level),
            false,
        )
        .unwrap();
        lines(&png, "t", "x", "y", one_line, &[level], true).unwrap();
        assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    }
}
