//! `froctomap ros2 FILE`: the ROS 2 node (cargo feature `ros2`). It publishes the map FILE
//! predicts, answers the services from FILE, and receives maps without recording them yet:
//! the recording sink comes with `record`'s `Recorder`.

use crate::ui::Ui;
use anyhow::Context as _;
use froctomap_convert::parse_duration;
use froctomap_core::Timestamp;
use froctomap_ros2_node::{
    domain_id_from_env, FileServices, MapSink, Network, Node, NodeOptions, PredictedPublisher,
    ReceivedMap, ServiceMapping,
};
use std::net::IpAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Arguments of `froctomap ros2`.
#[derive(clap::Args)]
pub struct Ros2Args {
    /// The FROctomap file whose predicted map is published on /froctomap/predicted.
    file: PathBuf,
    /// The topic of the maps received (octomap_msgs/msg/Octomap).
    #[arg(long, default_value = froctomap_ros2_node::DEFAULT_TOPIC)]
    topic: String,
    /// How often the predicted map is computed (published only when it changed).
    #[arg(long, value_name = "DURATION", default_value = "10s")]
    publish_every: String,
    /// The predicted map is the one at now + HORIZON (0: as the model expects it now).
    #[arg(long, value_name = "DURATION", default_value = "0")]
    horizon: String,
    /// Network interfaces: `lo` (127.0.0.1 only, the default), `all`, or interface
    /// addresses separated by commas.
    #[arg(long, value_name = "lo|all|ADDR,...", default_value = "lo")]
    network: String,
    /// The frame of the published maps.
    #[arg(long, default_value = "map")]
    frame_id: String,
    /// How service requests and replies are framed: `cyclone` (rmw_cyclonedds), `enhanced`
    /// (DDS-RPC enhanced: rmw_fastrtps, rmw_connextdds) or `basic` (DDS-RPC basic).
    #[arg(long, value_name = "cyclone|enhanced|basic", default_value = "cyclone")]
    service_mapping: ServiceMapping,
}

/// Logs each map received; appending it to FILE comes with `record`.
struct LogReceived;

impl MapSink for LogReceived {
    fn receive(
        &mut self,
        map: ReceivedMap,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        eprintln!(
            "received a map stamped {} ({} bytes, .{}); not recorded: recording comes with `record`",
            froctomap_core::calendar::iso8601(map.stamp),
            map.file.len(),
            if map.binary { "bt" } else { "ot" }
        );
        Ok(())
    }

    fn skipped(&mut self, reason: String) {
        eprintln!("warning: {reason}");
    }
}

/// The node crate's log (skipped messages and requests) as `warning:` lines on stderr.
struct StderrLog;

impl log::Log for StderrLog {
    fn enabled(&self, metadata: &log::Metadata<'_>) -> bool {
        metadata.level() <= log::Level::Warn
    }

    fn log(&self, record: &log::Record<'_>) {
        // RustDDS's own warnings (discovery chatter) stay out; the node's are for the user.
        if self.enabled(record.metadata()) && record.target().starts_with("froctomap") {
            eprintln!("warning: {}", record.args());
        }
    }

    fn flush(&self) {}
}

static STDERR_LOG: StderrLog = StderrLog;

fn network(text: &str) -> anyhow::Result<Network> {
    Ok(match text.trim() {
        "lo" => Network::Loopback,
        "all" => Network::All,
        list => Network::Only(
            list.split(',')
                .map(|a| {
                    a.trim()
                        .parse::<IpAddr>()
                        .with_context(|| format!("--network: `{a}` is not an IP address"))
                })
                .collect::<anyhow::Result<_>>()?,
        ),
    })
}

/// Runs the node until interrupted.
pub fn ros2_command(_ui: &Ui, args: &Ros2Args) -> anyhow::Result<()> {
    let every = parse_duration(&args.publish_every).context("--publish-every")?;
    anyhow::ensure!(every > 0, "--publish-every must be positive");
    // parse_duration takes positive spans only; 0 (in any unit) is "now".
    let zero = args
        .horizon
        .trim()
        .trim_end_matches(|c: char| c.is_ascii_alphabetic())
        .parse::<f64>()
        == Ok(0.0);
    let horizon = if zero {
        0
    } else {
        parse_duration(&args.horizon).context("--horizon")?
    };
    if log::set_logger(&STDERR_LOG).is_ok() {
        log::set_max_level(log::LevelFilter::Warn);
    }
    let mut options = NodeOptions::new(domain_id_from_env()?);
    options.topic = args.topic.clone();
    options.network = network(&args.network)?;
    options.service_mapping = args.service_mapping;
    let node = Node::new(&options)?;
    eprintln!(
        "froctomap node on ROS domain {}: receiving {}, publishing {} from {} every {}, serving {} and {} ({:?} mapping)",
        node.domain_id(),
        args.topic,
        froctomap_ros2_node::PREDICTED_TOPIC,
        args.file.display(),
        args.publish_every,
        froctomap_ros2_node::GET_OCTOMAP_AT_SERVICE,
        froctomap_ros2_node::PROBABILITY_AT_SERVICE,
        args.service_mapping
    );
    let mut predicted = PredictedPublisher::new(&args.file, &args.frame_id);
    let mut services = FileServices::new(&args.file, &args.frame_id);
    let mut sink = LogReceived;
    let period = Duration::from_nanos(every.unsigned_abs());
    loop {
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .context("the clock is before 1970")?;
        let now = i64::try_from(now.as_nanos()).context("the clock is past 2262")?;
        let t = Timestamp(now.saturating_add(horizon));
        match predicted.publish_if_changed(&node, t) {
            Ok(true) => eprintln!(
                "published the map predicted for {}",
                froctomap_core::calendar::iso8601(t)
            ),
            Ok(false) => {}
            Err(e) => eprintln!("warning: {e}"),
        }
        let next = Instant::now() + period;
        while Instant::now() < next {
            node.receive_into(
                &mut sink,
                next.saturating_duration_since(Instant::now())
                    .min(Duration::from_millis(50)),
            )?;
            node.serve_requests(&mut services);
        }
    }
}
