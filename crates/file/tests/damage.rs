//! Damaged files give typed errors, never panics; damage inside one tile leaves the others
//! readable.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use froctomap_file::{FileError, FormatViolation, FroctReader, MemorySource, ReadLimits};
use froctomap_temporal::ModelRegistry;
use proptest::prelude::*;
use std::sync::OnceLock;

/// Reads damaged bytes from memory, named as a file would be in errors.
fn open_bytes(bytes: &[u8]) -> Result<FroctReader, FileError> {
    FroctReader::from_source(
        MemorySource::new(bytes.to_vec()).named("damaged.froct"),
        ReadLimits::default(),
        &ModelRegistry::with_default_models(),
    )
}

fn golden_bytes() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| std::fs::read(golden_path()).unwrap())
}

/// Opens and decodes everything; returns which tiles failed.
fn read_all(bytes: &[u8]) -> Result<Vec<bool>, FileError> {
    let reader = open_bytes(bytes)?;
    Ok((0..reader.tiles().len())
        .map(|i| reader.read_tile(i).is_err())
        .collect())
}

#[test]
fn every_truncation_point_is_a_typed_error() {
    let bytes = golden_bytes().to_vec();
    for len in 0..bytes.len() {
        match open_bytes(&bytes[..len]) {
            Err(FileError::Invalid { violation, path }) => {
                assert!(path.ends_with("damaged.froct"));
                assert!(
                    matches!(
                        violation,
                        FormatViolation::Corrupt { .. } | FormatViolation::Checksum(_)
                    ),
                    "{len}: {violation}"
                );
            }
            Err(other) => panic!("truncation to {len}: unexpected error {other}"),
            Ok(_) => panic!("truncation to {len} of {} bytes opened", bytes.len()),
        }
    }
}

#[test]
fn empty_and_foreign_files_are_named_as_such() {
    let err = open_bytes(b"").unwrap_err().to_string();
    assert!(
        err.contains("damaged.froct") && err.contains("empty"),
        "{err}"
    );
    let octomap = b"# Octomap OcTree binary file\nid OcTree\nsize 0\nres 0.1\ndata\n".repeat(2);
    let err = open_bytes(&octomap).unwrap_err().to_string();
    assert!(err.contains("not a FROctomap file"), "{err}");
}

#[test]
fn a_newer_major_version_is_refused_and_a_newer_minor_is_read() {
    let bytes = golden_bytes().to_vec();
    // Patch the version and fix the header crc, as a newer writer would have produced it.
    let patched = |major: u16, minor: u16| {
        let mut b = bytes.clone();
        b[8..10].copy_from_slice(&major.to_le_bytes());
        b[10..12].copy_from_slice(&minor.to_le_bytes());
        let header_len = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
        let crc = crc32c::crc32c(&b[..16 + header_len]);
        b[16 + header_len..20 + header_len].copy_from_slice(&crc.to_le_bytes());
        b
    };
    let err = open_bytes(&patched(2, 0)).unwrap_err();
    assert!(
        matches!(
            err.violation(),
            Some(FormatViolation::UnsupportedVersion { major: 2, .. })
        ),
        "{err}"
    );
    let newer_minor = open_bytes(&patched(1, 7)).unwrap();
    assert_eq!(newer_minor.header().version, (1, 7));
    assert!(newer_minor.read_tile(0).is_ok());
}

#[test]
fn a_flipped_bit_in_one_tile_leaves_the_others_readable() {
    let bytes = golden_bytes().to_vec();
    let reader = open_bytes(&bytes).unwrap();
    let tiles = reader.tiles().to_vec();
    for (damaged_tile, entry) in tiles.iter().enumerate() {
        for offset in entry.offset..entry.offset + u64::from(entry.stored_len) {
            let mut damaged = bytes.clone();
            damaged[offset as usize] ^= 0x04;
            let failed = read_all(&damaged).unwrap();
            for (tile, &fail) in failed.iter().enumerate() {
                assert_eq!(
                    fail,
                    tile == damaged_tile,
                    "flip at {offset} in tile {damaged_tile}: tile {tile}"
                );
            }
        }
    }
}

