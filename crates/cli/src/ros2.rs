//! `froctomap ros2 FILE`: the ROS 2 node (cargo feature `ros2`). It records the maps it
//! receives into FILE through `record`'s `Recorder` (`--no-record`: receives only),
//! publishes the map FILE predicts and answers the services from FILE.

use crate::series::{tile_budget, TileBudgetArgs};
use crate::ui::Ui;
use anyhow::Context as _;
use froctomap_convert::{
    group_thousands, parse_duration, CommitEvery, Context, FroctFile, Opened, RecordEvent,
    RecordOptions, Recorder, SeriesRead, TimeError,
};
use froctomap_core::Timestamp;
use froctomap_ros2_node::{
    domain_id_from_env, parameter_type, FileServices, GraphLayout, MapSink, Network, Node,
    NodeOptions, ParameterValue, Parameters, PredictedPublisher, ReceivedMap, RecordingSink,
    RosArgs, ServiceMapping, TimeSource,
};
use std::net::IpAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Arguments of `froctomap ros2`.
#[derive(clap::Args, Clone)]
pub struct Ros2Args {
    /// The FROctomap file (the living map): the maps received are appended to it (it is
    /// created from the first ones if missing), its predicted map is published on
    /// /froctomap/predicted and the services answer from it.
    file: PathBuf,
    /// Commit every N maps or every DURATION (as `record`).
    #[arg(long, value_name = "N|DURATION", default_value = "5s", value_parser = clap::value_parser!(CommitEvery))]
    commit_every: CommitEvery,
    /// Take at most one map per DURATION (a fast publisher thinned); 0: every map.
    #[arg(long, value_name = "DURATION", default_value = "0")]
    min_interval: String,
    /// The time a map is recorded at: its `header` stamp, or the `receive` time (the
    /// system clock, or /clock's with use_sim_time).
    #[arg(long, value_name = "header|receive", default_value = "header")]
    time_source: TimeSource,
    /// Receive and serve only: do not append the maps received to FILE.
    #[arg(long)]
    no_record: bool,
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
    /// The frame of the maps: received maps in another frame are refused, and the maps
    /// published and served are in it. Default: the first map received fixes it (`map`
    /// until one arrives).
    #[arg(long)]
    frame_id: Option<String>,
    /// How service requests and replies are framed: `cyclone` (rmw_cyclonedds), `enhanced`
    /// (DDS-RPC enhanced: rmw_fastrtps, rmw_connextdds) or `basic` (DDS-RPC basic).
    #[arg(long, value_name = "cyclone|enhanced|basic", default_value = "cyclone")]
    service_mapping: ServiceMapping,
    /// Received maps larger than SIZE are refused (logged and skipped); service requests
    /// are refused over the smaller of SIZE and their own bound (the point limit). Checked
    /// once DDS has reassembled the message.
    #[arg(long, value_name = "SIZE", default_value = "256MiB", value_parser = message_bytes)]
    max_message_bytes: usize,
    /// Tiles of a new file's base (as `record --tile-depth`; default 10). An existing file
    /// keeps its own; the background compactions deepen them past --tile-budget.
    #[arg(long, value_name = "DEPTH", value_parser = tile_depth)]
    tile_depth: Option<u8>,
    #[command(flatten)]
    tile_budget: TileBudgetArgs,
    /// The ROS 2 distribution of the peers, for the node's graph entry (`ros2 node list`,
    /// `ros2 param`): `jazzy` (Iron and later) or `humble` (Humble and before).
    #[arg(long, value_name = "DISTRO", default_value = "jazzy")]
    ros_distro: GraphLayout,
    /// Serve the predicted map to the Foxglove app on a WebSocket server at PORT (0: a
    /// free port, printed): its occupied voxels with their probability, as
    /// `foxglove.PointCloud` on /froctomap/occupied_voxels.
    #[cfg(feature = "foxglove")]
    #[arg(long, value_name = "PORT")]
    foxglove: Option<u16>,
    /// The address the Foxglove server listens on (default: loopback only; 0.0.0.0 for
    /// every interface).
    #[cfg(feature = "foxglove")]
    #[arg(
        long,
        value_name = "ADDR",
        default_value = "127.0.0.1",
        requires = "foxglove"
    )]
    foxglove_address: IpAddr,
    /// ROS arguments, last on the line: `--ros-args -r from:=to` (topic and service
    /// remapping), `-r __ns:=/robot1`, `-r __node:=name`, `-p name:=value` (a parameter:
    /// the options above by their names with `_`, and `use_sim_time`).
    #[arg(long = "ros-args", num_args = 0.., allow_hyphen_values = true, value_name = "ARGS")]
    ros_args: Option<Vec<String>>,
}

