//! The ROS 2 node against an independent ROS 2 peer: Eclipse Cyclone DDS (PyPI `cyclonedds`,
//! the DDS under rmw_cyclonedds_cpp) with `octomap_msgs/msg/Octomap` declared in Python
//! (tests/scripts/ros2_peer.py). All traffic on loopback: the peer on interface `lo` without
//! multicast and with the peer 127.0.0.1, the node with [`Network::Loopback`], a domain id of
//! its own per run.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_convert::{Context, FroctFile, SeriesRead};
use froctomap_core::Timestamp;
use froctomap_ros2_node::{
    FileServices, MapSink, Network, Node, NodeOptions, PredictedPublisher, ReceivedMap,
    RecordingSink, TimeSource,
};
use froctomap_test_support::{
    octomap_fixture, octomap_python, python_leaves, scratch, workspace_root, LeafTuple,
};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Writes each map it receives to `dir`, named by its stamp, and hands it on to the node's
/// recording sink.
struct FilesSink<'a> {
    dir: PathBuf,
    received: Vec<ReceivedMap>,
    skipped: Vec<String>,
    recording: RecordingSink<'a>,
}

impl MapSink for FilesSink<'_> {
    fn receive(
        &mut self,
        map: ReceivedMap,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let ext = if map.binary { "bt" } else { "ot" };
        std::fs::write(self.dir.join(format!("{}.{ext}", map.stamp.0)), &map.file)?;
        self.received.push(map.clone());
        self.recording.receive(map)
    }

    fn skipped(&mut self, reason: String) {
        self.skipped.push(reason);
    }
}

/// Lets `node` hand maps to `sink` until `done` holds (at most a minute, then fails
/// saying what arrived).
fn receive_until(node: &Node, sink: &mut FilesSink, done: impl Fn(&FilesSink) -> bool) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while !done(sink) && Instant::now() < deadline {
        node.receive_into(sink, Duration::from_millis(100))
            .expect("the node never stops on input");
    }
    assert!(
        done(sink),
        "received {:?}, skipped {:?}",
        sink.received.len(),
        sink.skipped
    );
}

/// A domain id of this run's own (0..=232 are valid; 0 is everyone's default).
fn random_domain() -> u16 {
    let nanos = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(7);
    1 + ((nanos ^ std::process::id()) % 200) as u16
}

struct Peer {
    child: Child,
    events: mpsc::Receiver<serde_json::Value>,
}

impl Peer {
    fn start(domain: u16, predicted_out: &Path, maps: &[PathBuf], extra: &[&str]) -> Peer {
        let mut child = Command::new(octomap_python())
            .arg(workspace_root().join("tests/scripts/ros2_peer.py"))
            .args(["--domain", &domain.to_string(), "--timeout", "60"])
            .args(extra)
            .arg("--predicted-out")
            .arg(predicted_out)
            .args(maps)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("start the cyclonedds peer");
        let stdout = child.stdout.take().expect("peer stdout");
        let (send, events) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if let Ok(event) = serde_json::from_str(&line) {
                    if send.send(event).is_err() {
                        break;
                    }
                }
            }
        });
        Peer { child, events }
    }

    fn next_event(&self, wait: Duration) -> serde_json::Value {
        match self.events.recv_timeout(wait) {
            Ok(event) => event,
            Err(e) => panic!("the peer said nothing within {wait:?}: {e}"),
        }
    }

    /// Sends the peer a command line (JSON).
    fn command(&mut self, command: &serde_json::Value) {
        use std::io::Write;
        let stdin = self.child.stdin.as_mut().expect("peer stdin");
        writeln!(stdin, "{command}")
            .and_then(|()| stdin.flush())
            .expect("tell the peer");
    }

    /// The peer's next event, the node answering service requests meanwhile.
    fn event_while_serving(
        &self,
        node: &Node,
        services: &mut FileServices,
        wait: Duration,
    ) -> serde_json::Value {
        let deadline = Instant::now() + wait;
        loop {
            node.serve_requests(services);
            match self.events.recv_timeout(Duration::from_millis(20)) {
                Ok(event) => return event,
                Err(mpsc::RecvTimeoutError::Timeout) if Instant::now() < deadline => {}
                Err(e) => panic!("the peer said nothing within {wait:?}: {e}"),
            }
        }
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        drop(self.child.stdin.take()); // The peer exits when its stdin closes.
        let _ = self.child.wait();
    }
}

/// UDP sockets of process `pid` bound to an address that is neither loopback nor the
/// wildcard, from /proc/net/udp (the inode of each socket matched against the process's fds).
fn udp_binds(pid: u32) -> Vec<String> {
    let inodes: Vec<String> = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .map(|dir| {
            dir.filter_map(Result::ok)
                .filter_map(|fd| std::fs::read_link(fd.path()).ok())
                .filter_map(|link| {
                    let link = link.to_string_lossy().to_string();
                    link.strip_prefix("socket:[")
                        .map(|s| s.trim_end_matches(']').to_string())
                })
                .collect()
        })
        .unwrap_or_default();
    let table = std::fs::read_to_string("/proc/net/udp").unwrap_or_default();
    table
        .lines()
        .skip(1)
        .filter_map(|line| {
            let fields: Vec<&str> = line.split_whitespace().collect();
            let (local, inode) = (fields.get(1)?, fields.get(9)?);
            inodes.iter().any(|i| i == inode).then(|| local.to_string())
        })
        .collect()
}

/// The local address of a /proc/net/udp entry (`0100007F:1CE8`) as `a.b.c.d`.
fn address(entry: &str) -> String {
    let hex = entry.split(':').next().unwrap_or_default();
    let n = u32::from_str_radix(hex, 16).unwrap_or(u32::MAX);
    let [a, b, c, d] = n.to_le_bytes();
    format!("{a}.{b}.{c}.{d}")
}

