//! The recording row: the training series as one MCAP file (the maps as
//! `octomap_msgs/msg/Octomap` in CDR, as `ros2 bag record` stores `/octomap_binary`), built
//! in its own process like the `.bt` build it is compared with (`BUILD_NATIVE`, same run).
//!
//! `froctomap-bench mcap --series DIR` measures that row alone on any series of `.bt`
//! files (e.g. the shared 4-week series): it packs the series into one MCAP with our own
//! writer (the `mcap` crate; fine for a speed comparison, since the reader does not care who
//! wrote the chunks), then times `froctomap build` of the `.bt` directory and of the MCAP,
//! each in its own process, and checks that the two files are byte-identical.

use anyhow::{bail, Context, Result};
use clap::Args;
use froctomap_convert::{collect_inputs, group_thousands, SeriesInput, TimeSource};
use froctomap_file::FroctReader;
use froctomap_octomap_codec::{parse_header, FileKind};
use froctomap_ros::{encode_octomap_cdr, OCTOMAP_ROS2MSG, OCTOMAP_TOPIC, OCTOMAP_TYPE};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Instant;

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

/// `froctomap-bench mcap`.
#[derive(Args)]
pub struct McapRowArgs {
    /// The series: a directory of `.bt` files with `manifest.csv` (e.g. the `train`
    /// directory a `run` generates). Only read.
    #[arg(long)]
    series: PathBuf,
    /// Where the MCAP, the series' links and both built files go (removed afterwards unless
    /// --keep).
    #[arg(long)]
    out: PathBuf,
    /// The `froctomap` binary (default: the one beside this program).
    #[arg(long)]
    froctomap: Option<PathBuf>,
    /// `--memory` of both builds (default: the build's).
    #[arg(long)]
    memory: Option<String>,
    /// Keep the MCAP and the built files.
    #[arg(long)]
    keep: bool,
}

/// One timed `froctomap build`.
struct Timed {
    seconds: f64,
    peak_memory_bytes: Option<u64>,
    file_bytes: u64,
}

/// The `froctomap` binary given, else the one beside this program.
pub fn froctomap_binary(given: Option<&std::path::Path>) -> Result<std::path::PathBuf> {
    Ok(match given {
        Some(path) => path.to_path_buf(),
        None => std::env::current_exe()?
            .parent()
            .context("this program's directory")?
            .join("froctomap"),
    })
}