#[test]
fn checksum_errors_are_distinguished() {
    let bytes = golden_bytes().to_vec();
    let reader = open_bytes(&bytes).unwrap();
    let entry = reader.tiles()[1];
    let mut damaged = bytes.clone();
    damaged[entry.offset as usize + 1] ^= 1;
    let reader = open_bytes(&damaged).unwrap();
    let err = reader.read_tile(1).unwrap_err();
    assert!(
        matches!(err.violation(), Some(FormatViolation::Checksum("tile"))),
        "{err}"
    );
    let mut header_damage = bytes.clone();
    header_damage[20] ^= 1;
    assert!(matches!(
        open_bytes(&header_damage).unwrap_err().violation(),
        Some(FormatViolation::Checksum("header"))
    ));
    let mut index_damage = bytes;
    let at = index_damage.len() - 40;
    index_damage[at] ^= 1;
    assert!(matches!(
        open_bytes(&index_damage).unwrap_err().violation(),
        Some(FormatViolation::Checksum("index"))
    ));
}

#[test]
fn limits_are_checked_before_allocating() {
    let models = froctomap_temporal::ModelRegistry::with_default_models();
    let limits = froctomap_file::ReadLimits {
        max_cells_per_tile: 1,
        ..Default::default()
    };
    // The index's counts are checked at open, before any tile is read.
    let err = FroctReader::open_with_limits(&golden_path(), limits, &models).unwrap_err();
    assert!(
        matches!(
            err.violation(),
            Some(FormatViolation::Limit {
                what: "cells per tile",
                ..
            })
        ),
        "{err}"
    );
    let limits = froctomap_file::ReadLimits {
        max_header_bytes: 10,
        ..Default::default()
    };
    let err = FroctReader::open_with_limits(&golden_path(), limits, &models).unwrap_err();
    assert!(
        matches!(
            err.violation(),
            Some(FormatViolation::Limit {
                what: "header length",
                ..
            })
        ),
        "{err}"
    );
}

/// What opening and reading bytes that differ from the golden file at `changed` offsets
/// must report: every byte is covered by a checksum (or a magic number or version checked
/// before it), so each kind of damage has its own error.
fn expected_damage(
    changed: &[usize],
    len: usize,
) -> Result<Vec<bool>, fn(&FormatViolation) -> bool> {
    let reader = open_bytes(golden_bytes()).unwrap();
    let header_end = reader.tiles()[0].offset as usize;
    let index_start = len - froctomap_file::FOOTER_LEN - index_len(golden_bytes());
    let hit = |range: std::ops::Range<usize>| changed.iter().any(|i| range.contains(i));
    if hit(0..8) {
        return Err(|v| {
            matches!(
                v,
                FormatViolation::Corrupt {
                    what: "preamble",
                    ..
                }
            )
        });
    }
    if hit(8..10) {
        return Err(|v| matches!(v, FormatViolation::UnsupportedVersion { .. }));
    }
    if hit(12..16) {
        // The header length: too long for the limits or the file, or a header whose
        // checksum is then read from elsewhere.
        return Err(|v| {
            matches!(
                v,
                FormatViolation::Limit {
                    what: "header length",
                    ..
                } | FormatViolation::Corrupt { what: "header", .. }
                    | FormatViolation::Checksum("header")
            )
        });
    }
    if hit(10..12) || hit(16..header_end) {
        return Err(|v| matches!(v, FormatViolation::Checksum("header")));
    }
    if hit(len - 8..len) {
        return Err(|v| matches!(v, FormatViolation::Corrupt { what: "footer", .. }));
    }
    if hit(len - froctomap_file::FOOTER_LEN..len - 8) {
        return Err(|v| matches!(v, FormatViolation::Checksum("footer")));
    }
    if hit(index_start..len) {
        return Err(|v| matches!(v, FormatViolation::Checksum("index")));
    }
    Ok(reader
        .tiles()
        .iter()
        .map(|t| hit(t.offset as usize..(t.offset + u64::from(t.stored_len)) as usize))
        .collect())
}

