//! `froctomap-bench run`: one series, every measurement, one report.

use crate::child_build::{retrieve_once, spawn_build, timed, ChildModel};
use crate::dataset::{self, spread};
use crate::plots::{self, Level, Line};
use crate::report::{AccuracyRow, Dataset, Errors, MemoryRow, Results, TimeResults};
use crate::series_args::{Series, SeriesArgs};
use crate::size::Plan;
use crate::system::{self, tar_through, FONT};
use crate::tables::{rows, StorageRow};
use anyhow::{bail, Context, Result};
use clap::Args;
use froctomap_convert::{
    describe, evaluate, unix_seconds, write_predicted_map, EvalReport, SeriesInput, Silent,
};
use froctomap_core::calendar::iso8601;
use froctomap_core::{MortonCode, Occupancy, Timestamp};
use froctomap_file::{Cell, CellContent, FroctReader};
use froctomap_formats::{ReadOptions, WriteOptions};
use froctomap_render::{voxel_plot, VoxelPlot};
use froctomap_synth::{DoorDriver, ElementKind, Generator};
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// Options of `run`.
#[derive(Args, Debug)]
pub struct RunArgs {
    #[command(flatten)]
    series: SeriesArgs,
    /// Where results.json, results.md and the PNG plots go.
    #[arg(long, default_value = "target/bench")]
    out: PathBuf,
    /// Where the series and the built files go (default: a temporary directory, removed at
    /// the end unless --keep-data). A directory that already holds the same series is reused.
    #[arg(long)]
    data: Option<PathBuf>,
    /// Keep the temporary data directory.
    #[arg(long)]
    keep_data: bool,
    /// The froctomap CLI to time as a process (default: `froctomap` beside this binary;
    /// skipped when absent).
    #[arg(long)]
    cli: Option<PathBuf>,
    /// Runs behind each single-snapshot median.
    #[arg(long, default_value_t = 9, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeats: u32,
    /// Highest fixed order of the lossy files (0..=N), and the auto order's maximum.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u8).range(0..=16))]
    max_order: u8,
    /// Training snapshots used as reconstruction ground truth (evenly spread).
    #[arg(long, default_value_t = 48)]
    reconstruction_truths: usize,
    /// Held-out maps used as prediction ground truth (evenly spread).
    #[arg(long, default_value_t = 144)]
    prediction_truths: usize,
    /// Skip the lossless build through the C++ reader (it takes about as long as reading
    /// every file with the C++ library).
    #[arg(long)]
    skip_cpp_build: bool,
    /// Skip the xz baseline (slow on large series).
    #[arg(long)]
    skip_xz: bool,
    /// Memory budget of every build, MiB (`froctomap build --memory`; default: the
    /// build's own default, 64 MiB).
    #[arg(long)]
    memory_mib: Option<u64>,
    /// Only write the series into --data (or reuse it) and stop: the paper sizes take longer
    /// to generate than some measurements, and a later run with the same --data, --size,
    /// --step, --seed and base reuses it.
    #[arg(long, requires = "data")]
    generate_only: bool,
}

/// Reads every file with the C++ library, in parallel on `threads` threads.
fn cpp_read_all(inputs: &[SeriesInput], threads: usize) -> Result<(f64, u64)> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("thread pool")?;
    let started = Instant::now();
    let leaves = pool.install(|| {
        inputs
            .par_iter()
            .map(|input| -> Result<u64> {
                let bytes = std::fs::read(&input.path)
                    .with_context(|| format!("reading {}", input.path.display()))?;
                let tree = froctomap_octomap_ffi::OcTree::read_binary(&bytes)
                    .with_context(|| format!("C++ read of {}", input.path.display()))?;
                Ok(tree.tree.leaf_count())
            })
            .collect::<Result<Vec<u64>>>()
    })?;
    Ok((started.elapsed().as_secs_f64(), leaves.iter().sum()))
}

/// The errors a method makes, by name, from one evaluation.
fn method(report: &EvalReport, name: &str) -> (Errors, Errors) {
    let find = |rows: &[(String, froctomap_convert::ErrorRates)]| {
        rows.iter()
            .find(|(m, _)| m == name)
            .map(|(_, r)| Errors::from_rates(r))
            .unwrap_or_default()
    };
    (find(&report.reconstruction), find(&report.prediction))
}

