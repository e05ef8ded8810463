//! Decoding of `octomap_msgs/Octomap` (and `OctomapWithPose`) messages, and the map file
//! each one stands for.
//!
//! The message is short, so it is decoded here by hand rather than through a general
//! serialisation framework; every length is checked against the bytes at hand, so a hostile
//! message costs no allocation beyond its own size.
//!
//! * `Octomap`: `std_msgs/Header header, bool binary, string id, float64 resolution,
//!   int8[] data`.
//! * `OctomapWithPose`: `Header header, geometry_msgs/Pose origin` (7 × float64),
//!   `Octomap octomap`.
//! * ROS 1 serialisation: little endian, no padding; `Header` is `uint32 seq, time stamp
//!   (uint32 secs, uint32 nsecs), string frame_id`; strings and arrays are a `uint32` length
//!   then the bytes.
//! * CDR (ROS 2): a 4-byte encapsulation header (`00 01`: little endian, `00 00`: big), then
//!   each field aligned to its own size counted from after that header; `Header` is
//!   `int32 sec, uint32 nanosec, string frame_id`; strings are a `uint32` length counting a
//!   terminating NUL, then the bytes and the NUL.

use crate::error::MessageError;
use froctomap_octomap_codec::{
    walk_body, FileKind, ReadLimits, TreeType, BINARY_FIRST_LINE, FULL_FIRST_LINE,
};

/// How a message is serialised.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Encoding {
    /// ROS 1 (bags, and MCAP channels with message encoding `ros1`).
    Ros1,
    /// OMG CDR as ROS 2 writes it (MCAP channels with message encoding `cdr`).
    Cdr,
}

/// Which octomap message type a topic carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum MessageType {
    /// `octomap_msgs/Octomap`.
    Octomap,
    /// `octomap_msgs/OctomapWithPose` (the pose is skipped).
    OctomapWithPose,
}

impl MessageType {
    /// The type a ROS 1 or ROS 2 type name (`octomap_msgs/Octomap`,
    /// `octomap_msgs/msg/Octomap`) names, if it is an octomap message.
    ///
    /// ```
    /// use froctomap_ros::MessageType;
    /// assert_eq!(MessageType::from_name("octomap_msgs/msg/Octomap"), Some(MessageType::Octomap));
    /// assert_eq!(MessageType::from_name("octomap_msgs/OctomapWithPose"), Some(MessageType::OctomapWithPose));
    /// assert_eq!(MessageType::from_name("sensor_msgs/msg/PointCloud2"), None);
    /// ```
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "octomap_msgs/Octomap" | "octomap_msgs/msg/Octomap" => Some(Self::Octomap),
            "octomap_msgs/OctomapWithPose" | "octomap_msgs/msg/OctomapWithPose" => {
                Some(Self::OctomapWithPose)
            }
            _ => None,
        }
    }
}

/// A decoded octomap message, borrowing its map data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OctomapMessage<'a> {
    /// The header stamp, nanoseconds since the Unix epoch (0 when the publisher left it unset).
    pub stamp_ns: i64,
    /// The header's `frame_id` (of the outer header for `OctomapWithPose`).
    pub frame_id: &'a str,
    /// `true`: `data` is a `.bt` body; `false`: an `.ot` body.
    pub binary: bool,
    /// The tree type (`OcTree`, `ColorOcTree`…).
    pub id: &'a str,
    /// Voxel edge length in metres.
    pub resolution: f64,
    /// The map data.
    pub data: &'a [u8],
}

/// The header stamp of a message, without looking at its map (nanoseconds; 0: unset).
pub fn decode_stamp(
    bytes: &[u8],
    encoding: Encoding,
    kind: MessageType,
) -> Result<i64, MessageError> {
    let _ = kind; // Both types start with the header.
    let mut reader = Reader::new(bytes, encoding)?;
    reader.header().map(|(stamp, _)| stamp)
}

