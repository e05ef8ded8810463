//! Where and with which rhythm a file's world changes: the map's extent, the periods its
//! dynamic cells follow, and the connected regions of dynamic voxels. Every pass decodes one
//! tile at a time (per thread), the summary only its classes and models; what is kept grows
//! with the dynamic cells, never with the number of snapshots.

use crate::error::ConvertError;
use froctomap_core::{voxels_per_node, Leaf, MortonCode, Occupancy, VoxelKey};
use froctomap_file::{Cell, CellClass, CellContent, FroctReader, FrozenPrediction};
use froctomap_temporal::PreparedModel;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

/// What a cell does over time, as pictures and summaries see it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum CellDynamics {
    /// Always in this state when observed.
    Static(Occupancy),
    /// Almost always in this state, with rare flips (sensor noise at a surface).
    RareFlips(Occupancy),
    /// Modelled over time: the fraction of time it is occupied (the model's mean) and the
    /// period of its strongest periodic term (`None` for models without one).
    Modelled {
        /// Mean occupancy in `[0, 1]`.
        mean: f64,
        /// Period of the strongest periodic term, seconds.
        period_seconds: Option<f64>,
    },
}

impl CellDynamics {
    /// What `cell` does, read from its stored content and the file's model.
    pub fn of(cell: &Cell, model: &dyn PreparedModel) -> Self {
        match &cell.content {
            CellContent::Constant(state) => CellDynamics::Static(*state),
            CellContent::ConstantExcept { state, .. } => CellDynamics::RareFlips(*state),
            CellContent::Modelled(voxel) => Self::modelled(voxel.parameters(), model),
        }
    }

    /// What a cell does, read from its class and model alone (no history decoded): the
    /// same as [`of`](Self::of) the cell.
    pub fn of_class(cell: &CellClass<'_>, model: &dyn PreparedModel) -> Self {
        match cell.prediction {
            FrozenPrediction::State(state) if cell.has_outliers => CellDynamics::RareFlips(state),
            FrozenPrediction::State(state) => CellDynamics::Static(state),
            FrozenPrediction::Model(parameters) => Self::modelled(parameters, model),
        }
    }

    fn modelled(parameters: &[u8], model: &dyn PreparedModel) -> Self {
        // The reader checked the bytes; a description failing anyway still has a mean.
        let description = model.describe(parameters).ok();
        CellDynamics::Modelled {
            mean: description
                .as_ref()
                .map_or_else(|| model.mean(parameters), |d| d.mean),
            period_seconds: description
                .and_then(|d| d.periodic.first().map(|term| term.period_seconds))
                .filter(|p| p.is_finite() && *p > 0.0),
        }
    }
}

/// A period for people: `1 week`, `1 day`, `3.5 days`, `8 h`, `45 min`, `30 s`.
///
/// ```
/// use froctomap_convert::period_text;
/// assert_eq!(period_text(86_400.0), "1 day");
/// assert_eq!(period_text(7.0 * 86_400.0), "1 week");
/// assert_eq!(period_text(8.0 * 3_600.0), "8 h");
/// assert_eq!(period_text(3.5 * 86_400.0), "3.5 days");
/// assert_eq!(period_text(2_700.0), "45 min");
/// ```
pub fn period_text(seconds: f64) -> String {
    let short = |value: f64| {
        let text = format!("{value:.2}");
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    };
    const DAY: f64 = 86_400.0;
    if (seconds / (7.0 * DAY) - 1.0).abs() < 1e-3 {
        "1 week".to_string()
    } else if seconds >= 2.0 * 7.0 * DAY && (seconds / (7.0 * DAY)).fract().abs() < 1e-3 {
        format!("{} weeks", short(seconds / (7.0 * DAY)))
    } else if seconds >= DAY {
        let days = short(seconds / DAY);
        if days == "1" {
            "1 day".to_string()
        } else {
            format!("{days} days")
        }
    } else if seconds >= 3_600.0 {
        format!("{} h", short(seconds / 3_600.0))
    } else if seconds >= 60.0 {
        format!("{} min", short(seconds / 60.0))
    } else {
        format!("{} s", short(seconds))
    }
}

