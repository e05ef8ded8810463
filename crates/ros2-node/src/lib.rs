//! The froctomap ROS 2 node: receives `octomap_msgs/msg/Octomap` maps over DDS and publishes
//! the map a `.froct` file predicts, in pure Rust (RustDDS), without a ROS installation.
//!
//! The node speaks plain DDS the way every ROS 2 RMW maps topics: the ROS topic
//! `/octomap_binary` is the DDS topic `rt/octomap_binary` of type
//! `octomap_msgs::msg::dds_::Octomap_`, CDR encoded. Received messages are decoded by
//! [`froctomap_ros::decode_message`] (the decoder the bag and MCAP readers use) and handed,
//! as map files with their stamps, to a [`MapSink`]: the recording path (`record`) plugs in
//! there. Messages that are not maps are logged with the reason and skipped; the node keeps
//! running.
//!
//! Networking is confined by [`Network`]: [`Network::Loopback`] announces and sends on
//! 127.0.0.1 only (multicast only on `lo`, SPDP to the localhost peers), which is what the
//! tests use. RustDDS binds its sockets to the wildcard address even then (see
//! docs/ROS.md, "Live: the ROS 2 node"), so it receives what reaches the host on its
//! ports; run the node in a network namespace to forbid that too.
//!
//! ```no_run
//! use froctomap_ros2_node::{MapSink, Network, Node, NodeOptions, ReceivedMap};
//! struct Print;
//! impl MapSink for Print {
//!     fn receive(&mut self, map: ReceivedMap) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
//!         println!("{} bytes at {}", map.file.len(), map.stamp.0);
//!         Ok(())
//!     }
//! }
//! let mut options = NodeOptions::new(0);
//! options.network = Network::Loopback;
//! let node = Node::new(&options)?;
//! let mut sink = Print;
//! loop {
//!     node.receive_into(&mut sink, std::time::Duration::from_millis(100))?;
//! }
//! # Ok::<(), froctomap_ros2_node::NodeError>(())
//! ```

mod error;
mod names;
mod params;
mod recording;
mod services;
mod sink;

pub use error::NodeError;
pub use names::{dds_topic_name, RosArgs, NODE_NAME};
pub use params::{
    parameter_type, DescribeParametersResponse, GetParameterTypesResponse, GetParametersResponse,
    ListParametersRequest, ListParametersResponse, NamesRequest, Parameter, ParameterDescriptor,
    ParameterValue, Parameters, SetParametersRequest, SetParametersResponse, SetParametersResult,
};

pub use recording::{CommitFailed, RecordingSink, TimeSource};
pub use sink::{MapSink, ReceivedMap};

pub use services::{
    decode_cdr, encode_cdr, FileServices, GetOctomapAtRequest, GetOctomapAtResponse, Header,
    MapData, Octomap, Point, ProbabilityAtRequest, ProbabilityAtResponse, RequestError,
    ServiceHandler, ServiceMapping, Time, GET_OCTOMAP_AT_DDS_TYPE, GET_OCTOMAP_AT_SERVICE,
    MAX_GET_OCTOMAP_AT_REQUEST_BYTES, MAX_POINTS, MAX_PROBABILITY_AT_REQUEST_BYTES,
    PROBABILITY_AT_DDS_TYPE, PROBABILITY_AT_SERVICE,
};

use froctomap_convert::{FroctFile, SeriesRead};
use froctomap_core::{error_message, Timestamp};
use froctomap_formats::{ExportedKind, OccupiedCell};
use froctomap_octomap_codec::{parse_header, FileKind};
use froctomap_ros::{decode_message, encode_octomap_cdr, Encoding, MessageError, MessageType};
use rustdds::no_key::{
    DataWriter, Decode, DefaultDecoder, DeserializerAdapter, SerializerAdapter, SimpleDataReader,
};
use rustdds::policy::{Durability, History, Reliability};
use rustdds::{
    DataWriterStatus, DomainParticipant, DomainParticipantBuilder, QosPolicies, QosPolicyBuilder,
    RTPSEntity, RepresentationIdentifier, StatusEvented, TopicKind,
};
use services::{decode_request, encode_reply, RequestId};
use std::convert::Infallible;
use std::net::{IpAddr, Ipv4Addr};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The topic subscribed by default, relative (in the node's namespace), as octomap_server
/// names its binary map topic: `/octomap_binary` without a namespace.
pub const DEFAULT_TOPIC: &str = "octomap_binary";
/// The node's own names before resolution: private names, `/froctomap/...` for the node
/// `froctomap` without a namespace (the names of `froctomap_ros`, which the MCAP export
/// uses too), `/robot1/froctomap/...` under `__ns:=/robot1`.
const PREDICTED_NAME: &str = "~/predicted";
const DYNAMIC_NAME: &str = "~/dynamic";
const GET_OCTOMAP_AT_NAME: &str = "~/get_octomap_at";
const PROBABILITY_AT_NAME: &str = "~/probability_at";
/// The DDS type name every ROS 2 RMW gives `rosgraph_msgs/msg/Clock`.
pub const CLOCK_DDS_TYPE: &str = "rosgraph_msgs::msg::dds_::Clock_";
/// The parameter services every ROS 2 node offers, with their DDS type stems and request
/// size bounds (names only: 1 MiB).
const PARAMETER_SERVICES: [(&str, &str); 6] = [
    (
        "~/list_parameters",
        "rcl_interfaces::srv::dds_::ListParameters",
    ),
    (
        "~/get_parameters",
        "rcl_interfaces::srv::dds_::GetParameters",
    ),
    (
        "~/get_parameter_types",
        "rcl_interfaces::srv::dds_::GetParameterTypes",
    ),
    (
        "~/describe_parameters",
        "rcl_interfaces::srv::dds_::DescribeParameters",
    ),
    (
        "~/set_parameters",
        "rcl_interfaces::srv::dds_::SetParameters",
    ),
    (
        "~/set_parameters_atomically",
        "rcl_interfaces::srv::dds_::SetParametersAtomically",
    ),
];
const MAX_PARAMETER_REQUEST_BYTES: usize = 1 << 20;
pub use froctomap_ros::{DYNAMIC_TOPIC, PREDICTED_TOPIC};
/// The DDS type name every ROS 2 RMW gives `visualization_msgs/msg/MarkerArray`.
pub const MARKER_ARRAY_DDS_TYPE: &str = "visualization_msgs::msg::dds_::MarkerArray_";
/// The DDS type name every ROS 2 RMW gives `octomap_msgs/msg/Octomap`.
pub const OCTOMAP_DDS_TYPE: &str = "octomap_msgs::msg::dds_::Octomap_";
/// Received messages larger than this are refused by default (far below the file limits).
pub const DEFAULT_MAX_MESSAGE_BYTES: usize = 256 << 20;

/// [`Node::receive_into`] takes at most this many messages a call.
pub const MAPS_PER_PASS: usize = 16;
/// [`Node::serve_requests`] answers at most this many requests of each service a call.
pub const REQUESTS_PER_PASS: usize = 4;
/// How long a reply waits for its client's reply reader to be matched.
const REPLY_READER_WAIT: Duration = Duration::from_millis(100);

/// Which network interfaces the node uses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Network {
    /// 127.0.0.1 only: the node announces loopback locators only, sends multicast only on
    /// `lo` and finds peers on the same host through the localhost SPDP ports.
    Loopback,
    /// These interface addresses only (announced locators and multicast).
    Only(Vec<IpAddr>),
    /// Every interface (RustDDS's default).
    All,
}

