//! A small synthetic room for the query and anomaly tests: a floor, four walls, free space
//! inside, and a door that is open (free) from 08:00 to 18:00 UTC and closed otherwise.
//! Frames are hourly; every seventh frame hides one corner of the room (a partial view).
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use froctomap_convert::{build, collect_inputs, BuildOptions, Context, Silent, TimeSource};
use froctomap_core::calendar::iso8601_basic;
use froctomap_core::{Leaf, Occupancy, Snapshot, Timestamp, VoxelKey};
use froctomap_formats::WriteOptions;
use std::path::{Path, PathBuf};

/// Voxel edge, metres.
pub const RESOLUTION: f64 = 0.1;
/// The room spans keys `ORIGIN .. ORIGIN + SIDE` on x and y, `ORIGIN .. ORIGIN + HEIGHT` on z.
pub const ORIGIN: u16 = 32768;
/// Room side in voxels.
pub const SIDE: u16 = 32;
/// Room height in voxels.
pub const HEIGHT: u16 = 12;
/// 2016-01-04T00:00:00Z, a Monday.
pub const START: i64 = 1_451_865_600;

/// `true` for the door's voxels (in the wall at y = 0).
pub fn is_door(k: VoxelKey) -> bool {
    (ORIGIN + 12..ORIGIN + 18).contains(&k.x)
        && k.y == ORIGIN
        && (ORIGIN + 1..ORIGIN + 10).contains(&k.z)
}

/// The door is open from 08:00 to 18:00.
pub fn door_open_at(t: Timestamp) -> bool {
    let hour = (t.0 / 1_000_000_000).rem_euclid(86_400) / 3600;
    (8..18).contains(&hour)
}

/// The state of a voxel of the room at `t` (every key of the room box is known).
pub fn state(k: VoxelKey, t: Timestamp) -> Occupancy {
    if is_door(k) {
        return Occupancy::from(!door_open_at(t));
    }
    let wall = |v: u16| v == ORIGIN || v == ORIGIN + SIDE - 1;
    Occupancy::from(k.z == ORIGIN || wall(k.x) || wall(k.y))
}

/// Every key of the room box.
pub fn keys() -> impl Iterator<Item = VoxelKey> {
    (ORIGIN..ORIGIN + SIDE).flat_map(|x| {
        (ORIGIN..ORIGIN + SIDE)
            .flat_map(move |y| (ORIGIN..ORIGIN + HEIGHT).map(move |z| VoxelKey::new(x, y, z)))
    })
}

/// The map at frame `i` (hour `i` after [`START`]), with `edit` applied to each voxel.
pub fn frame_with(
    i: u32,
    mut edit: impl FnMut(VoxelKey, Occupancy) -> Option<Occupancy>,
) -> Snapshot {
    let t = time(i);
    let hidden = |k: VoxelKey| i % 7 == 3 && k.x >= ORIGIN + 24 && k.y >= ORIGIN + 24;
    let leaves = keys()
        .filter(|&k| !hidden(k))
        .filter_map(|k| edit(k, state(k, t)).map(|s| Leaf::voxel(k, s.log_odds())))
        .collect();
    Snapshot::from_leaves(RESOLUTION, leaves)
        .unwrap()
        .canonical()
}

/// The map at frame `i`.
pub fn frame(i: u32) -> Snapshot {
    frame_with(i, |_, s| Some(s))
}

/// The instant of frame `i`.
pub fn time(i: u32) -> Timestamp {
    Timestamp::from_secs(START + i64::from(i) * 3600)
}

/// Writes `frame` as a `.bt` named by its time into `dir`.
pub fn write_frame(context: &Context, dir: &Path, i: u32, map: &Snapshot) -> PathBuf {
    let path = dir.join(format!("room_{}.bt", iso8601_basic(time(i))));
    context
        .formats()
        .write_file(map, &path, WriteOptions::default())
        .unwrap();
    path
}

/// Writes frames `0..frames` into `dir/series` and builds `dir/room.froct` from them; the
/// frames' paths in order.
pub fn build_room(context: &Context, dir: &Path, frames: u32) -> (PathBuf, Vec<PathBuf>) {
    let series = dir.join("series");
    std::fs::create_dir_all(&series).unwrap();
    let paths: Vec<PathBuf> = (0..frames)
        .map(|i| write_frame(context, &series, i, &frame(i)))
        .collect();
    let inputs = collect_inputs(context, &[series], TimeSource::Auto).unwrap();
    let out = dir.join("room.froct");
    build(context, &inputs, &out, &BuildOptions::default(), &Silent).unwrap();
    (out, paths)
}
