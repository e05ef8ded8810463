//! Which part of a format 2.0 file's segments costs what: per segment, its stored tile bytes,
//! record bytes, and each tile stream compressed on its own (zstd level 19), summed over the
//! segments; the cells of the segments by kind (a patch tile's inherited parts included,
//! those observed at no sample left out); the patch tiles and their remainder runs;
//! and each segment tile's payload (its streams joined) compressed at zstd levels 19, 9, 3
//! and 1: bytes and compression time, what a commit pays per level.
//!
//! `cargo run --release -p froctomap-file --example segment_sizes -- FILE.froct`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use froctomap_file::{LivingReader, SegmentContent};

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: segment_sizes FILE.froct");
    let reader = LivingReader::open(std::path::Path::new(&path)).unwrap();
    let root = reader.root();
    println!(
        "base {} B, {} segments, {} samples, file {} B",
        root.base_len,
        reader.segment_count(),
        reader.sample_count(),
        root.committed_len
    );
    let mut rows: Vec<(&str, u64, u64)> = Vec::new();
    let (mut stored, mut tiles) = (0u64, 0u64);
    let mut kinds = [0u64; 4]; // constant, constant-except, inherited, with mask
    let mut payloads: Vec<Vec<u8>> = Vec::new();
    let (mut patches, mut regional, mut runs) = (0u64, 0u64, 0u64);
    for k in 0..reader.segment_count() {
        let entries = reader.segment_tiles(k);
        let seg_stored: u64 = entries.iter().map(|t| u64::from(t.stored_len)).sum();
        println!(
            "segment {k}: {} tiles, {} cells, {seg_stored} B of tiles",
            entries.len(),
            entries.iter().map(|t| u64::from(t.cell_count)).sum::<u64>()
        );
        stored += seg_stored;
        tiles += entries.len() as u64;
        for t in 0..entries.len() {
            patches += u64::from(reader.is_patch_tile(k, t));
            if let Some(remainder) = reader
                .remainder(k, t)
                .unwrap()
                .filter(|r| !r.runs.is_empty())
            {
                regional += 1;
                runs += remainder.runs.len() as u64;
            }
            let mut payload = Vec::new();
            for (i, (name, s)) in reader
                .segment_tile_streams(k, t)
                .unwrap()
                .into_iter()
                .enumerate()
            {
                if rows.len() <= i {
                    rows.push((name, 0, 0));
                }
                rows[i].1 += s.len() as u64;
                rows[i].2 += zstd::bulk::compress(&s, 19).unwrap().len() as u64;
                payload.extend_from_slice(&s);
            }
            payloads.push(payload);
            for cell in reader.read_segment_tile(k, t).unwrap() {
                kinds[match cell.content {
                    SegmentContent::Constant(_) => 0,
                    SegmentContent::ConstantExcept { .. } => 1,
                    SegmentContent::Inherited { .. } => 2,
                }] += 1;
                kinds[3] += u64::from(cell.mask.is_some());
            }
        }
    }
    println!("| stream | raw bytes | zstd-19 alone |");
    println!("| --- | ---: | ---: |");
    for (name, raw, packed) in rows {
        println!("| {name} | {raw} | {packed} |");
    }
    println!("| stored segment tiles ({tiles}) | | {stored} |");
    println!(
        "| segment records and tiles | | {} |",
        root.committed_len - root.base_len
    );
    println!(
        "cells: {} constant, {} constant with exceptions, {} inherited, {} with a mask; {patches} patch tiles, {regional} with {runs} remainder runs (FORMAT.md §10.7)",
        kinds[0], kinds[1], kinds[2], kinds[3]
    );
    println!("| zstd level | segment payload bytes | compression time |");
    println!("| ---: | ---: | ---: |");
    for level in [19, 9, 3, 1] {
        let started = std::time::Instant::now();
        let bytes: usize = payloads
            .iter()
            .map(|p| zstd::bulk::compress(p, level).unwrap().len())
            .sum();
        println!(
            "| {level} | {bytes} | {:.3} s |",
            started.elapsed().as_secs_f64()
        );
    }
}