/// The options `-p name:=value` sets, by their parameter names.
const PARAMETERS: [&str; 14] = [
    "commit_every",
    "frame_id",
    "horizon",
    "max_message_bytes",
    "min_interval",
    "network",
    "publish_every",
    "record",
    "service_mapping",
    "tile_budget",
    "tile_depth",
    "time_source",
    "topic",
    "use_sim_time",
];

/// `args` with the `-p` parameters of `ros` applied; whether `use_sim_time` is on.
fn with_parameters(args: &Ros2Args, ros: &RosArgs) -> anyhow::Result<(Ros2Args, bool)> {
    let mut args = args.clone();
    let mut use_sim_time = false;
    for (name, value) in &ros.parameters {
        let text = value.as_text();
        let bad = |e: String| anyhow::anyhow!("-p {name}:={text}: {e}");
        let boolean = || {
            (value.r#type == parameter_type::BOOL)
                .then_some(value.bool_value)
                .ok_or_else(|| bad("true or false".into()))
        };
        match name.as_str() {
            "commit_every" => {
                args.commit_every = text.parse().map_err(|e: TimeError| bad(e.to_string()))?
            }
            "frame_id" => args.frame_id = Some(text),
            "horizon" => args.horizon = text,
            "max_message_bytes" => args.max_message_bytes = message_bytes(&text).map_err(bad)?,
            "min_interval" => args.min_interval = text,
            "network" => args.network = text,
            "publish_every" => args.publish_every = text,
            "record" => args.no_record = !boolean()?,
            "service_mapping" => args.service_mapping = text.parse().map_err(bad)?,
            "tile_budget" => args.tile_budget.tile_budget = tile_budget(&text).map_err(bad)?,
            "tile_depth" => args.tile_depth = Some(tile_depth(&text).map_err(bad)?),
            "time_source" => args.time_source = text.parse().map_err(bad)?,
            "topic" => args.topic = text,
            "use_sim_time" => use_sim_time = boolean()?,
            _ => anyhow::bail!(
                "-p {name}:=…: froctomap has no parameter `{name}` ({})",
                PARAMETERS.join(", ")
            ),
        }
    }
    Ok((args, use_sim_time))
}

/// The parameters the node serves: every option's value as the node runs with it
/// (`use_sim_time` is the node's own).
fn parameters(args: &Ros2Args) -> Parameters {
    let mut parameters = Parameters::default();
    let text = |s: &str| ParameterValue::string(s);
    let commit_every = match args.commit_every {
        CommitEvery::Maps(maps) => maps.to_string(),
        every => format!("{every:?}"),
    };
    for (name, value, description) in [
        ("file", text(&args.file.to_string_lossy()), "the living map"),
        (
            "topic",
            text(&args.topic),
            "the maps received (before resolution)",
        ),
        (
            "commit_every",
            text(&commit_every),
            "a commit every N maps or DURATION",
        ),
        (
            "min_interval",
            text(&args.min_interval),
            "at most one map per DURATION",
        ),
        (
            "time_source",
            text(&format!("{:?}", args.time_source).to_lowercase()),
            "header or receive",
        ),
        (
            "record",
            ParameterValue::bool(!args.no_record),
            "whether maps are recorded",
        ),
        (
            "publish_every",
            text(&args.publish_every),
            "how often the predicted map is computed",
        ),
        (
            "horizon",
            text(&args.horizon),
            "the predicted map is at now + horizon",
        ),
        (
            "frame_id",
            text(args.frame_id.as_deref().unwrap_or("")),
            "the maps' frame (empty: the first map's)",
        ),
        (
            "service_mapping",
            text(&format!("{:?}", args.service_mapping).to_lowercase()),
            "the request/reply framing",
        ),
        ("network", text(&args.network), "the interfaces"),
        (
            "max_message_bytes",
            ParameterValue::integer(i64::try_from(args.max_message_bytes).unwrap_or(i64::MAX)),
            "larger messages are refused",
        ),
        (
            "tile_depth",
            ParameterValue::integer(i64::from(
                args.tile_depth
                    .unwrap_or(froctomap_convert::AppendOptions::default().tile_depth),
            )),
            "a new file's tiles: 2^(16 - depth) voxels per edge",
        ),
        (
            "tile_budget",
            text(
                &args
                    .tile_budget
                    .tile_budget
                    .0
                    .map_or("none".into(), |b| b.to_string()),
            ),
            "bytes of history past which a compaction deepens the tiles",
        ),
    ] {
        parameters.set(name, value, description);
    }
    parameters
}

/// `--tile-depth`: 1 to 16.
fn tile_depth(text: &str) -> Result<u8, String> {
    match text.trim().parse::<u8>() {
        Ok(depth @ 1..=16) => Ok(depth),
        _ => Err(format!("{text:?}: a tile depth from 1 to 16")),
    }
}

/// `--max-message-bytes`: a byte size (`64MiB`), at least 1 byte.
fn message_bytes(text: &str) -> Result<usize, String> {
    match crate::series::byte_size(text)? {
        0 => Err("at least 1 byte".into()),
        bytes => usize::try_from(bytes).map_err(|_| "out of range".to_string()),
    }
}

/// Logs each map received (`--no-record`).
struct LogReceived;

impl MapSink for LogReceived {
    fn receive(
        &mut self,
        map: ReceivedMap,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        eprintln!(
            "received a map stamped {} ({} bytes, .{}); not recorded (--no-record)",
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

/// A duration option that may be 0 (parse_duration takes positive spans only).
fn duration_or_zero(text: &str, option: &str) -> anyhow::Result<i64> {
    let zero = text
        .trim()
        .trim_end_matches(|c: char| c.is_ascii_alphabetic())
        .parse::<f64>()
        == Ok(0.0);
    if zero {
        Ok(0)
    } else {
        parse_duration(text).with_context(|| option.to_string())
    }
}

/// Set once SIGINT or SIGTERM asked the node to stop.
static STOP: AtomicBool = AtomicBool::new(false);

/// The first SIGINT/SIGTERM/SIGHUP stops the node's loop (it commits and exits 0); a
/// second one ends the process at once.
fn stop_on_signals() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
        return;
    };
    let started = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            let mut signals = signals.forever();
            if signals.next().is_some() {
                STOP.store(true, Ordering::SeqCst);
            }
            if let Some(signal) = signals.next() {
                crate::signals::end_by(signal);
            }
        });
    drop(started);
}

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
    let ros = RosArgs::parse(args.ros_args.as_deref().unwrap_or_default())?;
    let (args, use_sim_time) = with_parameters(args, &ros)?;
    let args = &args;
    let every = parse_duration(&args.publish_every).context("--publish-every")?;
    anyhow::ensure!(every > 0, "--publish-every must be positive");
    let horizon = duration_or_zero(&args.horizon, "--horizon")?;
    let min_interval = Duration::from_nanos(
        duration_or_zero(&args.min_interval, "--min-interval")?.unsigned_abs(),
    );
    stop_on_signals();
    if log::set_logger(&STDERR_LOG).is_ok() {
        log::set_max_level(log::LevelFilter::Warn);
    }
    let options = node_options(args, ros, use_sim_time)?;
    let node = Node::new(&options)?;
    say_started(&node, args, use_sim_time);
    let mut frame_id = args.frame_id.clone().unwrap_or_else(|| "map".to_string());
    let mut predicted = PredictedPublisher::new(&args.file, &frame_id);
    let mut services = FileServices::new(&args.file, &frame_id);
    #[cfg(feature = "foxglove")]
    let mut foxglove = start_foxglove(args)?;
    let context = Context::with_default_plugins();
    let mut recording = if args.no_record {
        None
    } else {
        Some(open_recording(&context, args, min_interval)?)
    };
    let period = Duration::from_nanos(every.unsigned_abs());
    while !STOP.load(Ordering::SeqCst) {
        // With use_sim_time, "now" is unknown until /clock says it.
        let t = node
            .now()
            .map(|now| Timestamp(now.0.saturating_add(horizon)));
        // Until the first commit creates it, there is no map to predict.
        let started = Instant::now();
        let published = match t {
            Some(t) if args.file.exists() => predicted.publish_if_changed(&node, t),
            _ => Ok(None),
        };
        match published {
            // What a publication costs (predicting, encoding the map and its markers).
            #[cfg_attr(not(feature = "foxglove"), allow(unused_variables))]
            Ok(Some(cells)) => {
                eprintln!(
                    "published the map predicted for {} ({} ms)",
                    t.map(froctomap_core::calendar::iso8601).unwrap_or_default(),
                    started.elapsed().as_millis()
                );
                #[cfg(feature = "foxglove")]
                if let (Some(view), Some(t)) = (foxglove.as_mut(), t) {
                    if let Err(e) = view.show_predicted(&cells, t, &frame_id) {
                        eprintln!("warning: {e:#}");
                    }
                }
            }
            Ok(None) => {}
            Err(e) => eprintln!("warning: {}", froctomap_core::error_message(&e)),
        }
        let next = Instant::now() + period;
        while Instant::now() < next && !STOP.load(Ordering::SeqCst) {
            let wait = next
                .saturating_duration_since(Instant::now())
                .min(Duration::from_millis(50));
            match recording.as_mut() {
                Some(sink) => {
                    node.receive_into(sink, wait)?;
                    if let Err(e) = sink.tick() {
                        eprintln!(
                            "warning: {}: {}",
                            args.file.display(),
                            froctomap_core::error_message(&e)
                        );
                    }
                }
                None => {
                    node.receive_into(&mut LogReceived, wait)?;
                }
            }
            if let Some(fixed) = node.frame_id().filter(|fixed| *fixed != frame_id) {
                eprintln!("the maps are in frame `{fixed}`: maps in other frames are refused, the maps published and served are in it");
                predicted.set_frame_id(&fixed);
                services.set_frame_id(&fixed);
                frame_id = fixed;
            }
            node.serve_requests(&mut services);
            #[cfg(feature = "foxglove")]
            if let Some(view) = foxglove.as_mut() {
                view.tick();
            }
        }
    }
    if let Some(sink) = recording {
        finish_recording(&node, sink)?;
    }
    Ok(())
}

