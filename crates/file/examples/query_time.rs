//! Times the map at one sample (every tile's observed states, what `retrieve` decodes
//! before building the `.bt`) on several files, interleaved run by run so that a shared,
//! noisy machine slows them alike. Prints the median and minimum per file.
//!
//! `cargo run --release -p froctomap-file --example query_time -- SAMPLE RUNS A.froct B.froct …`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use froctomap_file::FroctReader;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [sample, runs, files @ ..] = &args[..] else {
        panic!("usage: query_time SAMPLE RUNS FILE…");
    };
    let sample: u32 = sample.parse().unwrap();
    let runs: usize = runs.parse().unwrap();
    let readers: Vec<FroctReader> = files
        .iter()
        .map(|f| FroctReader::open(std::path::Path::new(f)).unwrap())
        .collect();
    let mut times = vec![Vec::new(); readers.len()];
    let mut leaves = Vec::new();
    for run in 0..=runs {
        for (reader, times) in readers.iter().zip(&mut times) {
            let start = Instant::now();
            leaves.clear();
            for tile in 0..reader.tiles().len() {
                reader.observed_leaves(tile, sample, &mut leaves).unwrap();
            }
            // Run 0 warms the page cache and the allocator.
            if run > 0 {
                times.push(start.elapsed().as_secs_f64() * 1e3);
            }
        }
    }
    let first = median(&mut times[0].clone());
    for (file, times) in files.iter().zip(&mut times) {
        let m = median(times);
        println!(
            "{file}: median {m:.2} ms, min {:.2} ms, {:.3}× the first",
            times[0],
            m / first
        );
    }
}

/// Sorts `times` and returns their median.
fn median(times: &mut [f64]) -> f64 {
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}
