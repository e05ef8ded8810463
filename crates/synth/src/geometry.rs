//! Boxes in key space, a fast view of the base map, and finding where elements fit.
//!
//! Everything here works in OctoMap key coordinates (`i32` copies of the `u16` keys, so
//! neighbours of the extreme keys need no special case).

use froctomap_core::{Leaf, MortonCode, Occupancy, Snapshot, VoxelKey, TREE_DEPTH};

/// An axis-aligned box of voxels, `min` inclusive, `max` exclusive, in key coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct KeyBox {
    /// First key on each axis.
    pub min: [i32; 3],
    /// One past the last key on each axis.
    pub max: [i32; 3],
}

/// How a cube relates to a box.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Relation {
    Outside,
    Inside,
    Partial,
}

impl KeyBox {
    /// A box from its first key and its size in voxels.
    pub fn new(min: [i32; 3], size: [i32; 3]) -> Self {
        Self {
            min,
            max: [min[0] + size[0], min[1] + size[1], min[2] + size[2]],
        }
    }

    /// `true` when the box holds no voxel.
    pub fn is_empty(&self) -> bool {
        (0..3).any(|a| self.max[a] <= self.min[a])
    }

    /// Number of voxels.
    pub fn volume(&self) -> u64 {
        (0..3)
            .map(|a| (self.max[a] - self.min[a]).max(0) as u64)
            .product()
    }

    /// `true` when the key lies in the box.
    pub fn contains(&self, k: [i32; 3]) -> bool {
        (0..3).all(|a| k[a] >= self.min[a] && k[a] < self.max[a])
    }

    /// `true` when the boxes share a voxel.
    pub fn intersects(&self, other: &KeyBox) -> bool {
        (0..3).all(|a| self.min[a] < other.max[a] && other.min[a] < self.max[a])
    }

    /// The box grown by `margin` voxels on each side of each axis.
    pub fn grown(&self, margin: [i32; 3]) -> KeyBox {
        KeyBox {
            min: [0, 1, 2].map(|a| self.min[a] - margin[a]),
            max: [0, 1, 2].map(|a| self.max[a] + margin[a]),
        }
    }

    /// Every key of the box, x fastest.
    pub fn keys(&self) -> impl Iterator<Item = [i32; 3]> + '_ {
        let b = *self;
        (b.min[2]..b.max[2]).flat_map(move |z| {
            (b.min[1]..b.max[1]).flat_map(move |y| (b.min[0]..b.max[0]).map(move |x| [x, y, z]))
        })
    }

    /// Relation of the cube of `edge` voxels starting at `min`.
    pub(crate) fn relation(&self, min: [i32; 3], edge: i32) -> Relation {
        let mut inside = true;
        for ((&lo, &box_lo), &box_hi) in min.iter().zip(&self.min).zip(&self.max) {
            let hi = lo + edge;
            if hi <= box_lo || lo >= box_hi {
                return Relation::Outside;
            }
            inside &= lo >= box_lo && hi <= box_hi;
        }
        if inside {
            Relation::Inside
        } else {
            Relation::Partial
        }
    }
}

/// Key coordinates of a voxel key.
pub(crate) fn coords(key: VoxelKey) -> [i32; 3] {
    [i32::from(key.x), i32::from(key.y), i32::from(key.z)]
}

/// The Morton code of in-range key coordinates (`None` outside the tree).
pub(crate) fn code_of(k: [i32; 3]) -> Option<u64> {
    let axis = |v: i32| u16::try_from(v).ok();
    Some(
        VoxelKey::new(axis(k[0])?, axis(k[1])?, axis(k[2])?)
            .morton()
            .0,
    )
}

/// Edge in voxels of a leaf at `depth`.
pub(crate) fn edge_of(depth: u8) -> i32 {
    1 << (TREE_DEPTH - depth.min(TREE_DEPTH))
}

/// The key-space bounds of a leaf.
pub(crate) fn leaf_box(leaf: &Leaf) -> KeyBox {
    let edge = edge_of(leaf.depth);
    KeyBox::new(coords(leaf.min_key()), [edge; 3])
}

const UNKNOWN: u8 = 0;
const FREE: u8 = 1;
const OCCUPIED: u8 = 2;

/// Largest dense grid (cells, one byte each) built for placement; larger maps are queried
/// through the snapshot's binary search instead, which is slower but needs no memory.
pub(crate) const DENSE_LIMIT: u64 = 1 << 26;

/// Voxel states of the base map with O(1) lookups where affordable.
pub(crate) struct BaseIndex<'a> {
    snapshot: &'a Snapshot,
    /// Known bounds in key space.
    pub(crate) bounds: KeyBox,
    dense: Option<Vec<u8>>,
}

impl<'a> BaseIndex<'a> {
    /// Indexes a non-empty snapshot; a dense grid is built when the known bounds hold at
    /// most `dense_limit` voxels.
    pub(crate) fn new(snapshot: &'a Snapshot, dense_limit: u64) -> Option<Self> {
        let mut leaves = snapshot.leaves().iter();
        let first = leaf_box(leaves.next()?);
        let bounds = leaves.fold(first, |b, leaf| {
            let l = leaf_box(leaf);
            KeyBox {
                min: [0, 1, 2].map(|a| b.min[a].min(l.min[a])),
                max: [0, 1, 2].map(|a| b.max[a].max(l.max[a])),
            }
        });
        let dense = (bounds.volume() <= dense_limit).then(|| {
            let mut cells = vec![UNKNOWN; bounds.volume() as usize];
            let dims = [0, 1, 2].map(|a| (bounds.max[a] - bounds.min[a]) as usize);
            for leaf in snapshot.leaves() {
                let value = match leaf.occupancy() {
                    Occupancy::Free => FREE,
                    Occupancy::Occupied => OCCUPIED,
                };
                let b = leaf_box(leaf);
                for z in b.min[2]..b.max[2] {
                    for y in b.min[1]..b.max[1] {
                        let row = ((z - bounds.min[2]) as usize * dims[1]
                            + (y - bounds.min[1]) as usize)
                            * dims[0];
                        let x0 = row + (b.min[0] - bounds.min[0]) as usize;
                        let x1 = row + (b.max[0] - bounds.min[0]) as usize;
                        cells[x0..x1].fill(value);
                    }
                }
            }
            cells
        });
        Some(Self {
            snapshot,
            bounds,
            dense,
        })
    }

