//! Point queries on a FROctomap file: the model's probability at metric points, and one
//! voxel's whole story (its cell, class, model, observed states, p(t) and outliers).
//!
//! Both read only the tiles that hold the points asked for, one tile at a time.

use crate::error::ConvertError;
use crate::series_file::SeriesRead;
use froctomap_core::{Leaf, MortonCode, Occupancy, Timestamp, VoxelKey};
use froctomap_file::{Cell, CellContent, FroctReader};
use froctomap_temporal::VoxelDescription;

/// The model's occupancy probability `p(t)` at each point (metres, the map's frame), in the
/// order of `points`; `NaN` where the file has no cell (never observed, or outside the
/// addressable range). Any instant: inside the file's span or beyond it (a prediction).
///
/// ```
/// # use froctomap_convert::*;
/// # use froctomap_file::FroctReader;
/// # let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
/// #     .join("../../fixtures/froct/golden-v1.1.froct");
/// let reader = FroctReader::open(&path)?;
/// let t = reader.header().axis.start();
/// let p = probabilities(&reader, t, &[[1e9, 0.0, 0.0]])?;
/// assert!(p[0].is_nan()); // far outside the map
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn probabilities(
    reader: &FroctReader,
    t: Timestamp,
    points: &[[f64; 3]],
) -> Result<Vec<f64>, ConvertError> {
    probabilities_at_times(reader, &[t], points)
}

/// [`probabilities`] at several instants in one pass over the tiles: row `i` of the result
/// (`times.len()` rows of `points.len()` values, row-major) holds `p(times[i])` at each
/// point. Each tile holding a point is read once, whatever the number of instants.
///
/// ```
/// # use froctomap_convert::*;
/// # use froctomap_file::FroctReader;
/// # let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
/// #     .join("../../fixtures/froct/golden-v1.1.froct");
/// let reader = FroctReader::open(&path)?;
/// let (start, end) = (reader.header().axis.start(), reader.header().axis.end());
/// let points = [[0.0, 0.0, 0.0], [1e9, 0.0, 0.0]];
/// let p = probabilities_at_times(&reader, &[start, end], &points)?;
/// assert_eq!(p.len(), 4);
/// assert_eq!(p[2..].iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
///            probabilities(&reader, end, &points)?.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn probabilities_at_times(
    reader: &FroctReader,
    times: &[Timestamp],
    points: &[[f64; 3]],
) -> Result<Vec<f64>, ConvertError> {
    let header = reader.header();
    let seconds: Vec<f64> = times
        .iter()
        .map(|t| t.secs_since(header.axis.start()))
        .collect();
    let model = reader.model();
    let n = points.len();
    let mut out = vec![f64::NAN; n.saturating_mul(times.len())];
    // Points in Morton order, grouped by tile: each tile is read once, its cells (also in
    // Morton order) matched to the points in one pass.
    let wanted = points_in_morton_order(points, header.resolution);
    let mut rest = &wanted[..];
    while let Some(&(first, _)) = rest.first() {
        let tile_start = first.node_start(header.tile_depth);
        let in_tile =
            rest.partition_point(|(code, _)| code.node_start(header.tile_depth) == tile_start);
        let (group, after) = rest.split_at(in_tile);
        rest = after;
        let Some(tile) = reader.tile_containing(first) else {
            continue;
        };
        let mut next = 0;
        reader.visit_cells(tile, |cell| {
            while let Some(&(code, index)) = group.get(next) {
                if code.0 >= cell.end() {
                    break;
                }
                if code >= cell.start {
                    for (row, &at) in seconds.iter().enumerate() {
                        out[row * n + index] = cell.probability(model, at);
                    }
                }
                next += 1;
            }
        })?;
    }
    Ok(out)
}

/// [`probabilities`] for a file of any version ([`FroctFile`](crate::FroctFile), a 2.0
/// [`LivingReader`](froctomap_file::LivingReader)): a 1.x file or a 2.0 file without
/// segments exactly as [`probabilities`]; a 2.0 file with segments from its predicted
/// leaves until it is compacted: the base's cells by their models at `f32` precision, the
/// segments' own cells at their last state (0 or 1). `NaN` where no cell is.
pub fn series_probabilities(
    reader: &dyn SeriesRead,
    t: Timestamp,
    points: &[[f64; 3]],
) -> Result<Vec<f64>, ConvertError> {
    if let Some(body) = reader.whole_body() {
        return probabilities(body, t, points);
    }
    let header = reader.header();
    let seconds = t.secs_since(header.axis.start());
    let mut out = vec![f64::NAN; points.len()];
    let wanted = points_in_morton_order(points, header.resolution);
    let tile_of = |code: &MortonCode| code.node_start(header.tile_depth);
    let mut leaves: Vec<Leaf> = Vec::new();
    for (code, _) in reader.predicted_tiles() {
        let first = wanted.partition_point(|(c, _)| tile_of(c) < code);
        let last = wanted.partition_point(|(c, _)| tile_of(c) <= code);
        if first >= last {
            continue;
        }
        leaves.clear();
        // The leaves carry p itself in their log-odds field here.
        reader.predicted_leaves(code, seconds, &|p| p as f32, &mut leaves)?;
        let mut next = 0;
        for &(point, index) in &wanted[first..last] {
            while leaves.get(next).is_some_and(|l| l.end() <= point.0) {
                next += 1;
            }
            if let Some(leaf) = leaves.get(next).filter(|l| l.start <= point) {
                out[index] = f64::from(leaf.log_odds);
            }
        }
    }
    Ok(out)
}

