//! `froctomap ros2 --foxglove PORT` (cargo feature `foxglove`): the predicted map on a
//! Foxglove WebSocket server (the Foxglove SDK), so the Foxglove app shows it without ROS.
//!
//! One channel, [`POINT_CLOUD_TOPIC`]: the predicted map's occupied voxels as the MCAP
//! export writes them (`foxglove.PointCloud` in JSON, one point per voxel with its
//! probability `p`, coloured from purple at 0.5 to yellow at 1: the cells that change are
//! the ones below 1), so one Foxglove layout serves exported files and the live node.

use anyhow::Context as _;
use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{
    ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, WebSocketServer,
    WebSocketServerHandle,
};
use froctomap_core::Timestamp;
use froctomap_ros::{
    point_cloud_json, POINT_CLOUD_JSON_SCHEMA, POINT_CLOUD_SCHEMA, POINT_CLOUD_TOPIC,
};
use froctomap_ros2_node::PublishedCells;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The Foxglove WebSocket server and its channel.
pub struct FoxgloveView {
    /// Kept: the server holds it weakly, and subscriptions reach the channel through it.
    _context: Arc<Context>,
    server: WebSocketServerHandle,
    cloud: Arc<RawChannel>,
    /// The last message logged and its time: channels do not latch, so a client that
    /// subscribes later gets it again.
    last: Option<(Vec<u8>, Timestamp)>,
    subscribed: Arc<AtomicBool>,
}

/// Notes a subscription, for the loop to log the last message again.
struct Subscriptions(Arc<AtomicBool>);

impl ServerListener for Subscriptions {
    fn on_subscribe(&self, _client: Client, _channel: ChannelView) {
        self.0.store(true, Ordering::SeqCst);
    }
}

impl FoxgloveView {
    /// A server listening on `address:port` (0: a free port, see [`Self::port`]).
    pub fn start(address: &str, port: u16) -> anyhow::Result<Self> {
        // A context of its own: nothing else logged in the process reaches the clients.
        let context = Context::new();
        let subscribed = Arc::new(AtomicBool::new(false));
        let cloud = ChannelBuilder::new(POINT_CLOUD_TOPIC)
            .context(&context)
            .message_encoding("json")
            .schema(Schema::new(
                POINT_CLOUD_SCHEMA,
                "jsonschema",
                POINT_CLOUD_JSON_SCHEMA.as_bytes(),
            ))
            .build_raw()
            .context("--foxglove: the point cloud channel")?;
        let server = WebSocketServer::new()
            .name("froctomap")
            .context(&context)
            .bind(address, port)
            .listener(Arc::new(Subscriptions(Arc::clone(&subscribed))))
            .start_blocking()
            .with_context(|| format!("--foxglove: cannot listen on {address}:{port}"))?;
        Ok(Self {
            _context: context,
            server,
            cloud,
            last: None,
            subscribed,
        })
    }

    /// The port the server listens on.
    pub fn port(&self) -> u16 {
        self.server.port()
    }

    /// Logs the occupied voxels of the map predicted for `t` (as the node published them),
    /// stamped `t`.
    pub fn show_predicted(
        &mut self,
        published: &PublishedCells,
        t: Timestamp,
        frame_id: &str,
    ) -> anyhow::Result<()> {
        let message = point_cloud_json(t, frame_id, published.resolution, &published.occupied)
            .context("--foxglove: the predicted map")?;
        self.log(&message, t);
        self.last = Some((message, t));
        Ok(())
    }

    /// Logs the last message again if a client subscribed since the last call.
    pub fn tick(&mut self) {
        if self.subscribed.swap(false, Ordering::SeqCst) {
            if let Some((message, t)) = &self.last {
                self.log(message, *t);
            }
        }
    }

    fn log(&self, message: &[u8], t: Timestamp) {
        let log_time = u64::try_from(t.0).ok();
        self.cloud
            .log_with_meta(message, PartialMetadata { log_time });
    }
}
