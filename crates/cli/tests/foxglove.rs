//! `froctomap ros2 FILE --foxglove PORT` (cargo feature `foxglove`): a WebSocket client
//! (tungstenite, speaking the Foxglove WebSocket protocol itself) on loopback offers both
//! names of the protocol as the Foxglove app does (`foxglove.websocket.v1`, the ws-protocol
//! name, and `foxglove.sdk.v1`, the same protocol as the Foxglove SDK names it and only
//! accepts), receives the server's advertisement, subscribes to the point-cloud channel
//! and decodes its message; its voxels and probabilities are those of the map `froctomap
//! predict` writes for the message's time, as octomap-python reads them from the `.ot`. A
//! client that subscribes after the publication gets the same message (channels do not
//! latch; the view sends the last one again).
#![cfg(all(unix, feature = "foxglove"))]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use base64::Engine as _;
use common::{lines, ok, random_domain, s, wait_for, Reap};
use froctomap_test_support::{octomap_fixture, octomap_python, scratch};
use std::collections::BTreeMap;
use std::net::TcpStream;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;
use tungstenite::client::IntoClientRequest as _;
use tungstenite::Message;

/// The occupied voxels of an `.ot` file as octomap-python reads them: a line with the
/// resolution and the clamping bounds, then one line per voxel, its integer position
/// (centre / resolution, floored) and its leaf's occupancy.
const OCCUPIED_VOXELS: &str = r#"
import sys, math, octomap
tree = octomap.OcTree.read(sys.argv[1].encode())
if tree is None:
    sys.exit("read failed")
res = tree.getResolution()
print(res, tree.getClampingThresMin(), tree.getClampingThresMax())
for leaf in tree.begin_leafs():
    if not tree.isNodeOccupied(leaf):
        continue
    n = round(leaf.getSize() / res)
    low = [math.floor((c - leaf.getSize() / 2) / res + 0.5) for c in leaf.getCoordinate()]
    for i in range(n):
        for j in range(n):
            for k in range(n):
                print(low[0] + i, low[1] + j, low[2] + k, leaf.getOccupancy())
"#;

type Voxels = BTreeMap<(i64, i64, i64), f64>;

/// The next message of the socket, failing after a minute.
fn next(socket: &mut tungstenite::WebSocket<TcpStream>) -> Message {
    socket
        .read()
        .unwrap_or_else(|e| panic!("no message from the Foxglove server within a minute: {e}"))
}

/// A client of the server at `address` (host:port), the handshake done.
fn connect(address: &str) -> tungstenite::WebSocket<TcpStream> {
    let stream = TcpStream::connect(address).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(60)))
        .unwrap();
    let mut request = format!("ws://{address}").into_client_request().unwrap();
    request.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        "foxglove.websocket.v1, foxglove.sdk.v1".parse().unwrap(),
    );
    let (socket, response) = tungstenite::client(request, stream).expect("handshake");
    assert_eq!(
        response.headers().get("Sec-WebSocket-Protocol").unwrap(),
        "foxglove.sdk.v1"
    );
    socket
}

/// The advertised channel (checked), subscribed as `subscription`: its first messageData
/// frame (opcode 1, the subscription as u32, the log time as u64, the message).
fn first_message(
    socket: &mut tungstenite::WebSocket<TcpStream>,
    subscription: u32,
) -> tungstenite::Bytes {
    // serverInfo, then the advertisement of the channel.
    let channel = loop {
        let Message::Text(text) = next(socket) else {
            continue;
        };
        let message: serde_json::Value = serde_json::from_str(text.as_str()).unwrap();
        if message["op"] == "advertise" {
            let channels = message["channels"].as_array().unwrap();
            assert_eq!(channels.len(), 1, "{message}");
            break channels[0].clone();
        }
    };
    assert_eq!(channel["topic"], "/froctomap/occupied_voxels", "{channel}");
    assert_eq!(channel["encoding"], "json", "{channel}");
    assert_eq!(channel["schemaName"], "foxglove.PointCloud", "{channel}");
    assert_eq!(channel["schemaEncoding"], "jsonschema", "{channel}");
    let subscribe = serde_json::json!({"op": "subscribe",
        "subscriptions": [{"id": subscription, "channelId": channel["id"]}]});
    socket
        .send(Message::Text(subscribe.to_string().into()))
        .unwrap();
    let data = loop {
        if let Message::Binary(data) = next(socket) {
            break data;
        }
    };
    assert_eq!(data[0], 1, "not a messageData frame");
    assert_eq!(
        u32::from_le_bytes(data[1..5].try_into().unwrap()),
        subscription
    );
    data
}

