//! `froctomap record FILE --follow DIR` and ROS 2 bag directories being recorded.
//!
//! * A directory of map files: the files there first, then each one written in place and
//!   closed, or written under a temporary name and renamed into place, while `record`
//!   runs; a file seen half written is neither read nor refused. SIGINT commits and exits
//!   0, and every map retrieves byte-identical to its file.
//! * A ROS 2 bag directory without `metadata.yaml` (as `ros2 bag record` leaves it while
//!   recording), its splits written by PyPI `mcap`/`mcap-ros2-support`: recorded whole, its
//!   splits are read in order and the last one, cut inside a chunk, up to its last complete
//!   chunk; followed, each split's maps are taken as its bytes arrive (a split appearing
//!   cut mid-chunk gives its complete chunks, then the rest once written; one whose writer
//!   died mid-chunk gives its complete chunks once a later split exists), a map of an
//!   overlapping split not later than the last one taken is skipped and counted.
//!
//! Every wait is bounded: a recorder that misbehaves fails the test instead of hanging it.
#![cfg(unix)]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use common::{err, fails, lines, ok, retrieves_as, s, samples, Reap};
use froctomap_test_support::write_recordings;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// Six maps, every 30 min.
const SERIES: [&str; 6] = ["--days", "0.125", "--step", "30min", "--seed", "5"];
const CREATED: &str = "2020-01-01T00:00:00Z";
/// The longest a test waits for one line or for the recorder to end.
const PATIENCE: Duration = Duration::from_secs(120);

/// The generated series' map files (named by their times) in time order, and their times
/// as `record -v` prints them.
fn generated(dir: &Path) -> Vec<(PathBuf, String)> {
    let maps = dir.join("maps");
    let mut args = vec!["-q", "generate", "-o", s(&maps)];
    args.extend(SERIES);
    ok(&args);
    let manifest = std::fs::read_to_string(maps.join("manifest.csv")).unwrap();
    manifest
        .lines()
        .skip(1)
        .map(|row| {
            let (name, unix) = row.split_once(',').unwrap();
            let unix: i64 = unix.trim().parse().unwrap();
            (maps.join(name), iso(unix))
        })
        .collect()
}

/// Unix seconds as `record` prints times (the series starts on 2016-01-04, every 30 min).
fn iso(unix: i64) -> String {
    let since = unix - 1_451_865_600; // 2016-01-04T00:00:00Z
    assert!((0..86_400).contains(&since), "{unix}");
    format!(
        "2016-01-04T{:02}:{:02}:{:02}Z",
        since / 3600,
        since / 60 % 60,
        since % 60
    )
}

fn froctomap() -> Command {
    Command::new(env!("CARGO_BIN_EXE_froctomap"))
}

/// `record FILE ARGS`, its output read line by line on threads.
fn spawn_record(file: &Path, args: &[&str]) -> (Child, Receiver<String>, Receiver<String>) {
    let mut child = froctomap()
        .args(["record", s(file)])
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = lines(child.stdout.take().unwrap());
    let stderr = lines(child.stderr.take().unwrap());
    (child, stdout, stderr)
}

/// The lines up to and including `wanted`, within [`PATIENCE`].
fn until(lines: &Receiver<String>, wanted: &str) -> Vec<String> {
    let mut seen = Vec::new();
    let deadline = Instant::now() + PATIENCE;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match lines.recv_timeout(left) {
            Ok(line) => {
                let done = line == wanted;
                seen.push(line);
                if done {
                    return seen;
                }
            }
            Err(e) => panic!("no line {wanted:?} ({e}); seen: {seen:#?}"),
        }
    }
}