/// The Morton codes of the points inside the addressable range, with their indices, in
/// Morton order (so grouped by tile).
fn points_in_morton_order(points: &[[f64; 3]], resolution: f64) -> Vec<(MortonCode, usize)> {
    let mut wanted: Vec<(MortonCode, usize)> = points
        .iter()
        .enumerate()
        .filter_map(|(i, &p)| Some((VoxelKey::from_point(p, resolution)?.morton(), i)))
        .collect();
    wanted.sort_unstable();
    wanted
}

/// What kind of cell a voxel belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum CellClass {
    /// Free at every sample it was observed.
    StaticFree,
    /// Occupied at every sample it was observed.
    StaticOccupied,
    /// Almost always in one state, with a few exceptions (sensor noise at a surface).
    Noisy,
    /// Changing: described by the file's temporal model.
    Dynamic,
}

impl CellClass {
    /// The class as in JSON (`static_free`, `static_occupied`, `noisy`, `dynamic`).
    pub fn name(self) -> &'static str {
        match self {
            CellClass::StaticFree => "static_free",
            CellClass::StaticOccupied => "static_occupied",
            CellClass::Noisy => "noisy",
            CellClass::Dynamic => "dynamic",
        }
    }
}

impl std::fmt::Display for CellClass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The cell of a file that holds a voxel.
#[derive(Clone, Debug, PartialEq)]
pub struct CellGeometry {
    /// The key of the voxel asked for.
    pub key: VoxelKey,
    /// Depth of the cell (16 is one voxel).
    pub depth: u8,
    /// Centre of the cell, metres.
    pub center: [f64; 3],
    /// Edge length of the cell, metres.
    pub size: f64,
    /// Minimum corner, metres.
    pub min: [f64; 3],
    /// Maximum corner, metres.
    pub max: [f64; 3],
}

/// One sample of a voxel's history.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HistorySample {
    /// Sample index on the file's time axis.
    pub sample: u32,
    /// Its instant.
    pub time: Timestamp,
    /// The observed state; `None` where the voxel (or the whole map) was not observed.
    pub state: Option<Occupancy>,
    /// The model's probability at that sample (0 or 1 for static cells).
    pub p: f64,
}

/// One voxel's story in a file, from [`voxel_history`].
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct VoxelHistory {
    /// The point asked for, metres.
    pub point: [f64; 3],
    /// The cell holding it.
    pub cell: CellGeometry,
    /// Its class.
    pub class: CellClass,
    /// `true` when the cell is unknown at some samples (it has an observation mask).
    pub sometimes_unknown: bool,
    /// The model's description of a dynamic cell (mean, periodic terms); `None` otherwise.
    pub model: Option<VoxelDescription>,
    /// Every sample of the range, in time order.
    pub samples: Vec<HistorySample>,
    /// Samples where the observed state differs from the model's (the outliers of a
    /// dynamic cell, the exceptions of a noisy one), in time order.
    pub outliers: Vec<HistorySample>,
}

