//! `-` as an input: an MCAP stream on standard input. The same generated maps as a directory
//! of .bt files, a ROS 1 bag and an MCAP file (both written by PyPI rosbags and
//! mcap-ros2-support), an MCAP stream piped from mcap-ros2-support's writer and one piped
//! from `froctomap generate --stream` all build files identical apart from their metadata;
//! cut and garbage streams are errors naming where they stopped, leaving nothing behind.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use common::{ok, s};
use froctomap_test_support::{octomap_python, scratch, workspace_root};
use serde_json::Value;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

const CREATED: &str = "2020-01-01T00:00:00Z";
/// The generated series (6 snapshots, some partial views).
const SERIES: [&str; 10] = [
    "--days",
    "0.125",
    "--step",
    "30min",
    "--seed",
    "5",
    "--partial",
    "0.3",
    "--noise",
    "0.01",
];

fn froctomap() -> Command {
    Command::new(env!("CARGO_BIN_EXE_froctomap"))
}

/// `froctomap build - -o out` reading `stdin`.
fn build_from(stdin: Stdio, out: &Path) -> Output {
    froctomap()
        .args(["-q", "build", "-", "--created", CREATED, "-o", s(out)])
        .stdin(stdin)
        .output()
        .unwrap()
}

/// `froctomap build - -o out` reading `bytes` on its standard input.
fn build_from_bytes(bytes: &[u8], out: &Path) -> Output {
    let mut child = froctomap()
        .args(["-q", "build", "-", "--created", CREATED, "-o", s(out)])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let bytes = bytes.to_vec();
    // The reader may stop early (garbage): a broken pipe is then expected.
    let feeder = std::thread::spawn(move || {
        let _ = stdin.write_all(&bytes);
    });
    let output = child.wait_with_output().unwrap();
    feeder.join().unwrap();
    output
}

