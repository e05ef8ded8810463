//! Why the node cannot start or go on.

use std::path::PathBuf;

/// Why the node cannot start or go on.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// `ROS_DOMAIN_ID` is not a domain.
    #[error("ROS_DOMAIN_ID `{0}` is not a domain id (0..=232)")]
    DomainId(String),
    /// A topic name ROS would refuse.
    #[error("`{0}` is not a valid ROS topic name")]
    TopicName(String),
    /// `--ros-args` that do not parse.
    #[error("--ros-args: {0}")]
    RosArgs(String),
    /// The DDS participant, topic, reader or writer could not be created.
    #[error("DDS setup failed: {0}")]
    Dds(String),
    /// A map could not be published.
    #[error("publishing on {topic} failed: {reason}")]
    Publish {
        /// The ROS topic.
        topic: String,
        /// What DDS said.
        reason: String,
    },
    /// The `.froct` file could not be read or its map predicted.
    #[error("{}", path.display())]
    Froct {
        /// The file.
        path: PathBuf,
        /// Why.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A map could not be put in a message (a field longer than CDR can say).
    #[error("the map of {bytes} bytes does not fit an octomap_msgs/Octomap message")]
    MessageTooLong {
        /// The data length.
        bytes: usize,
    },
}
