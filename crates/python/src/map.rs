//! One map out of a FROctomap file, as observed at a sample or as predicted at an instant:
//! its OctoMap bytes (the command line's bytes), and its voxels as numpy arrays.

use crate::errors::{froct_error_text, to_py};
use froctomap_convert::{
    observed_map, predicted_map, write_observed_map, write_predicted_map, FroctFile, SeriesRead,
    WrittenMap,
};
use froctomap_core::calendar::iso8601;
use froctomap_core::{Snapshot, Timestamp, VoxelKey};
use froctomap_formats::WriteOptions;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// `(occupied, free)` voxel centres, (N, 3) each.
type PointCloud<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);

/// `(state, p)` of points looked up in a map.
type Found<'py> = (Bound<'py, PyArray1<i8>>, Bound<'py, PyArray1<f64>>);

/// Which map of the file.
#[derive(Clone, Copy)]
enum Query {
    /// As observed at a sample.
    Observed { sample: u32, time: Timestamp },
    /// As predicted at an instant.
    Predicted { time: Timestamp },
}

/// A map from `FroctFile.retrieve` (as observed) or `FroctFile.predict` (p(t) per cell).
/// Its bytes are written as the command line writes them; its voxels are decoded once, when
/// first asked for.
#[pyclass(module = "froctomap", frozen)]
pub struct Map {
    reader: Arc<FroctFile>,
    query: Query,
    decoded: Mutex<Option<Arc<Snapshot>>>,
}

impl Map {
    pub(crate) fn observed(reader: Arc<FroctFile>, sample: u32, time: Timestamp) -> Self {
        Self::new(reader, Query::Observed { sample, time })
    }

    pub(crate) fn predicted(reader: Arc<FroctFile>, time: Timestamp) -> Self {
        Self::new(reader, Query::Predicted { time })
    }

    fn new(reader: Arc<FroctFile>, query: Query) -> Self {
        Self {
            reader,
            query,
            decoded: Mutex::new(None),
        }
    }

    fn time(&self) -> Timestamp {
        match self.query {
            Query::Observed { time, .. } | Query::Predicted { time } => time,
        }
    }

    /// Writes the map to `path` with the writer the command line uses for the same query.
    fn write_to(&self, path: &Path, format: Option<&str>) -> PyResult<WrittenMap> {
        let options = WriteOptions {
            format,
            backend: None,
        };
        let context = crate::plugins::context();
        match self.query {
            Query::Observed { sample, .. } => {
                write_observed_map(context, &*self.reader, sample, path, options)
            }
            Query::Predicted { time } => {
                write_predicted_map(context, &*self.reader, time, path, options)
            }
        }
        .map_err(to_py)
    }

    /// The file's bytes in `format`, written beside nothing: into a private temporary
    /// directory, through the same writer as `write`, and read back.
    fn bytes_in(&self, py: Python<'_>, format: &str) -> PyResult<Vec<u8>> {
        py.detach(|| {
            let dir = tempfile::tempdir().map_err(to_py)?;
            let path = dir.path().join("map");
            self.write_to(&path, Some(format))?;
            std::fs::read(&path).map_err(to_py)
        })
    }

    /// The decoded map (leaves in Morton order), decoded on first use. The decoding runs
    /// without the interpreter and without holding the lock, so that another thread waiting
    /// for the lock can never hold up the interpreter.
    fn snapshot(&self, py: Python<'_>) -> PyResult<Arc<Snapshot>> {
        if let Some(done) = self.decoded.lock().ok().and_then(|slot| slot.clone()) {
            return Ok(done);
        }
        let snapshot = py
            .detach(|| match self.query {
                Query::Observed { sample, .. } => observed_map(&*self.reader, sample),
                Query::Predicted { time } => predicted_map(&*self.reader, time),
            })
            .map_err(to_py)?;
        let snapshot = Arc::new(snapshot);
        if let Ok(mut slot) = self.decoded.lock() {
            *slot = Some(snapshot.clone());
        }
        Ok(snapshot)
    }
}

/// The occupancy probability of a leaf's log-odds, as OctoMap's `getOccupancy`.
fn probability_of(leaf: &froctomap_core::Leaf) -> f64 {
    froctomap_core::probability(leaf.log_odds)
}

