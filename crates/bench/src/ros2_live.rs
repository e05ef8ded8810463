//! `froctomap-bench ros2`: the ROS 2 node (`froctomap ros2`, a build with the `ros2`
//! feature) fed by the Cyclone DDS peer of `tests/scripts/ros2_peer.py`, all on loopback in
//! a domain of its own. The peer publishes the first N maps of a series, each one once the
//! node's reader acknowledged the one before (`wait_for_acks`); the node commits every K
//! maps. Measured in one run:
//!
//! * maps/s received (acknowledged) and committed, from the peer's publish times and the
//!   arrival of the node's commit lines;
//! * publish-to-commit latency of each map (its commit line's arrival less its publish
//!   time; both on this host's wall clock);
//! * `get_octomap_at` round trips from the peer (its Python client included), against
//!   `froctomap retrieve` of the same map as a process (the baseline, same run);
//! * what publishing the predicted map costs (the node's own line), against `froctomap
//!   predict` of the same instant as a process.

use anyhow::{bail, Context, Result};
use froctomap_convert::{collect_inputs, group_thousands, SeriesInput, TimeSource};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Arguments of `froctomap-bench ros2`.
#[derive(clap::Args)]
pub struct Ros2BenchArgs {
    /// A series directory with `manifest.csv` (`froctomap-bench generate`).
    #[arg(long)]
    series: PathBuf,
    /// Maps published (the series' first N).
    #[arg(long, default_value_t = 60)]
    maps: usize,
    /// The node's `--commit-every` (maps).
    #[arg(long, default_value_t = 10)]
    commit_every: usize,
    /// `get_octomap_at` calls.
    #[arg(long, default_value_t = 10)]
    calls: usize,
    /// The `froctomap` binary, built with `--features ros2` (default: beside this one).
    #[arg(long)]
    froctomap: Option<PathBuf>,
    /// Python with `cyclonedds` (default: $FROCTOMAP_PYTHON, else python3).
    #[arg(long)]
    python: Option<PathBuf>,
    /// Where the living file goes (emptied first).
    #[arg(long)]
    out: PathBuf,
}

/// Lines of a child's output with their arrival time (seconds since the epoch).
fn timed_lines(out: impl std::io::Read + Send + 'static) -> mpsc::Receiver<(f64, String)> {
    let (send, receive) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            if send.send((wall(), line)).is_err() {
                break;
            }
        }
    });
    receive
}

fn wall() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// The next line satisfying `wanted` within a minute.
fn next(
    lines: &mpsc::Receiver<(f64, String)>,
    wanted: impl Fn(&str) -> bool,
) -> Result<(f64, String)> {
    loop {
        match lines.recv_timeout(Duration::from_secs(60)) {
            Ok((at, line)) if wanted(&line) => return Ok((at, line)),
            Ok(_) => {}
            Err(e) => bail!("no line within a minute the run waits for ({e})"),
        }
    }
}

/// Kills and reaps the children left when the run ends.
struct Reap(Vec<Child>);

impl Drop for Reap {
    fn drop(&mut self) {
        for child in &mut self.0 {
            if matches!(child.try_wait(), Ok(None)) {
                let _ = child.kill();
            }
            let _ = child.wait();
        }
    }
}

/// Median and largest of `values`.
fn median_max(values: &mut [f64]) -> (f64, f64) {
    values.sort_by(f64::total_cmp);
    let median = values.get(values.len() / 2).copied().unwrap_or(f64::NAN);
    (median, values.last().copied().unwrap_or(f64::NAN))
}

/// Seconds a `froctomap` command takes (a process, as a user runs it).
fn timed(froctomap: &Path, args: &[&str]) -> Result<f64> {
    let started = Instant::now();
    let status = Command::new(froctomap)
        .args(args)
        .stdout(Stdio::null())
        .status()?;
    if !status.success() {
        bail!("froctomap {args:?} failed: {status}");
    }
    Ok(started.elapsed().as_secs_f64())
}

