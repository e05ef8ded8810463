//! Hostile files: valid files from the writer, patched and resealed (every checksum
//! recomputed) so that the damage reaches the decoders. Each must end quickly with a typed
//! error or a correct result, never a huge allocation.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use froctomap_file::{
    Codec, FileError, FormatViolation, FroctReader, MemorySource, ReadLimits, TileLayout,
    ToggleLayout,
};
use froctomap_temporal::ModelRegistry;

fn open_with(bytes: &[u8], limits: ReadLimits) -> Result<FroctReader, FileError> {
    FroctReader::from_source(
        MemorySource::new(bytes.to_vec()).named("hostile.froct"),
        limits,
        &ModelRegistry::with_default_models(),
    )
}

fn golden_bytes() -> Vec<u8> {
    std::fs::read(golden_path()).unwrap()
}

/// The golden series written raw with toggle blocks of `block` samples.
fn raw_file(block: u32) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("raw.froct");
    write_file(
        &path,
        &golden_axis(),
        "fremen-periods",
        &golden_config(),
        TileLayout {
            tile_depth: GOLDEN_TILE_DEPTH,
            codec: Codec::Raw,
            toggles: ToggleLayout::Blocked(block),
        },
        &golden_cells(),
    );
    std::fs::read(&path).unwrap()
}

fn limit_of(err: &FileError) -> Option<(&'static str, u64)> {
    match err.violation() {
        Some(FormatViolation::Limit { what, value, .. }) => Some((*what, *value)),
        _ => None,
    }
}

fn set_u32(bytes: &mut [u8], at: usize, value: u32) {
    bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
}

// Offsets inside an index entry (FORMAT.md §7): code u64, offset u64, stored_len, raw_len,
// crc, cell_count, first_sample, last_sample (u32 each).
const RAW_LEN: usize = 20;
const CELL_COUNT: usize = 28;

#[test]
fn a_resealed_huge_cell_count_is_refused_at_open() {
    let mut bytes = golden_bytes();
    let entry = index_entry(&bytes, 0);
    set_u32(&mut bytes, entry + CELL_COUNT, u32::MAX);
    reseal(&mut bytes);
    let err = open_with(&bytes, ReadLimits::default()).unwrap_err();
    assert!(
        matches!(
            err.violation(),
            Some(FormatViolation::Corrupt { what: "index", detail })
                if detail.contains("more cells than its decoded length")
        ),
        "{err}"
    );
    // A decoded length large enough for the count (within the tile byte limit) still
    // leaves the count beyond the cells a tile may hold.
    set_u32(&mut bytes, entry + RAW_LEN, 1 << 30);
    set_u32(&mut bytes, entry + CELL_COUNT, (1 << 24) + 1);
    reseal(&mut bytes);
    let err = open_with(&bytes, ReadLimits::default()).unwrap_err();
    assert_eq!(
        limit_of(&err),
        Some(("cells per tile", (1 << 24) + 1)),
        "{err}"
    );
}

#[test]
fn a_regular_axis_of_millions_of_one_sample_blocks_is_refused() {
    let mut bytes = raw_file(1);
    assert!(open_with(&bytes, ReadLimits::default()).is_ok());
    // TIME_AXIS of a regular axis: kind u8, start i64, step i64, sample count u32.
    let count = header_section(&bytes, 2) + 17;
    assert_eq!(bytes[count..count + 4], 72u32.to_le_bytes());
    set_u32(&mut bytes, count, 20_000_000);
    // A step of one second keeps the axis within the representable time range.
    let step = count - 8;
    bytes[step..count].copy_from_slice(&1_000_000_000i64.to_le_bytes());
    reseal_header(&mut bytes);
    let err = open_with(&bytes, ReadLimits::default()).unwrap_err();
    assert_eq!(limit_of(&err), Some(("toggle blocks", 20_000_000)), "{err}");
    // The sample count of a regular axis is bounded like an explicit one's.
    set_u32(&mut bytes, count, u32::MAX);
    reseal_header(&mut bytes);
    let err = open_with(&bytes, ReadLimits::default()).unwrap_err();
    assert_eq!(
        limit_of(&err),
        Some(("sample count", u64::from(u32::MAX))),
        "{err}"
    );
}

#[test]
fn the_cells_of_the_whole_file_are_bounded_at_open() {
    let bytes = golden_bytes();
    let reader = open_with(&bytes, ReadLimits::default()).unwrap();
    let total: u64 = reader.tiles().iter().map(|t| u64::from(t.cell_count)).sum();
    assert!(reader.tiles().len() > 1);
    let limits = |max_total_cells| ReadLimits {
        max_total_cells,
        ..Default::default()
    };
    open_with(&bytes, limits(total)).unwrap();
    let err = open_with(&bytes, limits(total - 1)).unwrap_err();
    assert_eq!(limit_of(&err), Some(("cells in the file", total)), "{err}");
    // Resealed counts of 2^24 cells per tile (each within the per-tile limit) add up past
    // a total of 2^25.
    let mut bytes = bytes;
    for t in 0..reader.tiles().len() {
        let entry = index_entry(&bytes, t);
        set_u32(&mut bytes, entry + RAW_LEN, 1 << 30);
        set_u32(&mut bytes, entry + CELL_COUNT, 1 << 24);
    }
    reseal(&mut bytes);
    let err = open_with(&bytes, limits(1 << 25)).unwrap_err();
    assert_eq!(
        limit_of(&err),
        Some(("cells in the file", 3 << 24)),
        "{err}"
    );
}
