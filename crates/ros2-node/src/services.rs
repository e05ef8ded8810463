//! The node's services, `/froctomap/get_octomap_at` and `/froctomap/probability_at`
//! (`froctomap_msgs/srv`, shipped in `ros/froctomap_msgs`), on the request and reply topics
//! every ROS 2 RMW uses (`rq/<service>Request`, `rr/<service>Reply`, types
//! `froctomap_msgs::srv::dds_::<Name>_Request_`/`_Response_`), framed by a
//! [`ServiceMapping`].
//!
//! The messages are CDR (XCDR1) as ROS 2 lays them out, through serde and the CDR codec
//! RustDDS itself uses (`cdr-encoding`); the framing of each mapping is a serde struct too,
//! so CDR alignment counts from the start of the payload as it does for the RMWs.

use froctomap_convert::{
    observed_bt, predicted_bt, resolve_observed, series_probabilities, FroctFile, SeriesRead,
    TimeQuery,
};
use froctomap_core::calendar::iso8601;
use froctomap_core::{error_message, Timestamp};
use froctomap_octomap_codec::{parse_header, FileKind};
use rustdds::cdr_encoding;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub use froctomap_ros::{GET_OCTOMAP_AT_SERVICE, PROBABILITY_AT_SERVICE};
/// The DDS type name stem of `froctomap_msgs/srv/GetOctomapAt` (`_Request_`, `_Response_`).
pub const GET_OCTOMAP_AT_DDS_TYPE: &str = "froctomap_msgs::srv::dds_::GetOctomapAt";
/// The DDS type name stem of `froctomap_msgs/srv/ProbabilityAt`.
pub const PROBABILITY_AT_DDS_TYPE: &str = "froctomap_msgs::srv::dds_::ProbabilityAt";
/// More points in one `probability_at` request are refused (an empty answer, logged).
pub const MAX_POINTS: usize = 1 << 22;
/// Room in a request for what precedes its fields: the CDR encapsulation, the mapping's
/// header (a basic `RequestHeader`'s instance name included) and alignment.
const REQUEST_FRAMING_BYTES: usize = 4096;
/// Larger `get_octomap_at` requests are skipped before decoding (the request is a stamp and
/// a bool).
pub const MAX_GET_OCTOMAP_AT_REQUEST_BYTES: usize = REQUEST_FRAMING_BYTES + 16;
/// Larger `probability_at` requests are skipped before decoding: a stamp and
/// [`MAX_POINTS`] points of 24 bytes, so their memory is bounded by the point limit.
pub const MAX_PROBABILITY_AT_REQUEST_BYTES: usize = REQUEST_FRAMING_BYTES + 16 + MAX_POINTS * 24;

/// How requests and replies carry the id that pairs them: the RMWs differ.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ServiceMapping {
    /// rmw_cyclonedds: a 16-byte header before the message, the client's 64-bit id (its
    /// request writer's instance handle) and a sequence number, echoed in the reply.
    #[default]
    Cyclone,
    /// DDS-RPC "enhanced" (rmw_fastrtps, rmw_connextdds): no header; the reply names the
    /// request's sample identity in its `related_sample_identity` inline QoS.
    Enhanced,
    /// DDS-RPC "basic": a `RequestHeader` (sample identity, instance name) before the
    /// request, a `ReplyHeader` (related sample identity, exception code) before the reply.
    Basic,
}

impl std::str::FromStr for ServiceMapping {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        match text.trim().to_ascii_lowercase().as_str() {
            "cyclone" => Ok(Self::Cyclone),
            "enhanced" => Ok(Self::Enhanced),
            "basic" => Ok(Self::Basic),
            _ => Err(format!(
                "`{text}` is not a service mapping (cyclone, enhanced, basic)"
            )),
        }
    }
}

/// `builtin_interfaces/Time`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Seconds since the Unix epoch.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// The instant this time names (`nanosec` beyond a second counts on, as in ROS).
    pub fn timestamp(self) -> Timestamp {
        Timestamp(i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec))
    }

    /// The time of an instant; `None` outside `builtin_interfaces/Time` (1901 .. 2038).
    pub fn of(t: Timestamp) -> Option<Self> {
        let sec = i32::try_from(t.0.div_euclid(1_000_000_000)).ok()?;
        let nanosec = u32::try_from(t.0.rem_euclid(1_000_000_000)).ok()?;
        Some(Self { sec, nanosec })
    }
}

