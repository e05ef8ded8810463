//! `froctomap record`: maps added to a FROctomap 2.0 file as they arrive, one segment
//! committed every `--commit-every` maps or seconds by a [`froctomap_convert::Recorder`],
//! which this command feeds and whose commits it prints.
//!
//! A stream (`-`) is read message by message on a thread of its own
//! (`froctomap_ros::McapStreamMaps`); its maps go to the recorder as bytes (spooled beside
//! the file until committed, so memory and disk follow one commit, not the stream). SIGINT/SIGTERM/SIGHUP reach the same channel: the maps
//! received are committed and `record` exits 0 (a second signal ends it at once).
//!
//! `--follow DIR` (after the sources, until a signal; `follow.rs` watches DIR): map
//! files reach the channel as paths once closed or renamed into DIR, and are taken as
//! `build` collects files; a ROS 2 bag directory's splits are read one after the other on a
//! thread of their own, as streams that wait for their file to grow, their maps taken as a
//! stream's are.

use crate::follow::DirEvent;
use crate::series::{print_input_notes, SpillArgs, TileBudgetArgs, TimeArgs};
use crate::ui::{escaped, Ui};
use anyhow::{anyhow, bail, Context as _, Result};
use clap::Args;
use froctomap_convert::{
    group_thousands, AppendOptions, CommitEvery, Compaction, Context, Opened, RecordError,
    RecordEvent, RecordOptions, RecordSummary, Recorder, SeriesInput, MANIFEST_NAME, STDIN_INPUT,
};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_ros::{McapStreamMaps, RosError, StreamedMap};
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::Duration;

#[derive(Args)]
pub struct RecordArgs {
    /// The FROctomap file to add to: format 2.0, or 1.x, which is converted to 2.0 first
    /// (said on stderr; older releases cannot read it). If it does not exist, the first
    /// commit's maps are built into it as its base (the default model, fremen-periods,
    /// lossless; `build` first for other options).
    #[arg(value_name = "FILE")]
    file: PathBuf,
    /// Where the maps come from, read in the order given: `-` (an MCAP stream on standard
    /// input, e.g. `froctomap generate --stream`, read map by map as it arrives), or inputs
    /// as for `build` (directories, globs, manifests, files, recordings). Maps not later
    /// than the last one taken (the file's last sample at first) are skipped and counted,
    /// so overlapping bag splits can be given whole.
    #[arg(required_unless_present = "follow", value_name = "SOURCE")]
    sources: Vec<PathBuf>,
    /// After the SOURCEs, record what appears in DIR until SIGINT/SIGTERM: a directory of
    /// map files (.bt, .ot) takes the files there first (in time order), then each new one
    /// once its writer closed it or renamed it into place (a file being written is never
    /// read; hidden and temporary names such as `map.bt.tmp` are ignored), its time from
    /// its name as `build` reads names; a ROS 2 bag directory being recorded (`ros2 bag
    /// record`: `NAME_0.mcap`, `NAME_1.mcap`…, with or without metadata.yaml) is read split
    /// by split in order, each map as soon as its chunk is complete, new splits as they
    /// appear. Maps not later than the last one taken are skipped and counted. A map file
    /// must stay in DIR until the commit that holds it.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["start", "times_file"])]
    follow: Option<PathBuf>,
    /// Commit a segment every N maps (a plain number) or every so much time (5s, 1min:
    /// measured from the first map of the commit as it arrives).
    #[arg(long, value_name = "N|DURATION", default_value = "5s", value_parser = clap::value_parser!(CommitEvery))]
    commit_every: CommitEvery,
    /// Leave maps that do not read out (logged, counted) instead of stopping; without it
    /// a bad map stops `record` after committing the maps before it.
    #[arg(long)]
    skip_bad: bool,
    /// Never compact automatically. By default, after a commit the file is compacted in
    /// place (as `froctomap compact` does, in the build's memory: --memory, --max-memory)
    /// when its segments exceed half of its base's size (once the maps added since the base
    /// are a quarter of the base's) or its span has doubled since the last compaction: the
    /// file stays at most 1.5× its base where segments cost per map at most twice what the
    /// base does, and the cost of compacting, amortised, does not grow with the history. It
    /// is also compacted when its segments reach 16,384, a quarter of the format's limit
    /// (commits every few seconds for days would reach the limit otherwise); one
    /// line says so, with the time it took. A compaction refits with the model options given
    /// here (--model-option), not the ones the file was built with, which files do not
    /// record.
    #[arg(long)]
    no_compact: bool,
    /// Tiles of a new file's base: cubes of 2^(16 − depth) voxels per edge (default 10, as
    /// `build`); an existing file keeps its own (`froctomap compact FILE --tile-depth N`
    /// makes them smaller). A compaction holds one tile's whole history at a time, so a
    /// recording meant to run for weeks keeps its compactions' memory down in smaller tiles
    /// (12: a 64th of the volume; docs/BENCHMARKS.md); --tile-budget deepens them as the
    /// history grows.
    #[arg(long, value_name = "DEPTH", value_parser = clap::value_parser!(u8).range(1..=16))]
    tile_depth: Option<u8>,
    /// The default (see --no-compact); accepted so that scripts written for the release
    /// where automatic compaction was opt-in keep working.
    #[arg(long, hide = true, conflicts_with = "no_compact")]
    auto_compact: bool,
    /// Compact on a thread of its own while maps keep being taken and committed (the file
    /// as committed when a compaction is due is compacted beside it, the maps committed
    /// meanwhile are added to the result, which then replaces the file): for live sources
    /// (--follow), whose maps would otherwise wait for as long as a build of the whole
    /// history. Needs the compaction's memory on top of the commits'. At the end `record`
    /// waits for a compaction still running; stopped by a signal, it abandons it.
    #[arg(long, conflicts_with = "no_compact")]
    compact_in_background: bool,
    #[command(flatten)]
    tile_budget: TileBudgetArgs,
    /// A temporal model option (KEY=VALUE, repeatable): for the base a missing FILE is
    /// built with and for automatic compactions (see `froctomap models`).
    #[arg(long, value_name = "KEY=VALUE")]
    model_option: Vec<String>,
    /// Print a line per map received (standard output, before the commit that holds it):
    /// `received TIME: taken`, `… older` (not later than the last one taken, skipped) or
    /// `received map message N (byte B): bad` (left out with --skip-bad).
    #[arg(short, long)]
    verbose: bool,
    /// Force the input map format instead of detecting it (file sources).
    #[arg(long, value_name = "FORMAT")]
    input_format: Option<String>,
    #[command(flatten)]
    times: TimeArgs,
    #[command(flatten)]
    spill: SpillArgs,
}

