//! `info` for FROctomap files: what a file holds and what it costs.

use crate::build::ClassCounts;
use crate::context::Context;
use crate::dynamics::{summarize_dynamics, DynamicRegion, MetricBox, PeriodCount};
use crate::error::ConvertError;
use crate::series_file::FroctFile;
use froctomap_core::calendar::iso8601;
use froctomap_core::{voxels_per_node, Occupancy};
use froctomap_file::{FroctReader, FrozenPrediction};
use froctomap_temporal::AxisKind;
use rayon::prelude::*;
use serde::Serialize;
use serde_json::{Map, Value};
use std::path::PathBuf;

/// The time axis, for people.
#[derive(Clone, Debug, Serialize)]
pub struct AxisInfo {
    /// `regular` or `explicit`.
    pub kind: &'static str,
    /// First sample, ISO 8601.
    pub start: String,
    /// Last sample, ISO 8601.
    pub end: String,
    /// Samples (including missing ones of a regular axis).
    pub samples: u32,
    /// Samples without a snapshot.
    pub missing: usize,
    /// Step of a regular axis, seconds.
    pub step_seconds: Option<f64>,
    /// Span, seconds.
    pub span_seconds: f64,
}

/// Bytes by part.
#[derive(Clone, Debug, Serialize)]
pub struct SizeInfo {
    /// Whole file.
    pub file: u64,
    /// Preamble, header sections and crc.
    pub header: u64,
    /// Index and footer.
    pub index: u64,
    /// Stored (compressed) tiles.
    pub tiles: u64,
    /// Raw bytes per tile stream before compression, as recorded by the writer.
    pub raw_streams: Value,
    /// Committed segments after the base (format 2.0), tiles and records.
    pub segments: u64,
}

/// One committed segment of a format 2.0 file.
#[derive(Clone, Debug, Serialize)]
pub struct SegmentInfo {
    /// Global index of its first sample.
    pub first_sample: u32,
    /// Its samples (missing ones included).
    pub samples: u32,
    /// Its samples without a map.
    pub missing: usize,
    /// First instant, ISO 8601.
    pub start: String,
    /// Last instant, ISO 8601.
    pub end: String,
    /// Tiles it stores.
    pub tiles: usize,
    /// Bytes of its tiles.
    pub tile_bytes: u64,
}

/// What a format 2.0 file holds beyond its base.
#[derive(Clone, Debug, Serialize)]
pub struct LivingInfo {
    /// Commit number of the root read.
    pub sequence: u64,
    /// Bytes committed (readers read nothing past them).
    pub committed_len: u64,
    /// End of the base.
    pub base_len: u64,
    /// Samples of the base.
    pub base_samples: u32,
    /// The committed segments, oldest first.
    pub segments: Vec<SegmentInfo>,
}

/// Everything `froctomap info` says about a FROctomap file.
#[derive(Clone, Debug, Serialize)]
pub struct FroctInfo {
    /// The file.
    pub file: PathBuf,
    /// Format version.
    pub version: String,
    /// Voxel edge length, metres.
    pub resolution_m: f64,
    /// Tile depth and count.
    pub tile_depth: u8,
    /// Tiles stored.
    pub tiles: usize,
    /// Samples per block of stored toggle lists (version 1.1), or `None` for whole lists.
    pub toggle_block: Option<u32>,
    /// The time axis.
    pub time: AxisInfo,
    /// Model name.
    pub model: String,
    /// `lossless` or `lossy`.
    pub outliers: &'static str,
    /// Cells by class.
    pub cells: ClassCounts,
    /// Voxels by class.
    pub voxels: ClassCounts,
    /// Sizes.
    pub size: SizeInfo,
    /// Input snapshots and their total size, as recorded at build time.
    pub input_files: Option<u64>,
    /// Input bytes recorded at build time.
    pub input_bytes: Option<u64>,
    /// `input_bytes / file bytes`.
    pub ratio_vs_inputs: Option<f64>,
    /// Raw states (one bit per known voxel per sample, as the FROctomap paper counts) over
    /// file bytes.
    pub ratio_vs_raw_states: f64,
    /// The header metadata.
    pub metadata: Map<String, Value>,
    /// Bounding box of every cell the file knows at some time, metres.
    pub bounds_m: Option<MetricBox>,
    /// Modelled cells by the period of their strongest term, most voxels first.
    pub periods: Vec<PeriodCount>,
    /// The largest connected regions of dynamic voxels, most voxels first (at most
    /// [`LARGEST_REGIONS`]).
    pub dynamic_regions: Vec<DynamicRegion>,
    /// How many connected dynamic regions there are in all.
    pub dynamic_region_count: usize,
    /// The base and segments of a format 2.0 file (`None` for 1.x). Cells, voxels, bounds,
    /// periods and regions describe the base; `time` and `size` the whole file.
    pub living: Option<LivingInfo>,
}

