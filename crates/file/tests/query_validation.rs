//! Every query path validates what it reads as the full walk (`read_tile`, what `info`
//! does) validates it: on resealed hostile files (every checksum recomputed), a query at
//! one sample or a prediction either fails with a typed error naming the file, or returns
//! exactly what the full walk of the same file decodes (or, where the full walk refuses
//! damage the query does not read, what the intact file holds). Never a different map.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::resealed::*;
use common::*;
use froctomap_core::{log_odds, Leaf};
use froctomap_file::{Cell, FileError, FroctReader, MemorySource, ReadLimits, ToggleLayout};
use froctomap_temporal::ModelRegistry;

const LAYOUTS: [ToggleLayout; 3] = [
    ToggleLayout::Whole,
    ToggleLayout::Blocked(16),
    ToggleLayout::Coded(16),
];
const NAME: &str = "resealed.froct";
/// Instants predicted, in seconds since the first sample.
const PREDICTED: [f64; 3] = [0.0, 7200.5, 1.0e6];

fn open_bytes(bytes: &[u8]) -> Result<FroctReader, FileError> {
    FroctReader::from_source(
        MemorySource::new(bytes.to_vec()).named(NAME),
        ReadLimits::default(),
        &ModelRegistry::with_default_models(),
    )
}

fn assert_names_the_file(err: &FileError, what: &str) {
    assert!(err.to_string().contains(NAME), "{what}: {err}");
}

/// The leaves the full walk's cells give at `sample`.
fn observed_from(reader: &FroctReader, cells: &[Cell], sample: u32) -> Vec<Leaf> {
    let axis = &reader.header().axis;
    cells
        .iter()
        .filter_map(|cell| {
            let state = cell.state_at(axis, reader.model(), sample)?;
            Some(Leaf {
                start: cell.start,
                depth: cell.depth,
                log_odds: state.log_odds(),
            })
        })
        .collect()
}

fn predicted_from(reader: &FroctReader, cells: &[Cell], seconds: f64) -> Vec<Leaf> {
    cells
        .iter()
        .map(|cell| Leaf {
            start: cell.start,
            depth: cell.depth,
            log_odds: log_odds(cell.probability(reader.model(), seconds)),
        })
        .collect()
}

/// Checks every query path of every tile of `bytes` against the full walk; returns how
/// many queries failed (with a typed error naming the file).
fn check_queries(bytes: &[u8], intact: &FroctReader, what: &str) -> usize {
    let reader = match open_bytes(bytes) {
        Ok(reader) => reader,
        Err(err) => {
            assert_names_the_file(&err, what);
            return 1;
        }
    };
    let samples = reader.header().axis.len();
    let mut failed = 0;
    for tile in 0..reader.tiles().len() {
        // What the query must give: the full walk's cells where it accepts the tile, else
        // the intact tile's (the damage lies where the query does not read).
        let (full, oracle) = match reader.read_tile(tile) {
            Ok(cells) => (true, cells),
            Err(err) => {
                assert_names_the_file(&err, what);
                (false, intact.read_tile(tile).unwrap())
            }
        };
        let oracle_reader = if full { &reader } else { intact };
        for sample in 0..samples + 2 {
            let mut leaves = Vec::new();
            match reader.observed_leaves(tile, sample, &mut leaves) {
                Ok(()) => assert_eq!(
                    leaves,
                    observed_from(oracle_reader, &oracle, sample),
                    "{what}: tile {tile} at sample {sample} (full walk accepts: {full})"
                ),
                Err(err) => {
                    assert_names_the_file(&err, what);
                    failed += 1;
                }
            }
        }
        for seconds in PREDICTED {
            let mut leaves = Vec::new();
            match reader.predicted_leaves(tile, seconds, &|p| log_odds(p), &mut leaves) {
                Ok(()) => assert_eq!(
                    leaves,
                    predicted_from(oracle_reader, &oracle, seconds),
                    "{what}: tile {tile} predicted at {seconds} s (full walk accepts: {full})"
                ),
                Err(err) => {
                    assert_names_the_file(&err, what);
                    failed += 1;
                }
            }
        }
    }
    failed
}