/// `geometry_msgs/Point`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// Metres.
    pub x: f64,
    /// Metres.
    pub y: f64,
    /// Metres.
    pub z: f64,
}

/// `std_msgs/Header`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// The stamp.
    pub stamp: Time,
    /// The frame.
    pub frame_id: String,
}

/// `octomap_msgs/Octomap`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Octomap {
    /// Stamp and frame.
    pub header: Header,
    /// `true`: `data` is a `.bt` body; `false`: an `.ot` body.
    pub binary: bool,
    /// The tree type (`OcTree`).
    pub id: String,
    /// Voxel edge length in metres.
    pub resolution: f64,
    /// The map file's body (behind its text header).
    pub data: MapData,
}

impl Octomap {
    /// The message of a `.bt` file, stamped `stamp` in `frame_id` (the body behind the
    /// file's header, as octomap_msgs' `binaryMapToMsg` fills it).
    pub fn of_bt(bt: &[u8], stamp: Time, frame_id: &str) -> Result<Self, String> {
        let header =
            parse_header(bt, FileKind::Binary).map_err(|e| format!("not a .bt file: {e}"))?;
        Ok(Self {
            header: Header {
                stamp,
                frame_id: frame_id.to_string(),
            },
            binary: true,
            id: header.tree_id.clone(),
            resolution: header.resolution,
            data: MapData(bt.get(header.body_offset..).unwrap_or_default().to_vec()),
        })
    }

    /// An empty message (what a failed request carries).
    pub fn empty(stamp: Time, frame_id: &str) -> Self {
        Self {
            header: Header {
                stamp,
                frame_id: frame_id.to_string(),
            },
            binary: true,
            id: String::new(),
            resolution: 0.0,
            data: MapData(Vec::new()),
        }
    }
}

/// An `int8[]` of map bytes, written in one piece (not byte by byte).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MapData(pub Vec<u8>);

impl Serialize for MapData {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_bytes(&self.0)
    }
}

impl<'de> Deserialize<'de> for MapData {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        Vec::<u8>::deserialize(deserializer).map(MapData)
    }
}

/// `froctomap_msgs/srv/GetOctomapAt` request.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GetOctomapAtRequest {
    /// When.
    pub stamp: Time,
    /// `true`: the model's estimate at any time; `false`: the map as recorded, inside the
    /// recorded span only.
    pub predict: bool,
}

/// `froctomap_msgs/srv/GetOctomapAt` response.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GetOctomapAtResponse {
    /// Whether `map` holds the map asked for.
    pub success: bool,
    /// What the map is, or why there is none.
    pub message: String,
    /// The map (empty when `success` is false).
    pub map: Octomap,
}

/// `froctomap_msgs/srv/ProbabilityAt` request.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbabilityAtRequest {
    /// When (any time: inside the span or beyond it).
    pub stamp: Time,
    /// Where, in the map's frame.
    pub points: Vec<Point>,
}

/// `froctomap_msgs/srv/ProbabilityAt` response.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbabilityAtResponse {
    /// The occupancy probability at each point, NaN outside the map.
    pub p: Vec<f64>,
}

/// What the services answer; [`FileServices`] answers from a `.froct` file.
pub trait ServiceHandler {
    /// `/froctomap/get_octomap_at`.
    fn get_octomap_at(&mut self, request: &GetOctomapAtRequest) -> GetOctomapAtResponse;
    /// `/froctomap/probability_at`.
    fn probability_at(&mut self, request: &ProbabilityAtRequest) -> ProbabilityAtResponse;
}

/// The services of a `.froct` file (opened anew for each request, so maps appended since
/// count).
pub struct FileServices {
    froct: PathBuf,
    frame_id: String,
}

impl FileServices {
    /// The services of `froct`, maps in `frame_id`.
    pub fn new(froct: &Path, frame_id: &str) -> Self {
        Self {
            froct: froct.to_path_buf(),
            frame_id: frame_id.to_string(),
        }
    }