/// How many dynamic cells (and voxels) follow one period as their strongest.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PeriodCount {
    /// The period in seconds; `None` for modelled cells without a periodic term.
    pub period_seconds: Option<f64>,
    /// The period as text (`1 day`, `8 h`), or `no period`.
    pub period: String,
    /// Modelled cells whose strongest term has this period.
    pub cells: u64,
    /// Their voxels.
    pub voxels: u64,
}

/// A connected region of dynamic voxels (cells sharing a face).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DynamicRegion {
    /// Minimum corner of its bounding box, metres.
    pub min: [f64; 3],
    /// Maximum corner of its bounding box, metres.
    pub max: [f64; 3],
    /// Dynamic voxels in the region.
    pub voxels: u64,
    /// Dynamic cells in the region.
    pub cells: u64,
}

/// An axis-aligned box in metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MetricBox {
    /// Minimum corner (x, y, z).
    pub min: [f64; 3],
    /// Maximum corner (x, y, z).
    pub max: [f64; 3],
}

/// Where a file's world is and where it changes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DynamicsSummary {
    /// Bounding box of every cell the file knows at some time, metres.
    pub bounds: Option<MetricBox>,
    /// Modelled cells by the period of their strongest term, most voxels first.
    pub periods: Vec<PeriodCount>,
    /// The largest connected regions of dynamic voxels (modelled cells and cells with rare
    /// flips), most voxels first.
    pub regions: Vec<DynamicRegion>,
    /// How many regions there are in all.
    pub region_count: usize,
}

/// Key box of a cell: its first key and its edge in voxels.
fn cell_box(start: MortonCode, depth: u8) -> (VoxelKey, u32) {
    let leaf = Leaf {
        start,
        depth,
        log_odds: 0.0,
    };
    (leaf.min_key(), leaf.edge_voxels())
}

/// Inclusive key bounds of cells, grown one cell at a time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyExtent {
    /// Smallest key on each axis.
    pub min: [u32; 3],
    /// Largest key on each axis (inclusive).
    pub max: [u32; 3],
}

impl KeyExtent {
    /// The extent of one cell.
    pub fn of_cell(start: MortonCode, depth: u8) -> Self {
        let (lo, edge) = cell_box(start, depth);
        let min = [u32::from(lo.x), u32::from(lo.y), u32::from(lo.z)];
        KeyExtent {
            min,
            max: min.map(|m| m + edge - 1),
        }
    }

    /// The smallest extent holding both.
    pub fn union(self, other: KeyExtent) -> KeyExtent {
        KeyExtent {
            min: std::array::from_fn(|a| self.min[a].min(other.min[a])),
            max: std::array::from_fn(|a| self.max[a].max(other.max[a])),
        }
    }

    /// Metric box: from the low corner of the first voxel to the high corner of the last.
    pub fn metric(&self, resolution: f64) -> MetricBox {
        let origin = f64::from(froctomap_core::KEY_ORIGIN);
        MetricBox {
            min: self.min.map(|k| (f64::from(k) - origin) * resolution),
            max: self.max.map(|k| (f64::from(k) + 1.0 - origin) * resolution),
        }
    }
}

/// Key extent of every cell of the file (known at some time), tile by tile in parallel, from
/// the cells' geometry alone (no history is decoded).
pub fn key_extent(reader: &FroctReader) -> Result<Option<KeyExtent>, ConvertError> {
    let per_tile = (0..reader.tiles().len())
        .into_par_iter()
        .map(|tile| {
            let mut extent: Option<KeyExtent> = None;
            reader.visit_cell_classes(tile, |cell| {
                let one = KeyExtent::of_cell(cell.start, cell.depth);
                extent = Some(extent.map_or(one, |e| e.union(one)));
            })?;
            Ok(extent)
        })
        .collect::<Result<Vec<_>, ConvertError>>()?;
    Ok(per_tile.into_iter().flatten().reduce(KeyExtent::union))
}

