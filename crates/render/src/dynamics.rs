//! Where the world changes: per column, the fraction of time its dynamic voxels are
//! occupied (colour strength) and their dominant period (hue); static structure in grey.

use crate::error::RenderError;
use crate::grid::Grid;
use crate::map::{occupied_shade, FREE, TALL_METRES, UNKNOWN};
use crate::picture::{check_width, grid_limits, paint, Decorations, LegendItem, Picture, Ramp};
use froctomap_convert::{key_extent, period_text, CellDynamics};
use froctomap_core::calendar::iso8601;
use froctomap_file::FroctReader;
use std::collections::HashMap;

/// Hues of the most common periods, most common first.
pub const PERIOD_HUES: [[u8; 3]; 6] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [23, 190, 207],
];
/// Hue of periods beyond the most common ones.
pub const OTHER_PERIODS: [u8; 3] = [188, 189, 34];
/// Hue of modelled voxels without a periodic term.
pub const NO_PERIOD: [u8; 3] = [227, 119, 194];

/// The colour of dynamic space of hue `hue`, occupied a `fraction` of the time: from a
/// pale tint (rarely occupied) to the full hue (always occupied).
pub fn dynamic_colour(hue: [u8; 3], fraction: f64) -> [u8; 3] {
    let strength = 0.2 + 0.8 * fraction.clamp(0.0, 1.0);
    hue.map(|c| (255.0 - (255.0 - f64::from(c)) * strength).round() as u8)
}

/// Dynamic voxels per voxel column (about 0.25 m at 0.08 m voxels) below which a column
/// counts as static: single voxels that flicker at surfaces (sensor noise) would otherwise
/// speckle the picture; doors, people, chairs and objects are taller.
pub const MIN_DYNAMIC_HEIGHT: f64 = 3.0;

/// Periods a column keeps track of; beyond them the weakest is replaced.
const SLOTS: usize = 4;

/// Per column: static occupied voxels, known-ness, and the dynamic voxels' weight, occupied
/// weight and strongest periods.
#[derive(Clone, Copy, Default)]
struct Column {
    static_occupied: u64,
    known: bool,
    dynamic: f64,
    occupied: f64,
    periods: [(u32, f64); SLOTS],
}

impl Column {
    fn add_period(&mut self, period: u32, weight: f64) {
        if let Some(slot) = self.periods.iter_mut().find(|s| s.0 == period && s.1 > 0.0) {
            slot.1 += weight;
        } else if let Some(slot) = self
            .periods
            .iter_mut()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|s| s.1 < weight)
        {
            *slot = (period, weight);
        }
    }

    fn dominant(&self) -> Option<u32> {
        self.periods
            .iter()
            .filter(|s| s.1 > 0.0)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|s| s.0)
    }
}

/// Index of "no period" among the periods.
const NONE: u32 = u32::MAX;

/// Draws where the world of `reader` changes, `width` pixels wide, one tile at a time.
pub fn render_dynamics(reader: &FroctReader, width: u32) -> Result<Picture, RenderError> {
    check_width(width)?;
    let resolution = reader.header().resolution;
    let extent = key_extent(reader)?.ok_or_else(|| RenderError::EmptyMap {
        path: reader.path().to_path_buf(),
    })?;
    let (max_x, max_y) = grid_limits(width);
    let grid = Grid::covering(&extent, resolution, max_x, max_y);
    let survey = Survey::of(reader, &grid)?;
    let ranking = PeriodRanking::of(&survey.columns, &grid);
    let colours = ranking.colours(&survey.columns, resolution);
    let legend = ranking.legend(&survey.periods);
    paint(&grid, &colours, width, &decorations(reader, &grid, legend))
}

/// The columns of the picture and the periods met while filling them.
struct Survey {
    columns: Vec<Column>,
    /// Periods in seconds, by the id the columns know them by (numbered as met).
    periods: Vec<f64>,
}

impl Survey {
    /// Spreads every cell of `reader` over the columns of `grid` it covers, one tile at a time,
    /// read from its class and model alone (no history is decoded).
    fn of(reader: &FroctReader, grid: &Grid) -> Result<Self, RenderError> {
        let mut columns = vec![Column::default(); grid.len()];
        // Periods by whole seconds, numbered as met.
        let mut period_ids: HashMap<i64, u32> = HashMap::new();
        let mut periods: Vec<f64> = Vec::new();
        let model = reader.model();
        for tile in 0..reader.tiles().len() {
            reader.visit_cell_classes(tile, |cell| {
                let edge = f64::from(
                    froctomap_core::Leaf {
                        start: cell.start,
                        depth: cell.depth,
                        log_odds: 0.0,
                    }
                    .edge_voxels(),
                );
                let dynamics = CellDynamics::of_class(&cell, model);
                let id = match dynamics {
                    CellDynamics::Modelled {
                        period_seconds: Some(p),
                        ..
                    } => {
                        let next = periods.len() as u32;
                        let id = *period_ids.entry(p.round() as i64).or_insert(next);
                        if id == next {
                            periods.push(p);
                        }
                        id
                    }
                    _ => NONE,
                };
                grid.overlaps(cell.start, cell.depth, |o| {
                    let column = &mut columns[o.column];
                    column.known = true;
                    let voxels = o.area as f64 * edge;
                    match dynamics {
                        CellDynamics::Static(state) | CellDynamics::RareFlips(state)
                            if state.is_occupied() =>
                        {
                            column.static_occupied += o.area * edge as u64;
                        }
                        CellDynamics::Modelled { mean, .. } => {
                            column.dynamic += voxels;
                            column.occupied += mean * voxels;
                            column.add_period(id, voxels);
                        }
                        _ => {}
                    }
                });
            })?;
        }
        Ok(Self { columns, periods })
    }
}

