//! The recordings in fixtures/ros (written by PyPI rosbags and mcap-ros2-support) read back:
//! topics, times, and maps identical to the .bt files they were made from; truncated and
//! damaged copies give errors, never panics.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_core::Timestamp;
use froctomap_formats::{
    FormatRegistry, ReadOptions, RecordedTime, Recording, RecordingFormat, RecordingOptions,
};
use froctomap_ros::{RosError, MCAP, ROS2_BAG, ROSBAG};
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(name)
}

fn open(
    format: &RecordingFormat,
    path: &Path,
    topic: Option<&str>,
    time: RecordedTime,
) -> Result<Recording, Box<dyn std::error::Error + Send + Sync>> {
    let options = RecordingOptions::new(topic.map(str::to_string), time);
    (format.open)(path, &options, 1 << 30)
}

/// The leaves of a map file's bytes, as the registry reads them.
fn leaves(bytes: &[u8]) -> Vec<froctomap_core::Leaf> {
    let registry = FormatRegistry::with_default_formats();
    let read = registry
        .read_bytes(Path::new("map"), bytes, ReadOptions::default())
        .unwrap();
    assert!(read.map.warnings.is_empty(), "{:?}", read.map.warnings);
    read.map.snapshot.leaves().to_vec()
}

fn fixture_leaves(name: &str) -> Vec<froctomap_core::Leaf> {
    leaves(&std::fs::read(fixture(&format!("octomap/{name}"))).unwrap())
}

const STAMPS: [i64; 2] = [1_700_000_000_000_000_000, 1_700_000_060_500_000_000];
const LOGS: [i64; 2] = [1_700_000_001_000_000_000, 1_700_000_061_000_000_000];

#[test]
fn every_kind_of_recording_gives_its_maps_at_their_stamps() {
    for (format, name) in [
        (&ROSBAG, "ros/two_maps_lz4.bag"),
        (&ROS2_BAG, "ros/two_maps_ros2"),
        (&MCAP, "ros/two_maps_zstd.mcap"),
    ] {
        let path = fixture(name);
        assert!(format.recognises(&path), "{name}");
        let recording = open(format, &path, None, RecordedTime::Header).unwrap();
        assert_eq!(recording.times, STAMPS.map(Timestamp), "{name}");
        assert!(recording.warnings.is_empty());
        let maps = [
            recording.maps.map_bytes(0, 1 << 30).unwrap(),
            recording.maps.map_bytes(1, 1 << 30).unwrap(),
        ];
        assert_eq!(leaves(&maps[0]), fixture_leaves("few_voxels.bt"), "{name}");
        assert_eq!(
            leaves(&maps[1]),
            fixture_leaves("coarse_leaves.bt"),
            "{name}"
        );
        assert_eq!(recording.maps.topic(), "/octomap_binary");
        let logged = open(format, &path, None, RecordedTime::Log).unwrap();
        assert_eq!(logged.times, LOGS.map(Timestamp), "{name}");
        // A map above the limit is refused before it is read.
        assert!(recording.maps.map_bytes(0, 10).is_err());
    }
    // Formats recognise their own kind only.
    assert!(!ROSBAG.recognises(&fixture("ros/two_maps_zstd.mcap")));
    assert!(!MCAP.recognises(&fixture("ros/two_maps_lz4.bag")));
    assert!(!ROS2_BAG.recognises(&fixture("ros/two_maps_lz4.bag")));
}

#[test]
fn topics_are_chosen_or_listed() {
    let path = fixture("ros/two_topics_bz2.bag");
    let err = open(&ROSBAG, &path, None, RecordedTime::Header).unwrap_err();
    match err.downcast_ref::<RosError>() {
        Some(RosError::SeveralOctomapTopics { topics, .. }) => {
            let names: Vec<&str> = topics.iter().map(|(t, _)| t.as_str()).collect();
            assert_eq!(names, ["/octomap_binary", "/octomap_full"]);
        }
        other => panic!("{other:?}"),
    }
    let full = open(&ROSBAG, &path, Some("/octomap_full"), RecordedTime::Header).unwrap();
    assert_eq!(full.times, [Timestamp(STAMPS[0])]);
    assert_eq!(
        leaves(&full.maps.map_bytes(0, 1 << 30).unwrap()),
        fixture_leaves("coarse_leaves.bt")
    );
    // A zero stamp takes the log time, with a warning.
    let binary = open(
        &ROSBAG,
        &path,
        Some("/octomap_binary"),
        RecordedTime::Header,
    )
    .unwrap();
    assert_eq!(binary.times, [Timestamp(LOGS[0])]);
    assert_eq!(binary.warnings.len(), 1, "{:?}", binary.warnings);
    assert!(binary.warnings[0].contains("zero header stamp"));
    let err = open(&ROSBAG, &path, Some("/chatter"), RecordedTime::Header).unwrap_err();
    assert!(
        matches!(err.downcast_ref::<RosError>(), Some(RosError::NotOctomapTopic { found, .. }) if found == "std_msgs/String"),
        "{err}"
    );
    let err = open(&ROSBAG, &path, Some("/nope"), RecordedTime::Header).unwrap_err();
    assert!(
        err.to_string().contains("/chatter [std_msgs/String]"),
        "{err}"
    );
}

