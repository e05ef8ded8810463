//! `froctomap`: the command-line front end of the froctomap libraries.

/// `println!` that returns the write's error instead of panicking, so that a closed pipe
/// (`froctomap info x | head -1`) ends the command quietly (see `main`).
/// Reports go to standard error when a map is written to standard output (`-o -`).
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if $crate::REPORTS_TO_STDERR.load(std::sync::atomic::Ordering::Relaxed) {
            writeln!(std::io::stderr().lock(), $($arg)*)
        } else {
            writeln!(std::io::stdout().lock(), $($arg)*)
        }
    }};
}

/// Set when an output is standard output (`-o -`, [`froctomap_core::STDOUT`]): what the
/// command would print goes to standard error instead, so the map's bytes stay alone.
static REPORTS_TO_STDERR: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether the arguments name standard output as an output (`-o -`, `--output -`,
/// `--output=-`, `-o-`).
fn writes_to_stdout(args: &[std::ffi::OsString]) -> bool {
    args.windows(2)
        .any(|pair| (pair[0] == "-o" || pair[0] == "--output") && pair[1] == "-")
        || args.iter().any(|a| a == "--output=-" || a == "-o-")
}

mod anomalies;
mod append;
mod commands;
mod compact;
mod errors;
mod follow;
#[cfg(feature = "foxglove")]
mod foxglove;
mod froct_info;
mod generate;
mod history;
mod manual;
mod memory_guard;
mod plugins;
mod progress;
mod record;
mod render;
#[cfg(feature = "ros2")]
mod ros2;
mod series;
mod signals;
mod ui;

use clap::{CommandFactory, Parser, Subcommand};
use froctomap_formats::Backend;
use std::process::ExitCode;

// Building a series allocates and frees a multi-megabyte leaf list per snapshot; glibc's
// malloc serves those with fresh mmaps (page faults on every touch), mimalloc reuses them.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// mimalloc's `mi_option_purge_delay` (15 in mimalloc 2 and 3; the bindings do not name it).
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Has mimalloc give freed memory back to the system at once. A build frees the
/// accumulator's histories and then one tile's fitted cells after another; mimalloc 3 keeps
/// freed pages for 1 s (arenas 10 s) by default, so a long build's resident memory counted
/// them on top of its live memory: the paper week's fit stage sat at 150 MiB between tiles
/// with about 50 MiB live (docs/BENCHMARKS.md). Costs a few percent of system time.
// The one call into mimalloc's C API, which has no safe binding for options.
#[allow(unsafe_code)]
fn purge_freed_memory_at_once() {
    // SAFETY: a plain option setter, called before the command's work starts.
    unsafe { libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, 0) }
}

/// Long-term 3D maps: turn a series of OctoMap snapshots into one compact spatio-temporal
/// file (FROctomap: a FreMEn model per changing voxel), retrieve the map at any past time,
/// predict it at a future one, and export either as standard OctoMap files.
///
/// Typical use:
///   froctomap build snapshots/ -o office.froct
///   froctomap retrieve office.froct --time 2016-01-05T10:00:00Z -o then.bt
///   froctomap predict office.froct --time 2016-02-01T10:00:00Z -o later.ot
#[derive(Parser)]
#[command(name = "froctomap", version, about, long_about = None, propagate_version = true)]
struct Cli {
    /// Print nothing but results and errors (no warnings, no summaries).
    #[arg(short, long, global = true)]
    quiet: bool,