fn succeeded(output: &Output, what: &str) {
    assert!(
        output.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// The maps of the generated directory: (file, Unix seconds) from its manifest.
fn manifest(maps: &Path) -> Vec<(PathBuf, i64)> {
    std::fs::read_to_string(maps.join("manifest.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|line| {
            let (path, time) = line.split_once(',').unwrap();
            (maps.join(path), time.parse().unwrap())
        })
        .collect()
}

/// The Python writers' spec for one recording of `maps` (stamped at their times, logged a
/// second later).
fn recording(kind: &str, path: &str, compression: &str, maps: &[(PathBuf, i64)]) -> String {
    let messages: Vec<String> = maps
        .iter()
        .map(|(map, secs)| {
            let stamp = secs * 1_000_000_000;
            format!(
                "{{\"topic\": \"/octomap_binary\", \"map\": \"{}\", \"stamp_ns\": {stamp}, \"log_ns\": {}}}",
                map.display(),
                stamp + 1_000_000_000
            )
        })
        .collect();
    format!(
        "{{\"kind\": \"{kind}\", \"path\": \"{path}\", \"compression\": \"{compression}\", \"chunk_bytes\": 200000, \"messages\": [{}]}}",
        messages.join(", ")
    )
}

/// Runs the Python writers on `recordings` (spec entries); the child, its standard output
/// piped when a recording goes there.
fn python_writer(dir: &Path, name: &str, recordings: &[String]) -> Command {
    let spec = dir.join(format!("{name}.json"));
    std::fs::write(
        &spec,
        format!("{{\"recordings\": [{}]}}", recordings.join(", ")),
    )
    .unwrap();
    let mut command = Command::new(octomap_python());
    command
        .arg(workspace_root().join("tests/scripts/write_recordings.py"))
        .arg(spec);
    command
}

/// `info --json` without what depends on the inputs' names and bytes (the metadata, the
/// header holding it, and the sizes and ratios that count them).
fn described(file: &Path) -> Value {
    let mut info: Value = serde_json::from_str(&ok(&["info", "--json", s(file)])).unwrap();
    let object = info.as_object_mut().unwrap();
    for key in [
        "file",
        "metadata",
        "input_bytes",
        "ratio_vs_inputs",
        "ratio_vs_raw_states",
    ] {
        object.remove(key);
    }
    let size = object["size"].as_object_mut().unwrap();
    size.remove("file");
    size.remove("header");
    info
}

/// The tiles' bytes (after the header, which holds the metadata).
fn tiles(file: &Path) -> Vec<u8> {
    let info: Value = serde_json::from_str(&ok(&["info", "--json", s(file)])).unwrap();
    let header = info["size"]["header"].as_u64().unwrap() as usize;
    let length = info["size"]["tiles"].as_u64().unwrap() as usize;
    std::fs::read(file).unwrap()[header..header + length].to_vec()
}

/// Asserts that `file` is `expected` apart from metadata: the same description, the same
/// tiles byte for byte, and every snapshot retrieved as the same .bt bytes.
fn same_apart_from_metadata(file: &Path, expected: &Path, snapshots: usize, what: &str) {
    assert_eq!(described(file), described(expected), "{what}");
    assert!(tiles(file) == tiles(expected), "{what}: tiles differ");
    let dir = file.parent().unwrap();
    for i in 0..snapshots {
        let time = format!("index:{i}");
        let [a, b] = [file, expected].map(|f| {
            let out = dir.join(format!(
                "{}-{i}.bt",
                f.file_stem().unwrap().to_str().unwrap()
            ));
            ok(&["retrieve", s(f), "--time", &time, "-o", s(&out)]);
            std::fs::read(out).unwrap()
        });
        assert!(a == b, "{what}: snapshot {i} differs");
    }
}

/// Nothing but the files named is left in `dir` (no spool, no temporary output).
fn only(dir: &Path, names: &[&str]) {
    let mut left: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    let mut expected: Vec<String> = names.iter().map(|n| n.to_string()).collect();
    expected.sort();
    assert_eq!(left, expected);
}

#[test]
fn a_directory_a_bag_an_mcap_file_and_mcap_streams_build_the_same_file() {
    let dir = scratch();
    let maps = dir.path().join("maps");
    let mut generate = vec!["generate", "-o", s(&maps)];
    generate.extend(SERIES);
    ok(&generate);
    let listed = manifest(&maps);
    assert_eq!(listed.len(), 6);
    let built = |name: &str| dir.path().join(name);
    ok(&[
        "-q",
        "build",
        s(&maps),
        "--created",
        CREATED,
        "-o",
        s(&built("dir.froct")),
    ]);
    let bag = built("maps.bag");
    let mcap = built("maps.mcap");
    let status = python_writer(
        dir.path(),
        "files",
        &[
            recording("ros1", s(&bag), "lz4", &listed),
            recording("mcap", s(&mcap), "zstd", &listed),
        ],
    )
    .status()
    .unwrap();
    assert!(status.success());
    for (input, out) in [(&bag, "bag.froct"), (&mcap, "mcap.froct")] {
        ok(&[
            "-q",
            "build",
            s(input),
            "--created",
            CREATED,
            "-o",
            s(&built(out)),
        ]);
    }

    // mcap-ros2-support's writer piped into `build -`.
    let mut writer = python_writer(
        dir.path(),
        "stream",
        &[recording("mcap", "-", "zstd", &listed)],
    )
    .stdout(Stdio::piped())
    .spawn()
    .unwrap();
    let piped = Stdio::from(writer.stdout.take().unwrap());
    let output = build_from(piped, &built("python-stream.froct"));
    assert!(writer.wait().unwrap().success());
    succeeded(&output, "build - from mcap-ros2-support");

    // `froctomap generate --stream` of the same series piped into `build -`.
    let mut generator = froctomap()
        .args(["generate", "--stream"])
        .args(SERIES)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let piped = Stdio::from(generator.stdout.take().unwrap());
    let output = build_from(piped, &built("generated-stream.froct"));
    let generated = generator.wait_with_output().unwrap();
    assert!(generated.status.success());
    let report = String::from_utf8_lossy(&generated.stderr);
    assert!(
        report.contains("streamed 6 snapshots"),
        "the report goes to standard error: {report}"
    );
    succeeded(&output, "build - from generate --stream");

    let expected = built("dir.froct");
    for name in [
        "bag.froct",
        "mcap.froct",
        "python-stream.froct",
        "generated-stream.froct",
    ] {
        same_apart_from_metadata(&built(name), &expected, listed.len(), name);
    }
    // The metadata do differ (the inputs' names): the comparison above did not compare
    // one file with itself.
    assert_ne!(
        std::fs::read(built("python-stream.froct")).unwrap(),
        std::fs::read(&expected).unwrap()
    );
}

#[test]
fn cut_and_garbage_streams_are_errors_naming_where_they_stopped() {
    let dir = scratch();
    let maps = dir.path().join("maps");
    let mut generate = vec!["generate", "-o", s(&maps), "--days", "0.0625"];
    generate.extend(&SERIES[2..]);
    ok(&generate);
    let listed = manifest(&maps);
    let mcap = dir.path().join("whole.mcap");
    let status = python_writer(
        dir.path(),
        "spec",
        &[recording("mcap", s(&mcap), "zstd", &listed)],
    )
    .status()
    .unwrap();
    assert!(status.success());
    let whole = std::fs::read(&mcap).unwrap();
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let out = out_dir.join("f.froct");

    // The writer died mid-stream: cut inside a chunk, and just before the end magic.
    for end in [whole.len() / 2, whole.len() - 8] {
        let output = build_from_bytes(&whole[..end], &out);
        assert_eq!(output.status.code(), Some(1));
        let error = String::from_utf8_lossy(&output.stderr);
        assert!(
            error.contains("MCAP stream on standard input: does not read after ")
                && error.contains(&format!("at byte {end}: ")),
            "cut at {end}: {error}"
        );
        only(&out_dir, &[]);
    }
    // Not MCAP at all, an empty stream, and MCAP's magic followed by garbage.
    for (garbage, expected) in [
        (
            b"# Octomap OcTree binary file\n".to_vec(),
            "-: standard input is not a stream of a format read from streams (mcap); it starts with \"# Octomap OcTree\"",
        ),
        (
            Vec::new(),
            "-: standard input is not a stream of a format read from streams (mcap); it is empty",
        ),
        (
            [&whole[..8], &[0xff; 64][..]].concat(),
            "MCAP stream on standard input: does not read after 0 message(s), at byte 17: record with opcode ff length exceeds limit",
        ),
    ] {
        let output = build_from_bytes(&garbage, &out);
        assert_eq!(output.status.code(), Some(1));
        let error = String::from_utf8_lossy(&output.stderr);
        assert!(error.contains(expected), "{error}");
        only(&out_dir, &[]);
    }
    // The whole stream builds, and leaves only the file.
    succeeded(&build_from_bytes(&whole, &out), "whole stream");
    only(&out_dir, &["f.froct"]);
    // Standard input is read once.
    let error = common::err(&["build", "-", "-", "-o", s(&out)]);
    assert!(error.contains("standard input is read once"), "{error}");
}

/// `append FILE -` takes a stream as `build -` does: appending `generate --stream` of later
/// maps gives the file appending the same maps from their directory gives, apart from the
/// metadata.
#[test]
fn append_takes_a_stream() {
    let dir = scratch();
    let first = dir.path().join("first");
    let later = dir.path().join("later");
    let series = ["--days", "0.0625", "--step", "30min", "--seed", "3"];
    let mut generate = vec!["generate", "-o", s(&first)];
    generate.extend(series);
    ok(&generate);
    let start = ["--start", "2016-01-04T06:00:00Z"];
    let mut generate = vec!["generate", "-o", s(&later)];
    generate.extend(series);
    generate.extend(start);
    ok(&generate);
    let from_dir = dir.path().join("dir.froct");
    ok(&[
        "-q",
        "build",
        s(&first),
        "--created",
        CREATED,
        "-o",
        s(&from_dir),
    ]);
    let from_stream = dir.path().join("stream.froct");
    std::fs::copy(&from_dir, &from_stream).unwrap();
    let appended = "--appended=2020-01-02T00:00:00Z";
    ok(&["-q", "append", s(&from_dir), s(&later), appended]);
    let mut generator = froctomap()
        .args(["generate", "--stream"])
        .args(series)
        .args(start)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let output = froctomap()
        .args(["-q", "append", s(&from_stream), "-", appended])
        .stdin(Stdio::from(generator.stdout.take().unwrap()))
        .output()
        .unwrap();
    assert!(generator.wait().unwrap().success());
    succeeded(&output, "append -");
    let samples = manifest(&first).len() + manifest(&later).len();
    same_apart_from_metadata(&from_stream, &from_dir, samples, "append -");
}

/// `generate --from TIME` writes the very files a run from the start writes at or after
/// TIME (same names, same bytes), and none before: how a long stream resumes.
#[test]
fn a_generated_series_resumed_from_a_time_writes_the_same_maps() {
    let dir = scratch();
    let whole = dir.path().join("whole");
    let mut generate = vec!["generate", "-o", s(&whole)];
    generate.extend(SERIES);
    ok(&generate);
    let maps = manifest(&whole);
    assert!(maps.len() >= 5, "{} maps", maps.len());
    let from = maps[2].1;
    let resumed = dir.path().join("resumed");
    let from_text = from.to_string();
    let mut generate = vec!["generate", "-o", s(&resumed), "--from", &from_text];
    generate.extend(SERIES);
    ok(&generate);
    let later = manifest(&resumed);
    let expected: Vec<&(PathBuf, i64)> = maps.iter().filter(|(_, t)| *t >= from).collect();
    assert_eq!(later.len(), expected.len());
    for ((path, time), (expected_path, expected_time)) in later.iter().zip(expected) {
        assert_eq!(time, expected_time);
        assert_eq!(path.file_name(), expected_path.file_name());
        assert!(
            std::fs::read(path).unwrap() == std::fs::read(expected_path).unwrap(),
            "{} differs",
            path.display()
        );
    }
}