/// How many dynamic regions [`describe`] lists.
pub const LARGEST_REGIONS: usize = 10;

fn counts_from_summary(summary: &Map<String, Value>, key: &str) -> Option<ClassCounts> {
    let object = summary.get(key)?;
    let field = |name: &str| object.get(name).and_then(Value::as_u64);
    Some(ClassCounts {
        static_free: field("static_free")?,
        static_occupied: field("static_occupied")?,
        dynamic: field("dynamic")?,
        unknown_sometimes: field("unknown_sometimes")?,
    })
}

/// Describes a file from its header and index, and from one pass over its tiles (one tile
/// per thread at a time) for its bounds, periods and dynamic regions; cells are recounted
/// from the tiles when the index carries no summary or `count_cells` asks for it.
pub fn describe(
    context: &Context,
    reader: &FroctReader,
    count_cells: bool,
) -> Result<FroctInfo, ConvertError> {
    let header = reader.header();
    let axis = &header.axis;
    let summary = reader.summary();
    let recorded = counts_from_summary(summary, "cell_classes")
        .zip(counts_from_summary(summary, "voxel_classes"));
    let (cells, voxels) = match recorded.filter(|_| !count_cells) {
        Some(counts) => counts,
        None => count(reader)?,
    };
    let dynamics = summarize_dynamics(reader, LARGEST_REGIONS)?;
    let tiles: u64 = reader.tiles().iter().map(|t| u64::from(t.stored_len)).sum();
    let file = reader.file_len();
    let index = file
        - reader
            .tiles()
            .last()
            .map_or(0, |t| t.offset + u64::from(t.stored_len));
    let input_bytes = header.metadata.get("input_bytes").and_then(Value::as_u64);
    let raw_bits = voxels.total() as f64 * f64::from(axis.len());
    let model = context.models().by_id(header.model_id).map_or_else(
        || format!("unknown model {}", header.model_id),
        |d| d.name.to_string(),
    );
    Ok(FroctInfo {
        file: reader.path().to_path_buf(),
        version: format!("{}.{}", header.version.0, header.version.1),
        resolution_m: header.resolution,
        tile_depth: header.tile_depth,
        toggle_block: header.toggles.block_len(),
        tiles: reader.tiles().len(),
        time: AxisInfo {
            kind: match axis.kind() {
                AxisKind::Regular => "regular",
                AxisKind::Explicit => "explicit",
            },
            start: iso8601(axis.start()),
            end: iso8601(axis.end()),
            samples: axis.len(),
            missing: axis.missing().len(),
            step_seconds: axis.step_ns().map(|s| s as f64 / 1e9),
            span_seconds: axis.span_seconds(),
        },
        model,
        outliers: if header.model_parameters.get(1) == Some(&1) {
            "lossy"
        } else {
            "lossless"
        },
        cells,
        voxels,
        size: SizeInfo {
            file,
            header: reader.tiles().first().map_or(file - index, |t| t.offset),
            index,
            tiles,
            raw_streams: summary
                .get("raw_stream_bytes")
                .cloned()
                .unwrap_or(Value::Null),
            segments: 0,
        },
        input_files: header.metadata.get("sources").and_then(Value::as_u64),
        input_bytes,
        ratio_vs_inputs: input_bytes.map(|b| b as f64 / file as f64),
        ratio_vs_raw_states: raw_bits / 8.0 / file as f64,
        metadata: header.metadata.clone(),
        bounds_m: dynamics.bounds,
        periods: dynamics.periods,
        dynamic_regions: dynamics.regions,
        dynamic_region_count: dynamics.region_count,
        living: None,
    })
}