/// What reaches the main thread: the stream's maps and the signals.
enum Event {
    Map(StreamedMap),
    /// A map message that does not read, and (bytes, messages) read when it came.
    BadMap(anyhow::Error, (u64, u64)),
    /// The stream ended whole.
    End,
    /// The stream stopped reading (cut, garbage, read error).
    Failed(RosError),
    /// `--follow`: a map file closed after writing or renamed into the directory.
    Ready(PathBuf),
    /// `--follow`: events were lost; the directory is listed again.
    Rescan,
    /// `--follow`: watching the directory failed.
    WatchFailed(String),
    /// SIGINT, SIGTERM or SIGHUP.
    Stop,
    /// `--follow BAGDIR`: a split was read to its end (`None`), or up to where it is cut.
    SplitEnded(PathBuf, Option<String>),
}

/// Set once a signal asked `record` to stop.
static STOP: AtomicBool = AtomicBool::new(false);

/// Map bytes the stream thread may hold ahead of the recorder (one map at least, however
/// large): it goes on reading, and the producer of a pipe (`generate --stream |`) on
/// making maps, while a commit runs, in memory bounded by this and not by the commit.
const READ_AHEAD_BYTES: usize = 16 << 20;

/// The map bytes read and not yet taken by the recorder, which the stream thread waits on
/// to stay within [`READ_AHEAD_BYTES`].
#[derive(Default)]
struct ReadAhead {
    bytes: Mutex<usize>,
    taken: Condvar,
}

