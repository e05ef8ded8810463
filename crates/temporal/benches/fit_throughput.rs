//! Fitting throughput of each temporal model: voxel series per second (one thread) for
//! series of 1,000 / 10,000 / 100,000 samples, printed as a markdown table.
//!
//! `cargo bench -p froctomap-temporal`. Run without `--bench` (as `cargo test --benches`
//! does) it only smoke-tests the smallest size.
//!
//! Every axis spans four weeks (so weekly and daily periods are usable at every length); the
//! sample step shrinks as the length grows. Two voxel populations:
//! - *mixed*: what a map holds: 60 % constant voxels (seen free or occupied, with
//!   visibility gaps), 25 % with a few state changes (objects moved), 15 % periodic (an
//!   office-hours rhythm with noise);
//! - *periodic*: only the periodic voxels, the worst case.
//!
//! Models run in their defaults: lossless, `Auto { max: 8 }` orders.

use froctomap_core::{Occupancy, Timestamp};
use froctomap_temporal::{
    ModelConfig, ModelRegistry, ObservationsBuilder, TimeAxis, VoxelObservations,
};
use std::error::Error;
use std::time::{Duration, Instant};

const FOUR_WEEKS_NS: i64 = 28 * 86_400 * 1_000_000_000;

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
}

fn state(b: bool) -> Occupancy {
    Occupancy::from(b)
}

/// One voxel: `kind` 0 constant, 1 few changes, 2 periodic.
fn voxel(
    n: u32,
    step_s: f64,
    kind: u8,
    rng: &mut Rng,
) -> Result<VoxelObservations, Box<dyn Error>> {
    let mut b = ObservationsBuilder::new();
    let base = rng.below(2) == 1;
    let changes: Vec<u32> = (0..1 + rng.below(4))
        .map(|_| rng.below(u64::from(n)) as u32)
        .collect();
    let mut visible = true;
    let mut next_visibility_change = 0u32;
    for i in 0..n {
        if i >= next_visibility_change {
            // Seen for a while, then hidden for a shorter while.
            visible = !visible || rng.below(4) != 0;
            let len = if visible { n / 8 } else { n / 40 };
            next_visibility_change = i + 1 + rng.below(u64::from(len.max(1))) as u32;
        }
        if !visible {
            continue;
        }
        let s = match kind {
            0 => base,
            1 => base ^ (changes.iter().filter(|&&c| c <= i).count() % 2 == 1),
            _ => {
                let t = f64::from(i) * step_s;
                let hour = (t / 3600.0) % 24.0;
                let weekday = (t / 86_400.0) % 7.0 < 5.0;
                (weekday && (8.0..18.0).contains(&hour)) ^ (rng.below(50) == 0)
            }
        };
        b.push(i, Some(state(s)))?;
    }
    Ok(b.finish())
}

fn population(
    n: u32,
    step_s: f64,
    periodic_only: bool,
    count: usize,
) -> Result<Vec<VoxelObservations>, Box<dyn Error>> {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15 ^ u64::from(n));
    (0..count)
        .map(|k| {
            let kind = if periodic_only {
                2
            } else {
                match k % 20 {
                    0..=11 => 0,
                    12..=16 => 1,
                    _ => 2,
                }
            };
            voxel(n, step_s, kind, &mut rng)
        })
        .collect()
}

fn main() -> Result<(), Box<dyn Error>> {
    let full = std::env::args().any(|a| a == "--bench");
    let sizes: &[u32] = if full {
        &[1_000, 10_000, 100_000]
    } else {
        &[1_000]
    };
    let budget = Duration::from_millis(if full { 600 } else { 20 });
    let registry = ModelRegistry::with_default_models();
    let config = ModelConfig::default();

    println!("| model | samples | prepare (ms) | mixed (series/s) | periodic (series/s) | mean encoded bytes (mixed) |");
    println!("|---|---:|---:|---:|---:|---:|");
    for &n in sizes {
        let step_ns = FOUR_WEEKS_NS / i64::from(n);
        let axis = TimeAxis::regular(Timestamp::from_secs(1_451_865_600), step_ns, n, vec![])?;
        let step_s = step_ns as f64 / 1e9;
        let count = if n >= 100_000 { 60 } else { 200 };
        let mixed = population(n, step_s, false, count)?;
        let periodic = population(n, step_s, true, count / 4)?;
        for d in registry.iter() {
            let started = Instant::now();
            let model = d.create().prepare(&axis, &config)?;
            // The first fit builds lazily made tables (FFT plan, prefix sums): part of prepare.
            if let Some(obs) = periodic.first() {
                model.fit(obs)?;
            }
            let prepare_ms = started.elapsed().as_secs_f64() * 1e3;
            let mut rates = Vec::new();
            let mut bytes = 0usize;
            for (k, voxels) in [&mixed, &periodic].into_iter().enumerate() {
                let started = Instant::now();
                let mut fitted = 0usize;
                while started.elapsed() < budget || fitted < voxels.len().min(10) {
                    let obs = &voxels[fitted % voxels.len()];
                    let voxel = model.fit(obs)?;
                    if k == 0 && fitted < voxels.len() {
                        let mut out = Vec::new();
                        model.encode_voxel(&voxel, &mut out);
                        bytes += out.len();
                    }
                    fitted += 1;
                }
                rates.push(fitted as f64 / started.elapsed().as_secs_f64());
            }
            println!(
                "| {} | {} | {:.1} | {:.0} | {:.0} | {:.1} |",
                d.name,
                n,
                prepare_ms,
                rates[0],
                rates[1],
                bytes as f64 / mixed.len() as f64
            );
        }
    }
    Ok(())
}