/// [`describe`] for a file of any version: a 2.0 file's base, with its segments listed in
/// [`FroctInfo::living`], and the time and sizes of the whole file.
pub fn describe_series(
    context: &Context,
    file: &FroctFile,
    count_cells: bool,
) -> Result<FroctInfo, ConvertError> {
    let living = match file {
        FroctFile::Flat(reader) => return describe(context, reader, count_cells),
        FroctFile::Living(living) => living,
    };
    let mut info = describe(context, living.base(), count_cells)?;
    let (major, minor) = file.version();
    info.version = format!("{major}.{minor}");
    let root = living.root();
    let base_axis = &living.header().axis;
    let mut segments = Vec::with_capacity(living.segment_count());
    for k in 0..living.segment_count() {
        let Some((first_sample, axis)) = living.segment_axis(k) else {
            continue;
        };
        let tiles = living.segment_tiles(k);
        segments.push(SegmentInfo {
            first_sample,
            samples: axis.len(),
            missing: axis.missing().len(),
            start: iso8601(axis.start()),
            end: iso8601(axis.end()),
            tiles: tiles.len(),
            tile_bytes: tiles.iter().map(|t| u64::from(t.stored_len)).sum(),
        });
    }
    if !segments.is_empty() {
        let time = &mut info.time;
        time.kind = "segmented";
        time.end = iso8601(living.last_instant());
        time.samples = living.sample_count();
        time.missing += segments.iter().map(|s| s.missing).sum::<usize>();
        time.step_seconds = None;
        time.span_seconds = living.last_instant().secs_since(base_axis.start());
    }
    info.size.segments = root.committed_len - root.base_len;
    info.size.file = root.committed_len;
    let raw_bits = info.voxels.total() as f64 * f64::from(base_axis.len());
    info.ratio_vs_raw_states = raw_bits / 8.0 / root.base_len as f64;
    // The inputs known are the base's (segments do not record theirs): the base against them.
    info.ratio_vs_inputs = info.input_bytes.map(|b| b as f64 / root.base_len as f64);
    info.living = Some(LivingInfo {
        sequence: root.sequence,
        committed_len: root.committed_len,
        base_len: root.base_len,
        base_samples: base_axis.len(),
        segments,
    });
    Ok(info)
}

fn count(reader: &FroctReader) -> Result<(ClassCounts, ClassCounts), ConvertError> {
    let per_tile = (0..reader.tiles().len())
        .into_par_iter()
        .map(|i| {
            let mut cells = ClassCounts::default();
            let mut voxels = ClassCounts::default();
            // One cell at a time (a tile may hold millions), from its class alone: no
            // history needs decoding to count it.
            reader.visit_cell_classes(i, |cell| {
                let n = voxels_per_node(cell.depth);
                let (c, v) = match (cell.prediction, cell.has_outliers) {
                    (FrozenPrediction::State(Occupancy::Free), false) => {
                        (&mut cells.static_free, &mut voxels.static_free)
                    }
                    (FrozenPrediction::State(Occupancy::Occupied), false) => {
                        (&mut cells.static_occupied, &mut voxels.static_occupied)
                    }
                    _ => (&mut cells.dynamic, &mut voxels.dynamic),
                };
                *c += 1;
                *v += n;
                if cell.sometimes_unknown {
                    cells.unknown_sometimes += 1;
                    voxels.unknown_sometimes += n;
                }
            })?;
            Ok((cells, voxels))
        })
        .collect::<Result<Vec<_>, ConvertError>>()?;
    let mut cells = ClassCounts::default();
    let mut voxels = ClassCounts::default();
    for (c, v) in per_tile {
        cells.add(&c);
        voxels.add(&v);
    }
    Ok((cells, voxels))
}