/// How the node is set up.
#[derive(Clone, Debug)]
pub struct NodeOptions {
    /// The ROS domain (`ROS_DOMAIN_ID`).
    pub domain_id: u16,
    /// The ROS topic of the maps received.
    pub topic: String,
    /// The interfaces used.
    pub network: Network,
    /// Larger messages are refused (logged and skipped).
    pub max_message_bytes: usize,
    /// How service requests and replies are framed.
    pub service_mapping: ServiceMapping,
    /// The frame every map received must be in; `None`: the first map received fixes it.
    /// Maps in another frame are refused (logged and skipped): one file holds one frame.
    pub frame_id: Option<String>,
    /// The node's name, namespace and remapping rules (`--ros-args`); `topic` and the
    /// node's own names are resolved through them.
    pub names: RosArgs,
    /// The parameters served (read-only); `use_sim_time` is added.
    pub parameters: Parameters,
    /// "Now" is the time `/clock` says ([`Node::now`]).
    pub use_sim_time: bool,
    /// The layout of the node's entry in the ROS graph (`ros_discovery_info`).
    pub graph: GraphLayout,
}

/// How the ROS graph message (`rmw_dds_common/msg/ParticipantEntitiesInfo` on
/// `ros_discovery_info`, what `ros2 node list` and `ros2 param` look nodes up in) lays out
/// its `Gid`: its size changed between ROS 2 releases.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum GraphLayout {
    /// 16-byte `Gid` (Iron, Jazzy and later).
    #[default]
    Jazzy,
    /// 24-byte `Gid` (Humble and before).
    Humble,
}

impl std::str::FromStr for GraphLayout {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        match text.trim().to_ascii_lowercase().as_str() {
            "jazzy" | "iron" | "kilted" | "rolling" => Ok(Self::Jazzy),
            "humble" | "galactic" | "foxy" => Ok(Self::Humble),
            _ => Err(format!(
                "`{text}` is not a ROS 2 distribution (humble, iron, jazzy, kilted, rolling)"
            )),
        }
    }
}

impl GraphLayout {
    fn gid_bytes(self) -> usize {
        match self {
            Self::Jazzy => 16,
            Self::Humble => 24,
        }
    }
}

/// The DDS topic (no `rt/` prefix: it is not a ROS topic) and type of the ROS graph.
const GRAPH_TOPIC: &str = "ros_discovery_info";
const GRAPH_DDS_TYPE: &str = "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";

impl NodeOptions {
    /// The defaults in `domain_id`: [`DEFAULT_TOPIC`], loopback only, 256 MiB messages.
    pub fn new(domain_id: u16) -> Self {
        Self {
            domain_id,
            topic: DEFAULT_TOPIC.to_string(),
            network: Network::Loopback,
            max_message_bytes: DEFAULT_MAX_MESSAGE_BYTES,
            service_mapping: ServiceMapping::default(),
            frame_id: None,
            names: RosArgs::default(),
            parameters: Parameters::default(),
            use_sim_time: false,
            graph: GraphLayout::default(),
        }
    }
}

/// The ROS domain named by `ROS_DOMAIN_ID` (0 when unset or empty, as in ROS 2).
pub fn domain_id_from_env() -> Result<u16, NodeError> {
    match std::env::var("ROS_DOMAIN_ID") {
        Err(_) => Ok(0),
        Ok(text) if text.trim().is_empty() => Ok(0),
        // RTPS ports overflow u16 past domain 232 (7400 + 250 * domain).
        Ok(text) => match text.trim().parse::<u16>() {
            Ok(domain) if domain <= 232 => Ok(domain),
            _ => Err(NodeError::DomainId(text)),
        },
    }
}

/// Why one received message was refused (logged; the node goes on).
#[derive(Debug, thiserror::Error)]
pub enum Refused {
    /// Over [`NodeOptions::max_message_bytes`].
    #[error("message of {bytes} bytes is over the limit of {limit} bytes")]
    TooLarge {
        /// Its size.
        bytes: usize,
        /// The limit.
        limit: usize,
    },
    /// Not an `octomap_msgs/Octomap` holding a map.
    #[error(transparent)]
    Message(#[from] MessageError),
    /// A `header.frame_id` no tf2 frame has: over [`MAX_FRAME_ID_BYTES`] bytes, or with
    /// characters outside letters, digits, `_`, `-`, `.` and `/`.
    #[error("the map's frame_id `{shown}` is not a frame name: {reason}")]
    FrameName {
        /// The frame_id, cut to 64 characters and escaped.
        shown: String,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// In another frame than the maps taken before (or than [`NodeOptions::frame_id`]).
    #[error("the map is in frame `{got}`, not `{expected}` as the maps before it (one file holds one frame)")]
    Frame {
        /// The message's `header.frame_id`.
        got: String,
        /// The frame fixed.
        expected: String,
    },
}

/// A request taken, with the participant of the client that sent it.
struct Request {
    message: Vec<u8>,
    sample: RequestId,
    client: Participant,
}

/// A participant's GUID prefix (RustDDS does not export its type).
type Participant = [u8; 12];

/// The participant of an endpoint: the first 12 bytes of its GUID.
fn participant(guid: rustdds::GUID) -> Participant {
    let bytes = guid.to_bytes();
    let mut prefix = [0; 12];
    prefix.copy_from_slice(&bytes[..12]);
    prefix
}

/// One service's request reader and reply writer.
struct ServiceEndpoints {
    /// The resolved service name.
    name: String,
    /// What its requests are (in errors).
    kind: &'static str,
    requests: SimpleDataReader<Vec<u8>, RawCdr>,
    replies: DataWriter<Vec<u8>, RawCdr>,
    /// Larger requests are skipped before decoding.
    max_request_bytes: usize,
    /// Readers matched to `replies`, from its status events (read on every pass: RustDDS
    /// keeps only a few and drops newer ones while they are unread).
    matched_readers: std::cell::RefCell<std::collections::HashSet<rustdds::GUID>>,
}

impl ServiceEndpoints {
    /// `rq/<service>Request` and `rr/<service>Reply` of types `<stem>_Request_` and
    /// `<stem>_Response_`, as every RMW names them; reliable, volatile, keep-last 10, as
    /// ROS's default service QoS.
    fn new(
        participant: &DomainParticipant,
        name: String,
        kind: &'static str,
        type_stem: &str,
        max_request_bytes: usize,
    ) -> Result<Self, NodeError> {
        let dds = |e: rustdds::dds::CreateError| NodeError::Dds(e.to_string());
        let qos = QosPolicyBuilder::new()
            .reliability(Reliability::Reliable {
                max_blocking_time: rustdds::Duration::from_millis(100),
            })
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth: 10 })
            .build();
        let stem = dds_topic_name(&name)?;
        let stem = stem.strip_prefix("rt/").unwrap_or(&stem);
        let request_topic = participant
            .create_topic(
                format!("rq/{stem}Request"),
                format!("{type_stem}_Request_"),
                &qos,
                TopicKind::NoKey,
            )
            .map_err(dds)?;
        let reply_topic = participant
            .create_topic(
                format!("rr/{stem}Reply"),
                format!("{type_stem}_Response_"),
                &qos,
                TopicKind::NoKey,
            )
            .map_err(dds)?;
        let requests = participant
            .create_subscriber(&qos)
            .map_err(dds)?
            .create_simple_datareader_no_key::<Vec<u8>, RawCdr>(&request_topic, Some(qos.clone()))
            .map_err(dds)?;
        let replies = participant
            .create_publisher(&qos)
            .map_err(dds)?
            .create_datawriter_no_key::<Vec<u8>, RawCdr>(&reply_topic, Some(qos.clone()))
            .map_err(dds)?;
        Ok(Self {
            name,
            kind,
            requests,
            replies,
            max_request_bytes,
            matched_readers: Default::default(),
        })
    }

