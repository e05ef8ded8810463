//! `froctomap-bench`: where froctomap stands, in numbers, on a series that looks like a
//! real long-term deployment.
//!
//! * `froctomap-bench generate` writes a deterministic series of `.bt` snapshots plus
//!   `manifest.csv` from a real base map (the `froctomap-synth` generator: doors driven by
//!   the real door recording and by schedules, people, chairs, objects, machines, surface
//!   noise, partial views, optional jitter and missed frames). It streams: memory does not
//!   grow with the number of frames.
//! * `froctomap-bench run --size ci|week|4weeks|<days>` generates a training series and the
//!   held-out days after it, then measures in one process, on the same files: storage
//!   (raw `.bt`, `tar | zstd -19 --long=31`, `tar | xz -9`, froctomap lossless and lossy at
//!   orders 0–5, ratio against raw states), time (`build` against the C++ library's
//!   read-only time, `retrieve`/`predict` of one snapshot against one C++ read, peak memory
//!   at two series lengths) and accuracy (reconstruction and prediction error against the
//!   static-mean and last-seen baselines). It prints markdown tables and writes
//!   `results.json` and PNG plots. `scripts/bench.sh` runs it in one line; what each number
//!   means is in `docs/BENCHMARKS.md`.
//!
//! Builds run as child processes of this binary (a hidden `build-child` subcommand) so that
//! each one's peak memory (`VmHWM`) is its own.

mod anomaly_eval;
mod append_cost;
mod child_build;
mod dataset;
mod floor;
mod generate;
mod greg_door;
mod plots;
mod recording;
mod report;
mod ros2_live;
mod run;
mod series_args;
mod size;
mod system;
mod tables;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

// The same allocator as the `froctomap` CLI, so builds here cost what they cost there.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// As the CLI does for `build` (its `purge_freed_memory_at_once`): mimalloc's
/// `mi_option_purge_delay` (index 15) set to 0, so freed memory leaves the resident set at once.
// The one call into mimalloc's C API, which has no safe binding for options.
#[allow(unsafe_code)]
fn purge_freed_memory_at_once() {
    // SAFETY: a plain option setter, called before the build starts.
    unsafe { libmimalloc_sys::mi_option_set(15, 0) }
}

/// Long-term benchmark of froctomap: realistic series, storage, time and accuracy against
/// tar | zstd, xz and the upstream OctoMap library.
#[derive(Parser)]
#[command(name = "froctomap-bench", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write a deterministic series of OctoMap snapshots (.bt) and manifest.csv.
    ///
    /// Example: froctomap-bench generate --days 28 --step 10min -o /work/data/w4
    Generate(generate::GenerateArgs),
    /// Generate a series and measure storage, time and accuracy; print markdown, write
    /// results.json and PNG plots.
    ///
    /// Example: froctomap-bench run --size 4weeks --out bench-out
    Run(run::RunArgs),
    /// Only the anomaly evaluation (injected boxes and closed doors in held-out snapshots;
    /// precision/recall against the last-seen and static-mean baselines), on the series
    /// `run` generates, kept under --data.
    ///
    /// Example: froctomap-bench anomalies --size ci --data target/bench-data
    Anomalies(anomaly_eval::AnomalyEvalArgs),
    /// Only the MCAP row: pack a series of .bt files into one MCAP and time `froctomap
    /// build` from it against the .bt directory (same files, checked byte-identical).
    ///
    /// Example: froctomap-bench mcap --series /work/data-18/4weeks/train --out target/mcap-row
    Mcap(recording::McapRowArgs),
    /// The entropy floor of a series (the bits the generator's random draws put into the
    /// observed training snapshots), optionally against the lossless file and tar | zstd.
    ///
    /// Example: froctomap-bench floor --size 4weeks --data /work/data/w4 --measure
    Floor(floor::FloorArgs),
    /// Prediction on the real greg_door recording made into a small room: per test week,
    /// the model, static mean, last seen and a plain FreMEn computed in numpy
    /// (scripts/fremen_reference.py): thresholded error, Brier score, log loss.
    ///
    /// Example: froctomap-bench greg-door --size full --out target/greg-door
    GregDoor(greg_door::GregDoorArgs),
    /// What appending the same maps costs as the file's history grows: as a format 2.0
    /// segment and by the 1.x rebuild-append, to files of several lengths (median times,
    /// ratio of the longest to the shortest).
    ///
    /// Example: froctomap-bench append-cost --series /work/data/office --work target/append-cost
    AppendCost(append_cost::AppendCostArgs),
    /// The ROS 2 node (`froctomap ros2`, built with the `ros2` feature) fed by the Cyclone
    /// DDS peer on loopback: maps/s received and committed, publish-to-commit latency,
    /// get_octomap_at round trips and the predicted map's publication, against `froctomap
    /// retrieve`/`predict` in the same run.
    ///
    /// Example: froctomap-bench ros2 --series target/bench-data/ci/train --maps 60 --out target/ros2-bench
    Ros2(ros2_live::Ros2BenchArgs),
    /// Build one file and print the report with this process's peak memory as JSON.
    #[command(hide = true)]
    BuildChild(child_build::BuildChildArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Generate(args) => generate::generate(&args),
        Command::Run(args) => run::run(&args),
        Command::Anomalies(args) => anomaly_eval::anomalies_command(&args),
        Command::Mcap(args) => recording::mcap_row(&args),
        Command::Floor(args) => floor::floor_command(&args),
        Command::GregDoor(args) => greg_door::greg_door_command(&args),
        Command::AppendCost(args) => append_cost::append_cost(&args),
        Command::Ros2(args) => ros2_live::ros2_bench(&args),
        Command::BuildChild(args) => {
            purge_freed_memory_at_once();
            child_build::build_child(&args)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}
