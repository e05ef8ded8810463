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
    // The violation is printed once: in the message, not again as a cause.
    assert!(err
        .to_string()
        .contains("more cells than its decoded length"));
    assert!(std::error::Error::source(&err).is_none());
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
    // Within every limit, a count beyond the voxels of a tile (cells are disjoint and lie
    // inside it) is refused too: no walk over cells that cannot exist.
    let tile_voxels = 1u32 << (3 * (16 - u32::from(GOLDEN_TILE_DEPTH)));
    for (count, refused) in [(tile_voxels, false), (tile_voxels + 1, true)] {
        set_u32(&mut bytes, entry + CELL_COUNT, count);
        reseal(&mut bytes);
        match open_with(&bytes, ReadLimits::default()) {
            Err(err) if refused => assert!(
                matches!(
                    err.violation(),
                    Some(FormatViolation::Corrupt { what: "index", detail })
                        if detail.contains(&format!("holds at most {tile_voxels}"))
                ),
                "{err}"
            ),
            // The count is only compared with the tile's cells when the tile is read.
            Ok(reader) => {
                assert!(!refused);
                assert!(reader.read_tile(0).is_err());
            }
            Err(err) => panic!("{count} cells refused at open: {err}"),
        }
    }
}

#[test]
fn a_regular_axis_of_millions_of_one_sample_blocks_is_refused() {
    let mut bytes = raw_golden_file(ToggleLayout::Blocked(1));
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
    // Resealed counts of a full tile each (within the per-tile limits) add up past a
    // total of two full tiles.
    let full = 1u32 << (3 * (16 - u32::from(GOLDEN_TILE_DEPTH)));
    assert!(reader.tiles().len() >= 3);
    let mut bytes = bytes;
    for t in 0..reader.tiles().len() {
        let entry = index_entry(&bytes, t);
        set_u32(&mut bytes, entry + RAW_LEN, 1 << 30);
        set_u32(&mut bytes, entry + CELL_COUNT, full);
    }
    reseal(&mut bytes);
    let err = open_with(&bytes, limits(2 * u64::from(full))).unwrap_err();
    assert_eq!(
        limit_of(&err),
        Some(("cells in the file", 3 * u64::from(full))),
        "{err}"
    );
}

/// A tile of `n` cells, each observed at one sample of its own (`n` distinct masks), on an
/// axis of `n` one-sample toggle blocks: whole toggle lists must be read in time linear in
/// the toggles, not masks × blocks.
fn many_masks_and_blocks(n: u16) -> Vec<u8> {
    use froctomap_core::{Occupancy, Timestamp, VoxelKey};
    let axis = froctomap_temporal::TimeAxis::regular(
        Timestamp::from_secs(1_700_000_000),
        1_000_000_000,
        u32::from(n),
        vec![],
    )
    .unwrap();
    let mut cells: Vec<SeriesCell> = (0..n)
        .map(|i| {
            let mut b = froctomap_temporal::ObservationsBuilder::new();
            b.push(u32::from(i), Some(Occupancy::Occupied)).unwrap();
            SeriesCell {
                start: VoxelKey::new(i % 32, (i / 32) % 32, i / 1024).morton(),
                depth: 16,
                observations: b.finish(),
            }
        })
        .collect();
    cells.sort_by_key(|c| c.start);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("masks.froct");
    write_file(
        &path,
        &axis,
        "fremen-periods",
        &golden_config(),
        TileLayout {
            tile_depth: 11,
            codec: Codec::Zstd { level: 3 },
            toggles: ToggleLayout::Blocked(1),
        },
        &cells,
    );
    std::fs::read(&path).unwrap()
}

/// 16,384 masks over 16,384 blocks: a walk over masks × blocks took 6.4 s here (debug
/// build), the walk over the blocks listing each mask 0.16 s.
#[test]
fn whole_toggle_lists_of_many_masks_over_many_blocks_read_back() {
    let n = 16384;
    let bytes = many_masks_and_blocks(n);
    let reader = open_with(&bytes, ReadLimits::default()).unwrap();
    assert_eq!(reader.tiles().len(), 1);
    let cells = reader.read_tile(0).unwrap();
    assert_eq!(cells.len(), usize::from(n));
    // Each cell observed at its own sample only: toggles on at `i`, off at `i + 1` (but
    // for the last sample).
    let mut seen = vec![false; usize::from(n)];
    for cell in &cells {
        let mask = cell.mask.as_ref().expect("a mask");
        let on = match *mask.as_slice() {
            [on, off] if off == on + 1 => on,
            [on] if on + 1 == u32::from(n) => on,
            ref other => panic!("{other:?}"),
        };
        assert!(!std::mem::replace(&mut seen[on as usize], true));
    }
}

/// Format 1.2's header: `TOGGLE_CODE` names a coding this reader knows and needs
/// `TOGGLE_BLOCKS`.
#[test]
fn a_toggle_code_of_another_kind_or_without_blocks_is_refused() {
    let golden = std::fs::read(golden_path_of("golden-v1.2.froct")).unwrap();
    assert!(open_with(&golden, ReadLimits::default()).is_ok());
    let mut bytes = golden.clone();
    let code = header_section(&bytes, 7);
    bytes[code] = 2;
    reseal_header(&mut bytes);
    let err = open_with(&bytes, ReadLimits::default()).unwrap_err();
    assert!(
        matches!(err.violation(), Some(FormatViolation::UnsupportedFeature(what)) if what.contains("toggle code 2")),
        "{err}"
    );
    // TOGGLE_BLOCKS turned into an unknown section that may be skipped.
    let mut bytes = golden;
    let blocks = header_section(&bytes, 6) - 8;
    bytes[blocks..blocks + 4].copy_from_slice(&[99, 0, 0, 0]);
    reseal_header(&mut bytes);
    let err = open_with(&bytes, ReadLimits::default()).unwrap_err();
    assert!(err.to_string().contains("without TOGGLE_BLOCKS"), "{err}");
}

/// Range-coded exceptions count against the toggle limit, one per list and block visited
/// besides their toggles: an empty list costs the coder next to nothing.
#[test]
fn range_coded_exceptions_are_bounded_by_the_toggle_limit() {
    let bytes = raw_golden_file(ToggleLayout::Coded(16));
    let reader = open_with(&bytes, ReadLimits::default()).unwrap();
    // The noisy voxel: the only cell with exceptions, alone in its list set.
    let (tile, exceptions) = (0..reader.tiles().len())
        .find_map(|t| {
            reader
                .read_tile(t)
                .unwrap()
                .into_iter()
                .find_map(|c| match c.content {
                    froctomap_file::CellContent::ConstantExcept { exceptions, .. } => {
                        Some((t, exceptions.len() as u64))
                    }
                    _ => None,
                })
        })
        .unwrap();
    // 72 samples in blocks of 16: five blocks visited.
    let needed = exceptions + 5;
    let with_limit = |limit: u64| {
        let limits = ReadLimits {
            max_toggles_per_tile: limit,
            ..ReadLimits::default()
        };
        open_with(&bytes, limits).unwrap().read_tile(tile)
    };
    let err = with_limit(needed - 1).unwrap_err();
    assert_eq!(
        limit_of(&err),
        Some(("toggles in a tile's list set", needed)),
        "{err}"
    );
    // The tile's other list sets hold fewer: at the exact limit the tile reads.
    with_limit(needed).unwrap();
}
