//! `froctomap record FILE -`: `froctomap generate --stream` piped into `record` commits a
//! segment every `--commit-every` maps, and every snapshot then retrieves byte-identical to
//! a build of the same maps from their directory; a second, overlapping stream skips the
//! maps the file has; SIGTERM commits what was received and exits 0; a cut stream commits
//! what came before and fails naming where it stopped.
#![cfg(unix)]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use common::{ok, retrieves_as, s, samples, temporaries};
use serde_json::Value;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

const CREATED: &str = "2020-01-01T00:00:00Z";
/// Six maps, every 30 min; `LONGER` holds the same six and three more.
const SERIES: [&str; 6] = ["--days", "0.125", "--step", "30min", "--seed", "5"];
const LONGER: [&str; 6] = ["--days", "0.1875", "--step", "30min", "--seed", "5"];

fn froctomap() -> Command {
    Command::new(env!("CARGO_BIN_EXE_froctomap"))
}

/// The series generated into `dir/name` and built from there: (maps, file).
fn built(dir: &Path, name: &str, series: &[&str]) -> (PathBuf, PathBuf) {
    let maps = dir.join(name);
    let mut args = vec!["-q", "generate", "-o", s(&maps)];
    args.extend(series);
    ok(&args);
    let file = dir.join(format!("{name}.froct"));
    ok(&[
        "-q",
        "build",
        s(&maps),
        "--created",
        CREATED,
        "-o",
        s(&file),
    ]);
    (maps, file)
}

/// A file built from the first map of `maps` only, for `record` to add to.
fn first_map_only(maps: &Path, file: &Path) {
    let manifest = std::fs::read_to_string(maps.join("manifest.csv")).unwrap();
    let first: Vec<&str> = manifest.lines().take(2).collect();
    let csv = maps.join("first.csv");
    std::fs::write(&csv, first.join("\n") + "\n").unwrap();
    ok(&["-q", "build", s(&csv), "--created", CREATED, "-o", s(file)]);
}

/// `generate --stream` of `series`, whole.
fn stream(series: &[&str]) -> Vec<u8> {
    common::generated_stream(series)
}

/// `generate --stream SERIES | record FILE - ARGS`, both processes spawned and piped.
fn record_piped(series: &[&str], file: &Path, args: &[&str]) -> Output {
    let mut generator = froctomap()
        .args(["generate", "--stream"])
        .args(series)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let output = froctomap()
        .args(["record", s(file), "-", "--no-compact"])
        .args(args)
        .stdin(Stdio::from(generator.stdout.take().unwrap()))
        .output()
        .unwrap();
    assert!(generator.wait().unwrap().success());
    output
}

