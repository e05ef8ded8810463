//! What a recording holds, for `froctomap info`: every topic with its type, encoding,
//! message count and first and last log times, as `ros2 bag info` and `rosbag info` list
//! them. Counts come from the indexes (bag index data, MCAP chunks' records, SQLite), so
//! nothing is decoded.

use crate::bag::Bag;
use crate::bag_metadata::BagMetadata;
use crate::error::RosError;
use crate::mcap_file::McapFile;
use crate::sqlite_bag;
use crate::topic_counts::{Span, TopicKey};
use froctomap_core::Timestamp;
use froctomap_formats::{RecordedTopic, RecordingOptions, RecordingSummary};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Topics: message count and log-time span.
#[derive(Default)]
struct Tally(BTreeMap<TopicKey, (u64, Span)>);

impl Tally {
    fn add(&mut self, key: TopicKey, count: u64, span: Span) {
        let entry = self.0.entry(key).or_insert((0, None));
        entry.0 += count;
        entry.1 = match (entry.1, span) {
            (Some((a, b)), Some((c, d))) => Some((a.min(c), b.max(d))),
            (x, y) => x.or(y),
        };
    }

    fn summary(self, warnings: Vec<String>) -> RecordingSummary {
        let topics = self
            .0
            .into_iter()
            .map(|((topic, type_name, encoding), (count, span))| {
                RecordedTopic::new(
                    topic,
                    type_name,
                    encoding,
                    count,
                    span.map(|(a, b)| (Timestamp(a), Timestamp(b))),
                )
            })
            .collect();
        RecordingSummary::new(topics, warnings)
    }
}

fn widen(span: Option<(i64, i64)>, t: i64) -> Option<(i64, i64)> {
    Some(span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))))
}

/// The topics of a ROS 1 bag, from its index data.
pub(crate) fn describe_bag(path: &Path, limit: u64) -> Result<RecordingSummary, RosError> {
    let bag = Bag::open(path, limit, false)?;
    let mut tally = Tally::default();
    for connection in &bag.connections {
        let mut count = 0u64;
        let mut span = None;
        for info in bag
            .chunks
            .iter()
            .filter(|c| c.connections.contains(&connection.id))
        {
            for message in bag.chunk_messages(info, &[connection.id])? {
                count += 1;
                span = widen(span, message.log_ns);
            }
        }
        tally.add(
            (
                connection.topic.clone(),
                connection.type_name.clone(),
                "ros1".into(),
            ),
            count,
            span,
        );
    }
    Ok(tally.summary(bag.warnings))
}

/// The topics of MCAP files read as one recording (one file, or a ROS 2 bag's).
pub(crate) fn describe_mcap(
    path: &Path,
    files: &[PathBuf],
    limit: u64,
) -> Result<RecordingSummary, RosError> {
    let mut tally = Tally::default();
    let mut warnings = Vec::new();
    for file in files {
        let mcap = McapFile::open(file, limit, false)?;
        warnings.extend(mcap.warnings.iter().map(|w| {
            if file == path {
                w.clone()
            } else {
                format!("{}: {w}", file.display())
            }
        }));
        for channel in &mcap.channels {
            let mut count = 0u64;
            let mut span = None;
            for i in 0..mcap.chunks.len() {
                if !mcap.chunks[i].may_hold(&[channel.id]) {
                    continue;
                }
                let found =
                    mcap.chunk_messages(i, &[channel.id], limit, &mut |_, _| Ok(Some(None)))?;
                for (message, _) in found {
                    count += 1;
                    span = widen(span, message.log_ns);
                }
            }
            tally.add(
                (
                    channel.topic.clone(),
                    channel.schema.clone(),
                    channel.encoding.clone(),
                ),
                count,
                span,
            );
        }
    }
    Ok(tally.summary(warnings))
}

/// The topics of a ROS 2 bag with sqlite3 storage, counted by SQLite.
pub(crate) fn describe_sqlite(
    dir: &Path,
    metadata: &BagMetadata,
    limit: u64,
) -> Result<RecordingSummary, RosError> {
    let bag = sqlite_bag::open_databases(dir, metadata, &RecordingOptions::default(), limit)?;
    let mut tally = Tally::default();
    for database in &bag.databases {
        for (key, count, span) in database.topic_counts()? {
            tally.add(key, count, span);
        }
    }
    Ok(tally.summary(Vec::new()))
}
