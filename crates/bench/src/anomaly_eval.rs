//! Anomaly detection, evaluated honestly: objects that never occur in training are injected
//! into held-out snapshots (as the sensor saw them: noise, partial views), and the regions
//! `froctomap anomalies` reports at its default thresholds are matched against them, next
//! to the same scoring against two simple expectations (the last seen map, the static mean
//! map).
//!
//! Per held-out frame: a box of [`BOX_EDGE_M`] in space that was free at every training
//! snapshot (and is free in the frame), and, where one exists, a door closed that was open
//! at nearly every training snapshot at that time of day (and is open in the frame). A reported region is a hit when its bounding box touches an injected object's;
//! every other region of an injected frame is a false alarm, including real but expected
//! changes (people, chairs) the method flags. The clean frame is scored too.

use anyhow::Result;
use clap::Args;
use froctomap_convert::{
    anomalies, build, collect_inputs, probabilities, voxel_history, AnomalyOptions, AnomalyReport,
    BuildOptions, Context, Expectation, SeriesInput, Silent, TimeSource,
};
use froctomap_core::{Leaf, MortonCode, Occupancy, Snapshot, Timestamp, VoxelKey, TREE_DEPTH};
use froctomap_file::FroctReader;
use froctomap_synth::{ElementKind, Generator};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Edge of an injected box, metres.
pub const BOX_EDGE_M: f64 = 0.3;
/// A door qualifies for closing when it was open at least at this share of the training
/// snapshots at that time of day (real door recordings are rarely open at every one).
pub const DOOR_OPEN_SHARE: f64 = 0.9;
/// Training snapshots this close to the frame's time of day (seconds) count as "that hour".
const HOUR_WINDOW: f64 = 1800.0;
/// Held-out frames used by default.
pub const DEFAULT_FRAMES: usize = 12;

/// The methods compared, by name.
const METHODS: [(&str, Expectation); 3] = [
    ("model (froctomap anomalies)", Expectation::Model),
    ("static mean map", Expectation::StaticMean),
    ("last seen map", Expectation::LastSeen),
];

/// Options of `froctomap-bench anomalies` (the evaluation alone, on a series `run` would
/// generate).
#[derive(Args, Debug)]
pub struct AnomalyEvalArgs {
    #[command(flatten)]
    series: crate::series_args::SeriesArgs,
    /// Where the series and the lossless file are (reused when they match).
    #[arg(long)]
    data: PathBuf,
    /// Held-out frames to inject into.
    #[arg(long, default_value_t = DEFAULT_FRAMES)]
    frames: usize,
    /// Where `anomalies.json` and `anomalies.md` go.
    #[arg(long, default_value = "target/bench")]
    out: PathBuf,
}

/// One method's detection quality.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MethodResult {
    /// The method.
    pub method: String,
    /// Regions reported on injected frames.
    pub regions: usize,
    /// Of those, regions touching an injected object.
    pub hits: usize,
    /// Injected boxes found.
    pub boxes_found: usize,
    /// Injected closed doors found.
    pub doors_found: usize,
    /// Injected frames whose top region is an injected object.
    pub top_is_injected: usize,
    /// Injected objects whose best region scores above every region of the clean frame.
    pub above_clean: usize,
    /// Regions of injected frames that miss the injected objects but touch a real change
    /// of the series (an element of the generator present then or at the end of training).
    pub real_changes: usize,
    /// Regions reported on the clean frames.
    pub clean_regions: usize,
    /// Of those, regions touching no real change (spurious).
    pub clean_spurious: usize,
    /// Seconds spent scoring (all frames, clean and injected).
    pub seconds: f64,
}

impl MethodResult {
    fn precision(&self) -> Option<f64> {
        (self.regions > 0).then(|| self.hits as f64 / self.regions as f64)
    }
}

/// The evaluation's results.
#[derive(Clone, Debug, Serialize)]
pub struct AnomalyEval {
    /// Held-out frames injected into.
    pub frames: usize,
    /// Boxes injected.
    pub boxes: usize,
    /// Doors closed.
    pub doors: usize,
    /// The thresholds (defaults of `froctomap anomalies`).
    pub error_rate: f64,
    /// Voxel threshold, nats.
    pub voxel_threshold: f64,
    /// Minimum region score, nats.
    pub min_region_score: f64,
    /// Per method.
    pub methods: Vec<MethodResult>,
}

/// An injected object: its kind and metric bounding box.
struct Injected {
    door: bool,
    min: [f64; 3],
    max: [f64; 3],
}

/// A small deterministic generator (splitmix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
}

