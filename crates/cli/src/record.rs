//! `froctomap record`: maps added to a FROctomap 2.0 file as they arrive, one segment
//! committed every `--commit-every` maps or seconds (`froctomap_convert::append_segment`).
//!
//! A stream (`-`) is read message by message on a thread of its own
//! (`froctomap_ros::McapStreamMaps`); the maps of the commit being gathered are kept in a
//! fresh [`MapSpool`] beside the file, dropped once committed, so memory and disk follow
//! one commit, not the stream. SIGINT/SIGTERM/SIGHUP reach the same channel: the maps
//! received are committed and `record` exits 0 (a second signal ends it at once).

use crate::series::{print_input_notes, SpillArgs, TimeArgs};
use crate::ui::{escaped, Ui};
use anyhow::{anyhow, bail, Context as _, Result};
use clap::Args;
use froctomap_convert::{
    append_segment, build, collect_recording, group_thousands, is_living_file, parse_duration,
    refuse_growing_fixed_span, AppendOptions, BuildOptions, Context, ConvertError, SeriesInput,
    Silent, STDIN_INPUT,
};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use froctomap_file::LivingWriter;
use froctomap_formats::MapSpool;
use froctomap_ros::{McapStreamMaps, RosError, StreamedMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender};
use std::time::{Duration, Instant};

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
    #[arg(required = true, value_name = "SOURCE")]
    sources: Vec<PathBuf>,
    /// Commit a segment every N maps (a plain number) or every so much time (5s, 1min:
    /// measured from the first map of the commit as it arrives).
    #[arg(long, value_name = "N|DURATION", default_value = "5s", value_parser = commit_every)]
    commit_every: CommitEvery,
    /// Leave maps that do not read out (logged, counted) instead of stopping; without it
    /// a bad map stops `record` after committing the maps before it.
    #[arg(long)]
    skip_bad: bool,
    /// Force the input map format instead of detecting it (file sources).
    #[arg(long, value_name = "FORMAT")]
    input_format: Option<String>,
    #[command(flatten)]
    times: TimeArgs,
    #[command(flatten)]
    spill: SpillArgs,
}

/// `--commit-every`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CommitEvery {
    Maps(usize),
    Time(Duration),
}

fn commit_every(text: &str) -> Result<CommitEvery, String> {
    if let Ok(maps) = text.trim().parse::<usize>() {
        return match maps {
            0 => Err("at least 1 map".into()),
            maps => Ok(CommitEvery::Maps(maps)),
        };
    }
    match parse_duration(text) {
        Ok(ns) if ns > 0 => Ok(CommitEvery::Time(Duration::from_nanos(ns.unsigned_abs()))),
        Ok(_) => Err("a positive duration".into()),
        Err(e) => Err(format!("{e} (or a number of maps)")),
    }
}

/// What reaches the main thread: the stream's maps and the signals.
enum Event {
    Map(StreamedMap),
    /// A map message that does not read, and (bytes, messages) read when it came.
    BadMap(RosError, (u64, u64)),
    /// The stream ended whole.
    End,
    /// The stream stopped reading (cut, garbage, read error).
    Failed(RosError),
    /// SIGINT, SIGTERM or SIGHUP.
    Stop,
}

/// Set once a signal asked `record` to stop.
static STOP: AtomicBool = AtomicBool::new(false);

/// The file being recorded to, and the maps of the commit being gathered.
struct Recorder<'a> {
    ui: &'a Ui,
    context: &'a Context,
    /// The file being recorded to (`None`: it does not exist yet, and the first commit's
    /// maps become its base).
    file: PathBuf,
    writer: Option<LivingWriter>,
    options: AppendOptions,
    spool_parent: PathBuf,
    /// The last time taken (the file's last sample at first).
    last: Timestamp,
    files: Vec<SeriesInput>,
    spool: Option<MapSpool>,
    /// When the first map of the commit being gathered arrived.
    gathering_since: Option<Instant>,
    commit_every: CommitEvery,
    older: u64,
    bad: u64,
    committed_maps: usize,
    commits: usize,
}

