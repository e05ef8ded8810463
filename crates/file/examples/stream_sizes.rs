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
    let mut rows: Vec<(&str, u64, u64)> = Vec::new();
    for i in 0..reader.tiles().len() {
        for (k, (name, s)) in reader.tile_streams(i).unwrap().into_iter().enumerate() {
            if rows.len() <= k {
                rows.push((name, 0, 0));
            }
            rows[k].1 += s.len() as u64;
            rows[k].2 += zstd::bulk::compress(&s, 19).unwrap().len() as u64;
        }
    }
    println!("| stream | raw bytes | zstd-19 alone |");
    println!("| --- | ---: | ---: |");
    for (name, raw, packed) in rows {
        println!("| {name} | {raw} | {packed} |");
    }
    println!("| file | | {} |", reader.file_len());
}