#[test]
fn cyclonedds_peer_maps_arrive_byte_identical_and_it_reads_the_predicted_map() {
    let dir = scratch();
    let received_dir = dir.path().join("received");
    std::fs::create_dir(&received_dir).expect("mkdir");
    let maps: Vec<PathBuf> = ["few_voxels.bt", "coarse_leaves.bt", "few_voxels.ot"]
        .iter()
        .map(|name| octomap_fixture(name))
        .collect();
    let domain = random_domain();
    let predicted_out = dir.path().join("predicted.bt");
    let markers_out = dir.path().join("markers.json");

    // The peer publishes the first map before the node exists: it must arrive latched
    // (transient-local); the others are published live.
    let markers_arg = markers_out.to_string_lossy().to_string();
    let mut peer = Peer::start(
        domain,
        &predicted_out,
        &maps,
        &["--markers-out", &markers_arg],
    );
    let event = peer.next_event(Duration::from_secs(30));
    assert_eq!(event["event"], "published", "{event}");

    let mut options = NodeOptions::new(domain);
    options.network = Network::Loopback;
    let node = Node::new(&options).expect("the node joins the domain on loopback");
    let froct = workspace_root().join("fixtures/froct/golden-v1.2.froct");
    let mut predicted = PredictedPublisher::new(&froct, "map");
    let t = froctomap_ros2_node::last_instant(&froct).expect("read the .froct");
    assert!(predicted
        .publish_if_changed(&node, t)
        .expect("publish")
        .is_some());
    assert!(
        predicted
            .publish_if_changed(&node, t)
            .expect("publish again")
            .is_none(),
        "unchanged maps are not republished"
    );

    // The maps received are recorded into a file that does not exist yet (the living map),
    // committed every two maps: a base, then a segment.
    let context = Context::with_default_plugins();
    let living = dir.path().join("living.froct");
    let options =
        froctomap_convert::RecordOptions::for_live_source(froctomap_convert::CommitEvery::Maps(2));
    let mut recorder =
        froctomap_convert::Recorder::open(&context, &living, options).expect("record");
    let retried = note_retries(&mut recorder);
    let mut sink = FilesSink {
        dir: received_dir.clone(),
        received: Vec::new(),
        skipped: Vec::new(),
        recording: RecordingSink::new(recorder, TimeSource::Header, Duration::ZERO),
    };
    let receive = |sink: &mut FilesSink, count: usize| {
        let deadline = Instant::now() + Duration::from_secs(60);
        while sink.received.len() < count && Instant::now() < deadline {
            node.receive_into(sink, Duration::from_millis(200))
                .expect("receive");
        }
    };
    receive(&mut sink, 1);
    assert_eq!(
        sink.received.len(),
        1,
        "the latched map: skipped {:?}",
        sink.skipped
    );
    {
        use std::io::Write;
        let stdin = peer.child.stdin.as_mut().expect("peer stdin");
        stdin
            .write_all(b"go\n")
            .and_then(|()| stdin.flush())
            .expect("tell the peer");
    }
    for map in &maps[1..] {
        let event = peer.next_event(Duration::from_secs(30));
        assert_eq!(event["event"], "published", "{event}");
        assert_eq!(event["map"], map.to_string_lossy().as_ref());
    }
    receive(&mut sink, maps.len());
    let stamps: Vec<i64> = sink.received.iter().map(|m| m.stamp.0).collect();
    assert_eq!(
        sink.received.len(),
        maps.len(),
        "maps received from the peer: {stamps:?}; skipped: {:?}",
        sink.skipped
    );

    assert_maps_arrived_whole(&sink, &maps, &received_dir);
    let (resolution, leaves) =
        peer_reads_the_predicted_map(&peer, &predicted, t, &predicted_out, dir.path());
    assert_markers_are_the_occupied_leaves(&peer, &markers_out, t, resolution, &leaves);
    assert_recording_retrieves_each_map(sink, &maps, &living, dir.path(), &context, &retried);
    living_services_answer_as_upstream(&mut peer, &node, &living, &maps, dir.path());
    file_services_answer_as_retrieve(&mut peer, &node, &froct, dir.path());
    assert_loopback_only(&peer);
}

/// Where the data of an OctoMap file starts (after its `data` line).
fn data_at(file: &[u8]) -> usize {
    file.windows(6)
        .position(|w| w == b"\ndata\n")
        .expect("data")
        + 6
}

/// Whole seconds and nanoseconds of `t`, as a ROS stamp.
fn sec_nanosec(t: Timestamp) -> (i64, i64) {
    (t.0.div_euclid(1_000_000_000), t.0.rem_euclid(1_000_000_000))
}

/// Each map arrives whole: the file the sink got is the one the peer published.
fn assert_maps_arrived_whole(sink: &FilesSink, maps: &[PathBuf], received_dir: &Path) {
    for (i, map) in maps.iter().enumerate() {
        let stamp = (1_700_000_000 + i as i64) * 1_000_000_000;
        let got = sink
            .received
            .iter()
            .find(|m| m.stamp.0 == stamp)
            .expect("a map per stamp");
        let original = std::fs::read(map).expect("read the fixture");
        assert_eq!(got.binary, map.extension().is_some_and(|e| e == "bt"));
        let body = |file: &[u8]| {
            let at = file
                .windows(6)
                .position(|w| w == b"\ndata\n")
                .expect("a data line")
                + 6;
            file[at..].to_vec()
        };
        assert_eq!(
            body(&got.file),
            body(&original),
            "{}: the data arrived unchanged",
            map.display()
        );
        // Upstream OctoMap reads the file the node made of the message as it reads the original.
        let written =
            received_dir.join(format!("{stamp}.{}", if got.binary { "bt" } else { "ot" }));
        let kind = if got.binary { "bt" } else { "ot" };
        assert_eq!(
            python_leaves(&written, kind),
            python_leaves(map, kind),
            "{}",
            map.display()
        );
    }
}

/// The peer got the latched predicted map and upstream OctoMap reads it; returns what
/// octomap-python reads of it.
fn peer_reads_the_predicted_map(
    peer: &Peer,
    predicted: &PredictedPublisher,
    t: Timestamp,
    predicted_out: &Path,
    dir: &Path,
) -> (f64, Vec<LeafTuple>) {
    let event = peer.next_event(Duration::from_secs(60));
    assert_eq!(event["event"], "predicted", "{event}");
    let sent = predicted.predicted_bt(t).expect("predict");
    let got = std::fs::read(predicted_out).expect("the peer wrote the predicted map");
    assert_eq!(
        got[data_at(&got)..],
        sent[data_at(&sent)..],
        "the predicted map's data arrived unchanged"
    );
    let (resolution, leaves) = python_leaves(predicted_out, "bt");
    assert!(
        resolution > 0.0 && !leaves.is_empty(),
        "octomap-python reads the predicted map"
    );
    let ours = dir.join("ours.bt");
    std::fs::write(&ours, &sent).expect("write");
    assert_eq!(python_leaves(&ours, "bt"), (resolution, leaves.clone()));
    (resolution, leaves)
}

