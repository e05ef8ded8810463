//! Where elements go: doorways found in the base map's walls, and free floor spots.
//!
//! Doors are searched at 1 m above the floor for runs of free voxels between two occupied
//! voxels along x or y: a gap in a wall. A run 0.6–1.4 m wide whose column is clear to at
//! least 1.8 m, with wall on both sides (jambs) for most of that height, floor beneath and
//! open space on both sides of the gap (so it leads somewhere) is a *doorway*; a run of
//! 1.4–3.2 m with the same properties is a corridor cross-section, where a corridor (fire)
//! door can stand. Everything else (people, chairs, objects, machines) stands on *floor
//! spots*: a box of known-free voxels whose footprint rests on occupied floor voxels, with
//! a free ring around it so it does not merge with walls. Placed elements reserve their box
//! plus a margin, so elements never overlap or block a doorway.

use crate::geometry::{BaseIndex, KeyBox};
use crate::rng::SplitMix64;

/// A door placement.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DoorSite {
    /// The slab (one voxel thick).
    pub(crate) slab: KeyBox,
    pub(crate) width_m: f64,
    pub(crate) across_corridor: bool,
}

pub(crate) struct Placer<'a, 'b> {
    index: &'b BaseIndex<'a>,
    resolution: f64,
    floor: i32,
    /// Tolerance on the floor height, in voxels.
    tolerance: i32,
    /// `(x, y, floor z)` of every column with floor and free space above it.
    floor_cells: Vec<[i32; 3]>,
    reserved: Vec<KeyBox>,
    pub(crate) rng: SplitMix64,
}

impl<'a, 'b> Placer<'a, 'b> {
    pub(crate) fn new(index: &'b BaseIndex<'a>, resolution: f64, seed: u64) -> Option<Self> {
        let floor = index.floor_level()?;
        let tolerance = voxels(0.3, resolution);
        let b = index.bounds;
        let stride = column_stride(&b);
        let mut floor_cells = Vec::new();
        for y in (b.min[1]..b.max[1]).step_by(stride) {
            for x in (b.min[0]..b.max[0]).step_by(stride) {
                for f in (floor - tolerance..=floor + tolerance).rev() {
                    if index.is_occupied([x, y, f]) && index.is_free([x, y, f + 1]) {
                        floor_cells.push([x, y, f]);
                        break;
                    }
                }
            }
        }
        Some(Self {
            index,
            resolution,
            floor,
            tolerance,
            floor_cells,
            reserved: Vec::new(),
            rng: SplitMix64::new(seed),
        })
    }

    /// Voxels spanning `metres` (at least one).
    pub(crate) fn voxels(&self, metres: f64) -> i32 {
        voxels(metres, self.resolution)
    }

    /// Voxels spanning a random length in `[lo, hi)` metres.
    pub(crate) fn random_voxels(&mut self, lo: f64, hi: f64) -> i32 {
        let metres = self.rng.range_f64(lo, hi);
        self.voxels(metres)
    }

    /// Floor columns found (for reports and tests).
    pub(crate) fn floor_cell_count(&self) -> usize {
        self.floor_cells.len()
    }

    fn reserve(&mut self, b: KeyBox, margin: i32) {
        self.reserved.push(b.grown([margin, margin, 0]));
    }

    fn is_reserved(&self, b: &KeyBox) -> bool {
        self.reserved.iter().any(|r| r.intersects(b))
    }

    /// Up to `n` door sites: doorways first, then corridor cross-sections, in random order.
    pub(crate) fn place_doors(&mut self, n: usize) -> Vec<DoorSite> {
        if n == 0 {
            return Vec::new();
        }
        let (mut doorways, mut corridors) = self.door_candidates();
        self.rng.shuffle(&mut doorways);
        self.rng.shuffle(&mut corridors);
        let margin = self.voxels(0.5);
        let mut sites = Vec::new();
        for site in doorways.into_iter().chain(corridors) {
            if sites.len() == n {
                break;
            }
            if self.is_reserved(&site.slab.grown([margin, margin, 0])) {
                continue;
            }
            self.reserve(site.slab, margin);
            sites.push(site);
        }
        sites
    }

    fn door_candidates(&self) -> (Vec<DoorSite>, Vec<DoorSite>) {
        let probe = self.floor + self.voxels(1.0);
        let (narrow, wide, widest) = (self.voxels(0.6), self.voxels(1.4), self.voxels(3.2));
        let b = self.index.bounds;
        let mut doorways = Vec::new();
        let mut corridors = Vec::new();
        for run_axis in [0usize, 1] {
            let across = 1 - run_axis;
            for vb in (b.min[across]..b.max[across]).step_by(line_stride(&b)) {
                // Runs of free voxels that start right after and end right before an
                // occupied voxel.
                let mut start: Option<i32> = None;
                let mut after_occupied = false;
                for va in b.min[run_axis]..b.max[run_axis] {
                    let k = at(run_axis, va, vb, probe);
                    match self.index.state(k) {
                        Some(froctomap_core::Occupancy::Occupied) => {
                            if let Some(s) = start.take() {
                                let width = va - s;
                                if (narrow..=widest).contains(&width) {
                                    if let Some(site) = self.check_door(run_axis, vb, s, va) {
                                        if width <= wide {
                                            doorways.push(site);
                                        } else {
                                            corridors.push(site);
                                        }
                                    }
                                }
                            }
                            after_occupied = true;
                        }
                        Some(froctomap_core::Occupancy::Free) => {
                            if after_occupied {
                                start = Some(va);
                            }
                            after_occupied = false;
                        }
                        None => {
                            start = None;
                            after_occupied = false;
                        }
                    }
                }
            }
        }
        (doorways, corridors)
    }