/// Scores `frames` held-out frames (evenly spread over `heldout`), clean and injected,
/// against the file at `froct` with each method.
pub fn evaluate(
    froct: &Path,
    generator: &Generator,
    heldout: &[(SeriesInput, u64)],
    frames: usize,
    note: &dyn Fn(&str),
) -> Result<AnomalyEval> {
    let context = Context::with_default_plugins();
    let reader = context.open_froct(froct)?;
    let defaults = AnomalyOptions::default();
    let mut methods: Vec<MethodResult> = METHODS
        .iter()
        .map(|(name, _)| MethodResult {
            method: (*name).to_string(),
            ..MethodResult::default()
        })
        .collect();
    let doors: Vec<Vec<MortonCode>> = generator
        .elements()
        .into_iter()
        .filter(|e| e.kind == ElementKind::Door && !e.voxels.is_empty())
        .map(|e| e.voxels)
        .collect();
    let step = generator.spec().step_secs;
    let train_end = reader.header().axis.end();
    let mut rng = Rng(generator.spec().seed ^ 0xA0_0A11E5);
    let (mut used, mut boxes, mut closed_doors) = (0, 0, 0);
    for (k, i) in crate::dataset::spread(heldout.len(), frames)
        .into_iter()
        .enumerate()
    {
        let (input, index) = &heldout[i];
        let Ok(clean) = generator.frame(*index) else {
            continue; // a missed frame
        };
        let t = input.time;
        let mut changes = BTreeMap::new();
        let mut objects = Vec::new();
        if let Some(object) = inject_box(&reader, &clean, t, &mut rng, &mut changes)? {
            objects.push(object);
            boxes += 1;
        }
        if let Some(object) = close_door(&reader, &clean, t, step, &doors, k, &mut changes)? {
            objects.push(object);
            closed_doors += 1;
        }
        if objects.is_empty() {
            continue;
        }
        let injected = with_changes(&clean, &changes)?;
        let real = real_changes(generator, t, train_end)?;
        used += 1;
        note(&format!(
            "anomalies: frame {} ({} injected)",
            froctomap_core::calendar::iso8601(t),
            objects.len()
        ));
        let margin = clean.resolution() / 2.0;
        for ((_, expectation), result) in METHODS.iter().zip(methods.iter_mut()) {
            let mut options = AnomalyOptions::default();
            options.expectation = *expectation;
            let started = std::time::Instant::now();
            let clean_report = anomalies(&reader, &clean, t, &options)?;
            let report = anomalies(&reader, &injected, t, &options)?;
            result.seconds += started.elapsed().as_secs_f64();
            tally(result, &clean_report, &report, &objects, &real, margin);
        }
    }
    Ok(AnomalyEval {
        frames: used,
        boxes,
        doors: closed_doors,
        error_rate: defaults.error_rate,
        voxel_threshold: defaults.voxel_threshold,
        min_region_score: defaults.min_region_score,
        methods,
    })
}

/// Adds one frame's outcome to a method's counts.
fn tally(
    result: &mut MethodResult,
    clean: &AnomalyReport,
    report: &AnomalyReport,
    objects: &[Injected],
    real: &[Injected],
    margin: f64,
) {
    let touches = |min: &[f64; 3], max: &[f64; 3], o: &Injected| {
        (0..3).all(|a| min[a] <= o.max[a] + margin && max[a] >= o.min[a] - margin)
    };
    let on_real =
        |r: &froctomap_convert::AnomalyRegion| real.iter().any(|o| touches(&r.min, &r.max, o));
    result.clean_regions += clean.regions.len();
    result.clean_spurious += clean.regions.iter().filter(|r| !on_real(r)).count();
    result.regions += report.regions.len();
    for region in &report.regions {
        if objects.iter().any(|o| touches(&region.min, &region.max, o)) {
            result.hits += 1;
        } else if on_real(region) {
            result.real_changes += 1;
        }
    }
    if report
        .regions
        .first()
        .is_some_and(|r| objects.iter().any(|o| touches(&r.min, &r.max, o)))
    {
        result.top_is_injected += 1;
    }
    let clean_best = clean.regions.first().map_or(0.0, |r| r.score);
    for object in objects {
        let best = report
            .regions
            .iter()
            .filter(|r| touches(&r.min, &r.max, object))
            .map(|r| r.score)
            .fold(None, |best: Option<f64>, s| {
                Some(best.map_or(s, |b| b.max(s)))
            });
        if let Some(best) = best {
            if object.door {
                result.doors_found += 1;
            } else {
                result.boxes_found += 1;
            }
            if best > clean_best {
                result.above_clean += 1;
            }
        }
    }
}

