//! The map at one time seen from above: each column occupied (shaded by how much of it is
//! occupied), free or unknown; or a horizontal cut at one height.

use crate::error::RenderError;
use crate::grid::{z_key, Grid};
use crate::picture::{check_width, grid_limits, paint, Decorations, LegendItem, Picture};
use froctomap_convert::{key_extent, resolve_observed, TimeQuery};
use froctomap_core::calendar::iso8601;
use froctomap_core::{Leaf, Occupancy, Timestamp};
use froctomap_file::FroctReader;

/// Free columns.
pub const FREE: [u8; 3] = [250, 250, 245];
/// Columns never observed.
pub const UNKNOWN: [u8; 3] = [206, 214, 224];
/// Occupied columns holding one voxel of occupied space (a floor).
pub const OCCUPIED_LOW: [u8; 3] = [170, 170, 180];
/// Occupied columns holding [`TALL_METRES`] of occupied space or more (walls); the slice's
/// occupied colour.
pub const OCCUPIED_HIGH: [u8; 3] = [20, 20, 30];
/// Occupied height drawn darkest.
pub const TALL_METRES: f64 = 1.5;

/// The shade of a column holding `metres` of occupied space.
pub fn occupied_shade(metres: f64) -> [u8; 3] {
    let t = (metres / TALL_METRES).clamp(0.0, 1.0);
    std::array::from_fn(|c| {
        let (lo, hi) = (f64::from(OCCUPIED_LOW[c]), f64::from(OCCUPIED_HIGH[c]));
        (lo + (hi - lo) * t).round() as u8
    })
}

/// `true` for the colours [`occupied_shade`] gives (greys from [`OCCUPIED_LOW`] to
/// [`OCCUPIED_HIGH`], blue 10 above red and green).
pub fn is_occupied_shade(pixel: [u8; 3]) -> bool {
    pixel[0] == pixel[1]
        && u16::from(pixel[2]) == u16::from(pixel[0]) + 10
        && (OCCUPIED_HIGH[0]..=OCCUPIED_LOW[0]).contains(&pixel[0])
}

/// Which map a picture shows.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum MapTime {
    /// The snapshot as observed at a sample (inside the file's span).
    Retrieved {
        /// The sample.
        sample: u32,
        /// Its time.
        time: Timestamp,
        /// The time asked for (the sample is the last one at or before it).
        asked: Timestamp,
    },
    /// The model's map (`p(t) > 0.5`) at any instant.
    Predicted(Timestamp),
}

impl MapTime {
    /// As `retrieve` and `predict` do: a sample index, or an instant inside the file's span,
    /// is the snapshot observed then (the last one at or before it); an instant outside the
    /// span is predicted.
    pub fn choose(reader: &FroctReader, query: TimeQuery) -> Result<Self, RenderError> {
        let axis = &reader.header().axis;
        if let TimeQuery::Instant(t) = query {
            if t < axis.start() || t > axis.end() {
                return Ok(MapTime::Predicted(t));
            }
        }
        let resolved = resolve_observed(reader, query)?;
        Ok(MapTime::Retrieved {
            sample: resolved.sample,
            time: resolved.time,
            asked: match query {
                TimeQuery::Instant(t) => t,
                _ => resolved.time,
            },
        })
    }

    /// `retrieved` or `predicted`.
    pub fn mode(&self) -> &'static str {
        match self {
            MapTime::Retrieved { .. } => "retrieved",
            MapTime::Predicted(_) => "predicted",
        }
    }
}

/// What part of the map is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum View {
    /// Every height, seen from above.
    TopDown,
    /// A horizontal cut through the voxels at height `z` (metres).
    Slice {
        /// Height, metres.
        z: f64,
    },
}

impl View {
    /// `z=0.5` (also `z = 0.5`): a slice at 0.5 m.
    pub fn slice(text: &str) -> Result<Self, RenderError> {
        let bad = || RenderError::BadSlice {
            text: text.to_string(),
        };
        let (axis, value) = text.split_once('=').ok_or_else(bad)?;
        if !axis.trim().eq_ignore_ascii_case("z") {
            return Err(bad());
        }
        let z: f64 = value.trim().parse().map_err(|_| bad())?;
        if !z.is_finite() {
            return Err(bad());
        }
        Ok(View::Slice { z })
    }
}

/// Per column: occupied voxels, and whether any voxel is known.
struct Columns {
    occupied: Vec<u64>,
    known: Vec<bool>,
}