    /// Implementation that reads and writes OctoMap .bt/.ot files: froctomap's native Rust
    /// codec, or the upstream OctoMap C++ library. Both give identical maps and bytes.
    #[arg(long, global = true, value_parser = crate::plugins::named::<Backend>(),
          default_value_t = Backend::Native)]
    backend: Backend,

    /// Time zone of times given without one (in file names, manifests, --start, --time,
    /// --from/--to): UTC (the default), local, an offset like +01:00, or a name like
    /// Europe/Berlin. Unix seconds and times with Z or an offset are not affected.
    #[arg(long, global = true, value_name = "ZONE|local")]
    tz: Option<String>,

    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Describe a map file: format, resolution, leaf and voxel counts, bounding boxes.
    ///
    /// The format is detected from the content, never from the extension. For a FROctomap
    /// file: its version, span, cells by class, sizes, periods and dynamic regions, and for
    /// a 2.0 file its segments (samples each) and committed length.
    ///
    /// Example: froctomap info geb079.bt
    Info(commands::InfoArgs),
    /// Convert a map file between formats (any readable format to any writable one).
    ///
    /// The input format is detected from the content (or forced with --input-format), the
    /// output format comes from the output extension (or --format). The output is written
    /// atomically: it appears complete or not at all.
    ///
    /// Example: froctomap convert geb079.bt geb079.ot
    Convert(commands::ConvertArgs),
    /// List the registered formats: map files per backend, the series file, recordings
    /// (with `rec,w` where froctomap writes them).
    Formats(commands::FormatsArgs),
    /// Build one FROctomap file from a series of OctoMap snapshots.
    ///
    /// Inputs are directories (their manifest.csv, else every .bt/.ot file), glob patterns,
    /// manifests (`path,time` CSV, times in Unix seconds or ISO 8601), files, recordings
    /// (ROS bags, MCAP) or `-`, an MCAP stream on standard input. Times come from the
    /// manifest, from the file names (Unix seconds or ISO 8601 in the name), from
    /// --start/--step, or from the recording. Snapshots are read in parallel and accumulated in time order;
    /// memory grows with the map, not with the number of snapshots. Unknown space stays
    /// unknown. Lossless by default: every observed state comes back exactly.
    ///
    /// Examples (a directory; files with times from a start and a step):
    ///
    /// froctomap build maps/ -o office.froct
    ///
    /// froctomap build 'scans/*.bt' --start 2016-01-04T00:00:00Z --step 10min -o office.froct
    Build(series::BuildArgs),
    /// Add snapshots later than a FROctomap file's last one to it.
    ///
    /// Inputs as for `build`, all later than the file's last sample and of its resolution
    /// (others are refused, and the file is left as it was). Reads the file and the new
    /// snapshots only: the snapshots the file was built from are not needed. Every earlier
    /// and every new observed state is kept (exactly, in a lossless file), and every model is
    /// refitted on the whole history, so the file is what a build of all the snapshots
    /// gives. A lossy file's past is its reconstruction: that is what the refit sees, and
    /// the file stays lossy. The file is replaced atomically.
    ///
    /// A format 2.0 file (or any file with --format-version 2.0, which converts a 1.x file)
    /// instead gets the snapshots as one new segment, committed at once: the cost follows
    /// the new snapshots, not the file's history (the models stay frozen until compaction).
    ///
    /// Example: froctomap append office.froct maps/today/
    Append(append::AppendArgs),
    /// Rewrite a FROctomap 2.0 file's base and segments as one base.
    ///
    /// Every cell is refitted on its whole history through the same stages as `build`
    /// (in the same bounded memory), so the result equals a build of the same maps apart
    /// from metadata. Reads only the file. Without -o the file is replaced atomically; a
    /// 2.0 file's writer lock is held meanwhile (an append to it fails, it does not wait);
    /// readers that have it open keep the old file. Whole-history commands (eval, anomalies, history,
    /// render) need a 2.0 file compacted first. The result is format 2.0 with no segment,
    /// or 1.x with --format-version.
    ///
    /// Examples (in place; a copy for readers of 1.2):
    ///
    /// froctomap compact office.froct
    ///
    /// froctomap compact office.froct -o office-1.2.froct --format-version 1.2
    Compact(compact::CompactArgs),
    /// Add maps to a FROctomap file as they arrive, one segment committed at a time.
    ///
    /// Reads its sources in the order given — `-`, an MCAP stream on standard input read
    /// map by map as it arrives (e.g. `froctomap generate --stream`, a recorder's output),
    /// or inputs as for `build` — and commits what it has gathered every --commit-every
    /// maps or seconds as one segment of format 2.0 (as `append` does for a 2.0 file), printing
    /// one line per commit. Only the maps of the commit being gathered are kept (on disk,
    /// beside the file), so memory and spool follow one commit; the file grows by a segment
    /// per commit and is compacted in place after a commit when its segments pass half its
    /// base's size, its span has doubled since the last compaction or its segments reach a
    /// quarter of the format's limit of 65,536 (one line each;
    /// --no-compact: only `froctomap compact FILE` does; at the segment limit `record`
    /// commits what it received and stops, saying so). -v prints a line per map received.
    /// Maps not later than the last one taken are skipped and counted (overlapping bag
    /// splits). A bad map stops it after committing the maps before it (--skip-bad: left
    /// out and logged); a cut stream likewise. Ctrl-C/SIGTERM commit the maps received and
    /// exit 0. A missing file gets the first commit's maps as its base (built with the
    /// default model); a 1.x file is converted to 2.0 first. `fremen-regular` files are
    /// refused (their model cannot grow). --follow DIR then records what appears in DIR
    /// until Ctrl-C: map files once closed or renamed into place, or the splits of a
    /// `ros2 bag record` directory as they grow.
    ///
    /// Example: froctomap generate --stream --days 1 | froctomap record office.froct - --commit-every 60
    ///
    /// Example: froctomap record office.froct --follow /robot/maps/
    Record(record::RecordArgs),
    /// Write the map as observed at a time (exact in lossless files).
    ///
    /// Example: froctomap retrieve office.froct --time 2016-01-05T10:00:00Z -o then.bt
    Retrieve(series::RetrieveArgs),
    /// Write the predicted map at any time, including the future.
    ///
    /// A .ot output carries each voxel's probability p(t) as log-odds (within OctoMap's
    /// clamping bounds); a .bt output the thresholded states (occupied when p(t) > 0.5).
    ///
    /// Example: froctomap predict office.froct --time 2016-02-01T10:00:00Z -o later.ot
    Predict(series::PredictArgs),
    /// Draw a FROctomap file as a PNG picture: the map at a time seen from above (occupied,
    /// free, unknown columns), a horizontal slice, or where the world changes (--dynamics).
    /// The text is set in DejaVu Sans (Debian: fonts-dejavu-core), or in the .ttf file the
    /// environment variable FROCTOMAP_FONT names.
    ///
    /// Examples (the map at a time; where the world changes):
    ///
    /// froctomap render office.froct --time 2016-01-05T10:00:00Z -o map.png
    ///
    /// froctomap render office.froct --dynamics -o changes.png
    Render(render::RenderArgs),
    /// One voxel's history: its observed states over time, its model's p(t), its outliers
    /// and its class, as a table (or --json), and as a plot with -o.
    ///
    /// Example: froctomap history office.froct --at 23.5,-0.5,1.0 -o voxel.png
    History(history::HistoryArgs),
    /// Write one OctoMap file per instant of a range, plus a manifest.csv, or every map into
    /// one recording: MCAP (an output named *.mcap) or a ROS 1 bag (*.bag).
    ///
    /// Examples (a directory of .bt files; an MCAP for rviz2; one for Foxglove, uncertain
    /// space drawn, under a robot's namespace):
    ///
    /// froctomap export office.froct --from 2016-01-04 --to 2016-01-05 --every 1h -o hourly/
    ///
    /// froctomap export office.froct --from 2016-01-04 --to 2016-01-05 --every 1h --mode auto -o office.mcap
    ///
    /// froctomap export office.froct --from 2016-01-04 --to 2016-01-05 --every 1h --profile foxglove --threshold 0.2 --frame-id odom --topic-prefix /robot1 -o office.mcap
    Export(series::ExportArgs),
    /// Compare a FROctomap file with ground-truth maps: reconstruction error inside the
    /// modelled span, prediction error outside it, against the static-mean and last-seen
    /// baselines.
    ///
    /// Example: froctomap eval office.froct --against later-maps/
    Eval(series::EvalArgs),
    /// Score a snapshot against a FROctomap file's model at the snapshot's time: what
    /// appeared or vanished that the model did not expect then, as connected regions ranked
    /// by surprise.
    ///
    /// Each observed voxel's surprise is −ln of the probability the model gave its state
    /// (static cells: their stored state with --error-rate; space never observed: occupied
    /// there is surprising). Voxels the model gave less than --voxel-probability are
    /// grouped into connected regions of one kind; regions of at least --min-score nats are
    /// listed, most surprising first (--json: bounding boxes in metres, voxels, score, kind).
    /// The time comes from --time, else from the snapshot's file name or a manifest.csv
    /// beside it.
    ///
    /// Example: froctomap anomalies office.froct scan_2016-01-20T10-00-00Z.bt -o anomalies.bt --png anomalies.png
    Anomalies(anomalies::AnomaliesArgs),
    /// Write a realistic series of OctoMap snapshots made from a real map: doors (driven by
    /// real recordings with --real-doors, or schedules), people and chairs in working hours,
    /// objects staying for days, machines on shifts, sensor noise at surfaces and partially
    /// observed snapshots. Deterministic for a seed. Files are named by time, with a
    /// manifest.csv that `build` reads.
    ///
    /// Example: froctomap generate --days 3 --step 30min -o series/
    Generate(generate::GenerateArgs),
    /// Run the ROS 2 node (in progress): publish the map FILE predicts on
    /// /froctomap/predicted (latched) and receive octomap_msgs/msg/Octomap maps on --topic
    /// (recording them comes with `record`). Domain from ROS_DOMAIN_ID; loopback only unless
    /// --network says otherwise.
    ///
    /// Example: ROS_DOMAIN_ID=7 froctomap ros2 office.froct --network all --horizon 1h
    #[cfg(feature = "ros2")]
    Ros2(ros2::Ros2Args),
    /// Print the completion script of a shell.
    ///
    /// Example: froctomap completions bash > ~/.local/share/bash-completion/completions/froctomap
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print the manual page (roff).
    ///
    /// Example: froctomap man > froctomap.1 && man ./froctomap.1
    Man,
}

