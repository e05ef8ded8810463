//! `froctomap-bench run`: one series, every measurement, one report.

use crate::anomaly_eval::AnomalyEval;
use crate::child_build::{retrieve_once, spawn_build, timed, BuildRow, ChildModel};
use crate::dataset::{self, spread, Written};
use crate::plots::{self, Level, Line};
use crate::report::{AccuracyRow, Dataset, Errors, MemoryRow, Results, TimeResults};
use crate::series_args::{Series, SeriesArgs};
use crate::size::Plan;
use crate::system::{self, tar_through, FONT};
use crate::tables::{rows, StorageRow};
use anyhow::{bail, Context, Result};
use clap::Args;
use froctomap_convert::{
    describe, evaluate, unix_seconds, write_predicted_map, EvalReport, FroctInfo, SeriesInput,
    Silent,
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

/// The builds of the whole series (lossless first), the lossy files of fixed order and
/// the markov file, when built.
type SeriesFiles = (Vec<BuildRow>, Vec<(u8, PathBuf)>, Option<PathBuf>);

/// What the stages of `run` share.
struct Bench<'a> {
    args: &'a RunArgs,
    started: Instant,
    /// Where the series and the built files go.
    root: PathBuf,
    plan: Plan,
    /// Seconds between snapshots.
    step: f64,
    /// A paper size (5 s steps): the slow extras are left out (see `run`).
    paper: bool,
}

/// The files built, each in its own process, and the builds' rows.
struct Built {
    builds: Vec<BuildRow>,
    /// The lossless build of the whole training series.
    full: BuildRow,
    lossless: PathBuf,
    /// The lossy files of fixed order, by order.
    lossy_files: Vec<(u8, PathBuf)>,
    /// The lossy markov file, when built.
    markov: Option<PathBuf>,
    /// Peak memory of the prefix builds and the full one.
    memory: Vec<MemoryRow>,
}

/// The accuracy table, its baselines and how many ground truths they were judged on.
struct Accuracy {
    accuracy: Vec<AccuracyRow>,
    baselines: Vec<AccuracyRow>,
    reconstruction_truths: usize,
    prediction_truths: usize,
}

/// Everything `run` does.
pub fn run(args: &RunArgs) -> Result<()> {
    let started = Instant::now();
    let (plan, step) = args.series.plan()?;
    // The paper sizes (5 s, 17,280 to 120,960 snapshots) measure what the issue asks at
    // that scale: lossless and lossy-auto builds, memory at ¼, ½ and all, retrieval,
    // prediction and accuracy. Each fixed lossy order, the markov and C++-reader builds
    // would take as long as the lossless build again, the MCAP copy would double the
    // 25 GB of input on disk, and `tar | zstd -19`/`xz -9` of 25 GB take hours on two
    // cores: those are left out (docs/BENCHMARKS.md gives zstd on a prefix).
    let paper = plan.step.is_some();
    let tools = system::check_tools()?;
    plots::register_font(system::load_font(Path::new(FONT))?)?;
    let threads = rayon::current_num_threads();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    // Kept alive to the end: dropping it removes the data.
    let (root, _temp) = data_dir(args)?;
    let bench = Bench {
        args,
        started,
        root,
        plan,
        step,
        paper,
    };
    bench.note(&format!("data in {}", bench.root.display()));
    let series = args.series.prepare(&bench.root, &|m| bench.note(m))?;
    let written = &series.written;
    bench.note(&format!(
        "series: {} training snapshots, {} held-out maps{}",
        written.train.len(),
        written.heldout.len(),
        if written.reused { " (reused)" } else { "" }
    ));
    if args.generate_only {
        bench.note("--generate-only: stopping here");
        return Ok(());
    }
    let bt_bytes = read_all(&written.train)?;
    bench.note("C++ library reading every training file");
    let (cpp_read_all_seconds, cpp_read_leaves) = cpp_read_all(&written.train, threads)?;
    let mut built = bench.build_all(&written.train)?;
    let lossless_reader = FroctReader::open(&built.lossless)?;
    let context = froctomap_convert::Context::with_default_plugins();
    let info = describe(&context, &lossless_reader, false)?;
    let storage = bench.storage(bt_bytes, &info, &built)?;
    bench.note("entropy floor");
    let floor = crate::floor::FloorSection::new(
        series.generator.entropy_floor(0..series.train_count),
        &storage,
        Some(crate::floor::base_map_bytes(&args.series.base)?),
    );
    let time = TimeResults {
        cpp_read_all_seconds,
        cpp_read_leaves,
        builds: std::mem::take(&mut built.builds),
        ..bench.time_one_snapshot(&context, &lossless_reader, &built.lossless, written)?
    };
    let accuracy = bench.accuracy(written, &built)?;
    let voxel_title = bench.plot(&accuracy, &storage, &built, &series)?;
    bench.note("anomaly detection on injected objects");
    let anomaly = crate::anomaly_eval::evaluate(
        &built.lossless,
        &series.generator,
        &written.heldout,
        crate::anomaly_eval::DEFAULT_FRAMES,
        &|m| bench.note(m),
    )?;
    let mut results = Results {
        machine: system::machine(threads, tools),
        dataset: bench.dataset(&series, bt_bytes, &info, &accuracy),
        storage,
        time,
        memory: built.memory,
        accuracy: accuracy.accuracy,
        baselines: accuracy.baselines,
        targets: Vec::new(),
        total_seconds: 0.0,
        floor: Some(floor),
    };
    results.targets = results.judge();
    results.total_seconds = started.elapsed().as_secs_f64();
    bench.write_results(&results, voxel_title, &anomaly)
}

