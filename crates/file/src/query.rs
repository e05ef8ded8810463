//! Queries over a whole file or a region: maps at a sample, probabilities at any instant.

use crate::error::FileError;
use crate::reader::FroctReader;
use crate::tile::Cell;
use froctomap_core::{Leaf, MortonCode, Occupancy, VoxelKey};

/// A cell's geometry with a value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellValue<T> {
    /// Morton code of the cell's first voxel.
    pub start: MortonCode,
    /// Depth of the cell.
    pub depth: u8,
    /// The value at the queried time.
    pub value: T,
}

fn intersects(cell: &Cell, min: VoxelKey, max: VoxelKey) -> bool {
    let leaf = Leaf {
        start: cell.start,
        depth: cell.depth,
        log_odds: 0.0,
    };
    let lo = leaf.min_key();
    let edge = leaf.edge_voxels();
    let axis = |lo: u16, min: u16, max: u16| {
        u32::from(lo) <= u32::from(max) && u32::from(lo) + edge > u32::from(min)
    };
    axis(lo.x, min.x, max.x) && axis(lo.y, min.y, max.y) && axis(lo.z, min.z, max.z)
}

impl FroctReader {
    fn region_cells<T>(
        &self,
        min: VoxelKey,
        max: VoxelKey,
        skip_tile: impl Fn(&crate::TileEntry) -> bool,
        mut value: impl FnMut(&Cell) -> Option<T>,
    ) -> Result<Vec<CellValue<T>>, FileError> {
        let mut out = Vec::new();
        for tile in self.tiles_in_box(min, max) {
            if skip_tile(&self.tiles()[tile]) {
                continue;
            }
            for cell in self.read_tile(tile)? {
                if intersects(&cell, min, max) {
                    if let Some(v) = value(&cell) {
                        out.push(CellValue {
                            start: cell.start,
                            depth: cell.depth,
                            value: v,
                        });
                    }
                }
            }
        }
        Ok(out)
    }

    /// The observed state of every cell that intersects the key box `min..=max` at `sample`
    /// (cells unknown at that sample are left out). Reads only the tiles the box touches.
    pub fn region_states(
        &self,
        min: VoxelKey,
        max: VoxelKey,
        sample: u32,
    ) -> Result<Vec<CellValue<Occupancy>>, FileError> {
        let axis = &self.header().axis;
        self.region_cells(
            min,
            max,
            |t| !t.may_observe(sample),
            |cell| cell.state_at(axis, self.model(), sample),
        )
    }

    /// Occupancy probability of every cell intersecting the key box at any instant, given in
    /// seconds since the first sample of the axis (negative or beyond the end is fine).
    pub fn region_probabilities(
        &self,
        min: VoxelKey,
        max: VoxelKey,
        seconds: f64,
    ) -> Result<Vec<CellValue<f64>>, FileError> {
        self.region_cells(
            min,
            max,
            |_| false,
            |cell| Some(cell.probability(self.model(), seconds)),
        )
    }
}