/// Packs `--series` into one MCAP and times `froctomap build` of both, checking that they
/// write the same bytes; prints a markdown table.
pub fn mcap_row(args: &McapRowArgs) -> Result<()> {
    let froctomap = froctomap_binary(args.froctomap.as_deref())?;
    let manifest = args.series.join("manifest.csv");
    let inputs = collect_inputs(
        &froctomap_convert::Context::with_default_plugins(),
        std::slice::from_ref(&manifest),
        TimeSource::Auto,
    )?;
    // The series as links beside the MCAP, so that both builds name the same source
    // directory in the header and the files can be compared byte for byte.
    let dir = args.out.join("series");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut bt_bytes = 0u64;
    for input in &inputs {
        let name = input
            .path
            .file_name()
            .context("a series file without a name")?;
        let link = dir.join(name);
        if !link.exists() {
            std::os::unix::fs::symlink(std::fs::canonicalize(&input.path)?, &link)?;
        }
        // Read once, so that both builds start from the page cache.
        bt_bytes += std::fs::read(&input.path)?.len() as u64;
    }
    std::fs::copy(&manifest, dir.join("manifest.csv"))?;
    let mcap = dir.join("series.mcap");
    let started = Instant::now();
    let mcap_bytes = write_mcap(&inputs, &mcap)?;
    let packing = started.elapsed().as_secs_f64();
    eprintln!(
        "{} snapshots, {} bytes of .bt; MCAP of {} bytes written in {packing:.1} s",
        inputs.len(),
        group_thousands(bt_bytes),
        group_thousands(mcap_bytes)
    );
    let from_bt = args.out.join("from-bt.froct");
    let from_mcap = args.out.join("from-mcap.froct");
    let bt = timed_build(&froctomap, &dir, &from_bt, args.memory.as_deref())?;
    let recorded = timed_build(&froctomap, &mcap, &from_mcap, args.memory.as_deref())?;
    let identical = std::fs::read(&from_bt)? == std::fs::read(&from_mcap)?;
    let difference = if identical {
        None
    } else {
        differences(&from_bt, &from_mcap)?
    };
    let mib = |b: Option<u64>| b.map_or("-".into(), |b| format!("{:.0} MiB", b as f64 / 1048576.0));
    println!(
        "| build of {} snapshots | input bytes | seconds | ratio | peak memory | file bytes |",
        inputs.len()
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: |");
    for (name, bytes, row) in [
        (".bt directory (baseline)", bt_bytes, &bt),
        ("one MCAP (ROS 2 CDR, zstd chunks)", mcap_bytes, &recorded),
    ] {
        println!(
            "| {name} | {} | {:.2} | {:.2}× | {} | {} |",
            group_thousands(bytes),
            row.seconds,
            row.seconds / bt.seconds,
            mib(row.peak_memory_bytes),
            group_thousands(row.file_bytes)
        );
    }
    match (identical, &difference) {
        (true, _) => println!("\nbuilt files: byte-identical"),
        (false, None) => println!(
            "\nbuilt files: identical tiles, index and header, but for the `input_bytes` noted in header and summary \
             (the .bt files' bytes against the maps' bytes as the reader rebuilds them from the \
             messages, with the standard .bt header)"
        ),
        (false, Some(what)) => println!("\nbuilt files DIFFER: {what}"),
    }
    if !args.keep {
        std::fs::remove_dir_all(&dir)?;
        std::fs::remove_file(&from_bt)?;
        std::fs::remove_file(&from_mcap)?;
    }
    if let Some(what) = difference {
        bail!("the builds from the MCAP and from the .bt files differ: {what}");
    }
    Ok(())
}

/// What differs between two built files other than `input_bytes` in the header and the
/// index summary (which counts what was read: `.bt` files, or maps rebuilt from messages);
/// `None`: nothing.
fn differences(a: &std::path::Path, b: &std::path::Path) -> Result<Option<String>> {
    let (ra, rb) = (FroctReader::open(a)?, FroctReader::open(b)?);
    let header = |r: &FroctReader| {
        let mut header = r.header().clone();
        header.metadata.remove("input_bytes");
        header
    };
    if header(&ra) != header(&rb) {
        return Ok(Some("the headers".into()));
    }
    let summary = |r: &FroctReader| {
        let mut summary = r.summary().clone();
        summary.remove("input_bytes");
        summary
    };
    if summary(&ra) != summary(&rb) {
        return Ok(Some("the summaries".into()));
    }
    if ra.tiles().len() != rb.tiles().len() {
        return Ok(Some("the number of tiles".into()));
    }
    let (bytes_a, bytes_b) = (std::fs::read(a)?, std::fs::read(b)?);
    for (ta, tb) in ra.tiles().iter().zip(rb.tiles()) {
        let stored = |bytes: &[u8], offset: u64, len: u32| {
            let start = usize::try_from(offset).ok()?;
            bytes
                .get(start..start.checked_add(len as usize)?)
                .map(<[u8]>::to_vec)
        };
        let same = (ta.code, ta.stored_len, ta.raw_len, ta.crc)
            == (tb.code, tb.stored_len, tb.raw_len, tb.crc)
            && stored(&bytes_a, ta.offset, ta.stored_len)
                == stored(&bytes_b, tb.offset, tb.stored_len);
        if !same {
            return Ok(Some(format!("the tile at Morton code {}", ta.code.0)));
        }
    }
    Ok(None)
}

/// `froctomap build INPUT -o OUTPUT --json` in its own process, with a fixed creation time.
fn timed_build(
    froctomap: &std::path::Path,
    input: &std::path::Path,
    output: &std::path::Path,
    memory: Option<&str>,
) -> Result<Timed> {
    let mut command = Command::new(froctomap);
    command.arg("build").arg(input).arg("-o").arg(output).args([
        "--created",
        "2026-01-01T00:00:00Z",
        "--json",
        "--quiet",
    ]);
    if let Some(memory) = memory {
        command.args(["--memory", memory]);
    }
    eprintln!("building {}", input.display());
    let out = command
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .with_context(|| format!("starting {}", froctomap.display()))?;
    if !out.status.success() {
        bail!("the build of {} failed ({})", input.display(), out.status);
    }
    let value: Value = serde_json::from_slice(&out.stdout)
        .with_context(|| format!("reading the report of the build of {}", input.display()))?;
    Ok(Timed {
        seconds: value["seconds"].as_f64().unwrap_or(0.0),
        peak_memory_bytes: value["peak_memory_bytes"].as_u64(),
        file_bytes: value["file_bytes"].as_u64().unwrap_or(0),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_convert::{
        build, collect_inputs, observed_map, BuildOptions, Context, Silent, TimeSource,
    };
    use froctomap_core::Timestamp;

    /// The MCAP of a series builds the same file as the series' `.bt` files.
    #[test]
    fn the_mcap_of_a_series_builds_the_file_of_its_bt_files() -> Result<()> {
        let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/octomap");
        let inputs: Vec<SeriesInput> = ["few_voxels.bt", "coarse_leaves.bt", "few_voxels.bt"]
            .iter()
            .enumerate()
            .map(|(i, name)| {
                SeriesInput::new(
                    fixtures.join(name),
                    Timestamp::from_secs(1_700_000_000 + 600 * i as i64),
                )
            })
            .collect();
        let dir = tempfile::tempdir()?;
        let mcap = dir.path().join("series.mcap");
        assert!(write_mcap(&inputs, &mcap)? > 0);
        let mut context = Context::with_default_plugins();
        froctomap_ros::register(context.formats_mut())?;
        let recorded = collect_inputs(&context, &[mcap], TimeSource::Auto)?;
        let times: Vec<Timestamp> = recorded.iter().map(|i| i.time).collect();
        assert_eq!(times, inputs.iter().map(|i| i.time).collect::<Vec<_>>());
        let options = BuildOptions {
            time: Some(Timestamp::from_secs(1_700_100_000)),
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