/// Runs the benchmark; prints a markdown table.
pub fn ros2_bench(args: &Ros2BenchArgs) -> Result<()> {
    let mut live = Live::prepare(args)?;
    let (mut peer, first_published) = live.start_peer()?;
    let recording = live.record(&mut peer, first_published)?;
    let mut calls = live.get_octomap_at_calls(&mut peer, recording.whole)?;
    let first_call = calls.remove(0); // Includes matching the service.
    Command::new("kill")
        .args(["-TERM", &recording.node_id.to_string()])
        .status()?;
    let _ = live.children.0[1].wait();
    drop(peer.calls);
    let measured = Measured {
        latencies: recording.latencies(),
        first_call,
        calls,
        retrieves: live.retrieve_times()?,
        publish_ms: live.predicted_publish_ms()?,
        predicts: live.predict_times()?,
    };
    live.print(&recording, measured);
    Ok(())
}

/// What the stages of the benchmark share.
struct Live<'a> {
    args: &'a Ros2BenchArgs,
    froctomap: PathBuf,
    /// The maps published, in time order.
    maps: Vec<SeriesInput>,
    /// Their bytes on disk.
    bytes: u64,
    /// The living file the node records into.
    living: PathBuf,
    /// The ROS domain of this run (its own, so that other runs do not interfere).
    domain: u32,
    /// The peer and the nodes, killed when the run ends.
    children: Reap,
}

/// The Cyclone DDS peer's events and the pipe that sends it calls.
struct Peer {
    events: mpsc::Receiver<(f64, String)>,
    calls: ChildStdin,
}

/// What the recording node did with the published maps.
struct Recording {
    /// Wall time each map was published.
    published: Vec<f64>,
    /// Arrival of each commit line and the maps it committed.
    committed: Vec<(f64, usize)>,
    /// The maps of whole groups of `--commit-every` (the rest commits at SIGTERM).
    whole: usize,
    node_id: u32,
}

impl Recording {
    /// Publish-to-commit latency of each committed map.
    fn latencies(&self) -> Vec<f64> {
        let mut latencies = Vec::new();
        let mut first = 0;
        for &(at, n) in &self.committed {
            for &sent in self.published.get(first..first + n).unwrap_or_default() {
                latencies.push(at - sent);
            }
            first += n;
        }
        latencies
    }
}

/// The times measured besides the recording's.
struct Measured {
    latencies: Vec<f64>,
    /// The first `get_octomap_at` round trip (it includes matching the service).
    first_call: f64,
    /// The other round trips.
    calls: Vec<f64>,
    /// `froctomap retrieve` processes.
    retrieves: Vec<f64>,
    /// The node's own time to publish the predicted map, ms.
    publish_ms: f64,
    /// `froctomap predict` processes.
    predicts: Vec<f64>,
}

/// Whole seconds of `t` (the stamps the peer publishes).
fn second(t: froctomap_core::Timestamp) -> i64 {
    t.0.div_euclid(1_000_000_000)
}

impl<'a> Live<'a> {
    /// Finds the binary, reads the series' first maps and empties the living file.
    fn prepare(args: &'a Ros2BenchArgs) -> Result<Self> {
        let froctomap = crate::recording::froctomap_binary(args.froctomap.as_deref())?;
        let inputs = collect_inputs(
            &froctomap_convert::Context::with_default_plugins(),
            &[args.series.join("manifest.csv")],
            TimeSource::Auto,
        )?;
        let maps: Vec<_> = inputs.into_iter().take(args.maps).collect();
        if maps.len() < 2 || args.commit_every == 0 {
            bail!("at least 2 maps and --commit-every 1");
        }
        let bytes: u64 = maps
            .iter()
            .map(|m| std::fs::metadata(&m.path).map_or(0, |m| m.len()))
            .sum();
        std::fs::create_dir_all(&args.out)?;
        let living = args.out.join("live.froct");
        let _ = std::fs::remove_file(&living);
        let domain = 1
            + (SystemTime::now().duration_since(UNIX_EPOCH)?.subsec_nanos() ^ std::process::id())
                % 200;
        Ok(Self {
            args,
            froctomap,
            maps,
            bytes,
            living,
            domain,
            children: Reap(Vec::new()),
        })
    }

