//! The raster of map columns a top-down picture is drawn from: the map's horizontal extent
//! cut into square columns of whole voxels, at most as many as the picture has pixels.

use froctomap_convert::KeyExtent;
use froctomap_core::{Leaf, MortonCode, KEY_ORIGIN};

/// Columns over the map's horizontal extent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Grid {
    /// Key of the first column's first voxel, x and y.
    origin: [u32; 2],
    /// Voxels per column edge.
    pub(crate) cell: u32,
    /// Columns along x.
    pub(crate) nx: u32,
    /// Columns along y.
    pub(crate) ny: u32,
    /// Voxel edge, metres.
    pub(crate) resolution: f64,
}

/// The part of a cube a column holds.
pub(crate) struct Overlap {
    /// Index of the column (`y * nx + x`).
    pub(crate) column: usize,
    /// Voxels of the cube's footprint inside the column.
    pub(crate) area: u64,
}

impl Grid {
    /// Columns over `extent`, no more than `max_x` along x and `max_y` along y.
    pub(crate) fn covering(extent: &KeyExtent, resolution: f64, max_x: u32, max_y: u32) -> Self {
        let span = |a: usize| extent.max[a] - extent.min[a] + 1;
        let cell = span(0)
            .div_ceil(max_x.max(1))
            .max(span(1).div_ceil(max_y.max(1)))
            .max(1);
        Grid {
            origin: [extent.min[0], extent.min[1]],
            cell,
            nx: span(0).div_ceil(cell),
            ny: span(1).div_ceil(cell),
            resolution,
        }
    }

    /// Number of columns.
    pub(crate) fn len(&self) -> usize {
        self.nx as usize * self.ny as usize
    }

    /// Metres covered along x and y.
    pub(crate) fn size_m(&self) -> [f64; 2] {
        let edge = f64::from(self.cell) * self.resolution;
        [f64::from(self.nx) * edge, f64::from(self.ny) * edge]
    }

    /// Metric x and y of the columns' low corner.
    pub(crate) fn min_m(&self) -> [f64; 2] {
        self.origin
            .map(|k| (f64::from(k) - f64::from(KEY_ORIGIN)) * self.resolution)
    }

    /// Calls `each` with every column a cell's footprint covers.
    pub(crate) fn overlaps(&self, start: MortonCode, depth: u8, mut each: impl FnMut(Overlap)) {
        let leaf = Leaf {
            start,
            depth,
            log_odds: 0.0,
        };
        let lo = leaf.min_key();
        let edge = leaf.edge_voxels();
        let range = |lo: u32, origin: u32, n: u32| {
            let from = lo.saturating_sub(origin);
            let to = (lo + edge).saturating_sub(origin).min(n * self.cell);
            (from, to)
        };
        let (x0, x1) = range(u32::from(lo.x), self.origin[0], self.nx);
        let (y0, y1) = range(u32::from(lo.y), self.origin[1], self.ny);
        if x0 >= x1 || y0 >= y1 {
            return;
        }
        let cell = self.cell;
        for j in y0 / cell..=(y1 - 1) / cell {
            let dy = (y1.min((j + 1) * cell) - y0.max(j * cell)) as u64;
            for i in x0 / cell..=(x1 - 1) / cell {
                let dx = (x1.min((i + 1) * cell) - x0.max(i * cell)) as u64;
                each(Overlap {
                    column: j as usize * self.nx as usize + i as usize,
                    area: dx * dy,
                });
            }
        }
    }
}

/// Key along z of a height in metres, if it lies in the key range.
pub(crate) fn z_key(z: f64, resolution: f64) -> Option<u32> {
    let key = (z / resolution).floor() + f64::from(KEY_ORIGIN);
    (key.is_finite() && (0.0..=f64::from(u16::MAX)).contains(&key)).then_some(key as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::VoxelKey;

    #[test]
    fn a_cube_spreads_its_footprint_over_the_columns_it_covers() {
        let extent = KeyExtent {
            min: [100, 200, 0],
            max: [107, 203, 10],
        };
        // 8 x 4 voxels into at most 4 columns across: columns of 2 voxels.
        let grid = Grid::covering(&extent, 0.1, 4, 100);
        assert_eq!((grid.cell, grid.nx, grid.ny), (2, 4, 2));
        // A depth-14 cube (4 voxels per edge) at x 104..108, y 200..204.
        let cube = VoxelKey::new(104, 200, 0).morton();
        let mut seen = Vec::new();
        grid.overlaps(cube, 14, |o| seen.push((o.column, o.area)));
        assert_eq!(seen, [(2, 4), (3, 4), (6, 4), (7, 4)]);
        assert_eq!(seen.iter().map(|s| s.1).sum::<u64>(), 16);
    }
}
