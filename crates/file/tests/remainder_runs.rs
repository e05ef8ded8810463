//! Format 2.0 patch tiles whose remainder several masks observe (FORMAT.md §10.7): each base
//! cell read by the mask its run gives (or at no sample), against states computed here from
//! the base's cells; the writer's checks; and hostile `REMAINDER_MASKS` sections (resealed,
//! truncated at every byte, every byte damaged) as typed errors, never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::living::*;
use froctomap_core::{MortonCode, Occupancy};
use froctomap_file::{
    Cell, FileError, FormatViolation, LivingReader, LivingWriter, MemorySource, ReadLimits,
    RemainderRun, TileEncodeError, TileRemainder, ROOT_SLOTS_AT, ROOT_SLOT_LEN,
};
use froctomap_temporal::{ModelRegistry, TimeAxis, Toggles};
use std::sync::Arc;

fn open_bytes(bytes: &[u8], limits: ReadLimits) -> Result<LivingReader, FileError> {
    LivingReader::from_source(
        Arc::new(MemorySource::new(bytes.to_vec()).named("living.froct")),
        limits,
        &ModelRegistry::with_default_models(),
    )
}

fn mask(positions: &[u32]) -> Option<Arc<Toggles>> {
    remainder_mask(positions)
}

/// Whether a remainder mask (`None`: every sample) observes segment sample `j`.
fn observes(mask: &Option<Arc<Toggles>>, j: u32) -> bool {
    mask.as_ref()
        .is_none_or(|m| m.as_slice().iter().filter(|&&p| p <= j).count() % 2 == 1)
}

/// `common::living::write_remainder_golden` into `dir`: the file, its segment's axis and
/// the base tile's cells.
fn regional_file(dir: &tempfile::TempDir) -> (std::path::PathBuf, TimeAxis, Vec<Cell>) {
    let path = dir.path().join("living.froct");
    let (axis, base_cells) = write_remainder_golden(&path);
    (path, axis, base_cells)
}

/// The section's bytes as the writer lays them out (FORMAT.md §10.7): one tile at patch
/// position 0 with one further mask `[0, 1]` and the runs (1, 1, mask 1), (2, 1, none).
const SECTION: [u8; 21] = [
    0x02, 0x02, 1, 0, 13, 0, 0, 0, // tag 0x0202, critical, 13 bytes
    1, 0, // one tile, at position 0
    1, 2, 0, 0, // one mask: two positions, 0 and 1
    2, 1, 1, 1, 0, 1, 0, // two runs
];

#[test]
fn each_base_cell_of_a_patch_tile_reads_by_the_mask_its_run_gives() {
    let dir = tempfile::tempdir().unwrap();
    let (path, axis, base_cells) = regional_file(&dir);
    let reader = LivingReader::open(&path).unwrap();
    let base = reader.base();
    let (first, origin) = (base.header().axis.len(), base.header().axis.start());
    let masks: Vec<Option<Option<Arc<Toggles>>>> = (0..base_cells.len())
        .map(|rank| match rank {
            0 => None, // stored
            1 => Some(mask(&[0, 1])),
            2 => Some(Some(Arc::new(Toggles::empty()))), // never observed
            _ => Some(mask(&[1])),
        })
        .collect();
    for j in 0..axis.len() {
        let got = reader.observed_states(first + j).unwrap();
        if axis.is_missing(j) {
            assert!(got.is_empty(), "sample {j} is missing");
            continue;
        }
        let seconds = axis.time(j).unwrap().secs_since(origin);
        let mut expected = vec![(
            base_cells[0].start,
            base_cells[0].depth,
            Occupancy::Occupied,
        )];
        for (rank, cell) in base_cells.iter().enumerate().skip(1) {
            let seen = match &masks[rank] {
                Some(Some(m)) if m.is_empty() => false,
                Some(m) => observes(m, j),
                None => false,
            };
            if seen {
                let state = base_prediction(base, &base_cells, cell.start, seconds);
                expected.push((cell.start, cell.depth, state));
            }
        }
        assert_eq!(got, expected, "sample {j}");
    }
    // Read whole: base cell 2 is no cell of the segment; the others carry their masks.
    let cells = reader.read_segment_tile(0, 0).unwrap();
    let starts: Vec<MortonCode> = cells.iter().map(|c| c.start).collect();
    let mut expected: Vec<MortonCode> = base_cells.iter().map(|c| c.start).collect();
    expected.remove(2);
    assert_eq!(starts, expected);
    assert_eq!(cells[1].mask, mask(&[0, 1]));
    assert!(cells[2..].iter().all(|c| c.mask == mask(&[1])));
    assert_eq!(reader.remainder_mask(0, 0).unwrap(), Some(mask(&[1])));
    assert_eq!(reader.remainder(0, 0).unwrap().unwrap().runs.len(), 2);
    // The section is where and as the format says.
    let bytes = std::fs::read(&path).unwrap();
    let (at, body) = newest_record(&bytes);
    assert_eq!(
        bytes[at + 24 + body - SECTION.len()..at + 24 + body],
        SECTION
    );
}