/// The hostile values given to a varint: past the axis, past u32, 2^63 (the value of the
/// attack), the largest.
const HUGE: [u64; 4] = [72, 1 << 32, 1 << 63, u64::MAX];

/// The outlier columns of every tile (and block) with one varint made huge.
fn huge_outlier_varints(bytes: &[u8], toggles: ToggleLayout) -> Vec<(String, Vec<u8>)> {
    let tiles = tiles_of(bytes, toggles);
    let mut out = Vec::new();
    for t in 0..tiles.len() {
        let (streams, blocks) = if toggles == ToggleLayout::Whole {
            (vec![WHOLE_OUTLIER_STARTS, WHOLE_OUTLIER_LENGTHS], 1)
        } else {
            (
                vec![BLOCK_OUTLIER_STARTS, BLOCK_OUTLIER_LENGTHS],
                tiles[t].frames.iter().map(Vec::len).sum(),
            )
        };
        for b in 0..blocks {
            for &stream in &streams {
                for k in 0..2 {
                    for value in HUGE {
                        let mut damaged = tiles.clone();
                        let column = match toggles {
                            ToggleLayout::Whole => &mut damaged[t].cells[stream],
                            _ => &mut damaged[t].blocks_mut().nth(b).unwrap()[stream],
                        };
                        let Some(changed) = with_varint(column, k, value) else {
                            continue;
                        };
                        *column = changed;
                        out.push((
                            format!("{toggles:?} tile {t} block {b} stream {stream} varint {k} = {value}"),
                            with_tiles(bytes, &damaged),
                        ));
                    }
                }
            }
        }
    }
    out
}

/// Class bytes given the outlier flag: every cell's, and each cell's alone.
fn outlier_flags(bytes: &[u8], toggles: ToggleLayout) -> Vec<(String, Vec<u8>)> {
    let tiles = tiles_of(bytes, toggles);
    let mut out = Vec::new();
    for t in 0..tiles.len() {
        let mut all = tiles.clone();
        for class in &mut all[t].cells[CLASS] {
            *class |= CLASS_HAS_OUTLIERS;
        }
        out.push((format!("{toggles:?} tile {t}: every class flagged"), all));
        for c in 0..tiles[t].cells[CLASS].len() {
            if tiles[t].cells[CLASS][c] & CLASS_HAS_OUTLIERS != 0 {
                continue;
            }
            let mut one = tiles.clone();
            one[t].cells[CLASS][c] |= CLASS_HAS_OUTLIERS;
            out.push((
                format!("{toggles:?} tile {t}: class of cell {c} flagged"),
                one,
            ));
        }
    }
    out.into_iter()
        .map(|(what, tiles)| (what, with_tiles(bytes, &tiles)))
        .collect()
}

/// Streams with one byte changed (a deterministic sample of positions and values).
fn changed_bytes(bytes: &[u8], toggles: ToggleLayout) -> Vec<(String, Vec<u8>)> {
    let tiles = tiles_of(bytes, toggles);
    let mut out = Vec::new();
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    for t in 0..tiles.len() {
        let parts = 1 + tiles[t].frames.iter().map(Vec::len).sum::<usize>();
        for _ in 0..150 {
            let mut damaged = tiles.clone();
            let part = next() as usize % parts;
            let streams = match part {
                0 => &mut damaged[t].cells,
                p => damaged[t].blocks_mut().nth(p - 1).unwrap(),
            };
            let stream = next() as usize % streams.len();
            if streams[stream].is_empty() {
                continue;
            }
            let at = next() as usize % streams[stream].len();
            let value = next() as u8;
            streams[stream][at] = value;
            out.push((
                format!("{toggles:?} tile {t} part {part} stream {stream} byte {at} = {value:#x}"),
                with_tiles(bytes, &damaged),
            ));
        }
    }
    out
}

#[test]
fn taking_a_raw_file_apart_and_back_changes_nothing() {
    for toggles in LAYOUTS {
        let bytes = raw_golden_file(toggles);
        assert_eq!(with_tiles(&bytes, &tiles_of(&bytes, toggles)), bytes);
    }
}

