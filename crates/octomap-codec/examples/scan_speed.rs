//! Times the native `.bt` scan on one file (all leaves, and merged runs).
//!
//! `cargo run --release -p froctomap-octomap-codec --example scan_speed -- FILE.bt`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use froctomap_octomap_codec::{scan, scan_runs, ReadLimits};
use std::time::Instant;

fn main() {
    let path = std::env::args().nth(1).expect("usage: scan_speed FILE");
    let bytes = std::fs::read(path).unwrap();
    for _ in 0..3 {
        let t = Instant::now();
        let mut leaves = 0u64;
        for _ in 0..50 {
            scan(&bytes, None, ReadLimits::default(), &mut |_| leaves += 1).unwrap();
        }
        let per_leaf = t.elapsed() / 50;
        let t = Instant::now();
        let mut runs = Vec::new();
        for _ in 0..50 {
            runs.clear();
            scan_runs(&bytes, None, ReadLimits::default(), &mut |r| runs.push(r)).unwrap();
        }
        println!(
            "scan {:?} per file ({} leaves), scan_runs {:?} per file ({} runs)",
            per_leaf,
            leaves / 50,
            t.elapsed() / 50,
            runs.len()
        );
    }
}
