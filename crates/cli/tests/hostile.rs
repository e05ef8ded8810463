//! Hostile inputs and outputs end to end (issue 29): resealed lengths in recordings end in
//! a typed error naming the file within a bounded address space, never an abort.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use std::path::Path;
use std::process::{Command, Output};

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(name)
}

/// Runs the command line in an address space of 4 GB (`ulimit -v`), as the attack did.
fn froctomap_bounded(args: &[&Path]) -> Output {
    let mut command = Command::new("sh");
    command
        .arg("-c")
        .arg("ulimit -v 4000000 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_froctomap"));
    command.args(args).output().expect("run froctomap")
}

/// The MCAP fixture with the first chunk's compression name declaring 0xFFFFFFFF bytes.
fn hostile_mcap() -> Vec<u8> {
    let mut bytes = std::fs::read(fixture("ros/two_maps_zstd.mcap")).unwrap();
    let mut pos = MCAP_MAGIC.len();
    loop {
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        if bytes[pos] == 0x06 {
            let at = pos + 9 + 28;
            bytes[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
            return bytes;
        }
        pos += 9 + len;
    }
}

#[test]
fn build_of_an_mcap_with_a_hostile_length_is_a_typed_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("hostile.mcap");
    std::fs::write(&input, hostile_mcap()).unwrap();
    let output = dir.path().join("out.froct");
    let run = froctomap_bounded(&[Path::new("build"), &input, Path::new("-o"), &output]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("hostile.mcap") && stderr.contains("a string runs past its record"),
        "{stderr}"
    );
    assert!(!output.exists());
}

/// A ROS 1 bag whose record `index` has a header length of 0 (no fields, no `op`).
fn bag_with_empty_header(index: usize) -> Vec<u8> {
    let mut bytes = std::fs::read(fixture("ros/one_map.bag")).unwrap();
    let le32 = |b: &[u8], at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap()) as usize;
    let mut pos = b"#ROSBAG V2.0\n".len();
    for _ in 0..index {
        let header = le32(&bytes, pos);
        pos += 8 + header + le32(&bytes, pos + 4 + header);
    }
    bytes[pos..pos + 4].fill(0);
    bytes
}

#[test]
fn a_bag_record_without_header_fields_is_named_as_such() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("empty-header.bag");
    std::fs::write(&input, bag_with_empty_header(4)).unwrap();
    let output = dir.path().join("out.froct");
    let run = froctomap_bounded(&[Path::new("build"), &input, Path::new("-o"), &output]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("empty-header.bag") && stderr.contains("no `op` field"),
        "{stderr}"
    );
}

/// The offsets of the records of the bag fixture after its magic.
fn bag_record_offsets(bytes: &[u8]) -> Vec<usize> {
    let le32 = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let mut offsets = Vec::new();
    let mut pos = b"#ROSBAG V2.0\n".len();
    while pos < bytes.len() {
        offsets.push(pos);
        let header = le32(pos);
        pos += 8 + header + le32(pos + 4 + header);
    }
    offsets
}

/// Issue 29: a header length of 0 on the index data after a chunk ended in "no input files"
/// (the chunk's messages were dropped without a word). Every record, with and without
/// `--skip-bad`, is now an error naming the bag.
#[test]
fn a_bag_record_header_of_length_zero_anywhere_is_an_error_naming_the_bag() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("zero-header.bag");
    let output = dir.path().join("out.froct");
    let bytes = std::fs::read(fixture("ros/one_map.bag")).unwrap();
    let offsets = bag_record_offsets(&bytes);
    assert!(offsets.len() > 4, "{offsets:?}");
    for (index, &at) in offsets.iter().enumerate() {
        let mut damaged = bytes.clone();
        damaged[at..at + 4].fill(0);
        std::fs::write(&input, &damaged).unwrap();
        for skip_bad in [false, true] {
            let mut args = vec![Path::new("build"), &input, Path::new("-o"), &output];
            if skip_bad {
                args.push(Path::new("--skip-bad"));
            }
            let run = froctomap_bounded(&args);
            let stderr = String::from_utf8_lossy(&run.stderr);
            let case = format!("record {index} at byte {at}, skip_bad {skip_bad}: {stderr}");
            assert_eq!(run.status.code(), Some(1), "{case}");
            assert!(stderr.contains("zero-header.bag"), "{case}");
            assert!(!stderr.contains("no input files"), "{case}");
            if index > 1 {
                // The records after the chunk: index data, then the index.
                assert!(
                    stderr.contains(&format!("the record at byte {at} has no `op` field")),
                    "{case}"
                );
            }
            assert!(!output.exists(), "{case}");
        }
    }
}