impl ReadAhead {
    /// Waits until `bytes` more fit (or nothing is held), then holds them.
    fn hold(&self, bytes: usize) {
        let mut held = self.bytes.lock().unwrap_or_else(PoisonError::into_inner);
        while *held > 0 && *held + bytes > READ_AHEAD_BYTES {
            held = self
                .taken
                .wait(held)
                .unwrap_or_else(PoisonError::into_inner);
        }
        *held += bytes;
    }

    /// `bytes` were taken by the recorder.
    fn release(&self, bytes: usize) {
        let mut held = self.bytes.lock().unwrap_or_else(PoisonError::into_inner);
        *held = held.saturating_sub(bytes);
        self.taken.notify_one();
    }
}

pub fn record_command(ui: &Ui, args: &RecordArgs) -> Result<()> {
    if let Some((limit, default)) = args.spill.max_memory.limit() {
        crate::memory_guard::watch(limit, default, "record");
    }
    if let Some(dir) = &args.follow {
        crate::follow::check_dir(dir)?;
    }
    // Bounded by bytes (ReadAhead), the count only keeps small maps from piling up.
    let (sender, events) = sync_channel::<Event>(256);
    stop_on_signals(sender.clone());
    if args
        .sources
        .iter()
        .filter(|s| s.as_os_str() == STDIN_INPUT)
        .count()
        > 1
    {
        bail!("`-` (standard input) is given twice");
    }
    let spool_parent = crate::series::spool_dir(args.spill.tmp_dir.as_deref(), Some(&args.file))
        .unwrap_or_else(|| PathBuf::from("."));
    let context = &args
        .times
        .context(ui, args.skip_bad, Some(spool_parent.clone()));
    let options = record_options(ui, args, spool_parent)?;
    let mut recorder = Recorder::open(context, &args.file, options)?;
    announce(ui, args, &recorder);
    // The first failure to print a commit line (standard output closed), said after the
    // call that committed.
    let printing: Rc<RefCell<Option<std::io::Error>>> = Rc::default();
    let failed_print = Rc::clone(&printing);
    recorder.on_event(move |event| print_event(ui, &failed_print, &event));
    let mut recording = Recording {
        ui,
        context,
        recorder,
        skip_bad: args.skip_bad,
        verbose: args.verbose,
        printing,
    };
    let follow_sender = sender.clone();
    let mut sender = Some(sender);
    for source in &args.sources {
        if STOP.load(Ordering::SeqCst) {
            break;
        }
        let result = if source.as_os_str() == STDIN_INPUT {
            let Some(sender) = sender.take() else {
                bail!("`-` (standard input) is given twice");
            };
            read_stream(&mut recording, sender, &events)
        } else {
            read_files(&mut recording, args, source)
        };
        if let Err(error) = result {
            return Err(recording.stopped(error));
        }
    }
    if let Some(dir) = args
        .follow
        .as_deref()
        .filter(|_| !STOP.load(Ordering::SeqCst))
    {
        if let Err(error) = follow(&mut recording, args, dir, follow_sender, &events) {
            return Err(recording.stopped(error));
        }
    }
    recording.commit()?;
    if recording.recorder.compacting() && !STOP.load(Ordering::SeqCst) {
        ui.note("waiting for the compaction running in the background (Ctrl-C abandons it)");
        while recording.recorder.compacting() && !STOP.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    let summary = if STOP.load(Ordering::SeqCst) {
        recording.recorder.stop()?
    } else {
        recording.recorder.finish()?
    };
    if STOP.load(Ordering::SeqCst) {
        ui.note("stopped by a signal: the maps received are committed");
    }
    say_recorded(ui, &summary);
    Ok(())
}

/// The recorder's settings from the command line.
fn record_options(ui: &Ui, args: &RecordArgs, spool_parent: PathBuf) -> Result<RecordOptions> {
    let mut options = RecordOptions {
        commit_every: args.commit_every,
        append: AppendOptions {
            skip_bad: args.skip_bad,
            allow_mostly_skipped: true,
            input_format: args.input_format.clone(),
            backend: Some(ui.backend),
            memory: args.spill.memory,
            tmp_dir: args.spill.tmp_dir.clone(),
            tile_depth: args
                .tile_depth
                .unwrap_or(AppendOptions::default().tile_depth),
            ..AppendOptions::default()
        },
        spool_dir: Some(spool_parent),
        compact: if args.no_compact {
            Compaction::Off
        } else if args.compact_in_background {
            Compaction::Background
        } else {
            Compaction::AfterCommit
        },
        tile_budget: args.tile_budget.tile_budget.0,
    };
    for assignment in &args.model_option {
        options
            .append
            .config
            .options
            .set_assignment(assignment)
            .context("--model-option")?;
    }
    Ok(options)
}

/// What the file is and how it will be committed to, before the first map.
fn announce(ui: &Ui, args: &RecordArgs, recorder: &Recorder<'_>) {
    match recorder.opened() {
        Opened::Missing => ui.note(&format!(
            "{} does not exist: the first commit's maps become its base (a build with the default model, fremen-periods, lossless)",
            escaped(args.file.display())
        )),
        Opened::Converted => ui.note(&format!(
            "converting {} to format 2.0 (older releases cannot read it)",
            escaped(args.file.display())
        )),
        _ => {}
    }
    if let (Some(asked), Some(depth)) = (args.tile_depth, recorder.tile_depth()) {
        if asked != depth {
            ui.note(&format!(
                "warning: {} keeps its tiles of depth {depth}: --tile-depth {asked} is for a new file (`froctomap compact {} --tile-depth {asked}` makes them smaller)",
                escaped(args.file.display()),
                escaped(args.file.display()),
            ));
        }
    }
    ui.note(&format!(
        "recording into {} (last sample {}), committing every {}",
        escaped(args.file.display()),
        recorder.last_time().map_or("none".to_string(), iso8601),
        args.commit_every
    ));
}

/// The last line: what was committed and what was left out.
fn say_recorded(ui: &Ui, summary: &RecordSummary) {
    ui.note(&format!(
        "recorded {} maps in {} segment(s); {} not later than the last one taken were skipped{}{}",
        summary.committed_maps,
        summary.commits,
        summary.older,
        match summary.bad {
            0 => String::new(),
            n => format!(", {n} bad map(s) left out"),
        },
        match summary.compactions {
            0 => String::new(),
            n => format!("; compacted {n} time(s)"),
        }
    ));
}

/// The recorder and what the command adds to it: the printing of its events.
struct Recording<'a> {
    ui: &'a Ui,
    context: &'a Context,
    recorder: Recorder<'a>,
    /// `--skip-bad`: a stream's map message that does not read is left out.
    skip_bad: bool,
    /// `--verbose`: a line per map received.
    verbose: bool,
    /// The first failure to print an event.
    printing: Rc<RefCell<Option<std::io::Error>>>,
}