/// Draws the map of `reader` at `when`, `width` pixels wide, going through the file one tile
/// at a time (the picture and one decoded tile in memory).
pub fn render_map(
    reader: &FroctReader,
    when: MapTime,
    view: View,
    width: u32,
) -> Result<Picture, RenderError> {
    check_width(width)?;
    let resolution = reader.header().resolution;
    let extent = key_extent(reader)?.ok_or_else(|| RenderError::EmptyMap {
        path: reader.path().to_path_buf(),
    })?;
    let slice = match view {
        View::TopDown => None,
        View::Slice { z } => {
            let metric = extent.metric(resolution);
            let key = z_key(z, resolution)
                .filter(|k| (extent.min[2]..=extent.max[2]).contains(k))
                .ok_or(RenderError::SliceOutside {
                    z,
                    min: metric.min[2],
                    max: metric.max[2],
                })?;
            Some(key)
        }
    };
    let (max_x, max_y) = grid_limits(width);
    let grid = Grid::covering(&extent, resolution, max_x, max_y);
    let mut columns = Columns {
        occupied: vec![0; grid.len()],
        known: vec![false; grid.len()],
    };
    let mut add = |start, depth, state: Occupancy| {
        let leaf = Leaf {
            start,
            depth,
            log_odds: 0.0,
        };
        let height = match slice {
            None => u64::from(leaf.edge_voxels()),
            Some(z) => {
                let lo = u32::from(leaf.min_key().z);
                if !(lo..lo + leaf.edge_voxels()).contains(&z) {
                    return;
                }
                1
            }
        };
        grid.overlaps(start, depth, |o| {
            columns.known[o.column] = true;
            if state.is_occupied() {
                columns.occupied[o.column] += o.area * height;
            }
        });
    };
    for tile in 0..reader.tiles().len() {
        match when {
            MapTime::Retrieved { sample, .. } => {
                reader.visit_observed_states(tile, sample, &mut add)?;
            }
            MapTime::Predicted(t) => {
                let seconds = t.secs_since(reader.header().axis.start());
                reader.visit_predicted_states(tile, seconds, &mut add)?;
            }
        }
    }
    let area = f64::from(grid.cell) * f64::from(grid.cell);
    let colours: Vec<[u8; 3]> = columns
        .occupied
        .iter()
        .zip(&columns.known)
        .map(|(&occupied, &known)| match (occupied, known, slice) {
            (0, true, _) => FREE,
            (0, false, _) => UNKNOWN,
            (_, _, Some(_)) => OCCUPIED_HIGH,
            (voxels, _, None) => occupied_shade(voxels as f64 / area * resolution),
        })
        .collect();
    paint(
        &grid,
        &colours,
        width,
        &decorations(reader, when, view, &grid),
    )
}

fn decorations(reader: &FroctReader, when: MapTime, view: View, grid: &Grid) -> Decorations {
    let name = reader
        .path()
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let axis = &reader.header().axis;
    let (time, how) = match when {
        MapTime::Retrieved {
            sample,
            time,
            asked,
        } => (
            asked,
            if asked == time {
                format!("snapshot {sample}")
            } else {
                format!("snapshot {sample} of {}", iso8601(time))
            },
        ),
        MapTime::Predicted(t) => (
            t,
            if t > axis.end() {
                format!(
                    "p > 0.5, {:.1} days after the last snapshot",
                    t.secs_since(axis.end()) / 86_400.0
                )
            } else {
                format!(
                    "p > 0.5, {:.1} days before the first snapshot",
                    axis.start().secs_since(t) / 86_400.0
                )
            },
        ),
    };
    let what = match view {
        View::TopDown => "seen from above".to_string(),
        View::Slice { z } => format!("slice at z = {z} m"),
    };
    let [x0, y0] = grid.min_m();
    let [w, h] = grid.size_m();
    let legend = match view {
        View::TopDown => vec![
            LegendItem {
                colour: occupied_shade(TALL_METRES),
                label: format!("occupied (darker: taller, {TALL_METRES} m+)"),
            },
            LegendItem {
                colour: occupied_shade(0.0),
                label: "occupied: floor only".to_string(),
            },
            LegendItem {
                colour: FREE,
                label: "free".to_string(),
            },
            LegendItem {
                colour: UNKNOWN,
                label: "unknown".to_string(),
            },
        ],
        View::Slice { .. } => vec![
            LegendItem {
                colour: OCCUPIED_HIGH,
                label: "occupied".to_string(),
            },
            LegendItem {
                colour: FREE,
                label: "free".to_string(),
            },
            LegendItem {
                colour: UNKNOWN,
                label: "unknown".to_string(),
            },
        ],
    };
    Decorations {
        title: format!("{name} at {}: {}", iso8601(time), when.mode()),
        subtitle: format!(
            "{how}; {what}; x {:.2} .. {:.2} m, y {:.2} .. {:.2} m, {} m voxels",
            x0,
            x0 + w,
            y0,
            y0 + h,
            grid.resolution
        ),
        legend,
        ramp: None,
    }
}
