//! The occupied voxels of an exported map as a `foxglove.PointCloud` message in JSON (with
//! a `jsonschema` schema), which Foxglove's 3D panel draws on its timeline without ROS.
//!
//! One point per occupied voxel at the map's resolution (a coarse cell gives one point per
//! voxel it covers), at the voxel's centre, with four colour fields (`red`, `green`, `blue`,
//! `alpha`: Foxglove's "RGBA (separate fields)" colour mode) and two value fields, the same
//! in every message whatever the map (so `--mode auto` changes no field's meaning within a
//! topic): `p`, the probability of the voxel being occupied in the map (a predicted voxel's
//! `p(t)`, coloured from purple at 0.5 to yellow at 1; 1 for a retrieved one, observed
//! occupied), and `dynamic`, 1 for a retrieved voxel whose state changes over the file's
//! span (orange), 0 for a static one (grey), NaN for a predicted one (not told).

use crate::encode::encode_point_cloud2_cdr;
use crate::error::McapWriteError;
use crate::markers::{cell_box, shade};
use base64::Engine;
use froctomap_core::{voxels_per_node, MortonCode, Timestamp};
use froctomap_formats::{ExportedKind, OccupiedCell};

/// The schema name Foxglove recognises.
pub const POINT_CLOUD_SCHEMA: &str = "foxglove.PointCloud";

/// Most points one message holds (16 Mi voxels: 320 MiB of points, more as base64 text).
pub const MAX_POINTS: u64 = 1 << 24;

/// Bytes per point: x, y, z (float32), red, green, blue, alpha (uint8), `p` and `dynamic`
/// (float32).
const STRIDE: usize = 24;

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
/// colour bytes in the order `colour` gives them, `p` and `dynamic` as float32).
fn points(
    resolution: f64,
    occupied: &[OccupiedCell],
    colour: fn([u8; 4]) -> [u8; 4],
) -> Result<Vec<u8>, McapWriteError> {
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
        let (rgba, p, dynamic) = shade(cell.shade);
        for code in cell.start.0..cell.start.0 + voxels_per_node(cell.depth) {
            for c in MortonCode(code).key().center(resolution) {
                data.extend_from_slice(&(c as f32).to_le_bytes());
            }
            data.extend_from_slice(&colour(rgba));
            data.extend_from_slice(&p.to_le_bytes());
            data.extend_from_slice(&dynamic.to_le_bytes());
        }
    }
    Ok(data)
}

/// The JSON `foxglove.PointCloud` message of a map's occupied cells (the MCAP export's
/// [`POINT_CLOUD_TOPIC`](crate::POINT_CLOUD_TOPIC) messages, and the node's Foxglove view).
pub fn point_cloud_json(
    time: Timestamp,
    frame_id: &str,
    resolution: f64,
    occupied: &[OccupiedCell],
) -> Result<Vec<u8>, McapWriteError> {
    let data = points(resolution, occupied, |rgba| rgba)?;
    let fields: Vec<serde_json::Value> = [
        ("x", 0, FLOAT32),
        ("y", 4, FLOAT32),
        ("z", 8, FLOAT32),
        ("red", 12, UINT8),
        ("green", 13, UINT8),
        ("blue", 14, UINT8),
        ("alpha", 15, UINT8),
        ("p", 16, FLOAT32),
        ("dynamic", 20, FLOAT32),
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
/// colours), `p` and `dynamic` (FLOAT32).
pub(crate) fn point_cloud2(
    stamp: (i32, u32),
    frame_id: &str,
    resolution: f64,
    occupied: &[OccupiedCell],
) -> Result<Vec<u8>, McapWriteError> {
    // Little-endian 0xAARRGGBB: blue, green, red, alpha.
    let data = points(resolution, occupied, |[r, g, b, a]| [b, g, r, a])?;
    const ROS_UINT32: u8 = 6;
    const ROS_FLOAT32: u8 = 7;
    let fields = [
        ("x", 0, ROS_FLOAT32),
        ("y", 4, ROS_FLOAT32),
        ("z", 8, ROS_FLOAT32),
        ("rgba", 12, ROS_UINT32),
        ("p", 16, ROS_FLOAT32),
        ("dynamic", 20, ROS_FLOAT32),
    ];
    encode_point_cloud2_cdr(stamp, frame_id, &fields, STRIDE as u32, &data).ok_or(
        McapWriteError::MessageTooLong {
            bytes: data.len() as u64,
        },
    )
}

/// The schema name of Foxglove's scene updates.
pub const SCENE_UPDATE_SCHEMA: &str = "foxglove.SceneUpdate";

/// `foxglove.SceneUpdate` as a JSON schema: the fields this writer fills (one entity of
/// cubes, its metadata; Foxglove's other primitives left empty).
pub const SCENE_UPDATE_JSON_SCHEMA: &str = r#"{
  "title": "foxglove.SceneUpdate",
  "description": "An update to the entities displayed in a 3D scene",
  "type": "object",
  "properties": {
    "deletions": {"type": "array", "items": {"type": "object"}},
    "entities": {
      "type": "array",
      "items": {
        "title": "foxglove.SceneEntity",
        "type": "object",
        "properties": {
          "timestamp": {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
          "frame_id": {"type": "string"},
          "id": {"type": "string"},
          "lifetime": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
          "frame_locked": {"type": "boolean"},
          "metadata": {"type": "array", "items": {"type": "object", "properties": {"key": {"type": "string"}, "value": {"type": "string"}}, "required": ["key", "value"]}},
          "arrows": {"type": "array"},
          "cubes": {
            "type": "array",
            "items": {
              "title": "foxglove.CubePrimitive",
              "type": "object",
              "properties": {
                "pose": {
                  "type": "object",
                  "properties": {
                    "position": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}, "required": ["x", "y", "z"]},
                    "orientation": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}, "w": {"type": "number"}}, "required": ["x", "y", "z", "w"]}
                  },
                  "required": ["position", "orientation"]
                },
                "size": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}, "required": ["x", "y", "z"]},
                "color": {"type": "object", "properties": {"r": {"type": "number"}, "g": {"type": "number"}, "b": {"type": "number"}, "a": {"type": "number"}}, "required": ["r", "g", "b", "a"]}
              },
              "required": ["pose", "size", "color"]
            }
          },
          "spheres": {"type": "array"},
          "cylinders": {"type": "array"},
          "lines": {"type": "array"},
          "triangles": {"type": "array"},
          "texts": {"type": "array"},
          "models": {"type": "array"}
        }
      }
    }
  }
}"#;