/// What one tile contributes to a [`DynamicsSummary`].
#[derive(Default)]
struct TilePart {
    extent: Option<KeyExtent>,
    /// Period (whole seconds; -1 for none) → (cells, voxels).
    periods: BTreeMap<i64, (u64, u64)>,
    dynamic: Vec<(MortonCode, u8)>,
}

/// The extent, the periods and the `largest` biggest dynamic regions of a file.
pub fn summarize_dynamics(
    reader: &FroctReader,
    largest: usize,
) -> Result<DynamicsSummary, ConvertError> {
    let model = reader.model();
    let parts = (0..reader.tiles().len())
        .into_par_iter()
        .map(|tile| {
            let mut part = TilePart::default();
            // Classes and models only: a walk of the histories would cost the file's bytes.
            reader.visit_cell_classes(tile, |cell| {
                let one = KeyExtent::of_cell(cell.start, cell.depth);
                part.extent = Some(part.extent.map_or(one, |e| e.union(one)));
                let dynamics = CellDynamics::of_class(&cell, model);
                if let CellDynamics::Modelled { period_seconds, .. } = dynamics {
                    let key = period_seconds.map_or(-1, |p| p.round() as i64);
                    let entry = part.periods.entry(key).or_default();
                    entry.0 += 1;
                    entry.1 += voxels_per_node(cell.depth);
                }
                if !matches!(dynamics, CellDynamics::Static(_)) {
                    part.dynamic.push((cell.start, cell.depth));
                }
            })?;
            Ok(part)
        })
        .collect::<Result<Vec<_>, ConvertError>>()?;
    let mut extent: Option<KeyExtent> = None;
    let mut periods: BTreeMap<i64, (u64, u64)> = BTreeMap::new();
    let mut dynamic = Vec::new();
    for part in parts {
        extent = match (extent, part.extent) {
            (Some(a), Some(b)) => Some(a.union(b)),
            (a, b) => a.or(b),
        };
        for (period, (cells, voxels)) in part.periods {
            let entry = periods.entry(period).or_default();
            entry.0 += cells;
            entry.1 += voxels;
        }
        dynamic.extend(part.dynamic);
    }
    let mut periods: Vec<PeriodCount> = periods
        .into_iter()
        .map(|(period, (cells, voxels))| {
            let seconds = (period >= 0).then_some(period as f64);
            PeriodCount {
                period_seconds: seconds,
                period: seconds.map_or_else(|| "no period".to_string(), period_text),
                cells,
                voxels,
            }
        })
        .collect();
    periods.sort_by(|a, b| b.voxels.cmp(&a.voxels).then(b.cells.cmp(&a.cells)));
    let resolution = reader.header().resolution;
    let mut regions = connected_regions(&dynamic, reader.header().tile_depth, resolution);
    let region_count = regions.len();
    regions.truncate(largest);
    Ok(DynamicsSummary {
        bounds: extent.map(|e| e.metric(resolution)),
        periods,
        regions,
        region_count,
    })
}