impl Recorder<'_> {
    fn pending(&self) -> usize {
        self.files.len() + self.spool.as_ref().map_or(0, MapSpool::len)
    }

    /// Counts a map at `time` as older when it is not later than the last one taken.
    fn is_older(&mut self, time: Timestamp) -> bool {
        if time <= self.last {
            self.older += 1;
            return true;
        }
        self.last = time;
        self.gathering_since.get_or_insert_with(Instant::now);
        false
    }

    fn take_file(&mut self, input: SeriesInput) -> Result<()> {
        if self.pending() == 0 {
            self.refuse_full()?;
        }
        if !self.is_older(input.time) {
            self.files.push(input);
        }
        self.commit_if_due()
    }

    fn take_streamed(&mut self, map: &StreamedMap) -> Result<()> {
        if self.pending() == 0 {
            self.refuse_full()?;
        }
        if !self.is_older(map.time) {
            let spool = match &mut self.spool {
                Some(spool) => spool,
                None => self
                    .spool
                    .insert(MapSpool::new(Some(&self.spool_parent), "-")?),
            };
            spool.push(map.time, &map.bytes)?;
        }
        self.commit_if_due()
    }

    /// How long until a commit by time is due (`None`: none is).
    fn time_left(&self) -> Option<Duration> {
        match (self.commit_every, self.gathering_since) {
            (CommitEvery::Time(every), Some(since)) => Some(every.saturating_sub(since.elapsed())),
            _ => None,
        }
    }

    fn commit_if_due(&mut self) -> Result<()> {
        let due = match self.commit_every {
            CommitEvery::Maps(n) => self.pending() >= n,
            CommitEvery::Time(_) => self.time_left() == Some(Duration::ZERO),
        };
        if due {
            self.commit()?;
        }
        Ok(())
    }

    /// Refuses to gather another commit when the file holds the most segments it may: the
    /// maps received so far are committed, and `compact` makes it one segment again.
    fn refuse_full(&self) -> Result<()> {
        let Some(writer) = &self.writer else {
            return Ok(());
        };
        let (segments, limit) = (
            writer.reader().segment_count(),
            self.context.limits().froct.max_segments,
        );
        if segments as u64 >= limit {
            bail!(
                "{} holds {segments} segments, the most a file may hold: run `froctomap compact {}` and record on (the maps received before are committed)",
                escaped(self.file.display()),
                escaped(self.file.display())
            );
        }
        Ok(())
    }

    /// Commits the maps gathered: as one segment, or, when that fails, in smaller pieces,
    /// so that every good map before a bad one is committed.
    fn commit(&mut self) -> Result<()> {
        self.gathering_since = None;
        if self.pending() == 0 {
            return Ok(());
        }
        let mut series = std::mem::take(&mut self.files);
        if let Some(spool) = self.spool.take() {
            let recording = spool.into_recording()?;
            series.extend(collect_recording(PathBuf::from(STDIN_INPUT), recording)?.series);
        }
        series.sort_by_key(|input| input.time);
        self.commit_pieces(&series)
    }

    /// Commits `series` as one segment; when that fails, its halves in order (a segment
    /// commits all its maps or none). Without `--skip-bad` the first map that fails alone
    /// stops `record` with its error; with it, that map is logged, counted and left out.
    /// A failure that is not the maps' (the file, the disk) fails alone as well, after at
    /// most log2(maps) tries.
    fn commit_pieces(&mut self, series: &[SeriesInput]) -> Result<()> {
        self.refuse_full()?;
        let error = match self.commit_segment(series) {
            Ok(()) => return Ok(()),
            Err(error) => error,
        };
        let all_bad = matches!(
            error.downcast_ref::<ConvertError>(),
            Some(ConvertError::NothingToBuild { .. })
        );
        if self.options.skip_bad && all_bad {
            self.bad += series.len() as u64;
            self.ui.note(&format!(
                "warning: nothing to commit: {} map(s) left out: {:#}",
                series.len(),
                escaped(&error)
            ));
            return Ok(());
        }
        match series {
            [] => Ok(()),
            [_] if self.options.skip_bad && is_bad_map(&error) => {
                self.bad += 1;
                self.ui
                    .note(&format!("warning: left out: {:#}", escaped(&error)));
                Ok(())
            }
            [_] => Err(error),
            _ => {
                let (before, after) = series.split_at(series.len() / 2);
                self.commit_pieces(before)?;
                self.commit_pieces(after)
            }
        }
    }

    /// Commits `series` (time-sorted, not empty) as one segment, printing one line.
    fn commit_segment(&mut self, series: &[SeriesInput]) -> Result<()> {
        let started = Instant::now();
        let (first, last) = match (series.first(), series.last()) {
            (Some(first), Some(last)) => (first.time, last.time),
            _ => return Ok(()),
        };
        let committing = || match series {
            [one] => format!(
                "committing the map of {} ({})",
                iso8601(first),
                escaped(one.path.display())
            ),
            _ => format!(
                "committing {} maps ({} .. {})",
                series.len(),
                iso8601(first),
                iso8601(last)
            ),
        };
        let Some(writer) = &mut self.writer else {
            let report = self.build_base(series).with_context(committing)?;
            self.commits += 1;
            self.committed_maps += report.used;
            outln!(
                "base: {} maps, {} .. {}, {} bytes, {} ms",
                report.used,
                iso8601(first),
                iso8601(last),
                group_thousands(report.file_bytes),
                started.elapsed().as_millis()
            )?;
            print_input_notes(self.ui, &[], &report.skipped);
            return Ok(());
        };
        let report = append_segment(self.context, writer, series, &self.options, &Silent)
            .with_context(committing)?;
        self.commits += 1;
        self.committed_maps += report.added;
        outln!(
            "segment {}: {} maps, {} .. {}, +{} bytes, {} ms",
            report.segments.unwrap_or(0),
            report.added,
            iso8601(first),
            iso8601(last),
            group_thousands(report.file_bytes.saturating_sub(report.bytes_before)),
            started.elapsed().as_millis()
        )?;
        print_input_notes(self.ui, &report.warnings, &report.skipped);
        Ok(())
    }

    /// The first maps built into the file, which did not exist (atomically, as `build`
    /// writes), then converted to 2.0 in place (atomically) and opened for the segments.
    /// Killed between the two, the file is a 1.x build, which the next `record` converts.
    fn build_base(&mut self, series: &[SeriesInput]) -> Result<froctomap_convert::BuildReport> {
        let options = BuildOptions {
            skip_bad: self.options.skip_bad,
            allow_mostly_skipped: true,
            input_format: self.options.input_format.clone(),
            backend: self.options.backend,
            memory: self.options.memory,
            tmp_dir: self.options.tmp_dir.clone(),
            ..BuildOptions::default()
        };
        let report = build(self.context, series, &self.file, &options, &Silent)?;
        LivingWriter::convert(&self.file, &self.file)?;
        self.writer = Some(LivingWriter::open_with_limits(
            &self.file,
            self.context.limits().froct,
            self.context.models(),
        )?);
        Ok(report)
    }
}