impl Recording<'_> {
    /// `result`, or the failure to print what it committed.
    fn printed(&self, result: Result<(), RecordError>) -> Result<()> {
        result?;
        match self.printing.borrow_mut().take() {
            Some(error) => Err(error.into()),
            None => Ok(()),
        }
    }

    fn take_file(&mut self, input: SeriesInput) -> Result<()> {
        self.received(input.time)?;
        let result = self.recorder.take_file(input).map(drop);
        self.printed(result)
    }

    fn take_streamed(&mut self, map: &StreamedMap) -> Result<()> {
        self.received(map.time)?;
        let result = self.recorder.take_bytes(map.time, &map.bytes).map(drop);
        self.printed(result)
    }

    /// With `--verbose`, the line of a map received at `time`, before it is taken (and
    /// perhaps committed, whose line then follows).
    fn received(&self, time: Timestamp) -> Result<()> {
        if self.verbose {
            let later = self.recorder.last_time().is_none_or(|last| time > last);
            let what = if later { "taken" } else { "older" };
            outln!("received {}: {what}", iso8601(time))?;
        }
        Ok(())
    }

    fn commit(&mut self) -> Result<()> {
        let result = self.recorder.commit();
        self.printed(result)
    }

    /// `error`, after the maps received before it are committed (a failure of that commit
    /// is said with it).
    fn stopped(&mut self, error: anyhow::Error) -> anyhow::Error {
        match self.commit() {
            Ok(()) => error,
            Err(commit) => error.context(format!(
                "record stopped, and the maps received before were not all committed: {commit:#}"
            )),
        }
    }

    /// The next event, committing whenever a commit by time falls due while waiting
    /// (`None`: no sender is left).
    fn next_event(&mut self, events: &Receiver<Event>) -> Result<Option<Event>> {
        loop {
            match self.recorder.time_left() {
                Some(left) => match events.recv_timeout(left) {
                    Ok(event) => return Ok(Some(event)),
                    Err(RecvTimeoutError::Timeout) => self.commit()?,
                    Err(RecvTimeoutError::Disconnected) => return Ok(None),
                },
                None => return Ok(events.recv().ok()),
            }
        }
    }
}