#[test]
fn the_writer_refuses_remainder_runs_the_format_cannot_hold() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _, base_cells) = regional_file(&dir);
    let before = std::fs::read(&path).unwrap();
    let mut writer = LivingWriter::open(&path).unwrap();
    let axis = golden_segment_axes()[1].clone();
    let run = |first, len, mask| RemainderRun { first, len, mask };
    let base_len = base_cells.len() as u32;
    let cases: Vec<(TileRemainder, bool)> = vec![
        // Overlapping, empty, naming a missing mask, past the base tile's cells.
        (vec![run(1, 2, 0), run(2, 1, 0)], false),
        (vec![run(1, 0, 0)], false),
        (vec![run(1, 1, 2)], false),
        (vec![run(base_len - 1, 2, 0)], false),
        (vec![run(1, 1, 1)], true),
    ]
    .into_iter()
    .map(|(runs, _)| {
        (
            TileRemainder {
                default: None,
                masks: vec![mask(&[0])],
                runs,
            },
            false,
        )
    })
    .chain([(
        TileRemainder {
            default: None,
            masks: vec![Some(Arc::new(Toggles::empty()))],
            runs: vec![run(1, 1, 1)],
        },
        true,
    )])
    .collect();
    for (i, (remainder, empty_mask)) in cases.into_iter().enumerate() {
        let well_formed = i == 4;
        let mut segment = writer.begin_segment(axis.clone()).unwrap();
        let mut encoder = segment.tile_encoder();
        encoder
            .push(stored_constant(&base_cells[0], Occupancy::Free))
            .unwrap();
        let result = segment.write_patch_tile_with(&encoder.finish().unwrap(), remainder);
        if well_formed {
            assert!(result.is_ok(), "case {i}: {result:?}");
            continue;
        }
        let err = result.unwrap_err();
        let expected = |source: &TileEncodeError| {
            if empty_mask {
                matches!(source, TileEncodeError::EmptyRemainderMask { .. })
            } else {
                matches!(source, TileEncodeError::BadRemainderRuns { .. })
            }
        };
        assert!(
            matches!(&err, FileError::TileEncode { source, .. } if expected(source)),
            "case {i}: {err}"
        );
    }
    drop(writer);
    // Nothing committed: the file reads as before.
    assert_eq!(std::fs::read(&path).unwrap(), before);
}

/// Every way of reading the segment: each sample's map and the tile whole; `Ok` or a
/// typed error naming the file.
fn read_all(reader: &LivingReader) {
    for g in 0..reader.sample_count() {
        if let Err(err) = reader.observed_states(g) {
            assert!(err.violation().is_some(), "{err}");
        }
    }
    for k in 0..reader.segment_count() {
        for t in 0..reader.segment_tiles(k).len() {
            if let Err(err) = reader.read_segment_tile(k, t) {
                assert!(err.violation().is_some(), "{err}");
            }
        }
    }
}