/// Evaluates one file against the ground truths.
fn evaluate_file(path: &Path, truths: &[SeriesInput]) -> Result<EvalReport> {
    let reader = FroctReader::open(path)?;
    let context = froctomap_convert::Context::with_default_plugins();
    Ok(evaluate(
        &context,
        &reader,
        truths,
        ReadOptions::default(),
        &Silent,
    )?)
}

/// The cell holding `voxel` in a file.
fn cell_of(
    reader: &FroctReader,
    cache: &mut HashMap<usize, Vec<Cell>>,
    voxel: MortonCode,
) -> Result<Option<Cell>> {
    let Some(tile) = reader.tile_containing(voxel) else {
        return Ok(None);
    };
    if let std::collections::hash_map::Entry::Vacant(e) = cache.entry(tile) {
        e.insert(reader.read_tile(tile)?);
    }
    Ok(cache
        .get(&tile)
        .and_then(|cells| {
            cells
                .iter()
                .find(|c| c.start.0 <= voxel.0 && voxel.0 < c.end())
        })
        .cloned())
}

/// Plots one door voxel's `p(t)` against its observations and the held-out truth.
fn plot_voxel(
    generator: &Generator,
    files: &[(String, PathBuf)],
    train: &[SeriesInput],
    heldout: &[(SeriesInput, u64)],
    out: &Path,
) -> Result<Option<String>> {
    let elements = generator.elements();
    let door = elements
        .iter()
        .find(|e| {
            e.kind == ElementKind::Door && matches!(e.door_driver, Some(DoorDriver::Real { .. }))
        })
        .or_else(|| elements.iter().find(|e| e.kind == ElementKind::Door))
        .or_else(|| elements.first());
    let Some(door) = door else {
        return Ok(None);
    };
    let Some((_, first_path)) = files.first() else {
        return Ok(None);
    };
    let reader = FroctReader::open(first_path)?;
    let mut cache = HashMap::new();
    let mut chosen = None;
    for &v in &door.voxels {
        if let Some(cell) = cell_of(&reader, &mut cache, v)? {
            let modelled = matches!(cell.content, CellContent::Modelled(_));
            if modelled || chosen.is_none() {
                chosen = Some((v, cell));
            }
            if modelled {
                break;
            }
        }
    }
    let Some((voxel, cell)) = chosen else {
        return Ok(None);
    };
    let axis = reader.header().axis.clone();
    let start = axis.start();
    let (Some(last_train), Some(last)) = (train.last(), heldout.last().or(None)) else {
        return Ok(None);
    };
    let window_days = 3.0f64.min(last_train.time.secs_since(start) / 86_400.0);
    let from = Timestamp(last_train.time.0 - (window_days * 86_400e9) as i64);
    let days = |t: Timestamp| t.secs_since(from) / 86_400.0;
    let step_ns = train
        .windows(2)
        .next()
        .map_or(600_000_000_000, |w| w[1].time.0 - w[0].time.0)
        .max(1);
    let mut curves = Vec::new();
    for (name, path) in files {
        let reader = FroctReader::open(path)?;
        let mut cache = HashMap::new();
        let Some(cell) = cell_of(&reader, &mut cache, voxel)? else {
            continue;
        };
        let model = reader.model();
        let mut points = Vec::new();
        let mut t = from;
        while t <= last.0.time {
            points.push((days(t), cell.probability(model, t.secs_since(start))));
            t = Timestamp(t.0 + step_ns / 2);
        }
        curves.push(Line {
            name: name.clone(),
            points,
        });
    }
    let model = reader.model();
    let observed: Vec<(f64, f64)> = train
        .iter()
        .filter(|s| s.time >= from)
        .filter_map(|s| {
            let k = axis.index_of(s.time)?;
            let state = cell.state_at(&axis, model, k)?;
            Some((days(s.time), if state.is_occupied() { 1.0 } else { 0.0 }))
        })
        .collect();
    let key = voxel.key();
    let truth: Vec<(f64, f64)> = heldout
        .iter()
        .filter_map(|(s, index)| {
            let state = generator.truth_state(*index, key).ok()??;
            Some((
                days(s.time),
                if state == Occupancy::Occupied {
                    1.0
                } else {
                    0.0
                },
            ))
        })
        .collect();
    let c = key.center(generator.base().resolution());
    let driver = door
        .door_driver
        .as_ref()
        .map_or_else(|| door.kind.to_string(), ToString::to_string);
    let title = format!(
        "{} voxel at ({:.2}, {:.2}, {:.2}) m: {driver}",
        door.kind, c[0], c[1], c[2]
    );
    let x_label = format!("days since {}", iso8601(from));
    voxel_plot(&VoxelPlot {
        title: &title,
        curves: &curves,
        observed: &observed,
        observed_label: "observed (training)",
        truth: &truth,
        truth_label: "ground truth (held out)",
        marker: Some(days(last_train.time)),
        x_label: &x_label,
        ..VoxelPlot::default()
    })?
    .write_png(&out.join("voxel_pt.png"), &[])?;
    Ok(Some(title))
}