/// Prints a commit line (standard output), or a note of maps left out.
fn print_event(ui: &Ui, failed: &RefCell<Option<std::io::Error>>, event: &RecordEvent<'_>) {
    match event {
        RecordEvent::Committed(commit) => {
            let printed = match commit.segment {
                None => outln!(
                    "base: {} maps, {} .. {}, {} bytes, {} ms",
                    commit.maps,
                    iso8601(commit.first),
                    iso8601(commit.last),
                    group_thousands(commit.bytes),
                    commit.elapsed.as_millis()
                ),
                Some(segment) => outln!(
                    "segment {segment}: {} maps, {} .. {}, +{} bytes, {} ms",
                    commit.maps,
                    iso8601(commit.first),
                    iso8601(commit.last),
                    group_thousands(commit.bytes.saturating_sub(commit.bytes_before)),
                    commit.elapsed.as_millis()
                ),
            };
            if let Err(error) = printed {
                failed.borrow_mut().get_or_insert(error);
            }
            print_input_notes(ui, &commit.warnings, &commit.skipped);
        }
        RecordEvent::Compacted(compacted) => {
            let meanwhile = match compacted.maps_added_meanwhile {
                0 => String::new(),
                maps => format!(", in the background ({maps} maps committed meanwhile added)"),
            };
            let deeper = match (compacted.tile_depth_before, compacted.tile_depth) {
                (before, after) if before != after => {
                    format!(", tiles of depth {after} (was {before}: --tile-budget)")
                }
                _ => String::new(),
            };
            let printed = outln!(
                "compacted: the base and {} segment(s) into one base, {} -> {} bytes, {} ms{deeper}{meanwhile}",
                compacted.segments_before,
                group_thousands(compacted.bytes_before),
                group_thousands(compacted.bytes),
                (compacted.seconds * 1000.0).round()
            );
            if let Err(error) = printed {
                failed.borrow_mut().get_or_insert(error);
            }
        }
        RecordEvent::CompactionFailed(error) => ui.note(&format!(
            "warning: the background compaction failed (every commit is kept; no more compactions in this run): {}",
            escaped(froctomap_core::error_message(*error))
        )),
        RecordEvent::LeftOut { maps, what, error } => {
            let why = escaped(format!("{what}: {}", froctomap_core::error_message(*error)));
            match maps {
                1 => ui.note(&format!("warning: left out: {why}")),
                _ => ui.note(&format!(
                    "warning: nothing to commit: {maps} map(s) left out: {why}"
                )),
            }
        }
        RecordEvent::Retrying { maps, what, error } => {
            let why = escaped(format!("{what}: {}", froctomap_core::error_message(*error)));
            ui.note(&format!(
                "warning: a commit of {maps} maps failed, trying its halves: {why}"
            ));
        }
        _ => {}
    }
}

fn read_files(recorder: &mut Recording<'_>, args: &RecordArgs, source: &Path) -> Result<()> {
    let ui = recorder.ui;
    let collected = args
        .times
        .collect(ui, recorder.context, &[source.to_path_buf()])?;
    print_input_notes(ui, &[], &collected.skipped);
    for input in collected.series {
        if STOP.load(Ordering::SeqCst) {
            break;
        }
        recorder.take_file(input)?;
    }
    Ok(())
}