/// The node's options from the command line and the ROS arguments.
fn node_options(args: &Ros2Args, ros: RosArgs, use_sim_time: bool) -> anyhow::Result<NodeOptions> {
    let mut options = NodeOptions::new(domain_id_from_env()?);
    options.topic = args.topic.clone();
    options.network = network(&args.network)?;
    options.service_mapping = args.service_mapping;
    options.max_message_bytes = args.max_message_bytes;
    options.frame_id = args.frame_id.clone();
    options.parameters = parameters(args); // The node adds use_sim_time.
    options.use_sim_time = use_sim_time;
    options.graph = args.ros_distro;
    options.names = ros;
    Ok(options)
}

/// The node's first line: its names, its file and its period.
fn say_started(node: &Node, args: &Ros2Args, use_sim_time: bool) {
    let names = node.names();
    eprintln!(
        "froctomap node {} on ROS domain {}: receiving {}, publishing {} and {} from {} every {}{}, serving {} and {} ({:?} mapping)",
        names.node,
        node.domain_id(),
        names.topic,
        names.predicted,
        names.dynamic,
        args.file.display(),
        args.publish_every,
        if use_sim_time { " of /clock's time" } else { "" },
        names.get_octomap_at,
        names.probability_at,
        args.service_mapping
    );
}