pub fn record_command(ui: &Ui, args: &RecordArgs) -> Result<()> {
    if let Some((limit, default)) = args.spill.max_memory.limit() {
        crate::memory_guard::watch(limit, default, "record");
    }
    let (sender, events) = sync_channel::<Event>(4);
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
    let writer = if args.file.exists() {
        Some(open_living(ui, context, &args.file)?)
    } else {
        ui.note(&format!(
            "{} does not exist: the first commit's maps become its base (a build with the default model, fremen-periods, lossless)",
            escaped(args.file.display())
        ));
        None
    };
    let last = writer
        .as_ref()
        .map_or(Timestamp(i64::MIN), |w| w.reader().last_instant());
    let mut recorder = Recorder {
        ui,
        context,
        file: args.file.clone(),
        writer,
        options: AppendOptions {
            skip_bad: args.skip_bad,
            allow_mostly_skipped: true,
            input_format: args.input_format.clone(),
            backend: Some(ui.backend),
            memory: args.spill.memory,
            tmp_dir: args.spill.tmp_dir.clone(),
            ..AppendOptions::default()
        },
        spool_parent,
        last,
        files: Vec::new(),
        spool: None,
        gathering_since: None,
        commit_every: args.commit_every,
        older: 0,
        bad: 0,
        committed_maps: 0,
        commits: 0,
    };
    ui.note(&format!(
        "recording into {} (last sample {}), committing every {}",
        escaped(args.file.display()),
        if recorder.writer.is_some() {
            iso8601(last)
        } else {
            "none".to_string()
        },
        match args.commit_every {
            CommitEvery::Maps(n) => format!("{n} maps"),
            CommitEvery::Time(t) => format!("{:.3} s", t.as_secs_f64()),
        }
    ));
    let mut sender = Some(sender);
    for source in &args.sources {
        if STOP.load(Ordering::SeqCst) {
            break;
        }
        let result = if source.as_os_str() == STDIN_INPUT {
            let Some(sender) = sender.take() else {
                bail!("`-` (standard input) is given twice");
            };
            read_stream(&mut recorder, sender, &events)
        } else {
            read_files(&mut recorder, args, source)
        };
        if let Err(error) = result {
            // What came before the failure is committed; its own commit failing is said
            // with the failure.
            if let Err(commit) = recorder.commit() {
                return Err(error.context(format!(
                    "record stopped, and the maps received before were not all committed: {commit:#}"
                )));
            }
            return Err(error);
        }
    }
    recorder.commit()?;
    if STOP.load(Ordering::SeqCst) {
        ui.note("stopped by a signal: the maps received are committed");
    }
    ui.note(&format!(
        "recorded {} maps in {} segment(s); {} not later than the last one taken were skipped{}",
        recorder.committed_maps,
        recorder.commits,
        recorder.older,
        match recorder.bad {
            0 => String::new(),
            n => format!(", {n} bad map(s) left out"),
        }
    ));
    Ok(())
}