/// `froctomap export golden-v1.2.froct --from 1700000000 --to TO --every EVERY [more…] -o
/// output`, `args` being `[TO, EVERY, more…]`.
fn export_golden(output: &Path, args: &[&str]) -> Output {
    let file = fixture("froct/golden-v1.2.froct");
    let mut all: Vec<&Path> = vec![Path::new("export"), &file, Path::new("--from")];
    all.push(Path::new("1700000000"));
    all.push(Path::new("--to"));
    all.push(Path::new(args[0]));
    all.push(Path::new("--every"));
    all.extend(args[1..].iter().map(Path::new));
    all.extend([Path::new("-o"), output]);
    froctomap_bounded(&all)
}

#[test]
fn export_refuses_sqlite3_bags_and_sizes_beyond_max_output_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    // A sqlite3 ROS 2 bag is read, not written.
    let output = dir.path().join("x.db3");
    let run = export_golden(&output, &["1700003600", "10min"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("does not write sqlite3 ROS 2 bags"),
        "{stderr}"
    );
    assert!(!output.exists());
    // A year every minute: refused with the count and the size, nothing written.
    let output = dir.path().join("year.mcap");
    let run = export_golden(&output, &["1731536000", "1min", "--max-output", "1MiB"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("525,601 maps") && stderr.contains("--max-output"),
        "{stderr}"
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// `export -o -` writes one recording file to standard output; a directory export (maps, a
/// ROS 2 bag) is refused there before anything is made (it used to make a directory `-`).
#[test]
fn export_of_a_directory_to_standard_output_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let export_to_stdout = |format: Option<&str>| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_froctomap"));
        command
            .current_dir(dir.path())
            .arg("export")
            .arg(fixture("froct/golden-v1.2.froct"))
            .args([
                "--from",
                "1700000000",
                "--to",
                "1700003600",
                "--every",
                "10min",
            ]);
        if let Some(format) = format {
            command.arg("--format").args(format.split(' '));
        }
        command.args(["-o", "-"]).output().unwrap()
    };
    for format in [None, Some("ros2bag")] {
        let run = export_to_stdout(format);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{format:?}: {stderr}");
        assert!(
            stderr.contains("-: a ") && stderr.contains("export is a directory"),
            "{format:?}: {stderr}"
        );
        assert!(run.stdout.is_empty(), "{format:?}");
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            0,
            "{format:?}"
        );
    }
    // One MCAP file goes there.
    let run = export_to_stdout(Some("mcap"));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(run.stdout.starts_with(b"\x89MCAP0\r\n"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // With --json the report is the whole of standard error (the map has standard output).
    let run = export_to_stdout(Some("mcap --json"));
    assert!(run.stdout.starts_with(b"\x89MCAP0\r\n"));
    let report: serde_json::Value = serde_json::from_slice(&run.stderr)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&run.stderr)));
    assert_eq!(report["format"], "mcap");
    assert_eq!(report["maps"].as_array().map(Vec::len), Some(7));
}