    /// Takes the reply writer's match events into `matched_readers`.
    fn update_matched_readers(&self) {
        let mut matched = self.matched_readers.borrow_mut();
        while let Some(status) = self.replies.try_recv_status() {
            if let DataWriterStatus::PublicationMatched {
                current, reader, ..
            } = status
            {
                if current.count_change() < 0 {
                    matched.remove(&reader);
                } else {
                    matched.insert(reader);
                }
            }
        }
    }

    /// Waits (up to `wait`) until a reply reader of the participant `client` (the
    /// requester's: a client's request writer and reply reader live in one participant)
    /// is matched to the reply writer: a reply written before would be lost (replies are
    /// not kept for late readers), and a reader of another client does not count.
    fn wait_for_the_clients_reader(&self, client: Participant, wait: Duration) {
        let deadline = Instant::now() + wait;
        loop {
            self.update_matched_readers();
            let matched = self
                .matched_readers
                .borrow()
                .iter()
                .any(|reader| participant(*reader) == client);
            if matched || Instant::now() >= deadline {
                return;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

/// The node: a DDS participant with the map subscription, the predicted-map publisher and
/// the services.
pub struct Node {
    participant: DomainParticipant,
    /// Keeps the node's graph entry published (latched) while the node lives.
    _graph_writer: DataWriter<Vec<u8>, RawCdr>,
    reader: SimpleDataReader<Vec<u8>, RawCdr>,
    predicted: DataWriter<Vec<u8>, RawCdr>,
    dynamic: DataWriter<Vec<u8>, RawCdr>,
    get_octomap_at: ServiceEndpoints,
    probability_at: ServiceEndpoints,
    parameter_services: Vec<ServiceEndpoints>,
    parameters: Parameters,
    /// `/clock`'s reader with `use_sim_time`, and the last time it gave.
    clock: Option<SimClock>,
    names: ResolvedNames,
    service_mapping: ServiceMapping,
    topic: String,
    max_message_bytes: usize,
    /// The frame of the maps taken: given, or fixed by the first map a sink took.
    frame_id: std::cell::RefCell<Option<String>>,
}

impl Node {
    /// Joins the domain, subscribes the map topic (reliable, transient-local: latched maps
    /// are received too) and offers [`PREDICTED_TOPIC`] (reliable, transient-local).
    pub fn new(options: &NodeOptions) -> Result<Self, NodeError> {
        let ros = &options.names;
        let names = ResolvedNames {
            node: ros.fully_qualified_node_name(),
            topic: ros.resolve(&options.topic)?,
            predicted: ros.resolve(PREDICTED_NAME)?,
            dynamic: ros.resolve(DYNAMIC_NAME)?,
            get_octomap_at: ros.resolve(GET_OCTOMAP_AT_NAME)?,
            probability_at: ros.resolve(PROBABILITY_AT_NAME)?,
            clock: ros.resolve(froctomap_ros::CLOCK_TOPIC)?,
        };
        let participant = join_domain(options)?;
        let qos = latched_qos();
        let reader = raw_reader(&participant, &names.topic, OCTOMAP_DDS_TYPE, &qos)?;
        let predicted = raw_writer(&participant, &names.predicted, OCTOMAP_DDS_TYPE, &qos)?;
        let dynamic = raw_writer(&participant, &names.dynamic, MARKER_ARRAY_DDS_TYPE, &qos)?;
        let get_octomap_at = ServiceEndpoints::new(
            &participant,
            names.get_octomap_at.clone(),
            GET_OCTOMAP_AT_SERVICE,
            GET_OCTOMAP_AT_DDS_TYPE,
            MAX_GET_OCTOMAP_AT_REQUEST_BYTES.min(options.max_message_bytes),
        )?;
        let probability_at = ServiceEndpoints::new(
            &participant,
            names.probability_at.clone(),
            PROBABILITY_AT_SERVICE,
            PROBABILITY_AT_DDS_TYPE,
            MAX_PROBABILITY_AT_REQUEST_BYTES.min(options.max_message_bytes),
        )?;
        let parameter_services = PARAMETER_SERVICES
            .iter()
            .map(|&(name, stem)| {
                ServiceEndpoints::new(
                    &participant,
                    ros.resolve(name)?,
                    stem,
                    stem,
                    MAX_PARAMETER_REQUEST_BYTES.min(options.max_message_bytes),
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut parameters = options.parameters.clone();
        parameters.set(
            "use_sim_time",
            ParameterValue::bool(options.use_sim_time),
            "now is the time /clock says",
        );
        let clock = options
            .use_sim_time
            .then(|| sim_clock(&participant, &names.clock))
            .transpose()?;
        let graph = graph_entry(
            options.graph,
            participant.guid(),
            &options.names,
            [&reader]
                .into_iter()
                .chain(clock.as_ref().map(|(r, _)| r))
                .map(|r| r.guid())
                .chain(
                    [&get_octomap_at, &probability_at]
                        .into_iter()
                        .chain(&parameter_services)
                        .map(|s| s.requests.guid()),
                ),
            [&predicted, &dynamic].into_iter().map(|w| w.guid()).chain(
                [&get_octomap_at, &probability_at]
                    .into_iter()
                    .chain(&parameter_services)
                    .map(|s| s.replies.guid()),
            ),
        );
        let graph_writer = announce(&participant, graph)?;
        Ok(Self {
            participant,
            _graph_writer: graph_writer,
            reader,
            predicted,
            dynamic,
            get_octomap_at,
            probability_at,
            parameter_services,
            parameters,
            clock,
            service_mapping: options.service_mapping,
            topic: names.topic.clone(),
            names,
            max_message_bytes: options.max_message_bytes,
            frame_id: std::cell::RefCell::new(options.frame_id.clone()),
        })
    }

    /// The DDS domain joined.
    pub fn domain_id(&self) -> u16 {
        self.participant.domain_id()
    }

    /// The names the node resolved (its options' `names` applied).
    pub fn names(&self) -> &ResolvedNames {
        &self.names
    }

    /// The parameters served.
    pub fn parameters(&self) -> &Parameters {
        &self.parameters
    }

    /// "Now": the system clock, or with `use_sim_time` the last time `/clock` gave (`None`
    /// before the first one).
    pub fn now(&self) -> Option<Timestamp> {
        let Some((reader, last)) = &self.clock else {
            let now = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .ok()?;
            return i64::try_from(now.as_nanos()).ok().map(Timestamp);
        };
        while let Ok(Some(sample)) = reader.try_take_one() {
            if let Some(time) = decode_clock(&sample.into_value()) {
                last.set(Some(time.timestamp()));
            }
        }
        last.get()
    }

    /// Hands the maps received within `wait` (at least one poll) to `sink`, at most
    /// [`MAPS_PER_PASS`] (the caller's loop comes back for the rest, and can stop in
    /// between), and returns how many were accepted. Refused messages and sink errors are
    /// logged and skipped.
    pub fn receive_into(&self, sink: &mut dyn MapSink, wait: Duration) -> Result<usize, NodeError> {
        let deadline = Instant::now() + wait;
        let mut accepted = 0;
        let mut taken = 0;
        loop {
            if taken == MAPS_PER_PASS {
                return Ok(accepted);
            }
            match self.reader.try_take_one() {
                Ok(Some(change)) => {
                    taken += 1;
                    match self
                        .to_map(&change.into_value())
                        .and_then(|map| self.in_the_frame(map))
                    {
                        Ok(map) => {
                            let stamp = map.stamp;
                            let frame_id = map.frame_id.clone();
                            match sink.receive(map) {
                                Ok(()) => {
                                    accepted += 1;
                                    self.frame_id.borrow_mut().get_or_insert(frame_id);
                                }
                                // A failed commit loses more than this map: say so.
                                Err(e) => match e.downcast_ref::<CommitFailed>() {
                                    Some(failed) => sink.skipped(format!(
                                        "{}: {} (the last one received stamped {} ns)",
                                        self.topic,
                                        error_message(failed),
                                        stamp.0
                                    )),
                                    None => sink.skipped(format!(
                                        "{}: the map stamped {} ns was not recorded: {}",
                                        self.topic,
                                        stamp.0,
                                        error_message(&*e)
                                    )),
                                },
                            }
                        }
                        Err(reason) => sink.skipped(format!(
                            "{}: message skipped: {}",
                            self.topic,
                            error_message(&reason)
                        )),
                    }
                    continue;
                }
                Ok(None) => {}
                Err(e) => sink.skipped(format!("{}: message skipped: {e}", self.topic)),
            }
            if Instant::now() >= deadline {
                return Ok(accepted);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Answers the service requests waiting through `handler`, at most
    /// [`REQUESTS_PER_PASS`] of each service (the caller's loop comes back for the rest, and
    /// can stop in between); returns how many were answered. Requests that do not decode
    /// are logged and skipped. A request whose client's reply reader is not matched yet
    /// waits for it up to 100 ms.
    pub fn serve_requests(&self, handler: &mut dyn ServiceHandler) -> usize {
        self.get_octomap_at.update_matched_readers();
        self.probability_at.update_matched_readers();
        let mut answered = self.serve_parameters();
        let pass = |service| (0..REQUESTS_PER_PASS).map_while(move |_| self.take_request(service));
        for request in pass(&self.get_octomap_at) {
            answered += usize::from(self.answer(&self.get_octomap_at, &request, |r| {
                handler.get_octomap_at(r)
            }));
        }
        for request in pass(&self.probability_at) {
            answered += usize::from(self.answer(
                &self.probability_at,
                &request,
                |r: &ProbabilityAtRequest| {
                    if r.points.len() > MAX_POINTS {
                        log::warn!(
                            "{PROBABILITY_AT_SERVICE}: {} points are over the limit of {MAX_POINTS}; answering none",
                            r.points.len()
                        );
                        return ProbabilityAtResponse { p: Vec::new() };
                    }
                    handler.probability_at(r)
                },
            ));
        }
        answered
    }

    /// Answers the parameter services' requests (at most [`REQUESTS_PER_PASS`] each).
    fn serve_parameters(&self) -> usize {
        let mut answered = 0;
        let p = &self.parameters;
        for (i, service) in self.parameter_services.iter().enumerate() {
            service.update_matched_readers();
            for request in (0..REQUESTS_PER_PASS).map_while(|_| self.take_request(service)) {
                let done = match i {
                    0 => self.answer(service, &request, |r| p.list(r)),
                    1 => self.answer(service, &request, |r| p.values(r)),
                    2 => self.answer(service, &request, |r| p.types(r)),
                    3 => self.answer(service, &request, |r| p.describe(r)),
                    4 => self.answer(service, &request, |r| p.refuse_set(r)),
                    _ => self.answer(service, &request, |r: &SetParametersRequest| {
                        p.refuse_set(r)
                            .results
                            .into_iter()
                            .next()
                            .unwrap_or_default()
                    }),
                };
                answered += usize::from(done);
            }
        }
        answered
    }

    fn take_request(&self, service: &ServiceEndpoints) -> Option<Request> {
        loop {
            match service.requests.try_take_one() {
                Ok(Some(change)) => {
                    let sample = request_identity(
                        self.service_mapping,
                        rustdds::SampleIdentity {
                            writer_guid: change.writer_guid,
                            sequence_number: change.sequence_number,
                        },
                        change.related_sample_identity(),
                    );
                    let client = participant(change.writer_guid);
                    return Some(Request {
                        message: change.into_value(),
                        sample,
                        client,
                    });
                }
                Ok(None) => return None,
                Err(e) => log::warn!("{}: request skipped: {e}", service.name),
            }
        }
    }

    /// Decodes one request, answers it and writes the reply; says whether it did.
    fn answer<Q, R>(
        &self,
        service: &ServiceEndpoints,
        Request {
            message,
            sample,
            client,
        }: &Request,
        respond: impl FnOnce(&Q) -> R,
    ) -> bool
    where
        Q: serde::de::DeserializeOwned,
        R: serde::Serialize,
    {
        if message.len() > service.max_request_bytes {
            log::warn!(
                "{}: request of {} bytes is over the limit of {} bytes; skipped",
                service.name,
                message.len(),
                service.max_request_bytes
            );
            return false;
        }
        let (id, request) =
            match decode_request::<Q>(self.service_mapping, message, *sample, service.kind) {
                Ok(decoded) => decoded,
                Err(e) => {
                    log::warn!("{}: request skipped: {e}", service.name);
                    return false;
                }
            };
        let reply = match encode_reply(self.service_mapping, id, &respond(&request)) {
            Ok(reply) => reply,
            Err(e) => {
                log::warn!("{}: the reply could not be encoded: {e}", service.name);
                return false;
            }
        };
        service.wait_for_the_clients_reader(*client, REPLY_READER_WAIT);
        let written = match (self.service_mapping, id) {
            (ServiceMapping::Enhanced, RequestId::Sample { guid, sequence }) => service
                .replies
                .write_with_options(
                    reply,
                    rustdds::WriteOptionsBuilder::new()
                        .related_sample_identity(rustdds::SampleIdentity {
                            writer_guid: rustdds::GUID::from_bytes(guid),
                            sequence_number: rustdds::SequenceNumber::from(sequence),
                        })
                        .build(),
                )
                .map(|_| ()),
            _ => service.replies.write(reply, None),
        };
        match written {
            Ok(()) => true,
            Err(e) => {
                log::warn!("{}: the reply could not be sent: {e}", service.name);
                false
            }
        }
    }

    /// The frame of the maps taken so far (given in [`NodeOptions::frame_id`], or the
    /// first map's); `None` before.
    pub fn frame_id(&self) -> Option<String> {
        self.frame_id.borrow().clone()
    }

    /// `map` if it is in the frame of the maps taken before it.
    fn in_the_frame(&self, map: ReceivedMap) -> Result<ReceivedMap, Refused> {
        match &*self.frame_id.borrow() {
            Some(expected) if *expected != map.frame_id => Err(Refused::Frame {
                got: map.frame_id,
                expected: expected.clone(),
            }),
            _ => Ok(map),
        }
    }

    fn to_map(&self, message: &[u8]) -> Result<ReceivedMap, Refused> {
        if message.len() > self.max_message_bytes {
            return Err(Refused::TooLarge {
                bytes: message.len(),
                limit: self.max_message_bytes,
            });
        }
        let decoded = decode_message(message, Encoding::Cdr, MessageType::Octomap)?;
        check_frame_id(decoded.frame_id)?;
        Ok(ReceivedMap {
            stamp: Timestamp(decoded.stamp_ns),
            frame_id: decoded.frame_id.to_string(),
            received: self.now(),
            binary: decoded.binary,
            file: decoded.map_file()?,
        })
    }

    /// Publishes a `.bt` file on [`PREDICTED_TOPIC`] stamped `stamp` in `frame_id` (latched:
    /// subscribers joining later get the last one).
    pub fn publish_predicted(
        &self,
        bt: &[u8],
        stamp: Timestamp,
        frame_id: &str,
    ) -> Result<(), NodeError> {
        let message = octomap_message_of_bt(bt, stamp, frame_id)?;
        self.predicted
            .write(message, None)
            .map_err(|e| NodeError::Publish {
                topic: self.names.predicted.clone(),
                reason: e.to_string(),
            })
    }

    /// Publishes a map's occupied cells on [`DYNAMIC_TOPIC`] as a
    /// `visualization_msgs/MarkerArray` (one `CUBE_LIST` per depth, as octomap_server's
    /// `occupied_cells_vis_array`; [`froctomap_ros::encode_occupied_marker_array_cdr`]),
    /// stamped `stamp` in `frame_id`, latched.
    pub fn publish_dynamic(
        &self,
        occupied: &[OccupiedCell],
        resolution: f64,
        stamp: Timestamp,
        frame_id: &str,
    ) -> Result<(), NodeError> {
        let failed = |reason: String| NodeError::Publish {
            topic: self.names.dynamic.clone(),
            reason,
        };
        let message = froctomap_ros::encode_occupied_marker_array_cdr(
            ros_time(stamp).map_err(failed)?,
            frame_id,
            resolution,
            occupied,
        )
        .ok_or_else(|| failed(format!("{} cells do not fit a MarkerArray", occupied.len())))?;
        self.dynamic
            .write(message, None)
            .map_err(|e| failed(e.to_string()))
    }
}

/// `/clock`'s reader and the last time it gave.
type SimClock = (
    SimpleDataReader<Vec<u8>, RawCdr>,
    std::cell::Cell<Option<Timestamp>>,
);

/// The names a node resolved: its fully qualified name and its topics' and services'.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResolvedNames {
    /// The node (`/froctomap`).
    pub node: String,
    /// The maps received.
    pub topic: String,
    /// The predicted map.
    pub predicted: String,
    /// The predicted map's markers.
    pub dynamic: String,
    /// The map-at-a-time service.
    pub get_octomap_at: String,
    /// The probability service.
    pub probability_at: String,
    /// The simulated clock.
    pub clock: String,
}

/// The node's entry in the ROS graph: `rmw_dds_common/msg/ParticipantEntitiesInfo` in CDR
/// (the participant's `Gid`, then one `NodeEntitiesInfo`: namespace, name, its readers' and
/// writers' `Gid`s), each `Gid` the entity's GUID padded to the layout's size, as the RMWs
/// fill it.
fn graph_entry(
    layout: GraphLayout,
    participant: rustdds::GUID,
    names: &RosArgs,
    readers: impl Iterator<Item = rustdds::GUID>,
    writers: impl Iterator<Item = rustdds::GUID>,
) -> Vec<u8> {
    let gid = |out: &mut Vec<u8>, guid: rustdds::GUID| {
        let mut bytes = guid.to_bytes().to_vec();
        bytes.resize(layout.gid_bytes(), 0);
        out.extend_from_slice(&bytes);
    };
    // Alignment counts from the payload, after the 4-byte encapsulation header.
    let u32 = |out: &mut Vec<u8>, value: u32| {
        while !(out.len() - 4).is_multiple_of(4) {
            out.push(0);
        }
        out.extend_from_slice(&value.to_le_bytes());
    };
    let string = |out: &mut Vec<u8>, text: &str| {
        u32(out, text.len() as u32 + 1); // A node name or namespace: short.
        out.extend_from_slice(text.as_bytes());
        out.push(0);
    };
    let mut out = vec![0x00, 0x01, 0x00, 0x00];
    gid(&mut out, participant);
    u32(&mut out, 1);
    string(&mut out, &names.namespace);
    string(&mut out, &names.node_name);
    for guids in [readers.collect::<Vec<_>>(), writers.collect()] {
        u32(&mut out, guids.len() as u32);
        for guid in guids {
            gid(&mut out, guid);
        }
    }
    out
}

/// The DDS topic of the ROS topic `ros_topic`, of type `dds_type`.
fn raw_topic(
    participant: &DomainParticipant,
    ros_topic: &str,
    dds_type: &str,
    qos: &QosPolicies,
) -> Result<rustdds::Topic, NodeError> {
    participant
        .create_topic(
            dds_topic_name(ros_topic)?,
            dds_type.to_string(),
            qos,
            TopicKind::NoKey,
        )
        .map_err(|e| NodeError::Dds(e.to_string()))
}

/// The DDS participant on the options' domain and networks.
fn join_domain(options: &NodeOptions) -> Result<DomainParticipant, NodeError> {
    let dds = |e: rustdds::dds::CreateError| NodeError::Dds(e.to_string());
    let mut builder = DomainParticipantBuilder::new(options.domain_id);
    match &options.network {
        Network::Loopback => {
            builder = builder
                .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
                .same_host_loopback(true);
        }
        Network::Only(addresses) => builder = builder.with_only_networks(addresses.clone()),
        Network::All => {}
    }
    builder.build().map_err(dds)
}

/// `/clock`'s reader, with no time yet.
fn sim_clock(participant: &DomainParticipant, topic: &str) -> Result<SimClock, NodeError> {
    // As rclcpp's clock QoS: the last one, best effort (reads reliable writers too).
    let qos = QosPolicyBuilder::new()
        .reliability(Reliability::BestEffort)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1 })
        .build();
    let reader = raw_reader(participant, topic, CLOCK_DDS_TYPE, &qos)?;
    Ok((reader, std::cell::Cell::new(None)))
}

/// Publishes the node's graph entry (`graph`, serialized) and keeps its writer, whose
/// lifetime is the entry's.
fn announce(
    participant: &DomainParticipant,
    graph: Vec<u8>,
) -> Result<DataWriter<Vec<u8>, RawCdr>, NodeError> {
    let dds = |e: rustdds::dds::CreateError| NodeError::Dds(e.to_string());
    // The graph entry: reliable, transient-local, the last one, as the RMWs publish it.
    let graph_qos = QosPolicyBuilder::new()
        .reliability(Reliability::Reliable {
            max_blocking_time: rustdds::Duration::from_millis(100),
        })
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
        .build();
    let graph_topic = participant
        .create_topic(
            GRAPH_TOPIC.to_string(),
            GRAPH_DDS_TYPE.to_string(),
            &graph_qos,
            TopicKind::NoKey,
        )
        .map_err(dds)?;
    let graph_writer = participant
        .create_publisher(&graph_qos)
        .and_then(|p| {
            p.create_datawriter_no_key::<Vec<u8>, RawCdr>(&graph_topic, Some(graph_qos.clone()))
        })
        .map_err(dds)?;
    graph_writer
        .write(graph, None)
        .map_err(|e| NodeError::Publish {
            topic: GRAPH_TOPIC.to_string(),
            reason: e.to_string(),
        })?;
    Ok(graph_writer)
}

/// A reader of serialized messages of `dds_type` on the ROS topic `ros_topic`.
fn raw_reader(
    participant: &DomainParticipant,
    ros_topic: &str,
    dds_type: &str,
    qos: &QosPolicies,
) -> Result<SimpleDataReader<Vec<u8>, RawCdr>, NodeError> {
    let topic = raw_topic(participant, ros_topic, dds_type, qos)?;
    participant
        .create_subscriber(qos)
        .and_then(|s| {
            s.create_simple_datareader_no_key::<Vec<u8>, RawCdr>(&topic, Some(qos.clone()))
        })
        .map_err(|e| NodeError::Dds(e.to_string()))
}

/// A writer of serialized messages of `dds_type` on the ROS topic `ros_topic`.
fn raw_writer(
    participant: &DomainParticipant,
    ros_topic: &str,
    dds_type: &str,
    qos: &QosPolicies,
) -> Result<DataWriter<Vec<u8>, RawCdr>, NodeError> {
    let topic = raw_topic(participant, ros_topic, dds_type, qos)?;
    participant
        .create_publisher(qos)
        .and_then(|p| p.create_datawriter_no_key::<Vec<u8>, RawCdr>(&topic, Some(qos.clone())))
        .map_err(|e| NodeError::Dds(e.to_string()))
}

/// A time as `builtin_interfaces/Time` (`sec`, `nanosec`), or why it is outside it.
fn ros_time(stamp: Timestamp) -> Result<(i32, u32), String> {
    let seconds = i32::try_from(stamp.0.div_euclid(1_000_000_000))
        .map_err(|_| format!("stamp {} ns is outside builtin_interfaces/Time", stamp.0))?;
    Ok((seconds, stamp.0.rem_euclid(1_000_000_000) as u32)) // < 1e9.
}

/// Publishes the map a `.froct` file predicts on [`PREDICTED_TOPIC`], only when it changed.
pub struct PredictedPublisher {
    froct: PathBuf,
    frame_id: String,
    last: Option<Vec<u8>>,
}

impl PredictedPublisher {
    /// The predicted maps of `froct`, in `frame_id`.
    pub fn new(froct: &Path, frame_id: &str) -> Self {
        Self {
            froct: froct.to_path_buf(),
            frame_id: frame_id.to_string(),
            last: None,
        }
    }

    /// Maps from now on in `frame_id` (the node's frame, once the first map fixed it).
    pub fn set_frame_id(&mut self, frame_id: &str) {
        if self.frame_id != frame_id {
            frame_id.clone_into(&mut self.frame_id);
            self.last = None; // Published again, in its new frame.
        }
    }

    /// The canonical `.bt` of the map predicted for `t` (the file is opened anew, so maps
    /// appended since the last call count).
    pub fn predicted_bt(&self, t: Timestamp) -> Result<Vec<u8>, NodeError> {
        froctomap_convert::predicted_bt(&self.open()?, t).map_err(|e| self.failed(e))
    }

    fn open(&self) -> Result<FroctFile, NodeError> {
        FroctFile::open(&self.froct).map_err(|e| self.failed(e))
    }

    fn failed(&self, source: impl std::error::Error + Send + Sync + 'static) -> NodeError {
        NodeError::Froct {
            path: self.froct.clone(),
            source: Box::new(source),
        }
    }

    /// Publishes the map predicted for `t` stamped `t` if it differs from the last one
    /// published, with its occupied cells on [`DYNAMIC_TOPIC`] (coloured by their
    /// probability); returns those cells when it did, for other views of the same map
    /// (the CLI's Foxglove view), so that they need not predict it again. The map counts as
    /// published once it is, even when its markers then fail ([`NodeError::Publish`] on the
    /// markers' topic, saying the map went out): the same map is not sent again for them.
    pub fn publish_if_changed(
        &mut self,
        node: &Node,
        t: Timestamp,
    ) -> Result<Option<PublishedCells>, NodeError> {
        let reader = self.open()?;
        let bt = froctomap_convert::predicted_bt(&reader, t).map_err(|e| self.failed(e))?;
        if self.last.as_ref() == Some(&bt) {
            return Ok(None);
        }
        node.publish_predicted(&bt, t, &self.frame_id)?;
        self.last = Some(bt);
        let resolution = reader.header().resolution;
        let markers = froctomap_convert::occupied_cells_at(&reader, ExportedKind::Predicted, t)
            .map_err(|e| self.failed(e))
            .and_then(|occupied| {
                node.publish_dynamic(&occupied, resolution, t, &self.frame_id)?;
                Ok(occupied)
            });
        let occupied = markers.map_err(|e| NodeError::Publish {
            topic: node.names.dynamic.clone(),
            reason: format!(
                "the predicted map was published, its markers were not: {}",
                error_message(&e)
            ),
        })?;
        Ok(Some(PublishedCells {
            occupied,
            resolution,
        }))
    }
}

/// The occupied cells of a map [`PredictedPublisher::publish_if_changed`] published, with
/// their probabilities.
#[derive(Clone, Debug)]
pub struct PublishedCells {
    /// The cells, as [`DYNAMIC_TOPIC`]'s markers show them.
    pub occupied: Vec<OccupiedCell>,
    /// The map's resolution in metres.
    pub resolution: f64,
}

/// The last instant of a `.froct` file's time axis.
pub fn last_instant(froct: &Path) -> Result<Timestamp, NodeError> {
    let reader = FroctFile::open(froct).map_err(|source| NodeError::Froct {
        path: froct.to_path_buf(),
        source: Box::new(source),
    })?;
    Ok(reader.last_instant())
}

/// The CDR `octomap_msgs/Octomap` message of a `.bt` file (`binary` true, the body behind
/// the file's header, as octomap_msgs' `binaryMapToMsg` fills it).
pub fn octomap_message_of_bt(
    bt: &[u8],
    stamp: Timestamp,
    frame_id: &str,
) -> Result<Vec<u8>, NodeError> {
    let header = parse_header(bt, FileKind::Binary).map_err(|e| NodeError::Publish {
        topic: PREDICTED_TOPIC.to_string(),
        reason: format!("the predicted map is not a .bt file: {e}"),
    })?;
    let body = bt.get(header.body_offset..).unwrap_or_default();
    let stamp = ros_time(stamp).map_err(|reason| NodeError::Publish {
        topic: PREDICTED_TOPIC.to_string(),
        reason,
    })?;
    encode_octomap_cdr(
        stamp,
        frame_id,
        true,
        &header.tree_id,
        header.resolution,
        body,
    )
    .ok_or(NodeError::MessageTooLong { bytes: body.len() })
}

/// The identity a reply names for a request whose own sample identity is `own`.
/// Enhanced: the request may name another one (its `related_sample_identity`), whose GUID
/// wins; rmw_fastrtps clients set only that GUID (their reply reader's) and leave the
/// sequence number UNKNOWN, and take the request's own sequence number back, as
/// rmw_fastrtps' server does.
fn request_identity(
    mapping: ServiceMapping,
    own: rustdds::SampleIdentity,
    related: Option<rustdds::SampleIdentity>,
) -> RequestId {
    let identity = match related {
        Some(related) if mapping == ServiceMapping::Enhanced => rustdds::SampleIdentity {
            writer_guid: related.writer_guid,
            sequence_number: if related.sequence_number == rustdds::SequenceNumber::UNKNOWN {
                own.sequence_number
            } else {
                related.sequence_number
            },
        },
        _ => own,
    };
    RequestId::Sample {
        guid: identity.writer_guid.to_bytes(),
        sequence: i64::from(identity.sequence_number),
    }
}

/// Reliable, transient-local, the last 16 samples: what `octomap_server` offers for its
/// latched maps, and deep enough that a burst of maps is not thinned before it is taken.
fn latched_qos() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::Reliable {
            max_blocking_time: rustdds::Duration::from_millis(100),
        })
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 16 })
        .build()
}

/// Serialized messages as they are: the node decodes and encodes CDR itself
/// (`froctomap_ros`), so the DDS layer moves bytes, with their encapsulation header.
struct RawCdr;

#[derive(Clone)]
struct RawCdrDecoder;

const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];
const CDR_BE_HEADER: [u8; 4] = [0x00, 0x00, 0x00, 0x00];

impl DeserializerAdapter<Vec<u8>> for RawCdr {
    type Error = Infallible;
    type Decoded = Vec<u8>;

    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &[
            RepresentationIdentifier::CDR_LE,
            RepresentationIdentifier::CDR_BE,
        ]
    }

    fn transform_decoded(decoded: Self::Decoded) -> Vec<u8> {
        decoded
    }
}

impl DefaultDecoder<Vec<u8>> for RawCdr {
    type Decoder = RawCdrDecoder;
    const DECODER: Self::Decoder = RawCdrDecoder;
}

impl<'de> Decode<'de, Vec<u8>> for RawCdrDecoder {
    type Error = Infallible;