/// `record FILE - ARGS`, its standard streams piped.
fn spawn_record(file: &Path, args: &[&str]) -> Child {
    froctomap()
        .args(["record", s(file), "-", "--no-compact"])
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The samples of each segment of a 2.0 file (`info --json`).
fn segments(file: &Path) -> Vec<u64> {
    let info: Value = serde_json::from_str(&ok(&["info", s(file), "--json"])).unwrap();
    info["living"]["segments"]
        .as_array()
        .unwrap()
        .iter()
        .map(|segment| segment["samples"].as_u64().unwrap())
        .collect()
}

/// Snapshots `0..count` of `file` retrieve byte-identical to those of `expected`.
fn same_snapshots(file: &Path, expected: &Path, count: u64) {
    let dir = file.parent().unwrap();
    for i in 0..count {
        let time = format!("index:{i}");
        let got = dir.join(format!("got-{i}.bt"));
        let want = dir.join(format!("want-{i}.bt"));
        ok(&["-q", "retrieve", s(file), "--time", &time, "-o", s(&got)]);
        ok(&[
            "-q",
            "retrieve",
            s(expected),
            "--time",
            &time,
            "-o",
            s(&want),
        ]);
        assert!(
            std::fs::read(&got).unwrap() == std::fs::read(&want).unwrap(),
            "snapshot {i} of {} differs from the directory build's",
            file.display()
        );
    }
}

/// The commit lines `record` printed.
fn commit_lines(stdout: &str) -> Vec<&str> {
    stdout
        .lines()
        .filter(|line| line.starts_with("segment "))
        .collect()
}

#[test]
fn a_streamed_series_records_segment_by_segment_and_retrieves_as_its_directory_builds() {
    let dir = tempfile::tempdir().unwrap();
    let (maps, whole) = built(dir.path(), "maps", &SERIES);
    let file = dir.path().join("recorded.froct");
    first_map_only(&maps, &file);

    // The 1.2 file is converted; its first map comes again and is skipped.
    let output = record_piped(&SERIES, &file, &["--commit-every", "3"]);
    let (stdout, stderr) = (text(&output.stdout), text(&output.stderr));
    assert!(output.status.success(), "record: {stderr}");
    assert!(stderr.contains("converting"), "{stderr}");
    assert!(
        stderr.contains(
            "recorded 5 maps in 2 segment(s); 1 not later than the last one taken were skipped"
        ),
        "{stderr}"
    );
    let commits = commit_lines(&stdout);
    assert_eq!(commits.len(), 2, "{stdout}");
    assert!(
        commits[0]
            .starts_with("segment 1: 3 maps, 2016-01-04T00:30:00Z .. 2016-01-04T01:30:00Z, +"),
        "{stdout}"
    );
    assert!(
        commits[1]
            .starts_with("segment 2: 2 maps, 2016-01-04T02:00:00Z .. 2016-01-04T02:30:00Z, +"),
        "{stdout}"
    );
    assert_eq!(segments(&file), [3, 2]);
    same_snapshots(&file, &whole, 6);
    // The segments store what differs from the base's predictions (patch tiles).
    let reader = froctomap_file::LivingReader::open(&file).unwrap();
    let patches = (0..reader.segment_count())
        .flat_map(|k| (0..reader.segment_tiles(k).len()).map(move |t| (k, t)))
        .filter(|&(k, t)| reader.is_patch_tile(k, t))
        .count();
    assert!(patches > 0, "no patch tile");
    assert_eq!(temporaries(dir.path()), Vec::<String>::new());

    // A longer stream overlapping it: its first six maps are skipped, the rest committed.
    let (_, longer) = built(dir.path(), "longer", &LONGER);
    let output = record_piped(&LONGER, &file, &["--commit-every", "10"]);
    let stderr = text(&output.stderr);
    assert!(output.status.success(), "record: {stderr}");
    assert!(
        stderr.contains(
            "recorded 3 maps in 1 segment(s); 6 not later than the last one taken were skipped"
        ),
        "{stderr}"
    );
    assert_eq!(segments(&file), [3, 2, 3]);
    same_snapshots(&file, &longer, 9);
}

/// The maps `record -v` said it took (`received TIME: taken`), as their times.
fn taken_lines(stdout: &str) -> Vec<&str> {
    stdout
        .lines()
        .filter_map(|line| line.strip_prefix("received ")?.strip_suffix(": taken"))
        .collect()
}

/// SIGTERM with maps received and no commit due (`--commit-every` far away): the signal's
/// commit is the only one, and it holds exactly the maps `-v` said were taken.
#[test]
fn sigterm_commits_the_maps_received_and_exits_0() {
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps");
    let mut args = vec!["-q", "generate", "-o", s(&maps)];
    args.extend(SERIES);
    ok(&args);
    let (_, inputs) = manifest_of(&maps, "all.csv", 0..6);
    let file = dir.path().join("recorded.froct");
    first_map_only(&maps, &file);
    let bytes = stream(&SERIES);
    let mut child = spawn_record(&file, &["--commit-every", "1000", "-v"]);
    // A producer that has not finished: all but the stream's end, stdin kept open.
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(&bytes[..bytes.len() - 64]).unwrap();
    stdin.flush().unwrap();
    // Waits for the first map (the file's own: older) and four more to be received.
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut received = String::new();
    while received.lines().count() < 5 {
        let mut line = String::new();
        assert!(stdout.read_line(&mut line).unwrap() > 0, "{received}");
        assert!(line.starts_with("received "), "{line}");
        received.push_str(&line);
    }
    assert!(
        received.starts_with("received 2016-01-04T00:00:00Z: older\n"),
        "{received}"
    );
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stdout, &mut rest).unwrap();
    let output = child.wait_with_output().unwrap();
    drop(stdin);
    let stderr = text(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("stopped by a signal"), "{stderr}");
    let printed = received + &rest;
    let taken = taken_lines(&printed);
    assert!((4..=5).contains(&taken.len()), "{printed}");
    // One commit, the signal's, of every map taken, and nothing else.
    assert_eq!(commit_lines(&printed).len(), 1, "{printed}");
    assert_eq!(segments(&file), [taken.len() as u64], "{printed}");
    assert_eq!(samples(&file), 1 + taken.len() as u64);
    for (i, time) in taken.iter().enumerate() {
        assert!(
            inputs[i + 1]
                .to_str()
                .unwrap()
                .contains(&time.replace([':', '-'], "")),
            "{time}"
        );
    }
    for (i, input) in inputs.iter().take(1 + taken.len()).enumerate() {
        retrieves_as(&file, i, input);
    }
    assert_eq!(temporaries(dir.path()), Vec::<String>::new());
}