    /// Starts the peer, which publishes the first map; returns it and that map's publish time.
    fn start_peer(&mut self) -> Result<(Peer, f64)> {
        let python = self
            .args
            .python
            .clone()
            .or_else(|| std::env::var_os("FROCTOMAP_PYTHON").map(PathBuf::from))
            .unwrap_or_else(|| PathBuf::from("python3"));
        let peer_script =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/scripts/ros2_peer.py");
        let mut peer = Command::new(&python)
            .arg(&peer_script)
            .args([
                "--domain",
                &self.domain.to_string(),
                "--no-predicted",
                "--timeout",
                "600",
            ])
            .args(["--first-stamp", &second(self.maps[0].time).to_string()])
            .arg("--predicted-out")
            .arg(self.args.out.join("unused.bt"))
            .arg(&self.maps[0].path)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .context("starting the Cyclone DDS peer")?;
        let events = timed_lines(peer.stdout.take().context("peer stdout")?);
        let calls = peer.stdin.take().context("peer stdin")?;
        self.children.0.push(peer);
        let first = event(&next(&events, |l| l.contains("published"))?.1)?["wall"]
            .as_f64()
            .context("a publish time")?;
        Ok((Peer { events, calls }, first))
    }

    /// Starts the recording node, has the peer publish the other maps, each once the node
    /// acknowledged the one before, and waits for the commits of whole groups.
    fn record(&mut self, peer: &mut Peer, first_published: f64) -> Result<Recording> {
        let mut node = Command::new(&self.froctomap)
            .args([
                "ros2",
                &self.living.to_string_lossy(),
                "--publish-every",
                "1h",
            ])
            .args(["--commit-every", &self.args.commit_every.to_string()])
            .env("ROS_DOMAIN_ID", self.domain.to_string())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .with_context(|| format!("starting {}", self.froctomap.display()))?;
        let commits = timed_lines(node.stdout.take().context("node stdout")?);
        let node_id = node.id();
        self.children.0.push(node);
        let mut published = vec![first_published];
        for map in &self.maps[1..] {
            writeln!(
                peer.calls,
                "{}",
                serde_json::json!({"call": "publish_map", "path": map.path, "stamp": second(map.time)})
            )?;
            let reply = event(&next(&peer.events, |l| l.contains("published"))?.1)?;
            if reply["acked"] != true {
                bail!("the node did not acknowledge {}", map.path.display());
            }
            published.push(reply["wall"].as_f64().context("a publish time")?);
        }
        // The commits of whole groups of K maps; the rest commits at SIGTERM.
        let commit_every = self.args.commit_every;
        let whole = self.maps.len() / commit_every * commit_every;
        let mut committed: Vec<(f64, usize)> = Vec::new();
        while committed.iter().map(|c| c.1).sum::<usize>() < whole {
            let (at, line) = next(&commits, |l| committed_maps(l).is_some())?;
            committed.push((at, committed_maps(&line).unwrap_or(0)));
        }
        Ok(Recording {
            published,
            committed,
            whole,
            node_id,
        })
    }

    /// `get_octomap_at` round trips from the peer, at the stamps of the first `whole`
    /// recorded maps.
    fn get_octomap_at_calls(&self, peer: &mut Peer, whole: usize) -> Result<Vec<f64>> {
        let mut calls = Vec::new();
        for i in 0..self.args.calls.max(2) {
            let map = &self.maps[i % whole.max(1)];
            writeln!(
                peer.calls,
                "{}",
                serde_json::json!({"call": "get_octomap_at", "sec": second(map.time), "nanosec": 0,
                    "predict": false, "out": self.args.out.join("got.bt")})
            )?;
            let reply = event(&next(&peer.events, |l| l.contains("get_octomap_at"))?.1)?;
            if reply["success"] != true {
                bail!("get_octomap_at failed: {reply}");
            }
            calls.push(reply["seconds"].as_f64().context("a round trip")?);
        }
        Ok(calls)
    }

    /// Three runs of `froctomap -q sub living --time time -o out` as processes.
    fn cli_times(&self, sub: &str, time: &str, out: &Path) -> Result<Vec<f64>> {
        (0..3)
            .map(|_| {
                timed(
                    &self.froctomap,
                    &[
                        "-q",
                        sub,
                        &self.living.to_string_lossy(),
                        "--time",
                        time,
                        "-o",
                        &out.to_string_lossy(),
                    ],
                )
            })
            .collect()
    }

