//! A picture of a map: the columns' colours scaled into a frame, a title, a metre scale and
//! a legend, drawn with plotters into one RGB buffer and written as PNG atomically.

use crate::error::{draw_error, RenderError};
use crate::font::ensure_font;
use crate::grid::Grid;
use froctomap_convert::refuse_overwriting_input;
use froctomap_core::write_atomically;
use image::RgbImage;
use plotters::prelude::*;
use std::path::Path;

/// Narrowest picture drawn, pixels.
pub const MIN_WIDTH: u32 = 300;
/// Widest picture drawn, pixels.
pub const MAX_WIDTH: u32 = 8000;
/// Default width (fits a README).
pub const DEFAULT_WIDTH: u32 = 1200;

const MARGIN: u32 = 20;
const TITLE_BAND: u32 = 64;
const SCALE_BAND: u32 = 44;
const LEGEND_ROW: u32 = 24;
const LEGEND_COLUMNS: u32 = 4;

/// Where the map lies in a picture, and how pixels relate to metres (x to the right, y up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapFrame {
    /// First pixel column of the map.
    pub left: u32,
    /// First pixel row of the map.
    pub top: u32,
    /// Map width, pixels.
    pub width: u32,
    /// Map height, pixels.
    pub height: u32,
    /// Metric x at the map's left edge.
    pub min_x: f64,
    /// Metric y at the map's top edge.
    pub max_y: f64,
    /// Pixels per metre.
    pub pixels_per_metre: f64,
}

impl MapFrame {
    /// Metric (x, y) of a pixel's centre, if the pixel shows the map.
    pub fn point_at(&self, px: u32, py: u32) -> Option<[f64; 2]> {
        let inside = (self.left..self.left + self.width).contains(&px)
            && (self.top..self.top + self.height).contains(&py);
        inside.then(|| {
            [
                self.min_x + (f64::from(px - self.left) + 0.5) / self.pixels_per_metre,
                self.max_y - (f64::from(py - self.top) + 0.5) / self.pixels_per_metre,
            ]
        })
    }

    /// The pixel showing a metric point, if the map holds it.
    pub fn pixel_at(&self, x: f64, y: f64) -> Option<(u32, u32)> {
        let px = ((x - self.min_x) * self.pixels_per_metre).floor();
        let py = ((self.max_y - y) * self.pixels_per_metre).floor();
        let fits = |v: f64, n: u32| v.is_finite() && v >= 0.0 && v < f64::from(n);
        (fits(px, self.width) && fits(py, self.height))
            .then(|| (self.left + px as u32, self.top + py as u32))
    }
}

/// A drawn picture.
#[derive(Clone, Debug)]
pub struct Picture {
    image: RgbImage,
    frame: Option<MapFrame>,
}

impl Picture {
    /// The pixels.
    pub fn image(&self) -> &RgbImage {
        &self.image
    }

    /// Where the map is (pictures of maps only).
    pub fn frame(&self) -> Option<&MapFrame> {
        self.frame.as_ref()
    }

    /// The picture as PNG bytes (best compression: pictures go into READMEs and reports).
    pub fn png(&self) -> Result<Vec<u8>, RenderError> {
        use image::codecs::png::{CompressionType, FilterType, PngEncoder};
        use image::ImageEncoder as _;
        let mut bytes = Vec::new();
        PngEncoder::new_with_quality(&mut bytes, CompressionType::Best, FilterType::Adaptive)
            .write_image(
                self.image.as_raw(),
                self.image.width(),
                self.image.height(),
                image::ColorType::Rgb8,
            )
            .map_err(|source| RenderError::Encode { source })?;
        Ok(bytes)
    }

    /// Writes the picture as PNG to `path`, atomically; refused when `path` is one of
    /// `inputs` (also through links).
    pub fn write_png(&self, path: &Path, inputs: &[&Path]) -> Result<(), RenderError> {
        refuse_overwriting_input(path, inputs.iter().copied())?;
        let bytes = self.png()?;
        write_atomically(path, |out| out.write_all(&bytes))?;
        Ok(())
    }

    pub(crate) fn from_rgb(width: u32, height: u32, buffer: Vec<u8>) -> Result<Self, RenderError> {
        let image = RgbImage::from_raw(width, height, buffer).ok_or_else(|| RenderError::Draw {
            message: "picture buffer of the wrong size".to_string(),
        })?;
        Ok(Picture { image, frame: None })
    }
}

/// Checks a requested picture width.
pub(crate) fn check_width(width: u32) -> Result<(), RenderError> {
    if (MIN_WIDTH..=MAX_WIDTH).contains(&width) {
        Ok(())
    } else {
        Err(RenderError::BadWidth {
            width,
            min: MIN_WIDTH,
            max: MAX_WIDTH,
        })
    }
}

