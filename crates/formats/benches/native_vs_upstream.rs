//! Native Rust codec vs the upstream C++ library, same run, same files: median times of
//! reading (`.bt`/`.ot` bytes → `Snapshot`) and writing (`Snapshot` → bytes) through the
//! registry's plugins, on the real FR-079 scan and on a generated series of perturbed
//! copies of it. Prints a markdown table; asserts nothing about time.
//!
//! `cargo bench -p froctomap-formats --bench native_vs_upstream`
//! Environment: `FROCTOMAP_GEB079` (path of `geb079.bt`, default Debian's copy),
//! `FROCTOMAP_BENCH_SERIES` (number of generated snapshots, default 30),
//! `FROCTOMAP_BENCH_REPEATS` (repetitions on geb079, default 15).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use froctomap_core::{Leaf, Snapshot, StateChange};
use froctomap_formats::{Backend, FormatRegistry, MapFormat, ReadOptions};
use froctomap_octomap_codec::{
    diff, encode_binary, encode_full, scan, FileKind, ReadLimits, TreeIndex,
};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(Clone, Copy, PartialEq)]
enum Op {
    ReadBt,
    ReadOt,
    WriteBt,
    WriteOt,
    /// Native streaming of a `.bt`'s leaves (`scan`, no `Snapshot`), against upstream's full
    /// read: the cost a pipeline that consumes leaves as they come pays per file.
    ScanBt,
    /// Native comparison of a `.bt` with the file before it (`diff`, with the index kept from
    /// comparing that one), against upstream's full read: what `build` pays per snapshot.
    DiffBt,
}

impl Op {
    const ALL: [Op; 6] = [
        Op::ReadBt,
        Op::ReadOt,
        Op::WriteBt,
        Op::WriteOt,
        Op::ScanBt,
        Op::DiffBt,
    ];

    fn label(self) -> &'static str {
        match self {
            Op::ReadBt => "read .bt → Snapshot",
            Op::ReadOt => "read .ot → Snapshot",
            Op::WriteBt => "write .bt (Snapshot → bytes)",
            Op::WriteOt => "write .ot (Snapshot → bytes)",
            Op::ScanBt => "stream .bt leaves (native `scan`) vs upstream read .bt",
            Op::DiffBt => "compare .bt with the one before (native `diff`) vs upstream read .bt",
        }
    }

    fn format_name(self) -> &'static str {
        match self {
            Op::ReadBt | Op::WriteBt | Op::ScanBt | Op::DiffBt => "bt",
            Op::ReadOt | Op::WriteOt => "ot",
        }
    }
}

/// One map in both file layouts.
struct Sample {
    snapshot: Snapshot,
    bt: Vec<u8>,
    ot: Vec<u8>,
    /// The `.bt` of the map before it in the series (itself for a lone map), and its index.
    previous_bt: (Vec<u8>, TreeIndex),
}

impl Sample {
    fn new(snapshot: Snapshot, previous: Option<&Snapshot>) -> Self {
        // The native encoders are byte-identical to upstream's (tests/native_vs_upstream.rs).
        let bt = encode_binary(&snapshot);
        let previous_bt = previous.map_or_else(|| bt.clone(), encode_binary);
        let index = TreeIndex::of(&previous_bt, FileKind::Binary).unwrap();
        Sample {
            bt,
            ot: encode_full(&snapshot),
            snapshot,
            previous_bt: (previous_bt, index),
        }
    }
}

fn format(registry: &FormatRegistry, op: Op, backend: Backend) -> MapFormat {
    let format = *registry.by_name(op.format_name(), Some(backend)).unwrap();
    assert!(format.backend == backend, "no {} backend", backend.name());
    format
}

/// Runs one operation once and returns its wall time.
fn time_once(registry: &FormatRegistry, op: Op, backend: Backend, sample: &Sample) -> Duration {
    if matches!(op, Op::ScanBt | Op::DiffBt) && backend == Backend::Octomap {
        // Upstream has no streaming reader: compare with its full read.
        return time_once(registry, Op::ReadBt, backend, sample);
    }
    let format = format(registry, op, backend);
    let start = Instant::now();
    match op {
        Op::ScanBt => {
            let mut occupied = 0u64;
            scan(
                &sample.bt,
                None,
                ReadLimits::default(),
                &mut |leaf: Leaf| {
                    occupied += u64::from(leaf.occupancy().is_occupied());
                },
            )
            .unwrap();
            black_box(occupied);
        }
        Op::DiffBt => {
            let (previous, index) = &sample.previous_bt;
            let mut changed = 0u64;
            diff(
                Some((previous, Some(index))),
                &sample.bt,
                None,
                ReadLimits::default(),
                &mut |change: StateChange| changed += change.end - change.start,
            )
            .unwrap();
            black_box(changed);
        }
        Op::ReadBt | Op::ReadOt => {
            let bytes = if op == Op::ReadBt {
                &sample.bt
            } else {
                &sample.ot
            };
            let read = registry
                .read_bytes(
                    Path::new("bench"),
                    bytes,
                    ReadOptions {
                        format: Some(op.format_name()),
                        backend: Some(backend),
                    },
                )
                .unwrap();
            black_box(read.map.snapshot.leaves().len());
        }
        Op::WriteBt | Op::WriteOt => {
            let writer = (format.writer.unwrap())();
            let mut out = Vec::new();
            writer.write(&sample.snapshot, &mut out).unwrap();
            black_box(out.len());
        }
    }
    start.elapsed()
}

