//! The recording row: the training series as one MCAP file (the maps as
//! `octomap_msgs/msg/Octomap` in CDR, as `ros2 bag record` stores `/octomap_binary`), built
//! in its own process like the `.bt` build it is compared with (`BUILD_NATIVE`, same run).

use anyhow::{Context, Result};
use froctomap_convert::SeriesInput;
use froctomap_octomap_codec::{parse_header, FileKind};
use froctomap_ros::{encode_octomap_cdr, OCTOMAP_ROS2MSG, OCTOMAP_TOPIC, OCTOMAP_TYPE};
use std::collections::BTreeMap;
use std::path::Path;

/// The row's name in the build table.
pub const BUILD_FROM_MCAP: &str = "build lossless from one MCAP of the series (ROS 2 CDR)";

/// Writes every map of `inputs` into the MCAP file `path` (zstd chunks) at its time, one map
/// in memory at a time; returns the file's bytes.
pub fn write_mcap(inputs: &[SeriesInput], path: &Path) -> Result<u64> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut writer = mcap::WriteOptions::new()
        .profile("ros2")
        .create(std::io::BufWriter::new(file))?;
    let schema = writer.add_schema(OCTOMAP_TYPE, "ros2msg", OCTOMAP_ROS2MSG.as_bytes())?;
    let channel = writer.add_channel(schema, OCTOMAP_TOPIC, "cdr", &BTreeMap::new())?;
    for (sequence, input) in inputs.iter().enumerate() {
        let bt = std::fs::read(&input.path)
            .with_context(|| format!("reading {}", input.path.display()))?;
        let header = parse_header(&bt, FileKind::Binary)
            .with_context(|| format!("{}: not a .bt file", input.path.display()))?;
        let seconds = i32::try_from(input.time.0.div_euclid(1_000_000_000))?;
        let stamp = (seconds, input.time.0.rem_euclid(1_000_000_000) as u32);
        let body = bt.get(header.body_offset..).unwrap_or_default();
        let message = encode_octomap_cdr(stamp, "map", true, "OcTree", header.resolution, body)
            .context("a map too large for one message")?;
        let time = u64::try_from(input.time.0)?;
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: sequence as u32,
            log_time: time,
            publish_time: time,
        };
        writer.write_to_known_channel(&header, &message)?;
    }
    writer.finish()?;
    drop(writer);
    Ok(std::fs::metadata(path)?.len())
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_convert::{
        build, collect_inputs, observed_map, BuildOptions, Context, Silent, TimeSource,
    };
    use froctomap_core::Timestamp;
    use froctomap_file::FroctReader;

    /// The MCAP of a series builds the same file as the series' `.bt` files.
    #[test]
    fn the_mcap_of_a_series_builds_the_file_of_its_bt_files() -> Result<()> {
        let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/octomap");
        let inputs: Vec<SeriesInput> = ["few_voxels.bt", "coarse_leaves.bt", "few_voxels.bt"]
            .iter()
            .enumerate()
            .map(|(i, name)| SeriesInput {
                path: fixtures.join(name),
                time: Timestamp::from_secs(1_700_000_000 + 600 * i as i64),
            })
            .collect();
        let dir = tempfile::tempdir()?;
        let mcap = dir.path().join("series.mcap");
        assert!(write_mcap(&inputs, &mcap)? > 0);
        let mut context = Context::with_default_plugins();
        froctomap_ros::register(&mut context);
        let recorded = collect_inputs(&context, &[mcap], TimeSource::Auto)?;
        let times: Vec<Timestamp> = recorded.iter().map(|i| i.time).collect();
        assert_eq!(times, inputs.iter().map(|i| i.time).collect::<Vec<_>>());
        let options = BuildOptions {
            created: Some(Timestamp::from_secs(1_700_100_000)),
            ..BuildOptions::default()
        };
        let (a, b) = (dir.path().join("a.froct"), dir.path().join("b.froct"));
        build(&context, &recorded, &a, &options, &Silent)?;
        build(&context, &inputs, &b, &options, &Silent)?;
        // The same maps at every sample (the headers differ in what they say of the inputs).
        let (a, b) = (FroctReader::open(&a)?, FroctReader::open(&b)?);
        assert_eq!(a.header().axis.len(), 3);
        for sample in 0..3 {
            let map = |r: &FroctReader| observed_map(r, sample).map(|m| m.leaves().to_vec());
            assert!(map(&a)? == map(&b)?, "sample {sample}");
        }
        Ok(())
    }
}