/// Decodes a whole message.
///
/// ```
/// use froctomap_ros::{decode_message, Encoding, MessageType};
/// // ROS 1: seq, stamp (secs, nsecs), frame_id "map", binary, id "OcTree", resolution, data.
/// let mut bytes = Vec::new();
/// bytes.extend_from_slice(&7u32.to_le_bytes());
/// bytes.extend_from_slice(&1_700_000_000u32.to_le_bytes());
/// bytes.extend_from_slice(&5u32.to_le_bytes());
/// bytes.extend_from_slice(&3u32.to_le_bytes());
/// bytes.extend_from_slice(b"map");
/// bytes.push(1);
/// bytes.extend_from_slice(&6u32.to_le_bytes());
/// bytes.extend_from_slice(b"OcTree");
/// bytes.extend_from_slice(&0.1f64.to_le_bytes());
/// bytes.extend_from_slice(&2u32.to_le_bytes());
/// bytes.extend_from_slice(&[0x09, 0x00]);
/// let message = decode_message(&bytes, Encoding::Ros1, MessageType::Octomap)?;
/// assert_eq!((message.stamp_ns, message.frame_id), (1_700_000_000_000_000_005, "map"));
/// assert_eq!((message.binary, message.id, message.resolution, message.data), (true, "OcTree", 0.1, &[0x09, 0x00][..]));
/// # Ok::<(), froctomap_ros::MessageError>(())
/// ```
pub fn decode_message(
    bytes: &[u8],
    encoding: Encoding,
    kind: MessageType,
) -> Result<OctomapMessage<'_>, MessageError> {
    let mut reader = Reader::new(bytes, encoding)?;
    let (stamp_ns, frame_id) = reader.header()?;
    if kind == MessageType::OctomapWithPose {
        // geometry_msgs/Pose: position (x, y, z) and orientation (x, y, z, w).
        for _ in 0..7 {
            reader.f64("origin")?;
        }
        // The inner map's own header; the outer stamp is the message's time.
        reader.header()?;
    }
    let binary = reader.u8("binary")? != 0;
    let id = reader.string("id")?;
    let resolution = reader.f64("resolution")?;
    let data = reader.sequence("data")?;
    Ok(OctomapMessage {
        stamp_ns,
        frame_id,
        binary,
        id,
        resolution,
        data,
    })
}

impl OctomapMessage<'_> {
    /// The map file this message stands for: `data` itself when a publisher put a whole
    /// `.bt`/`.ot` file there (header included); else the body behind the header OctoMap
    /// writes for it (`# Octomap OcTree binary file` for `binary`, else `# Octomap OcTree
    /// file`), with the message's tree type, resolution and the body's node count, so that
    /// the file reads exactly as the message's map.
    pub fn map_file(&self) -> Result<Vec<u8>, MessageError> {
        if self.data.starts_with(b"# Octomap OcTree") {
            return Ok(self.data.to_vec());
        }
        if !(self.resolution.is_finite() && self.resolution > 0.0) {
            return Err(MessageError::Resolution(self.resolution.to_string()));
        }
        let kind = if self.binary {
            FileKind::Binary
        } else {
            FileKind::Full
        };
        let id = match self.id.trim() {
            "" => "OcTree",
            id if id.contains(char::is_whitespace) => {
                return Err(MessageError::BadString { field: "id" })
            }
            id => id,
        };
        // A binary body has no node data, so any tree type walks as an OcTree; a full body of a
        // type the codec does not know fails here, or later by name in the file reader.
        let tree = TreeType::from_id(id).unwrap_or(TreeType::OcTree);
        let limits = ReadLimits::default();
        // The header needs the node count only: a binary body that is a whole well-formed
        // tree is counted in one flat pass; anything else is walked, which says what is
        // wrong with it (or counts the tree before trailing bytes) as the reader would.
        let counted = match kind {
            FileKind::Binary => binary_node_count(self.data, limits),
            FileKind::Full => None,
        };
        let node_count = match counted {
            Some(count) => count,
            None => {
                walk_body(kind, tree, self.data, 0, limits, &mut |_| {})
                    .map_err(MessageError::NotAMap)?
                    .node_count
            }
        };
        let first_line = match kind {
            FileKind::Binary => BINARY_FIRST_LINE,
            _ => FULL_FIRST_LINE,
        };
        // `{}` prints the shortest text that reads back as the same f64.
        let header = format!(
            "{first_line}\nid {id}\nsize {}\nres {}\ndata\n",
            node_count, self.resolution
        );
        let mut file = Vec::with_capacity(header.len() + self.data.len());
        file.extend_from_slice(header.as_bytes());
        file.extend_from_slice(self.data);
        Ok(file)
    }
}