    /// Maps from now on in `frame_id` (the node's frame, once the first map fixed it).
    pub fn set_frame_id(&mut self, frame_id: &str) {
        frame_id.clone_into(&mut self.frame_id);
    }

    fn open(&self) -> Result<FroctFile, String> {
        // The reader's errors name the file.
        FroctFile::open(&self.froct).map_err(|e| error_message(&e))
    }

    /// The `.bt` answering `request` and the time its map is at, or why there is none.
    fn map_at(
        &self,
        request: &GetOctomapAtRequest,
    ) -> Result<(Vec<u8>, Timestamp, String), String> {
        let reader = self.open()?;
        let t = request.stamp.timestamp();
        let fail = |e: froctomap_convert::ConvertError| error_message(&e);
        if request.predict {
            let bt = predicted_bt(&reader, t).map_err(fail)?;
            return Ok((
                bt,
                t,
                format!("the map the model predicts for {}", iso8601(t)),
            ));
        }
        let (start, end) = (reader.first_instant(), reader.last_instant());
        if t < start || t > end {
            return Err(format!(
                "{} is outside the recorded span {} .. {}; set predict to estimate the map there",
                iso8601(t),
                iso8601(start),
                iso8601(end)
            ));
        }
        let when = resolve_observed(&reader, TimeQuery::Instant(t)).map_err(fail)?;
        let bt = observed_bt(&reader, when.sample).map_err(fail)?;
        let what = if when.exact {
            format!(
                "the map recorded at {} (sample {})",
                iso8601(when.time),
                when.sample
            )
        } else {
            format!(
                "no map recorded at {}; the last one before it, recorded at {} (sample {})",
                iso8601(t),
                iso8601(when.time),
                when.sample
            )
        };
        Ok((bt, when.time, what))
    }
}

impl ServiceHandler for FileServices {
    fn get_octomap_at(&mut self, request: &GetOctomapAtRequest) -> GetOctomapAtResponse {
        let answer = self.map_at(request).and_then(|(bt, at, what)| {
            let stamp = Time::of(at).unwrap_or(request.stamp);
            Octomap::of_bt(&bt, stamp, &self.frame_id).map(|map| (map, what))
        });
        match answer {
            Ok((map, message)) => GetOctomapAtResponse {
                success: true,
                message,
                map,
            },
            Err(message) => GetOctomapAtResponse {
                success: false,
                message,
                map: Octomap::empty(request.stamp, &self.frame_id),
            },
        }
    }

    fn probability_at(&mut self, request: &ProbabilityAtRequest) -> ProbabilityAtResponse {
        let nan = || vec![f64::NAN; request.points.len()];
        let points: Vec<[f64; 3]> = request.points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let t = request.stamp.timestamp();
        let p = self.open().and_then(|reader| {
            series_probabilities(&reader, t, &points).map_err(|e| error_message(&e))
        });
        match p {
            Ok(p) => ProbabilityAtResponse { p },
            Err(e) => {
                log::warn!("{PROBABILITY_AT_SERVICE}: {e}; answering NaN");
                ProbabilityAtResponse { p: nan() }
            }
        }
    }
}

/// The id pairing a reply with its request, as the mapping carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum RequestId {
    /// rmw_cyclonedds' header: the client's id and the request's number.
    Cyclone { client: u64, sequence: i64 },
    /// A DDS sample identity (the request writer's GUID and the sample's sequence number).
    Sample { guid: [u8; 16], sequence: i64 },
}

#[derive(Serialize, Deserialize)]
struct CycloneFramed<T> {
    client: u64,
    sequence: i64,
    body: T,
}

#[derive(Serialize, Deserialize)]
struct SampleIdentityCdr {
    guid: [u8; 16],
    sequence_high: i32,
    sequence_low: u32,
}

impl SampleIdentityCdr {
    fn of(guid: [u8; 16], sequence: i64) -> Self {
        Self {
            guid,
            sequence_high: (sequence >> 32) as i32,
            sequence_low: sequence as u32, // The low 32 bits.
        }
    }

    fn sequence(&self) -> i64 {
        (i64::from(self.sequence_high) << 32) | i64::from(self.sequence_low)
    }
}

