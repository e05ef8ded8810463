//! `froctomap`: the command-line front end of the froctomap libraries.

mod commands;

use clap::{Parser, Subcommand, ValueEnum};
use froctomap_formats::Backend;
use std::process::ExitCode;

/// Long-term 3D maps: turn a series of OctoMap snapshots into one spatio-temporal file and
/// back. This version inspects and converts OctoMap files.
#[derive(Parser)]
#[command(name = "froctomap", version, about, long_about = None, propagate_version = true)]
struct Cli {
    /// Print nothing but results and errors (no warnings, no summaries).
    #[arg(short, long, global = true)]
    quiet: bool,

    /// Implementation that reads and writes OctoMap .bt/.ot files: froctomap's native Rust
    /// codec, or the upstream OctoMap C++ library. Both give identical maps and bytes.
    #[arg(long, global = true, value_enum, default_value_t = BackendArg::Native)]
    backend: BackendArg,

    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, ValueEnum)]
enum BackendArg {
    /// The upstream OctoMap C++ library (liboctomap).
    Octomap,
    /// froctomap's own Rust codec (the default; faster).
    Native,
}

impl From<BackendArg> for Backend {
    fn from(arg: BackendArg) -> Self {
        match arg {
            BackendArg::Octomap => Backend::Octomap,
            BackendArg::Native => Backend::Native,
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Describe a map file: format, resolution, leaf and voxel counts, bounding boxes.
    ///
    /// The format is detected from the content, never from the extension.
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
    /// List the registered map formats.
    Formats,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let ui = commands::Ui {
        quiet: cli.quiet,
        backend: cli.backend.into(),
    };
    let result = match cli.command {
        Command::Info(args) => commands::info(&ui, &args),
        Command::Convert(args) => commands::convert(&ui, &args),
        Command::Formats => commands::formats(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}
