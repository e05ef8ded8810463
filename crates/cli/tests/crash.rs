//! `kill -9` at seeded random instants of `record` and `append` (format 2.0): the file still
//! opens, holds every commit whose line was printed before the kill, each of its snapshots
//! retrieving byte-identical to the generated map, and once the next write has run no
//! temporary file or directory of froctomap is left beside it.
#![cfg(unix)]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use common::{ok, s, temporaries};
use serde_json::Value;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

/// Nine maps, every 30 min.
const SERIES: [&str; 6] = ["--days", "0.1875", "--step", "30min", "--seed", "5"];
/// Kills per command: few, so that CI stays short.
const RUNS: u64 = 4;
const SEED: u64 = 26;

fn froctomap() -> Command {
    Command::new(env!("CARGO_BIN_EXE_froctomap"))
}

/// A small seeded generator (xorshift64*): the same fractions in every run.
struct Delays(u64);

impl Delays {
    /// A delay in `[0, max)`.
    fn next(&mut self, max: Duration) -> Duration {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let unit = (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64;
        max.mul_f64(unit)
    }
}

/// The generated maps: the directory, its maps' files in time order, and the stream.
struct Series {
    maps: PathBuf,
    inputs: Vec<PathBuf>,
    stream: Vec<u8>,
}

fn series(dir: &Path) -> Series {
    let maps = dir.join("maps");
    let mut args = vec!["-q", "generate", "-o", s(&maps)];
    args.extend(SERIES);
    ok(&args);
    let manifest = std::fs::read_to_string(maps.join("manifest.csv")).unwrap();
    let inputs = manifest
        .lines()
        .skip(1)
        .map(|row| maps.join(row.split(',').next().unwrap()))
        .collect();
    Series {
        maps,
        inputs,
        stream: common::generated_stream(&SERIES),
    }
}

impl Series {
    /// A manifest of maps `range` (0-based).
    fn manifest(&self, name: &str, range: std::ops::Range<usize>) -> PathBuf {
        let manifest = std::fs::read_to_string(self.maps.join("manifest.csv")).unwrap();
        let mut lines = manifest.lines();
        let header = lines.next().unwrap();
        let rows: Vec<&str> = lines.skip(range.start).take(range.len()).collect();
        let csv = self.maps.join(name);
        std::fs::write(&csv, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
        csv
    }
}

/// The file's samples (`info --json`: it opens).
fn samples(file: &Path) -> usize {
    let info: Value = serde_json::from_str(&ok(&["info", s(file), "--json"])).unwrap();
    info["time"]["samples"].as_u64().unwrap() as usize
}

/// Samples `range` of `file` retrieve byte-identical to the generated maps.
fn retrieve_as_generated(file: &Path, range: std::ops::Range<usize>, inputs: &[PathBuf]) {
    for i in range {
        let got = file.with_extension("got.bt");
        let time = format!("index:{i}");
        ok(&["-q", "retrieve", s(file), "--time", &time, "-o", s(&got)]);
        assert!(
            std::fs::read(&got).unwrap() == std::fs::read(&inputs[i]).unwrap(),
            "sample {i} of {} differs from {}",
            file.display(),
            inputs[i].display()
        );
        std::fs::remove_file(got).unwrap();
    }
}

/// How long `froctomap ARGS` takes to the end on this machine now (standard input:
/// `stdin`), so that kills spread over a whole run whatever the load.
fn full_run(args: &[&str], stdin: &[u8]) -> Duration {
    let started = std::time::Instant::now();
    let mut child = froctomap()
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(stdin).unwrap();
    let output = child.wait_with_output().unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    started.elapsed()
}

/// Runs `froctomap ARGS` (standard input: `stdin`, fed from a thread), kills it with
/// SIGKILL after `delay` unless it ended before; what it printed on standard output.
fn killed_after(args: &[&str], stdin: &[u8], delay: Duration) -> String {
    let mut child = froctomap()
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut input = child.stdin.take().unwrap();
    let bytes = stdin.to_vec();
    // Fails with a broken pipe once the process is gone.
    let feeder = std::thread::spawn(move || {
        let _ = input.write_all(&bytes);
    });
    std::thread::sleep(delay);
    let _ = child.kill();
    let output = child.wait_with_output().unwrap();
    feeder.join().unwrap();
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// The maps of the commit lines `record` printed (`base: N maps`, `segment K: N maps`).
fn committed_maps(stdout: &str) -> usize {
    stdout
        .lines()
        .filter(|line| line.starts_with("base: ") || line.starts_with("segment "))
        .map(|line| {
            let maps = line.split(": ").nth(1).unwrap();
            maps.split(' ').next().unwrap().parse::<usize>().unwrap()
        })
        .sum()
}

/// A 2.0 file of the first map, made by `record` (missing file: its base).
fn first_map(series: &Series, file: &Path) {
    let first = series.manifest("first.csv", 0..1);
    ok(&["record", s(file), s(&first), "--commit-every", "1"]);
}

#[test]
fn record_killed_at_random_instants_keeps_every_printed_commit() {
    let dir = tempfile::tempdir().unwrap();
    let series = series(dir.path());
    let mut delays = Delays(SEED);
    let scratch = dir.path().join("scratch.froct");
    first_map(&series, &scratch);
    let whole = full_run(
        &["record", s(&scratch), "-", "--commit-every", "2"],
        &series.stream,
    );
    for run in 0..RUNS {
        let work = dir.path().join(format!("record-{run}"));
        std::fs::create_dir(&work).unwrap();
        let file = work.join("map.froct");
        first_map(&series, &file);
        let delay = delays.next(whole);
        // Runs compact in place (the default), not at all, or in the background while
        // committing, and may be killed compacting.
        let mut args = vec!["record", s(&file), "-", "--commit-every", "2"];
        match run % 3 {
            1 => args.push("--no-compact"),
            2 => args.push("--compact-in-background"),
            _ => {}
        }
        let stdout = killed_after(&args, &series.stream, delay);
        let held = samples(&file);
        let printed = 1 + committed_maps(&stdout);
        assert!(
            (printed..=9).contains(&held),
            "run {run}, killed after {delay:?}: {held} samples, {printed} printed:\n{stdout}"
        );
        eprintln!(
            "record run {run}: killed after {delay:?}, {held} samples held, {printed} printed, left: {:?}",
            temporaries(&work)
        );
        retrieve_as_generated(&file, 0..held, &series.inputs);
        // The next write: the same stream, to its end (the maps held are skipped).
        let mut next = froctomap()
            .args([
                "record",
                s(&file),
                "-",
                "--commit-every",
                "100",
                "--no-compact",
            ])
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        next.stdin
            .take()
            .unwrap()
            .write_all(&series.stream)
            .unwrap();
        let output = next.wait_with_output().unwrap();
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        assert_eq!(temporaries(&work), Vec::<String>::new(), "run {run}");
        assert_eq!(samples(&file), 9);
        retrieve_as_generated(&file, held..9, &series.inputs);
    }
}

#[test]
fn append_killed_at_random_instants_commits_all_or_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let series = series(dir.path());
    let rest = series.manifest("rest.csv", 1..9);
    let mut delays = Delays(SEED + 1);
    let scratch = dir.path().join("scratch.froct");
    first_map(&series, &scratch);
    let whole = full_run(&["append", s(&scratch), s(&rest)], &[]);
    for run in 0..RUNS {
        let work = dir.path().join(format!("append-{run}"));
        std::fs::create_dir(&work).unwrap();
        let file = work.join("map.froct");
        first_map(&series, &file);
        // Some runs end before the kill.
        let delay = delays.next(whole.mul_f64(1.3));
        let stdout = killed_after(&["append", s(&file), s(&rest)], &[], delay);
        let held = samples(&file);
        assert!(
            [1, 9].contains(&held),
            "run {run}: {held} samples:\n{stdout}"
        );
        if stdout.contains("appended 8 snapshots") {
            assert_eq!(held, 9, "run {run}: printed, not held:\n{stdout}");
        }
        eprintln!(
            "append run {run}: killed after {delay:?}, {held} samples held, left: {:?}",
            temporaries(&work)
        );
        retrieve_as_generated(&file, 0..held, &series.inputs);
        // The next write: the rest if it was not committed, else a compaction.
        if held == 1 {
            ok(&["-q", "append", s(&file), s(&rest)]);
        } else {
            ok(&["-q", "compact", s(&file)]);
        }
        assert_eq!(temporaries(&work), Vec::<String>::new(), "run {run}");
        assert_eq!(samples(&file), 9);
        retrieve_as_generated(&file, held..9, &series.inputs);
    }
}