#[test]
fn a_cut_stream_commits_what_came_before_and_fails_naming_where_it_stopped() {
    let dir = tempfile::tempdir().unwrap();
    let (maps, whole) = built(dir.path(), "maps", &SERIES);
    let file = dir.path().join("recorded.froct");
    first_map_only(&maps, &file);
    let bytes = stream(&SERIES);
    // Cut inside the fourth map's chunk (each map is a chunk of about the same size).
    let cut = &bytes[..bytes.len() * 7 / 12];
    let mut child = spawn_record(&file, &["--commit-every", "100"]);
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(cut).unwrap();
    drop(stdin);
    let output = child.wait_with_output().unwrap();
    let (stdout, stderr) = (text(&output.stdout), text(&output.stderr));
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("record stopped: the stream does not read on"),
        "{stderr}"
    );
    assert!(
        stderr.contains("MCAP stream on standard input: does not read after "),
        "{stderr}"
    );
    // The maps before the cut, committed as one segment (the first map skipped).
    let commits = commit_lines(&stdout);
    assert_eq!(commits.len(), 1, "{stdout}");
    let committed = segments(&file);
    assert_eq!(committed.len(), 1);
    assert!((1..5).contains(&committed[0]), "{committed:?}");
    same_snapshots(&file, &whole, 1 + committed[0]);
    assert_eq!(temporaries(dir.path()), Vec::<String>::new());
}

#[test]
fn a_file_whose_model_cannot_grow_is_refused_and_left_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps");
    let mut args = vec!["-q", "generate", "-o", s(&maps)];
    args.extend(SERIES);
    ok(&args);
    let file = dir.path().join("regular.froct");
    let manifest = std::fs::read_to_string(maps.join("manifest.csv")).unwrap();
    let first: Vec<&str> = manifest.lines().take(3).collect();
    let csv = maps.join("first.csv");
    std::fs::write(&csv, first.join("\n") + "\n").unwrap();
    ok(&[
        "-q",
        "build",
        s(&csv),
        "--model",
        "fremen-regular",
        "--created",
        CREATED,
        "-o",
        s(&file),
    ]);
    let before = std::fs::read(&file).unwrap();
    let error = common::err(&["record", s(&file), s(&maps)]);
    assert!(
        error.contains("its model `fremen-regular` cannot grow by segments"),
        "{error}"
    );
    // Not converted to 2.0 either.
    assert!(std::fs::read(&file).unwrap() == before);
}