/// With it, /froctomap/dynamic: a MarkerArray as octomap_server's occupied_cells_vis_array,
/// decoded by the peer through the types it declares. Its cubes are the occupied leaves
/// upstream OctoMap reads from the predicted map, each at its depth's marker.
fn assert_markers_are_the_occupied_leaves(
    peer: &Peer,
    markers_out: &Path,
    t: Timestamp,
    resolution: f64,
    leaves: &[LeafTuple],
) {
    let event = peer.next_event(Duration::from_secs(60));
    assert_eq!(event["event"], "markers", "{event}");
    let markers: Vec<serde_json::Value> =
        serde_json::from_slice(&std::fs::read(markers_out).expect("the peer wrote the markers"))
            .expect("JSON");
    assert_eq!(markers.len(), 17, "one marker per depth 0..=16");
    let stamp_of_t = [t.0.div_euclid(1_000_000_000), t.0.rem_euclid(1_000_000_000)];
    let mut cubes = Vec::new();
    for (depth, marker) in markers.iter().enumerate() {
        assert_eq!(marker["id"], depth, "{marker}");
        assert_eq!(marker["type"], 6, "CUBE_LIST");
        assert_eq!(
            (&marker["frame_id"], &marker["ns"]),
            (&serde_json::json!("map"), &serde_json::json!("froctomap"))
        );
        assert_eq!(marker["stamp"], serde_json::json!(stamp_of_t));
        assert_eq!(
            marker["pose"],
            serde_json::json!([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
        );
        let side = f64::from(1u32 << (16 - depth));
        assert_eq!(
            marker["scale"],
            serde_json::json!([resolution * side, resolution * side, resolution * side])
        );
        let points = marker["points"].as_array().expect("points");
        let colors = marker["colors"].as_array().expect("colors");
        assert_eq!(points.len(), colors.len(), "a colour per cube");
        // ADD (0) with cubes, DELETE (2) without, as octomap_server does.
        assert_eq!(marker["action"], if points.is_empty() { 2 } else { 0 });
        for (point, color) in points.iter().zip(colors) {
            let key = |i: usize| {
                let c = point[i].as_f64().expect("a coordinate");
                let k = c / resolution - side / 2.0 + 32768.0;
                assert!(
                    (k - k.round()).abs() < 1e-6,
                    "{c} is a node centre at depth {depth}"
                );
                k.round() as u16
            };
            cubes.push((key(0), key(1), key(2), depth as u8));
            assert_eq!(color[3], 1.0, "opaque");
        }
    }
    cubes.sort_unstable();
    let occupied: Vec<(u16, u16, u16, u8)> = leaves
        .iter()
        .filter(|l| f32::from_bits(l.4) > 0.0)
        .map(|&(x, y, z, depth, _)| (x, y, z, depth))
        .collect();
    assert!(!occupied.is_empty());
    assert_eq!(
        cubes, occupied,
        "the cubes are the predicted map's occupied leaves"
    );
}

/// The node stops: what it recorded retrieves as each map the peer published.
fn assert_recording_retrieves_each_map(
    sink: FilesSink,
    maps: &[PathBuf],
    living: &Path,
    dir: &Path,
    context: &Context,
    retried: &std::cell::RefCell<Vec<String>>,
) {
    let FilesSink { recording, .. } = sink;
    let summary = recording.finish().expect("the last commit");
    assert!(
        retried.borrow().is_empty(),
        "no commit failed and was tried again as halves: {:?}",
        retried.borrow()
    );
    assert_eq!((summary.committed_maps, summary.commits), (maps.len(), 2));
    let recorded = FroctFile::open(living).expect("the living map");
    for (i, map) in maps.iter().enumerate() {
        let stamp = Timestamp((1_700_000_000 + i as i64) * 1_000_000_000);
        let resolved = froctomap_convert::resolve_observed(
            &recorded,
            froctomap_convert::TimeQuery::Instant(stamp),
        )
        .expect("a map at each stamp");
        assert!(resolved.exact);
        let kind = map.extension().and_then(|e| e.to_str()).expect("ext");
        let out = dir.join(format!("recorded-{i}.{kind}"));
        froctomap_convert::write_observed_map(
            context,
            &recorded,
            resolved.sample,
            &out,
            Default::default(),
        )
        .expect("retrieve");
        if kind == "bt" {
            assert_eq!(
                std::fs::read(&out).expect("read"),
                std::fs::read(map).expect("read"),
                "{}: retrieved byte-identical",
                map.display()
            );
        }
        // froctomap keeps each voxel's state (occupied or free), so an `.ot` comes back with
        // the same leaves in the same states, their log-odds those of its states.
        let states = |path: &Path| {
            let (resolution, leaves) = python_leaves(path, kind);
            let states: Vec<_> = leaves
                .into_iter()
                .map(|(x, y, z, depth, bits)| (x, y, z, depth, f32::from_bits(bits) > 0.0))
                .collect();
            (resolution, states)
        };
        assert_eq!(states(&out), states(map), "{}", map.display());
    }
}

/// The services answer from the living file as the upstream maps it was recorded from
/// say: get_octomap_at gives the data of the .bt published at that stamp, and
/// probability_at is a number exactly where octomap-python finds a node in one of the
/// maps recorded (the file's map is their union), NaN elsewhere.
fn living_services_answer_as_upstream(
    peer: &mut Peer,
    node: &Node,
    living: &Path,
    maps: &[PathBuf],
    dir: &Path,
) {
    let mut from_living = FileServices::new(living, "map");
    let living_path = dir.join("living-get.bt");
    peer.command(
        &serde_json::json!({"call": "get_octomap_at", "sec": 1_700_000_001, "nanosec": 0,
        "predict": false, "out": living_path}),
    );
    let event = peer.event_while_serving(node, &mut from_living, Duration::from_secs(60));
    assert_eq!(event["success"], true, "{event}");
    let upstream = std::fs::read(&maps[1]).expect("read");
    let got = std::fs::read(&living_path).expect("the peer wrote the map");
    assert_eq!(
        got[data_at(&got)..],
        upstream[data_at(&upstream)..],
        "get_octomap_at gives the map published at that stamp"
    );
    let (upstream_resolution, upstream_leaves) = python_leaves(&maps[1], "bt");
    assert_eq!(
        python_leaves(&living_path, "bt"),
        (upstream_resolution, upstream_leaves.clone())
    );
    let key_metric = |k: u16| (f64::from(k) - 32768.0 + 0.5) * upstream_resolution;
    let mut probes: Vec<[f64; 3]> = Vec::new();
    for &(x, y, z, _, _) in upstream_leaves.iter().step_by(3) {
        let c = [key_metric(x), key_metric(y), key_metric(z)];
        probes.push(c);
        // Beside it, in or out of the maps.
        probes.push([c[0] + 7.3 * upstream_resolution, c[1], c[2]]);
    }
    probes.push([1.0e6, 0.0, 0.0]);
    probes.push([40.0, -40.0, 40.0]);
    let found = found_by_octomap_python(&probes, maps);
    assert!(found.iter().any(|f| *f) && found.iter().any(|f| !*f));
    peer.command(
        &serde_json::json!({"call": "probability_at", "sec": 1_700_000_001, "nanosec": 0,
        "points": probes}),
    );
    let event = peer.event_while_serving(node, &mut from_living, Duration::from_secs(60));
    let p_bits = event["p_bits"].as_array().expect("p").clone();
    assert_eq!(p_bits.len(), probes.len());
    for ((hex, point), found) in p_bits.iter().zip(&probes).zip(&found) {
        let p = f64_hex_value(hex.as_str().expect("hex"));
        assert_eq!(
            p.is_finite(),
            *found,
            "probability_at {point:?} is {p} where octomap-python finds a node: {found}"
        );
    }
}

/// Whether octomap-python finds a node at each of `probes` in any of `maps`.
fn found_by_octomap_python(probes: &[[f64; 3]], maps: &[PathBuf]) -> Vec<bool> {
    let script = r#"
import json, sys, numpy as np, octomap
points = json.loads(sys.argv[1])
trees = []
for path in sys.argv[2:]:
    if path.endswith(".bt"):
        tree = octomap.OcTree(0.1)
        assert tree.readBinary(path.encode())
    else:
        tree = octomap.OcTree.read(path.encode())
    trees.append(tree)
def found(tree, p):
    try:
        tree.search(np.array(p, dtype=float)).getValue()
        return True
    except Exception:
        return False
print(json.dumps([any(found(t, p) for t in trees) for p in points]))
"#;
    let out = Command::new(octomap_python())
        .args(["-c", script])
        .arg(serde_json::json!(probes).to_string())
        .args(maps)
        .stderr(Stdio::null())
        .output()
        .expect("run python");
    assert!(out.status.success(), "octomap-python search");
    serde_json::from_slice::<Vec<bool>>(&out.stdout).expect("one bool a point")
}

/// The services, as an rmw_cyclonedds client calls them (the Cyclone mapping).
fn file_services_answer_as_retrieve(peer: &mut Peer, node: &Node, froct: &Path, dir: &Path) {
    let mut services = FileServices::new(froct, "map");
    let file = FroctFile::open(froct).expect("open the .froct");
    let (start, end) = (file.first_instant(), file.last_instant());
    let sample = 1;
    let past = file.sample_time(sample).expect("a second sample");
    assert!(past > start && past < end);
    let (resolution, leaves) =
        get_octomap_at_gives_the_retrieved_map(peer, node, &mut services, &file, sample, dir);
    get_octomap_at_outside_the_span(peer, node, &mut services, &file, end, dir);
    probability_at_is_the_files(peer, node, &mut services, &file, past, resolution, &leaves);
}

/// A past stamp of the file: the map recorded then, exactly as `retrieve` writes it.
fn get_octomap_at_gives_the_retrieved_map(
    peer: &mut Peer,
    node: &Node,
    services: &mut FileServices,
    file: &FroctFile,
    sample: u32,
    dir: &Path,
) -> (f64, Vec<LeafTuple>) {
    let past = file.sample_time(sample).expect("a second sample");
    let (sec, nanosec) = sec_nanosec(past);
    let got_path = dir.join("get_octomap_at.bt");
    peer.command(
        &serde_json::json!({"call": "get_octomap_at", "sec": sec, "nanosec": nanosec,
        "predict": false, "out": got_path}),
    );
    let event = peer.event_while_serving(node, services, Duration::from_secs(60));
    assert_eq!(event["event"], "get_octomap_at", "{event}");
    assert_eq!(event["success"], true, "{event}");
    assert_eq!(event["stamp"], serde_json::json!([sec, nanosec]), "{event}");
    let retrieved = dir.join("retrieved.bt");
    froctomap_convert::write_observed_map(
        &Context::with_default_plugins(),
        file,
        sample,
        &retrieved,
        Default::default(),
    )
    .expect("retrieve");
    let retrieved_bytes = std::fs::read(&retrieved).expect("read");
    let got_bytes = std::fs::read(&got_path).expect("the peer wrote the map");
    assert_eq!(
        got_bytes[data_at(&got_bytes)..],
        retrieved_bytes[data_at(&retrieved_bytes)..],
        "the map of get_octomap_at is the one retrieve writes"
    );
    let (resolution, leaves) = python_leaves(&retrieved, "bt");
    assert!(!leaves.is_empty());
    assert_eq!(python_leaves(&got_path, "bt"), (resolution, leaves.clone()));
    (resolution, leaves)
}

/// predict=false outside the recorded span fails with a reason; predict=true there is
/// the model's estimate.
fn get_octomap_at_outside_the_span(
    peer: &mut Peer,
    node: &Node,
    services: &mut FileServices,
    file: &FroctFile,
    end: Timestamp,
    dir: &Path,
) {
    let (sec, nanosec) = sec_nanosec(Timestamp(end.0 + 86_400_000_000_000));
    peer.command(
        &serde_json::json!({"call": "get_octomap_at", "sec": sec, "nanosec": nanosec,
        "predict": false, "out": dir.join("never.bt")}),
    );
    let event = peer.event_while_serving(node, services, Duration::from_secs(60));
    assert_eq!(event["success"], false, "{event}");
    assert!(
        event["message"]
            .as_str()
            .is_some_and(|m| m.contains("outside the recorded span")),
        "{event}"
    );
    assert!(!dir.join("never.bt").exists());
    let future_path = dir.join("future.bt");
    peer.command(
        &serde_json::json!({"call": "get_octomap_at", "sec": sec, "nanosec": nanosec,
        "predict": true, "out": future_path}),
    );
    let event = peer.event_while_serving(node, services, Duration::from_secs(60));
    assert_eq!(event["success"], true, "{event}");
    let future = froctomap_convert::predicted_bt(file, Timestamp(end.0 + 86_400_000_000_000))
        .expect("predict");
    let got_future = std::fs::read(&future_path).expect("the predicted map");
    assert_eq!(
        got_future[data_at(&got_future)..],
        future[data_at(&future)..]
    );
    let ours = dir.join("future-ours.bt");
    std::fs::write(&ours, &future).expect("write");
    assert_eq!(
        python_leaves(&future_path, "bt"),
        python_leaves(&ours, "bt")
    );
}

/// probability_at: points inside leaves of the map, and one far outside (NaN).
fn probability_at_is_the_files(
    peer: &mut Peer,
    node: &Node,
    services: &mut FileServices,
    file: &FroctFile,
    past: Timestamp,
    resolution: f64,
    leaves: &[LeafTuple],
) {
    let metric = |k: u16| (f64::from(k) - 32768.0 + 0.5) * resolution;
    let mut points: Vec<[f64; 3]> = leaves
        .iter()
        .step_by((leaves.len() / 5).max(1))
        .map(|&(x, y, z, _, _)| [metric(x), metric(y), metric(z)])
        .collect();
    points.push([1.0e6, 0.0, 0.0]);
    let (sec, nanosec) = sec_nanosec(past);
    peer.command(
        &serde_json::json!({"call": "probability_at", "sec": sec, "nanosec": nanosec,
        "points": points}),
    );
    let event = peer.event_while_serving(node, services, Duration::from_secs(60));
    assert_eq!(event["event"], "probability_at", "{event}");
    let expected =
        froctomap_convert::probabilities(file.whole_history().expect("a 1.x file"), past, &points)
            .expect("probabilities");
    let got: Vec<u64> = event["p_bits"]
        .as_array()
        .expect("p")
        .iter()
        .map(|hex| f64_hex_value(hex.as_str().expect("hex")).to_bits())
        .collect();
    assert_eq!(got.len(), points.len());
    assert!(
        f64::from_bits(got[points.len() - 1]).is_nan(),
        "NaN outside the map"
    );
    assert!(expected[..points.len() - 1].iter().all(|p| p.is_finite()));
    for (got, expected) in got.iter().zip(&expected) {
        assert!(
            *got == expected.to_bits() || (f64::from_bits(*got).is_nan() && expected.is_nan()),
            "p {} != {expected}",
            f64::from_bits(*got)
        );
    }
}

/// Loopback only: no socket of the peer or of this process is bound to an address other
/// than 127.0.0.1 or the wildcard (RustDDS binds the wildcard; see docs/ROS.md).
fn assert_loopback_only(peer: &Peer) {
    for (who, pid) in [("peer", peer.child.id()), ("node", std::process::id())] {
        for entry in udp_binds(pid) {
            let bound = address(&entry);
            assert!(
                bound == "127.0.0.1" || bound == "0.0.0.0",
                "{who} has a UDP socket bound to {bound}"
            );
        }
    }
}

/// The f64 as rosbags' side of the check prints it: its little-endian bytes in hex.
/// The f64 of the peer's little-endian hex.
fn f64_hex_value(hex: &str) -> f64 {
    let bytes: Vec<u8> = (0..8)
        .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).expect("hex"))
        .collect();
    f64::from_le_bytes(bytes.try_into().expect("8 bytes"))
}