/// The map `froctomap predict` writes for `time`, read by upstream's Python binding: its
/// resolution, clamping bounds and occupied voxels.
fn predicted_voxels(dir: &Path, file: &Path, time: &str) -> (f64, f64, f64, Voxels) {
    let predicted = dir.join("predicted.ot");
    ok(&[
        "-q",
        "predict",
        s(file),
        "--time",
        time,
        "-o",
        s(&predicted),
    ]);
    let out = Command::new(octomap_python())
        .args(["-c", OCCUPIED_VOXELS])
        .arg(&predicted)
        .output()
        .expect("run octomap-python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = String::from_utf8(out.stdout).unwrap();
    let mut out = out.lines();
    let numbers = |line: &str| -> Vec<f64> {
        line.split_whitespace()
            .map(|v| v.parse::<f64>().unwrap())
            .collect()
    };
    let [resolution, clamp_min, clamp_max] = numbers(out.next().expect("the header line"))[..]
    else {
        panic!("no resolution and clamping bounds")
    };
    let expected: Voxels = out
        .map(|line| {
            let v = numbers(line);
            ((v[0] as i64, v[1] as i64, v[2] as i64), v[3])
        })
        .collect();
    (resolution, clamp_min, clamp_max, expected)
}

#[test]
fn a_foxglove_client_receives_the_predicted_map() {
    let dir = scratch();
    // Two maps taking turns hourly: the cells only one holds have a probability below 1.
    let inputs = dir.path().join("maps");
    std::fs::create_dir(&inputs).unwrap();
    for hour in 0..8u64 {
        let map = ["few_voxels.bt", "coarse_leaves.bt"][hour as usize % 2];
        std::fs::copy(
            octomap_fixture(map),
            inputs.join(format!("map_{}.bt", 1_700_000_000 + hour * 3600)),
        )
        .unwrap();
    }
    let file = dir.path().join("series.froct");
    ok(&["-q", "build", s(&inputs), "-o", s(&file)]);

    let mut children = Reap(Vec::new());
    let mut node = Command::new(env!("CARGO_BIN_EXE_froctomap"))
        // One publication (at the start): later subscribers get it again, not a new one.
        .args(["ros2", s(&file), "--no-record", "--publish-every", "1h"])
        .args(["--foxglove", "0"])
        .env("ROS_DOMAIN_ID", random_domain().to_string())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the node");
    let log = lines(node.stderr.take().expect("stderr"));
    children.0.push(node);
    let line = wait_for(&log, |l| l.starts_with("Foxglove WebSocket server on"));
    let address = line
        .split_whitespace()
        .find_map(|w| w.strip_prefix("ws://"))
        .and_then(|a| a.strip_suffix(':'))
        .unwrap_or_else(|| panic!("no address in `{line}`"));
    assert!(address.starts_with("127.0.0.1:"), "{line}");

    let mut socket = connect(address);
    let data = first_message(&mut socket, 7);
    let log_time = u64::from_le_bytes(data[5..13].try_into().unwrap());
    let cloud: serde_json::Value = serde_json::from_slice(&data[13..]).unwrap();
    let (sec, nsec) = (
        cloud["timestamp"]["sec"].as_u64().unwrap(),
        cloud["timestamp"]["nsec"].as_u64().unwrap(),
    );
    assert_eq!(log_time, sec * 1_000_000_000 + nsec);
    let stride = cloud["point_stride"].as_u64().unwrap() as usize;
    let offset = |name: &str| {
        cloud["fields"]
            .as_array()
            .unwrap()
            .iter()
            .find(|f| f["name"] == name)
            .unwrap_or_else(|| panic!("no field {name}: {}", cloud["fields"]))["offset"]
            .as_u64()
            .unwrap() as usize
    };
    let (x, p) = (offset("x"), offset("p"));
    let points = base64::engine::general_purpose::STANDARD
        .decode(cloud["data"].as_str().unwrap())
        .unwrap();
    assert_eq!(points.len() % stride, 0);
    let f32_at = |at: usize| f32::from_le_bytes(points[at..at + 4].try_into().unwrap());

    let (resolution, clamp_min, clamp_max, expected) =
        predicted_voxels(dir.path(), &file, &format!("{sec}.{nsec:09}"));
    let got: Voxels = (0..points.len() / stride)
        .map(|i| {
            let at = i * stride;
            let key =
                |axis: usize| (f64::from(f32_at(at + x + 4 * axis)) / resolution).floor() as i64;
            ((key(0), key(1), key(2)), f64::from(f32_at(at + p)))
        })
        .collect();
    assert!(
        !expected.is_empty(),
        "the predicted map has no occupied voxel"
    );
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>(),
        "the voxels of the Foxglove point cloud and of `froctomap predict`"
    );
    // The .ot holds p(t) within OctoMap's clamping bounds (as upstream stores log-odds).
    for (key, p) in &expected {
        let clamped = got[key].clamp(clamp_min, clamp_max);
        assert!(
            (clamped - p).abs() < 1e-4,
            "{key:?}: {} against {p}",
            got[key]
        );
    }
    // The maps alternate: some cells are certain, some not.
    assert!(got.values().any(|&p| p < 0.99), "{got:?}");

    // A client subscribing after the publication gets the same message.
    let mut late = connect(address);
    let again = first_message(&mut late, 3);
    assert_eq!(
        again[5..],
        data[5..],
        "the message sent again to a later subscriber"
    );
    drop((socket, late));
}
