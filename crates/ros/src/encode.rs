//! Writing `octomap_msgs/msg/Octomap` messages in CDR, as ROS 2 publishes them (the inverse
//! of [`decode_message`](crate::decode_message) for [`Encoding::Cdr`](crate::Encoding)),
//! and the message definition MCAP files embed as the channel's `ros2msg` schema.

/// The `ros2msg` definitions of `std_msgs/Header` and the `builtin_interfaces/Time` in it,
/// each after a separator line: the nested types every stamped message's schema ends with.
macro_rules! header_definitions {
    () => {
        "\
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"
    };
}

/// The `ros2msg` schema of `octomap_msgs/msg/Octomap`: its fields, then each nested type's
/// definition after a separator line, as `ros2 bag record` embeds them in MCAP.
pub const OCTOMAP_ROS2MSG: &str = concat!(
    "\
std_msgs/Header header
bool binary
string id
float64 resolution
int8[] data
",
    header_definitions!()
);

/// The ROS 2 type name of the messages [`encode_octomap_cdr`] writes.
pub const OCTOMAP_TYPE: &str = "octomap_msgs/msg/Octomap";

/// An `octomap_msgs/msg/Octomap` message in little-endian CDR: header stamp (`sec`,
/// `nanosec`) and `frame_id`, `binary`, the tree `id`, `resolution` and the map `data` (for
/// `binary`, the body of a `.bt` file behind its text header, as octomap_msgs'
/// `binaryMapToMsg` fills it). `None` when a field is longer than a CDR length (`u32`) can
/// say.
///
/// ```
/// use froctomap_ros::{decode_message, encode_octomap_cdr, Encoding, MessageType};
/// let bytes = encode_octomap_cdr((1_700_000_000, 5), "map", true, "OcTree", 0.05, &[0x09, 0x00]).unwrap();
/// let message = decode_message(&bytes, Encoding::Cdr, MessageType::Octomap)?;
/// assert_eq!(message.stamp_ns, 1_700_000_000_000_000_005);
/// assert_eq!((message.binary, message.id, message.resolution, message.data), (true, "OcTree", 0.05, &[0x09, 0x00][..]));
/// # Ok::<(), froctomap_ros::MessageError>(())
/// ```
pub fn encode_octomap_cdr(
    stamp: (i32, u32),
    frame_id: &str,
    binary: bool,
    id: &str,
    resolution: f64,
    data: &[u8],
) -> Option<Vec<u8>> {
    if [frame_id.len(), id.len(), data.len()]
        .into_iter()
        .any(too_long)
    {
        return None;
    }
    let mut out = CdrWriter::with_capacity(64 + frame_id.len() + id.len() + data.len());
    out.header(stamp, frame_id);
    out.bytes.push(u8::from(binary));
    out.string(id);
    out.align(8);
    out.bytes.extend_from_slice(&resolution.to_le_bytes());
    out.u32(data.len() as u32); // Checked above.
    out.bytes.extend_from_slice(data);
    Some(out.bytes)
}

/// The ROS 1 type name of the messages [`encode_octomap_ros1`] writes.
pub const OCTOMAP_ROS1_TYPE: &str = "octomap_msgs/Octomap";

/// The full ROS 1 definition of `octomap_msgs/Octomap` as a bag's connection stores it: its
/// fields, then the nested `std_msgs/Header` after a separator line.
pub const OCTOMAP_ROS1_DEFINITION: &str = "\
std_msgs/Header header
bool binary
string id
float64 resolution
int8[] data
================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id
";

/// ROS 1's MD5 sum of `octomap_msgs/Octomap` (of its definition with the nested type's sum
/// in its place), which a bag's connection and ROS 1 subscribers check.
pub const OCTOMAP_ROS1_MD5: &str = "9a45536b45c5e409cd49f04bb2d9999f";