/// Reads the stream on standard input on a thread, taking its maps as they come.
fn read_stream(
    recorder: &mut Recording<'_>,
    sender: SyncSender<Event>,
    events: &Receiver<Event>,
) -> Result<()> {
    let stdin = std::io::stdin();
    if std::io::IsTerminal::is_terminal(&stdin) {
        bail!("-: standard input is a terminal, not an MCAP stream");
    }
    let options = recorder.context.recording_options().clone();
    let limit = recorder.context.limits().max_map_file_bytes;
    let skip_bad = recorder.skip_bad;
    let read_ahead = Arc::new(ReadAhead::default());
    let held = Arc::clone(&read_ahead);
    // Not joined: at a signal it may be blocked reading, and ends with the process.
    std::thread::Builder::new()
        .name("stream".into())
        .spawn(move || {
            let mut maps = McapStreamMaps::new(stdin.lock(), &options, limit);
            loop {
                let event = match maps.next_map() {
                    Ok(Some(Ok(map))) => {
                        held.hold(map.bytes.len());
                        Event::Map(map)
                    }
                    Ok(Some(Err(bad))) => Event::BadMap(anyhow!(bad), maps.position()),
                    Ok(None) => Event::End,
                    Err(failed) => Event::Failed(failed),
                };
                let last = matches!(event, Event::End | Event::Failed(_));
                if sender.send(event).is_err() || last {
                    return;
                }
            }
        })?;
    loop {
        let Some(event) = recorder.next_event(events)? else {
            return Ok(());
        };
        match event {
            Event::Map(map) => {
                read_ahead.release(map.bytes.len());
                recorder.take_streamed(&map)?
            }
            Event::BadMap(bad, (bytes, messages)) => {
                let at = format!("map message {messages} of the stream (byte {bytes})");
                if !skip_bad {
                    return Err(anyhow!(bad).context(format!("record stopped at {at}")));
                }
                recorder.recorder.count_bad();
                if recorder.verbose {
                    outln!("received {at}: bad")?;
                }
                recorder
                    .ui
                    .note(&format!("warning: left out {at}: {}", escaped(bad)));
            }
            Event::End | Event::Stop => return Ok(()),
            // A signal to the whole pipeline (Ctrl-C) ends the producer too: its cut
            // stream may arrive before the signal's `Stop`.
            Event::Failed(_) if STOP.load(Ordering::SeqCst) => return Ok(()),
            Event::Failed(failed) => {
                return Err(anyhow!(failed).context("record stopped: the stream does not read on"))
            }
            // Only `--follow` sends these.
            Event::Ready(_) | Event::Rescan | Event::WatchFailed(_) | Event::SplitEnded(..) => {}
        }
    }
}

/// `--follow DIR`: a ROS 2 bag directory (`metadata.yaml`, or `.mcap` files) split by
/// split, else the map files there and then each one that becomes ready, until a signal.
fn follow(
    recording: &mut Recording<'_>,
    args: &RecordArgs,
    dir: &Path,
    sender: SyncSender<Event>,
    events: &Receiver<Event>,
) -> Result<()> {
    let splits = crate::follow::listed(dir, &[SPLIT_EXTENSION])?;
    if !splits.is_empty() || dir.join("metadata.yaml").is_file() {
        return follow_bag(recording, dir, sender, events);
    }
    let ui = recording.ui;
    let extensions: Vec<String> = recording
        .context
        .formats()
        .formats()
        .iter()
        .flat_map(|f| f.extensions.iter().map(|e| e.to_string()))
        .collect();
    let extensions: Vec<&str> = extensions.iter().map(String::as_str).collect();
    let watched: Vec<String> = extensions.iter().map(|e| e.to_string()).collect();
    // Watching starts before the directory is listed, so that no file closed in between
    // is missed (one seen twice is skipped as not later the second time).
    let _watcher = crate::follow::watch(dir, move |event| {
        let event = match event {
            DirEvent::Ready(path) => {
                let watched: Vec<&str> = watched.iter().map(String::as_str).collect();
                if !crate::follow::is_followed(&path, &watched) {
                    return;
                }
                Event::Ready(path)
            }
            DirEvent::Rescan => Event::Rescan,
            DirEvent::Failed(error) => Event::WatchFailed(error),
            DirEvent::Written => return,
        };
        let _ = sender.send(event);
    })?;
    if dir.join(MANIFEST_NAME).is_file() {
        ui.note(&format!(
            "warning: --follow {}: its {MANIFEST_NAME} is not read; each map's time comes from its file name",
            escaped(dir.display())
        ));
    }
    let present = crate::follow::listed(dir, &extensions)?;
    ui.note(&format!(
        "following {}: {} map file(s) there first, then each new one once closed or renamed into place (Ctrl-C commits and stops)",
        escaped(dir.display()),
        present.len()
    ));
    take_listed(recording, args, &present, false)?;
    // Until the signal's event: what became ready before it is taken.
    loop {
        let Some(event) = recording.next_event(events)? else {
            return Ok(());
        };
        match event {
            Event::Ready(path) => take_listed(recording, args, &[path], false)?,
            Event::Rescan => {
                let present = crate::follow::listed(dir, &extensions)?;
                take_listed(recording, args, &present, true)?;
            }
            Event::WatchFailed(error) => {
                bail!(
                    "--follow {}: watching failed: {error}",
                    escaped(dir.display())
                )
            }
            Event::Stop => return Ok(()),
            _ => {}
        }
    }
}