/// The periods that dominate the most dynamic space in the picture, strongest first, and
/// the hue each of them gets.
struct PeriodRanking {
    /// Area of one column in voxels.
    area: f64,
    ranked: Vec<(u32, f64)>,
    hue_of: HashMap<u32, [u8; 3]>,
    /// Whether some shown column is dominated by voxels without a period.
    unperiodic: bool,
}

impl PeriodRanking {
    fn of(columns: &[Column], grid: &Grid) -> Self {
        let area = f64::from(grid.cell) * f64::from(grid.cell);
        let mut weights: HashMap<u32, f64> = HashMap::new();
        for column in columns.iter().filter(|c| shown(c, area)) {
            *weights
                .entry(column.dominant().unwrap_or(NONE))
                .or_default() += column.dynamic;
        }
        let unperiodic = weights.remove(&NONE).is_some();
        let mut ranked: Vec<(u32, f64)> = weights.into_iter().collect();
        ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let hue_of: HashMap<u32, [u8; 3]> = ranked
            .iter()
            .zip(PERIOD_HUES)
            .map(|(&(id, _), hue)| (id, hue))
            .collect();
        Self {
            area,
            ranked,
            hue_of,
            unperiodic,
        }
    }

    /// The colour of each column: dynamic by its dominant period's hue, else static
    /// occupied, free or unknown.
    fn colours(&self, columns: &[Column], resolution: f64) -> Vec<[u8; 3]> {
        columns
            .iter()
            .map(|c| {
                if shown(c, self.area) {
                    let hue = match c.dominant() {
                        Some(NONE) | None => NO_PERIOD,
                        Some(id) => self.hue_of.get(&id).copied().unwrap_or(OTHER_PERIODS),
                    };
                    dynamic_colour(hue, c.occupied / c.dynamic)
                } else if c.static_occupied > 0 {
                    occupied_shade(c.static_occupied as f64 / self.area * resolution)
                } else if c.known {
                    FREE
                } else {
                    UNKNOWN
                }
            })
            .collect()
    }

    /// The legend: the ranked periods' hues (`periods` in seconds by id), then the rest.
    fn legend(&self, periods: &[f64]) -> Vec<LegendItem> {
        let mut legend: Vec<LegendItem> = self
            .ranked
            .iter()
            .zip(PERIOD_HUES)
            .map(|(&(id, _), hue)| LegendItem {
                colour: hue,
                label: format!(
                    "period {}",
                    periods
                        .get(id as usize)
                        .map_or_else(String::new, |p| period_text(*p))
                ),
            })
            .collect();
        if self.ranked.len() > PERIOD_HUES.len() {
            legend.push(LegendItem {
                colour: OTHER_PERIODS,
                label: format!("{} other periods", self.ranked.len() - PERIOD_HUES.len()),
            });
        }
        if self.unperiodic {
            legend.push(LegendItem {
                colour: NO_PERIOD,
                label: "changing, no period".to_string(),
            });
        }
        legend.extend([
            LegendItem {
                colour: occupied_shade(TALL_METRES),
                label: "static occupied (darker: taller)".to_string(),
            },
            LegendItem {
                colour: FREE,
                label: "free".to_string(),
            },
            LegendItem {
                colour: UNKNOWN,
                label: "unknown".to_string(),
            },
        ]);
        legend
    }
}

/// Whether column `c` (of `area` voxels) holds enough dynamic space to be drawn as dynamic.
fn shown(c: &Column, area: f64) -> bool {
    c.dynamic >= MIN_DYNAMIC_HEIGHT * area
}

/// Title, subtitle (time span and extent), `legend` and ramp of the picture.
fn decorations(reader: &FroctReader, grid: &Grid, legend: Vec<LegendItem>) -> Decorations {
    let name = reader
        .path()
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let axis = &reader.header().axis;
    let [x0, y0] = grid.min_m();
    let [w, h] = grid.size_m();
    Decorations {
        title: format!("{name}: where the world changes"),
        subtitle: format!(
            "{} .. {}; colour: strongest period of a column's modelled voxels (columns with {MIN_DYNAMIC_HEIGHT}+ dynamic voxels); x {:.2} .. {:.2} m, y {:.2} .. {:.2} m",
            iso8601(axis.start()),
            iso8601(axis.end()),
            x0,
            x0 + w,
            y0,
            y0 + h
        ),
        legend,
        ramp: Some(Ramp {
            label: "fraction of time occupied".to_string(),
            low: "0".to_string(),
            high: "1".to_string(),
            colour: Box::new(|f| dynamic_colour(PERIOD_HUES[0], f)),
        }),
    }
}