/// Everything `run` does.
pub fn run(args: &RunArgs) -> Result<()> {
    let started = Instant::now();
    let (
        Plan {
            train_days,
            heldout_days,
            short_days,
            half_too,
            step: size_step,
        },
        step,
    ) = args.series.plan()?;
    let memory_mib = args.memory_mib;
    // The paper sizes (5 s, 17,280 to 120,960 snapshots) measure what the issue asks at
    // that scale: lossless and lossy-auto builds, memory at ¼, ½ and all, retrieval,
    // prediction and accuracy. Each fixed lossy order, the markov and C++-reader builds
    // would take as long as the lossless build again, the MCAP copy would double the
    // 25 GB of input on disk, and `tar | zstd -19`/`xz -9` of 25 GB take hours on two
    // cores: those are left out (docs/BENCHMARKS.md gives zstd on a prefix).
    let paper = size_step.is_some();
    let tools = system::check_tools()?;
    plots::register_font(system::load_font(Path::new(FONT))?)?;
    let threads = rayon::current_num_threads();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let temp;
    let root = match &args.data {
        Some(dir) => dir.clone(),
        None => {
            temp = tempfile::Builder::new()
                .prefix("froctomap-bench-")
                .tempdir()
                .context("creating a temporary directory")?;
            if args.keep_data {
                temp.keep()
            } else {
                temp.path().to_path_buf()
            }
        }
    };
    std::fs::create_dir_all(&root).with_context(|| format!("creating {}", root.display()))?;
    let note = |m: &str| eprintln!("[{:>6.0} s] {m}", started.elapsed().as_secs_f64());
    note(&format!("data in {}", root.display()));

    // The series.
    let Series {
        doors,
        base,
        generator,
        train_count,
        written,
        ..
    } = args.series.prepare(&root, &|m| note(m))?;
    note(&format!(
        "series: {} training snapshots, {} held-out maps{}",
        written.train.len(),
        written.heldout.len(),
        if written.reused { " (reused)" } else { "" }
    ));
    if args.generate_only {
        note("--generate-only: stopping here");
        return Ok(());
    }
    let train = &written.train;
    let train_dir = root.join("train");
    let mut bt_bytes = 0u64;
    // Read every file once so that every measurement starts from the page cache.
    for input in train {
        bt_bytes += std::fs::read(&input.path)
            .with_context(|| format!("reading {}", input.path.display()))?
            .len() as u64;
    }
    let summary = generator.change_summary();
    let mut elements: Vec<String> = summary
        .kinds
        .iter()
        .map(|k| {
            format!(
                "{}: {} of {} placed, {} voxels",
                k.kind, k.placed, k.requested, k.voxels
            )
        })
        .collect();
    let real = generator
        .elements()
        .iter()
        .filter(|e| matches!(e.door_driver, Some(DoorDriver::Real { .. })))
        .count();
    elements.push(format!(
        "doors on the real recording: {real}; surface noise: {} candidate voxels, {:.0} flips per frame; partial views: {:.0} % of frames",
        summary.noise_candidates,
        summary.noise_flips_per_frame,
        100.0 * generator.spec().partial_probability
    ));

    // The C++ read-only baseline.
    note("C++ library reading every training file");
    let (cpp_read_all_seconds, cpp_read_leaves) = cpp_read_all(train, threads)?;

    // Builds, each in its own process.
    let train_manifest = train_dir.join("manifest.csv");
    let lossless = root.join("lossless.froct");
    let mut builds = Vec::new();
    note("building lossless (native reader)");
    builds.push(spawn_build(
        rows::BUILD_NATIVE,
        &train_manifest,
        &lossless,
        &ChildModel::fremen(None, args.max_order),
        false,
        false,
        memory_mib,
    )?);
    if !paper {
        let mcap = root.join("train.mcap");
        note("writing the training series as one MCAP file");
        let mcap_bytes = crate::recording::write_mcap(train, &mcap)?;
        note(&format!(
            "building lossless from the MCAP file ({mcap_bytes} bytes)"
        ));
        builds.push(spawn_build(
            crate::recording::BUILD_FROM_MCAP,
            &mcap,
            &root.join("from-mcap.froct"),
            &ChildModel::fremen(None, args.max_order),
            false,
            false,
            memory_mib,
        )?);
    }
    if !args.skip_cpp_build && !paper {
        note("building lossless (C++ reader)");
        builds.push(spawn_build(
            rows::BUILD_FFI,
            &train_manifest,
            &root.join("lossless-cpp.froct"),
            &ChildModel::fremen(None, args.max_order),
            false,
            true,
            memory_mib,
        )?);
    }
    let mut lossy_files = Vec::new();
    for n in (0..=args.max_order).filter(|_| !paper) {
        note(&format!("building lossy, order {n}"));
        let path = root.join(format!("lossy-{n}.froct"));
        builds.push(spawn_build(
            &rows::lossy(n),
            &train_manifest,
            &path,
            &ChildModel::fremen(Some(n), args.max_order),
            true,
            false,
            memory_mib,
        )?);
        lossy_files.push((n, path));
    }
    note("building lossy, auto order");
    builds.push(spawn_build(
        rows::LOSSY_AUTO,
        &train_manifest,
        &root.join("lossy-auto.froct"),
        &ChildModel::fremen(None, args.max_order),
        true,
        false,
        memory_mib,
    )?);
    // A second, non-spectral model for the accuracy table (lossy: the model alone is what
    // is compared, and it is the quick build).
    let markov = if paper {
        None
    } else {
        note("building lossy, markov");
        let markov = root.join("markov.froct");
        builds.push(spawn_build(
            rows::MARKOV_BUILD,
            &train_manifest,
            &markov,
            &ChildModel {
                name: "markov",
                order: None,
                max_order: args.max_order,
            },
            true,
            false,
            memory_mib,
        )?);
        Some(markov)
    };
    let short_frames =
        froctomap_synth::frames_for(short_days, step).min(train.len() as u64) as usize;
    let short_manifest = dataset::prefix_manifest(train, &root, short_frames)?;
    note(&format!(
        "building lossless from the first {short_frames} snapshots (memory)"
    ));
    let short = spawn_build(
        &format!("build lossless, first {short_frames} snapshots"),
        &short_manifest,
        &root.join("short.froct"),
        &ChildModel::fremen(None, args.max_order),
        false,
        false,
        memory_mib,
    )?;
    let half = if half_too {
        let half_frames =
            (froctomap_synth::frames_for(train_days / 2.0, step) as usize).min(train.len());
        let half_manifest = dataset::prefix_manifest(train, &root, half_frames)?;
        note(&format!(
            "building lossless from the first {half_frames} snapshots (memory)"
        ));
        Some(spawn_build(
            &format!("build lossless, first {half_frames} snapshots"),
            &half_manifest,
            &root.join("half.froct"),
            &ChildModel::fremen(None, args.max_order),
            false,
            false,
            memory_mib,
        )?)
    } else {
        None
    };
    let full = builds[0].clone();
    let mut memory = vec![MemoryRow {
        frames: short.frames,
        days: short_days,
        peak_memory_bytes: short.peak_memory_bytes,
        seconds: short.seconds,
        file_bytes: short.file_bytes,
    }];
    memory.extend(half.iter().map(|half| MemoryRow {
        frames: half.frames,
        days: train_days / 2.0,
        peak_memory_bytes: half.peak_memory_bytes,
        seconds: half.seconds,
        file_bytes: half.file_bytes,
    }));
    memory.extend([MemoryRow {
        frames: full.frames,
        days: train_days,
        peak_memory_bytes: full.peak_memory_bytes,
        seconds: full.seconds,
        file_bytes: full.file_bytes,
    }]);
    builds.push(short);
    builds.extend(half);

    // Archive baselines.
    let zstd = if paper {
        None
    } else {
        note("tar | zstd -19 --long=31 -T0");
        Some(tar_through(
            &train_dir,
            "zstd",
            &["-19", "--long=31", "-T0", "-q", "-c"],
        )?)
    };
    let xz = if args.skip_xz || paper {
        None
    } else {
        note("tar | xz -9 -T0");
        Some(tar_through(&train_dir, "xz", &["-9", "-T0", "-c"])?)
    };

    // Sizes.
    let lossless_reader = FroctReader::open(&lossless)?;
    let context = froctomap_convert::Context::with_default_plugins();
    let info = describe(&context, &lossless_reader, false)?;
    let raw_state_bytes = info.voxels.total() as f64 * f64::from(info.time.samples) / 8.0;
    let vs_states = |bytes: u64| crate::tables::ratio(raw_state_bytes, bytes as f64);
    let mut storage = vec![StorageRow {
        name: rows::RAW.into(),
        bytes: bt_bytes,
        seconds: None,
        vs_raw_states: vs_states(bt_bytes),
        order: None,
    }];
    if let Some(zstd) = zstd {
        storage.push(StorageRow {
            name: rows::ZSTD.into(),
            bytes: zstd.bytes,
            seconds: Some(zstd.seconds),
            vs_raw_states: vs_states(zstd.bytes),
            order: None,
        });
    }
    if let Some(xz) = xz {
        storage.push(StorageRow {
            name: rows::XZ.into(),
            bytes: xz.bytes,
            seconds: Some(xz.seconds),
            vs_raw_states: vs_states(xz.bytes),
            order: None,
        });
    }
    storage.push(StorageRow {
        name: rows::LOSSLESS.into(),
        bytes: full.file_bytes,
        seconds: Some(full.seconds),
        vs_raw_states: vs_states(full.file_bytes),
        order: None,
    });
    if let Some(b) = builds.iter().find(|b| b.name == rows::LOSSY_AUTO) {
        storage.push(StorageRow {
            name: rows::LOSSY_AUTO.into(),
            bytes: b.file_bytes,
            seconds: Some(b.seconds),
            vs_raw_states: vs_states(b.file_bytes),
            order: None,
        });
    }
    for (n, _) in &lossy_files {
        if let Some(b) = builds.iter().find(|b| b.name == rows::lossy(*n)) {
            storage.push(StorageRow {
                name: rows::lossy(*n),
                bytes: b.file_bytes,
                seconds: Some(b.seconds),
                vs_raw_states: vs_states(b.file_bytes),
                order: Some(*n),
            });
        }
    }

    note("entropy floor");
    let floor = crate::floor::FloorSection::new(
        generator.entropy_floor(0..train_count),
        &storage,
        Some(crate::floor::base_map_bytes(&args.series.base)?),
    );

    // One snapshot.
    note("timing one snapshot");
    let mid = &train[train.len() / 2];
    let sample = lossless_reader
        .header()
        .axis
        .index_of(mid.time)
        .context("the middle snapshot is not on the file's axis")?;
    let registry = context.formats();
    let cpp_read_one_seconds = timed(args.repeats, || {
        let bytes = std::fs::read(&mid.path)?;
        std::hint::black_box(froctomap_octomap_ffi::OcTree::read_binary(&bytes)?);
        Ok(())
    })?;
    let native_read_one_seconds = timed(args.repeats, || {
        std::hint::black_box(registry.read_file(&mid.path, ReadOptions::default())?);
        Ok(())
    })?;
    let scratch = root.join("scratch");
    std::fs::create_dir_all(&scratch)?;
    let retrieved = scratch.join("retrieved.bt");
    let retrieve_seconds = timed(args.repeats, || {
        retrieve_once(&context, &lossless, sample, &retrieved)
    })?;
    // The retrieved map must be the input snapshot (lossless).
    let back = registry.read_file(&retrieved, ReadOptions::default())?;
    let original = registry.read_file(&mid.path, ReadOptions::default())?;
    if back.map.snapshot.to_max_likelihood().canonical()
        != original.map.snapshot.to_max_likelihood().canonical()
    {
        bail!("the retrieved snapshot differs from the input it was built from");
    }
    let future = written.heldout.first().map_or(mid.time, |(s, _)| s.time);
    let predicted = scratch.join("predicted.bt");
    let predict_seconds = timed(args.repeats, || {
        let reader = FroctReader::open(&lossless)?;
        write_predicted_map(
            &context,
            &reader,
            future,
            &predicted,
            WriteOptions::default(),
        )?;
        Ok(())
    })?;
    let cli = system::find_cli(args.cli.as_deref());
    let cli_time = |sub: &str, time: String, out: &Path| -> Result<Option<f64>> {
        let Some(cli) = &cli else { return Ok(None) };
        let seconds = timed(args.repeats, || {
            let status = Command::new(cli)
                .args(["--quiet", sub])
                .arg(&lossless)
                .arg("--time")
                .arg(&time)
                .arg("-o")
                .arg(out)
                .stdin(Stdio::null())
                .status()
                .with_context(|| format!("running {}", cli.display()))?;
            if !status.success() {
                bail!("{} {sub} failed ({status})", cli.display());
            }
            Ok(())
        })?;
        Ok(Some(seconds))
    };
    let cli_retrieve_seconds = cli_time("retrieve", format!("index:{sample}"), &retrieved)?;
    let cli_predict_seconds = cli_time("predict", unix_seconds(future), &predicted)?;
    if cli.is_none() {
        note("froctomap CLI not found beside this binary: CLI timings skipped (build froctomap-cli or pass --cli)");
    }

    // Accuracy.
    note("evaluating");
    let recon: Vec<SeriesInput> = spread(train.len(), args.reconstruction_truths)
        .into_iter()
        .map(|i| train[i].clone())
        .collect();
    let heldout_inputs: Vec<SeriesInput> = written.heldout.iter().map(|(s, _)| s.clone()).collect();
    let pred: Vec<SeriesInput> = spread(heldout_inputs.len(), args.prediction_truths)
        .into_iter()
        .map(|i| heldout_inputs[i].clone())
        .collect();
    let truths: Vec<SeriesInput> = recon.iter().chain(&pred).cloned().collect();
    let mut accuracy = Vec::new();
    let mut baselines = Vec::new();
    let lossless_eval = evaluate_file(&lossless, &truths)?;
    let (r, p) = method(&lossless_eval, "model");
    accuracy.push(AccuracyRow {
        name: rows::MODEL_LOSSLESS.into(),
        order: None,
        reconstruction: r,
        prediction: p,
    });
    for (name, method_name) in [
        (rows::STORED, "stored"),
        (rows::STATIC_MEAN, "static mean"),
        (rows::LAST_SEEN, "last seen"),
    ] {
        let (r, p) = method(&lossless_eval, method_name);
        baselines.push(AccuracyRow {
            name: name.into(),
            order: None,
            reconstruction: r,
            prediction: p,
        });
    }
    for (n, path) in &lossy_files {
        let report = evaluate_file(path, &truths)?;
        let (r, p) = method(&report, "model");
        accuracy.push(AccuracyRow {
            name: format!("model, order {n} (lossy file)"),
            order: Some(*n),
            reconstruction: r,
            prediction: p,
        });
    }
    if let Some(markov) = &markov {
        let (r, p) = method(&evaluate_file(markov, &truths)?, "model");
        accuracy.push(AccuracyRow {
            name: rows::MARKOV.into(),
            order: None,
            reconstruction: r,
            prediction: p,
        });
    }

    // Plots.
    note("plotting");
    let order_points = |f: &dyn Fn(&AccuracyRow) -> Option<f64>| -> Vec<(f64, f64)> {
        accuracy
            .iter()
            .filter_map(|r| Some((f64::from(r.order?), f(r)?)))
            .collect()
    };
    let level = |rows: &[AccuracyRow], name: &str, f: &dyn Fn(&AccuracyRow) -> Option<f64>| {
        rows.iter()
            .find(|r| r.name == name)
            .and_then(f)
            .map(|y| Level {
                name: format!("{name} (prediction)"),
                y,
            })
    };
    let pred_dyn = |r: &AccuracyRow| r.prediction.dynamic;
    let recon_dyn = |r: &AccuracyRow| r.reconstruction.dynamic;
    let error_levels: Vec<Level> = [
        level(&accuracy, rows::MODEL_LOSSLESS, &pred_dyn),
        level(&baselines, rows::STATIC_MEAN, &pred_dyn),
        level(&baselines, rows::LAST_SEEN, &pred_dyn),
    ]
    .into_iter()
    .flatten()
    .collect();
    plots::lines(
        &args.out.join("error_vs_order.png"),
        "Error on dynamic voxels vs model order (lossy files)",
        "model order (spectral components per voxel)",
        "error on dynamic voxels (%)",
        &[
            Line {
                name: "reconstruction (training snapshots)".into(),
                points: order_points(&recon_dyn),
            },
            Line {
                name: "prediction (held-out days)".into(),
                points: order_points(&pred_dyn),
            },
        ],
        &error_levels,
        false,
    )?;
    let mut size_levels = vec![Level {
        name: "froctomap lossless".into(),
        y: full.file_bytes as f64,
    }];
    for s in &storage {
        if s.name == rows::ZSTD || s.name == rows::XZ || s.name == rows::RAW {
            size_levels.push(Level {
                name: s.name.clone(),
                y: s.bytes as f64,
            });
        }
    }
    plots::lines(
        &args.out.join("size_vs_order.png"),
        "Storage vs model order",
        "model order of the lossy file",
        "bytes (log scale)",
        &[Line {
            name: "froctomap lossy".into(),
            points: storage
                .iter()
                .filter_map(|s| Some((f64::from(s.order?), s.bytes as f64)))
                .collect(),
        }],
        &size_levels,
        true,
    )?;
    let mut voxel_files = vec![(
        "p(t), lossless file (auto order)".to_string(),
        lossless.clone(),
    )];
    if let Some((n, path)) = lossy_files
        .iter()
        .find(|(n, _)| *n == 2.min(args.max_order))
    {
        voxel_files.push((format!("p(t), lossy file (order {n})"), path.clone()));
    }
    if let Some(markov) = &markov {
        voxel_files.push(("p(t), markov (lossy file)".to_string(), markov.clone()));
    }
    let voxel_title = plot_voxel(&generator, &voxel_files, train, &written.heldout, &args.out)?;
    note("anomaly detection on injected objects");
    let anomaly = crate::anomaly_eval::evaluate(
        &lossless,
        &generator,
        &written.heldout,
        crate::anomaly_eval::DEFAULT_FRAMES,
        &|m| note(m),
    )?;

    let mut results = Results {
        machine: system::machine(threads, tools),
        dataset: Dataset {
            base: args.series.base.display().to_string(),
            door_file: doors.display().to_string(),
            seed: args.series.seed,
            step_seconds: step,
            train_days,
            heldout_days,
            train_frames: train.len(),
            heldout_frames: written.heldout.len(),
            first: train.first().map_or_else(String::new, |s| iso8601(s.time)),
            last: train.last().map_or_else(String::new, |s| iso8601(s.time)),
            bt_bytes,
            base_leaves: base.leaves().len(),
            voxels: info.voxels.total(),
            dynamic_voxels: info.voxels.dynamic,
            elements,
            reconstruction_truths: recon.len(),
            prediction_truths: pred.len(),
            generate_seconds: written.seconds,
        },
        storage,
        time: TimeResults {
            cpp_read_all_seconds,
            cpp_read_leaves,
            builds,
            cpp_read_one_seconds,
            native_read_one_seconds,
            retrieve_seconds,
            predict_seconds,
            cli_retrieve_seconds,
            cli_predict_seconds,
            repeats: args.repeats as usize,
            retrieve_sample: sample,
        },
        memory,
        accuracy,
        baselines,
        targets: Vec::new(),
        total_seconds: 0.0,
        floor: Some(floor),
    };
    results.targets = results.judge();
    results.total_seconds = started.elapsed().as_secs_f64();
    let mut markdown = results.markdown();
    if let Some(floor) = &results.floor {
        markdown.push_str(&floor.markdown());
    }
    markdown.push_str(&format!(
        "\nPlots: `error_vs_order.png`, `size_vs_order.png`, `voxel_pt.png`{}.\n",
        voxel_title.map_or_else(String::new, |t| format!(" ({t})"))
    ));
    markdown.push_str(&anomaly.markdown());
    std::fs::write(
        args.out.join("anomalies.json"),
        serde_json::to_string_pretty(&anomaly)?,
    )?;
    std::fs::write(
        args.out.join("results.json"),
        serde_json::to_string_pretty(&results)?,
    )?;
    std::fs::write(args.out.join("results.md"), &markdown)?;
    println!("{markdown}");
    note(&format!("results in {}", args.out.display()));
    if args.data.is_none() && args.keep_data {
        note(&format!("data kept in {}", root.display()));
    }
    Ok(())
}