/// Most columns a grid may have across and down for a picture `width` wide.
pub(crate) fn grid_limits(width: u32) -> (u32, u32) {
    (width - 2 * MARGIN, 2 * width)
}

/// One entry of a legend.
#[derive(Clone, Debug)]
pub(crate) struct LegendItem {
    pub(crate) colour: [u8; 3],
    pub(crate) label: String,
}

/// A colour ramp in the legend: `label`, then `steps` colours from low to high.
pub(crate) struct Ramp {
    pub(crate) label: String,
    pub(crate) low: String,
    pub(crate) high: String,
    pub(crate) colour: Box<dyn Fn(f64) -> [u8; 3]>,
}

/// Everything drawn around the map.
pub(crate) struct Decorations {
    pub(crate) title: String,
    pub(crate) subtitle: String,
    pub(crate) legend: Vec<LegendItem>,
    pub(crate) ramp: Option<Ramp>,
}

/// Draws the columns' colours (`colours[y * nx + x]`) scaled to a picture `width` wide,
/// with the decorations.
pub(crate) fn paint(
    grid: &Grid,
    colours: &[[u8; 3]],
    width: u32,
    decorations: &Decorations,
) -> Result<Picture, RenderError> {
    ensure_font()?;
    let [size_x, size_y] = grid.size_m();
    let (max_w, max_h) = grid_limits(width);
    let scale = (f64::from(max_w) / size_x).min(f64::from(max_h) / size_y);
    let map_w = ((size_x * scale).round() as u32).clamp(1, max_w);
    let map_h = ((size_y * scale).round() as u32).clamp(1, max_h);
    let [min_x, min_y] = grid.min_m();
    let frame = MapFrame {
        left: MARGIN + (max_w - map_w) / 2,
        top: TITLE_BAND,
        width: map_w,
        height: map_h,
        min_x,
        max_y: min_y + size_y,
        pixels_per_metre: scale,
    };
    let legend_rows = (decorations.legend.len() as u32).div_ceil(LEGEND_COLUMNS)
        + u32::from(decorations.ramp.is_some());
    let height = TITLE_BAND + map_h + SCALE_BAND + legend_rows * LEGEND_ROW + MARGIN;
    let mut buffer = vec![255u8; width as usize * height as usize * 3];
    fill_map(&mut buffer, width, &frame, grid, colours);
    draw_decorations(&mut buffer, (width, height), &frame, decorations)?;
    let mut picture = Picture::from_rgb(width, height, buffer)?;
    picture.frame = Some(frame);
    Ok(picture)
}