/// Sends SIGINT and waits (bounded) for the recorder to end.
fn interrupt(child: &mut Child) -> ExitStatus {
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let deadline = Instant::now() + PATIENCE;
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        assert!(Instant::now() < deadline, "record did not end after SIGINT");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Everything left on a finished child's stream.
fn rest(lines: &Receiver<String>) -> String {
    let mut text = String::new();
    while let Ok(line) = lines.recv_timeout(PATIENCE) {
        text.push_str(&line);
        text.push('\n');
    }
    text
}

/// The map file `from` copied to `to` the way an editor or a robot writes: under a
/// temporary name in the same directory, then renamed into place.
fn write_and_rename(from: &Path, to: &Path) {
    let temporary = to.with_extension("bt.part");
    std::fs::copy(from, &temporary).unwrap();
    std::fs::rename(&temporary, to).unwrap();
}

#[test]
fn follow_takes_map_files_once_closed_or_renamed_and_sigint_commits_them() {
    let dir = tempfile::tempdir().unwrap();
    let maps = generated(dir.path());
    assert_eq!(maps.len(), 6);
    let name = |i: usize| maps[i].0.file_name().unwrap().to_owned();
    let received = |i: usize, what: &str| format!("received {}: {what}", maps[i].1);
    // The file holds the first map: the directory's copy of it is older.
    let file = dir.path().join("recorded.froct");
    ok(&[
        "-q",
        "build",
        s(&maps[0].0),
        "--created",
        CREATED,
        "-o",
        s(&file),
    ]);
    let live = dir.path().join("live");
    std::fs::create_dir(&live).unwrap();
    for i in [1, 0] {
        std::fs::copy(&maps[i].0, live.join(name(i))).unwrap();
    }
    let (child, stdout, stderr) = spawn_record(
        &file,
        &[
            "--follow",
            s(&live),
            "--commit-every",
            "1000",
            "--no-compact",
            "-v",
        ],
    );
    let mut reap = Reap(vec![child]);
    // The files there first, in time order.
    let seen = until(&stdout, &received(1, "taken"));
    assert_eq!(seen, [received(0, "older"), received(1, "taken")]);
    // Written under a temporary name, then renamed.
    write_and_rename(&maps[2].0, &live.join(name(2)));
    until(&stdout, &received(2, "taken"));
    // Half of map 4 written in place, its file left open; then map 3 renamed into place.
    // Its events come after map 4's, so once map 3 is taken map 4 was seen half written.
    let bytes4 = std::fs::read(&maps[4].0).unwrap();
    let mut open4 = std::fs::File::create(live.join(name(4))).unwrap();
    open4.write_all(&bytes4[..bytes4.len() / 2]).unwrap();
    open4.flush().unwrap();
    write_and_rename(&maps[3].0, &live.join(name(3)));
    let seen = until(&stdout, &received(3, "taken"));
    assert_eq!(seen, [received(3, "taken")], "map 4 was read half written");
    open4.write_all(&bytes4[bytes4.len() / 2..]).unwrap();
    drop(open4);
    let seen = until(&stdout, &received(4, "taken"));
    assert_eq!(seen, [received(4, "taken")]);
    // Written in place and closed at once, as `cp` does.
    std::fs::copy(&maps[5].0, live.join(name(5))).unwrap();
    until(&stdout, &received(5, "taken"));

    let status = interrupt(&mut reap.0[0]);
    let (out, errors) = (rest(&stdout), rest(&stderr));
    assert_eq!(status.code(), Some(0), "{errors}");
    assert!(errors.contains("stopped by a signal"), "{errors}");
    assert!(
        errors.contains(
            "recorded 5 maps in 1 segment(s); 1 not later than the last one taken were skipped"
        ),
        "{errors}"
    );
    assert!(!errors.contains("warning"), "{errors}");
    assert_eq!(
        out.lines().filter(|l| l.starts_with("segment ")).count(),
        1,
        "{out}"
    );
    assert_eq!(samples(&file), 6);
    for (i, (map, _)) in maps.iter().enumerate() {
        retrieves_as(&file, i, map);
    }
}

#[test]
fn follow_refuses_what_is_not_a_directory_before_touching_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("new.froct");
    let missing = dir.path().join("nowhere");
    let error = err(&["record", s(&file), "--follow", s(&missing)]);
    assert!(
        error.contains("--follow")
            && error.contains("nowhere")
            && error.contains("no such directory"),
        "{error}"
    );
    let plain = dir.path().join("map.bt");
    std::fs::write(&plain, b"# Octomap OcTree binary file\n").unwrap();
    let error = err(&["record", s(&file), "--follow", s(&plain)]);
    assert!(error.contains("not a directory"), "{error}");
    assert!(!file.exists());
    // --start/--step give no time to files that are not there yet.
    let error = fails(&[
        "record",
        s(&file),
        "--follow",
        s(dir.path()),
        "--start",
        "0",
        "--step",
        "1s",
    ]);
    assert!(error.contains("--start"), "{error}");
}

