//! Builds in a child process (`build-child`, so that each build's peak memory is its own) and
//! timing of repeated work.

use crate::system::peak_memory_bytes;
use crate::tables::median;
use anyhow::{bail, Context, Result};
use clap::Args;
use froctomap_convert::{
    build, collect_inputs, write_observed_map, BuildOptions, Silent, TimeSource,
};
use froctomap_file::FroctReader;
use froctomap_formats::{Backend, WriteOptions};
use froctomap_temporal::{ModelConfig, Order, OutlierMode};
use serde::Serialize;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// One build of the training series (a child process).
#[derive(Clone, Debug, Default, Serialize)]
pub struct BuildRow {
    /// What was built.
    pub name: String,
    /// Snapshots in.
    pub frames: usize,
    /// Wall time of the library call inside the child, seconds.
    pub seconds: f64,
    /// Of which reading and accumulating the inputs.
    pub read_seconds: f64,
    /// Of which fitting, encoding and writing.
    pub model_seconds: f64,
    /// Peak resident memory of the child (`VmHWM`), bytes.
    pub peak_memory_bytes: Option<u64>,
    /// Output bytes.
    pub file_bytes: u64,
}

/// Options of the hidden `build-child`.
#[derive(Args, Debug)]
pub struct BuildChildArgs {
    /// Inputs (a manifest or directory).
    #[arg(long)]
    input: PathBuf,
    /// The file to write.
    #[arg(long)]
    output: PathBuf,
    /// Temporal model (a registered name).
    #[arg(long, default_value = froctomap_temporal::models::DEFAULT_MODEL)]
    model: String,
    /// Fixed order (default: auto up to --max-order), for models with orders.
    #[arg(long)]
    order: Option<u8>,
    /// Highest auto order.
    #[arg(long, default_value_t = 5)]
    max_order: u8,
    /// Lossy (no outliers).
    #[arg(long)]
    lossy: bool,
    /// Read the inputs with the upstream C++ library.
    #[arg(long)]
    cpp_reader: bool,
    /// Memory budget of the histories, MiB (default: the build's).
    #[arg(long)]
    memory_mib: Option<u64>,
}

/// Builds one file in this process and prints `{report, seconds, peak_memory_bytes}`.
pub fn build_child(args: &BuildChildArgs) -> Result<()> {
    let mut context = froctomap_convert::Context::with_default_plugins();
    // Recordings too (the MCAP row), as the CLI reads them.
    froctomap_ros::register(context.formats_mut())?;
    let inputs = collect_inputs(
        &context,
        std::slice::from_ref(&args.input),
        TimeSource::Auto,
    )?;
    let model = context
        .models()
        .by_name(&args.model)
        .with_context(|| format!("unknown model {}", args.model))?;
    let config = ModelConfig::default().with_outliers(if args.lossy {
        OutlierMode::Lossy
    } else {
        OutlierMode::Lossless
    });
    // Models without orders (e.g. markov) take their defaults.
    let config = if model.options.iter().any(|o| o.key == "order") {
        match args.order {
            Some(n) => Order::Fixed(n),
            None => Order::Auto {
                max: args.max_order,
            },
        }
        .apply(config)
    } else {
        config
    };
    model.create().check_options(&config.options)?;
    let options = BuildOptions {
        model: model.name.to_string(),
        config,
        backend: Some(if args.cpp_reader {
            Backend::Octomap
        } else {
            Backend::Native
        }),
        ..BuildOptions::default()
    };
    let options = match args.memory_mib {
        Some(mib) => BuildOptions {
            memory: mib.saturating_mul(1 << 20),
            ..options
        },
        None => options,
    };
    let started = Instant::now();
    let report = build(&context, &inputs, &args.output, &options, &Silent)?;
    let seconds = started.elapsed().as_secs_f64();
    let value = serde_json::json!({
        "report": report,
        "seconds": seconds,
        "peak_memory_bytes": peak_memory_bytes(),
    });
    println!("{value}");
    Ok(())
}

/// The model of a child build: a registered name, and the order for models with orders.
pub(crate) struct ChildModel<'a> {
    /// A registered model name.
    pub(crate) name: &'a str,
    /// A fixed order (`None`: auto).
    pub(crate) order: Option<u8>,
    /// The highest auto order.
    pub(crate) max_order: u8,
}

impl ChildModel<'_> {
    /// The default model (FreMEn at candidate periods).
    pub(crate) fn fremen(order: Option<u8>, max_order: u8) -> Self {
        ChildModel {
            name: froctomap_temporal::models::fremen_periods::DESCRIPTOR.name,
            order,
            max_order,
        }
    }
}

/// Runs `build-child` as a process and reads its report.
pub(crate) fn spawn_build(
    name: &str,
    input: &Path,
    output: &Path,
    model: &ChildModel<'_>,
    lossy: bool,
    cpp_reader: bool,
    memory_mib: Option<u64>,
) -> Result<BuildRow> {
    let ChildModel {
        name: model_name,
        order,
        max_order,
    } = *model;
    let exe = std::env::current_exe().context("cannot find this executable")?;
    let mut command = Command::new(exe);
    command
        .arg("build-child")
        .arg("--input")
        .arg(input)
        .arg("--output")
        .arg(output)
        .arg("--model")
        .arg(model_name)
        .arg("--max-order")
        .arg(max_order.to_string());
    if let Some(n) = order {
        command.arg("--order").arg(n.to_string());
    }
    if lossy {
        command.arg("--lossy");
    }
    if cpp_reader {
        command.arg("--cpp-reader");
    }
    if let Some(mib) = memory_mib {
        command.arg("--memory-mib").arg(mib.to_string());
    }
    let out = command
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .with_context(|| format!("starting the build of {name}"))?;
    if !out.status.success() {
        bail!("the build of {name} failed ({})", out.status);
    }
    let value: Value = serde_json::from_slice(&out.stdout)
        .with_context(|| format!("reading the report of the build of {name}"))?;
    let report = &value["report"];
    let f = |v: &Value| v.as_f64().unwrap_or(0.0);
    Ok(BuildRow {
        name: name.to_string(),
        frames: report["used"].as_u64().unwrap_or(0) as usize,
        seconds: f(&value["seconds"]),
        read_seconds: f(&report["read_seconds"]),
        model_seconds: f(&report["model_seconds"]),
        peak_memory_bytes: value["peak_memory_bytes"].as_u64(),
        file_bytes: report["file_bytes"].as_u64().unwrap_or(0),
    })
}

/// What `froctomap retrieve` does, in this process: open `file` and write the map observed
/// at `sample` to `out` as `.bt`.
pub(crate) fn retrieve_once(
    context: &froctomap_convert::Context,
    file: &Path,
    sample: u32,
    out: &Path,
) -> Result<()> {
    let reader = FroctReader::open(file)?;
    write_observed_map(context, &reader, sample, out, WriteOptions::default())?;
    Ok(())
}

/// Median seconds of `repeats` runs of `f`, after one untimed warm-up run.
pub(crate) fn timed(repeats: u32, mut f: impl FnMut() -> Result<()>) -> Result<f64> {
    f()?;
    let mut times = Vec::with_capacity(repeats as usize);
    for _ in 0..repeats {
        let started = Instant::now();
        f()?;
        times.push(started.elapsed().as_secs_f64());
    }
    median(&times).context("no timing")
}