    fn decode_bytes(
        self,
        input: &'de [u8],
        encoding: RepresentationIdentifier,
    ) -> Result<Vec<u8>, Infallible> {
        // The decoder reads the encapsulation header, which DDS hands over separately.
        let header = if encoding == RepresentationIdentifier::CDR_BE {
            CDR_BE_HEADER
        } else {
            CDR_LE_HEADER
        };
        let mut message = Vec::with_capacity(4 + input.len());
        message.extend_from_slice(&header);
        message.extend_from_slice(input);
        Ok(message)
    }
}

impl SerializerAdapter<Vec<u8>> for RawCdr {
    type Error = Infallible;

    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }

    fn to_bytes(value: &Vec<u8>) -> Result<rustdds::bytes::Bytes, Infallible> {
        // `encode_octomap_cdr` writes the little-endian header; DDS writes its own.
        Ok(rustdds::bytes::Bytes::copy_from_slice(
            value.get(4..).unwrap_or_default(),
        ))
    }
}

/// Longest `header.frame_id` a map may carry: the frame is written into the file's
/// metadata and every message the node publishes.
pub const MAX_FRAME_ID_BYTES: usize = 256;

/// `Ok` when `frame_id` can name a tf2 frame (empty: no frame given).
fn check_frame_id(frame_id: &str) -> Result<(), Refused> {
    let refuse = |reason| {
        Err(Refused::FrameName {
            shown: frame_id
                .chars()
                .take(64)
                .collect::<String>()
                .escape_debug()
                .to_string(),
            reason,
        })
    };
    if frame_id.len() > MAX_FRAME_ID_BYTES {
        return refuse("longer than 256 bytes");
    }
    let allowed = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '/');
    if !frame_id.chars().all(allowed) {
        return refuse("only letters, digits, `_`, `-`, `.` and `/` name a tf2 frame");
    }
    Ok(())
}