    /// Baseline of `get_octomap_at`: the first map through `froctomap retrieve`.
    fn retrieve_times(&self) -> Result<Vec<f64>> {
        let stamp = second(self.maps[0].time).to_string();
        self.cli_times("retrieve", &stamp, &self.args.out.join("retrieved.bt"))
    }

    /// The node's own time to publish the predicted map at start (now), in ms.
    fn predicted_publish_ms(&mut self) -> Result<f64> {
        let mut node = Command::new(&self.froctomap)
            .args([
                "ros2",
                &self.living.to_string_lossy(),
                "--no-record",
                "--publish-every",
                "1h",
            ])
            .env("ROS_DOMAIN_ID", self.domain.to_string())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()?;
        let log = timed_lines(node.stderr.take().context("node stderr")?);
        let node_id = node.id();
        self.children.0.push(node);
        let (_, line) = next(&log, |l| l.starts_with("published the map predicted"))?;
        let publish_ms: f64 = line
            .rsplit_once('(')
            .and_then(|(_, ms)| ms.trim_end_matches(" ms)").parse().ok())
            .context("the node's publish time")?;
        Command::new("kill")
            .args(["-TERM", &node_id.to_string()])
            .status()?;
        Ok(publish_ms)
    }

    /// Baseline of the node's predicted map: `froctomap predict` at the same now.
    fn predict_times(&self) -> Result<Vec<f64>> {
        let now = (wall() as i64).to_string();
        self.cli_times("predict", &now, &self.args.out.join("predicted.bt"))
    }

    /// Prints the table of what was measured.
    fn print(&self, recording: &Recording, mut measured: Measured) {
        let maps = self.maps.len();
        let published = &recording.published;
        let span = published.last().copied().unwrap_or(0.0) - published[0];
        let last_commit = recording.committed.last().map_or(0.0, |c| c.0);
        let (latency_median, latency_max) = median_max(&mut measured.latencies);
        let (call_median, call_max) = median_max(&mut measured.calls);
        let (retrieve_median, _) = median_max(&mut measured.retrieves);
        let (predict_median, _) = median_max(&mut measured.predicts);
        let publish_ms = measured.publish_ms;
        println!(
            "{} maps ({} bytes of .bt) published by the Cyclone DDS peer, each after the node acknowledged the one before; --commit-every {}\n",
            maps,
            group_thousands(self.bytes),
            self.args.commit_every
        );
        println!("| measure | value | baseline (same run) | ratio |");
        println!("| --- | ---: | ---: | ---: |");
        println!(
            "| maps/s received (acknowledged) | {:.1} | | |",
            (maps - 1) as f64 / span
        );
        println!(
            "| maps/s committed ({} maps in {} commits) | {:.1} | | |",
            recording.whole,
            recording.committed.len(),
            recording.whole as f64 / (last_commit - published[0])
        );
        println!(
            "| publish-to-commit latency, median / max | {:.2} s / {:.2} s | | |",
            latency_median, latency_max
        );
        println!(
            "| get_octomap_at round trip, median / max of {} (first, with matching: {:.3} s) | {:.3} s / {:.3} s | `froctomap retrieve` process {:.3} s | {:.2}× |",
            measured.calls.len(),
            measured.first_call,
            call_median,
            call_max,
            retrieve_median,
            call_median / retrieve_median
        );
        println!(
            "| publishing the predicted map (predict + encode map and markers + write) | {:.3} s | `froctomap predict` process {:.3} s | {:.2}× |",
            publish_ms / 1000.0,
            predict_median,
            publish_ms / 1000.0 / predict_median
        );
        let file_bytes = std::fs::metadata(&self.living).map_or(0, |m| m.len());
        println!("\nliving file: {} bytes", group_thousands(file_bytes));
    }
}

/// One event line of the peer, as JSON.
fn event(line: &str) -> Result<serde_json::Value> {
    Ok(serde_json::from_str(line)?)
}

/// The maps a commit line of the node says it committed (`...: N maps ...`).
fn committed_maps(line: &str) -> Option<usize> {
    line.split_once(": ")?
        .1
        .split_once(" maps")?
        .0
        .trim()
        .parse()
        .ok()
}