/// A box of [`BOX_EDGE_M`] where the frame is free and the file's cells are free at every
/// sample (`p` exactly 0: static free), at a random free spot; `None` after many tries.
fn inject_box(
    reader: &FroctReader,
    frame: &Snapshot,
    t: Timestamp,
    rng: &mut Rng,
    changes: &mut BTreeMap<u64, Occupancy>,
) -> Result<Option<Injected>> {
    let resolution = frame.resolution();
    let edge = ((BOX_EDGE_M / resolution).round() as u16).max(1);
    let free: Vec<&Leaf> = frame
        .leaves()
        .iter()
        .filter(|l| !l.occupancy().is_occupied())
        .collect();
    if free.is_empty() {
        return Ok(None);
    }
    for _ in 0..500 {
        let leaf = free[rng.below(free.len() as u64) as usize];
        let lo = leaf.min_key();
        let span = u64::from(leaf.edge_voxels());
        let pick = |v: u16, r: u64| v.saturating_add((r % span) as u16);
        let corner = VoxelKey::new(
            pick(lo.x, rng.next()),
            pick(lo.y, rng.next()),
            pick(lo.z, rng.next()),
        );
        let keys: Vec<VoxelKey> = (0..edge)
            .flat_map(|x| {
                (0..edge).flat_map(move |y| {
                    (0..edge).map(move |z| {
                        VoxelKey::new(
                            corner.x.saturating_add(x),
                            corner.y.saturating_add(y),
                            corner.z.saturating_add(z),
                        )
                    })
                })
            })
            .collect();
        if keys.iter().any(|k| {
            frame.state_at(k.morton()) != Some(Occupancy::Free)
                || changes.contains_key(&k.morton().0)
        }) {
            continue;
        }
        let points: Vec<[f64; 3]> = keys.iter().map(|k| k.center(resolution)).collect();
        if probabilities(reader, t, &points)?.iter().any(|&p| p != 0.0) {
            continue;
        }
        for k in &keys {
            changes.insert(k.morton().0, Occupancy::Occupied);
        }
        let (min, max) = bounds(keys.iter().copied(), resolution);
        return Ok(Some(Injected {
            door: false,
            min,
            max,
        }));
    }
    Ok(None)
}

/// Closes a door that is open (every voxel observed free) in the frame and was open at
/// [`DOOR_OPEN_SHARE`] of the training snapshots within half an hour of this time of day
/// (all of them on a short series); doors are tried from the
/// `k`-th on, so that frames use different doors.
fn close_door(
    reader: &FroctReader,
    frame: &Snapshot,
    t: Timestamp,
    step: f64,
    doors: &[Vec<MortonCode>],
    k: usize,
    changes: &mut BTreeMap<u64, Occupancy>,
) -> Result<Option<Injected>> {
    let resolution = frame.resolution();
    let day = 86_400.0;
    let time_of_day = |t: Timestamp| t.as_secs_f64().rem_euclid(day);
    let at = time_of_day(t);
    for d in 0..doors.len() {
        let voxels = &doors[(k + d) % doors.len()];
        if voxels
            .iter()
            .any(|&c| frame.state_at(c) != Some(Occupancy::Free) || changes.contains_key(&c.0))
        {
            continue;
        }
        let middle = voxels[voxels.len() / 2].key().center(resolution);
        let Ok(history) = voxel_history(reader, middle, None) else {
            continue;
        };
        let same_hour: Vec<Option<Occupancy>> = history
            .samples
            .iter()
            .filter(|s| {
                let gap = (time_of_day(s.time) - at).abs();
                gap.min(day - gap) <= HOUR_WINDOW.max(step / 2.0)
            })
            .map(|s| s.state)
            .filter(Option::is_some)
            .collect();
        let open = same_hour
            .iter()
            .filter(|s| **s == Some(Occupancy::Free))
            .count();
        if same_hour.is_empty() || (open as f64) < DOOR_OPEN_SHARE * same_hour.len() as f64 {
            continue;
        }
        for c in voxels {
            changes.insert(c.0, Occupancy::Occupied);
        }
        let (min, max) = bounds(voxels.iter().map(|c| c.key()), resolution);
        return Ok(Some(Injected {
            door: true,
            min,
            max,
        }));
    }
    Ok(None)
}

/// Where the series itself changes around `t`: the bounding box of every generated element
/// (door, person, chair, object, machine) as present at `t` and at the end of training.
fn real_changes(
    generator: &Generator,
    t: Timestamp,
    train_end: Timestamp,
) -> Result<Vec<Injected>> {
    let resolution = generator.base().resolution();
    let mut boxes = Vec::new();
    for element in generator.elements() {
        for when in [t, train_end] {
            let voxels = generator.occupied_by(element.kind, element.index, when);
            if voxels.is_empty() {
                continue;
            }
            let (min, max) = bounds(voxels.iter().map(|c| c.key()), resolution);
            boxes.push(Injected {
                door: element.kind == ElementKind::Door,
                min,
                max,
            });
        }
    }
    Ok(boxes)
}