    /// Validates the free run `[s, e)` along `a` on line `vb` as a door opening.
    fn check_door(&self, a: usize, vb: i32, s: i32, e: i32) -> Option<DoorSite> {
        let index = self.index;
        let mid = s + (e - s) / 2;
        let probe = self.floor + self.voxels(1.0);
        // Floor under the middle of the opening.
        let mut f = probe - 1;
        while f >= self.floor - self.tolerance && index.is_free(at(a, mid, vb, f)) {
            f -= 1;
        }
        if f < self.floor - self.tolerance
            || f > self.floor + self.tolerance
            || !index.is_occupied(at(a, mid, vb, f))
        {
            return None;
        }
        // Clear height across the whole opening.
        let (max_h, min_h) = (self.voxels(2.0), self.voxels(1.8));
        let mut h = 0;
        while h < max_h && (s..e).all(|va| index.is_free(at(a, va, vb, f + 1 + h))) {
            h += 1;
        }
        if h < min_h {
            return None;
        }
        let width = e - s;
        let supported = (s..e)
            .filter(|&va| {
                index.is_occupied(at(a, va, vb, f)) || index.is_occupied(at(a, va, vb, f - 1))
            })
            .count() as i32;
        if supported * 4 < width * 3 {
            return None;
        }
        // Wall on both sides for most of the height (allowing one voxel of slant).
        let jamb = |va: i32| {
            (f + 1..f + 1 + h)
                .filter(|&z| (-1..=1).any(|d| index.is_occupied(at(a, va, vb + d, z))))
                .count() as i32
        };
        if jamb(s - 1) * 5 < h * 3 || jamb(e) * 5 < h * 3 {
            return None;
        }
        // Open space on both sides: the gap leads somewhere.
        let z = f + self.voxels(1.0);
        for sign in [-1, 1] {
            let cells: Vec<_> = (2..=4).map(|d| at(a, mid, vb + sign * d, z)).collect();
            if cells.iter().any(|&k| index.is_occupied(k))
                || !cells.iter().any(|&k| index.is_free(k))
            {
                return None;
            }
        }
        let min = at(a, s, vb, f + 1);
        let mut size = [1, 1, h];
        size[a] = width;
        Some(DoorSite {
            slab: KeyBox::new(min, size),
            width_m: f64::from(width) * self.resolution,
            across_corridor: width > self.voxels(1.4),
        })
    }

    /// A free floor box of `size` voxels (x, y, z), reserved with `margin` voxels around it.
    pub(crate) fn place_on_floor(&mut self, size: [i32; 3], margin: i32) -> Option<KeyBox> {
        if self.floor_cells.is_empty() {
            return None;
        }
        for _ in 0..400 {
            let i = self.rng.below(self.floor_cells.len() as u64) as usize;
            let [x, y, f] = self.floor_cells[i];
            let candidate = KeyBox::new([x, y, f + 1], size);
            if self.fits(&candidate) && !self.is_reserved(&candidate.grown([margin, margin, 0])) {
                self.reserve(candidate, margin);
                return Some(candidate);
            }
        }
        None
    }

    fn fits(&self, b: &KeyBox) -> bool {
        let index = self.index;
        let f = b.min[2] - 1;
        let footprint = KeyBox {
            min: [b.min[0], b.min[1], f],
            max: [b.max[0], b.max[1], f + 1],
        };
        let area = footprint.volume() as usize;
        let supported = footprint
            .keys()
            .filter(|&[x, y, z]| index.is_occupied([x, y, z]) || index.is_occupied([x, y, z - 1]))
            .count();
        if supported * 5 < area * 4 {
            return false;
        }
        // The ring one voxel around (and above) must hold no wall; the box itself must be
        // known free so the element only ever replaces observed free space.
        let ring = KeyBox {
            min: [b.min[0] - 1, b.min[1] - 1, b.min[2]],
            max: [b.max[0] + 1, b.max[1] + 1, b.max[2] + 1],
        };
        index.all_free(b) && index.none_occupied(&ring)
    }
}

/// Columns scanned per map: enough for a building floor at fine resolution (4096 x 4096).
const MAX_COLUMNS: u64 = 1 << 24;

/// Step between scanned columns and lines: 1 for maps up to [`MAX_COLUMNS`] columns, then
/// coarser so placement time stays bounded on huge maps (candidates are still checked
/// voxel by voxel).
fn column_stride(b: &KeyBox) -> usize {
    let area = (b.max[0] - b.min[0]).max(0) as u64 * (b.max[1] - b.min[1]).max(0) as u64;
    let mut stride = 1u64;
    while area / (stride * stride) > MAX_COLUMNS {
        stride += 1;
    }
    stride as usize
}

/// Step between scanned lines of the door search: every line for maps up to
/// [`MAX_COLUMNS`] columns, then fewer so that at most that many voxels are visited per axis.
fn line_stride(b: &KeyBox) -> usize {
    let area = (b.max[0] - b.min[0]).max(0) as u64 * (b.max[1] - b.min[1]).max(0) as u64;
    area.div_ceil(MAX_COLUMNS).max(1) as usize
}

/// Key coordinates of position `va` along axis `a`, `vb` along the other horizontal axis.
fn at(a: usize, va: i32, vb: i32, z: i32) -> [i32; 3] {
    let mut k = [0, 0, z];
    k[a] = va;
    k[1 - a] = vb;
    k
}

fn voxels(metres: f64, resolution: f64) -> i32 {
    // Clamped to the key range; NaN becomes 1.
    let n = (metres / resolution).round();
    if n >= 65_536.0 {
        65_536
    } else if n >= 1.0 {
        n as i32
    } else {
        1
    }
}