/// One voxel's history: the cell holding `point` (metres), its class and model, every
/// sample's time and observed state (`None` = unknown) with the model's `p` there, and the
/// samples where observation and model disagree. `range` (inclusive) keeps the samples
/// between two instants; it must overlap the file's span. A point without a cell (never
/// observed, outside the map) is an error naming the file and the map's extent.
///
/// ```
/// # use froctomap_convert::*;
/// # use froctomap_file::FroctReader;
/// # let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
/// #     .join("../../fixtures/froct/golden-v1.1.froct");
/// let reader = FroctReader::open(&path)?;
/// let err = voxel_history(&reader, [1e9, 0.0, 0.0], None).unwrap_err();
/// assert!(matches!(err, ConvertError::PointOutsideMap { .. }));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn voxel_history(
    reader: &FroctReader,
    point: [f64; 3],
    range: Option<(Timestamp, Timestamp)>,
) -> Result<VoxelHistory, ConvertError> {
    let header = reader.header();
    let axis = &header.axis;
    let samples = samples_in_range(reader, range)?;
    let outside = || ConvertError::PointOutsideMap {
        path: reader.path().to_path_buf(),
        point,
        extent: extent(reader),
    };
    let key = VoxelKey::from_point(point, header.resolution).ok_or_else(outside)?;
    let code = key.morton();
    let tile = reader.tile_containing(code).ok_or_else(outside)?;
    let mut found: Option<Cell> = None;
    reader.visit_cells(tile, |cell| {
        if cell.start <= code && code.0 < cell.end() {
            found = Some(cell);
        }
    })?;
    let cell = found.ok_or_else(outside)?;
    let model = reader.model();
    let (class, description) = match &cell.content {
        CellContent::Constant(Occupancy::Free) => (CellClass::StaticFree, None),
        CellContent::Constant(Occupancy::Occupied) => (CellClass::StaticOccupied, None),
        CellContent::ConstantExcept { .. } => (CellClass::Noisy, None),
        CellContent::Modelled(voxel) => (
            CellClass::Dynamic,
            Some(model.describe(voxel.parameters())?),
        ),
    };
    let mut history = Vec::with_capacity(samples.len());
    let mut outliers = Vec::new();
    for sample in samples {
        let Some(time) = axis.time(sample) else {
            continue;
        };
        let (p, usual) = match &cell.content {
            CellContent::Constant(state) | CellContent::ConstantExcept { state, .. } => {
                (f64::from(u8::from(state.is_occupied())), *state)
            }
            CellContent::Modelled(voxel) => {
                let p = model.probability_at_sample(voxel.parameters(), sample);
                (p, Occupancy::from(p > 0.5))
            }
        };
        let entry = HistorySample {
            sample,
            time,
            state: cell.state_at(axis, model, sample),
            p,
        };
        if entry.state.is_some_and(|s| s != usual) {
            outliers.push(entry);
        }
        history.push(entry);
    }
    let leaf = Leaf {
        start: cell.start,
        depth: cell.depth,
        log_odds: 0.0,
    };
    let (min, max) = leaf.bounds(header.resolution);
    Ok(VoxelHistory {
        point,
        cell: CellGeometry {
            key,
            depth: cell.depth,
            center: [0, 1, 2].map(|a| (min[a] + max[a]) / 2.0),
            size: max[0] - min[0],
            min,
            max,
        },
        class,
        sometimes_unknown: cell.mask.is_some(),
        model: description,
        samples: history,
        outliers,
    })
}

/// The samples of the axis inside `range` (all of them without one).
fn samples_in_range(
    reader: &FroctReader,
    range: Option<(Timestamp, Timestamp)>,
) -> Result<std::ops::Range<u32>, ConvertError> {
    let axis = &reader.header().axis;
    let Some((from, to)) = range else {
        return Ok(0..axis.len());
    };
    if to < from {
        return Err(ConvertError::EmptyRange { from, to });
    }
    // Samples are in time order: the first at or after `from`, the last at or before `to`.
    let first = first_sample_where(axis.len(), |s| axis.time(s).is_none_or(|t| t >= from));
    let end = first_sample_where(axis.len(), |s| axis.time(s).is_none_or(|t| t > to));
    if first >= end {
        return Err(ConvertError::RangeOutsideAxis {
            path: reader.path().to_path_buf(),
            from,
            to,
            start: axis.start(),
            end: axis.end(),
        });
    }
    Ok(first..end)
}

/// The first of `0..len` where `past` holds (`len` if none); `past` must be monotonic.
fn first_sample_where(len: u32, past: impl Fn(u32) -> bool) -> u32 {
    let (mut lo, mut hi) = (0, len);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if past(mid) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// The metric box the file's tiles cover, if it has any.
fn extent(reader: &FroctReader) -> Option<([f64; 3], [f64; 3])> {
    let header = reader.header();
    reader
        .tiles()
        .iter()
        .map(|tile| {
            Leaf {
                start: tile.code,
                depth: header.tile_depth,
                log_odds: 0.0,
            }
            .bounds(header.resolution)
        })
        .reduce(|(lo, hi), (min, max)| {
            (
                [0, 1, 2].map(|a| lo[a].min(min[a])),
                [0, 1, 2].map(|a| hi[a].max(max[a])),
            )
        })
}

#[cfg(test)]
mod tests {
    use super::CellClass;

    #[test]
    fn class_names_are_the_json_names() {
        for class in [
            CellClass::StaticFree,
            CellClass::StaticOccupied,
            CellClass::Noisy,
            CellClass::Dynamic,
        ] {
            let json = serde_json::to_value(class).unwrap_or_default();
            assert_eq!(json.as_str(), Some(class.name()));
            assert_eq!(class.to_string(), class.name());
        }
    }
}
