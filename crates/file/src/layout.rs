//! How a file lays out its tiles: the part of the header that tile encoding and decoding
//! need, kept apart so that neither the header nor the tiles depend on each other.

use crate::toggle_lists::ToggleLayout;

/// How tile payloads are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Codec {
    /// Uncompressed.
    Raw,
    /// One zstd frame per tile, at the given compression level.
    Zstd {
        /// Compression level (informative for readers).
        level: i8,
    },
}

impl Default for Codec {
    fn default() -> Self {
        Codec::Zstd { level: 19 }
    }
}

/// How a file lays out its tiles: what a tile encoder and decoder need of the header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileLayout {
    /// Depth of the tiles' nodes.
    pub tile_depth: u8,
    /// How tile payloads are stored.
    pub codec: Codec,
    /// How toggle lists are stored.
    pub toggles: ToggleLayout,
}
