//! Which part of a FROctomap file costs what: each tile stream compressed on its own.
//!
//! `cargo run --release -p froctomap-file --example stream_sizes -- FILE.froct`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use froctomap_file::FroctReader;

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: stream_sizes FILE.froct");
    let reader = FroctReader::open(std::path::Path::new(&path)).unwrap();
    let names = [
        "geometry",
        "depth",
        "class",
        "mask count",
        "mask refs",
        "mask counts",
        "mask starts",
        "mask lengths",
        "models",
        "outlier counts",
        "outlier starts",
        "outlier lengths",
    ];
    let mut raw = [0u64; 12];
    let mut packed = [0u64; 12];
    for i in 0..reader.tiles().len() {
        let streams = reader.tile_streams(i).unwrap();
        for (k, s) in streams.iter().enumerate() {
            raw[k] += s.len() as u64;
            packed[k] += zstd::bulk::compress(s, 19).unwrap().len() as u64;
        }
    }
    println!("| stream | raw bytes | zstd-19 alone |");
    println!("| --- | ---: | ---: |");
    for k in 0..12 {
        println!("| {} | {} | {} |", names[k], raw[k], packed[k]);
    }
    println!("| file | | {} |", reader.file_len());
}
