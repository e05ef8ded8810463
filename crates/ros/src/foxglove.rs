//! The occupied voxels of an exported map as a `foxglove.PointCloud` message in JSON (with
//! a `jsonschema` schema), which Foxglove's 3D panel draws on its timeline without ROS.
//!
//! One point per occupied voxel at the map's resolution (a coarse cell gives one point per
//! voxel it covers), at the voxel's centre, with four colour fields (`red`, `green`, `blue`,
//! `alpha`: Foxglove's "RGBA (separate fields)" colour mode) and one value field: `p`, the
//! probability of a predicted voxel (coloured from purple at 0.5 to yellow at 1), or
//! `dynamic`, 1 for a retrieved voxel whose state changes over the file's span (orange) and
//! 0 for a static one (grey).

use crate::encode::encode_point_cloud2_cdr;
use crate::error::McapWriteError;
use base64::Engine;
use froctomap_core::{voxels_per_node, MortonCode, Timestamp};
use froctomap_formats::{CellShade, ExportedKind, OccupiedCell};

/// The schema name Foxglove recognises.
pub const POINT_CLOUD_SCHEMA: &str = "foxglove.PointCloud";

/// Most points one message holds (16 Mi voxels: 320 MiB of points, more as base64 text).
pub const MAX_POINTS: u64 = 1 << 24;

/// Bytes per point: x, y, z (float32), red, green, blue, alpha (uint8), the value (float32).
const STRIDE: usize = 20;

/// `foxglove.PointCloud` as a JSON schema (the fields this writer fills).
pub const POINT_CLOUD_JSON_SCHEMA: &str = r#"{
  "title": "foxglove.PointCloud",
  "description": "A collection of N-dimensional points",
  "type": "object",
  "properties": {
    "timestamp": {
      "type": "object",
      "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}
    },
    "frame_id": {"type": "string"},
    "pose": {
      "type": "object",
      "properties": {
        "position": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}},
        "orientation": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}, "w": {"type": "number"}}}
      }
    },
    "point_stride": {"type": "integer", "minimum": 0},
    "fields": {
      "type": "array",
      "items": {
        "type": "object",
        "properties": {
          "name": {"type": "string"},
          "offset": {"type": "integer", "minimum": 0},
          "type": {"type": "integer", "description": "foxglove.NumericType: 1 UINT8, 7 FLOAT32"}
        }
      }
    },
    "data": {"type": "string", "contentEncoding": "base64"}
  }
}"#;

/// foxglove.NumericType values.
const UINT8: u8 = 1;
const FLOAT32: u8 = 7;

/// The points of a map's occupied cells: `STRIDE` bytes each (x, y, z as float32, four
/// colour bytes in the order `colour` gives them, the value as float32), and the value's
/// name (`p` or `dynamic`).
fn points(
    kind: ExportedKind,
    resolution: f64,
    occupied: &[OccupiedCell],
    colour: fn([u8; 4]) -> [u8; 4],
) -> Result<(Vec<u8>, &'static str), McapWriteError> {
    let voxels: u64 = occupied
        .iter()
        .map(|cell| voxels_per_node(cell.depth))
        .fold(0, u64::saturating_add);
    if voxels > MAX_POINTS {
        return Err(McapWriteError::TooManyPoints {
            voxels,
            limit: MAX_POINTS,
        });
    }
    let mut data = Vec::with_capacity(voxels as usize * STRIDE);
    for cell in occupied {
        let (rgba, value) = shade(cell.shade);
        for code in cell.start.0..cell.start.0 + voxels_per_node(cell.depth) {
            for c in MortonCode(code).key().center(resolution) {
                data.extend_from_slice(&(c as f32).to_le_bytes());
            }
            data.extend_from_slice(&colour(rgba));
            data.extend_from_slice(&value.to_le_bytes());
        }
    }
    let value_field = match kind {
        ExportedKind::Predicted => "p",
        _ => "dynamic",
    };
    Ok((data, value_field))
}

/// The JSON `foxglove.PointCloud` message of a map's occupied cells (the MCAP export's
/// [`POINT_CLOUD_TOPIC`](crate::POINT_CLOUD_TOPIC) messages, and the node's Foxglove view).
pub fn point_cloud_json(
    time: Timestamp,
    frame_id: &str,
    kind: ExportedKind,
    resolution: f64,
    occupied: &[OccupiedCell],
) -> Result<Vec<u8>, McapWriteError> {
    let (data, value_field) = points(kind, resolution, occupied, |rgba| rgba)?;
    let fields: Vec<serde_json::Value> = [
        ("x", 0, FLOAT32),
        ("y", 4, FLOAT32),
        ("z", 8, FLOAT32),
        ("red", 12, UINT8),
        ("green", 13, UINT8),
        ("blue", 14, UINT8),
        ("alpha", 15, UINT8),
        (value_field, 16, FLOAT32),
    ]
    .iter()
    .map(|&(name, offset, kind)| serde_json::json!({"name": name, "offset": offset, "type": kind}))
    .collect();
    let message = serde_json::json!({
        "timestamp": {
            "sec": time.0.div_euclid(1_000_000_000),
            "nsec": time.0.rem_euclid(1_000_000_000),
        },
        "frame_id": frame_id,
        "pose": {
            "position": {"x": 0.0, "y": 0.0, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
        },
        "point_stride": STRIDE,
        "fields": fields,
        "data": base64::engine::general_purpose::STANDARD.encode(&data),
    });
    Ok(message.to_string().into_bytes())
}

/// The same points as a `sensor_msgs/msg/PointCloud2` in CDR (for rviz2, Rerun and
/// Foxglove): fields `x y z` (FLOAT32), `rgba` (UINT32, `0xAARRGGBB` as rviz2 and PCL pack
/// colours) and the value (FLOAT32).
pub(crate) fn point_cloud2(
    stamp: (i32, u32),
    frame_id: &str,
    kind: ExportedKind,
    resolution: f64,
    occupied: &[OccupiedCell],
) -> Result<Vec<u8>, McapWriteError> {
    // Little-endian 0xAARRGGBB: blue, green, red, alpha.
    let (data, value_field) = points(kind, resolution, occupied, |[r, g, b, a]| [b, g, r, a])?;
    const ROS_UINT32: u8 = 6;
    const ROS_FLOAT32: u8 = 7;
    let fields = [
        ("x", 0, ROS_FLOAT32),
        ("y", 4, ROS_FLOAT32),
        ("z", 8, ROS_FLOAT32),
        ("rgba", 12, ROS_UINT32),
        (value_field, 16, ROS_FLOAT32),
    ];
    encode_point_cloud2_cdr(stamp, frame_id, &fields, STRIDE as u32, &data).ok_or(
        McapWriteError::MessageTooLong {
            bytes: data.len() as u64,
        },
    )
}

/// A cell's colour and value.
pub(crate) fn shade(shade: CellShade) -> ([u8; 4], f32) {
    match shade {
        CellShade::Probability(p) => (ramp(p), p),
        CellShade::Dynamic => ([230, 85, 13, 255], 1.0),
        _ => ([150, 150, 150, 255], 0.0),
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