/// Sources other than a stream: a directory, read in time order, committed as a stream is.
#[test]
fn a_directory_records_as_a_stream_does() {
    let dir = tempfile::tempdir().unwrap();
    let (maps, whole) = built(dir.path(), "maps", &SERIES);
    let file = dir.path().join("recorded.froct");
    first_map_only(&maps, &file);
    let stdout = ok(&[
        "record",
        s(&file),
        s(&maps),
        "--commit-every",
        "2",
        "--no-compact",
    ]);
    assert_eq!(commit_lines(&stdout).len(), 3, "{stdout}");
    assert_eq!(segments(&file), [2, 2, 1]);
    same_snapshots(&file, &whole, 6);
}

/// The maps of `maps` (its manifest) as an MCAP stream, the `bad`-th (from 0) cut short.
fn stream_with_a_bad_map(maps: &Path, bad: usize) -> Vec<u8> {
    let manifest = std::fs::read_to_string(maps.join("manifest.csv")).unwrap();
    let mut stream = froctomap_ros::McapMapStream::new(Vec::new()).unwrap();
    for (i, row) in manifest.lines().skip(1).enumerate() {
        let (name, time) = row.split_once(',').unwrap();
        let mut bt = std::fs::read(maps.join(name)).unwrap();
        if i == bad {
            bt.truncate(bt.len() * 3 / 5);
        }
        let time = froctomap_core::Timestamp::from_secs(time.parse().unwrap());
        stream.write_map(time, &bt).unwrap();
    }
    stream.finish().unwrap()
}

/// `record FILE - ARGS` reading `bytes`.
fn record_bytes(file: &Path, bytes: &[u8], args: &[&str]) -> Output {
    let mut child = spawn_record(file, args);
    let mut stdin = child.stdin.take().unwrap();
    // It may stop reading early: a broken pipe is then expected.
    let _ = stdin.write_all(bytes);
    drop(stdin);
    child.wait_with_output().unwrap()
}

