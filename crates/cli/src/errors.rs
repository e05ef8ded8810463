//! What to try after an error: the command-line options that get past it, which the
//! libraries cannot name.

use froctomap_convert::{ConvertError, SnapshotError};
use froctomap_formats::FormatError;
use froctomap_ros::RosError;

/// The error and its causes on one line, each text once
/// ([`froctomap_core::error_message`], which Python's `FroctError` shows too).
pub fn message(error: &anyhow::Error) -> String {
    let error: &(dyn std::error::Error + Send + Sync + 'static) = error.as_ref();
    froctomap_core::error_message(error)
}

/// A hint for `error`, from the first typed cause that has one. `skips_bad_files`: the
/// command has `--skip-bad`.
pub fn hint(error: &anyhow::Error, skips_bad_files: bool) -> Option<&'static str> {
    error.chain().find_map(|cause| {
        if let Some(error) = cause.downcast_ref::<RosError>() {
            return recording_hint(error, skips_bad_files);
        }
        if let Some(error) = cause.downcast_ref::<ConvertError>() {
            if let Some(hint) = convert_hint(error, skips_bad_files) {
                return Some(hint);
            }
        }
        match cause.downcast_ref::<FormatError>() {
            Some(FormatError::UnknownExtension { .. }) => {
                Some("name the file accordingly or pass --format")
            }
            _ => None,
        }
    })
}

fn convert_hint(error: &ConvertError, skips_bad_files: bool) -> Option<&'static str> {
    match error {
        e if skips_bad_files && e.is_skippable() => {
            Some("use --skip-bad to leave such files out (they are listed at the end)")
        }
        ConvertError::NoTimes { .. } | ConvertError::EarlyNameTime { .. } => {
            Some("give the times with --start and --step, or name the files by their times")
        }
        ConvertError::Snapshot { source, .. }
            if matches!(**source, SnapshotError::TooManyTiles { .. }) =>
        {
            Some("build with a smaller --tile-depth (coarser tiles), or leave the file out")
        }
        ConvertError::MostlySkipped { .. } => Some(
            "give the series' resolution with --resolution (build), or pass --allow-mostly-skipped to go on with the rest",
        ),
        ConvertError::AppendOverlap { .. } => Some(
            "append takes only snapshots later than the file's last one (`froctomap info FILE` shows its span); leave the earlier ones out",
        ),
        ConvertError::SnapshotResolution { .. } => Some(
            "score snapshots of the file's resolution (`froctomap info` shows both), or build a file from snapshots of this one",
        ),
        ConvertError::AnomalyTimeBeforeFile { .. } => Some(
            "give the snapshot's time with --time; `froctomap info FILE` shows the file's span",
        ),
        ConvertError::TooManyMaps { .. } => Some("use a longer --every"),
        ConvertError::EmptyRange { .. } => Some("--to must not be before --from"),
        ConvertError::NonPositiveInterval => Some("--every must be positive"),
        ConvertError::DirectoryNotEmpty { .. } => {
            Some("choose a new directory, or pass --overwrite to replace its files")
        }
        ConvertError::Write(FormatError::UnknownExtension { .. }) => {
            Some("name the file accordingly or pass --format")
        }
        ConvertError::RecordingTimes { .. } => {
            Some("leave out --start/--step and --times-file; --time-source log takes the recording times")
        }
        _ => None,
    }
}

fn recording_hint(error: &RosError, skips_bad_files: bool) -> Option<&'static str> {
    match error {
        RosError::SeveralOctomapTopics { .. }
        | RosError::NoSuchTopic { .. }
        | RosError::NotOctomapTopic { .. } => {
            Some("choose one of the listed topics with --topic NAME")
        }
        RosError::NoOctomapTopic { .. } => Some(
            "record the map topic of octomap_server (/octomap_binary), or name a topic of another octomap type with --topic",
        ),
        RosError::UnsupportedCompression { .. } => {
            Some("decompress the bag with `rosbag decompress` first")
        }
        RosError::DamagedChunk { problem, .. }
            if matches!(**problem, RosError::UnsupportedCompression { .. }) =>
        {
            Some("decompress the bag with `rosbag decompress` first")
        }
        RosError::DamagedChunk { .. } if skips_bad_files => {
            Some("pass --skip-bad to leave damaged chunks out (they are listed at the end)")
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[derive(Debug, thiserror::Error)]
    #[error("{path}: {source}")]
    struct Repeats {
        path: &'static str,
        #[source]
        source: std::io::Error,
    }

    #[test]
    fn each_cause_is_printed_once() {
        let io = || std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let repeating = anyhow::Error::new(Repeats {
            path: "a.froct",
            source: io(),
        });
        assert_eq!(message(&repeating), "a.froct: no such file");
        let layered = anyhow::Error::new(io()).context("reading the base map");
        assert_eq!(message(&layered), "reading the base map: no such file");
    }

    #[test]
    fn skip_bad_is_suggested_only_where_it_exists() {
        let mixed = || {
            anyhow::Error::new(ConvertError::MixedResolution {
                first: PathBuf::from("a.bt"),
                first_resolution: 0.1,
                second: PathBuf::from("b.bt"),
                second_resolution: 0.05,
            })
        };
        assert!(hint(&mixed(), true).is_some_and(|h| h.contains("--skip-bad")));
        assert_eq!(hint(&mixed(), false), None);
        let many = anyhow::Error::new(ConvertError::TooManyMaps { count: 5, limit: 1 });
        assert_eq!(hint(&many, false), Some("use a longer --every"));
    }
}