    /// `true` when lookups use the dense grid.
    #[cfg(test)]
    pub(crate) fn is_dense(&self) -> bool {
        self.dense.is_some()
    }

    /// State of the voxel at key coordinates `k` (`None` = unknown).
    pub(crate) fn state(&self, k: [i32; 3]) -> Option<Occupancy> {
        if !self.bounds.contains(k) {
            return None;
        }
        match &self.dense {
            Some(cells) => {
                let b = &self.bounds;
                let dx = (b.max[0] - b.min[0]) as usize;
                let dy = (b.max[1] - b.min[1]) as usize;
                let i = ((k[2] - b.min[2]) as usize * dy + (k[1] - b.min[1]) as usize) * dx
                    + (k[0] - b.min[0]) as usize;
                match cells.get(i) {
                    Some(&FREE) => Some(Occupancy::Free),
                    Some(&OCCUPIED) => Some(Occupancy::Occupied),
                    _ => None,
                }
            }
            None => self.snapshot.state_at(MortonCode(code_of(k)?)),
        }
    }

    pub(crate) fn is_free(&self, k: [i32; 3]) -> bool {
        self.state(k) == Some(Occupancy::Free)
    }

    pub(crate) fn is_occupied(&self, k: [i32; 3]) -> bool {
        self.state(k) == Some(Occupancy::Occupied)
    }

    /// `true` when every voxel of the box is known free.
    pub(crate) fn all_free(&self, b: &KeyBox) -> bool {
        b.keys().all(|k| self.is_free(k))
    }

    /// `true` when no voxel of the box is occupied.
    pub(crate) fn none_occupied(&self, b: &KeyBox) -> bool {
        b.keys().all(|k| !self.is_occupied(k))
    }

    /// The floor level of the map: the top of the band of z levels, in the lower half of the
    /// occupied height range, with the most occupied voxels (the scanned floor plane).
    pub(crate) fn floor_level(&self) -> Option<i32> {
        let mut counts: Vec<(i32, u64)> = Vec::new();
        let (lo, hi) = (self.bounds.min[2], self.bounds.max[2]);
        let mut per_level = vec![0u64; (hi - lo) as usize];
        for leaf in self.snapshot.leaves() {
            if leaf.occupancy() != Occupancy::Occupied {
                continue;
            }
            let b = leaf_box(leaf);
            let area = ((b.max[0] - b.min[0]) as u64) * ((b.max[1] - b.min[1]) as u64);
            for z in b.min[2]..b.max[2] {
                if let Some(c) = per_level.get_mut((z - lo) as usize) {
                    *c += area;
                }
            }
        }
        let occupied: Vec<i32> = (lo..hi)
            .filter(|z| per_level[(z - lo) as usize] > 0)
            .collect();
        let (&zmin, &zmax) = (occupied.first()?, occupied.last()?);
        let mid = zmin + (zmax - zmin) / 2;
        for z in zmin..=mid {
            counts.push((z, per_level[(z - lo) as usize]));
        }
        let &(peak, peak_count) = counts
            .iter()
            .max_by_key(|&&(z, c)| (c, std::cmp::Reverse(z)))?;
        let mut top = peak;
        while top < zmax && per_level[(top + 1 - lo) as usize] * 2 >= peak_count {
            top += 1;
        }
        Some(top)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relations() {
        let b = KeyBox::new([10, 10, 10], [4, 4, 4]);
        assert_eq!(b.relation([0, 0, 0], 8), Relation::Outside);
        assert_eq!(b.relation([8, 8, 8], 8), Relation::Partial);
        assert_eq!(b.relation([10, 10, 10], 2), Relation::Inside);
        assert_eq!(b.relation([10, 10, 14], 2), Relation::Outside);
        assert_eq!(b.volume(), 64);
        assert_eq!(b.keys().count(), 64);
        assert!(b.intersects(&KeyBox::new([13, 13, 13], [5, 5, 5])));
        assert!(!b.intersects(&KeyBox::new([14, 10, 10], [5, 5, 5])));
    }

    #[test]
    fn dense_and_sparse_views_agree() {
        let mut voxels = Vec::new();
        for x in 0..12 {
            for y in 0..9 {
                for z in 0..7 {
                    let state = Occupancy::from(z == 1 || x == 11);
                    voxels.push((
                        VoxelKey::new(32760 + x, 32760 + y, 32760 + z).morton(),
                        state,
                    ));
                }
            }
        }
        let map = Snapshot::from_voxel_states(0.1, voxels).unwrap();
        let dense = BaseIndex::new(&map, DENSE_LIMIT).unwrap();
        let sparse = BaseIndex::new(&map, 0).unwrap();
        assert!(dense.is_dense() && !sparse.is_dense());
        for k in KeyBox::new([32758, 32758, 32758], [16, 13, 11]).keys() {
            assert_eq!(dense.state(k), sparse.state(k), "{k:?}");
        }
        assert_eq!(dense.floor_level(), Some(32761));
    }
}