fn main() -> ExitCode {
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    if writes_to_stdout(&args) {
        REPORTS_TO_STDERR.store(true, std::sync::atomic::Ordering::Relaxed);
    }
    let cli = Cli::parse_from(args);
    if matches!(&cli.command, Command::Generate(args) if args.streams()) {
        REPORTS_TO_STDERR.store(true, std::sync::atomic::Ordering::Relaxed);
    }
    // `record` and `ros2` handle the signals themselves: they commit what they received.
    let handles_signals = match &cli.command {
        Command::Record(_) => true,
        #[cfg(feature = "ros2")]
        Command::Ros2(_) => true,
        _ => false,
    };
    if !handles_signals {
        signals::clean_up_on_signals();
    }
    let zone = match cli.tz.as_deref().map(froctomap_convert::Zone::named) {
        None => froctomap_convert::Zone::utc(),
        Some(Ok(zone)) => zone,
        Some(Err(error)) => {
            eprintln!("error: --tz: {}", ui::escaped(error));
            return ExitCode::from(2);
        }
    };
    let ui = ui::Ui {
        quiet: cli.quiet,
        backend: cli.backend,
        context: plugins::context(),
        zone,
        zone_given: cli.tz.is_some(),
        told_zoneless: std::cell::Cell::new(false),
    };
    let skips_bad_files = matches!(
        cli.command,
        Command::Build(_) | Command::Append(_) | Command::Record(_)
    );
    let builds = skips_bad_files || matches!(cli.command, Command::Compact(_));
    if builds {
        purge_freed_memory_at_once();
    }
    let result = match cli.command {
        Command::Info(args) => commands::info(&ui, &args),
        Command::Convert(args) => commands::convert(&ui, &args),
        Command::Formats(args) => commands::formats(&ui, &args),
        Command::Build(args) => series::build_command(&ui, &args),
        Command::Append(args) => append::append_command(&ui, &args),
        Command::Compact(args) => compact::compact_command(&ui, &args),
        Command::Record(args) => record::record_command(&ui, &args),
        Command::Retrieve(args) => series::retrieve_command(&ui, &args),
        Command::Predict(args) => series::predict_command(&ui, &args),
        Command::Render(args) => render::render_command(&ui, &args),
        Command::History(args) => history::history_command(&ui, &args),
        Command::Export(args) => series::export_command(&ui, &args),
        Command::Eval(args) => series::eval_command(&ui, &args),
        Command::Anomalies(args) => anomalies::anomalies_command(&ui, &args),
        Command::Generate(args) => generate::generate_command(&ui, &args),
        #[cfg(feature = "ros2")]
        Command::Ros2(args) => ros2::ros2_command(&ui, &args),
        Command::Completions { shell } => manual::completions(Cli::command(), shell),
        Command::Man => manual::man(Cli::command()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The reader of our output has gone (`| head`): nothing more to say to anyone.
        Err(error) if is_broken_pipe(&error) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", ui::escaped(errors::message(&error)));
            if let Some(hint) = errors::hint(&error, skips_bad_files) {
                eprintln!("hint: {hint}");
            }
            ExitCode::FAILURE
        }
    }
}

fn is_broken_pipe(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(unsafe_code)]
    fn the_option_set_is_mimallocs_purge_delay() {
        // SAFETY: plain option getter.
        let delay = || unsafe { libmimalloc_sys::mi_option_get(MI_OPTION_PURGE_DELAY) };
        // mimalloc 3's default purge delay: the index names that option, not another.
        assert_eq!(
            delay(),
            1000,
            "is MI_OPTION_PURGE_DELAY still mimalloc's index?"
        );
        purge_freed_memory_at_once();
        assert_eq!(delay(), 0);
    }
}