/// The node count `walk_body` gives for the `.bt` body `body`, when the body is exactly one
/// tree that walks without error (every node pair read, none after it, no inner node below
/// depth 15, at most `limits.max_nodes` nodes); `None` otherwise. One pass over the node
/// pairs in their depth-first order, keeping per depth only how many inner children are
/// left, with no recursion and no leaf made: a map message is counted about ten times
/// faster than walked.
fn binary_node_count(body: &[u8], limits: ReadLimits) -> Option<u64> {
    /// Depth of a voxel: an inner node deeper than this less one cannot be walked.
    const TREE_DEPTH: usize = 16;
    let mut nodes: u64 = 1;
    // `left[d]`: inner children of the node being read at depth `d` not finished yet.
    let mut left = [0u32; TREE_DEPTH];
    let mut depth = 0usize;
    let mut pairs = body.chunks_exact(2);
    if !pairs.remainder().is_empty() {
        return None;
    }
    loop {
        let pair = pairs.next()?;
        let codes = u16::from_le_bytes([pair[0], pair[1]]);
        // 2 bits per child: present when either is set, inner (3) when both are.
        nodes += u64::from(((codes | codes >> 1) & 0x5555).count_ones());
        let inner = (codes & codes >> 1 & 0x5555).count_ones();
        if nodes > limits.max_nodes {
            return None;
        }
        if inner > 0 {
            if depth + 1 >= TREE_DEPTH {
                return None;
            }
            left[depth] = inner;
            depth += 1;
            continue;
        }
        // This subtree is done: on to the next inner sibling, or up.
        loop {
            if depth == 0 {
                return pairs.next().is_none().then_some(nodes);
            }
            depth -= 1;
            left[depth] -= 1;
            if left[depth] > 0 {
                depth += 1;
                break;
            }
        }
    }
}