fn median(mut times: Vec<Duration>) -> Duration {
    times.sort_unstable();
    times[times.len() / 2]
}

fn ms(d: Duration) -> String {
    format!("{:.2} ms", d.as_secs_f64() * 1e3)
}

/// Median time of `op` per backend over `samples`, each measured `repeats` times, native
/// and upstream alternating so both see the same machine state.
fn measure(
    registry: &FormatRegistry,
    op: Op,
    samples: &[Sample],
    repeats: usize,
) -> (Duration, Duration) {
    let (mut native, mut upstream) = (Vec::new(), Vec::new());
    // One warm-up of each, not counted.
    time_once(registry, op, Backend::Native, &samples[0]);
    time_once(registry, op, Backend::Octomap, &samples[0]);
    for _ in 0..repeats {
        for sample in samples {
            native.push(time_once(registry, op, Backend::Native, sample));
            upstream.push(time_once(registry, op, Backend::Octomap, sample));
        }
    }
    (median(native), median(upstream))
}

/// xorshift64*: deterministic perturbations without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn chance(&mut self, per_mille: u64) -> bool {
        self.next() % 1000 < per_mille
    }
}

/// A copy of `base` as a later observation might see it: about 3% of leaves change state,
/// 1% are forgotten, 1% of coarse leaves are split into their eight children (with graded
/// values, as an `.ot` would carry them).
fn perturbed(base: &Snapshot, seed: u64) -> Snapshot {
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let mut leaves = Vec::with_capacity(base.leaves().len() + 1024);
    for leaf in base.leaves() {
        if rng.chance(10) {
            continue;
        }
        let mut leaf = *leaf;
        if rng.chance(30) {
            leaf.log_odds = (!leaf.occupancy()).log_odds();
        }
        if leaf.depth < 16 && rng.chance(10) {
            let size = froctomap_core::voxels_per_node(leaf.depth + 1);
            for child in 0..8 {
                leaves.push(Leaf {
                    start: froctomap_core::MortonCode(leaf.start.0 + child * size),
                    depth: leaf.depth + 1,
                    log_odds: leaf.log_odds + (child as f32) * 0.125,
                });
            }
        } else {
            leaves.push(leaf);
        }
    }
    Snapshot::from_leaves(base.resolution(), leaves).unwrap()
}

fn env_number(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let geb_path = std::env::var_os("FROCTOMAP_GEB079")
        .map(PathBuf::from)
        .unwrap_or_else(|| "/usr/share/doc/liboctomap-dev/examples/data/geb079.bt".into());
    let geb_bytes = std::fs::read(&geb_path).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (install liboctomap-dev or set FROCTOMAP_GEB079)",
            geb_path.display()
        )
    });
    let registry = FormatRegistry::with_default_formats();
    let geb = registry
        .read_bytes(&geb_path, &geb_bytes, ReadOptions::default())
        .unwrap()
        .map
        .snapshot;
    let series_len = env_number("FROCTOMAP_BENCH_SERIES", 30).max(1);
    let repeats = env_number("FROCTOMAP_BENCH_REPEATS", 15).max(1);

    let geb_sample = [Sample::new(geb.clone(), None)];
    assert!(
        geb_sample[0].bt == geb_bytes,
        "geb079.bt is canonical; the native writer must reproduce it"
    );
    let maps: Vec<Snapshot> = (0..series_len as u64).map(|i| perturbed(&geb, i)).collect();
    let series: Vec<Sample> = maps
        .iter()
        .enumerate()
        .map(|(i, map)| Sample::new(map.clone(), i.checked_sub(1).map(|j| &maps[j])))
        .collect();
    let leaves: usize = series.iter().map(|s| s.snapshot.leaves().len()).sum();
    let bt_bytes: usize = series.iter().map(|s| s.bt.len()).sum();

    println!(
        "\n## Native Rust codec vs upstream OctoMap (FFI), {} logical CPUs\n",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!(
        "* `geb079`: the FR-079 scan, {} leaves, {} B .bt / {} B .ot; {repeats} runs each, median.",
        geb.leaves().len(),
        geb_sample[0].bt.len(),
        geb_sample[0].ot.len()
    );
    println!(
        "* `series`: {series_len} perturbed copies of it ({:.0} leaves, {:.0} B .bt on average); each file once per backend, median over files.\n",
        leaves as f64 / series_len as f64,
        bt_bytes as f64 / series_len as f64
    );
    println!("| data | operation | native | upstream (C++) | native / upstream |");
    println!("| --- | --- | ---: | ---: | ---: |");
    for (label, samples, repeats) in [
        ("geb079", &geb_sample[..], repeats),
        ("series", &series[..], 1),
    ] {
        for op in Op::ALL {
            let (native, upstream) = measure(&registry, op, samples, repeats);
            println!(
                "| {label} | {} | {} | {} | {:.3} |",
                op.label(),
                ms(native),
                ms(upstream),
                native.as_secs_f64() / upstream.as_secs_f64()
            );
        }
    }
    println!(
        "\n(geb079 is compared with itself, the series with the copy before. The pipeline itself (`build`, `retrieve`) is measured by `froctomap-bench`.)"
    );
}