/// MCAP files of `maps` (one chunk per message, uncompressed) written by PyPI
/// mcap-ros2-support, one file per list of indices, named `dir/NAME_k.mcap`.
fn write_splits(
    dir: &Path,
    name: &str,
    maps: &[(PathBuf, String)],
    splits: &[&[usize]],
) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir).unwrap();
    let second = 1_000_000_000i64;
    let mut recordings = Vec::new();
    let mut paths = Vec::new();
    for (k, indices) in splits.iter().enumerate() {
        let path = dir.join(format!("{name}_{k}.mcap"));
        let messages: Vec<String> = indices
            .iter()
            .map(|&i| {
                let unix = stamp(&maps[i].0);
                format!(
                    "{{\"topic\": \"/octomap_binary\", \"map\": \"{}\", \"stamp_ns\": {}, \"log_ns\": {}}}",
                    maps[i].0.display(),
                    unix * second,
                    (unix + 1) * second
                )
            })
            .collect();
        recordings.push(format!(
            "{{\"kind\": \"mcap\", \"path\": \"{}\", \"compression\": \"none\", \"chunk_bytes\": 1, \"messages\": [{}]}}",
            path.display(),
            messages.join(", ")
        ));
        paths.push(path);
    }
    let spec = dir.join("spec.json");
    std::fs::write(
        &spec,
        format!("{{\"recordings\": [{}]}}", recordings.join(", ")),
    )
    .unwrap();
    write_recordings(&spec);
    std::fs::remove_file(spec).unwrap();
    paths
}

/// Unix seconds of a generated map from its name (`frame_20160104T013000Z.bt`).
fn stamp(map: &Path) -> i64 {
    let name = map.file_stem().unwrap().to_str().unwrap();
    let clock = name.rsplit('T').next().unwrap();
    let (h, m, s): (i64, i64, i64) = (
        clock[0..2].parse().unwrap(),
        clock[2..4].parse().unwrap(),
        clock[4..6].parse().unwrap(),
    );
    1_451_865_600 + h * 3600 + m * 60 + s
}

/// A byte inside the chunk that holds `map` in `split` (uncompressed: the map's `.bt`
/// body is in it as it is).
fn inside_chunk_of(split: &[u8], map: &Path) -> usize {
    let bt = std::fs::read(map).unwrap();
    let body = &bt[bt.windows(6).position(|w| w == b"\ndata\n").unwrap() + 6..];
    let needle = &body[..256];
    let at = split
        .windows(needle.len())
        .position(|w| w == needle)
        .expect("the map's body in its split");
    at + 128
}