/// Voxel centres of the leaves of one state, expanded to the finest resolution.
fn voxel_centres(snapshot: &Snapshot, occupied: bool, voxels: usize) -> Array2<f64> {
    let resolution = snapshot.resolution();
    let mut out = Vec::with_capacity(voxels * 3);
    for leaf in snapshot.leaves() {
        if leaf.occupancy().is_occupied() != occupied {
            continue;
        }
        let min = leaf.min_key();
        let edge = leaf.edge_voxels();
        for dz in 0..edge {
            for dy in 0..edge {
                for dx in 0..edge {
                    // In range: a leaf lies inside the 16-bit key space.
                    let key = VoxelKey::new(
                        (u32::from(min.x) + dx) as u16,
                        (u32::from(min.y) + dy) as u16,
                        (u32::from(min.z) + dz) as u16,
                    );
                    out.extend_from_slice(&key.center(resolution));
                }
            }
        }
    }
    let rows = out.len() / 3;
    Array2::from_shape_vec((rows, 3), out).unwrap_or_else(|_| Array2::zeros((0, 3)))
}

#[pymethods]
impl Map {
    /// `"observed"` (from `retrieve`) or `"predicted"` (from `predict`).
    #[getter]
    fn kind(&self) -> &'static str {
        match self.query {
            Query::Observed { .. } => "observed",
            Query::Predicted { .. } => "predicted",
        }
    }

    /// The map's time, Unix seconds (a retrieved map: its snapshot's time).
    #[getter(time)]
    fn time_seconds(&self) -> f64 {
        crate::times::unix_seconds(self.time())
    }

    /// The map's time in ISO 8601 (UTC).
    #[getter]
    fn iso_time(&self) -> String {
        iso8601(self.time())
    }

    /// The sample of a retrieved map (`None` for a predicted one).
    #[getter]
    fn sample(&self) -> Option<u32> {
        match self.query {
            Query::Observed { sample, .. } => Some(sample),
            Query::Predicted { .. } => None,
        }
    }

    /// Voxel edge length, metres.
    #[getter]
    fn resolution(&self) -> f64 {
        self.reader.header().resolution
    }

    /// The map as an OctoMap `.bt` file's bytes (states; a predicted map thresholded at
    /// p > 0.5): byte for byte what `froctomap retrieve/predict … -o x.bt` writes.
    fn to_bt_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let bytes = self.bytes_in(py, "bt")?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// The map as an OctoMap `.ot` file's bytes (log-odds; a predicted map's are those of
    /// p(t)): byte for byte what `froctomap retrieve/predict … -o x.ot` writes.
    fn to_ot_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let bytes = self.bytes_in(py, "ot")?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// Writes the map to `path` (atomically), in the format its extension names (`.bt`,
    /// `.ot`) or `format`; the same bytes as the command line. Refuses to overwrite the
    /// `.froct` file itself. Returns the number of leaves written.
    #[pyo3(signature = (path, format = None))]
    fn write(&self, py: Python<'_>, path: PathBuf, format: Option<String>) -> PyResult<usize> {
        let written = py.detach(|| self.write_to(&path, format.as_deref()))?;
        Ok(written.leaves)
    }

    /// Voxel centres in metres, `(occupied, free)`, each a numpy float64 array of shape
    /// (N, 3): every voxel at the map's resolution (leaves of coarser nodes are expanded, as
    /// octomap-python's `extractPointCloud` does). Raises FroctError when there would be
    /// more than `max_points` points in all (see `leaves()` for the compact form).
    #[pyo3(signature = (max_points = 50_000_000))]
    fn point_cloud<'py>(&self, py: Python<'py>, max_points: u64) -> PyResult<PointCloud<'py>> {
        let snapshot = self.snapshot(py)?;
        let (mut occupied, mut free) = (0u64, 0u64);
        for leaf in snapshot.leaves() {
            let count = if leaf.occupancy().is_occupied() {
                &mut occupied
            } else {
                &mut free
            };
            *count = count.saturating_add(leaf.voxel_count());
        }
        let total = occupied.saturating_add(free);
        if total > max_points {
            return Err(froct_error_text(format!(
                "the map has {total} voxels, more than max_points={max_points}; raise max_points or use leaves()"
            )));
        }
        let (occupied, free) = py.detach(|| {
            (
                voxel_centres(&snapshot, true, occupied as usize),
                voxel_centres(&snapshot, false, free as usize),
            )
        });
        Ok((occupied.into_pyarray(py), free.into_pyarray(py)))
    }

    /// The map's leaves (one per octree node without children, coarse free space in one
    /// leaf): `(centres, sizes, occupied)`, numpy arrays of shapes (N, 3) float64 (metres),
    /// (N,) float64 (edge length, metres) and (N,) bool; with `with_p=True` a fourth array,
    /// (N,) float64, the occupancy probability each leaf holds (a prediction's p(t) as its
    /// `.ot` log-odds store it, clamped to OctoMap's limits 0.1192 .. 0.971; a retrieved
    /// map's states as OctoMap's clamping bounds).
    #[pyo3(signature = (with_p = false))]
    fn leaves<'py>(&self, py: Python<'py>, with_p: bool) -> PyResult<Bound<'py, PyTuple>> {
        let snapshot = self.snapshot(py)?;
        let resolution = snapshot.resolution();
        let leaves = snapshot.leaves();
        let mut centres = Vec::with_capacity(leaves.len() * 3);
        let mut sizes = Vec::with_capacity(leaves.len());
        let mut occupied = Vec::with_capacity(leaves.len());
        let mut p = Vec::with_capacity(if with_p { leaves.len() } else { 0 });
        for leaf in leaves {
            let (min, max) = leaf.bounds(resolution);
            centres.extend((0..3).map(|i| (min[i] + max[i]) / 2.0));
            sizes.push(max[0] - min[0]);
            occupied.push(leaf.occupancy().is_occupied());
            if with_p {
                p.push(probability_of(leaf));
            }
        }
        let centres = Array2::from_shape_vec((leaves.len(), 3), centres)
            .unwrap_or_else(|_| Array2::zeros((0, 3)));
        let mut items: Vec<Bound<'py, PyAny>> = vec![
            centres.into_pyarray(py).into_any(),
            sizes.into_pyarray(py).into_any(),
            occupied.into_pyarray(py).into_any(),
        ];
        if with_p {
            items.push(p.into_pyarray(py).into_any());
        }
        PyTuple::new(py, items)
    }

    /// Looks up `points` (an (N, 3) array of metres) in the map, as octomap-python's
    /// `search` and `isNodeOccupied`/`getOccupancy` do on the map's `.ot`: `(state, p)`,
    /// numpy arrays of shape (N,): `state` int8 (1 occupied, 0 free, -1 unknown: no leaf
    /// there, or outside the map) and `p` float64 (the leaf's occupancy probability, as
    /// `leaves(with_p=True)` gives it; NaN where unknown).
    fn search<'py>(&self, py: Python<'py>, points: &Bound<'py, PyAny>) -> PyResult<Found<'py>> {
        let points = crate::arrays::points_array(py, points)?;
        let snapshot = self.snapshot(py)?;
        let (states, p): (Vec<i8>, Vec<f64>) = py.detach(|| {
            let resolution = snapshot.resolution();
            points
                .iter()
                .map(|&point| {
                    let leaf = VoxelKey::from_point(point, resolution)
                        .and_then(|key| snapshot.leaf_at(key.morton()));
                    match leaf {
                        Some(leaf) => (
                            i8::from(leaf.occupancy().is_occupied()),
                            probability_of(leaf),
                        ),
                        None => (-1, f64::NAN),
                    }
                })
                .unzip()
        });
        Ok((states.into_pyarray(py), p.into_pyarray(py)))
    }

    /// Leaves of the map.
    fn __len__(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.snapshot(py)?.leaves().len())
    }

    fn __repr__(&self) -> String {
        match self.query {
            Query::Observed { sample, time } => format!(
                "<froctomap.Map observed at {} (sample {sample})>",
                iso8601(time)
            ),
            Query::Predicted { time } => {
                format!("<froctomap.Map predicted for {}>", iso8601(time))
            }
        }
    }
}