/// Takes the map files `paths` in time order, their times from their names (as `build`
/// reads them). A file that went away again is passed over; one without a time in its
/// name stops `record`, or with `--skip-bad` is left out and counted. `later_only`: files
/// not later than the last one taken are passed over without being counted (a listing
/// after lost events sees files taken before).
fn take_listed(
    recording: &mut Recording<'_>,
    args: &RecordArgs,
    paths: &[PathBuf],
    later_only: bool,
) -> Result<()> {
    let paths: Vec<PathBuf> = paths.iter().filter(|p| p.is_file()).cloned().collect();
    if paths.is_empty() {
        return Ok(());
    }
    let ui = recording.ui;
    let collected = match args.times.collect(ui, recording.context, &paths) {
        Ok(collected) => collected,
        Err(error) if recording.skip_bad && paths.len() == 1 => {
            recording.recorder.count_bad();
            ui.note(&format!(
                "warning: left out: {}",
                escaped(format!("{error:#}"))
            ));
            return Ok(());
        }
        // Files of a listing one by one, so that --skip-bad leaves out only the bad one.
        Err(_) if recording.skip_bad => {
            for path in paths {
                take_listed(recording, args, &[path], later_only)?;
            }
            return Ok(());
        }
        Err(error) => return Err(error.context("record stopped")),
    };
    print_input_notes(ui, &[], &collected.skipped);
    let listing = collected.series.len() > 1;
    for input in collected.series {
        // A signal cuts a listing short; a file that became ready before it is taken.
        if listing && STOP.load(Ordering::SeqCst) {
            break;
        }
        let last = recording.recorder.last_time();
        if later_only && last.is_some_and(|last| input.time <= last) {
            continue;
        }
        recording.take_file(input)?;
    }
    Ok(())
}

/// The extension of a ROS 2 bag's MCAP splits.
const SPLIT_EXTENSION: &str = "mcap";