#[test]
fn resealed_hostile_remainder_masks_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _, base_cells) = regional_file(&dir);
    let bytes = std::fs::read(&path).unwrap();
    let (at, body) = newest_record(&bytes);
    let section = at + 24 + body - SECTION.len();
    let payload = section + 8;
    let patched = |patch: &dyn Fn(&mut Vec<u8>)| {
        let mut hostile = bytes.clone();
        patch(&mut hostile);
        reseal_record(&mut hostile, at, body);
        hostile
    };
    let refused = |hostile: &[u8], check: &dyn Fn(&FormatViolation) -> bool| {
        let err = open_bytes(hostile, ReadLimits::default()).unwrap_err();
        let violation = err.violation().expect("a format violation");
        assert!(check(violation), "{err}");
        assert!(err.to_string().starts_with("living.froct: "), "{err}");
    };
    let corrupt = |v: &FormatViolation| matches!(v, FormatViolation::Corrupt { .. });
    // A second tile (the segment has one patch tile), a tile past the patch tiles.
    refused(&patched(&|b| b[payload] = 2), &|v| {
        matches!(v, FormatViolation::Limit { .. })
    });
    refused(&patched(&|b| b[payload + 1] = 1), &corrupt);
    // A run naming mask 2 (the tile has one), an empty run, no run at all.
    refused(&patched(&|b| b[payload + 9] = 2), &corrupt);
    refused(&patched(&|b| b[payload + 8] = 0), &corrupt);
    refused(&patched(&|b| b[payload + 6] = 0), &corrupt);
    // A run past the base tile's cells (its first rank moved to the tile's cell count).
    let past = u8::try_from(base_cells.len()).unwrap();
    assert!(past < 0x80);
    refused(
        &patched(&|b| b[payload + 7] = past),
        &|v| matches!(v, FormatViolation::Corrupt { detail, .. } if detail.contains("base cells")),
    );
    // A mask position past the segment's samples.
    refused(&patched(&|b| b[payload + 5] = 100), &corrupt);
    // Counts that the bytes cannot hold (masks, runs), in their longest varints: refused
    // before anything is allocated for them.
    for offset in [2usize, 6] {
        let mut tail = bytes[section..payload + offset].to_vec();
        tail.extend_from_slice(&[0xFF, 0xFF, 0xFF, 0xFF, 0x0F]);
        tail.extend_from_slice(&bytes[payload + offset + 1..at + 24 + body]);
        let len = u32::try_from(tail.len() - 8).unwrap();
        tail[4..8].copy_from_slice(&len.to_le_bytes());
        let hostile = reframed(&bytes, at, section, &tail);
        let err = open_bytes(&hostile, ReadLimits::default()).unwrap_err();
        assert!(err.violation().is_some(), "{err}");
    }
    // Bytes after the last run.
    let mut tail = SECTION.to_vec();
    tail[4] += 1;
    tail.push(0);
    refused(&reframed(&bytes, at, section, &tail), &corrupt);
    // Every byte of the section damaged every way: opens and reads, or a typed error.
    for i in section..section + SECTION.len() {
        for value in [0u8, 1, 2, 3, 0x7F, 0x80, 0xFF] {
            let hostile = patched(&|b| b[i] = value);
            match open_bytes(&hostile, ReadLimits::default()) {
                Ok(reader) => read_all(&reader),
                Err(err) => assert!(err.violation().is_some(), "byte {i} = {value}: {err}"),
            }
        }
    }
    // Cut anywhere in the segment: the file opens without it or is refused.
    let base_end = open_bytes(&bytes, ReadLimits::default())
        .unwrap()
        .root()
        .base_len as usize;
    for len in base_end..bytes.len() {
        match open_bytes(&bytes[..len], ReadLimits::default()) {
            Ok(reader) => assert_eq!(reader.segment_count(), 0),
            Err(err) => assert!(err.violation().is_some(), "{err}"),
        }
    }
    // Cut anywhere in the section, the record re-framed and resealed around what is left.
    for cut in section..at + 24 + body {
        let hostile = reframed(&bytes, at, cut, &[]);
        match open_bytes(&hostile, ReadLimits::default()) {
            Ok(reader) => read_all(&reader),
            Err(err) => assert!(err.violation().is_some(), "cut at {cut}: {err}"),
        }
    }
}

