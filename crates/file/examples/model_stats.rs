//! Histogram of model orders (periodic terms) and toggle counts of the modelled cells of a
//! file.
//!
//! `cargo run --release -p froctomap-file --example model_stats -- FILE.froct`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use froctomap_file::{CellContent, FroctReader};

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: model_stats FILE.froct");
    let reader = FroctReader::open(std::path::Path::new(&path)).unwrap();
    let mut orders = [0u64; 8];
    let mut toggles = [0u64; 8];
    let mut extreme_mean = 0u64;
    let mut cells = 0u64;
    for i in 0..reader.tiles().len() {
        for cell in reader.read_tile(i).unwrap() {
            if let CellContent::Modelled(v) = &cell.content {
                cells += 1;
                let description = reader.model().describe(v.parameters()).unwrap();
                orders[description.periodic.len().min(7)] += 1;
                let t = v.toggles().len();
                toggles[(usize::BITS - t.leading_zeros()) as usize % 8] += 1;
                if description.mean < 0.05 || description.mean > 0.95 {
                    extreme_mean += 1;
                }
            }
        }
    }
    println!("modelled cells: {cells}, mean outside [0.05, 0.95]: {extreme_mean}");
    println!("orders: {orders:?}");
    println!("toggle count log2 buckets (0, 1, 2-3, 4-7, ...): {toggles:?}");
}