/// `--follow BAGDIR`: the bag's splits in name order (`NAME_0.mcap`, `NAME_1.mcap`…) read
/// on a thread as streams that wait for their file to grow: each map is taken once its
/// chunk is complete, a split ends at its footer (or, cut by a writer that died, once a
/// later split exists and it stayed unchanged or was closed), and the next one is read
/// when it appears.
fn follow_bag(
    recording: &mut Recording<'_>,
    dir: &Path,
    sender: SyncSender<Event>,
    events: &Receiver<Event>,
) -> Result<()> {
    let ui = recording.ui;
    let (wake, woken) = sync_channel::<DirEvent>(64);
    let _watcher = crate::follow::watch(dir, move |event| {
        // A wake-up only: one lost to a full queue is made up by the reader's polling.
        let _ = wake.try_send(event);
    })?;
    ui.note(&format!(
        "following the bag {}: its splits in order, each map once its chunk is complete (Ctrl-C commits and stops)",
        escaped(dir.display())
    ));
    let options = recording.context.recording_options().clone();
    let limit = recording.context.limits().max_map_file_bytes;
    let dir_owned = dir.to_path_buf();
    let read_ahead = Arc::new(ReadAhead::default());
    let held = Arc::clone(&read_ahead);
    // Not joined: at a signal it may be waiting for a split to grow, and ends with the
    // process.
    std::thread::Builder::new()
        .name("splits".into())
        .spawn(move || read_splits(&dir_owned, &options, limit, &sender, &woken, &held))?;
    let skip_bad = recording.skip_bad;
    // Until the signal's event: what became ready before it is taken.
    loop {
        let Some(event) = recording.next_event(events)? else {
            return Ok(());
        };
        match event {
            Event::Map(map) => {
                read_ahead.release(map.bytes.len());
                recording.take_streamed(&map)?
            }
            Event::BadMap(bad, (bytes, messages)) => {
                if !skip_bad {
                    return Err(anyhow!(bad).context("record stopped"));
                }
                recording.recorder.count_bad();
                if recording.verbose {
                    outln!("received map message {messages} of a split (byte {bytes}): bad")?;
                }
                ui.note(&format!(
                    "warning: left out {}",
                    escaped(format!("{bad:#}"))
                ));
            }
            Event::SplitEnded(path, cut) => match cut {
                None => ui.note(&format!("{}: read to its end", escaped(path.display()))),
                Some(cut) => ui.note(&format!(
                    "warning: {}: {}; the next split is read",
                    escaped(path.display()),
                    escaped(cut)
                )),
            },
            Event::Failed(failed) => return Err(anyhow!(failed).context("record stopped")),
            Event::WatchFailed(error) => {
                bail!(
                    "--follow {}: watching failed: {error}",
                    escaped(dir.display())
                )
            }
            Event::Stop | Event::End => return Ok(()),
            Event::Ready(_) | Event::Rescan => {}
        }
    }
}

/// The splits thread of [`follow_bag`]: each split in turn, its maps sent as they come.
fn read_splits(
    dir: &Path,
    options: &froctomap_formats::RecordingOptions,
    limit: u64,
    sender: &SyncSender<Event>,
    woken: &Receiver<DirEvent>,
    held: &ReadAhead,
) {
    let mut last: Option<PathBuf> = None;
    loop {
        let split = match crate::follow::next_split(dir, last.as_deref(), woken, &STOP) {
            Ok(Some(split)) => split,
            Ok(None) => return,
            Err(error) => {
                let _ = sender.send(Event::WatchFailed(format!("{error:#}")));
                return;
            }
        };
        let growing = match crate::follow::GrowingSplit::open(&split, woken, &STOP) {
            Ok(growing) => growing,
            Err(error) => {
                let _ = sender.send(Event::WatchFailed(format!("{error:#}")));
                return;
            }
        };
        let mut maps = McapStreamMaps::new(growing, options, limit);
        let ended = loop {
            let event = match maps.next_map() {
                Ok(Some(Ok(map))) => {
                    held.hold(map.bytes.len());
                    Event::Map(map)
                }
                Ok(Some(Err(bad))) => {
                    let (bytes, messages) = maps.position();
                    let at = format!(
                        "{}: map message {messages} (byte {bytes})",
                        escaped(split.display())
                    );
                    Event::BadMap(anyhow!(bad).context(at), (bytes, messages))
                }
                Ok(None) => break None,
                Err(_) if STOP.load(Ordering::SeqCst) => return,
                Err(RosError::Stream {
                    bytes,
                    messages,
                    source,
                    ..
                }) => break Some(format!(
                    "it stops after {messages} message(s), at byte {bytes} ({source}): its writer did not finish it; its complete chunks are taken"
                )),
                Err(cut) => break Some(cut.to_string()),
            };
            if sender.send(event).is_err() {
                return;
            }
        };
        if sender
            .send(Event::SplitEnded(split.clone(), ended))
            .is_err()
        {
            return;
        }
        last = Some(split);
    }
}

/// The first SIGINT/SIGTERM/SIGHUP asks `record` to commit and stop; a second one ends it
/// at once, as other commands end (temporary paths removed, killed by the signal).
fn stop_on_signals(sender: SyncSender<Event>) {
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
                let _ = sender.send(Event::Stop);
            }
            drop(sender);
            if let Some(signal) = signals.next() {
                crate::signals::end_by(signal);
            }
        });
    drop(started);
}
