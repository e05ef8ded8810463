//! Times `changes` between two consecutive snapshots.
#![allow(clippy::unwrap_used, clippy::expect_used)]
use froctomap_core::changes;
use froctomap_formats::{FormatRegistry, ReadOptions};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let r = FormatRegistry::with_default_formats();
    let a = r
        .read_file(args[1].as_ref(), ReadOptions::default())
        .unwrap()
        .map
        .snapshot;
    let b = r
        .read_file(args[2].as_ref(), ReadOptions::default())
        .unwrap()
        .map
        .snapshot;
    let t = Instant::now();
    let mut n = 0;
    for _ in 0..50 {
        n = changes(a.leaves(), b.leaves()).len();
    }
    println!(
        "{} leaves vs {}: {} changes, {:?} per diff",
        a.leaves().len(),
        b.leaves().len(),
        n,
        t.elapsed() / 50
    );
    let t = Instant::now();
    for _ in 0..50 {
        let _ = r
            .read_file(args[1].as_ref(), ReadOptions::default())
            .unwrap();
    }
    println!("read {:?}", t.elapsed() / 50);
}