/// `--foxglove PORT`'s WebSocket server, saying where it listens.
#[cfg(feature = "foxglove")]
fn start_foxglove(args: &Ros2Args) -> anyhow::Result<Option<crate::foxglove::FoxgloveView>> {
    Ok(match args.foxglove {
        Some(port) => {
            let view =
                crate::foxglove::FoxgloveView::start(&args.foxglove_address.to_string(), port)?;
            // Port 0 asks for a free one: the line says which (scripts read it); an IPv6
            // address in brackets.
            eprintln!(
                "Foxglove WebSocket server on ws://{}: the predicted map on {}",
                std::net::SocketAddr::new(args.foxglove_address, view.port()),
                froctomap_ros::POINT_CLOUD_TOPIC
            );
            Some(view)
        }
        None => None,
    })
}

/// Takes the maps DDS already delivered, commits and says what was recorded.
fn finish_recording(node: &Node, mut sink: RecordingSink<'_>) -> anyhow::Result<()> {
    // Maps DDS already delivered (and acknowledged) are taken before the last commit:
    // one pass takes them all (the reader keeps 16, `MAPS_PER_PASS`).
    node.receive_into(&mut sink, Duration::ZERO)?;
    let (thinned, lost) = (sink.thinned(), sink.lost());
    let summary = sink.finish()?;
    eprintln!(
        "stopped: {} maps recorded in {} commit(s); {} not later than the last one and {} thinned by --min-interval skipped, {} bad left out, {} lost to failed commits",
        summary.committed_maps, summary.commits, summary.older, thinned, summary.bad, lost
    );
    Ok(())
}