#[test]
fn a_bag_being_recorded_is_read_split_by_split_up_to_its_last_complete_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let maps = generated(dir.path());
    // No metadata.yaml yet: splits 0 and 1, the second cut inside the chunk of map 5.
    let bag = dir.path().join("rosbag2_live");
    let splits = write_splits(&bag, "rosbag2_live", &maps, &[&[0, 1, 2], &[3, 4, 5]]);
    let second = std::fs::read(&splits[1]).unwrap();
    let cut = inside_chunk_of(&second, &maps[5].0);
    std::fs::write(&splits[1], &second[..cut]).unwrap();
    let file = dir.path().join("bag.froct");
    let output = froctomap()
        .args([
            "record",
            s(&file),
            s(&bag),
            "--commit-every",
            "2",
            "--no-compact",
        ])
        .output()
        .unwrap();
    let errors = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{errors}");
    assert!(
        errors.contains("rosbag2_live_1.mcap") && errors.contains("is cut off"),
        "{errors}"
    );
    assert!(errors.contains("recorded 5 maps"), "{errors}");
    assert_eq!(samples(&file), 5);
    for (i, (map, _)) in maps.iter().take(5).enumerate() {
        retrieves_as(&file, i, map);
    }
}

#[test]
fn follow_reads_a_growing_bag_split_by_split_and_skips_overlapping_maps() {
    let dir = tempfile::tempdir().unwrap();
    let maps = generated(dir.path());
    let received = |i: usize, what: &str| format!("received {}: {what}", maps[i].1);
    // Written elsewhere, then put in the bag's directory piece by piece. Split 1 repeats
    // map 2 (an overlapping split).
    let staged = write_splits(
        &dir.path().join("staged"),
        "bag",
        &maps,
        &[&[0, 1, 2], &[2, 3, 4], &[5]],
    );
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    let split = |k: usize| bag.join(format!("bag_{k}.mcap"));
    std::fs::copy(&staged[0], split(0)).unwrap();
    let file = dir.path().join("followed.froct");
    let (child, stdout, stderr) = spawn_record(
        &file,
        &[
            "--follow",
            s(&bag),
            "--commit-every",
            "1000",
            "--no-compact",
            "-v",
        ],
    );
    let mut reap = Reap(vec![child]);
    let seen = until(&stdout, &received(2, "taken"));
    assert_eq!(
        seen,
        [
            received(0, "taken"),
            received(1, "taken"),
            received(2, "taken")
        ]
    );
    // Split 1 appears cut inside the chunk of map 4: maps 2 (older) and 3 are read, map 4
    // once the rest of the split is written.
    let bytes = std::fs::read(&staged[1]).unwrap();
    let cut = inside_chunk_of(&bytes, &maps[4].0);
    let mut growing = std::fs::File::create(split(1)).unwrap();
    growing.write_all(&bytes[..cut]).unwrap();
    growing.flush().unwrap();
    let seen = until(&stdout, &received(3, "taken"));
    assert_eq!(seen, [received(2, "older"), received(3, "taken")]);
    growing.write_all(&bytes[cut..]).unwrap();
    drop(growing);
    until(&stdout, &received(4, "taken"));
    // Split 2 stops inside the chunk of map 5 (its writer died); split 3 holds map 5 again.
    let bytes = std::fs::read(&staged[2]).unwrap();
    let cut = inside_chunk_of(&bytes, &maps[5].0);
    std::fs::write(split(2), &bytes[..cut]).unwrap();
    std::fs::copy(&staged[2], split(3)).unwrap();
    let seen = until(&stdout, &received(5, "taken"));
    assert_eq!(seen, [received(5, "taken")]);

    let status = interrupt(&mut reap.0[0]);
    let (_, errors) = (rest(&stdout), rest(&stderr));
    assert_eq!(status.code(), Some(0), "{errors}");
    assert!(
        errors.contains(
            "recorded 6 maps in 1 segment(s); 1 not later than the last one taken were skipped"
        ),
        "{errors}"
    );
    assert!(errors.contains("bag_1.mcap: read to its end"), "{errors}");
    assert!(
        errors.contains("bag_2.mcap: it stops after")
            && errors.contains("its writer did not finish it"),
        "{errors}"
    );
    assert_eq!(samples(&file), 6);
    for (i, (map, _)) in maps.iter().enumerate() {
        retrieves_as(&file, i, map);
    }
}
