//! Measures what things cost in a FROctomap file, on a generated four-week series at
//! 10-minute steps (4,032 samples): bytes per static voxel, per dynamic voxel model, per
//! outlier toggle, and the fixed header + index overhead.
//!
//! `cargo run --release -p froctomap-file --example size_table`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use froctomap_core::{MortonCode, Occupancy, Timestamp, VoxelKey};
use froctomap_file::{
    encode_tile, mask_from_ranges, Cell, CellContent, Codec, FroctWriter, Header, WrittenFile,
};
use froctomap_temporal::{
    ModelConfig, ModelRegistry, ObservationsBuilder, OutlierMode, PreparedModel, TimeAxis,
    VoxelObservations,
};

const SAMPLES: u32 = 4 * 7 * 144;
const TILE_DEPTH: u8 = 10;

fn axis() -> TimeAxis {
    TimeAxis::regular(
        Timestamp::from_secs(1_700_000_000),
        600_000_000_000,
        SAMPLES,
        vec![],
    )
    .unwrap()
}

/// Voxel `i` of a dense 64-voxel-wide slab starting at the origin.
fn voxel(i: u64) -> MortonCode {
    let o = 32768u16;
    VoxelKey::new(
        o + (i % 64) as u16,
        o + ((i / 64) % 64) as u16,
        o + (i / 4096) as u16,
    )
    .morton()
}

/// xorshift64: a fixed, seedable sequence, so the table is reproducible.
fn rng(seed: u64) -> impl FnMut() -> u64 {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}

/// A door-like schedule: open on weekdays from a per-voxel time for a per-voxel duration,
/// closed (occupied) otherwise, with `noise` random one-sample flips per week.
fn dynamic_series(seed: u64, noise: u32) -> VoxelObservations {
    let mut next = rng(seed);
    let open_from = (next() % 100) as u32;
    let duration = 20 + (next() % 80) as u32;
    let mut b = ObservationsBuilder::new();
    for i in 0..SAMPLES {
        let (day, slot) = (i / 144, i % 144);
        let mut open = day % 7 < 5 && (open_from..open_from + duration).contains(&slot);
        if noise > 0 && next() % 1008 < u64::from(noise) {
            open = !open;
        }
        b.push(i, Some(Occupancy::from(!open))).unwrap();
    }
    b.finish()
}

fn write(
    cells: &[Cell],
    model: &dyn PreparedModel,
    id: froctomap_temporal::ModelId,
) -> WrittenFile {
    let mut cells = cells.to_vec();
    cells.sort_by_key(|c| c.start);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("size.froct");
    let header = Header::new(
        0.05,
        TILE_DEPTH,
        axis(),
        id,
        model.encode_parameters(),
        Codec::default(),
    );
    let mut writer = FroctWriter::create(&path, &header).unwrap();
    let mut start = 0;
    while start < cells.len() {
        let tile = cells[start].start.node_start(TILE_DEPTH);
        let len = cells[start..]
            .iter()
            .take_while(|c| c.start.node_start(TILE_DEPTH) == tile)
            .count();
        writer
            .write_tile(
                &encode_tile(&header.tile_layout(), &cells[start..start + len], model).unwrap(),
            )
            .unwrap();
        start += len;
    }
    writer.finish(Default::default()).unwrap()
}

fn main() {
    let axis = axis();
    let registry = ModelRegistry::with_default_models();
    let model = registry.by_name("fremen-periods").unwrap().create();
    let lossless = model.prepare(&axis, &ModelConfig::default()).unwrap();
    let lossy = model
        .prepare(
            &axis,
            &ModelConfig::default().with_outliers(OutlierMode::Lossy),
        )
        .unwrap();

    // Static voxels at random positions (30 % of a dense block), 30 % of them occupied.
    let statics = |n: u64| -> Vec<Cell> {
        let (mut position, mut state) = (rng(7), rng(8));
        (0..)
            .filter(|_| position() % 10 < 3)
            .take(n as usize)
            .map(|i| Cell {
                start: voxel(i),
                depth: 16,
                mask: None,
                content: CellContent::Constant(Occupancy::from(state() % 10 < 3)),
            })
            .collect()
    };
    let dynamics = |n: u64, noise: u32, prepared: &dyn PreparedModel| -> (Vec<Cell>, u64) {
        let mut toggles = 0;
        let cells = (0..n)
            .map(|i| {
                let obs = dynamic_series(i, noise);
                let fitted = prepared.fit(&obs).unwrap();
                toggles += fitted.toggles().len() as u64;
                Cell {
                    start: voxel(i),
                    depth: 16,
                    mask: mask_from_ranges(&axis, &[(0, u64::from(SAMPLES))]),
                    content: CellContent::Modelled(fitted),
                }
            })
            .collect();
        (cells, toggles)
    };

    let one = write(&statics(1), lossless.as_ref(), model.id());
    let overhead = one.header_bytes + one.index_bytes;
    let many = write(&statics(100_000), lossless.as_ref(), model.id());
    let per_static = (many.file_bytes - overhead) as f64 / 100_000.0;

    let n = 10_000;
    let (clean_lossy, _) = dynamics(n, 0, lossy.as_ref());
    let lossy_file = write(&clean_lossy, lossy.as_ref(), model.id());
    let per_model = (lossy_file.file_bytes - overhead) as f64 / n as f64;
    let (noisy_lossless, toggles) = dynamics(n, 4, lossless.as_ref());
    let (noisy_lossy, _) = dynamics(n, 4, lossy.as_ref());
    let noisy_lossless_file = write(&noisy_lossless, lossless.as_ref(), model.id());
    let noisy_lossy_file = write(&noisy_lossy, lossy.as_ref(), model.id());
    let per_toggle =
        (noisy_lossless_file.file_bytes - noisy_lossy_file.file_bytes) as f64 / toggles as f64;

    println!("Series: {SAMPLES} samples (4 weeks at 10 min), model fremen-periods (default: auto order ≤ 5), zstd 19, tiles of 64³ voxels.\n");
    println!("| quantity | measured |");
    println!("| --- | --- |");
    println!(
        "| header + index + footer (1 tile) | {overhead} bytes ({} + {}) |",
        one.header_bytes, one.index_bytes
    );
    println!("| per static voxel (100,000 constant voxels at random positions, 30 % occupied) | {per_static:.3} bytes |");
    println!("| per dynamic voxel model (10,000 voxels, random weekday schedules, lossy: model only) | {per_model:.2} bytes |");
    println!("| per outlier toggle (10,000 noisy voxels, lossless − lossy, {toggles} toggles) | {per_toggle:.2} bytes |");
    println!(
        "| raw states, for scale (1 bit per voxel per sample) | {:.0} bytes per voxel |",
        f64::from(SAMPLES) / 8.0
    );
    println!(
        "| index entry per tile | {} bytes |",
        froctomap_file::TILE_ENTRY_LEN
    );
}