#[derive(Deserialize)]
struct BasicRequest<T> {
    identity: SampleIdentityCdr,
    _instance_name: String,
    body: T,
}

#[derive(Serialize)]
struct BasicReply<'a, T> {
    identity: SampleIdentityCdr,
    remote_exception: u32,
    body: &'a T,
}

/// Why a request could not be read.
#[derive(Debug, thiserror::Error)]
pub enum RequestError {
    /// Shorter than its encapsulation header, or not CDR.
    #[error("not a CDR message")]
    NotCdr,
    /// The bytes do not decode as the request (truncated, wrong type, bad string).
    #[error("not a {what} request: {reason}")]
    Decode {
        /// The request type.
        what: &'static str,
        /// What the decoder said.
        reason: String,
    },
}

/// Reads a request framed by `mapping`; `sample` is the request sample's own identity (the
/// id [`ServiceMapping::Enhanced`] replies name when the request carries no other).
pub(crate) fn decode_request<T: serde::de::DeserializeOwned>(
    mapping: ServiceMapping,
    message: &[u8],
    sample: RequestId,
    what: &'static str,
) -> Result<(RequestId, T), RequestError> {
    let (head, payload) = message.split_at_checked(4).ok_or(RequestError::NotCdr)?;
    let big_endian = match head[..2] {
        [0x00, 0x00] => true,
        [0x00, 0x01] => false,
        _ => return Err(RequestError::NotCdr),
    };
    let decode_error = |e: cdr_encoding::Error| RequestError::Decode {
        what,
        reason: e.to_string(),
    };
    match mapping {
        ServiceMapping::Cyclone => {
            let framed: CycloneFramed<T> = decode(payload, big_endian).map_err(decode_error)?;
            Ok((
                RequestId::Cyclone {
                    client: framed.client,
                    sequence: framed.sequence,
                },
                framed.body,
            ))
        }
        ServiceMapping::Basic => {
            let framed: BasicRequest<T> = decode(payload, big_endian).map_err(decode_error)?;
            Ok((
                RequestId::Sample {
                    guid: framed.identity.guid,
                    sequence: framed.identity.sequence(),
                },
                framed.body,
            ))
        }
        ServiceMapping::Enhanced => {
            Ok((sample, decode(payload, big_endian).map_err(decode_error)?))
        }
    }
}

fn decode<T: serde::de::DeserializeOwned>(
    payload: &[u8],
    big_endian: bool,
) -> Result<T, cdr_encoding::Error> {
    if big_endian {
        cdr_encoding::from_bytes::<T, byteorder::BigEndian>(payload).map(|(t, _)| t)
    } else {
        cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(payload).map(|(t, _)| t)
    }
}

/// A reply framed by `mapping` for the request `id`: little-endian CDR with its
/// encapsulation header.
pub(crate) fn encode_reply<T: Serialize>(
    mapping: ServiceMapping,
    id: RequestId,
    body: &T,
) -> Result<Vec<u8>, cdr_encoding::Error> {
    let mut out = vec![0x00, 0x01, 0x00, 0x00];
    let payload = match (mapping, id) {
        (ServiceMapping::Cyclone, RequestId::Cyclone { client, sequence }) => {
            cdr_encoding::to_vec::<_, byteorder::LittleEndian>(&CycloneFramed {
                client,
                sequence,
                body,
            })
        }
        (ServiceMapping::Basic, RequestId::Sample { guid, sequence }) => {
            cdr_encoding::to_vec::<_, byteorder::LittleEndian>(&BasicReply {
                identity: SampleIdentityCdr::of(guid, sequence),
                remote_exception: 0,
                body,
            })
        }
        _ => cdr_encoding::to_vec::<_, byteorder::LittleEndian>(body),
    }?;
    out.extend_from_slice(&payload);
    Ok(out)
}

/// A service message in little-endian CDR with its encapsulation header, without any
/// mapping's framing: what a `ros2 bag` of the service would hold.
pub fn encode_cdr<T: Serialize>(message: &T) -> Result<Vec<u8>, cdr_encoding::Error> {
    let mut out = vec![0x00, 0x01, 0x00, 0x00];
    out.extend_from_slice(&cdr_encoding::to_vec::<_, byteorder::LittleEndian>(
        message,
    )?);
    Ok(out)
}

