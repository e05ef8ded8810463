//! Bounds on what a reader accepts from a file.

/// Maxima checked before anything read from a file is allocated. The defaults accept any
/// file froctomap writes for maps of realistic size while bounding what a hostile file can
/// make a reader allocate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadLimits {
    /// Header section bytes (default 16 MiB).
    pub max_header_bytes: u64,
    /// Samples of an explicit time axis (default 2^28).
    pub max_samples: u64,
    /// Model parameter bytes (default 16 MiB).
    pub max_model_parameter_bytes: u64,
    /// Tiles in the index (default 2^24).
    pub max_tiles: u64,
    /// Stored or decoded bytes of one tile (default 1 GiB).
    pub max_tile_bytes: u64,
    /// Cells in one tile (default 2^24).
    pub max_cells_per_tile: u64,
    /// Index bytes (default 1 GiB).
    pub max_index_bytes: u64,
}

impl Default for ReadLimits {
    fn default() -> Self {
        Self {
            max_header_bytes: 16 << 20,
            max_samples: 1 << 28,
            max_model_parameter_bytes: 16 << 20,
            max_tiles: 1 << 24,
            max_tile_bytes: 1 << 30,
            max_cells_per_tile: 1 << 24,
            max_index_bytes: 1 << 30,
        }
    }
}
