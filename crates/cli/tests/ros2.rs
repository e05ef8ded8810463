//! `froctomap ros2 FILE` (cargo feature `ros2`) against the Cyclone DDS peer of
//! tests/scripts/ros2_peer.py, all on loopback with a domain of its own: the maps the peer
//! publishes are committed into FILE (created by the first commit, a line per commit), the
//! node answers `get_octomap_at` from the living file, and SIGTERM commits the map received
//! (acknowledged to the peer) but not committed yet, and exits 0; the file then retrieves
//! each map byte-identical.
#![cfg(all(unix, feature = "ros2"))]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use common::{lines, ok, random_domain, s, wait_for, Reap};
use froctomap_test_support::{octomap_fixture, octomap_python, scratch, workspace_root};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::Receiver;

#[test]
fn the_node_records_serves_and_stops_on_sigterm() {
    let dir = scratch();
    let maps = [
        octomap_fixture("few_voxels.bt"),
        octomap_fixture("coarse_leaves.bt"),
        octomap_fixture("few_voxels.bt"),
    ];
    let domain = random_domain();
    let mut children = Reap(Vec::new());
    let mut peer = robot1_peer(domain, &dir.path().join("unused.bt"), &maps[..2]);
    let events = lines(peer.stdout.take().expect("stdout"));
    let mut stdin = peer.stdin.take().expect("stdin");
    children.0.push(peer);
    wait_for(&events, |l| l.contains("\"published\""));

    let living = dir.path().join("living.froct");
    // Two maps a commit (a ROS parameter here): the third one is still gathered when
    // SIGTERM comes. In the namespace /robot1: the maps on /robot1/octomap_binary, the
    // services under /robot1/froctomap.
    let mut node = Command::new(env!("CARGO_BIN_EXE_froctomap"))
        .args([
            "ros2",
            s(&living),
            "--publish-every",
            "1s",
            "--ros-args",
            "-r",
            "__ns:=/robot1",
            "-p",
            "commit_every:=2",
        ])
        .env("ROS_DOMAIN_ID", domain.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start the node");
    let commits = lines(node.stdout.take().expect("stdout"));
    let node_id = node.id();
    children.0.push(node);
    writeln!(stdin, "go").expect("tell the peer");
    let base = wait_for(&commits, |_| true);
    assert!(base.starts_with("base: 2 maps"), "{base}");

    // The node answers from the living file it records.
    let got = dir.path().join("got.bt");
    writeln!(
        stdin,
        "{}",
        serde_json::json!({"call": "get_octomap_at", "sec": 1_700_000_000, "nanosec": 0,
            "predict": false, "out": got})
    )
    .expect("call");
    let reply = wait_for(&events, |l| l.contains("get_octomap_at"));
    assert!(reply.contains("\"success\": true"), "{reply}");
    assert_eq!(tree_bytes(&got), tree_bytes(&maps[0]));

    assert_parameters(&mut stdin, &events, &living);

    // A second client, while the first one's reply reader stays matched: its reply waits for
    // its own reply reader (a reply written before that is lost to it). Its latched map is
    // not later than the last one taken: skipped.
    let mut second = robot1_peer(domain, &dir.path().join("unused2.bt"), &maps[..1]);
    let second_events = lines(second.stdout.take().expect("stdout"));
    let mut second_stdin = second.stdin.take().expect("stdin");
    children.0.push(second);
    let got2 = dir.path().join("got2.bt");
    writeln!(
        second_stdin,
        "{}",
        serde_json::json!({"call": "get_octomap_at", "sec": 1_700_000_001, "nanosec": 0,
            "predict": false, "out": got2})
    )
    .expect("call");
    let reply = wait_for(&second_events, |l| l.contains("get_octomap_at"));
    assert!(reply.contains("\"success\": true"), "{reply}");
    assert_eq!(tree_bytes(&got2), tree_bytes(&maps[1]));
    drop(second_stdin);

    // A third map, acknowledged by the node's reader, then SIGTERM before its commit is due.
    writeln!(
        stdin,
        "{}",
        serde_json::json!({"call": "publish_map", "path": maps[2], "stamp": 1_700_000_002})
    )
    .expect("publish");
    let published = wait_for(&events, |l| l.contains("\"acked\""));
    assert!(published.contains("\"acked\": true"), "{published}");
    let killed = Command::new("kill")
        .args(["-TERM", &node_id.to_string()])
        .status()
        .expect("kill");
    assert!(killed.success());
    let last = wait_for(&commits, |_| true);
    assert!(last.starts_with("segment 1: 1 maps"), "{last}");
    let status = children.0[1].wait().expect("wait");
    let _ = children.0[2].wait();
    assert!(status.success(), "{status}");
    drop(stdin);
    let _ = children.0[0].wait();

    for (i, map) in maps.iter().enumerate() {
        let out = dir.path().join(format!("{i}.bt"));
        let time = (1_700_000_000 + i).to_string();
        ok(&["-q", "retrieve", s(&living), "--time", &time, "-o", s(&out)]);
        assert_eq!(
            std::fs::read(&out).expect("read"),
            std::fs::read(map).expect("read"),
            "{}",
            map.display()
        );
    }
}

/// The Cyclone DDS peer in namespace /robot1, publishing `maps` when told "go".
fn robot1_peer(domain: u32, predicted_out: &Path, maps: &[PathBuf]) -> Child {
    Command::new(octomap_python())
        .arg(workspace_root().join("tests/scripts/ros2_peer.py"))
        .args(["--domain", &domain.to_string(), "--no-predicted"])
        .args([
            "--topic",
            "/robot1/octomap_binary",
            "--node",
            "/robot1/froctomap",
        ])
        .arg("--predicted-out")
        .arg(predicted_out)
        .args(maps)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("start the peer")
}

/// A .bt file's tree: what follows its `data` line.
fn tree_bytes(path: &Path) -> Vec<u8> {
    let file = std::fs::read(path).expect("read");
    let at = file
        .windows(6)
        .position(|w| w == b"\ndata\n")
        .expect("data")
        + 6;
    file[at..].to_vec()
}

/// The node's parameters, read as `ros2 param get` reads them (rcl_interfaces GetParameters).
fn assert_parameters(stdin: &mut ChildStdin, events: &Receiver<String>, living: &Path) {
    writeln!(
        stdin,
        "{}",
        serde_json::json!({"call": "get_parameters", "names": ["commit_every", "use_sim_time", "file"]})
    )
    .expect("call");
    let reply = wait_for(events, |l| l.contains("get_parameters"));
    let reply: serde_json::Value = serde_json::from_str(&reply).expect("JSON");
    assert_eq!(reply["values"][0]["string"], "2", "{reply}");
    assert_eq!(
        (&reply["values"][1]["type"], &reply["values"][1]["bool"]),
        (&serde_json::json!(1), &serde_json::json!(false)),
        "{reply}"
    );
    assert_eq!(reply["values"][2]["string"], s(living), "{reply}");
}

#[test]
fn the_message_size_limit_is_an_option_of_at_least_one_byte() {
    let dir = scratch();
    let living = dir.path().join("living.froct");
    let refused = common::fails(&["ros2", s(&living), "--max-message-bytes", "0"]);
    assert!(refused.contains("at least 1 byte"), "{refused}");
    let refused = common::fails(&["ros2", s(&living), "--max-message-bytes", "lots"]);
    assert!(refused.contains("--max-message-bytes"), "{refused}");
    assert!(!living.exists());
}

#[test]
fn bad_ros_args_are_refused_by_name() {
    let dir = scratch();
    let living = dir.path().join("living.froct");
    for (args, said) in [
        (&["-p", "no_such:=1"][..], "no parameter `no_such`"),
        (&["-p", "use_sim_time:=maybe"], "true or false"),
        (&["-p", "commit_every:=0"], "commit_every"),
        (&["-p", "tile_budget:=0"], "tile_budget"),
        (&["-r", "__ns:=robot1"], "absolute"),
        (&["--no-such-argument"], "--no-such-argument"),
    ] {
        let mut line = vec!["ros2", s(&living), "--ros-args"];
        line.extend_from_slice(args);
        let refused = common::fails(&line);
        assert!(refused.contains(said), "{args:?}: {refused}");
    }
    assert!(!living.exists());
}