/// Connected components of cells (sharing a face), biggest first.
fn connected_regions(
    cells: &[(MortonCode, u8)],
    coarsest: u8,
    resolution: f64,
) -> Vec<DynamicRegion> {
    let index: HashMap<(u64, u8), usize> = cells
        .iter()
        .enumerate()
        .map(|(i, &(start, depth))| ((start.0, depth), i))
        .collect();
    let mut parent: Vec<usize> = (0..cells.len()).collect();
    for (i, &(start, depth)) in cells.iter().enumerate() {
        let (lo, edge) = cell_box(start, depth);
        let lo = [u32::from(lo.x), u32::from(lo.y), u32::from(lo.z)];
        for axis in 0..3 {
            // One probe beyond each face, at the face's first voxel: a neighbour as large
            // or larger holds it; a smaller one finds this cell from its own side.
            for probe in [lo[axis].checked_sub(1), Some(lo[axis] + edge)] {
                let Some(probe) = probe.filter(|&p| p <= u32::from(u16::MAX)) else {
                    continue;
                };
                let mut key = lo;
                key[axis] = probe;
                let key = VoxelKey::new(key[0] as u16, key[1] as u16, key[2] as u16).morton();
                for d in (coarsest..=froctomap_core::TREE_DEPTH).rev() {
                    if let Some(&j) = index.get(&(key.node_start(d).0, d)) {
                        union(&mut parent, i, j);
                        break;
                    }
                }
            }
        }
    }
    let mut regions: HashMap<usize, (KeyExtent, u64, u64)> = HashMap::new();
    for (i, &(start, depth)) in cells.iter().enumerate() {
        let root = find(&mut parent, i);
        let one = KeyExtent::of_cell(start, depth);
        let entry = regions.entry(root).or_insert((one, 0, 0));
        entry.0 = entry.0.union(one);
        entry.1 += voxels_per_node(depth);
        entry.2 += 1;
    }
    let mut regions: Vec<(KeyExtent, u64, u64)> = regions.into_values().collect();
    regions.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.min.cmp(&b.0.min)));
    regions
        .into_iter()
        .map(|(extent, voxels, cells)| {
            let metric = extent.metric(resolution);
            DynamicRegion {
                min: metric.min,
                max: metric.max,
                voxels,
                cells,
            }
        })
        .collect()
}

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

fn union(parent: &mut [usize], a: usize, b: usize) {
    let (a, b) = (find(parent, a), find(parent, b));
    if a != b {
        parent[a.max(b)] = a.min(b);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn voxel(x: u16, y: u16, z: u16) -> (MortonCode, u8) {
        (VoxelKey::new(x, y, z).morton(), 16)
    }

    #[test]
    fn face_neighbours_join_and_diagonals_do_not() {
        let cells = [
            voxel(100, 100, 100),
            voxel(101, 100, 100),
            voxel(101, 101, 100),
            voxel(200, 200, 200),
            voxel(201, 201, 201), // only a corner shared with the one before
        ];
        let regions = connected_regions(&cells, 10, 0.1);
        let sizes: Vec<u64> = regions.iter().map(|r| r.voxels).collect();
        assert_eq!(sizes, [3, 1, 1]);
        let first = &regions[0];
        let origin = f64::from(froctomap_core::KEY_ORIGIN);
        assert!((first.min[0] - (100.0 - origin) * 0.1).abs() < 1e-9);
        assert!((first.max[1] - (102.0 - origin) * 0.1).abs() < 1e-9);
    }

    #[test]
    fn a_small_cell_joins_a_larger_neighbour() {
        // A depth-14 cube (4 voxels per edge) at 64..68 and a voxel touching its +x face
        // away from the cube's corner.
        let big = (VoxelKey::new(64, 64, 64).morton(), 14);
        let small = voxel(68, 66, 67);
        let apart = voxel(69, 70, 70);
        let regions = connected_regions(&[big, small, apart], 10, 0.1);
        let sizes: Vec<u64> = regions.iter().map(|r| r.voxels).collect();
        assert_eq!(sizes, [65, 1]);
    }

    #[test]
    fn periods_read_as_people_say_them() {
        assert_eq!(period_text(7.0 * 86_400.0 / 3.0), "2.33 days");
        assert_eq!(period_text(14.0 * 86_400.0), "2 weeks");
        assert_eq!(period_text(12.0 * 3_600.0), "12 h");
        assert_eq!(period_text(30.0), "30 s");
    }
}
