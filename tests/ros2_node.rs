//! The ROS 2 node against an independent ROS 2 peer: Eclipse Cyclone DDS (PyPI `cyclonedds`,
//! the DDS under rmw_cyclonedds_cpp) with `octomap_msgs/msg/Octomap` declared in Python
//! (tests/scripts/ros2_peer.py). All traffic on loopback: the peer on interface `lo` without
//! multicast and with the peer 127.0.0.1, the node with [`Network::Loopback`], a domain id of
//! its own per run.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_ros2_node::{MapSink, Network, Node, NodeOptions, PredictedPublisher, ReceivedMap};
use froctomap_test_support::{
    octomap_fixture, octomap_python, python_leaves, scratch, workspace_root,
};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Writes each map it receives to `dir`, named by its stamp.
struct FilesSink {
    dir: PathBuf,
    received: Vec<ReceivedMap>,
    skipped: Vec<String>,
}

impl MapSink for FilesSink {
    fn receive(
        &mut self,
        map: ReceivedMap,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let ext = if map.binary { "bt" } else { "ot" };
        std::fs::write(self.dir.join(format!("{}.{ext}", map.stamp.0)), &map.file)?;
        self.received.push(map);
        Ok(())
    }

    fn skipped(&mut self, reason: String) {
        self.skipped.push(reason);
    }
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
    fn start(domain: u16, predicted_out: &Path, maps: &[PathBuf]) -> Peer {
        let mut child = Command::new(octomap_python())
            .arg(workspace_root().join("tests/scripts/ros2_peer.py"))
            .args(["--domain", &domain.to_string(), "--timeout", "60"])
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

    // The peer publishes the first map before the node exists: it must arrive latched
    // (transient-local); the others are published live.
    let mut peer = Peer::start(domain, &predicted_out, &maps);
    let event = peer.next_event(Duration::from_secs(30));
    assert_eq!(event["event"], "published", "{event}");

    let mut options = NodeOptions::new(domain);
    options.network = Network::Loopback;
    let node = Node::new(&options).expect("the node joins the domain on loopback");
    let froct = workspace_root().join("fixtures/froct/golden-v1.2.froct");
    let mut predicted = PredictedPublisher::new(&froct, "map");
    let t = froctomap_ros2_node::last_instant(&froct).expect("read the .froct");
    assert!(predicted.publish_if_changed(&node, t).expect("publish"));
    assert!(
        !predicted
            .publish_if_changed(&node, t)
            .expect("publish again"),
        "unchanged maps are not republished"
    );

    let mut sink = FilesSink {
        dir: received_dir.clone(),
        received: Vec::new(),
        skipped: Vec::new(),
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

    // Each map arrives whole: the file the sink got is the one the peer published.
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

    // The peer got the latched predicted map and upstream OctoMap reads it.
    let event = peer.next_event(Duration::from_secs(60));
    assert_eq!(event["event"], "predicted", "{event}");
    let sent = predicted.predicted_bt(t).expect("predict");
    let got = std::fs::read(&predicted_out).expect("the peer wrote the predicted map");
    let at = |file: &[u8]| {
        file.windows(6)
            .position(|w| w == b"\ndata\n")
            .expect("data")
            + 6
    };
    assert_eq!(
        got[at(&got)..],
        sent[at(&sent)..],
        "the predicted map's data arrived unchanged"
    );
    let (resolution, leaves) = python_leaves(&predicted_out, "bt");
    assert!(
        resolution > 0.0 && !leaves.is_empty(),
        "octomap-python reads the predicted map"
    );
    let ours = dir.path().join("ours.bt");
    std::fs::write(&ours, &sent).expect("write");
    assert_eq!(python_leaves(&ours, "bt"), (resolution, leaves));

    // Loopback only: no socket of the peer or of this process is bound to an address other
    // than 127.0.0.1 or the wildcard (RustDDS binds the wildcard; see docs/ROS.md).
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