fn f64_hex(v: f64) -> String {
    v.to_le_bytes().iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn service_messages_encode_as_rosbags_reads_the_srv_files() {
    use froctomap_ros2_node::{
        encode_cdr, GetOctomapAtRequest, GetOctomapAtResponse, Header, MapData, Octomap, Point,
        ProbabilityAtRequest, ProbabilityAtResponse, Time,
    };
    use serde_json::json;
    let hex = |bytes: &[u8]| -> String { bytes.iter().map(|b| format!("{b:02x}")).collect() };
    let time = |sec: i32, nanosec: u32| Time { sec, nanosec };
    let time_fields = |t: Time| json!({"sec": t.sec, "nanosec": t.nanosec});
    let data: Vec<u8> = vec![0x09, 0x00, 0xff, 0x80, 0x7f, 0x01, 0x00];
    let mut cases = Vec::new();
    for predict in [false, true] {
        let request = GetOctomapAtRequest {
            stamp: time(1_700_000_123, 456_789),
            predict,
        };
        cases.push(json!({
            "type": "froctomap_msgs/srv/GetOctomapAt_Request",
            "cdr_hex": hex(&encode_cdr(&request).unwrap()),
            "fields": {"stamp": time_fields(request.stamp), "predict": predict},
        }));
    }
    // Field lengths that make every alignment case: the message string's NUL lands at
    // different offsets before the nested header and the 8-aligned resolution.
    for (message, frame_id, id) in [
        ("", "map", "OcTree"),
        ("ok", "m", ""),
        ("recorded at 12:00", "odom_frame", "ColorOcTree"),
    ] {
        let response = GetOctomapAtResponse {
            success: !message.is_empty(),
            message: message.to_string(),
            map: Octomap {
                header: Header {
                    stamp: time(-5, 999_999_999),
                    frame_id: frame_id.to_string(),
                },
                binary: id != "ColorOcTree",
                id: id.to_string(),
                resolution: 0.05,
                data: MapData(data.clone()),
            },
        };
        cases.push(json!({
            "type": "froctomap_msgs/srv/GetOctomapAt_Response",
            "cdr_hex": hex(&encode_cdr(&response).unwrap()),
            "fields": {
                "success": response.success,
                "message": message,
                "map": {
                    "header": {"stamp": time_fields(response.map.header.stamp), "frame_id": frame_id},
                    "binary": response.map.binary,
                    "id": id,
                    "resolution": f64_hex(0.05),
                    "data": data.iter().map(|&b| b as i8).collect::<Vec<_>>(),
                },
            },
        }));
    }
    let points = vec![
        Point {
            x: 1.5,
            y: -2.25,
            z: 0.125,
        },
        Point {
            x: 1e6,
            y: 0.0,
            z: -0.0,
        },
    ];
    let request = ProbabilityAtRequest {
        stamp: time(1_700_000_000, 0),
        points: points.clone(),
    };
    cases.push(json!({
        "type": "froctomap_msgs/srv/ProbabilityAt_Request",
        "cdr_hex": hex(&encode_cdr(&request).unwrap()),
        "fields": {
            "stamp": time_fields(request.stamp),
            "points": points.iter().map(|p| json!({"x": f64_hex(p.x), "y": f64_hex(p.y), "z": f64_hex(p.z)})).collect::<Vec<_>>(),
        },
    }));
    for p in [vec![], vec![0.25, f64::NAN, 1.0]] {
        let response = ProbabilityAtResponse { p: p.clone() };
        cases.push(json!({
            "type": "froctomap_msgs/srv/ProbabilityAt_Response",
            "cdr_hex": hex(&encode_cdr(&response).unwrap()),
            "fields": {"p": p.iter().map(|&v| f64_hex(v)).collect::<Vec<_>>()},
        }));
    }
    // And the node reads what it writes (its requests come from rosbags-compatible clients).
    let decoded: ProbabilityAtRequest =
        froctomap_ros2_node::decode_cdr(&encode_cdr(&request).unwrap()).unwrap();
    assert_eq!(decoded, request);

    let dir = scratch();
    let cases_path = dir.path().join("cases.json");
    std::fs::write(&cases_path, serde_json::to_vec(&cases).unwrap()).unwrap();
    let out = Command::new(octomap_python())
        .arg(workspace_root().join("tests/scripts/srv_cdr.py"))
        .arg(workspace_root().join("ros/froctomap_msgs/srv"))
        .arg(&cases_path)
        .output()
        .expect("run rosbags");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let result: serde_json::Value = serde_json::from_str(text.trim()).expect("a JSON line");
    assert_eq!(result["checked"], cases.len(), "{result}");
}

#[test]
fn bad_maps_over_the_wire_are_skipped_and_the_file_stays_whole() {
    let dir = scratch();
    let received_dir = dir.path().join("received");
    std::fs::create_dir(&received_dir).expect("mkdir");
    let good: Vec<PathBuf> = ["few_voxels.bt", "coarse_leaves.bt"]
        .iter()
        .map(|name| octomap_fixture(name))
        .collect();
    let domain = random_domain();
    let mut peer = Peer::start(
        domain,
        &dir.path().join("unused.bt"),
        &good,
        &["--no-predicted"],
    );
    assert_eq!(
        peer.next_event(Duration::from_secs(30))["event"],
        "published"
    );

    let mut options = NodeOptions::new(domain);
    options.network = Network::Loopback;
    options.max_message_bytes = 64 << 10;
    let node = Node::new(&options).expect("the node joins the domain on loopback");
    let context = Context::with_default_plugins();
    let living = dir.path().join("living.froct");
    let record_options =
        froctomap_convert::RecordOptions::for_live_source(froctomap_convert::CommitEvery::Maps(2));
    let mut recorder =
        froctomap_convert::Recorder::open(&context, &living, record_options).expect("record");
    let left_out = note_left_out(&mut recorder);
    let mut sink = FilesSink {
        dir: received_dir,
        received: Vec::new(),
        skipped: Vec::new(),
        recording: RecordingSink::new(recorder, TimeSource::Header, Duration::ZERO),
    };
    receive_until(&node, &mut sink, |s| s.received.len() == 1);
    peer.command(&serde_json::json!("go"));
    assert_eq!(
        peer.next_event(Duration::from_secs(30))["event"],
        "published"
    );
    // Two maps: the base is committed.
    receive_until(&node, &mut sink, |s| s.received.len() == 2);
    let base = std::fs::read(&living).expect("the base is written");

    // The bad ones, each refused with its reason while the node goes on.
    let first = 1_700_000_000i64;
    let bt = good[0].to_string_lossy().to_string();
    let bad = [
        serde_json::json!({"call": "publish_wrong_type"}),
        serde_json::json!({"call": "publish_map", "path": bt, "stamp": first + 3, "truncate": 5}),
        serde_json::json!({"call": "publish_garbage", "stamp": first + 4, "size": 300, "binary": false}),
        serde_json::json!({"call": "publish_garbage", "stamp": first + 5, "size": 100_000, "binary": true}),
    ];
    publish(&mut peer, &bad);
    receive_until(&node, &mut sink, |s| s.skipped.len() == bad.len());
    assert_eq!(
        sink.received.len(),
        2,
        "no bad message reached the recorder"
    );
    let reasons = sink.skipped.join("\n");
    assert!(reasons.contains("over the limit"), "{reasons}");
    assert_eq!(
        std::fs::read(&living).expect("read"),
        base,
        "the file is untouched"
    );

    // A huge resolution decodes as a map but is not this file's: left out at the commit. A
    // stamp going backwards is skipped; the next good map is committed.
    publish(
        &mut peer,
        &[
            serde_json::json!({"call": "publish_map", "path": bt, "stamp": first + 6, "resolution": 1.0e300}),
            serde_json::json!({"call": "publish_map", "path": bt, "stamp": first + 2}),
            serde_json::json!({"call": "publish_map", "path": bt, "stamp": first + 7}),
        ],
    );
    receive_until(&node, &mut sink, |s| s.received.len() == 5);
    let FilesSink {
        recording, skipped, ..
    } = sink;
    assert_eq!(skipped.len(), bad.len(), "{skipped:?}");
    let summary = recording.finish().expect("the node's last commit");
    assert_eq!(
        (summary.committed_maps, summary.older),
        (3, 1),
        "{summary:?}"
    );
    let left_out = left_out.borrow();
    assert_eq!(left_out.len(), 1, "{left_out:?}");
    assert!(left_out[0].contains("resolution"), "{left_out:?}");

    assert_holds_exactly(&context, &living, dir.path(), &good, first);
}

/// Has the peer publish each of `commands`, each acknowledged by a `published` event.
fn publish(peer: &mut Peer, commands: &[serde_json::Value]) {
    for command in commands {
        peer.command(command);
        assert_eq!(
            peer.next_event(Duration::from_secs(30))["event"],
            "published"
        );
    }
}

/// The maps a commit of `recorder` leaves out, with why, as they come.
fn note_left_out(
    recorder: &mut froctomap_convert::Recorder<'_>,
) -> std::rc::Rc<std::cell::RefCell<Vec<String>>> {
    let left_out: std::rc::Rc<std::cell::RefCell<Vec<String>>> = Default::default();
    let seen = std::rc::Rc::clone(&left_out);
    recorder.on_event(move |event| match event {
        froctomap_convert::RecordEvent::Committed(commit) => seen
            .borrow_mut()
            .extend(commit.skipped.iter().map(|s| s.message.clone())),
        froctomap_convert::RecordEvent::LeftOut { what, .. } => {
            seen.borrow_mut().push(what.to_string())
        }
        _ => {}
    });
    left_out
}

/// The commits of `recorder` that failed and were tried again as halves, with why.
fn note_retries(
    recorder: &mut froctomap_convert::Recorder<'_>,
) -> std::rc::Rc<std::cell::RefCell<Vec<String>>> {
    let retried: std::rc::Rc<std::cell::RefCell<Vec<String>>> = Default::default();
    let seen = std::rc::Rc::clone(&retried);
    recorder.on_event(move |event| {
        if let froctomap_convert::RecordEvent::Retrying { what, error, .. } = event {
            seen.borrow_mut()
                .push(format!("{what}: {}", froctomap_core::error_message(error)));
        }
    });
    retried
}

/// The file reads, and holds the `good` maps (at seconds `first`, `first + 1` and
/// `first + 7`) exactly.
fn assert_holds_exactly(
    context: &Context,
    living: &Path,
    dir: &Path,
    good: &[PathBuf],
    first: i64,
) {
    let recorded = FroctFile::open(living).expect("the living map reads");
    for (stamp, map) in [
        (first, &good[0]),
        (first + 1, &good[1]),
        (first + 7, &good[0]),
    ] {
        let resolved = froctomap_convert::resolve_observed(
            &recorded,
            froctomap_convert::TimeQuery::Instant(Timestamp(stamp * 1_000_000_000)),
        )
        .expect("a map at the stamp");
        assert!(resolved.exact, "{stamp}");
        let out = dir.join(format!("{stamp}.bt"));
        froctomap_convert::write_observed_map(
            context,
            &recorded,
            resolved.sample,
            &out,
            Default::default(),
        )
        .expect("retrieve");
        assert_eq!(
            std::fs::read(&out).expect("read"),
            std::fs::read(map).expect("read"),
            "{stamp}"
        );
    }
    let maps: Vec<Option<Timestamp>> = (0..recorded.sample_count())
        .filter(|&s| !recorded.is_missing(s))
        .map(|s| recorded.sample_time(s))
        .collect();
    assert_eq!(
        maps,
        [first, first + 1, first + 7].map(|s| Some(Timestamp(s * 1_000_000_000))),
        "no other map entered the file"
    );
}

#[test]
fn a_basic_mapping_client_gets_its_map() {
    // DDS-RPC basic framing: the peer writes a RequestHeader (sample identity, instance
    // name) before the request and keeps the replies whose ReplyHeader names it.
    let dir = scratch();
    let domain = random_domain();
    let map = octomap_fixture("few_voxels.bt");
    let mut peer = Peer::start(
        domain,
        &dir.path().join("unused.bt"),
        std::slice::from_ref(&map),
        &["--no-predicted", "--service-mapping", "basic"],
    );
    assert_eq!(
        peer.next_event(Duration::from_secs(30))["event"],
        "published"
    );
    let mut options = NodeOptions::new(domain);
    options.network = Network::Loopback;
    options.service_mapping = froctomap_ros2_node::ServiceMapping::Basic;
    let node = Node::new(&options).expect("the node joins the domain on loopback");
    let froct = workspace_root().join("fixtures/froct/golden-v1.2.froct");
    let mut services = FileServices::new(&froct, "map");
    let file = FroctFile::open(&froct).expect("open");
    let t = file.sample_time(0).expect("a sample");
    let got_path = dir.path().join("got.bt");
    peer.command(&serde_json::json!({"call": "get_octomap_at",
        "sec": t.0.div_euclid(1_000_000_000), "nanosec": t.0.rem_euclid(1_000_000_000),
        "predict": false, "out": got_path}));
    let event = peer.event_while_serving(&node, &mut services, Duration::from_secs(60));
    assert_eq!(event["success"], true, "{event}");
    let retrieved = dir.path().join("retrieved.bt");
    froctomap_convert::write_observed_map(
        &Context::with_default_plugins(),
        &file,
        0,
        &retrieved,
        Default::default(),
    )
    .expect("retrieve");
    assert_eq!(
        python_leaves(&got_path, "bt"),
        python_leaves(&retrieved, "bt")
    );
}

#[test]
fn maps_in_another_frame_are_refused_and_the_node_goes_on() {
    // The first map taken fixes the frame (one file holds one frame); a map in another frame
    // is skipped with the reason, and the next map in the frame is recorded.
    let dir = scratch();
    let received_dir = dir.path().join("received");
    std::fs::create_dir(&received_dir).expect("mkdir");
    let map = octomap_fixture("few_voxels.bt");
    let domain = random_domain();
    let mut peer = Peer::start(
        domain,
        &dir.path().join("unused.bt"),
        std::slice::from_ref(&map),
        &["--no-predicted"],
    );
    assert_eq!(
        peer.next_event(Duration::from_secs(30))["event"],
        "published"
    );
    let mut options = NodeOptions::new(domain);
    options.network = Network::Loopback;
    let node = Node::new(&options).expect("the node joins the domain on loopback");
    assert_eq!(node.frame_id(), None, "no frame before the first map");
    let context = Context::with_default_plugins();
    let living = dir.path().join("living.froct");
    let recorder = froctomap_convert::Recorder::open(
        &context,
        &living,
        froctomap_convert::RecordOptions::for_live_source(froctomap_convert::CommitEvery::Maps(10)),
    )
    .expect("record");
    let mut sink = FilesSink {
        dir: received_dir,
        received: Vec::new(),
        skipped: Vec::new(),
        recording: RecordingSink::new(recorder, TimeSource::Header, Duration::ZERO),
    };
    receive_until(&node, &mut sink, |s| s.received.len() == 1);
    assert_eq!(
        node.frame_id().as_deref(),
        Some("map"),
        "the first map's frame"
    );

    let first = 1_700_000_000i64;
    let bt = map.to_string_lossy().to_string();
    for (stamp, frame) in [(first + 1, "odom"), (first + 2, "map"), (first + 3, "")] {
        peer.command(
            &serde_json::json!({"call": "publish_map", "path": bt, "stamp": stamp,
            "frame_id": frame}),
        );
        assert_eq!(
            peer.next_event(Duration::from_secs(30))["event"],
            "published"
        );
    }
    receive_until(&node, &mut sink, |s| {
        s.received.len() + s.skipped.len() == 4
    });
    let FilesSink {
        recording,
        received,
        skipped,
        ..
    } = sink;
    assert_eq!(skipped.len(), 2, "{skipped:?}");
    assert!(
        skipped[0].contains("frame `odom`, not `map`"),
        "{skipped:?}"
    );
    assert!(skipped[1].contains("frame ``, not `map`"), "{skipped:?}");
    assert!(received.iter().all(|m| m.frame_id == "map"));
    assert_eq!(node.frame_id().as_deref(), Some("map"));
    let summary = recording.finish().expect("commit");
    assert_eq!(summary.committed_maps, 2, "{summary:?}");
    let recorded = FroctFile::open(&living).expect("the living map reads");
    let times: Vec<Option<Timestamp>> = (0..recorded.sample_count())
        .filter(|&s| !recorded.is_missing(s))
        .map(|s| recorded.sample_time(s))
        .collect();
    assert_eq!(
        times,
        [first, first + 2].map(|s| Some(Timestamp(s * 1_000_000_000))),
        "only the maps in the first map's frame entered the file"
    );

    // A frame given up front (`--frame-id`): the maps in another one are refused from the
    // first, the latched map of the peer included.
    let mut options = NodeOptions::new(domain);
    options.network = Network::Loopback;
    options.frame_id = Some("odom".to_string());
    let strict = Node::new(&options).expect("a second node");
    struct Count(usize, Vec<String>);
    impl MapSink for Count {
        fn receive(
            &mut self,
            _: ReceivedMap,
        ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            self.0 += 1;
            Ok(())
        }
        fn skipped(&mut self, reason: String) {
            self.1.push(reason);
        }
    }
    let mut count = Count(0, Vec::new());
    let deadline = Instant::now() + Duration::from_secs(60);
    while count.1.is_empty() && Instant::now() < deadline {
        strict
            .receive_into(&mut count, Duration::from_millis(100))
            .expect("receive");
    }
    assert_eq!(count.0, 0, "{:?}", count.1);
    assert!(
        count.1.iter().all(|r| r.contains("not `odom`")) && !count.1.is_empty(),
        "{:?}",
        count.1
    );
}

#[test]
fn remapped_names_parameters_and_sim_time_as_ros_args_say() {
    // `--ros-args -r __ns:=/robot1 -r __node:=mapper -r octomap_binary:=maps_in -p
    // horizon:=1h` with use_sim_time: the peer publishes on /robot1/maps_in, finds the
    // predicted map and the services under /robot1/mapper, reads the parameters through
    // rcl_interfaces' GetParameters, and its /clock sets the predicted map's time.
    let dir = scratch();
    let domain = random_domain();
    let args: Vec<String> = [
        "-r",
        "__ns:=/robot1",
        "-r",
        "__node:=mapper",
        "-r",
        "octomap_binary:=maps_in",
        "-p",
        "horizon:=1h",
        "-p",
        "use_sim_time:=true",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let ros = froctomap_ros2_node::RosArgs::parse(&args).expect("ROS arguments");
    let clock_sec = 1_600_000_000i64;
    let predicted_out = dir.path().join("predicted.bt");
    let map = octomap_fixture("few_voxels.bt");
    let mut peer = Peer::start(
        domain,
        &predicted_out,
        std::slice::from_ref(&map),
        &[
            "--topic",
            "/robot1/maps_in",
            "--node",
            "/robot1/mapper",
            "--clock",
            &clock_sec.to_string(),
        ],
    );
    assert_eq!(
        peer.next_event(Duration::from_secs(30))["event"],
        "published"
    );
    let mut options = NodeOptions::new(domain);
    options.network = Network::Loopback;
    options.use_sim_time = ros.parameter("use_sim_time").is_some_and(|v| v.bool_value);
    for (name, value) in &ros.parameters {
        options.parameters.set(name, value.clone(), "");
    }
    options.names = ros;
    let node = Node::new(&options).expect("the node joins the domain on loopback");
    assert_eq!(node.names().node, "/robot1/mapper");
    assert_eq!(node.names().topic, "/robot1/maps_in");
    assert_eq!(node.names().predicted, "/robot1/mapper/predicted");

    assert_map_arrives_on_the_remapped_topic(&node);
    let froct = workspace_root().join("fixtures/froct/golden-v1.2.froct");
    assert_predicted_map_is_at_clock_now(&node, &peer, clock_sec, &froct);
    let mut services = FileServices::new(&froct, "map");
    assert_parameters_are_served(&mut peer, &node, &mut services);
    assert_node_is_in_the_ros_graph(&mut peer, &node, &mut services);
}

/// The map arrives on the remapped topic in the namespace.
fn assert_map_arrives_on_the_remapped_topic(node: &Node) {
    struct Count(Vec<ReceivedMap>);
    impl MapSink for Count {
        fn receive(
            &mut self,
            map: ReceivedMap,
        ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            self.0.push(map);
            Ok(())
        }
    }
    let mut got = Count(Vec::new());
    let deadline = Instant::now() + Duration::from_secs(60);
    while got.0.is_empty() && Instant::now() < deadline {
        node.receive_into(&mut got, Duration::from_millis(100))
            .expect("receive");
    }
    assert_eq!(got.0.len(), 1, "the map on /robot1/maps_in");
    assert_eq!(
        got.0[0].stamp,
        Timestamp(1_700_000_000 * 1_000_000_000),
        "the peer's map"
    );
}

/// "Now" is /clock's time, not the system's; the predicted map is at now + horizon.
fn assert_predicted_map_is_at_clock_now(node: &Node, peer: &Peer, clock_sec: i64, froct: &Path) {
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut now = node.now();
    while now.is_none() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(50));
        now = node.now();
    }
    assert_eq!(now, Some(Timestamp(clock_sec * 1_000_000_000)), "/clock");
    let horizon = froctomap_convert::parse_duration(
        &node
            .parameters()
            .get("horizon")
            .expect("the horizon parameter")
            .as_text(),
    )
    .expect("a duration");
    let t = Timestamp(clock_sec * 1_000_000_000 + horizon);
    let mut predicted = PredictedPublisher::new(froct, "map");
    assert!(predicted
        .publish_if_changed(node, t)
        .expect("publish")
        .is_some());
    let event = peer.next_event(Duration::from_secs(60));
    assert_eq!(event["event"], "predicted", "{event}");
    assert_eq!(
        event["stamp"],
        clock_sec + 3600,
        "the predicted map is at /clock's now + 1 h"
    );
}