/// Reads a service message written by [`encode_cdr`] (either byte order).
pub fn decode_cdr<T: serde::de::DeserializeOwned>(message: &[u8]) -> Result<T, RequestError> {
    let sample = RequestId::Sample {
        guid: [0; 16],
        sequence: 0,
    };
    decode_request(ServiceMapping::Enhanced, message, sample, "service").map(|(_, message)| message)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_request_byte_limits_let_the_largest_valid_requests_through_and_no_more() {
        let point = Point {
            x: 1.0,
            y: 2.0,
            z: 3.0,
        };
        let stamp = Time {
            sec: 1_700_000_000,
            nanosec: 0,
        };
        let points = |n| ProbabilityAtRequest {
            stamp,
            points: vec![point; n],
        };
        let framed = |bytes: Vec<u8>| bytes.len() + 16; // rmw_cyclonedds' header.
        let largest = framed(encode_cdr(&points(MAX_POINTS)).expect("encode"));
        assert!(largest <= MAX_PROBABILITY_AT_REQUEST_BYTES, "{largest}");
        let over = MAX_POINTS + REQUEST_FRAMING_BYTES / 24 + 1;
        let too_many = encode_cdr(&points(over)).expect("encode").len();
        assert!(too_many > MAX_PROBABILITY_AT_REQUEST_BYTES, "{too_many}");
        let get = framed(
            encode_cdr(&GetOctomapAtRequest {
                stamp,
                predict: true,
            })
            .expect("encode"),
        );
        assert!(get <= MAX_GET_OCTOMAP_AT_REQUEST_BYTES, "{get}");
    }

    #[test]
    fn cyclone_framing_puts_the_16_byte_header_first_and_echoes_it() {
        // rmw_cyclonedds: client id (u64), sequence (i64), then the request.
        let mut request = vec![0x00, 0x01, 0x00, 0x00];
        request.extend_from_slice(&0x1122_3344_5566_7788u64.to_le_bytes());
        request.extend_from_slice(&5i64.to_le_bytes());
        request.extend_from_slice(&1_700_000_000i32.to_le_bytes());
        request.extend_from_slice(&7u32.to_le_bytes());
        request.push(1);
        let sample = RequestId::Sample {
            guid: [0; 16],
            sequence: 1,
        };
        let (id, body): (_, GetOctomapAtRequest) =
            decode_request(ServiceMapping::Cyclone, &request, sample, "test").unwrap();
        assert_eq!(
            id,
            RequestId::Cyclone {
                client: 0x1122_3344_5566_7788,
                sequence: 5
            }
        );
        assert_eq!(
            body,
            GetOctomapAtRequest {
                stamp: Time {
                    sec: 1_700_000_000,
                    nanosec: 7
                },
                predict: true
            }
        );
        let reply = encode_reply(
            ServiceMapping::Cyclone,
            id,
            &ProbabilityAtResponse { p: vec![0.25] },
        )
        .unwrap();
        assert_eq!(reply[4..20], request[4..20]);
        assert_eq!(reply[20..24], 1u32.to_le_bytes());
        // The f64 is aligned to 8 from the payload start (after the header's 16 bytes).
        assert_eq!(reply[28..36], 0.25f64.to_le_bytes());
        // Truncated: an error, not a panic.
        for cut in 0..request.len() {
            assert!(
                decode_request::<GetOctomapAtRequest>(
                    ServiceMapping::Cyclone,
                    &request[..cut],
                    sample,
                    "test"
                )
                .is_err(),
                "{cut}"
            );
        }
    }

    #[test]
    fn a_huge_point_count_is_refused_without_allocating_it() {
        let mut request = vec![0x00, 0x01, 0x00, 0x00];
        request.extend_from_slice(&[0; 8]);
        request.extend_from_slice(&u32::MAX.to_le_bytes());
        let sample = RequestId::Sample {
            guid: [0; 16],
            sequence: 1,
        };
        assert!(decode_request::<ProbabilityAtRequest>(
            ServiceMapping::Enhanced,
            &request,
            sample,
            "test"
        )
        .is_err());
    }
}