/// Reads fields of either encoding from a message's bytes.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// CDR aligns fields from here (after the encapsulation header).
    origin: usize,
    encoding: Encoding,
    little_endian: bool,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8], encoding: Encoding) -> Result<Self, MessageError> {
        let mut reader = Reader {
            bytes,
            pos: 0,
            origin: 0,
            encoding,
            little_endian: true,
        };
        if encoding == Encoding::Cdr {
            let head = reader.take(4, "encapsulation")?;
            let kind = u16::from_be_bytes([head[0], head[1]]);
            reader.little_endian = match kind {
                0x0000 => false,
                0x0001 => true,
                other => return Err(MessageError::Encapsulation(other)),
            };
            reader.origin = 4;
        }
        Ok(reader)
    }

    fn take(&mut self, n: usize, field: &'static str) -> Result<&'a [u8], MessageError> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&end| end <= self.bytes.len())
            .ok_or(MessageError::Truncated { field })?;
        let out = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(out)
    }

    /// Skips CDR padding up to a multiple of `n` from the origin.
    fn align(&mut self, n: usize, field: &'static str) -> Result<(), MessageError> {
        if self.encoding == Encoding::Cdr {
            let misalignment = (self.pos - self.origin) % n;
            if misalignment != 0 {
                self.take(n - misalignment, field)?;
            }
        }
        Ok(())
    }

    fn fixed<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], MessageError> {
        self.align(N, field)?;
        let bytes = self.take(N, field)?;
        let mut out = [0u8; N];
        out.copy_from_slice(bytes);
        if !self.little_endian {
            out.reverse();
        }
        Ok(out)
    }

    fn u8(&mut self, field: &'static str) -> Result<u8, MessageError> {
        Ok(self.take(1, field)?[0])
    }

    fn u32(&mut self, field: &'static str) -> Result<u32, MessageError> {
        self.fixed::<4>(field).map(u32::from_le_bytes)
    }

    fn f64(&mut self, field: &'static str) -> Result<f64, MessageError> {
        self.fixed::<8>(field).map(f64::from_le_bytes)
    }

    /// A length-prefixed byte sequence (`int8[]`).
    fn sequence(&mut self, field: &'static str) -> Result<&'a [u8], MessageError> {
        let len = self.u32(field)? as usize;
        self.take(len, field)
    }

    fn string(&mut self, field: &'static str) -> Result<&'a str, MessageError> {
        let raw = self.sequence(field)?;
        let text = match self.encoding {
            Encoding::Ros1 => raw,
            // The length counts a terminating NUL (0 for an empty string from some writers).
            Encoding::Cdr => match raw.split_last() {
                None => raw,
                Some((0, text)) => text,
                Some(_) => return Err(MessageError::BadString { field }),
            },
        };
        std::str::from_utf8(text).map_err(|_| MessageError::BadString { field })
    }

    /// A `std_msgs/Header`: its stamp in nanoseconds and its frame.
    fn header(&mut self) -> Result<(i64, &'a str), MessageError> {
        let (secs, nanos) = match self.encoding {
            Encoding::Ros1 => {
                self.u32("header.seq")?;
                let secs = i64::from(self.u32("header.stamp")?);
                (secs, self.u32("header.stamp")?)
            }
            Encoding::Cdr => {
                // int32 sec: the same four bytes read as signed.
                let secs = i64::from(self.u32("header.stamp")? as i32);
                (secs, self.u32("header.stamp")?)
            }
        };
        let frame_id = self.string("header.frame_id")?;
        // Cannot overflow: |secs| < 2^32 and nanos < 2^32.
        Ok((secs * 1_000_000_000 + i64::from(nanos), frame_id))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random `.bt` body of a tree whose inner nodes go no deeper than `max_depth`, from a
    /// small xorshift generator (`state`).
    fn random_body(state: &mut u64, depth: usize, max_depth: usize, out: &mut Vec<u8>) {
        let mut next = || {
            *state ^= *state << 13;
            *state ^= *state >> 7;
            *state ^= *state << 17;
            *state
        };
        let mut codes = 0u16;
        for child in 0..8 {
            // Inner children rarer with depth, so trees stay small.
            let code = match next() % 8 {
                0..=2 => 0,
                3 | 4 => 1,
                5 => 2,
                _ if depth < max_depth && next() % 3 == 0 => 3,
                _ => 2,
            };
            codes |= (code as u16) << (2 * child);
        }
        out.extend_from_slice(&codes.to_le_bytes());
        for child in 0..8 {
            if codes >> (2 * child) & 3 == 3 {
                random_body(state, depth + 1, max_depth, out);
            }
        }
    }

    /// The flat count equals the walk's on whole trees, and leaves to the walk every body
    /// the walk refuses or reads only in part (truncated, trailing bytes, too deep, odd).
    #[test]
    fn binary_node_count_is_the_walks_or_none() {
        let walked = |body: &[u8], limits| {
            walk_body(
                FileKind::Binary,
                TreeType::OcTree,
                body,
                0,
                limits,
                &mut |_| {},
            )
        };
        let limits = ReadLimits::default();
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for round in 0..400 {
            let mut body = Vec::new();
            random_body(&mut state, 0, 1 + round % 15, &mut body);
            let walk = walked(&body, limits).unwrap();
            assert_eq!(walk.len, body.len());
            assert_eq!(
                binary_node_count(&body, limits),
                Some(walk.node_count),
                "round {round}"
            );
            // A limit just below the count: the walk refuses, the count leaves it to it.
            let tight = ReadLimits {
                max_nodes: walk.node_count - 1,
            };
            assert!(walked(&body, tight).is_err());
            assert_eq!(binary_node_count(&body, tight), None);
            // Cut, extended, or of odd length: never a count the walk would not give.
            let mut variants = vec![
                body[..body.len() - 2].to_vec(),
                body[..body.len() - 1].to_vec(),
            ];
            variants.push([body.as_slice(), &[0, 0]].concat());
            variants.push([body.as_slice(), &[0]].concat());
            for variant in variants {
                if let Some(count) = binary_node_count(&variant, limits) {
                    let walk = walked(&variant, limits).unwrap();
                    assert_eq!((count, walk.len), (walk.node_count, variant.len()));
                }
            }
        }
        // Inner nodes down to depth 15: the walk refuses, and the count leaves it to it.
        let mut deep = Vec::new();
        for _ in 0..16 {
            deep.extend_from_slice(&3u16.to_le_bytes());
        }
        deep.extend_from_slice(&1u16.to_le_bytes());
        assert!(walked(&deep, limits).is_err());
        assert_eq!(binary_node_count(&deep, limits), None);
        // Down to depth 14 walks, and counts the same.
        let ok = [&deep[..30], &1u16.to_le_bytes()[..]].concat();
        assert_eq!(
            binary_node_count(&ok, limits),
            Some(walked(&ok, limits).unwrap().node_count)
        );
        assert_eq!(binary_node_count(&[], limits), None);
    }

    /// A CDR little-endian `Octomap` as ROS 2 lays it out, written field by field.
    fn cdr_message(stamp: (i32, u32), binary: bool, id: &str, data: &[u8]) -> Vec<u8> {
        let mut out = vec![0, 1, 0, 0];
        let pad = |out: &mut Vec<u8>, n: usize| {
            while (out.len() - 4) % n != 0 {
                out.push(0);
            }
        };
        out.extend_from_slice(&stamp.0.to_le_bytes());
        out.extend_from_slice(&stamp.1.to_le_bytes());
        out.extend_from_slice(&4u32.to_le_bytes());
        out.extend_from_slice(b"map\0");
        out.push(u8::from(binary));
        pad(&mut out, 4);
        out.extend_from_slice(&(id.len() as u32 + 1).to_le_bytes());
        out.extend_from_slice(id.as_bytes());
        out.push(0);
        pad(&mut out, 8);
        out.extend_from_slice(&0.05f64.to_le_bytes());
        out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        out.extend_from_slice(data);
        out
    }

    #[test]
    fn cdr_fields_are_read_after_their_padding() {
        let bytes = cdr_message((1_700_000_000, 42), true, "OcTree", &[0x09, 0x00]);
        let message = decode_message(&bytes, Encoding::Cdr, MessageType::Octomap).unwrap();
        assert_eq!(message.stamp_ns, 1_700_000_000_000_000_042);
        assert_eq!(message.id, "OcTree");
        assert_eq!(message.resolution, 0.05);
        assert_eq!(message.data, [0x09, 0x00]);
        let file = message.map_file().unwrap();
        assert!(
            file.starts_with(b"# Octomap OcTree binary file\nid OcTree\nsize 3\nres 0.05\ndata\n")
        );
        assert_eq!(
            decode_stamp(&bytes, Encoding::Cdr, MessageType::Octomap).unwrap(),
            message.stamp_ns
        );
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        let bytes = cdr_message((1, 2), false, "OcTree", &[0, 0, 0, 0, 0]);
        for end in 0..bytes.len() {
            assert!(
                decode_message(&bytes[..end], Encoding::Cdr, MessageType::Octomap).is_err(),
                "{end}"
            );
            let _ = decode_message(&bytes[..end], Encoding::Ros1, MessageType::OctomapWithPose);
        }
        let message = decode_message(&bytes, Encoding::Cdr, MessageType::Octomap).unwrap();
        // A full (.ot) body: one leaf node, value then an empty child mask.
        assert!(message
            .map_file()
            .unwrap()
            .starts_with(b"# Octomap OcTree file\n"));
    }

    #[test]
    fn a_whole_file_in_data_is_taken_as_is_and_garbage_is_refused() {
        let file = b"# Octomap OcTree binary file\nid OcTree\nsize 3\nres 0.1\ndata\n\x09\x00";
        let message = OctomapMessage {
            stamp_ns: 0,
            frame_id: "map",
            binary: true,
            id: "OcTree",
            resolution: 0.1,
            data: file,
        };
        assert_eq!(message.map_file().unwrap(), file);
        let garbage = OctomapMessage {
            data: &[0xff],
            ..message
        };
        assert!(matches!(garbage.map_file(), Err(MessageError::NotAMap(_))));
        let bad_resolution = OctomapMessage {
            data: &[0x09, 0x00],
            resolution: f64::NAN,
            ..message
        };
        assert!(matches!(
            bad_resolution.map_file(),
            Err(MessageError::Resolution(_))
        ));
    }

    #[test]
    fn unknown_encapsulations_are_refused() {
        let mut bytes = cdr_message((1, 2), true, "OcTree", &[]);
        bytes[1] = 3; // PL_CDR_LE
        assert!(matches!(
            decode_message(&bytes, Encoding::Cdr, MessageType::Octomap),
            Err(MessageError::Encapsulation(3))
        ));
    }
}
