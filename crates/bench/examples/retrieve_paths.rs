//! Checks and times the two ways `retrieve`/`predict` can write a `.bt` on a real file: the
//! tiled writer straight from the cells' states, and the whole map in memory (ML, canonical
//! split, encoder). Both must give identical bytes; prints the median of each.
//!
//! `cargo run --release -p froctomap-bench --example retrieve_paths -- FILE.froct [SAMPLE]`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use froctomap_convert::{
    observed_map, predicted_map, write_observed_map, write_owned_map, write_predicted_map, Context,
};
use froctomap_file::FroctReader;
use froctomap_formats::WriteOptions;
use std::path::PathBuf;
use std::time::Instant;

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn median_ms(mut f: impl FnMut()) -> f64 {
    f();
    let mut times: Vec<f64> = (0..15)
        .map(|_| {
            let started = Instant::now();
            f();
            started.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = PathBuf::from(
        args.next()
            .expect("usage: retrieve_paths FILE.froct [SAMPLE]"),
    );
    let context = Context::with_default_plugins();
    let reader = FroctReader::open(&path).unwrap();
    let axis = reader.header().axis.clone();
    let sample: u32 = args
        .next()
        .map_or(axis.len() / 2, |s| s.parse().expect("a sample index"));
    let dir = tempfile::tempdir().unwrap();
    let (whole, tiled) = (dir.path().join("whole.bt"), dir.path().join("tiled.bt"));
    let future = axis.end();
    for s in [0, sample, axis.len() - 1] {
        write_owned_map(
            &context,
            observed_map(&reader, s).unwrap(),
            &whole,
            WriteOptions::default(),
        )
        .unwrap();
        write_observed_map(&context, &reader, s, &tiled, WriteOptions::default()).unwrap();
        assert_eq!(
            std::fs::read(&whole).unwrap(),
            std::fs::read(&tiled).unwrap()
        );
    }
    write_owned_map(
        &context,
        predicted_map(&reader, future).unwrap(),
        &whole,
        WriteOptions::default(),
    )
    .unwrap();
    write_predicted_map(&context, &reader, future, &tiled, WriteOptions::default()).unwrap();
    assert_eq!(
        std::fs::read(&whole).unwrap(),
        std::fs::read(&tiled).unwrap()
    );
    println!(
        "identical bytes: observed at 0, {sample}, {}; predicted",
        axis.len() - 1
    );
    let retrieve_whole = median_ms(|| {
        let map = observed_map(&reader, sample).unwrap();
        write_owned_map(&context, map, &whole, WriteOptions::default()).unwrap();
    });
    let retrieve_tiled = median_ms(|| {
        write_observed_map(&context, &reader, sample, &tiled, WriteOptions::default()).unwrap();
    });
    let predict_whole = median_ms(|| {
        let map = predicted_map(&reader, future).unwrap();
        write_owned_map(&context, map, &whole, WriteOptions::default()).unwrap();
    });
    let predict_tiled = median_ms(|| {
        write_predicted_map(&context, &reader, future, &tiled, WriteOptions::default()).unwrap();
    });
    println!("| path | retrieve (sample {sample}) | predict |");
    println!("| --- | ---: | ---: |");
    println!("| whole map | {retrieve_whole:.1} ms | {predict_whole:.1} ms |");
    println!("| tiled | {retrieve_tiled:.1} ms | {predict_tiled:.1} ms |");
}