/// The directory of the series and the built files: `--data`, or a new temporary one
/// (returned too unless `--keep-data`, so that dropping it removes the directory).
fn data_dir(args: &RunArgs) -> Result<(PathBuf, Option<tempfile::TempDir>)> {
    let (root, temp) = match &args.data {
        Some(dir) => (dir.clone(), None),
        None => {
            let temp = tempfile::Builder::new()
                .prefix("froctomap-bench-")
                .tempdir()
                .context("creating a temporary directory")?;
            if args.keep_data {
                (temp.keep(), None)
            } else {
                (temp.path().to_path_buf(), Some(temp))
            }
        }
    };
    std::fs::create_dir_all(&root).with_context(|| format!("creating {}", root.display()))?;
    Ok((root, temp))
}

/// Reads every file once so that every measurement starts from the page cache; returns
/// their total size.
fn read_all(train: &[SeriesInput]) -> Result<u64> {
    let mut bt_bytes = 0u64;
    for input in train {
        bt_bytes += std::fs::read(&input.path)
            .with_context(|| format!("reading {}", input.path.display()))?
            .len() as u64;
    }
    Ok(bt_bytes)
}

/// One line per kind of element the generator placed, then the doors, noise and views.
fn element_lines(generator: &Generator) -> Vec<String> {
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
    elements
}

/// A storage row of `bytes`, against the raw states (`vs_states`).
fn storage_row(
    name: String,
    bytes: u64,
    seconds: Option<f64>,
    order: Option<u8>,
    vs_states: &dyn Fn(u64) -> Option<f64>,
) -> StorageRow {
    StorageRow {
        name,
        bytes,
        seconds,
        vs_raw_states: vs_states(bytes),
        order,
    }
}