/// Whether a commit's `error` is its map's (unreadable, of another resolution, too large),
/// which `--skip-bad` leaves out, rather than the file's or the disk's.
fn is_bad_map(error: &anyhow::Error) -> bool {
    matches!(
        error.downcast_ref::<ConvertError>(),
        Some(
            ConvertError::MixedResolution { .. }
                | ConvertError::Snapshot { .. }
                | ConvertError::Read(_)
                | ConvertError::SnapshotResolution { .. }
                | ConvertError::NothingToBuild { .. }
                | ConvertError::AllSkipped { .. }
                | ConvertError::MostlySkipped { .. }
                | ConvertError::TooManyMaps { .. }
                | ConvertError::BadResolution { .. }
        )
    )
}

/// The file as a 2.0 writer: a 1.x file converted in place first (atomically).
fn open_living(ui: &Ui, context: &Context, file: &Path) -> Result<LivingWriter> {
    // Refused (a map file, a damaged file, a model that cannot grow) before any conversion.
    refuse_growing_fixed_span(context, file)?;
    if !is_living_file(file)? {
        ui.note(&format!(
            "converting {} to format 2.0 (older releases cannot read it)",
            escaped(file.display())
        ));
        LivingWriter::convert(file, file)?;
    }
    Ok(LivingWriter::open_with_limits(
        file,
        context.limits().froct,
        context.models(),
    )?)
}

fn read_files(recorder: &mut Recorder<'_>, args: &RecordArgs, source: &Path) -> Result<()> {
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
    recorder: &mut Recorder<'_>,
    sender: SyncSender<Event>,
    events: &Receiver<Event>,
) -> Result<()> {
    let stdin = std::io::stdin();
    if std::io::IsTerminal::is_terminal(&stdin) {
        bail!("-: standard input is a terminal, not an MCAP stream");
    }
    let options = recorder.context.recording_options().clone();
    let limit = recorder.context.limits().max_map_file_bytes;
    // Not joined: at a signal it may be blocked reading, and ends with the process.
    std::thread::Builder::new()
        .name("stream".into())
        .spawn(move || {
            let mut maps = McapStreamMaps::new(stdin.lock(), &options, limit);
            loop {
                let event = match maps.next_map() {
                    Ok(Some(Ok(map))) => Event::Map(map),
                    Ok(Some(Err(bad))) => Event::BadMap(bad, maps.position()),
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
        let event = match recorder.time_left() {
            Some(left) => match events.recv_timeout(left) {
                Ok(event) => event,
                Err(RecvTimeoutError::Timeout) => {
                    recorder.commit()?;
                    continue;
                }
                Err(RecvTimeoutError::Disconnected) => return Ok(()),
            },
            None => match events.recv() {
                Ok(event) => event,
                Err(_) => return Ok(()),
            },
        };
        match event {
            Event::Map(map) => recorder.take_streamed(&map)?,
            Event::BadMap(bad, (bytes, messages)) => {
                let at = format!("map message {messages} of the stream (byte {bytes})");
                if !recorder.options.skip_bad {
                    return Err(anyhow!(bad).context(format!("record stopped at {at}")));
                }
                recorder.bad += 1;
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
        }
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
