//! Voxel keys and their Morton codes.
//!
//! OctoMap addresses a voxel by three 16-bit keys, `key = floor(coord / resolution) + 32768`.
//! The child index of a node at depth `d` is built from bit `15 - d` of each key
//! (x → 1, y → 2, z → 4). Interleaving the key bits in that order gives a 48-bit Morton
//! code whose numeric order *is* OctoMap's depth-first (pre-order) traversal order, the
//! order in which `.bt`/`.ot` files list their nodes.

use std::fmt;

/// Depth of every OctoMap tree: 16 levels below the root, one per key bit.
pub const TREE_DEPTH: u8 = 16;

/// Key value of the coordinate origin on every axis (OctoMap's `tree_max_val`).
pub const KEY_ORIGIN: i32 = 32768;

/// The finest-level address of one voxel, exactly as OctoMap's `OcTreeKey`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct VoxelKey {
    /// Key along x.
    pub x: u16,
    /// Key along y.
    pub y: u16,
    /// Key along z.
    pub z: u16,
}

impl VoxelKey {
    /// Creates a key from its three axis values.
    pub const fn new(x: u16, y: u16, z: u16) -> Self {
        Self { x, y, z }
    }

    /// The key of the voxel containing a metric point, or `None` when the point lies outside
    /// the ±32768-voxel range a tree can address (or is not finite).
    ///
    /// ```
    /// use froctomap_core::VoxelKey;
    /// let key = VoxelKey::from_point([0.05, -0.05, 1.0], 0.1).unwrap();
    /// assert_eq!(key, VoxelKey::new(32768, 32767, 32778));
    /// ```
    pub fn from_point(point: [f64; 3], resolution: f64) -> Option<Self> {
        let axis = |c: f64| -> Option<u16> {
            let cell = (c / resolution).floor();
            if !cell.is_finite() {
                return None;
            }
            let key = cell + f64::from(KEY_ORIGIN);
            if (0.0..=f64::from(u16::MAX)).contains(&key) {
                // In range and integral, so the conversion is exact.
                Some(key as u16)
            } else {
                None
            }
        };
        Some(Self::new(axis(point[0])?, axis(point[1])?, axis(point[2])?))
    }

    /// Metric centre of this voxel at the given resolution (OctoMap's `keyToCoord`).
    pub fn center(self, resolution: f64) -> [f64; 3] {
        let axis = |k: u16| (f64::from(i32::from(k) - KEY_ORIGIN) + 0.5) * resolution;
        [axis(self.x), axis(self.y), axis(self.z)]
    }

    /// The Morton code of this key.
    pub fn morton(self) -> MortonCode {
        MortonCode(spread_bits(self.x) | spread_bits(self.y) << 1 | spread_bits(self.z) << 2)
    }
}

impl fmt::Display for VoxelKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({}, {}, {})", self.x, self.y, self.z)
    }
}

/// A 48-bit interleaved key: bits `3b, 3b+1, 3b+2` hold bit `b` of x, y, z.
///
/// Sorting by Morton code sorts voxels in OctoMap's depth-first order.
///
/// ```
/// use froctomap_core::{MortonCode, VoxelKey};
/// let key = VoxelKey::new(40000, 123, 65535);
/// assert_eq!(key.morton().key(), key);
/// // Child index at depth 0 comes from the top bit of each axis: x=1, y=0, z=1 → 5.
/// assert_eq!(key.morton().child_index(0), 5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct MortonCode(pub u64);

impl MortonCode {
    /// Number of meaningful bits in a code.
    pub const BITS: u32 = 3 * TREE_DEPTH as u32;
    /// One past the largest valid code.
    pub const END: u64 = 1 << Self::BITS;

    /// The voxel key this code interleaves.
    pub fn key(self) -> VoxelKey {
        VoxelKey::new(
            compact_bits(self.0),
            compact_bits(self.0 >> 1),
            compact_bits(self.0 >> 2),
        )
    }

    /// Index (0..8) of the child taken when descending from depth `depth` to `depth + 1`.
    pub fn child_index(self, depth: u8) -> u8 {
        debug_assert!(depth < TREE_DEPTH);
        ((self.0 >> (3 * u32::from(TREE_DEPTH - 1 - depth))) & 7) as u8
    }