impl Bench<'_> {
    fn note(&self, m: &str) {
        eprintln!("[{:>6.0} s] {m}", self.started.elapsed().as_secs_f64());
    }

    /// Builds `output` from `input` in a child process, within `--memory-mib`.
    fn spawn(
        &self,
        name: &str,
        input: &Path,
        output: &Path,
        model: &ChildModel<'_>,
        lossy: bool,
        cpp_reader: bool,
    ) -> Result<BuildRow> {
        spawn_build(
            name,
            input,
            output,
            model,
            lossy,
            cpp_reader,
            self.args.memory_mib,
        )
    }

    /// Every build: the files of the whole series, then the prefixes for the memory table.
    fn build_all(&self, train: &[SeriesInput]) -> Result<Built> {
        let lossless = self.root.join("lossless.froct");
        let (mut builds, lossy_files, markov) = self.build_files(train, &lossless)?;
        let full = builds[0].clone();
        let (prefixes, memory) = self.build_prefixes(train, &full)?;
        builds.extend(prefixes);
        Ok(Built {
            builds,
            full,
            lossless,
            lossy_files,
            markov,
            memory,
        })
    }

    /// The files of the whole training series: lossless (first), from MCAP, through the
    /// C++ reader, lossy of each order and auto, markov.
    fn build_files(&self, train: &[SeriesInput], lossless: &Path) -> Result<SeriesFiles> {
        let (args, root, paper) = (self.args, &self.root, self.paper);
        let train_manifest = root.join("train").join("manifest.csv");
        let fremen_auto = ChildModel::fremen(None, args.max_order);
        let mut builds = Vec::new();
        self.note("building lossless (native reader)");
        builds.push(self.spawn(
            rows::BUILD_NATIVE,
            &train_manifest,
            lossless,
            &fremen_auto,
            false,
            false,
        )?);
        if !paper {
            let mcap = root.join("train.mcap");
            self.note("writing the training series as one MCAP file");
            let mcap_bytes = crate::recording::write_mcap(train, &mcap)?;
            self.note(&format!(
                "building lossless from the MCAP file ({mcap_bytes} bytes)"
            ));
            builds.push(self.spawn(
                crate::recording::BUILD_FROM_MCAP,
                &mcap,
                &root.join("from-mcap.froct"),
                &fremen_auto,
                false,
                false,
            )?);
        }
        if !args.skip_cpp_build && !paper {
            self.note("building lossless (C++ reader)");
            builds.push(self.spawn(
                rows::BUILD_FFI,
                &train_manifest,
                &root.join("lossless-cpp.froct"),
                &fremen_auto,
                false,
                true,
            )?);
        }
        let mut lossy_files = Vec::new();
        for n in (0..=args.max_order).filter(|_| !paper) {
            self.note(&format!("building lossy, order {n}"));
            let path = root.join(format!("lossy-{n}.froct"));
            builds.push(self.spawn(
                &rows::lossy(n),
                &train_manifest,
                &path,
                &ChildModel::fremen(Some(n), args.max_order),
                true,
                false,
            )?);
            lossy_files.push((n, path));
        }
        self.note("building lossy, auto order");
        builds.push(self.spawn(
            rows::LOSSY_AUTO,
            &train_manifest,
            &root.join("lossy-auto.froct"),
            &fremen_auto,
            true,
            false,
        )?);
        // A second, non-spectral model for the accuracy table (lossy: the model alone is what
        // is compared, and it is the quick build).
        let markov = if paper {
            None
        } else {
            self.note("building lossy, markov");
            let markov = root.join("markov.froct");
            builds.push(self.spawn(
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
            )?);
            Some(markov)
        };
        Ok((builds, lossy_files, markov))
    }

    /// Lossless builds of the first days (short, and half when asked) for the memory table,
    /// whose last row is the `full` build.
    fn build_prefixes(
        &self,
        train: &[SeriesInput],
        full: &BuildRow,
    ) -> Result<(Vec<BuildRow>, Vec<MemoryRow>)> {
        let Plan {
            train_days,
            short_days,
            half_too,
            ..
        } = self.plan;
        let short_frames =
            froctomap_synth::frames_for(short_days, self.step).min(train.len() as u64) as usize;
        let short = self.build_prefix(train, short_frames, "short.froct")?;
        let half = if half_too {
            let half_frames = (froctomap_synth::frames_for(train_days / 2.0, self.step) as usize)
                .min(train.len());
            Some(self.build_prefix(train, half_frames, "half.froct")?)
        } else {
            None
        };
        let memory_row = |build: &BuildRow, days: f64| MemoryRow {
            frames: build.frames,
            days,
            peak_memory_bytes: build.peak_memory_bytes,
            seconds: build.seconds,
            file_bytes: build.file_bytes,
        };
        let mut memory = vec![memory_row(&short, short_days)];
        memory.extend(half.iter().map(|half| memory_row(half, train_days / 2.0)));
        memory.push(memory_row(full, train_days));
        let mut builds = vec![short];
        builds.extend(half);
        Ok((builds, memory))
    }

    /// The lossless build of the first `frames` snapshots into `file`.
    fn build_prefix(&self, train: &[SeriesInput], frames: usize, file: &str) -> Result<BuildRow> {
        let manifest = dataset::prefix_manifest(train, &self.root, frames)?;
        self.note(&format!(
            "building lossless from the first {frames} snapshots (memory)"
        ));
        self.spawn(
            &format!("build lossless, first {frames} snapshots"),
            &manifest,
            &self.root.join(file),
            &ChildModel::fremen(None, self.args.max_order),
            false,
            false,
        )
    }

    /// The storage table: the inputs, the archive baselines and the built files, against
    /// the raw states of the lossless file (`info`).
    fn storage(&self, bt_bytes: u64, info: &FroctInfo, built: &Built) -> Result<Vec<StorageRow>> {
        let train_dir = self.root.join("train");
        let zstd = if self.paper {
            None
        } else {
            self.note("tar | zstd -19 --long=31 -T0");
            Some(tar_through(
                &train_dir,
                "zstd",
                &["-19", "--long=31", "-T0", "-q", "-c"],
            )?)
        };
        let xz = if self.args.skip_xz || self.paper {
            None
        } else {
            self.note("tar | xz -9 -T0");
            Some(tar_through(&train_dir, "xz", &["-9", "-T0", "-c"])?)
        };
        let raw_state_bytes = info.voxels.total() as f64 * f64::from(info.time.samples) / 8.0;
        let vs_states = |bytes: u64| crate::tables::ratio(raw_state_bytes, bytes as f64);
        let row = |name: String, bytes, seconds, order| {
            storage_row(name, bytes, seconds, order, &vs_states)
        };
        let mut storage = vec![row(rows::RAW.into(), bt_bytes, None, None)];
        for (name, archive) in [(rows::ZSTD, zstd), (rows::XZ, xz)] {
            if let Some(archive) = archive {
                storage.push(row(name.into(), archive.bytes, Some(archive.seconds), None));
            }
        }
        let full = &built.full;
        storage.push(row(
            rows::LOSSLESS.into(),
            full.file_bytes,
            Some(full.seconds),
            None,
        ));
        let find = |name: &str| built.builds.iter().find(|b| b.name == name);
        if let Some(b) = find(rows::LOSSY_AUTO) {
            storage.push(row(
                rows::LOSSY_AUTO.into(),
                b.file_bytes,
                Some(b.seconds),
                None,
            ));
        }
        for (n, _) in &built.lossy_files {
            if let Some(b) = find(&rows::lossy(*n)) {
                storage.push(row(
                    rows::lossy(*n),
                    b.file_bytes,
                    Some(b.seconds),
                    Some(*n),
                ));
            }
        }
        Ok(storage)
    }

    /// Reading, retrieving and predicting one snapshot (the middle one), in process and
    /// through the CLI; the retrieved map is checked against its input.
    fn time_one_snapshot(
        &self,
        context: &froctomap_convert::Context,
        lossless_reader: &FroctReader,
        lossless: &Path,
        written: &Written,
    ) -> Result<TimeResults> {
        self.note("timing one snapshot");
        let repeats = self.args.repeats;
        let train = &written.train;
        let mid = &train[train.len() / 2];
        let sample = lossless_reader
            .header()
            .axis
            .index_of(mid.time)
            .context("the middle snapshot is not on the file's axis")?;
        let registry = context.formats();
        let cpp_read_one_seconds = timed(repeats, || {
            let bytes = std::fs::read(&mid.path)?;
            std::hint::black_box(froctomap_octomap_ffi::OcTree::read_binary(&bytes)?);
            Ok(())
        })?;
        let native_read_one_seconds = timed(repeats, || {
            std::hint::black_box(registry.read_file(&mid.path, ReadOptions::default())?);
            Ok(())
        })?;
        let scratch = self.root.join("scratch");
        std::fs::create_dir_all(&scratch)?;
        let retrieved = scratch.join("retrieved.bt");
        let retrieve_seconds = timed(repeats, || {
            retrieve_once(context, lossless, sample, &retrieved)
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
        let predict_seconds = timed(repeats, || {
            let reader = FroctReader::open(lossless)?;
            write_predicted_map(
                context,
                &reader,
                future,
                &predicted,
                WriteOptions::default(),
            )?;
            Ok(())
        })?;
        let cli = system::find_cli(self.args.cli.as_deref());
        let cli_retrieve_seconds = self.time_cli(
            cli.as_deref(),
            "retrieve",
            lossless,
            format!("index:{sample}"),
            &retrieved,
        )?;
        let cli_predict_seconds = self.time_cli(
            cli.as_deref(),
            "predict",
            lossless,
            unix_seconds(future),
            &predicted,
        )?;
        if cli.is_none() {
            self.note("froctomap CLI not found beside this binary: CLI timings skipped (build froctomap-cli or pass --cli)");
        }
        Ok(TimeResults {
            cpp_read_one_seconds,
            native_read_one_seconds,
            retrieve_seconds,
            predict_seconds,
            cli_retrieve_seconds,
            cli_predict_seconds,
            repeats: repeats as usize,
            retrieve_sample: sample,
            ..TimeResults::default()
        })
    }

    /// The median time of `cli sub file --time time -o out` as a process (`None`: no CLI).
    fn time_cli(
        &self,
        cli: Option<&Path>,
        sub: &str,
        file: &Path,
        time: String,
        out: &Path,
    ) -> Result<Option<f64>> {
        let Some(cli) = cli else { return Ok(None) };
        let seconds = timed(self.args.repeats, || {
            let status = Command::new(cli)
                .args(["--quiet", sub])
                .arg(file)
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
    }

    /// Every file's errors on spread training snapshots (reconstruction) and held-out maps
    /// (prediction), and the baselines' from the lossless file's evaluation.
    fn accuracy(&self, written: &Written, built: &Built) -> Result<Accuracy> {
        self.note("evaluating");
        let train = &written.train;
        let recon: Vec<SeriesInput> = spread(train.len(), self.args.reconstruction_truths)
            .into_iter()
            .map(|i| train[i].clone())
            .collect();
        let heldout_inputs: Vec<SeriesInput> =
            written.heldout.iter().map(|(s, _)| s.clone()).collect();
        let pred: Vec<SeriesInput> = spread(heldout_inputs.len(), self.args.prediction_truths)
            .into_iter()
            .map(|i| heldout_inputs[i].clone())
            .collect();
        let truths: Vec<SeriesInput> = recon.iter().chain(&pred).cloned().collect();
        let row = |name: String, order: Option<u8>, (reconstruction, prediction)| AccuracyRow {
            name,
            order,
            reconstruction,
            prediction,
        };
        let lossless_eval = evaluate_file(&built.lossless, &truths)?;
        let mut accuracy = vec![row(
            rows::MODEL_LOSSLESS.into(),
            None,
            method(&lossless_eval, "model"),
        )];
        let baselines = [
            (rows::STORED, "stored"),
            (rows::STATIC_MEAN, "static mean"),
            (rows::LAST_SEEN, "last seen"),
        ]
        .into_iter()
        .map(|(name, method_name)| row(name.into(), None, method(&lossless_eval, method_name)))
        .collect();
        for (n, path) in &built.lossy_files {
            let report = evaluate_file(path, &truths)?;
            accuracy.push(row(
                format!("model, order {n} (lossy file)"),
                Some(*n),
                method(&report, "model"),
            ));
        }
        if let Some(markov) = &built.markov {
            let errors = method(&evaluate_file(markov, &truths)?, "model");
            accuracy.push(row(rows::MARKOV.into(), None, errors));
        }
        Ok(Accuracy {
            accuracy,
            baselines,
            reconstruction_truths: recon.len(),
            prediction_truths: pred.len(),
        })
    }

    /// The plots: error and size against the model order, and one door voxel's `p(t)`
    /// (whose title is returned).
    fn plot(
        &self,
        accuracy: &Accuracy,
        storage: &[StorageRow],
        built: &Built,
        series: &Series,
    ) -> Result<Option<String>> {
        self.note("plotting");
        let out = &self.args.out;
        plot_error_vs_order(accuracy, &out.join("error_vs_order.png"))?;
        plot_size_vs_order(storage, &built.full, &out.join("size_vs_order.png"))?;
        let mut voxel_files = vec![(
            "p(t), lossless file (auto order)".to_string(),
            built.lossless.clone(),
        )];
        if let Some((n, path)) = built
            .lossy_files
            .iter()
            .find(|(n, _)| *n == 2.min(self.args.max_order))
        {
            voxel_files.push((format!("p(t), lossy file (order {n})"), path.clone()));
        }
        if let Some(markov) = &built.markov {
            voxel_files.push(("p(t), markov (lossy file)".to_string(), markov.clone()));
        }
        plot_voxel(
            &series.generator,
            &voxel_files,
            &series.written.train,
            &series.written.heldout,
            out,
        )
    }

    /// The dataset section of the results.
    fn dataset(
        &self,
        series: &Series,
        bt_bytes: u64,
        info: &FroctInfo,
        accuracy: &Accuracy,
    ) -> Dataset {
        let args = &self.args.series;
        let train = &series.written.train;
        Dataset {
            base: args.base.display().to_string(),
            door_file: series.doors.display().to_string(),
            seed: args.seed,
            step_seconds: self.step,
            train_days: self.plan.train_days,
            heldout_days: self.plan.heldout_days,
            train_frames: train.len(),
            heldout_frames: series.written.heldout.len(),
            first: train.first().map_or_else(String::new, |s| iso8601(s.time)),
            last: train.last().map_or_else(String::new, |s| iso8601(s.time)),
            bt_bytes,
            base_leaves: series.base.leaves().len(),
            voxels: info.voxels.total(),
            dynamic_voxels: info.voxels.dynamic,
            elements: element_lines(&series.generator),
            reconstruction_truths: accuracy.reconstruction_truths,
            prediction_truths: accuracy.prediction_truths,
            generate_seconds: series.written.seconds,
        }
    }

    /// Writes results.json, results.md (also printed) and anomalies.json.
    fn write_results(
        &self,
        results: &Results,
        voxel_title: Option<String>,
        anomaly: &AnomalyEval,
    ) -> Result<()> {
        let out = &self.args.out;
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
            out.join("anomalies.json"),
            serde_json::to_string_pretty(anomaly)?,
        )?;
        std::fs::write(
            out.join("results.json"),
            serde_json::to_string_pretty(results)?,
        )?;
        std::fs::write(out.join("results.md"), &markdown)?;
        println!("{markdown}");
        self.note(&format!("results in {}", out.display()));
        if self.args.data.is_none() && self.args.keep_data {
            self.note(&format!("data kept in {}", self.root.display()));
        }
        Ok(())
    }
}

/// Error on dynamic voxels against the lossy files' order, with the lossless model and the
/// baselines as levels.
fn plot_error_vs_order(accuracy: &Accuracy, path: &Path) -> Result<()> {
    let order_points = |f: &dyn Fn(&AccuracyRow) -> Option<f64>| -> Vec<(f64, f64)> {
        accuracy
            .accuracy
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
        level(&accuracy.accuracy, rows::MODEL_LOSSLESS, &pred_dyn),
        level(&accuracy.baselines, rows::STATIC_MEAN, &pred_dyn),
        level(&accuracy.baselines, rows::LAST_SEEN, &pred_dyn),
    ]
    .into_iter()
    .flatten()
    .collect();
    plots::lines(
        path,
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
    Ok(())
}

/// Size of the lossy files against their order, with the lossless file (`full`) and the
/// archives as levels.
fn plot_size_vs_order(storage: &[StorageRow], full: &BuildRow, path: &Path) -> Result<()> {
    let mut size_levels = vec![Level {
        name: "froctomap lossless".into(),
        y: full.file_bytes as f64,
    }];
    for s in storage {
        if s.name == rows::ZSTD || s.name == rows::XZ || s.name == rows::RAW {
            size_levels.push(Level {
                name: s.name.clone(),
                y: s.bytes as f64,
            });
        }
    }
    plots::lines(
        path,
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
    Ok(())
}