/// The index length the footer gives.
fn index_len(bytes: &[u8]) -> usize {
    let footer = bytes.len() - froctomap_file::FOOTER_LEN;
    u64::from_le_bytes(bytes[footer + 8..footer + 16].try_into().unwrap()) as usize
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Up to three flipped bits anywhere (crc32c detects every such error in messages of
    /// any length a file has): opening fails with the error of the part hit first, or the
    /// damaged tiles, and only they, fail their checksum.
    #[test]
    fn random_bit_flips_are_reported_by_the_part_they_hit(flips in proptest::collection::vec((any::<proptest::sample::Index>(), 0u8..8), 1..4)) {
        let golden = golden_bytes();
        let mut bytes = golden.to_vec();
        for (index, bit) in flips {
            let i = index.index(bytes.len());
            bytes[i] ^= 1 << bit;
        }
        let changed: Vec<usize> = (0..bytes.len()).filter(|&i| bytes[i] != golden[i]).collect();
        match (expected_damage(&changed, bytes.len()), open_bytes(&bytes)) {
            (Err(expected), Err(err)) => {
                prop_assert!(err.violation().is_some_and(expected), "{changed:?}: {err}");
            }
            (Ok(damaged), Ok(reader)) => {
                for (tile, damaged) in damaged.into_iter().enumerate() {
                    match reader.read_tile(tile) {
                        Err(err) => prop_assert!(
                            damaged && matches!(err.violation(), Some(FormatViolation::Checksum("tile"))),
                            "{changed:?}: tile {tile}: {err}"
                        ),
                        Ok(_) => prop_assert!(!damaged, "{changed:?}: tile {tile} read"),
                    }
                }
            }
            (Err(_), Ok(_)) => prop_assert!(false, "{changed:?}: damaged file opened"),
            (Ok(_), Err(err)) => prop_assert!(false, "{changed:?}: {err}"),
        }
    }
}

/// The golden series stored raw (no zstd), so that damage reaches the tile parser instead
/// of the decompressor, in each toggle layout.
fn raw_golden(toggles: froctomap_file::ToggleLayout) -> Vec<u8> {
    static RAW: OnceLock<[Vec<u8>; 3]> = OnceLock::new();
    let [whole, blocked, coded] = RAW.get_or_init(|| {
        [
            froctomap_file::ToggleLayout::Whole,
            froctomap_file::ToggleLayout::Blocked(16),
            froctomap_file::ToggleLayout::Coded(16),
        ]
        .map(raw_golden_file)
    });
    match toggles {
        froctomap_file::ToggleLayout::Whole => whole.clone(),
        froctomap_file::ToggleLayout::Blocked(16) => blocked.clone(),
        froctomap_file::ToggleLayout::Coded(16) => coded.clone(),
        other => panic!("no raw golden file in layout {other:?}"),
    }
}

/// Every way of reading a tile: whole, at single samples (one toggle block), predicted.
fn read_every_way(bytes: &[u8]) -> Result<(), FileError> {
    let reader = open_bytes(bytes)?;
    let samples = reader.header().axis.len();
    for tile in 0..reader.tiles().len() {
        let _ = reader.read_tile(tile);
        for sample in [0, 15, 16, 40, samples - 1, samples + 3] {
            let _ = reader.observed_leaves(tile, sample, &mut Vec::new());
        }
        let _ = reader.predicted_leaves(tile, 7200.0, &|p| p as f32, &mut Vec::new());
    }
    Ok(())
}

#[test]
fn resealed_raw_files_read_back_in_every_layout() {
    for toggles in [
        froctomap_file::ToggleLayout::Whole,
        froctomap_file::ToggleLayout::Blocked(16),
        froctomap_file::ToggleLayout::Coded(16),
    ] {
        let mut bytes = raw_golden(toggles);
        let sealed = bytes.clone();
        reseal(&mut bytes);
        assert_eq!(bytes, sealed, "resealing an intact file changes nothing");
        let reader = open_bytes(&bytes).unwrap();
        for tile in 0..reader.tiles().len() {
            reader.read_tile(tile).unwrap();
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Damage inside tiles that still passes every checksum (raw tiles, checksums
    /// recomputed) reaches the frame table, the block parts and the cell streams: every read
    /// path ends in values or typed errors, never a panic or a huge allocation.
    #[test]
    fn damaged_tiles_with_valid_checksums_never_panic(
        layout in 0u8..3,
        flips in proptest::collection::vec((any::<proptest::sample::Index>(), 0u8..8), 1..6),
    ) {
        let toggles = match layout {
            0 => froctomap_file::ToggleLayout::Whole,
            1 => froctomap_file::ToggleLayout::Blocked(16),
            _ => froctomap_file::ToggleLayout::Coded(16),
        };
        let mut bytes = raw_golden(toggles);
        let reader = open_bytes(&bytes).unwrap();
        let tiles: Vec<(usize, usize)> = reader
            .tiles()
            .iter()
            .map(|t| (t.offset as usize, t.stored_len as usize))
            .collect();
        let tile_bytes: usize = tiles.iter().map(|t| t.1).sum();
        for (index, bit) in flips {
            // A position among the tiles' bytes only.
            let mut at = index.index(tile_bytes);
            let (offset, _) = tiles
                .iter()
                .find(|&&(_, len)| {
                    if at < len {
                        true
                    } else {
                        at -= len;
                        false
                    }
                })
                .copied()
                .unwrap();
            bytes[offset + at] ^= 1 << bit;
        }
        reseal(&mut bytes);
        read_every_way(&bytes).unwrap();
    }
}
