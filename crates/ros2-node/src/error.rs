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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::services::RequestError;
    use crate::{CommitFailed, Refused};
    use froctomap_convert::{ConvertError, RecordError};
    use froctomap_core::said_twice;

    fn io() -> std::io::Error {
        std::io::Error::other("disk full")
    }

    /// Every variant of this crate's errors, as its chain prints: no text repeats another of
    /// the chain and none is empty (the node's warnings print the chain, so the cause of a
    /// refused message or a failed commit is shown once).
    #[test]
    fn every_error_is_said_once() {
        let node = [
            NodeError::DomainId("x".into()),
            NodeError::TopicName("a b".into()),
            NodeError::RosArgs("-r needs from:=to".into()),
            NodeError::Dds("no network interface".into()),
            NodeError::Publish {
                topic: "/froctomap/predicted".into(),
                reason: "the writer is gone".into(),
            },
            NodeError::Froct {
                path: "a.froct".into(),
                source: Box::new(io()),
            },
            NodeError::MessageTooLong { bytes: 1 << 33 },
        ];
        for e in &node {
            // Fails to compile when a variant is added and not listed above.
            match e {
                NodeError::DomainId(_)
                | NodeError::TopicName(_)
                | NodeError::RosArgs(_)
                | NodeError::Dds(_)
                | NodeError::Publish { .. }
                | NodeError::Froct { .. }
                | NodeError::MessageTooLong { .. } => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        assert_eq!(
            froctomap_core::error_message(&node[5]),
            "a.froct: disk full"
        );
        let refused = [
            Refused::TooLarge { bytes: 9, limit: 8 },
            Refused::Message(froctomap_ros::MessageError::NotAMap(
                froctomap_octomap_codec::CodecError::Empty,
            )),
            Refused::FrameName {
                shown: "a b".into(),
                reason: "a space",
            },
            Refused::Frame {
                got: "odom".into(),
                expected: "map".into(),
            },
        ];
        for e in &refused {
            match e {
                Refused::TooLarge { .. }
                | Refused::Message(_)
                | Refused::FrameName { .. }
                | Refused::Frame { .. } => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        let requests = [
            RequestError::NotCdr,
            RequestError::Decode {
                what: "GetOctomapAt",
                reason: "the message ends early".into(),
            },
        ];
        for e in &requests {
            match e {
                RequestError::NotCdr | RequestError::Decode { .. } => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        let commit = CommitFailed {
            lost: 2,
            source: Box::new(RecordError::Convert(ConvertError::NoInputs)),
        };
        assert_eq!(said_twice(&commit), None, "{commit:?}");
    }
}