#[test]
fn a_directory_of_bags_is_not_a_ros2_bag_and_a_ros2_bag_without_storage_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    assert!(!ROS2_BAG.recognises(dir.path()));
    std::fs::write(
        dir.path().join("metadata.yaml"),
        "rosbag2_bagfile_information:\n",
    )
    .unwrap();
    assert!(ROS2_BAG.recognises(dir.path()));
    let err = open(&ROS2_BAG, dir.path(), None, RecordedTime::Header).unwrap_err();
    assert!(
        matches!(
            err.downcast_ref::<RosError>(),
            Some(RosError::NoStorageInBag { .. })
        ),
        "{err}"
    );
    // A database cut after SQLite's magic: SQLite's error, naming the file.
    std::fs::write(dir.path().join("x_0.db3"), b"SQLite format 3\0").unwrap();
    let err = open(&ROS2_BAG, dir.path(), None, RecordedTime::Header).unwrap_err();
    assert!(
        matches!(
            err.downcast_ref::<RosError>(),
            Some(RosError::Sqlite { .. })
        ),
        "{err}"
    );
    assert!(err.to_string().contains("x_0.db3"), "{err}");
}

/// Opens a damaged copy and fetches every map: any outcome but a panic.
fn read_all(format: &RecordingFormat, path: &Path) -> Result<usize, String> {
    let recording = open(format, path, None, RecordedTime::Header).map_err(|e| e.to_string())?;
    for i in 0..recording.times.len() {
        recording
            .maps
            .map_bytes(i, 1 << 30)
            .map_err(|e| e.to_string())?;
    }
    Ok(recording.times.len())
}

#[test]
fn truncated_and_damaged_recordings_give_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    for (format, name) in [
        (&ROSBAG, "ros/two_maps_lz4.bag"),
        (&ROSBAG, "ros/two_topics_bz2.bag"),
        (&ROSBAG, "ros/one_map.bag"),
        (&MCAP, "ros/two_maps_zstd.mcap"),
    ] {
        let bytes = std::fs::read(fixture(name)).unwrap();
        let copy = dir.path().join("copy");
        for end in (0..bytes.len()).step_by(7) {
            std::fs::write(&copy, &bytes[..end]).unwrap();
            if let Err(message) = read_all(format, &copy) {
                assert!(message.contains("copy"), "{name} cut at {end}: {message}");
            }
        }
        // Every byte damaged in turn (in steps, to keep the test short): no panic, no hang.
        for at in (0..bytes.len()).step_by(3) {
            let mut damaged = bytes.clone();
            damaged[at] ^= 0x5a;
            std::fs::write(&copy, &damaged).unwrap();
            let _ = read_all(format, &copy);
        }
    }
}

/// Issue 29: a record header of length 0 (no fields, no `op`) at any record of a bag is an
/// error naming the bag and where the record is, never a bag that reads with maps missing.
#[test]
fn a_bag_record_header_of_length_zero_is_an_error_naming_the_bag_and_the_record() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(fixture("ros/one_map.bag")).unwrap();
    let le32 = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let copy = dir.path().join("zero-header.bag");
    let mut pos = b"#ROSBAG V2.0\n".len();
    let mut records = 0;
    while pos < bytes.len() {
        let mut damaged = bytes.clone();
        damaged[pos..pos + 4].fill(0);
        std::fs::write(&copy, &damaged).unwrap();
        let message = read_all(&ROSBAG, &copy).expect_err(&format!("record at byte {pos}"));
        assert!(message.contains("zero-header.bag"), "{pos}: {message}");
        if records > 1 {
            assert!(
                message.contains(&format!("the record at byte {pos} has no `op` field")),
                "{pos}: {message}"
            );
        }
        records += 1;
        let header = le32(pos);
        pos += 8 + header + le32(pos + 4 + header);
    }
    assert!(records > 4);
}

#[test]
fn the_plugin_registers_once_in_a_format_registry() {
    let mut registry = FormatRegistry::with_default_formats();
    froctomap_ros::register(&mut registry).unwrap();
    let names: Vec<&str> = registry
        .recording_formats()
        .iter()
        .map(|f| f.name)
        .collect();
    assert_eq!(names, ["rosbag", "mcap", "ros2bag"]);
    // One descriptor per container both opens and identifies it.
    let head = std::fs::read(fixture("ros/one_map.bag")).unwrap();
    assert!(matches!(
        registry.identify(&head),
        Some(froctomap_formats::Identified::Recording(f)) if f.name == "rosbag"
    ));
    assert_eq!(
        registry
            .recording_for(&fixture("ros/two_maps_ros2"))
            .map(|f| f.name),
        Some("ros2bag")
    );
    assert_eq!(
        registry
            .recording_for(&fixture("ros/two_maps_zstd.mcap"))
            .map(|f| f.name),
        Some("mcap")
    );
    let again = froctomap_ros::register(&mut registry).unwrap_err();
    assert_eq!(again.name, "rosbag");
}