/// The `builtin_interfaces/Time` of a `/clock` message (`rosgraph_msgs/Clock`) behind its
/// encapsulation header: `[0, 1]` (CDR) or `[0, 7]` (XCDR2) little-endian, `[0, 0]` or
/// `[0, 6]` big-endian; `None` for any other header or a short message.
fn decode_clock(message: &[u8]) -> Option<Time> {
    let little = match message.get(..2)? {
        [0, 1] | [0, 7] => true,
        [0, 0] | [0, 6] => false,
        _ => return None,
    };
    let field = |at: usize| {
        let bytes: [u8; 4] = message.get(at..at + 4)?.try_into().ok()?;
        Some(if little {
            u32::from_le_bytes(bytes)
        } else {
            u32::from_be_bytes(bytes)
        })
    };
    Some(Time {
        sec: field(4)? as i32,
        nanosec: field(8)?,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn frame_ids_that_name_no_frame_are_refused() {
        for good in [
            "",
            "map",
            "/odom",
            "base_link",
            "robot1/map",
            "cam-0.optical",
        ] {
            assert!(check_frame_id(good).is_ok(), "{good}");
        }
        let long = "m".repeat(MAX_FRAME_ID_BYTES + 1);
        for bad in [long.as_str(), "map frame", "map\n", "kart\u{e9}", "a;b"] {
            let err = check_frame_id(bad).unwrap_err();
            assert!(matches!(err, Refused::FrameName { .. }), "{bad}: {err}");
            assert!(err.to_string().len() < 200, "{err}");
        }
        assert!(check_frame_id(&"m".repeat(MAX_FRAME_ID_BYTES)).is_ok());
    }

    #[test]
    fn clock_messages_decode_by_their_encapsulation() {
        let le = [0u8, 1, 0, 0, 5, 0, 0, 0, 7, 0, 0, 0];
        let be = [0u8, 0, 0, 0, 0, 0, 0, 5, 0, 0, 0, 7];
        let want = Some(Time { sec: 5, nanosec: 7 });
        assert_eq!(decode_clock(&le), want);
        assert_eq!(decode_clock(&be), want);
        let mut xcdr2_le = le;
        xcdr2_le[1] = 7;
        assert_eq!(decode_clock(&xcdr2_le), want);
        let mut xcdr2_be = be;
        xcdr2_be[1] = 6;
        assert_eq!(decode_clock(&xcdr2_be), want);
        // PL_CDR, an unknown header, a non-zero first byte, a short message: skipped.
        for header in [[0u8, 3], [0, 9], [1, 1], [0xFF, 0xFF]] {
            let mut message = le;
            message[..2].copy_from_slice(&header);
            assert_eq!(decode_clock(&message), None, "{header:?}");
        }
        assert_eq!(decode_clock(&le[..11]), None);
    }

    use super::*;

    #[test]
    fn the_default_names_are_froctomap_ros_names() {
        // The node and the MCAP export share the names of `froctomap_ros`.
        let ros = RosArgs::default();
        let resolve = |name| ros.resolve(name).ok();
        assert_eq!(
            resolve(DEFAULT_TOPIC).as_deref(),
            Some(froctomap_ros::OCTOMAP_TOPIC)
        );
        assert_eq!(resolve(PREDICTED_NAME).as_deref(), Some(PREDICTED_TOPIC));
        assert_eq!(resolve(DYNAMIC_NAME).as_deref(), Some(DYNAMIC_TOPIC));
        assert_eq!(
            resolve(GET_OCTOMAP_AT_NAME).as_deref(),
            Some(GET_OCTOMAP_AT_SERVICE)
        );
        assert_eq!(
            resolve(PROBABILITY_AT_NAME).as_deref(),
            Some(PROBABILITY_AT_SERVICE)
        );
    }

    #[test]
    fn ros_topics_map_to_dds_names_as_rmws_do() {
        assert_eq!(
            dds_topic_name("/octomap_binary").ok().as_deref(),
            Some("rt/octomap_binary")
        );
        assert_eq!(
            dds_topic_name("/froctomap/predicted").ok().as_deref(),
            Some("rt/froctomap/predicted")
        );
        for bad in ["", "/", "//a", "/a/", "/a b", "/1a"] {
            assert!(dds_topic_name(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn enhanced_replies_take_the_requests_own_sequence_number_when_the_related_one_is_unknown() {
        let guid = |b: u8| rustdds::GUID::from_bytes([b; 16]);
        let own = rustdds::SampleIdentity {
            writer_guid: guid(1),
            sequence_number: rustdds::SequenceNumber::from(7_i64),
        };
        // rmw_fastrtps: the reply reader's GUID, sequence number UNKNOWN.
        let fastrtps = rustdds::SampleIdentity {
            writer_guid: guid(2),
            sequence_number: rustdds::SequenceNumber::UNKNOWN,
        };
        let full = rustdds::SampleIdentity {
            writer_guid: guid(3),
            sequence_number: rustdds::SequenceNumber::from(9_i64),
        };
        let id = |mapping, related| match request_identity(mapping, own, related) {
            RequestId::Sample { guid, sequence } => (guid, sequence),
            RequestId::Cyclone { .. } => panic!("a sample identity"),
        };
        assert_eq!(id(ServiceMapping::Enhanced, Some(fastrtps)), ([2; 16], 7));
        assert_eq!(id(ServiceMapping::Enhanced, Some(full)), ([3; 16], 9));
        assert_eq!(id(ServiceMapping::Enhanced, None), ([1; 16], 7));
        // Basic replies name the request's own identity whatever it carries.
        assert_eq!(id(ServiceMapping::Basic, Some(full)), ([1; 16], 7));
    }
}