#[test]
fn a_bad_map_stops_record_after_what_came_before_or_is_skipped_with_skip_bad() {
    let dir = tempfile::tempdir().unwrap();
    let (maps, whole) = built(dir.path(), "maps", &SERIES);
    // The fourth map (sample 3) does not read.
    let bytes = stream_with_a_bad_map(&maps, 3);

    let stopped = dir.path().join("stopped.froct");
    first_map_only(&maps, &stopped);
    let output = record_bytes(&stopped, &bytes, &["--commit-every", "100"]);
    let stderr = text(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    // Messages count from 1: the fourth message of the stream.
    assert!(
        stderr.contains("record stopped at map message 4 of the stream (byte "),
        "{stderr}"
    );
    assert!(stderr.contains("2016-01-04T01:30:00Z"), "{stderr}");
    assert_eq!(segments(&stopped), [2]);
    same_snapshots(&stopped, &whole, 3);

    let skipped = dir.path().join("skipped.froct");
    first_map_only(&maps, &skipped);
    let output = record_bytes(&skipped, &bytes, &["--commit-every", "100", "--skip-bad"]);
    let stderr = text(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: left out map message 4 of the stream (byte "),
        "{stderr}"
    );
    assert!(
        stderr.contains("recorded 4 maps in 1 segment(s); 1 not later than the last one taken were skipped, 1 bad map(s) left out"),
        "{stderr}"
    );
    // The segment's regular axis keeps the bad map's time as a missing sample, as a
    // build leaves a skipped file out.
    assert_eq!(segments(&skipped), [5]);
    let info: Value = serde_json::from_str(&ok(&["info", s(&skipped), "--json"])).unwrap();
    assert_eq!(info["time"]["missing"], 1, "{info}");
    same_snapshots(&skipped, &whole, 3);
    let dir = dir.path();
    for (got, want) in [(4, 4), (5, 5)] {
        let (g, w) = (dir.join("g.bt"), dir.join("w.bt"));
        ok(&[
            "-q",
            "retrieve",
            s(&skipped),
            "--time",
            &format!("index:{got}"),
            "-o",
            s(&g),
        ]);
        ok(&[
            "-q",
            "retrieve",
            s(&whole),
            "--time",
            &format!("index:{want}"),
            "-o",
            s(&w),
        ]);
        assert!(
            std::fs::read(&g).unwrap() == std::fs::read(&w).unwrap(),
            "sample {got}"
        );
    }
}

/// Into a file that does not exist: the first commit's maps are built as its base.
#[test]
fn a_missing_file_gets_the_first_commit_as_its_base() {
    let dir = tempfile::tempdir().unwrap();
    let (_, whole) = built(dir.path(), "maps", &SERIES);
    let file = dir.path().join("new.froct");
    let output = record_piped(&SERIES, &file, &["--commit-every", "4"]);
    let (stdout, stderr) = (text(&output.stdout), text(&output.stderr));
    assert!(output.status.success(), "record: {stderr}");
    assert!(
        stdout.starts_with("base: 4 maps, 2016-01-04T00:00:00Z .. 2016-01-04T01:30:00Z, "),
        "{stdout}"
    );
    assert_eq!(commit_lines(&stdout).len(), 1, "{stdout}");
    assert_eq!(segments(&file), [2]);
    same_snapshots(&file, &whole, 6);
    assert_eq!(temporaries(dir.path()), Vec::<String>::new());

    // --tile-depth: a new file's tiles; an existing file keeps its own, and says so.
    let small = dir.path().join("small-tiles.froct");
    let output = record_piped(
        &SERIES,
        &small,
        &["--commit-every", "4", "--tile-depth", "12"],
    );
    assert!(output.status.success(), "record: {}", text(&output.stderr));
    let depth = |file: &Path| -> Value {
        serde_json::from_str::<Value>(&ok(&["info", s(file), "--json"])).unwrap()["tile_depth"]
            .clone()
    };
    assert_eq!(depth(&small), 12);
    same_snapshots(&small, &whole, 6);
    let output = record_piped(&LONGER, &small, &["--tile-depth", "11"]);
    let stderr = text(&output.stderr);
    assert!(output.status.success(), "record: {stderr}");
    assert!(
        stderr.contains("keeps its tiles of depth 12: --tile-depth 11 is for a new file"),
        "{stderr}"
    );
    assert_eq!(depth(&small), 12);
}

/// Snapshots of `file` at `times` (instants or `index:N`) retrieve byte-identical to those of
/// `expected` at `expected_times`.
fn same_at(file: &Path, times: &[&str], expected: &Path, expected_times: &[&str]) {
    let dir = file.parent().unwrap();
    for (i, (time, expected_time)) in times.iter().zip(expected_times).enumerate() {
        let got = dir.join(format!("got-at-{i}.bt"));
        let want = dir.join(format!("want-at-{i}.bt"));
        ok(&["-q", "retrieve", s(file), "--time", time, "-o", s(&got)]);
        ok(&[
            "-q",
            "retrieve",
            s(expected),
            "--time",
            expected_time,
            "-o",
            s(&want),
        ]);
        assert!(
            std::fs::read(&got).unwrap() == std::fs::read(&want).unwrap(),
            "{} at {time} differs from {} at {expected_time}",
            file.display(),
            expected.display()
        );
    }
}

#[test]
fn a_map_of_another_resolution_commits_the_maps_before_it_and_stops_or_is_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let (maps, whole) = built(dir.path(), "maps", &SERIES);
    // The series again, its fourth map (01:30) saying another resolution in its header.
    let mixed = dir.path().join("mixed");
    std::fs::create_dir(&mixed).unwrap();
    for entry in std::fs::read_dir(&maps).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, mixed.join(path.file_name().unwrap())).unwrap();
    }
    let bad = mixed.join("frame_20160104T013000Z.bt");
    let bytes = std::fs::read(&bad).unwrap();
    let header = b"res 0.08\n";
    let at = bytes
        .windows(header.len())
        .position(|w| w == header)
        .unwrap();
    let mut other = bytes[..at].to_vec();
    other.extend_from_slice(b"res 0.16\n");
    other.extend_from_slice(&bytes[at + header.len()..]);
    std::fs::write(&bad, other).unwrap();

    // Without --skip-bad: one commit of five maps fails; the two before the bad map are
    // committed, and record fails naming it.
    let file = dir.path().join("recorded.froct");
    first_map_only(&maps, &file);
    let output = froctomap()
        .args(["record", s(&file), s(&mixed), "--commit-every", "100"])
        .arg("--no-compact")
        .output()
        .unwrap();
    let stderr = text(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(stderr.contains("frame_20160104T013000Z.bt"), "{stderr}");
    assert!(stderr.contains("resolution 0.16"), "{stderr}");
    // The halves are said, with the error of the whole.
    assert!(
        stderr.contains("warning: a commit of 5 maps failed, trying its halves: committing 5 maps"),
        "{stderr}"
    );
    assert_eq!(samples(&file), 3);
    same_snapshots(&file, &whole, 3);

    // With it: every good map is committed, the bad one left out.
    let skipping = dir.path().join("skipping.froct");
    first_map_only(&maps, &skipping);
    let output = froctomap()
        .args(["record", s(&skipping), s(&mixed), "--commit-every", "100"])
        .arg("--no-compact")
        .arg("--skip-bad")
        .output()
        .unwrap();
    let stderr = text(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("recorded 4 maps"), "{stderr}");
    let good = [
        "2016-01-04T00:00:00Z",
        "2016-01-04T00:30:00Z",
        "2016-01-04T01:00:00Z",
        "2016-01-04T02:00:00Z",
        "2016-01-04T02:30:00Z",
    ];
    same_at(&skipping, &good, &whole, &good);
    assert_eq!(temporaries(dir.path()), Vec::<String>::new());
}