/// `export --format ros2bag` makes a new bag directory: one that exists (even empty) is
/// refused and left as it was, nothing made beside it; a bag directory that holds a file of a
/// name the export would write is refused too; a refused profile leaves nothing. A directory
/// named `OUT/` without `--format ros2bag` is a directory of `.bt` maps, never a bag.
#[test]
fn export_to_a_ros2_bag_directory_refuses_an_existing_target_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let export = |output: &Path, extra: &[&str]| {
        let mut args = vec!["1700003600", "20min"];
        args.extend(extra);
        export_golden(output, &args)
    };
    let listing = |path: &Path| {
        let mut names: Vec<String> = std::fs::read_dir(path)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        names
    };
    // An empty directory: refused, still empty, nothing beside it.
    let empty = dir.path().join("empty_bag");
    std::fs::create_dir(&empty).unwrap();
    // A directory holding what a bag holds (a previous export): refused, untouched.
    let previous = dir.path().join("previous_bag");
    std::fs::create_dir(&previous).unwrap();
    std::fs::write(previous.join("metadata.yaml"), b"kept").unwrap();
    // A file where the bag would go.
    let taken = dir.path().join("taken_bag");
    std::fs::write(&taken, b"kept").unwrap();
    for target in [&empty, &previous, &taken] {
        let run = export(target, &["--format", "ros2bag"]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains(&format!("{}: it already exists", target.display())),
            "{stderr}"
        );
    }
    assert!(listing(&empty).is_empty());
    assert_eq!(
        std::fs::read(previous.join("metadata.yaml")).unwrap(),
        b"kept"
    );
    assert_eq!(std::fs::read(&taken).unwrap(), b"kept");
    let before = listing(dir.path());
    assert_eq!(before, ["empty_bag", "previous_bag", "taken_bag"]);

    // Foxglove's JSON messages: refused, naming the option, nothing left.
    let refused = dir.path().join("foxglove_bag");
    let run = export(&refused, &["--format", "ros2bag", "--profile", "foxglove"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("profile \"foxglove\""), "{stderr}");
    assert_eq!(listing(dir.path()), before);

    // The bag made new; the same name given again is refused, the bag unchanged.
    let bag = dir.path().join("maps_bag");
    let run = export(&bag, &["--format", "ros2bag"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(listing(&bag), ["maps_bag_0.mcap", "metadata.yaml"]);
    // Our own commands read it back: `info` lists its topics, `build` makes a file of it.
    let run = froctomap_bounded(&[Path::new("info"), &bag]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(stdout.contains("ros2bag (ROS 2 bag directory)"), "{stdout}");
    assert!(
        stdout.contains("/octomap_binary [octomap_msgs/msg/Octomap, cdr]: 4 message(s)"),
        "{stdout}"
    );
    let built = dir.path().join("built.froct");
    let run = froctomap_bounded(&[Path::new("build"), &bag, Path::new("-o"), &built]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(built.is_file());
    std::fs::remove_file(&built).unwrap();
    let metadata = std::fs::read(bag.join("metadata.yaml")).unwrap();
    let run = export(&bag, &["--format", "ros2bag"]);
    assert_eq!(run.status.code(), Some(1));
    assert_eq!(std::fs::read(bag.join("metadata.yaml")).unwrap(), metadata);
    assert_eq!(listing(&bag), ["maps_bag_0.mcap", "metadata.yaml"]);

    // `-o maps/` alone: a directory of .bt maps and their manifest, not a bag.
    let maps = dir.path().join("maps");
    let run = export(&maps, &[]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(listing(&maps).contains(&"manifest.csv".to_string()));
    assert!(!maps.join("metadata.yaml").exists());
}

/// Issue 29, item 3: a map whose build needs more memory than allowed ends in an error
/// naming --max-memory (here a map of 2^15 leaves at --tile-depth 1 under a bound below what
/// the command needs just to start), never an allocation failure; nothing is written.
#[test]
fn a_build_past_max_memory_is_an_error_naming_the_limit() {
    use froctomap_core::{Leaf, Snapshot, VoxelKey};
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps");
    std::fs::create_dir(&maps).unwrap();
    let registry = froctomap_formats::FormatRegistry::with_default_formats();
    for (i, time) in [1_451_865_600u32, 1_451_866_200].into_iter().enumerate() {
        let leaves = (0..1u16 << 15)
            .map(|k| {
                let (x, y, z) = (k & 31, (k >> 5) & 31, k >> 10);
                let occupied = (k as usize + i) % 3 == 0;
                Leaf::voxel(
                    VoxelKey::new(32768 + 2 * x, 32768 + 2 * y, 32768 + 2 * z),
                    if occupied { 3.5 } else { -2.0 },
                )
            })
            .collect();
        let map = Snapshot::from_leaves(0.1, leaves).unwrap();
        registry
            .write_file(&map, &maps.join(format!("m_{time}.bt")), Default::default())
            .unwrap();
    }
    let output = dir.path().join("out.froct");
    let run = froctomap_bounded(&[
        Path::new("build"),
        &maps,
        Path::new("--tile-depth"),
        Path::new("1"),
        Path::new("--max-memory"),
        Path::new("1MiB"),
        Path::new("-o"),
        &output,
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("--max-memory 1 MiB"), "{stderr}");
    assert!(!output.exists());
    // Within a sufficient bound the same build succeeds.
    let run = froctomap_bounded(&[
        Path::new("-q"),
        Path::new("build"),
        &maps,
        Path::new("--tile-depth"),
        Path::new("1"),
        Path::new("--max-memory"),
        Path::new("3GiB"),
        Path::new("-o"),
        &output,
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(output.exists());
}

/// A legal `.bt` (OctoMap's binary layout: two bytes of child bits per inner node, depth
/// first) whose `full` first levels are complete, whose next level has two inner children
/// per node, each with eight leaves, alternately occupied and free: 2^(3·full+4) leaves.
fn wide_bt(full: u32) -> Vec<u8> {
    let mut subtree = [0x0f, 0x00].to_vec();
    subtree.extend([0x66u8; 4]);
    for _ in 0..full {
        let mut wider = vec![0xff, 0xff];
        for _ in 0..8 {
            wider.extend_from_slice(&subtree);
        }
        subtree = wider;
    }
    let inner: u64 = (0..=full).map(|d| 8u64.pow(d)).sum::<u64>() + 2 * 8u64.pow(full);
    let leaves = 16 * 8u64.pow(full);
    let mut bytes = format!(
        "# Octomap OcTree binary file\nid OcTree\nsize {}\nres 0.1\ndata\n",
        inner + leaves
    )
    .into_bytes();
    bytes.extend(subtree);
    bytes
}

/// Issue 29, item 3 in small: a map too wide for the address space (`ulimit -v`) ends in the
/// default `--max-memory`'s error naming the limit and how to raise it, not in an abort.
/// (The map, 2^25 leaves under 4 GB, is measured in docs/LIMITS.md.)
#[test]
fn a_map_too_wide_for_the_address_space_ends_in_the_default_max_memory_error() {
    let dir = tempfile::tempdir().unwrap();
    let map = wide_bt(6); // 2^22 leaves
    std::fs::write(dir.path().join("a.bt"), &map).unwrap();
    std::fs::write(dir.path().join("b.bt"), &map).unwrap();
    let manifest = dir.path().join("m.csv");
    std::fs::write(&manifest, "path,time\na.bt,0\nb.bt,600\n").unwrap();
    let output = dir.path().join("out.froct");
    let run = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 1000000 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_froctomap"))
        .args(["build", "--tile-depth", "1", "-o"])
        .arg(&output)
        .arg(&manifest)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("--max-memory 488 MiB (the default")
            && stderr.contains("--max-memory none"),
        "{stderr}"
    );
    assert!(!output.exists());
}