/// The attack of issue 29: a resealed 1.2 file whose outlier-length (or start) varint is
/// 2^63 was retrieved as a map with extra leaves where `info` reported the damage.
#[test]
fn a_huge_outlier_varint_is_an_error_at_every_sample_of_its_block() {
    for toggles in LAYOUTS {
        let intact = raw_golden_file(toggles);
        let tiles = tiles_of(&intact, toggles);
        let reader = open_bytes(&intact).unwrap();
        let samples = reader.header().axis.len();
        let mut attacked = 0;
        for t in 0..tiles.len() {
            let blocks: Vec<usize> = match toggles {
                ToggleLayout::Whole => vec![0],
                _ => (0..tiles[t].frames.iter().map(Vec::len).sum()).collect(),
            };
            for b in blocks {
                for stream in [WHOLE_OUTLIER_LENGTHS, WHOLE_OUTLIER_STARTS] {
                    let mut damaged = tiles.clone();
                    let column = match toggles {
                        ToggleLayout::Whole => &mut damaged[t].cells[stream],
                        _ => {
                            let block_stream = stream - WHOLE_OUTLIER_STARTS + BLOCK_OUTLIER_STARTS;
                            &mut damaged[t].blocks_mut().nth(b).unwrap()[block_stream]
                        }
                    };
                    let Some(changed) = with_varint(column, 0, 1 << 63) else {
                        continue;
                    };
                    *column = changed;
                    attacked += 1;
                    let bytes = with_tiles(&intact, &damaged);
                    let reader = open_bytes(&bytes).unwrap();
                    let err = reader.read_tile(t).unwrap_err();
                    assert!(
                        err.to_string().contains("toggle beyond the time axis"),
                        "{err}"
                    );
                    let block = match toggles.block_len() {
                        Some(len) => b as u32 * len..((b as u32 + 1) * len).min(samples),
                        None => 0..samples,
                    };
                    for sample in block {
                        let err = reader
                            .observed_leaves(t, sample, &mut Vec::new())
                            .unwrap_err();
                        assert_names_the_file(&err, "query");
                        assert!(
                            err.to_string().contains("toggle beyond the time axis"),
                            "{toggles:?} tile {t} block {b} sample {sample}: {err}"
                        );
                    }
                }
            }
        }
        assert!(attacked > 0, "{toggles:?}: the golden series has outliers");
    }
}

/// Every class byte of a tile given the outlier flag: the lists no longer match the cells.
#[test]
fn class_bytes_all_flagged_with_outliers_are_an_error_at_every_sample() {
    for toggles in LAYOUTS {
        let intact = raw_golden_file(toggles);
        let tiles = tiles_of(&intact, toggles);
        let samples = open_bytes(&intact).unwrap().header().axis.len();
        for t in 0..tiles.len() {
            let mut damaged = tiles.clone();
            for class in &mut damaged[t].cells[CLASS] {
                *class |= CLASS_HAS_OUTLIERS;
            }
            let reader = open_bytes(&with_tiles(&intact, &damaged)).unwrap();
            assert_names_the_file(&reader.read_tile(t).unwrap_err(), "full walk");
            for sample in 0..samples {
                let err = reader
                    .observed_leaves(t, sample, &mut Vec::new())
                    .expect_err(&format!("{toggles:?} tile {t} sample {sample}"));
                assert_names_the_file(&err, "query");
            }
        }
    }
}

/// The differential test of issue 29 over a corpus of resealed files.
#[test]
fn queries_on_resealed_files_error_or_agree_with_the_full_walk() {
    let mut files = 0;
    let mut failed = 0;
    for toggles in LAYOUTS {
        let bytes = raw_golden_file(toggles);
        let intact = open_bytes(&bytes).unwrap();
        let corpus = huge_outlier_varints(&bytes, toggles)
            .into_iter()
            .chain(outlier_flags(&bytes, toggles))
            .chain(changed_bytes(&bytes, toggles));
        for (what, damaged) in corpus {
            files += 1;
            failed += check_queries(&damaged, &intact, &what);
        }
    }
    assert!(files > 500, "{files} files");
    assert!(failed > 0);
}