/// One OctoMap file (`.bt`, `.ot`, ...) described, as `froctomap info --json` prints it.
#[derive(Clone, Debug, Serialize)]
#[non_exhaustive]
pub struct MapFileInfo {
    /// The file.
    pub file: PathBuf,
    /// Its size.
    pub file_bytes: u64,
    /// Name of its format.
    pub format: &'static str,
    /// What the format is.
    pub format_description: &'static str,
    /// Voxel edge length, metres.
    pub resolution_m: f64,
    /// Octree nodes in the file.
    pub nodes: u64,
    /// Leaves (nodes without children) with a state.
    pub leaves: u64,
    /// Occupied leaves.
    pub occupied_leaves: u64,
    /// Free leaves.
    pub free_leaves: u64,
    /// Known voxels at the finest resolution.
    pub voxels: u64,
    /// Occupied voxels.
    pub occupied_voxels: u64,
    /// Free voxels.
    pub free_voxels: u64,
    /// Bounds of the known space, metres.
    pub known_bounds_m: Option<MetricBounds>,
    /// Bounds of the occupied space, metres.
    pub occupied_bounds_m: Option<MetricBounds>,
    /// What the reader warned about.
    pub warnings: Vec<String>,
}

/// An axis-aligned box, metres.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MetricBounds {
    /// Lower corner.
    pub min: [f64; 3],
    /// Upper corner.
    pub max: [f64; 3],
}

impl From<froctomap_core::BoundingBox> for MetricBounds {
    fn from(b: froctomap_core::BoundingBox) -> Self {
        Self {
            min: b.min,
            max: b.max,
        }
    }
}

/// Reads the map file at `path` (in the format `options` forces, else the detected one) and
/// describes it: what `froctomap info` prints for a single map.
pub fn describe_map_file(
    context: &Context,
    path: &std::path::Path,
    options: froctomap_formats::ReadOptions<'_>,
) -> Result<MapFileInfo, ConvertError> {
    let read = context
        .formats()
        .read_file(path, options)
        .map_err(ConvertError::Read)?;
    let snapshot = &read.map.snapshot;
    let stats = snapshot.stats();
    Ok(MapFileInfo {
        file: path.to_path_buf(),
        file_bytes: std::fs::metadata(path).map(|m| m.len()).unwrap_or(0),
        format: read.format.name,
        format_description: read.format.description,
        resolution_m: snapshot.resolution(),
        nodes: read.map.node_count,
        leaves: snapshot.leaves().len() as u64,
        occupied_leaves: stats.occupied_leaves,
        free_leaves: stats.free_leaves,
        voxels: stats.occupied_voxels + stats.free_voxels,
        occupied_voxels: stats.occupied_voxels,
        free_voxels: stats.free_voxels,
        known_bounds_m: snapshot.known_bounds().map(MetricBounds::from),
        occupied_bounds_m: snapshot.occupied_bounds().map(MetricBounds::from),
        warnings: read.map.warnings.clone(),
    })
}

/// The registered formats as `froctomap formats --json` prints them and Python's
/// `froctomap.formats()` returns them: a row `{name, kind, backend, extensions, read,
/// write, description}` per [`FormatRegistry::listing`](froctomap_formats::FormatRegistry::listing) entry.
///
/// ```
/// let rows = froctomap_convert::format_listing(&froctomap_convert::Context::with_default_plugins());
/// assert!(rows.iter().any(|row| row["name"] == "froct" && row["kind"] == "series"));
/// ```
pub fn format_listing(context: &Context) -> Vec<serde_json::Value> {
    context
        .formats()
        .listing()
        .iter()
        .map(|format| {
            serde_json::json!({
                "name": format.name,
                "kind": froctomap_core::Named::name(format.kind),
                "backend": format.backend.map(|b| b.name()),
                "extensions": format.extensions,
                "read": format.read,
                "write": format.write,
                "description": format.description,
            })
        })
        .collect()
}
