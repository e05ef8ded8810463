//! Bounds on what a reader accepts from a file.

use crate::error::FormatViolation;

/// Maxima checked before anything read from a file is allocated. The defaults accept any
/// file froctomap writes for maps of realistic size while bounding what a hostile file can
/// make a reader allocate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadLimits {
    /// Header section bytes (default 16 MiB).
    pub max_header_bytes: u64,
    /// Samples of a time axis, regular or explicit (default 2^28).
    pub max_samples: u64,
    /// Toggle blocks a tile may split the time axis into (default 2^20; the default block
    /// length of 256 samples reaches it at the default `max_samples`). Readers keep a few
    /// values per block.
    pub max_toggle_blocks: u64,
    /// Model parameter bytes (default 16 MiB).
    pub max_model_parameter_bytes: u64,
    /// Tiles in the index (default 2^24).
    pub max_tiles: u64,
    /// Stored or decoded bytes of one tile (default 1 GiB).
    pub max_tile_bytes: u64,
    /// Cells in one tile (default 2^24); a patch tile counts its stored cells and the
    /// aligned nodes of its remainder together (FORMAT.md §10.6).
    pub max_cells_per_tile: u64,
    /// Index bytes (default 1 GiB).
    pub max_index_bytes: u64,
    /// Cells of the whole file, summed over the index (default 2^26): whole-map reads hold
    /// one leaf or cell per cell.
    pub max_total_cells: u64,
    /// Toggles (observation changes, outliers, exceptions) a reader decodes from one tile
    /// (default 2^28): whole toggle lists are built from them.
    pub max_toggles_per_tile: u64,
    /// Segments of a format 2.0 file (default 2^16): a reader keeps each segment's tile
    /// index and axis (its patch remainders are read when a query needs them).
    /// The segment indexes count, summed, against `max_index_bytes`.
    pub max_segments: u64,
}

impl ReadLimits {
    /// The defaults, usable in constants (`ReadLimits { max_tiles: 16, ..ReadLimits::DEFAULT }`).
    pub const DEFAULT: Self = Self {
        max_header_bytes: 16 << 20,
        max_samples: 1 << 28,
        max_toggle_blocks: 1 << 20,
        max_model_parameter_bytes: 16 << 20,
        max_tiles: 1 << 24,
        max_tile_bytes: 1 << 30,
        max_cells_per_tile: 1 << 24,
        max_index_bytes: 1 << 30,
        max_total_cells: 1 << 26,
        max_toggles_per_tile: 1 << 28,
        max_segments: 1 << 16,
    };
}

impl Default for ReadLimits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Toggles (and, for coded lists, visits) decoded from one tile's list set against the
/// most a reader allows (FORMAT.md §9), so that hostile counts cannot make it work without end.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ToggleBudget {
    spent: u64,
    max: u64,
}

impl ToggleBudget {
    /// Nothing spent yet, at most `max`.
    pub(crate) fn new(max: u64) -> Self {
        Self { spent: 0, max }
    }

    /// Spends `count` more; an error once more than the most allowed are spent.
    pub(crate) fn spend(&mut self, count: u64) -> Result<(), FormatViolation> {
        self.spent = self.spent.saturating_add(count);
        if self.spent > self.max {
            return Err(FormatViolation::Limit {
                what: "toggles in a tile's list set",
                value: self.spent,
                limit: self.max,
            });
        }
        Ok(())
    }
}