fn newest_record(bytes: &[u8]) -> (usize, usize) {
    let reader = open_bytes(bytes, ReadLimits::default()).unwrap();
    let at = reader.root().last_segment as usize;
    let body = u32::from_le_bytes(bytes[at + 20..at + 24].try_into().unwrap()) as usize;
    (at, body)
}

fn reseal_record(bytes: &mut [u8], at: usize, body: usize) {
    let crc = crc32c::crc32c(&bytes[at..at + 24 + body]);
    bytes[at + 24 + body..at + 28 + body].copy_from_slice(&crc.to_le_bytes());
}

/// The newest record (at `at`) re-framed as its bytes up to `keep` followed by `tail`: body
/// length, record checksum and the root's committed length recomputed.
fn reframed(bytes: &[u8], at: usize, keep: usize, tail: &[u8]) -> Vec<u8> {
    let mut out = bytes[..keep].to_vec();
    out.extend_from_slice(tail);
    let new_body = out.len() - at - 24;
    out[at + 20..at + 24].copy_from_slice(&(new_body as u32).to_le_bytes());
    out.extend_from_slice(&[0; 4]);
    reseal_record(&mut out, at, new_body);
    let end = out.len() as u64;
    let slot = (0..2)
        .map(|s| ROOT_SLOTS_AT as usize + s * ROOT_SLOT_LEN)
        .max_by_key(|&slot| u64::from_le_bytes(out[slot..slot + 8].try_into().unwrap()))
        .unwrap();
    out[slot + 8..slot + 16].copy_from_slice(&end.to_le_bytes());
    let crc = crc32c::crc32c(&out[slot..slot + 60]);
    out[slot + 60..slot + 64].copy_from_slice(&crc.to_le_bytes());
    out
}

/// A reader keeps only a few segments' remainders decoded and reads a record again when a
/// query needs it: a record damaged under an open reader is a checksum error, one damaged and
/// resealed a typed error or a well-formed map, never a panic; the file put back, the same
/// reader reads every map again as at first.
#[test]
fn a_record_changed_under_an_open_reader_is_read_again_safely() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("remainder.froct");
    write_remainder_golden(&path);
    let original = std::fs::read(&path).unwrap();
    let (at, body) = newest_record(&original);
    let reader = LivingReader::open(&path).unwrap();
    let samples = reader.segment_axis(0).unwrap().0..reader.sample_count();
    let maps = |reader: &LivingReader| -> Vec<Result<Vec<_>, FileError>> {
        samples.clone().map(|g| reader.observed_states(g)).collect()
    };
    let expected: Vec<_> = maps(&reader).into_iter().map(Result::unwrap).collect();
    for byte in at + 24..at + 24 + body {
        for resealed in [false, true] {
            // A new reader each time: the one above has the record decoded.
            let reader = LivingReader::open(&path).unwrap();
            let mut hostile = original.clone();
            hostile[byte] ^= 0x01;
            if resealed {
                reseal_record(&mut hostile, at, body);
            }
            std::fs::write(&path, &hostile).unwrap();
            let mut decoded = false;
            for map in maps(&reader) {
                match map {
                    Err(err) if !resealed => assert!(
                        matches!(
                            err.violation(),
                            Some(FormatViolation::Checksum("segment record"))
                        ),
                        "byte {byte}: {err}"
                    ),
                    Err(err) => assert!(err.violation().is_some(), "byte {byte}: {err}"),
                    Ok(_) => {
                        assert!(resealed, "byte {byte}: damage read as a map");
                        decoded = true;
                    }
                }
            }
            std::fs::write(&path, &original).unwrap();
            // What a reader decoded it keeps; what failed it reads again.
            if !decoded {
                let read: Vec<_> = maps(&reader).into_iter().map(Result::unwrap).collect();
                assert_eq!(read, expected, "byte {byte}: put back");
            }
        }
    }
}