    /// The code of the first voxel of the depth-`depth` node that contains this voxel.
    pub fn node_start(self, depth: u8) -> MortonCode {
        MortonCode(self.0 & !(voxels_per_node(depth) - 1))
    }
}

/// How many finest-level voxels a node at `depth` covers: `8^(16 - depth)`.
///
/// `depth` must be at most [`TREE_DEPTH`].
pub const fn voxels_per_node(depth: u8) -> u64 {
    1 << (3 * (TREE_DEPTH - depth) as u32)
}

/// Spreads the 16 bits of `v` to every third bit of a u64 (bit i → bit 3i).
fn spread_bits(v: u16) -> u64 {
    let mut x = u64::from(v);
    x = (x | x << 16) & 0x0000_FF00_00FF;
    x = (x | x << 8) & 0x00F0_0F00_F00F;
    x = (x | x << 4) & 0x0C30_C30C_30C3;
    x = (x | x << 2) & 0x2492_4924_9249;
    x
}

/// Inverse of [`spread_bits`]: gathers every third bit starting at bit 0.
fn compact_bits(v: u64) -> u16 {
    let mut x = v & 0x2492_4924_9249;
    x = (x | x >> 2) & 0x0C30_C30C_30C3;
    x = (x | x >> 4) & 0x00F0_0F00_F00F;
    x = (x | x >> 8) & 0x0000_FF00_00FF;
    x = (x | x >> 16) & 0x0000_0000_FFFF;
    // Only 16 input bits were spread, so the result fits.
    x as u16
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn slow_morton(k: VoxelKey) -> u64 {
        let mut code = 0u64;
        for b in 0..16 {
            code |= u64::from((k.x >> b) & 1) << (3 * b);
            code |= u64::from((k.y >> b) & 1) << (3 * b + 1);
            code |= u64::from((k.z >> b) & 1) << (3 * b + 2);
        }
        code
    }

    proptest! {
        #[test]
        fn morton_matches_bitwise_definition(x: u16, y: u16, z: u16) {
            let key = VoxelKey::new(x, y, z);
            prop_assert_eq!(key.morton().0, slow_morton(key));
            prop_assert_eq!(key.morton().key(), key);
        }

        #[test]
        fn child_index_uses_octomap_bit_order(x: u16, y: u16, z: u16, depth in 0u8..16) {
            let key = VoxelKey::new(x, y, z);
            let bit = 15 - depth;
            let expected = ((x >> bit) & 1) | ((y >> bit) & 1) << 1 | ((z >> bit) & 1) << 2;
            prop_assert_eq!(u16::from(key.morton().child_index(depth)), expected);
        }

        #[test]
        fn point_to_key_and_back(x in -2000.0f64..2000.0, y in -2000.0f64..2000.0, z in -2000.0f64..2000.0) {
            let res = 0.08;
            let key = VoxelKey::from_point([x, y, z], res).unwrap();
            let c = key.center(res);
            for (p, q) in [x, y, z].iter().zip(c.iter()) {
                prop_assert!((p - q).abs() <= res / 2.0 + 1e-9);
            }
        }
    }

    #[test]
    fn out_of_range_points_have_no_key() {
        assert!(VoxelKey::from_point([1e9, 0.0, 0.0], 0.1).is_none());
        assert!(VoxelKey::from_point([f64::NAN, 0.0, 0.0], 0.1).is_none());
        assert_eq!(
            VoxelKey::from_point([-3276.8, 0.0, 0.0], 0.1).map(|k| k.x),
            Some(0)
        );
    }

    #[test]
    fn node_start_and_size() {
        assert_eq!(voxels_per_node(16), 1);
        assert_eq!(voxels_per_node(0), MortonCode::END);
        let code = VoxelKey::new(0xFFFF, 0xFFFF, 0xFFFF).morton();
        assert_eq!(code.node_start(15).0, code.0 - 7);
        assert_eq!(code.node_start(0).0, 0);
    }
}