/// A manifest in `maps` of its maps `range` (0-based, in time order): (path, its maps' files).
fn manifest_of(maps: &Path, name: &str, range: std::ops::Range<usize>) -> (PathBuf, Vec<PathBuf>) {
    let manifest = std::fs::read_to_string(maps.join("manifest.csv")).unwrap();
    let mut lines = manifest.lines();
    let header = lines.next().unwrap();
    let rows: Vec<&str> = lines.skip(range.start).take(range.len()).collect();
    let csv = maps.join(name);
    std::fs::write(&csv, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
    let files = rows
        .iter()
        .map(|row| maps.join(row.split(',').next().unwrap()))
        .collect();
    (csv, files)
}

fn size(file: &Path) -> u64 {
    std::fs::metadata(file).unwrap().len()
}

/// Recorded one map per `record` run, each run a commit: after every run the file is at
/// most 1.5× a `build` of the maps so far, and every snapshot retrieves byte-identical to
/// its generated map (automatic compaction, the default). The same runs without it
/// (`--no-compact`) pass that bound too on this series: segments store only what differs
/// from the base's predictions (patch tiles, FORMAT.md §10.6, §10.7), not every cell their
/// maps saw.
#[test]
fn automatic_compaction_keeps_a_recorded_file_within_1_5_times_its_build() {
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps");
    let mut args = vec!["-q", "generate", "-o", s(&maps)];
    args.extend(LONGER);
    ok(&args);
    let (_, inputs) = manifest_of(&maps, "all.csv", 0..9);
    let compacted = dir.path().join("compacted.froct");
    let segmented = dir.path().join("segmented.froct");
    let (mut compactions, mut worst_segmented) = (0, 0.0_f64);
    for (k, input) in inputs.iter().enumerate() {
        let (one, _) = manifest_of(&maps, &format!("one-{k}.csv"), k..k + 1);
        let (prefix, _) = manifest_of(&maps, &format!("prefix-{k}.csv"), 0..k + 1);
        let built = dir.path().join(format!("built-{k}.froct"));
        ok(&["-q", "build", s(&prefix), "-o", s(&built)]);
        // Automatic compaction is the default.
        let stdout = ok(&["record", s(&compacted), s(&one), "--commit-every", "1"]);
        compactions += stdout.matches("compacted: ").count();
        ok(&[
            "record",
            s(&segmented),
            s(&one),
            "--commit-every",
            "1",
            "--no-compact",
        ]);
        let ratio = size(&compacted) as f64 / size(&built) as f64;
        assert!(
            ratio <= 1.5,
            "after map {k}: {} bytes, {ratio:.3}× the build's {} ({stdout})",
            size(&compacted),
            size(&built)
        );
        worst_segmented = worst_segmented.max(size(&segmented) as f64 / size(&built) as f64);
        retrieves_as(&compacted, k, input);
        std::fs::remove_file(built).unwrap();
    }
    assert!(compactions > 0);
    // Before any compaction too, map by map: segments store what differs from the base
    // (patch tiles), not every cell their maps observed.
    assert!(worst_segmented <= 1.5, "{worst_segmented}");
    for (i, input) in inputs.iter().enumerate() {
        retrieves_as(&compacted, i, input);
        retrieves_as(&segmented, i, input);
    }
    assert_eq!(samples(&compacted), 9);
    assert_eq!(temporaries(dir.path()), Vec::<String>::new());
}

/// `--compact-in-background`: maps keep being committed while the file is compacted on a
/// thread of its own; the compaction's result gets the maps committed meanwhile and then
/// replaces the file, which retrieves every snapshot as a build of the same maps does and
/// compacts to that build's tiles; nothing is left beside it.
#[test]
fn a_background_compaction_adds_the_maps_committed_meanwhile() {
    let dir = tempfile::tempdir().unwrap();
    let (_, whole) = built(dir.path(), "maps", &LONGER);
    let file = dir.path().join("recorded.froct");
    let output = froctomap()
        .args(["record", s(&file), "-", "--commit-every", "1"])
        .arg("--compact-in-background")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .and_then(|mut child| {
            child.stdin.take().unwrap().write_all(&stream(&LONGER))?;
            child.wait_with_output()
        })
        .unwrap();
    let (stdout, stderr) = (text(&output.stdout), text(&output.stderr));
    assert!(output.status.success(), "record: {stderr}");
    assert_eq!(commit_lines(&stdout).len(), 8, "{stdout}");
    // A compaction starts after the commit that makes it due and is swapped in at the first
    // commit after it is done, or at the end: the first is due before the last commit, so
    // its result took at least that commit's map.
    let meanwhile: Vec<usize> = stdout
        .lines()
        .filter(|line| line.starts_with("compacted: "))
        .map(|line| {
            let (_, added) = line
                .split_once("in the background (")
                .unwrap_or_else(|| panic!("not a background compaction: {line}"));
            added.split(' ').next().unwrap().parse().unwrap()
        })
        .collect();
    assert!(meanwhile.iter().any(|&maps| maps > 0), "{stdout}");
    assert_eq!(samples(&file), 9);
    same_snapshots(&file, &whole, 9);
    // Compacted once more, it holds the build's tiles, byte for byte.
    let compacted = dir.path().join("compacted.froct");
    ok(&["-q", "compact", s(&file), "-o", s(&compacted)]);
    let tiles = |path: &Path, reader: &froctomap_file::FroctReader| {
        let bytes = std::fs::read(path).unwrap();
        let (first, last) = (&reader.tiles()[0], reader.tiles().last().unwrap());
        bytes[first.offset as usize..(last.offset + u64::from(last.stored_len)) as usize].to_vec()
    };
    let living = froctomap_file::LivingReader::open(&compacted).unwrap();
    let build = froctomap_file::FroctReader::open(&whole).unwrap();
    assert!(
        tiles(&compacted, living.base()) == tiles(&whole, &build),
        "the compacted recording's tiles differ from the build's"
    );
    assert_eq!(temporaries(dir.path()), Vec::<String>::new());
}
