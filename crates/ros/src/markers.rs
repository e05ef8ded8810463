//! The occupied cells of a map as a `visualization_msgs/msg/MarkerArray`, laid out as
//! `octomap_server` lays out its `occupied_cells_vis_array` (`OctomapServer::publishAll`):
//! one `CUBE_LIST` marker per tree depth 0..=16 (`id` the depth, cubes the size of a node at
//! that depth, centred on the node), `ADD` when the depth has cubes and `DELETE` when not,
//! so that rviz2's MarkerArray display drops the cubes a depth no longer has. Each cube has
//! its own colour (`colors`, as octomap_server's height map does): the probability ramp of
//! a predicted cell (purple at 0.5 to yellow at 1), orange for a retrieved cell whose state
//! changes, grey for a static one (the colours of the MCAP export's point clouds).
//!
//! The message is the `visualization_msgs/msg/Marker` of ROS 2 Humble and later (with
//! `texture`, `uv_coordinates` and `mesh_file`, left empty).

use crate::encode::{too_long, CdrWriter};
use froctomap_core::MortonCode;
use froctomap_formats::{CellShade, OccupiedCell};

/// The ROS 2 type name of the messages [`encode_occupied_marker_array_cdr`] writes.
pub const MARKER_ARRAY_TYPE: &str = "visualization_msgs/msg/MarkerArray";
/// `visualization_msgs/msg/Marker.CUBE_LIST`.
pub const CUBE_LIST: i32 = 6;
/// `visualization_msgs/msg/Marker.DELETE`.
pub const MARKER_DELETE: i32 = 2;
/// The markers' namespace.
pub const MARKER_NAMESPACE: &str = "froctomap";

/// The deepest tree depth (one voxel).
const TREE_DEPTH: u8 = 16;

/// A `visualization_msgs/msg/MarkerArray` in little-endian CDR of `occupied` (a map's
/// occupied cells at `resolution`): 17 `CUBE_LIST` markers stamped `stamp` in `frame_id`,
/// marker `d` holding the cells of depth `d`. `None` when a field is longer than a CDR
/// length can say.
///
/// ```
/// use froctomap_core::MortonCode;
/// use froctomap_formats::{CellShade, OccupiedCell};
/// let cell = OccupiedCell { start: MortonCode(0), depth: 16, shade: CellShade::Probability(0.9) };
/// let bytes = froctomap_ros::encode_occupied_marker_array_cdr((1, 0), "map", 0.1, &[cell]).unwrap();
/// assert_eq!(&bytes[4..8], &17u32.to_le_bytes()); // one marker per depth 0..=16
/// ```
pub fn encode_occupied_marker_array_cdr(
    stamp: (i32, u32),
    frame_id: &str,
    resolution: f64,
    occupied: &[OccupiedCell],
) -> Option<Vec<u8>> {
    if too_long(frame_id.len()) {
        return None;
    }
    let mut by_depth: Vec<Vec<&OccupiedCell>> = vec![Vec::new(); usize::from(TREE_DEPTH) + 1];
    for cell in occupied {
        by_depth.get_mut(usize::from(cell.depth))?.push(cell);
    }
    // 24 bytes a point, 16 a colour.
    let mut out = CdrWriter::with_capacity(256 * by_depth.len() + 40 * occupied.len());
    out.u32(by_depth.len() as u32);
    for (depth, cells) in by_depth.iter().enumerate() {
        let count = u32::try_from(cells.len()).ok()?;
        // 2^(16 - depth) voxels along each axis.
        let side = f64::from(1u32 << (usize::from(TREE_DEPTH) - depth));
        let size = resolution * side;
        out.header(stamp, frame_id);
        out.string(MARKER_NAMESPACE);
        out.i32(depth as i32);
        out.i32(CUBE_LIST);
        out.i32(if cells.is_empty() { MARKER_DELETE } else { 0 });
        // pose: position 0, orientation identity.
        for v in [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0] {
            out.f64(v);
        }
        for _ in 0..3 {
            out.f64(size);
        }
        for c in [1.0f32; 4] {
            out.f32(c); // color: unused, every cube has its own
        }
        out.i32(0); // lifetime: forever
        out.u32(0);
        out.bytes.push(0); // frame_locked
        out.u32(count);
        for cell in cells {
            for c in cell_box(cell, resolution).0 {
                out.f64(c);
            }
        }
        out.u32(count);
        for cell in cells {
            let (rgba, _, _) = shade(cell.shade);
            for c in rgba {
                out.f32(f32::from(c) / 255.0);
            }
        }
        out.string(""); // texture_resource
        out.header((0, 0), ""); // texture: sensor_msgs/CompressedImage, empty
        out.string("");
        out.u32(0);
        out.u32(0); // uv_coordinates
        out.string(""); // text
        out.string(""); // mesh_resource
        out.string(""); // mesh_file: filename, data
        out.u32(0);
        out.bytes.push(0); // mesh_use_embedded_materials
    }
    Some(out.bytes)
}

/// The centre of an occupied cell and its edge length, metres.
pub(crate) fn cell_box(cell: &OccupiedCell, resolution: f64) -> ([f64; 3], f64) {
    // 2^(16 - depth) voxels along each axis.
    let side = f64::from(1u32 << (TREE_DEPTH - cell.depth.min(TREE_DEPTH)));
    let key = MortonCode(cell.start.0).key();
    let centre = |k: u16| (f64::from(k) - 32768.0 + side / 2.0) * resolution;
    (
        [centre(key.x), centre(key.y), centre(key.z)],
        side * resolution,
    )
}

/// A cell's colour, `p` and `dynamic` (the colours the `foxglove` module's documentation describes).
pub(crate) fn shade(shade: CellShade) -> ([u8; 4], f32, f32) {
    match shade {
        CellShade::Probability(p) => (ramp(p), p, f32::NAN),
        CellShade::Dynamic => ([230, 85, 13, 255], 1.0, 1.0),
        _ => ([150, 150, 150, 255], 1.0, 0.0),
    }
}

/// Purple (p = 0.5) through teal to yellow (p = 1), linear between three stops.
fn ramp(p: f32) -> [u8; 4] {
    const STOPS: [[f32; 3]; 3] = [
        [68.0, 1.0, 84.0],
        [33.0, 145.0, 140.0],
        [253.0, 231.0, 37.0],
    ];
    let t = ((p - 0.5) * 2.0).clamp(0.0, 1.0) * 2.0;
    let (low, high, f) = if t < 1.0 {
        (STOPS[0], STOPS[1], t)
    } else {
        (STOPS[1], STOPS[2], t - 1.0)
    };
    let mix = |i: usize| (low[i] + (high[i] - low[i]) * f).round() as u8;
    [mix(0), mix(1), mix(2), 255]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_runs_from_purple_to_yellow() {
        assert_eq!(ramp(0.5), [68, 1, 84, 255]);
        assert_eq!(ramp(0.75), [33, 145, 140, 255]);
        assert_eq!(ramp(1.0), [253, 231, 37, 255]);
    }
}