/// The recorder of FILE (created from the first commit's maps if missing), printing one
/// line per commit, wrapped as the node's map sink.
fn open_recording<'a>(
    context: &'a Context,
    args: &Ros2Args,
    min_interval: Duration,
) -> anyhow::Result<RecordingSink<'a>> {
    // A bad map over the wire is left out (and said), never the end of the node; compaction
    // in the background: in place it would block the map intake for as long as a build of
    // the whole history takes, while the DDS reader keeps only the last 16 maps.
    let mut options = RecordOptions::for_live_source(args.commit_every);
    if let Some(depth) = args.tile_depth {
        options.append.tile_depth = depth;
    }
    options.tile_budget = args.tile_budget.tile_budget.0;
    let mut recorder = Recorder::open(context, &args.file, options)?;
    match recorder.opened() {
        Opened::Missing => eprintln!(
            "{} does not exist: the first commit's maps become its base",
            args.file.display()
        ),
        Opened::Converted => eprintln!(
            "converted {} to format 2.0 (older releases cannot read it)",
            args.file.display()
        ),
        _ => {}
    }
    let file = args.file.clone();
    // One reader for the commit lines, refreshed after each commit: it reads the new
    // segments' records only (opening the file again would read every one, each commit).
    let mut view: Option<FroctFile> = None;
    recorder.on_event(move |event| match event {
        RecordEvent::Committed(commit) => {
            let refreshed = match view.as_mut() {
                Some(open) => open.refresh().is_ok(),
                None => false,
            };
            if !refreshed {
                view = FroctFile::open(&file).ok();
            }
            // The cells of the map as observed at the last sample (the file's own cells
            // add those of every earlier map).
            let cells = view
                .as_ref()
                .and_then(|f| {
                    let last = f.sample_at_or_before(f.last_instant())?;
                    let tiles = f.observed_tiles(last);
                    Some(tiles.iter().map(|t| u64::from(t.cell_count)).sum::<u64>())
                })
                .map_or_else(|| "?".to_string(), group_thousands);
            println!(
                "{}: {} maps, {} .. {}, {} cells in the last map, file {} bytes ({} ms)",
                match commit.segment {
                    None => "base".to_string(),
                    Some(segment) => format!("segment {segment}"),
                },
                commit.maps,
                froctomap_core::calendar::iso8601(commit.first),
                froctomap_core::calendar::iso8601(commit.last),
                cells,
                group_thousands(commit.bytes),
                commit.elapsed.as_millis()
            );
        }
        RecordEvent::LeftOut { maps, what, error } => {
            eprintln!(
                "warning: {maps} map(s) left out: {what}: {}",
                froctomap_core::error_message(error)
            );
        }
        RecordEvent::Retrying { maps, what, error } => {
            eprintln!(
                "warning: a commit of {maps} maps failed, trying its halves: {what}: {}",
                froctomap_core::error_message(error)
            );
        }
        // A compaction replaces the file: the reader held sees the old one.
        RecordEvent::Compacted(report) => {
            view = None;
            println!(
                "compacted: the base and {} segment(s) into one base, {} -> {} bytes, {} ms, {} maps committed meanwhile added",
                report.segments_before,
                group_thousands(report.bytes_before),
                group_thousands(report.bytes),
                (report.seconds * 1000.0).round(),
                report.maps_added_meanwhile
            );
        }
        RecordEvent::CompactionFailed(error) => eprintln!(
            "warning: the background compaction failed (every commit is kept; no more compactions until the node restarts): {}",
            froctomap_core::error_message(error)
        ),
        _ => {}
    });
    Ok(RecordingSink::new(recorder, args.time_source, min_interval))
}