/// The parameters, through rcl_interfaces/srv/GetParameters and ListParameters.
fn assert_parameters_are_served(peer: &mut Peer, node: &Node, services: &mut FileServices) {
    peer.command(&serde_json::json!({"call": "list_parameters"}));
    let event = peer.event_while_serving(node, services, Duration::from_secs(60));
    assert_eq!(
        event["names"],
        serde_json::json!(["horizon", "use_sim_time"]),
        "{event}"
    );
    peer.command(&serde_json::json!({"call": "get_parameters",
        "names": ["horizon", "use_sim_time", "no_such_parameter"]}));
    let event = peer.event_while_serving(node, services, Duration::from_secs(60));
    let values = event["values"].as_array().expect("values");
    assert_eq!(values.len(), 3, "{event}");
    assert_eq!(
        (&values[0]["type"], &values[0]["string"]),
        (&serde_json::json!(4), &serde_json::json!("1h"))
    );
    assert_eq!(
        (&values[1]["type"], &values[1]["bool"]),
        (&serde_json::json!(1), &serde_json::json!(true))
    );
    assert_eq!(values[2]["type"], 0, "NOT_SET");
}

/// The node's entry in the ROS graph (what `ros2 node list` and `ros2 param` look it up
/// in): its namespace and name, its participant's GUID as Cyclone discovered it, and the
/// predicted map's writer among its writers.
fn assert_node_is_in_the_ros_graph(peer: &mut Peer, node: &Node, services: &mut FileServices) {
    peer.command(&serde_json::json!({"call": "graph"}));
    let event = peer.event_while_serving(node, services, Duration::from_secs(60));
    let entries = event["entries"].as_array().expect("entries");
    assert_eq!(entries.len(), 1, "{event}");
    let entry = &entries[0];
    assert_eq!(entry["nodes"].as_array().map(Vec::len), Some(1), "{event}");
    let info = &entry["nodes"][0];
    assert_eq!(
        (&info["namespace"], &info["name"]),
        (&serde_json::json!("/robot1"), &serde_json::json!("mapper"))
    );
    let participants = event["participants"].as_array().expect("participants");
    assert!(participants.contains(&entry["gid"]), "{event}");
    let predicted_writer = event["publications"]
        .as_object()
        .expect("publications")
        .iter()
        .find(|(_, topic)| *topic == "rt/robot1/mapper/predicted")
        .map(|(guid, _)| serde_json::json!(guid))
        .expect("Cyclone discovered the predicted map's writer");
    let writers = info["writers"].as_array().expect("writers");
    assert!(writers.contains(&predicted_writer), "{event}");
    assert_eq!(
        writers.len(),
        10,
        "predicted, dynamic, 8 service replies: {event}"
    );
    assert_eq!(
        info["readers"].as_array().map(Vec::len),
        Some(10),
        "maps, /clock, 8 service requests: {event}"
    );
}