/// Each map pixel takes the colour of the column under its centre.
fn fill_map(buffer: &mut [u8], width: u32, frame: &MapFrame, grid: &Grid, colours: &[[u8; 3]]) {
    let column_m = f64::from(grid.cell) * grid.resolution;
    let [min_x, min_y] = grid.min_m();
    let index = |metres: f64, origin: f64, n: u32| {
        (((metres - origin) / column_m).floor().max(0.0) as u32).min(n - 1) as usize
    };
    let xs: Vec<usize> = (0..frame.width)
        .map(|px| {
            let x = frame.min_x + (f64::from(px) + 0.5) / frame.pixels_per_metre;
            index(x, min_x, grid.nx)
        })
        .collect();
    for py in 0..frame.height {
        let y = frame.max_y - (f64::from(py) + 0.5) / frame.pixels_per_metre;
        let j = index(y, min_y, grid.ny);
        let row = (frame.top + py) as usize * width as usize;
        for (px, &i) in xs.iter().enumerate() {
            let at = (row + frame.left as usize + px) * 3;
            let colour = colours.get(j * grid.nx as usize + i).copied();
            if let (Some(colour), Some(pixel)) = (colour, buffer.get_mut(at..at + 3)) {
                pixel.copy_from_slice(&colour);
            }
        }
    }
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

fn draw_decorations(
    buffer: &mut [u8],
    size: (u32, u32),
    frame: &MapFrame,
    decorations: &Decorations,
) -> Result<(), RenderError> {
    let root = BitMapBackend::with_buffer(buffer, size).into_drawing_area();
    let at = |x: u32, y: u32| (x as i32, y as i32);
    let font = |px: u32| ("sans-serif", px).into_font().color(&BLACK);
    root.draw(&Text::new(
        decorations.title.clone(),
        at(MARGIN, 12),
        font(22),
    ))
    .map_err(draw_error)?;
    root.draw(&Text::new(
        decorations.subtitle.clone(),
        at(MARGIN, 40),
        ("sans-serif", 15).into_font().color(&RGBColor(70, 70, 70)),
    ))
    .map_err(draw_error)?;
    let (right, bottom) = (frame.left + frame.width, frame.top + frame.height);
    root.draw(&Rectangle::new(
        [at(frame.left - 1, frame.top - 1), at(right, bottom)],
        BLACK.stroke_width(1),
    ))
    .map_err(draw_error)?;
    // Metre scale: the longest 1, 2 or 5 × 10^k metres within a fifth of the map.
    let width_m = f64::from(frame.width) / frame.pixels_per_metre;
    let target = (width_m / 5.0).max(f64::MIN_POSITIVE);
    let power = 10f64.powf(target.log10().floor());
    let metres = [5.0, 2.0, 1.0]
        .into_iter()
        .map(|f| f * power)
        .find(|&m| m <= target)
        .unwrap_or(power);
    let bar = ((metres * frame.pixels_per_metre).round() as u32).max(1);
    let y = bottom + 16;
    root.draw(&Rectangle::new(
        [at(frame.left, y), at(frame.left + bar, y + 5)],
        BLACK.filled(),
    ))
    .map_err(draw_error)?;
    for x in [frame.left, frame.left + bar] {
        root.draw(&PathElement::new(
            vec![at(x, y - 5), at(x, y + 10)],
            BLACK.stroke_width(2),
        ))
        .map_err(draw_error)?;
    }
    root.draw(&Text::new(
        format!("{} m", trim_number(metres)),
        at(frame.left + bar + 10, y - 4),
        font(15),
    ))
    .map_err(draw_error)?;
    // Legend: coloured squares with labels, a few per row, then the ramp.
    let column_w = (size.0 - 2 * MARGIN) / LEGEND_COLUMNS;
    let legend_top = bottom + SCALE_BAND;
    for (k, item) in decorations.legend.iter().enumerate() {
        let k = k as u32;
        let x = MARGIN + (k % LEGEND_COLUMNS) * column_w;
        let y = legend_top + (k / LEGEND_COLUMNS) * LEGEND_ROW;
        root.draw(&Rectangle::new(
            [at(x, y), at(x + 16, y + 16)],
            rgb(item.colour).filled(),
        ))
        .map_err(draw_error)?;
        root.draw(&Rectangle::new(
            [at(x, y), at(x + 16, y + 16)],
            RGBColor(90, 90, 90).stroke_width(1),
        ))
        .map_err(draw_error)?;
        root.draw(&Text::new(item.label.clone(), at(x + 22, y + 1), font(14)))
            .map_err(draw_error)?;
    }
    if let Some(ramp) = &decorations.ramp {
        let rows = (decorations.legend.len() as u32).div_ceil(LEGEND_COLUMNS);
        let y = legend_top + rows * LEGEND_ROW;
        root.draw(&Text::new(ramp.label.clone(), at(MARGIN, y + 1), font(14)))
            .map_err(draw_error)?;
        let x0 = MARGIN + column_w + column_w / 2;
        root.draw(&Text::new(ramp.low.clone(), at(x0 - 30, y + 1), font(14)))
            .map_err(draw_error)?;
        let steps = 200u32;
        for s in 0..steps {
            let c = (ramp.colour)(f64::from(s) / f64::from(steps - 1));
            root.draw(&Rectangle::new(
                [at(x0 + s, y), at(x0 + s + 1, y + 16)],
                rgb(c).filled(),
            ))
            .map_err(draw_error)?;
        }
        root.draw(&Text::new(
            ramp.high.clone(),
            at(x0 + steps + 8, y + 1),
            font(14),
        ))
        .map_err(draw_error)?;
    }
    root.present().map_err(draw_error)?;
    Ok(())
}

/// `5`, `0.5`, `20`: a scale length without trailing zeros.
fn trim_number(value: f64) -> String {
    let text = format!("{value:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_and_metres_agree() {
        let frame = MapFrame {
            left: 20,
            top: 64,
            width: 400,
            height: 200,
            min_x: -8.0,
            max_y: 7.5,
            pixels_per_metre: 10.0,
        };
        let [x, y] = frame.point_at(20, 64).unwrap();
        assert!((x - -7.95).abs() < 1e-9 && (y - 7.45).abs() < 1e-9);
        assert_eq!(frame.pixel_at(x, y), Some((20, 64)));
        assert_eq!(frame.pixel_at(-8.01, 0.0), None);
        assert_eq!(frame.point_at(420, 100), None);
        assert_eq!(trim_number(0.5), "0.5");
        assert_eq!(trim_number(20.0), "20");
    }
}
