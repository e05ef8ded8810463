//! Shared test material: a small synthetic office and the real door data.

#![allow(dead_code)]

use froctomap_core::{Occupancy, Snapshot, VoxelKey};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The real door series, beside the checkout (never copied into the repository).
pub const DOOR_FILE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../../shared/data/greg_door_2016_min/training_data.txt"
);

/// The real FR-079 corridor scan shipped with liboctomap-dev.
pub const GEB079: &str = "/usr/share/doc/liboctomap-dev/examples/data/geb079.bt";

pub fn door_file() -> PathBuf {
    PathBuf::from(DOOR_FILE)
}

/// Reads the door file independently of the crate's parser: unix second -> open.
pub fn raw_door_states(path: &Path) -> HashMap<i64, bool> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let mut f = l.split_whitespace();
            let t: i64 = f.next().unwrap().parse().unwrap();
            let s = f.next().unwrap() == "1";
            (t, s)
        })
        .collect()
}

/// A 10 x 6 m office floor at 0.1 m resolution, 2.6 m high: a corridor along x (y 0..2 m)
/// and two rooms (y 2.1..6 m) behind a wall with one 0.9 m doorway each, a wall between the
/// rooms, floor and ceiling. Space outside the walls is unknown. 156 k voxels.
pub fn office() -> Snapshot {
    let (nx, ny, nz) = (100u16, 60u16, 26u16);
    let mut voxels = Vec::with_capacity(usize::from(nx) * usize::from(ny) * usize::from(nz));
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let outer = x == 0 || x == nx - 1 || y == 0 || y == ny - 1;
                let doorway = (20..29).contains(&x) || (70..79).contains(&x);
                let corridor_wall = y == 20 && !(doorway && z <= 20);
                let room_wall = x == 50 && y > 20;
                let solid = z == 0 || z == nz - 1 || outer || corridor_wall || room_wall;
                let state = Occupancy::from(solid);
                voxels.push((
                    VoxelKey::new(32768 + x, 32768 + y, 32768 + z).morton(),
                    state,
                ));
            }
        }
    }
    Snapshot::from_voxel_states(0.1, voxels).unwrap()
}

/// Loads geb079 through the registry.
pub fn geb079() -> Snapshot {
    froctomap_formats::FormatRegistry::with_default_formats()
        .read_file(Path::new(GEB079), Default::default())
        .unwrap()
        .map
        .snapshot
}
