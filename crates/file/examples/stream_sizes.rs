//! Which part of a FROctomap file costs what: each tile stream compressed on its own, and
//! what the toggle lists hold (lists, toggles, one-sample pulses, by kind of list).
//!
//! `cargo run --release -p froctomap-file --example stream_sizes -- FILE.froct`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use froctomap_file::{CellContent, FroctReader};
use std::collections::HashSet;
use std::sync::Arc;

/// Lists, toggles and one-sample pulses (toggle pairs `t, t + 1` starting a run) of a kind.
#[derive(Default)]
struct ListStats {
    lists: u64,
    toggles: u64,
    pulses: u64,
}

impl ListStats {
    fn add(&mut self, toggles: &[u32]) {
        self.lists += 1;
        self.toggles += toggles.len() as u64;
        self.pulses += toggles
            .chunks(2)
            .filter(|pair| pair.len() == 2 && pair[1] == pair[0] + 1)
            .count() as u64;
    }
}

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: stream_sizes FILE.froct");
    let reader = FroctReader::open(std::path::Path::new(&path)).unwrap();
    let header = reader.header();
    println!(
        "format {}.{}, toggles {:?}, {} samples, {} tiles",
        header.version.0,
        header.version.1,
        header.toggles,
        header.axis.len(),
        reader.tiles().len()
    );
    let mut rows: Vec<(&str, u64, u64)> = Vec::new();
    let (mut masks, mut exceptions, mut outliers) = Default::default();
    let (mut stored, mut cells) = (0u64, 0u64);
    for i in 0..reader.tiles().len() {
        stored += u64::from(reader.tiles()[i].stored_len);
        for (k, (name, s)) in reader.tile_streams(i).unwrap().into_iter().enumerate() {
            if rows.len() <= k {
                rows.push((name, 0, 0));
            }
            rows[k].1 += s.len() as u64;
            rows[k].2 += zstd::bulk::compress(&s, 19).unwrap().len() as u64;
        }
        let mut seen = HashSet::new();
        reader
            .visit_cells(i, |cell| {
                cells += 1;
                if let Some(mask) = &cell.mask {
                    if seen.insert(Arc::as_ptr(mask)) {
                        ListStats::add(&mut masks, mask.as_slice());
                    }
                }
                match &cell.content {
                    CellContent::ConstantExcept { exceptions: e, .. } => {
                        ListStats::add(&mut exceptions, e.as_slice());
                    }
                    CellContent::Modelled(voxel) if !voxel.toggles().is_empty() => {
                        ListStats::add(&mut outliers, voxel.toggles().as_slice());
                    }
                    _ => {}
                }
            })
            .unwrap();
    }
    println!("| stream | raw bytes | zstd-19 alone |");
    println!("| --- | ---: | ---: |");
    for (name, raw, packed) in rows {
        println!("| {name} | {raw} | {packed} |");
    }
    println!("| stored tiles | | {stored} |");
    println!("| file | | {} |", reader.file_len());
    println!();
    println!("{cells} cells");
    println!("| lists | lists | toggles | one-sample pulses |");
    println!("| --- | ---: | ---: | ---: |");
    for (name, s) in [
        ("distinct masks", &masks),
        ("exceptions (constant cells)", &exceptions),
        ("outliers (modelled cells)", &outliers),
    ] {
        println!("| {name} | {} | {} | {} |", s.lists, s.toggles, s.pulses);
    }
}