/// The metric bounding box of voxel keys.
fn bounds(keys: impl Iterator<Item = VoxelKey>, resolution: f64) -> ([f64; 3], [f64; 3]) {
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for k in keys {
        let c = k.center(resolution);
        for a in 0..3 {
            min[a] = min[a].min(c[a] - resolution / 2.0);
            max[a] = max[a].max(c[a] + resolution / 2.0);
        }
    }
    (min, max)
}

/// The frame with some voxels' states replaced: leaves holding a change are split down to
/// the changed voxels (8 children per level), the rest kept whole.
fn with_changes(frame: &Snapshot, changes: &BTreeMap<u64, Occupancy>) -> Result<Snapshot> {
    fn split(leaf: Leaf, changes: &BTreeMap<u64, Occupancy>, out: &mut Vec<Leaf>) {
        let mut inside = changes.range(leaf.start.0..leaf.end());
        let Some((_, &first)) = inside.next() else {
            out.push(leaf);
            return;
        };
        if leaf.depth == TREE_DEPTH {
            out.push(Leaf {
                log_odds: first.log_odds(),
                ..leaf
            });
            return;
        }
        let child = leaf.voxel_count() / 8;
        for i in 0..8 {
            let part = Leaf {
                start: MortonCode(leaf.start.0 + i * child),
                depth: leaf.depth + 1,
                log_odds: leaf.log_odds,
            };
            split(part, changes, out);
        }
    }
    let mut leaves = Vec::with_capacity(frame.leaves().len() + changes.len());
    for leaf in frame.leaves() {
        split(*leaf, changes, &mut leaves);
    }
    Ok(Snapshot::from_leaves(frame.resolution(), leaves)?)
}

impl AnomalyEval {
    /// The section of the benchmark report.
    pub fn markdown(&self) -> String {
        let mut text = format!(
            "\n## Anomaly detection (injected objects)\n\n{} held-out snapshots (as the sensor saw them), each with a {BOX_EDGE_M} m box injected in space free at every training snapshot ({} boxes) and, where one qualified, a door closed that was open at ≥ {:.0} % of the training snapshots within half an hour of that time of day ({} doors). Default thresholds: error rate {}, voxel surprise > {:.2} nats, region score ≥ {} nats. A region is a hit when its box touches an injected object; every other region of an injected snapshot counts against precision (real changes such as people included).\n\n",
            self.frames, self.boxes, 100.0 * DOOR_OPEN_SHARE, self.doors, self.error_rate, self.voxel_threshold, self.min_region_score
        );
        text.push_str("| method | precision | recall: boxes | recall: doors | top region injected | injected above all clean regions | other regions on real changes | regions per clean snapshot (spurious) | seconds per snapshot |\n");
        text.push_str("| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
        let share = |n: usize, d: usize| {
            if d == 0 {
                "–".to_string()
            } else {
                format!("{:.0} % ({n}/{d})", 100.0 * n as f64 / d as f64)
            }
        };
        let frames = self.frames.max(1) as f64;
        for m in &self.methods {
            text.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {:.1} ({:.1}) | {:.2} |\n",
                m.method,
                m.precision().map_or_else(
                    || "–".to_string(),
                    |p| format!("{:.0} % ({}/{})", 100.0 * p, m.hits, m.regions)
                ),
                share(m.boxes_found, self.boxes),
                share(m.doors_found, self.doors),
                share(m.top_is_injected, self.frames),
                share(m.above_clean, self.boxes + self.doors),
                share(m.real_changes, m.regions - m.hits),
                m.clean_regions as f64 / frames,
                m.clean_spurious as f64 / frames,
                m.seconds / (2.0 * frames),
            ));
        }
        text
    }
}

/// `froctomap-bench anomalies`: the series of `run` (generated or reused under `--data`),
/// its lossless file (built when missing), then the evaluation alone.
pub fn anomalies_command(args: &AnomalyEvalArgs) -> Result<()> {
    let note = |m: &str| eprintln!("{m}");
    let crate::series_args::Series {
        generator, written, ..
    } = args.series.prepare(&args.data, &note)?;
    let froct = args.data.join("lossless.froct");
    if !froct.exists() {
        note("building lossless.froct");
        let context = Context::with_default_plugins();
        let manifest: PathBuf = args.data.join("train").join("manifest.csv");
        let inputs = collect_inputs(&context, &[manifest], TimeSource::Auto)?;
        build(&context, &inputs, &froct, &BuildOptions::default(), &Silent)?;
    }
    let eval = evaluate(&froct, &generator, &written.heldout, args.frames, &note)?;
    std::fs::create_dir_all(&args.out)?;
    let markdown = eval.markdown();
    std::fs::write(
        args.out.join("anomalies.json"),
        serde_json::to_string_pretty(&eval)?,
    )?;
    std::fs::write(args.out.join("anomalies.md"), &markdown)?;
    println!("{markdown}");
    Ok(())
}