/// An `octomap_msgs/Octomap` message serialised as ROS 1 does (little-endian, no alignment):
/// header `seq`, stamp (`secs`, `nsecs`) and `frame_id`, `binary`, the tree `id`,
/// `resolution` and the map `data`. `None` when a field is longer than a ROS 1 length
/// (`u32`) can say.
///
/// ```
/// use froctomap_ros::{decode_message, encode_octomap_ros1, Encoding, MessageType};
/// let bytes = encode_octomap_ros1(7, (1_700_000_000, 5), "map", true, "OcTree", 0.05, &[0x09, 0x00]).unwrap();
/// let message = decode_message(&bytes, Encoding::Ros1, MessageType::Octomap)?;
/// assert_eq!(message.stamp_ns, 1_700_000_000_000_000_005);
/// assert_eq!((message.binary, message.id, message.resolution, message.data), (true, "OcTree", 0.05, &[0x09, 0x00][..]));
/// # Ok::<(), froctomap_ros::MessageError>(())
/// ```
pub fn encode_octomap_ros1(
    seq: u32,
    stamp: (u32, u32),
    frame_id: &str,
    binary: bool,
    id: &str,
    resolution: f64,
    data: &[u8],
) -> Option<Vec<u8>> {
    let length = |bytes: &[u8]| u32::try_from(bytes.len()).ok().map(u32::to_le_bytes);
    let (frame_len, id_len, data_len) = (
        length(frame_id.as_bytes())?,
        length(id.as_bytes())?,
        length(data)?,
    );
    let mut out = Vec::with_capacity(40 + frame_id.len() + id.len() + data.len());
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&stamp.0.to_le_bytes());
    out.extend_from_slice(&stamp.1.to_le_bytes());
    out.extend_from_slice(&frame_len);
    out.extend_from_slice(frame_id.as_bytes());
    out.push(u8::from(binary));
    out.extend_from_slice(&id_len);
    out.extend_from_slice(id.as_bytes());
    out.extend_from_slice(&resolution.to_le_bytes());
    out.extend_from_slice(&data_len);
    out.extend_from_slice(data);
    Some(out)
}

/// The `ros2msg` schema of `sensor_msgs/msg/PointCloud2`, with its nested types.
pub const POINT_CLOUD2_ROS2MSG: &str = concat!(
    "\
std_msgs/Header header
uint32 height
uint32 width
sensor_msgs/PointField[] fields
bool is_bigendian
uint32 point_step
uint32 row_step
uint8[] data
bool is_dense
",
    header_definitions!(),
    "\
================================================================================
MSG: sensor_msgs/PointField
uint8 INT8    = 1
uint8 UINT8   = 2
uint8 INT16   = 3
uint8 UINT16  = 4
uint8 INT32   = 5
uint8 UINT32  = 6
uint8 FLOAT32 = 7
uint8 FLOAT64 = 8
string name
uint32 offset
uint8 datatype
uint32 count
"
);

/// The `ros2msg` schema of `visualization_msgs/msg/MarkerArray` (the `Marker` of ROS 2
/// Humble and later, with `texture`, `uv_coordinates` and `mesh_file`), with its nested
/// types: what [`encode_occupied_marker_array_cdr`](crate::encode_occupied_marker_array_cdr)
/// writes.
pub const MARKER_ARRAY_ROS2MSG: &str = concat!(
    "\
visualization_msgs/Marker[] markers
================================================================================
MSG: visualization_msgs/Marker
int32 ARROW=0
int32 CUBE=1
int32 SPHERE=2
int32 CYLINDER=3
int32 LINE_STRIP=4
int32 LINE_LIST=5
int32 CUBE_LIST=6
int32 SPHERE_LIST=7
int32 POINTS=8
int32 TEXT_VIEW_FACING=9
int32 MESH_RESOURCE=10
int32 TRIANGLE_LIST=11
int32 ADD=0
int32 MODIFY=0
int32 DELETE=2
int32 DELETEALL=3
std_msgs/Header header
string ns
int32 id
int32 type
int32 action
geometry_msgs/Pose pose
geometry_msgs/Vector3 scale
std_msgs/ColorRGBA color
builtin_interfaces/Duration lifetime
bool frame_locked
geometry_msgs/Point[] points
std_msgs/ColorRGBA[] colors
string texture_resource
sensor_msgs/CompressedImage texture
visualization_msgs/UVCoordinate[] uv_coordinates
string text
string mesh_resource
visualization_msgs/MeshFile mesh_file
bool mesh_use_embedded_materials
",
    header_definitions!(),
    "\
================================================================================
MSG: geometry_msgs/Pose
geometry_msgs/Point position
geometry_msgs/Quaternion orientation
================================================================================
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
================================================================================
MSG: std_msgs/ColorRGBA
float32 r
float32 g
float32 b
float32 a
================================================================================
MSG: builtin_interfaces/Duration
int32 sec
uint32 nanosec
================================================================================
MSG: sensor_msgs/CompressedImage
std_msgs/Header header
string format
uint8[] data
================================================================================
MSG: visualization_msgs/UVCoordinate
float32 u
float32 v
================================================================================
MSG: visualization_msgs/MeshFile
string filename
uint8[] data
"
);

