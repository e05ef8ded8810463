//! How many cells, voxels and toggles a tile or a file holds, by class: what the stages
//! count and the reports print.

use serde::Serialize;

/// Cell and voxel counts by class.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ClassCounts {
    /// Always observed free.
    pub static_free: u64,
    /// Always observed occupied.
    pub static_occupied: u64,
    /// Changed state at least once (carry a model).
    pub dynamic: u64,
    /// Unobserved at some sample of the series (carry an observation mask).
    pub unknown_sometimes: u64,
}

impl ClassCounts {
    /// Adds another count (saturating: counts read from a file may be anything).
    pub fn add(&mut self, other: &ClassCounts) {
        self.static_free = self.static_free.saturating_add(other.static_free);
        self.static_occupied = self.static_occupied.saturating_add(other.static_occupied);
        self.dynamic = self.dynamic.saturating_add(other.dynamic);
        self.unknown_sometimes = self
            .unknown_sometimes
            .saturating_add(other.unknown_sometimes);
    }

    /// All cells (or voxels), saturating at `u64::MAX` rather than wrapping when the counts
    /// come from a hostile file's summary.
    ///
    /// ```
    /// use froctomap_convert::ClassCounts;
    /// let forged = ClassCounts { static_free: u64::MAX, dynamic: 2, ..ClassCounts::default() };
    /// assert_eq!(forged.total(), u64::MAX);
    /// ```
    pub fn total(&self) -> u64 {
        self.static_free
            .saturating_add(self.static_occupied)
            .saturating_add(self.dynamic)
    }
}

/// The summary entry of [`TileStats::largest_tile_history_bytes`]: what the next compaction
/// reads to choose its tile depth (`compact`).
pub(crate) const LARGEST_TILE_HISTORY_KEY: &str = "largest_tile_history_bytes";

/// Counts of a tile's (or a file's) cells, voxels and stored toggles.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct TileStats {
    pub cells: ClassCounts,
    pub voxels: ClassCounts,
    pub toggles: u64,
    pub model_errors: u64,
    /// Bytes of the cells' observation runs as the fit received them, packed
    /// ([`PackedObservations`](crate::history::PackedObservations)): what a build or a
    /// compaction holds of a tile's history while it fits the tile.
    pub history_bytes: u64,
    /// The most [`history_bytes`](Self::history_bytes) of one tile among the tiles added
    /// with [`add_tile`](Self::add_tile).
    pub largest_tile_history_bytes: u64,
}

impl TileStats {
    /// Adds other counts (of part of a tile, or of other tiles).
    pub fn add(&mut self, other: &TileStats) {
        self.cells.add(&other.cells);
        self.voxels.add(&other.voxels);
        self.toggles += other.toggles;
        self.model_errors += other.model_errors;
        self.history_bytes += other.history_bytes;
        self.largest_tile_history_bytes = self
            .largest_tile_history_bytes
            .max(other.largest_tile_history_bytes);
    }

    /// Adds a whole tile's counts.
    pub fn add_tile(&mut self, tile: &TileStats) {
        self.add(tile);
        self.largest_tile_history_bytes = self.largest_tile_history_bytes.max(tile.history_bytes);
    }

    /// The file summary's entries these counts give (`cell_classes`, `voxel_classes`,
    /// `toggles`, `model_errors`) and `outliers`, which build, append and compaction write
    /// first, each adding its own after.
    pub fn summary(&self, lossless: bool) -> serde_json::Map<String, serde_json::Value> {
        use serde_json::json;
        let mut summary = serde_json::Map::new();
        let mut put = |key: &str, value| summary.insert(key.to_string(), value);
        put("cell_classes", json!(self.cells));
        put("voxel_classes", json!(self.voxels));
        put("toggles", json!(self.toggles));
        put("model_errors", json!(self.model_errors));
        put(
            LARGEST_TILE_HISTORY_KEY,
            json!(self.largest_tile_history_bytes),
        );
        put(
            "outliers",
            json!(if lossless { "lossless" } else { "lossy" }),
        );
        summary
    }
}
