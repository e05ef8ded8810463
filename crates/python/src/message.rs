//! Maps as `octomap_msgs/Octomap` messages: a `.bt`/`.ot` file's header becomes the
//! message's `id` and `resolution` (and `binary`), its body the message's `data`, and back,
//! as octomap_msgs' `binaryMapToMsg`/`fullMapToMsg` and `msgToMap` do.

use crate::errors::{froct_error_text, to_py};
use froctomap_octomap_codec::{detect_kind, parse_header, FileKind};
use froctomap_ros::OctomapMessage;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

/// The fields of the `octomap_msgs/Octomap` message holding the map file `data` (a `.bt`
/// or `.ot` file's bytes): `{"binary", "id", "resolution", "data"}`, `data` the file's body
/// behind its text header.
#[pyfunction]
pub fn octomap_message_fields<'py>(py: Python<'py>, data: &[u8]) -> PyResult<Bound<'py, PyDict>> {
    let kind = detect_kind(data).ok_or_else(|| {
        froct_error_text(
            "not an OctoMap file with a text header (`# Octomap OcTree binary file` or `# Octomap OcTree file`)",
        )
    })?;
    let header = parse_header(data, kind).map_err(to_py)?;
    let body = data.get(header.body_offset..).unwrap_or_default();
    let fields = PyDict::new(py);
    fields.set_item("binary", kind == FileKind::Binary)?;
    fields.set_item("id", header.tree_id)?;
    fields.set_item("resolution", header.resolution)?;
    fields.set_item("data", PyBytes::new(py, body))?;
    Ok(fields)
}

/// The map file (`.bt` for `binary`, else `.ot`) an `octomap_msgs/Octomap` message holds:
/// its `data` behind the header OctoMap writes, with the message's `id`, `resolution` and
/// the body's node count (a `data` that is a whole file, header included, is returned as
/// it is).
#[pyfunction]
pub fn octomap_message_file<'py>(
    py: Python<'py>,
    binary: bool,
    id: &str,
    resolution: f64,
    data: &[u8],
) -> PyResult<Bound<'py, PyBytes>> {
    let message = OctomapMessage {
        stamp_ns: 0,
        frame_id: "",
        binary,
        id,
        resolution,
        data,
    };
    let file = py.detach(|| message.map_file()).map_err(to_py)?;
    Ok(PyBytes::new(py, &file))
}