/// The ROS 2 type name of the messages [`encode_point_cloud2_cdr`] writes.
pub const POINT_CLOUD2_TYPE: &str = "sensor_msgs/msg/PointCloud2";

/// A field of a point: its name, its byte offset in the point and its `PointField` datatype
/// (7: FLOAT32, 6: UINT32…).
pub type PointFieldSpec<'a> = (&'a str, u32, u8);

/// A `sensor_msgs/msg/PointCloud2` message in little-endian CDR: one row of
/// `data.len() / point_step` points of the given fields (count 1 each), dense. `None` when
/// a field is longer than a CDR length (`u32`) can say.
pub fn encode_point_cloud2_cdr(
    stamp: (i32, u32),
    frame_id: &str,
    fields: &[PointFieldSpec<'_>],
    point_step: u32,
    data: &[u8],
) -> Option<Vec<u8>> {
    let width = u32::try_from(data.len() / point_step.max(1) as usize).ok()?;
    let row_step = u32::try_from(data.len()).ok()?;
    if too_long(frame_id.len()) {
        return None;
    }
    let mut out = CdrWriter::with_capacity(128 + frame_id.len() + data.len());
    out.header(stamp, frame_id);
    out.u32(1);
    out.u32(width);
    out.u32(u32::try_from(fields.len()).ok()?);
    for &(name, offset, datatype) in fields {
        out.string(name);
        out.u32(offset);
        out.bytes.push(datatype);
        out.u32(1);
    }
    out.bytes.push(0); // is_bigendian
    out.u32(point_step);
    out.u32(row_step);
    out.u32(row_step);
    out.bytes.extend_from_slice(data);
    out.bytes.push(1); // is_dense
    Some(out.bytes)
}

/// Whether a string or sequence of `len` bytes is too long for a CDR length (a `u32`
/// that, for strings, also counts the terminating NUL).
pub(crate) fn too_long(len: usize) -> bool {
    u32::try_from(len.saturating_add(1)).is_err()
}

/// Little-endian CDR: a 4-byte encapsulation header, then each primitive aligned to its size
/// counted from the end of that header.
pub(crate) struct CdrWriter {
    pub(crate) bytes: Vec<u8>,
}

impl CdrWriter {
    const ORIGIN: usize = 4;

    pub(crate) fn with_capacity(capacity: usize) -> Self {
        let mut bytes = Vec::with_capacity(capacity);
        bytes.extend_from_slice(&[0x00, 0x01, 0x00, 0x00]);
        Self { bytes }
    }

    pub(crate) fn align(&mut self, to: usize) {
        while (self.bytes.len() - Self::ORIGIN) % to != 0 {
            self.bytes.push(0);
        }
    }

    pub(crate) fn u32(&mut self, value: u32) {
        self.align(4);
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    pub(crate) fn i32(&mut self, value: i32) {
        self.u32(value as u32);
    }

    pub(crate) fn f32(&mut self, value: f32) {
        self.u32(value.to_bits());
    }

    pub(crate) fn f64(&mut self, value: f64) {
        self.align(8);
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    /// A `std_msgs/Header`: the stamp's `sec` and `nanosec`, then `frame_id`.
    pub(crate) fn header(&mut self, stamp: (i32, u32), frame_id: &str) {
        self.u32(stamp.0 as u32);
        self.u32(stamp.1);
        self.string(frame_id);
    }

    /// A string: its length counting a terminating NUL, the bytes, the NUL.
    pub(crate) fn string(&mut self, text: &str) {
        self.u32((text.len() + 1) as u32); // Checked by the caller.
        self.bytes.extend_from_slice(text.as_bytes());
        self.bytes.push(0);
    }
}
