//! Surprising pieces grouped into connected regions (26-neighbourhood, one kind per region).

use super::report::{AnomalyKind, AnomalyRegion};
use super::score::Piece;
use froctomap_core::VoxelKey;
use std::collections::BTreeMap;

/// Union-find over piece indices.
struct Groups(Vec<usize>);

impl Groups {
    fn root(&mut self, mut i: usize) -> usize {
        while self.0[i] != i {
            self.0[i] = self.0[self.0[i]];
            i = self.0[i];
        }
        i
    }

    fn join(&mut self, a: usize, b: usize) {
        let (a, b) = (self.root(a), self.root(b));
        if a != b {
            self.0[a.max(b)] = a.min(b);
        }
    }
}

/// The connected regions of pieces of one kind (pieces touching by a face, an edge or a
/// corner belong together), each with its bounding box, voxels and score: the surprise of its
/// voxels beyond `threshold`, summed.
/// Cost: each piece probes the keys of the shell around it, so a coarse piece costs its
/// surface, never its volume.
pub(crate) fn regions(
    pieces: &[Piece],
    kind: AnomalyKind,
    resolution: f64,
    threshold: f64,
) -> Vec<AnomalyRegion> {
    let of_kind: Vec<&Piece> = pieces.iter().filter(|p| p.kind == kind).collect();
    let by_start: BTreeMap<u64, usize> = of_kind
        .iter()
        .enumerate()
        .map(|(i, p)| (p.start.0, i))
        .collect();
    let containing = |key: VoxelKey| -> Option<usize> {
        let code = key.morton().0;
        let (_, &i) = by_start.range(..=code).next_back()?;
        let piece = of_kind.get(i)?;
        (code < piece.start.0 + piece.voxels()).then_some(i)
    };
    let mut groups = Groups((0..of_kind.len()).collect());
    for (i, piece) in of_kind.iter().enumerate() {
        let leaf = piece.leaf();
        let lo = leaf.min_key();
        let edge = leaf.edge_voxels();
        if edge <= MAX_PROBED_EDGE {
            for neighbour in shell(lo, edge) {
                if let Some(j) = containing(neighbour) {
                    groups.join(i, j);
                }
            }
        } else {
            // A coarse cube's surface costs more than comparing it with every piece.
            for (j, other) in of_kind.iter().enumerate() {
                if j != i && touch(piece, other) {
                    groups.join(i, j);
                }
            }
        }
    }
    let mut by_root: BTreeMap<usize, AnomalyRegion> = BTreeMap::new();
    for (i, piece) in of_kind.iter().enumerate() {
        let root = groups.root(i);
        let (min, max) = piece.leaf().bounds(resolution);
        let voxels = piece.voxels();
        let region = by_root.entry(root).or_insert_with(|| AnomalyRegion {
            min,
            max,
            voxels: 0,
            score: 0.0,
            kind,
            cubes: Vec::new(),
        });
        for a in 0..3 {
            region.min[a] = region.min[a].min(min[a]);
            region.max[a] = region.max[a].max(max[a]);
        }
        region.voxels += voxels;
        region.score += (piece.surprise - threshold) * voxels as f64;
        region.cubes.push((piece.start, piece.depth));
    }
    by_root.into_values().collect()
}

/// Cubes up to this edge (voxels) find their neighbours by probing their shell; coarser
/// ones (rare: a large region seen for the first time) by comparing with every piece.
const MAX_PROBED_EDGE: u32 = 16;

/// `true` when two cubes touch or overlap (26-neighbourhood).
fn touch(a: &Piece, b: &Piece) -> bool {
    let (la, lb) = (a.leaf(), b.leaf());
    let (ka, kb) = (la.min_key(), lb.min_key());
    let (ea, eb) = (i64::from(la.edge_voxels()), i64::from(lb.edge_voxels()));
    let axis = |a: u16, b: u16| {
        let (a, b) = (i64::from(a), i64::from(b));
        a <= b + eb && b <= a + ea
    };
    axis(ka.x, kb.x) && axis(ka.y, kb.y) && axis(ka.z, kb.z)
}