/// The id of the one entity a [`scene_update_json`] message holds (each message replaces
/// the previous map's cubes).
pub const SCENE_ENTITY_ID: &str = "occupied";

/// The JSON `foxglove.SceneUpdate` of a map's occupied cells: one entity
/// ([`SCENE_ENTITY_ID`]) holding a cube per cell, centred on it and sized by it (a coarse
/// cell one large cube), in the colours of the point clouds, and its metadata: `map`
/// (`retrieved` or `predicted`) and, for a retrieved map, `sample`.
pub fn scene_update_json(
    time: Timestamp,
    frame_id: &str,
    kind: ExportedKind,
    resolution: f64,
    occupied: &[OccupiedCell],
) -> Result<Vec<u8>, McapWriteError> {
    use std::fmt::Write as _;
    if occupied.len() as u64 > MAX_POINTS {
        return Err(McapWriteError::TooManyPoints {
            voxels: occupied.len() as u64,
            limit: MAX_POINTS,
        });
    }
    let mut metadata = vec![serde_json::json!({"key": "map", "value": kind_name(kind)})];
    if let ExportedKind::Retrieved { sample } = kind {
        metadata.push(serde_json::json!({"key": "sample", "value": sample.to_string()}));
    }
    let entity_head = serde_json::json!({
        "timestamp": {
            "sec": time.0.div_euclid(1_000_000_000),
            "nsec": time.0.rem_euclid(1_000_000_000),
        },
        "frame_id": frame_id,
        "id": SCENE_ENTITY_ID,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": false,
        "metadata": metadata,
    })
    .to_string();
    // About 190 bytes a cube.
    let mut out = String::with_capacity(512 + 200 * occupied.len());
    out.push_str(r#"{"deletions":[],"entities":["#);
    // The entity's fields, then its cubes and empty primitives.
    out.push_str(entity_head.strip_suffix('}').unwrap_or(&entity_head));
    out.push_str(r#","cubes":["#);
    for (i, cell) in occupied.iter().enumerate() {
        let ([x, y, z], size) = cell_box(cell, resolution);
        let ([r, g, b, a], _, _) = shade(cell.shade);
        let unit = |c: u8| f32::from(c) / 255.0;
        let _ = write!(
            out,
            r#"{}{{"pose":{{"position":{{"x":{x},"y":{y},"z":{z}}},"orientation":{{"x":0,"y":0,"z":0,"w":1}}}},"size":{{"x":{size},"y":{size},"z":{size}}},"color":{{"r":{},"g":{},"b":{},"a":{}}}}}"#,
            if i > 0 { "," } else { "" },
            unit(r),
            unit(g),
            unit(b),
            unit(a),
        );
    }
    out.push_str(
        r#"],"arrows":[],"spheres":[],"cylinders":[],"lines":[],"triangles":[],"texts":[],"models":[]}]}"#,
    );
    Ok(out.into_bytes())
}

/// `retrieved` or `predicted`: what an exported map is, as its messages' metadata say.
pub fn kind_name(kind: ExportedKind) -> &'static str {
    match kind {
        ExportedKind::Retrieved { .. } => "retrieved",
        ExportedKind::Predicted => "predicted",
    }
}
