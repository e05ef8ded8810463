//! Where received maps go: [`MapSink`] and the [`ReceivedMap`] it takes.

use froctomap_core::Timestamp;

/// A map received over the wire, as a map file.
#[derive(Clone, Debug, PartialEq)]
pub struct ReceivedMap {
    /// The message's `header.stamp` (0: the publisher left it unset).
    pub stamp: Timestamp,
    /// The message's `header.frame_id`.
    pub frame_id: String,
    /// When the node took it: [`Node::now`](crate::Node::now), the system clock or with
    /// `use_sim_time` `/clock`'s time (`None` before `/clock` said one).
    pub received: Option<Timestamp>,
    /// `true`: a `.bt` file (`binary` messages); `false`: an `.ot` file.
    pub binary: bool,
    /// The map file: the message's data behind the header OctoMap writes for it
    /// ([`froctomap_ros::OctomapMessage::map_file`]).
    pub file: Vec<u8>,
}

/// Where received maps go: the recording path implements it (`record`'s commit), tests
/// write files.
pub trait MapSink {
    /// Takes one map. An error is logged with the map's stamp; the node keeps running.
    fn receive(&mut self, map: ReceivedMap)
        -> Result<(), Box<dyn std::error::Error + Send + Sync>>;

    /// A message was skipped, for `reason` (a refused message, or `receive`'s error). The
    /// default logs it as a warning (`log`).
    fn skipped(&mut self, reason: String) {
        log::warn!("{reason}");
    }
}