/// Reads `bytes` as an MCAP stream, in reads of at most `step` bytes (a pipe's pieces),
/// spooling into `spool`.
fn open_stream(
    bytes: &[u8],
    step: usize,
    spool: &Path,
    skip_bad: bool,
) -> Result<Recording, Box<dyn std::error::Error + Send + Sync>> {
    /// A reader handing out at most `step` bytes at a time.
    struct Pieces<'a>(&'a [u8], usize);
    impl std::io::Read for Pieces<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = buf.len().min(self.1).min(self.0.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }
    let options = RecordingOptions::new(None, RecordedTime::Header)
        .with_skip_bad(skip_bad)
        .with_spool_dir(Some(spool.to_path_buf()));
    let open_stream = MCAP.open_stream.expect("MCAP reads streams");
    open_stream(&mut Pieces(bytes, step), &options, 1 << 30)
}

/// The MCAP fixture written by mcap-ros2-support, streamed in pieces of any size, gives the
/// maps and times the file gives; its spool lives beside (in the directory asked for) until
/// the recording is dropped.
#[test]
fn an_mcap_stream_gives_the_maps_of_the_file() {
    let bytes = std::fs::read(fixture("ros/two_maps_zstd.mcap")).unwrap();
    let spool = tempfile::tempdir().unwrap();
    for step in [1, 7, 4096, usize::MAX] {
        let recording = open_stream(&bytes, step, spool.path(), false).unwrap();
        assert_eq!(recording.times, STAMPS.map(Timestamp), "{step}");
        assert_eq!(recording.maps.topic(), "/octomap_binary");
        let entries = || std::fs::read_dir(spool.path()).unwrap().count();
        assert_eq!(
            entries(),
            1,
            "one spool directory while the recording lives"
        );
        assert_eq!(
            leaves(&recording.maps.map_bytes(0, 1 << 30).unwrap()),
            fixture_leaves("few_voxels.bt")
        );
        assert_eq!(
            leaves(&recording.maps.map_bytes(1, 1 << 30).unwrap()),
            fixture_leaves("coarse_leaves.bt")
        );
        assert!(recording.maps.map_bytes(0, 10).is_err());
        drop(recording);
        assert_eq!(entries(), 0, "the spool goes with the recording");
    }
}

/// A stream cut anywhere (its writer died) or damaged anywhere is an error naming where it
/// stopped (bytes and messages read) or a bad message, never a panic, a hang or a recording
/// of part of the stream; nothing is left in the spool directory.
/// `error` as the front ends print it: the MCAP reader's own error is the cause, after the
/// place the stream stopped.
fn printed(error: &(dyn std::error::Error + Send + Sync + 'static)) -> String {
    assert_eq!(froctomap_core::said_twice(error), None, "{error:?}");
    froctomap_core::error_message(error)
}

#[test]
fn cut_or_damaged_mcap_streams_are_errors_naming_where_they_stopped() {
    let bytes = std::fs::read(fixture("ros/two_maps_zstd.mcap")).unwrap();
    let spool = tempfile::tempdir().unwrap();
    for end in 0..bytes.len() {
        let error = printed(
            &*open_stream(&bytes[..end], 64, spool.path(), false)
                .expect_err("a cut stream is refused"),
        );
        assert!(
            error.starts_with("MCAP stream on standard input: does not read after ")
                && error.contains(&format!("at byte {end}: ")),
            "cut at {end}: {error}"
        );
    }
    let error = printed(
        &*open_stream(&bytes[..bytes.len() - 8], 64, spool.path(), true)
            .expect_err("--skip-bad does not take a cut stream"),
    );
    assert!(error.contains("after 3 message(s)"), "{error}");
    for at in (0..bytes.len()).step_by(3) {
        let mut damaged = bytes.clone();
        damaged[at] ^= 0x5a;
        match open_stream(&damaged, 64, spool.path(), false) {
            Err(error) => {
                let error = printed(&*error);
                assert!(
                    error.starts_with("MCAP stream on standard input:") || error.starts_with("-: "),
                    "damaged at {at}: {error}"
                );
            }
            // A byte nothing checks (a padding, a summary offset): the maps must read or
            // fail with an error.
            Ok(recording) => {
                for i in 0..recording.times.len() {
                    let _ = recording.maps.map_bytes(i, 1 << 30);
                }
            }
        }
    }
    assert_eq!(std::fs::read_dir(spool.path()).unwrap().count(), 0);
}