/// The keys just outside the cube of `edge` voxels whose minimum corner is `lo`, that the
/// tree can address: its surface, not its volume (columns over the cube's footprint give
/// only the keys below and above it).
fn shell(lo: VoxelKey, edge: u32) -> impl Iterator<Item = VoxelKey> {
    let around = |v: u16| {
        let first = i64::from(v) - 1;
        let last = i64::from(v) + i64::from(edge);
        (first.max(0)..=last.min(i64::from(u16::MAX))).map(|k| k as u16)
    };
    let within =
        move |k: u16, v: u16| u32::from(k) >= u32::from(v) && u32::from(k) < u32::from(v) + edge;
    let ends: Vec<u16> = [i64::from(lo.z) - 1, i64::from(lo.z) + i64::from(edge)]
        .into_iter()
        .filter_map(|z| u16::try_from(z).ok())
        .collect();
    let (xs, ys, zs) = (around(lo.x), around(lo.y), around(lo.z));
    xs.flat_map(move |x| {
        let (zs, ends) = (zs.clone(), ends.clone());
        ys.clone().flat_map(move |y| {
            let column: Vec<u16> = if within(x, lo.x) && within(y, lo.y) {
                ends.clone()
            } else {
                zs.clone().collect()
            };
            column.into_iter().map(move |z| VoxelKey::new(x, y, z))
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::MortonCode;

    fn code(x: u16, y: u16, z: u16) -> MortonCode {
        VoxelKey::new(x, y, z).morton()
    }

    fn voxel(x: u16, y: u16, z: u16, kind: AnomalyKind) -> Piece {
        Piece {
            start: code(x, y, z),
            depth: 16,
            kind,
            surprise: 2.0,
        }
    }

    #[test]
    fn touching_pieces_of_one_kind_form_one_region() {
        use AnomalyKind::*;
        let pieces = [
            voxel(10, 10, 10, Appeared),
            voxel(11, 11, 11, Appeared), // corner contact
            voxel(13, 11, 11, Appeared), // a gap of one voxel: another region
            voxel(12, 11, 11, Vanished), // touches both, but of the other kind
            // An 8-voxel cube at (16..18)³ touching (15, 15, 15) by a corner.
            Piece {
                start: code(16, 16, 16),
                depth: 15,
                kind: Appeared,
                surprise: 1.0,
            },
            voxel(15, 15, 15, Appeared),
        ];
        let mut appeared = regions(&pieces, Appeared, 0.1, 1.0);
        appeared.sort_by(|a, b| a.voxels.cmp(&b.voxels).then(a.score.total_cmp(&b.score)));
        let summary: Vec<(u64, f64)> = appeared.iter().map(|r| (r.voxels, r.score)).collect();
        assert_eq!(summary, [(1, 1.0), (2, 2.0), (9, 1.0)]);
        let big = &appeared[2];
        let key_min = |m: f64| (m / 0.1).round() as i64;
        assert_eq!(big.min.map(key_min), [15 - 32768, 15 - 32768, 15 - 32768]);
        assert_eq!(big.max.map(key_min), [18 - 32768, 18 - 32768, 18 - 32768]);
        let vanished = regions(&pieces, Vanished, 0.1, 1.0);
        assert_eq!(vanished.len(), 1);
        assert_eq!(vanished[0].kind, Vanished);
    }

    #[test]
    fn coarse_cubes_join_their_neighbours_too() {
        use AnomalyKind::*;
        // A 32-voxel cube at (0..32)³, a voxel touching its far corner, one a voxel away.
        let pieces = [
            Piece {
                start: code(0, 0, 0),
                depth: 11,
                kind: Appeared,
                surprise: 2.0,
            },
            voxel(32, 32, 32, Appeared),
            voxel(34, 0, 0, Appeared),
        ];
        let mut found: Vec<u64> = regions(&pieces, Appeared, 0.1, 1.0)
            .iter()
            .map(|r| r.voxels)
            .collect();
        found.sort_unstable();
        assert_eq!(found, [1, 32 * 32 * 32 + 1]);
    }

    #[test]
    fn shells_stay_inside_the_key_range() {
        assert_eq!(shell(VoxelKey::new(5, 5, 5), 1).count(), 26);
        assert_eq!(shell(VoxelKey::new(5, 5, 5), 2).count(), 64 - 8);
        assert_eq!(shell(VoxelKey::new(0, 0, 0), 1).count(), 7);
        assert_eq!(shell(VoxelKey::new(u16::MAX, 0, 0), 1).count(), 7);
    }
}
