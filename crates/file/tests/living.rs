//! Format 2.0: a base and segments appended by the one writer, read at every sample against
//! a table of true states; interrupted appends, open readers, and hostile roots and records.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::living::*;
use common::*;
use froctomap_core::{MortonCode, Occupancy, Timestamp, VoxelKey};
use froctomap_file::{
    encode_axis, CellState, FileError, FormatViolation, FroctReader, LivingReader, LivingWriter,
    MemorySource, ReadLimits, Root, SegmentCell, SegmentContent, LIVING_MAJOR_VERSION,
    ROOT_SLOTS_AT, ROOT_SLOT_LEN,
};
use froctomap_temporal::{ModelRegistry, TimeAxis, Toggles};
use proptest::prelude::*;
use std::sync::Arc;

fn open_bytes(bytes: &[u8], limits: ReadLimits) -> Result<LivingReader, FileError> {
    LivingReader::from_source(
        Arc::new(MemorySource::new(bytes.to_vec()).named("living.froct")),
        limits,
        &ModelRegistry::with_default_models(),
    )
}

/// Every sample's observed map, or the first error.
fn all_maps(reader: &LivingReader) -> Result<Vec<Vec<CellState>>, FileError> {
    (0..reader.sample_count())
        .map(|g| reader.observed_states(g))
        .collect()
}

/// A 2.0 file of the golden base and the first `segments` planned segments: its bytes and
/// its plans.
fn living_file(segments: usize) -> (tempfile::TempDir, std::path::PathBuf, Vec<PlannedSegment>) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("living.froct");
    let plans = write_living_golden(&path, segments);
    (dir, path, plans)
}

fn violation(err: &FileError) -> &FormatViolation {
    err.violation()
        .unwrap_or_else(|| panic!("not a format violation: {err}"))
}

#[test]
fn every_sample_reads_back_what_was_put_in() {
    let (_dir, path, plans) = living_file(3);
    let reader = LivingReader::open(&path).unwrap();
    assert_eq!(reader.header().version, (LIVING_MAJOR_VERSION, 0));
    assert_eq!(reader.segment_count(), 3);
    let expected = expected_maps(&plans);
    assert_eq!(reader.sample_count() as usize, expected.len());
    assert_eq!(all_maps(&reader).unwrap(), expected);
    // The segments' instants, off the base's grid and jittered, are kept as given.
    let mut g = golden_axis().len();
    for (k, plan) in plans.iter().enumerate() {
        assert_eq!(reader.segment_axis(k).unwrap(), (g, &plan.axis));
        for j in 0..plan.axis.len() {
            assert_eq!(reader.sample_time(g + j), plan.axis.time(j));
            assert_eq!(reader.is_missing(g + j), plan.axis.is_missing(j));
        }
        g += plan.axis.len();
    }
    assert!(reader.observed_states(g).unwrap().is_empty());
    assert_eq!(reader.last_instant(), plans[2].axis.end());
    // Instants map to the last sample with a map at or before them, across the seams.
    for sample in 0..g {
        let t = reader.sample_time(sample).unwrap();
        let present = (0..=sample).rev().find(|&s| !reader.is_missing(s));
        assert_eq!(reader.sample_at_or_before(t), present, "sample {sample}");
        assert_eq!(reader.sample_at_or_before(Timestamp(t.0 + 1)), present);
    }
    assert_eq!(
        reader.sample_at_or_before(Timestamp(golden_axis().start().0 - 1)),
        None
    );
    assert_eq!(reader.sample_at_or_before(Timestamp(i64::MAX)), Some(g - 1));
    // The segment cells read back as written.
    let base_cells = all_cells(reader.base());
    let cells = segment_cells(&plans[1], reader.base(), &base_cells);
    let read: Vec<SegmentCell> = (0..reader.segment_tiles(1).len())
        .flat_map(|t| reader.read_segment_tile(1, t).unwrap())
        .collect();
    assert_eq!(read, cells);
}

#[test]
fn the_predicted_map_is_the_base_models_and_the_newest_state_of_new_space() {
    let (_dir, path, plans) = living_file(3);
    let reader = LivingReader::open(&path).unwrap();
    let base = FroctReader::open(&golden_path_of("golden-v1.2.froct")).unwrap();
    let base_cells = all_cells(&base);
    let o = 32768u16;
    for hours in [0.0, 13.0, 100.0, 24.0 * 30.0 + 5.0] {
        let seconds = hours * 3600.0;
        let mut expected: Vec<CellState> = base_cells
            .iter()
            .map(|c| {
                let state = base_prediction(&base, &base_cells, c.start, seconds);
                (c.start, c.depth, state)
            })
            .collect();
        // Space only segments saw: the newest segment's usual state (segment 2 saw the
        // new voxel beside the door occupied, segment 1 free).
        assert_eq!(plans.len(), 3);
        expected.push((VoxelKey::new(o + 6, o, o).morton(), 16, Occupancy::Occupied));
        expected.push((
            VoxelKey::new(o + 100, o, o).morton(),
            16,
            Occupancy::Occupied,
        ));
        expected.sort_by_key(|c| c.0);
        assert_eq!(
            reader.predicted_states(seconds).unwrap(),
            expected,
            "{hours} h"
        );
    }
    // With two segments, the newest saw that voxel free.
    let (_dir, path, _) = living_file(2);
    let reader = LivingReader::open(&path).unwrap();
    let voxel = VoxelKey::new(o + 6, o, o).morton();
    let predicted = reader.predicted_states(0.0).unwrap();
    assert!(predicted.contains(&(voxel, 16, Occupancy::Free)));
}

#[test]
fn a_reader_keeps_its_view_until_it_refreshes() {
    let (_dir, path, plans) = living_file(1);
    let expected = expected_maps(
        &golden_segment_axes()
            .iter()
            .enumerate()
            .map(|(k, axis)| golden_segment(k as u64, axis))
            .collect::<Vec<_>>(),
    );
    let mut reader = LivingReader::open(&path).unwrap();
    let before = reader.sample_count();
    assert_eq!(reader.segment_count(), plans.len());
    let axes = golden_segment_axes();
    append_planned(&path, &golden_segment(1, &axes[1]));
    // Still the state at open: the new samples do not exist for it, the old ones read the same.
    assert_eq!(reader.sample_count(), before);
    assert_eq!(reader.segment_count(), 1);
    assert!(reader.observed_states(before).unwrap().is_empty());
    assert_eq!(all_maps(&reader).unwrap(), expected[..before as usize]);
    assert!(reader.refresh().unwrap());
    assert!(!reader.refresh().unwrap());
    assert_eq!(reader.segment_count(), 2);
    let now = reader.sample_count() as usize;
    assert_eq!(all_maps(&reader).unwrap(), expected[..now]);
    append_planned(&path, &golden_segment(2, &axes[2]));
    assert!(reader.refresh().unwrap());
    assert_eq!(all_maps(&reader).unwrap(), expected);
}

#[test]
fn one_writer_at_a_time() {
    let (_dir, path, _) = living_file(0);
    let writer = LivingWriter::open(&path).unwrap();
    let err = LivingWriter::open(&path).unwrap_err();
    assert!(matches!(err, FileError::Locked { .. }), "{err}");
    assert!(err.to_string().contains("living.froct"), "{err}");
    // Converting over a file a writer holds would take it from under the writer.
    let err = LivingWriter::convert(&golden_path_of("golden-v1.2.froct"), &path).unwrap_err();
    assert!(matches!(err, FileError::Locked { .. }), "{err}");
    drop(writer);
    let _again = LivingWriter::open(&path).unwrap();
}

#[test]
fn segments_follow_the_last_sample() {
    let (_dir, path, _) = living_file(1);
    let mut writer = LivingWriter::open(&path).unwrap();
    let last = golden_segment_axes()[0].end();
    for start in [last, Timestamp(last.0 - 1), golden_axis().start()] {
        let axis = TimeAxis::regular(start, 1_000_000_000, 3, vec![]).unwrap();
        let err = writer.begin_segment(axis).unwrap_err();
        assert!(matches!(err, FileError::SegmentTime { .. }), "{err}");
    }
    // One nanosecond later is fine, and an empty segment (no map observed anything) too.
    let axis = TimeAxis::regular(Timestamp(last.0 + 1), 1_000_000_000, 3, vec![]).unwrap();
    let root = writer.begin_segment(axis).unwrap().commit().unwrap();
    assert_eq!(root.segment_count, 2);
    let reader = LivingReader::open(&path).unwrap();
    let g = reader.sample_count() - 1;
    assert!(reader.observed_states(g).unwrap().is_empty());
}

#[test]
fn each_major_version_is_read_by_its_own_reader() {
    let (_dir, path, _) = living_file(1);
    let err = FroctReader::open(&path).unwrap_err();
    assert!(
        matches!(
            violation(&err),
            FormatViolation::UnsupportedVersion {
                major: 2,
                supported: 1,
                ..
            }
        ),
        "{err}"
    );
    let err = LivingReader::open(&golden_path_of("golden-v1.2.froct")).unwrap_err();
    assert!(
        matches!(
            violation(&err),
            FormatViolation::UnsupportedVersion {
                major: 1,
                supported: 2,
                ..
            }
        ),
        "{err}"
    );
}

/// The root slot a commit wrote: the one whose bytes differ between two files.
fn written_slot(before: &[u8], after: &[u8]) -> std::ops::Range<usize> {
    (0..2)
        .map(|s| {
            let at = ROOT_SLOTS_AT as usize + s * ROOT_SLOT_LEN;
            at..at + ROOT_SLOT_LEN
        })
        .find(|r| before[r.clone()] != after[r.clone()])
        .unwrap()
}

#[test]
fn an_append_interrupted_at_any_instant_leaves_exactly_the_committed_segments() {
    let (dir, path, plans) = living_file(2);
    let committed = std::fs::read(&path).unwrap();
    let committed_root = LivingReader::open(&path).unwrap().root();
    let axes = golden_segment_axes();
    let third = golden_segment(2, &axes[2]);
    let new_root = append_planned(&path, &third);
    let appended = std::fs::read(&path).unwrap();
    let expected = expected_maps(&[plans.clone(), vec![third.clone()]].concat());
    let slot = written_slot(&committed, &appended);
    let sees = |bytes: &[u8]| {
        let reader = open_bytes(bytes, ReadLimits::default()).unwrap();
        assert_eq!(
            all_maps(&reader).unwrap(),
            expected[..reader.sample_count() as usize]
        );
        reader.root()
    };
    // The commit writes the tail (tiles, record), syncs, then the slot: a crash while the
    // tail is written leaves any prefix of it, the slot untouched.
    let tail = committed.len()..appended.len();
    let mut crashed = Vec::new();
    for cut in tail.clone() {
        let mut bytes = committed.clone();
        bytes.extend_from_slice(&appended[committed.len()..cut]);
        assert_eq!(sees(&bytes), committed_root, "cut at {cut}");
        if cut % 97 == 0 || cut == tail.end - 1 {
            crashed.push(bytes);
        }
    }
    // Then the slot is written: torn at any byte, or garbled, it is not valid, and the
    // other slot is current.
    let mut rng = Lcg(3);
    for torn in 0..=ROOT_SLOT_LEN {
        let mut bytes = appended.clone();
        bytes[slot.start + torn..slot.end].copy_from_slice(&committed[slot.start + torn..slot.end]);
        let root = sees(&bytes);
        assert_eq!(
            root,
            if torn == ROOT_SLOT_LEN {
                new_root
            } else {
                committed_root
            }
        );
        for b in &mut bytes[slot.start..slot.start + torn] {
            *b = rng.next() as u8;
        }
        if torn > 0 {
            assert_eq!(sees(&bytes), committed_root, "garbled {torn}");
        }
    }
    // The next writer cuts what the crash left and commits the same segment again: the file
    // is then byte for byte what the uninterrupted append wrote.
    for (n, bytes) in crashed.into_iter().enumerate() {
        let again = dir.path().join(format!("crashed-{n}.froct"));
        std::fs::write(&again, &bytes).unwrap();
        append_planned(&again, &third);
        assert!(std::fs::read(&again).unwrap() == appended, "crash {n}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn bytes_past_the_committed_length_are_never_read(
        garbage in proptest::collection::vec(any::<u8>(), 0..3000),
    ) {
        let (_dir, path, plans) = living_file(1);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes.extend_from_slice(&garbage);
        let reader = open_bytes(&bytes, ReadLimits::default()).unwrap();
        prop_assert_eq!(reader.segment_count(), 1);
        prop_assert_eq!(all_maps(&reader).unwrap(), expected_maps(&plans));
    }
}

/// Offsets of the newest segment's record: its start and its body length.
fn newest_record(bytes: &[u8]) -> (usize, usize) {
    let reader = open_bytes(bytes, ReadLimits::default()).unwrap();
    let at = reader.root().last_segment as usize;
    let body = u32::from_le_bytes(bytes[at + 20..at + 24].try_into().unwrap()) as usize;
    (at, body)
}

/// One past the base's footer.
fn reader_base_end(bytes: &[u8]) -> usize {
    open_bytes(bytes, ReadLimits::default())
        .unwrap()
        .root()
        .base_len as usize
}

fn reseal_record(bytes: &mut [u8], at: usize, body: usize) {
    let crc = crc32c::crc32c(&bytes[at..at + 24 + body]);
    bytes[at + 24 + body..at + 28 + body].copy_from_slice(&crc.to_le_bytes());
}

/// The newest record (at `at`, body length `body`) re-framed as its bytes up to `keep`
/// followed by `tail`: body length, record checksum and the root's committed length
/// recomputed.
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

/// Rewrites the current root slot with `patch` applied to it, checksum recomputed.
fn patch_root(bytes: &mut [u8], patch: impl FnOnce(&mut Root)) {
    let reader = open_bytes(bytes, ReadLimits::default()).unwrap();
    let mut root = reader.root();
    patch(&mut root);
    let at = (0..2)
        .map(|s| ROOT_SLOTS_AT as usize + s * ROOT_SLOT_LEN)
        .find(|&at| {
            u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) == reader.root().sequence
        })
        .unwrap();
    let le = |v: u64| v.to_le_bytes();
    bytes[at..at + 8].copy_from_slice(&le(root.sequence));
    bytes[at + 8..at + 16].copy_from_slice(&le(root.committed_len));
    bytes[at + 16..at + 24].copy_from_slice(&le(root.base_len));
    bytes[at + 24..at + 32].copy_from_slice(&le(root.last_segment));
    bytes[at + 32..at + 36].copy_from_slice(&root.segment_count.to_le_bytes());
    bytes[at + 36..at + 40].copy_from_slice(&root.sample_count.to_le_bytes());
    let crc = crc32c::crc32c(&bytes[at..at + 60]);
    bytes[at + 60..at + 64].copy_from_slice(&crc.to_le_bytes());
}

type RootPatch = Box<dyn Fn(&mut Root)>;
type ViolationCheck = Box<dyn Fn(&FormatViolation) -> bool>;

fn assert_violation(bytes: &[u8], limits: ReadLimits, check: impl Fn(&FormatViolation) -> bool) {
    let err = open_bytes(bytes, limits).unwrap_err();
    assert!(check(violation(&err)), "{err}");
    assert!(err.to_string().starts_with("living.froct: "), "{err}");
}

#[test]
fn resealed_hostile_roots_are_typed_errors() {
    let (_dir, path, _) = living_file(2);
    let bytes = std::fs::read(&path).unwrap();
    let limit = |what: &str| {
        let what = what.to_string();
        move |v: &FormatViolation| matches!(v, FormatViolation::Limit { what: w, .. } if *w == what)
    };
    let corrupt = |v: &FormatViolation| matches!(v, FormatViolation::Corrupt { .. });
    let cases: Vec<(RootPatch, ViolationCheck)> = vec![
        (
            Box::new(|r| r.segment_count = u32::MAX),
            Box::new(limit("segments")),
        ),
        (Box::new(|r| r.segment_count = 1000), Box::new(corrupt)),
        (Box::new(|r| r.segment_count = 1), Box::new(corrupt)),
        (Box::new(|r| r.segment_count = 0), Box::new(corrupt)),
        (Box::new(|r| r.committed_len += 1), Box::new(corrupt)),
        (Box::new(|r| r.committed_len -= 1), Box::new(corrupt)),
        (Box::new(|r| r.committed_len = u64::MAX), Box::new(corrupt)),
        (Box::new(|r| r.base_len = 3), Box::new(corrupt)),
        (Box::new(|r| r.base_len += 8), Box::new(corrupt)),
        (Box::new(|r| r.last_segment = 0), Box::new(corrupt)),
        (Box::new(|r| r.last_segment += 1), Box::new(corrupt)),
        (
            Box::new(|r| r.last_segment = u64::MAX - 8),
            Box::new(corrupt),
        ),
        (Box::new(|r| r.sample_count += 1), Box::new(corrupt)),
        (
            Box::new(|r| r.sample_count = u32::MAX),
            Box::new(limit("sample count")),
        ),
    ];
    for (n, (patch, check)) in cases.into_iter().enumerate() {
        let mut hostile = bytes.clone();
        patch_root(&mut hostile, patch);
        let err = open_bytes(&hostile, ReadLimits::default()).unwrap_err();
        assert!(check(violation(&err)), "case {n}: {err}");
    }
}

/// The newest segment record of a two-segment living file, to patch and reseal.
struct NewestRecord {
    _dir: tempfile::TempDir,
    bytes: Vec<u8>,
    /// Where the record starts.
    at: usize,
    /// Its body length.
    body: usize,
    /// The length of the second segment's encoded axis.
    axis_len: usize,
}

impl NewestRecord {
    fn of_living_file() -> Self {
        let (dir, path, plans) = living_file(2);
        let bytes = std::fs::read(&path).unwrap();
        let (at, body) = newest_record(&bytes);
        let axis_len = encode_axis(&plans[1].axis).len();
        Self {
            _dir: dir,
            bytes,
            at,
            body,
            axis_len,
        }
    }

    /// The file with `patch` applied and the record's checksum recomputed.
    fn patched(&self, patch: &dyn Fn(&mut Vec<u8>)) -> Vec<u8> {
        let mut hostile = self.bytes.clone();
        patch(&mut hostile);
        reseal_record(&mut hostile, self.at, self.body);
        hostile
    }
}

fn set32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn set64(b: &mut [u8], at: usize, v: u64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

fn is_corrupt(v: &FormatViolation) -> bool {
    matches!(v, FormatViolation::Corrupt { .. })
}

/// A check that the violation is the limit on `what`.
fn is_limit(what: &'static str) -> impl Fn(&FormatViolation) -> bool {
    move |v| matches!(v, FormatViolation::Limit { what: w, .. } if *w == what)
}

#[test]
fn resealed_hostile_segment_record_chains_are_typed_errors() {
    let record = NewestRecord::of_living_file();
    let at = record.at;
    // The chain: previous record, first sample.
    for patch in [
        &(|b: &mut Vec<u8>| set64(b, at + 8, at as u64)) as &dyn Fn(&mut Vec<u8>),
        &|b| set64(b, at + 8, 0),
        &|b| set64(b, at + 8, 1 << 40),
        &|b| set32(b, at + 16, 0),
        &|b| b[at] = b'X',
    ] {
        assert_violation(&record.patched(patch), ReadLimits::default(), is_corrupt);
    }
}

#[test]
fn hostile_segment_record_lengths_and_counts_are_typed_errors() {
    let record = NewestRecord::of_living_file();
    let NewestRecord {
        ref bytes,
        at,
        body,
        axis_len,
        ..
    } = record;
    // Counts and lengths: the body length, the axis piece, the tile count.
    let mut huge_body = bytes.clone();
    set32(&mut huge_body, at + 20, u32::MAX - 64);
    assert_violation(
        &huge_body,
        ReadLimits::default(),
        is_limit("segment index bytes"),
    );
    // Within the limit, but past the committed bytes.
    set32(&mut huge_body, at + 20, 1 << 20);
    assert_violation(&huge_body, ReadLimits::default(), is_corrupt);
    // The segment indexes, summed, count against the index limit (the base's index on its
    // own).
    let first = u64::from_le_bytes(bytes[at + 8..at + 16].try_into().unwrap()) as usize;
    let first_body = u32::from_le_bytes(bytes[first + 20..first + 24].try_into().unwrap());
    let base_index = u64::from_le_bytes(
        bytes[reader_base_end(bytes) - 24..reader_base_end(bytes) - 16]
            .try_into()
            .unwrap(),
    );
    let limit = base_index.max(u64::from(first_body)).max(body as u64);
    assert!(limit < u64::from(first_body) + body as u64);
    let small = ReadLimits {
        max_index_bytes: limit,
        ..ReadLimits::DEFAULT
    };
    assert_violation(bytes, small, is_limit("segment index bytes"));
    let tiles_at = at + 24 + axis_len;
    assert_violation(
        &record.patched(&|b| set32(b, tiles_at, u32::MAX)),
        ReadLimits::default(),
        is_limit("tile count"),
    );
    assert_violation(
        &record.patched(&|b| set32(b, tiles_at, 1000)),
        ReadLimits::default(),
        is_corrupt,
    );
}

#[test]
fn hostile_segment_record_axes_are_typed_errors() {
    let record = NewestRecord::of_living_file();
    let at = record.at;
    // The segment's axis (explicit instants: kind, count, first instant, differences):
    // 2^31 samples, or starting before the previous segment ended.
    assert_eq!(
        record.bytes[at + 24],
        1,
        "the second segment's instants are explicit"
    );
    assert_violation(
        &record.patched(&|b| set32(b, at + 25, 1 << 31)),
        ReadLimits::default(),
        is_limit("sample count"),
    );
    let start = golden_axis().start().0 as u64;
    assert_violation(
        &record.patched(&|b| set64(b, at + 29, start)),
        ReadLimits::default(),
        is_corrupt,
    );
    let blocks = ReadLimits {
        max_toggle_blocks: 1,
        ..ReadLimits::DEFAULT
    };
    assert_violation(&record.bytes, blocks, |v| {
        matches!(
            v,
            FormatViolation::Limit {
                what: "toggle blocks",
                ..
            }
        )
    });
}

#[test]
fn damaged_roots_and_records_never_give_a_wrong_map() {
    let (_dir, path, _plans) = living_file(2);
    let bytes = std::fs::read(&path).unwrap();
    let reader = open_bytes(&bytes, ReadLimits::default()).unwrap();
    let expected = all_maps(&reader).unwrap();
    let (newest, _) = newest_record(&bytes);
    // Both root slots, and every record byte of the newest segment.
    let slots = ROOT_SLOTS_AT as usize..ROOT_SLOTS_AT as usize + 2 * ROOT_SLOT_LEN;
    for at in slots.chain(newest..bytes.len()) {
        let mut damaged = bytes.clone();
        damaged[at] ^= 0x40;
        match open_bytes(&damaged, ReadLimits::default()) {
            Ok(reader) => {
                // Damage to the slot that is not current, or to the current one: the other
                // slot's commit, whole.
                assert!(
                    slots_contain(at),
                    "byte {at} damaged and the file still opened"
                );
                let n = reader.sample_count() as usize;
                assert_eq!(all_maps(&reader).unwrap(), expected[..n], "byte {at}");
            }
            Err(err) => {
                assert!(err.violation().is_some(), "byte {at}: {err}");
            }
        }
    }
}

fn slots_contain(at: usize) -> bool {
    (ROOT_SLOTS_AT as usize..ROOT_SLOTS_AT as usize + 2 * ROOT_SLOT_LEN).contains(&at)
}

#[test]
fn an_inherited_cell_outside_the_base_is_a_typed_error() {
    let (_dir, path, _) = living_file(0);
    let mut writer = LivingWriter::open(&path).unwrap();
    let axis = golden_segment_axes()[0].clone();
    let mut segment = writer.begin_segment(axis).unwrap();
    let nowhere = VoxelKey::new(1000, 1000, 1000).morton();
    let orphan = SegmentCell {
        start: nowhere,
        depth: 16,
        mask: None,
        content: SegmentContent::Inherited {
            outliers: Toggles::empty(),
        },
    };
    // The checked path refuses it before writing.
    let err = segment.push_tile([orphan.clone()]).unwrap_err();
    assert!(
        matches!(violation(&err), FormatViolation::Corrupt { detail, .. }
            if detail.contains("inside no base cell")),
        "{err}"
    );
    // A cell that splits a base cell is fine (the door's neighbour block, depth 14 → 16).
    let o = 32768u16;
    let split = SegmentCell {
        start: VoxelKey::new(o + 1, o + 1, o + 1).morton(),
        ..orphan.clone()
    };
    // The unchecked path writes it (its tile comes first in Morton order); readers report it.
    let mut encoder = segment.tile_encoder();
    encoder.push(orphan).unwrap();
    segment.write_tile(&encoder.finish().unwrap()).unwrap();
    segment.push_tile([split.clone()]).unwrap();
    segment.commit().unwrap();
    let reader = LivingReader::open(&path).unwrap();
    let g = golden_axis().len();
    let mut split_state = Vec::new();
    reader
        .visit_observed_states(g, 1, |start, depth, state| {
            split_state.push((start, depth, state))
        })
        .unwrap();
    // The block (o, o, o) at depth 14 is free throughout the base: so is its piece.
    assert_eq!(split_state, vec![(split.start, 16, Occupancy::Free)]);
    for err in [
        reader.observed_states(g).unwrap_err(),
        reader.predicted_states(0.0).unwrap_err(),
    ] {
        assert!(
            matches!(violation(&err), FormatViolation::Corrupt { what: "segment tile", detail }
                if detail.contains("inside no base cell")),
            "{err}"
        );
    }
    let _: MortonCode = nowhere;
}

#[test]
fn files_of_every_1x_layout_convert_in_place_and_grow() {
    for name in ["golden-v1.0.froct", "golden-v1.1.froct"] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("upgraded.froct");
        std::fs::copy(golden_path_of(name), &path).unwrap();
        let root = LivingWriter::convert(&path, &path).unwrap();
        assert_eq!(root.segment_count, 0);
        assert_eq!(root.committed_len, std::fs::metadata(&path).unwrap().len());
        let reader = LivingReader::open(&path).unwrap();
        let original = FroctReader::open(&golden_path_of(name)).unwrap();
        assert_eq!(reader.header().toggles, original.header().toggles, "{name}");
        assert_eq!(reader.header().version, (LIVING_MAJOR_VERSION, 0));
        assert_eq!(all_cells(reader.base()), all_cells(&original), "{name}");
        assert_eq!(all_maps(&reader).unwrap(), expected_maps(&[]), "{name}");
        // No temporary file is left beside it.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        // Segments take the base's toggle layout (whole lists, or blocks in columns).
        let plans: Vec<_> = golden_segment_axes()
            .iter()
            .enumerate()
            .map(|(k, axis)| golden_segment(k as u64, axis))
            .collect();
        for plan in &plans {
            append_planned(&path, plan);
        }
        let reader = LivingReader::open(&path).unwrap();
        assert_eq!(all_maps(&reader).unwrap(), expected_maps(&plans), "{name}");
    }
}

#[test]
fn resealed_hostile_segment_tiles_never_panic() {
    let (_dir, path, _) = living_file(2);
    let bytes = std::fs::read(&path).unwrap();
    let (at, body) = newest_record(&bytes);
    let reader = open_bytes(&bytes, ReadLimits::default()).unwrap();
    let entry = reader.segment_tiles(1)[0];
    let first = reader.segment_axis(1).unwrap().0;
    let samples = first..reader.sample_count();
    // The tile entry's crc field, inside the record's index (after the axis piece).
    let index = at + 24 + body - (reader.segment_tiles(1).len() * 40 + 4);
    let crc_at = index + 4 + 24;
    assert_eq!(
        u64::from_le_bytes(bytes[index + 4 + 8..index + 4 + 16].try_into().unwrap()),
        entry.offset
    );
    let tile = entry.offset as usize..entry.offset as usize + entry.stored_len as usize;
    for byte in tile.clone() {
        for flip in [0x01u8, 0x80] {
            let mut hostile = bytes.clone();
            hostile[byte] ^= flip;
            let crc = crc32c::crc32c(&hostile[tile.clone()]);
            hostile[crc_at..crc_at + 4].copy_from_slice(&crc.to_le_bytes());
            reseal_record(&mut hostile, at, body);
            let reader = open_bytes(&hostile, ReadLimits::default()).unwrap();
            for g in samples.clone() {
                if let Err(err) = reader.observed_states(g) {
                    assert!(err.violation().is_some(), "{err}");
                }
            }
            let _ = reader.predicted_states(0.0);
        }
    }
}

/// Recomputes the header, root slot and segment record checksums (along the chain from the
/// newer slot) where the bytes let it find them.
fn reseal_living(bytes: &mut [u8]) -> Option<()> {
    let le32 = |b: &[u8], at: usize| {
        Some(u32::from_le_bytes(
            b.get(at..at.checked_add(4)?)?.try_into().ok()?,
        ))
    };
    let le64 = |b: &[u8], at: usize| {
        Some(u64::from_le_bytes(
            b.get(at..at.checked_add(8)?)?.try_into().ok()?,
        ))
    };
    let put = |b: &mut [u8], at: usize, crc: u32| -> Option<()> {
        b.get_mut(at..at.checked_add(4)?)?
            .copy_from_slice(&crc.to_le_bytes());
        Some(())
    };
    let slots = ROOT_SLOTS_AT as usize;
    let header_at = slots + 2 * ROOT_SLOT_LEN;
    let sections = le32(bytes, 12)? as usize;
    let mut covered = bytes.get(..16)?.to_vec();
    covered.extend_from_slice(bytes.get(header_at..header_at.checked_add(sections)?)?);
    put(bytes, header_at + sections, crc32c::crc32c(&covered))?;
    let mut newest = (0u64, 0u64);
    for slot in 0..2 {
        let at = slots + slot * ROOT_SLOT_LEN;
        let crc = crc32c::crc32c(bytes.get(at..at + ROOT_SLOT_LEN - 4)?);
        put(bytes, at + ROOT_SLOT_LEN - 4, crc)?;
        let sequence = le64(bytes, at)?;
        if sequence >= newest.0 {
            newest = (sequence, le64(bytes, at + 24)?);
        }
    }
    let mut record = usize::try_from(newest.1).ok()?;
    for _ in 0..16 {
        if record == 0 {
            break;
        }
        let body = le32(bytes, record.checked_add(20)?)? as usize;
        let end = record.checked_add(24)?.checked_add(body)?;
        let crc = crc32c::crc32c(bytes.get(record..end)?);
        put(bytes, end, crc)?;
        record = usize::try_from(le64(bytes, record + 8)?).ok()?;
    }
    Some(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Random damage to the golden 2.0 file, resealed: a typed error or a reader that
    /// answers every query with a typed error or a map, never a panic or a huge allocation.
    #[test]
    fn resealed_random_damage_is_survived(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
    ) {
        let mut bytes = std::fs::read(golden_path_of("golden-v2.0.froct")).unwrap();
        for (at, value) in edits {
            let at = at.index(bytes.len());
            bytes[at] = value;
        }
        reseal_living(&mut bytes);
        let small = ReadLimits {
            max_samples: 1 << 12,
            max_tiles: 1 << 8,
            max_cells_per_tile: 1 << 12,
            max_index_bytes: 1 << 16,
            max_toggle_blocks: 1 << 10,
            max_total_cells: 1 << 14,
            max_toggles_per_tile: 1 << 16,
            max_segments: 1 << 6,
            ..ReadLimits::DEFAULT
        };
        let Ok(mut reader) = open_bytes(&bytes, small) else {
            return Ok(());
        };
        for g in 0..reader.sample_count() {
            if let Err(err) = reader.observed_states(g) {
                prop_assert!(err.violation().is_some(), "{}", err);
            }
        }
        for k in 0..reader.segment_count() {
            for t in 0..reader.segment_tiles(k).len() {
                let _ = reader.read_segment_tile(k, t);
            }
        }
        let _ = reader.predicted_states(3600.0);
        prop_assert!(!reader.refresh().unwrap());
    }
}

#[test]
fn readers_refreshing_while_a_writer_commits_see_whole_commits_only() {
    let (_dir, path, _) = living_file(0);
    let base_samples = golden_axis().len();
    let segments = 40u32;
    let voxel = |k: u32| MortonCode(0x7000_0000_0000 + u64::from(k % 5));
    let state = |k: u32| Occupancy::from(k % 3 == 0);
    let expected = |k: u32| vec![(voxel(k), 16, state(k))];
    let done = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|scope| {
        scope.spawn(|| {
            let mut writer = LivingWriter::open(&path).unwrap();
            let step = 60_000_000_000;
            let mut next = golden_axis().end().0;
            for k in 0..segments {
                next += step;
                let axis = TimeAxis::regular(Timestamp(next), step, 1, vec![]).unwrap();
                let mut segment = writer.begin_segment(axis).unwrap();
                segment
                    .push_tile([SegmentCell {
                        start: voxel(k),
                        depth: 16,
                        mask: None,
                        content: SegmentContent::Constant(state(k)),
                    }])
                    .unwrap();
                segment.commit().unwrap();
            }
            done.store(true, std::sync::atomic::Ordering::SeqCst);
        });
        for _ in 0..2 {
            scope.spawn(|| {
                let mut reader = LivingReader::open(&path).unwrap();
                let mut seen = 0;
                loop {
                    let finished = done.load(std::sync::atomic::Ordering::SeqCst);
                    reader.refresh().unwrap();
                    let count = reader.segment_count() as u32;
                    assert!(count >= seen);
                    assert_eq!(reader.sample_count(), base_samples + count);
                    for k in seen.saturating_sub(1)..count {
                        assert_eq!(
                            reader.observed_states(base_samples + k).unwrap(),
                            expected(k)
                        );
                    }
                    seen = count;
                    if finished {
                        break;
                    }
                }
                assert_eq!(seen, segments);
            });
        }
    });
}

/// The golden base converted, then one segment of `golden_segment_axes()[0]` (which has a
/// missing sample) whose only tile is a patch tile over the base's largest tile: its first
/// base cell stored occupied throughout, its second stored free and observed at sample 0
/// only, everything else left to the base from sample 1 on (the remainder's mask). Returns
/// the file and the base tile's cells.
fn patch_file() -> (
    tempfile::TempDir,
    std::path::PathBuf,
    TimeAxis,
    Vec<froctomap_file::Cell>,
) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("living.froct");
    let (axis, base_cells) = write_patch_golden(&path);
    (dir, path, axis, base_cells)
}

#[test]
fn a_patch_tile_is_its_cells_and_the_base_predictions_elsewhere() {
    let (_dir, path, axis, base_cells) = patch_file();
    let reader = LivingReader::open(&path).unwrap();
    assert!(reader.is_patch_tile(0, 0));
    let base = reader.base();
    let first = base.header().axis.len();
    let origin = base.header().axis.start();
    assert!((0..axis.len()).any(|j| axis.is_missing(j)));
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
        if j == 0 {
            // The remainder is not observed at sample 0.
            expected.push((base_cells[1].start, base_cells[1].depth, Occupancy::Free));
            assert_eq!(got, expected, "sample {j}");
            continue;
        }
        for cell in &base_cells[2..] {
            let state = base_prediction(base, &base_cells, cell.start, seconds);
            expected.push((cell.start, cell.depth, state));
        }
        assert_eq!(got, expected, "sample {j}");
    }
    // Read whole: the stored cells and the rest of the base tile as inherited cells.
    let cells = reader.read_segment_tile(0, 0).unwrap();
    assert_eq!(cells.len(), base_cells.len());
    assert!(cells[2..].iter().all(|c| {
        matches!(&c.content, SegmentContent::Inherited { outliers } if outliers.is_empty())
            && c.mask.as_deref().map(Toggles::as_slice) == Some(&[1][..])
    }));
    assert_eq!(
        reader.remainder_mask(0, 0).unwrap(),
        Some(Some(Arc::new(Toggles::new(vec![1]).unwrap())))
    );
    // A patch tile needs a base tile with its code.
    let mut writer = LivingWriter::open(&path).unwrap();
    let next = Timestamp(reader.last_instant().0 + 1_000_000_000);
    let mut segment = writer
        .begin_segment(TimeAxis::regular(next, 1_000_000_000, 1, vec![]).unwrap())
        .unwrap();
    let mut encoder = segment.tile_encoder();
    let far = VoxelKey::new(1000, 1000, 1000).morton();
    assert!(reader.base().tile_containing(far).is_none());
    encoder
        .push(SegmentCell {
            start: far,
            depth: 16,
            mask: None,
            content: SegmentContent::Constant(Occupancy::Occupied),
        })
        .unwrap();
    let err = segment
        .write_patch_tile(&encoder.finish().unwrap(), None)
        .unwrap_err();
    // The encoder's refusal is the cause of the error naming the file: printed once after it.
    assert_eq!(froctomap_core::said_twice(&err), None, "{err:?}");
    let message = froctomap_core::error_message(&err);
    assert!(
        message.starts_with(&format!("{}: ", path.display()))
            && message.contains("has no base tile"),
        "{message}"
    );
}

#[test]
fn an_empty_remainder_mask_is_refused_by_the_writer() {
    let (_dir, path, _, base_cells) = patch_file();
    let before = std::fs::read(&path).unwrap();
    let mut writer = LivingWriter::open(&path).unwrap();
    let next = Timestamp(writer.reader().last_instant().0 + 1_000_000_000);
    let mut segment = writer
        .begin_segment(TimeAxis::regular(next, 1_000_000_000, 2, vec![]).unwrap())
        .unwrap();
    let mut encoder = segment.tile_encoder();
    encoder
        .push(stored_constant(&base_cells[0], Occupancy::Occupied))
        .unwrap();
    let err = segment
        .write_patch_tile(&encoder.finish().unwrap(), Some(Arc::new(Toggles::empty())))
        .unwrap_err();
    assert!(
        matches!(
            &err,
            FileError::TileEncode {
                source: froctomap_file::TileEncodeError::EmptyRemainderMask { .. },
                ..
            }
        ),
        "{err}"
    );
    drop(segment);
    drop(writer);
    // Nothing committed: the file reads as before.
    let reader = LivingReader::open(&path).unwrap();
    assert_eq!(reader.segment_count(), 1);
    assert_eq!(std::fs::read(&path).unwrap().len(), before.len());
}

#[test]
fn resealed_patch_tile_mask_whose_gap_overflows_is_a_typed_error() {
    let (_dir, path, _, _) = patch_file();
    let bytes = std::fs::read(&path).unwrap();
    let (at, body) = newest_record(&bytes);
    let section = at + 24 + body - 13;
    assert_eq!(bytes[section..section + 8], [0x01, 0x02, 1, 0, 5, 0, 0, 0]);
    // The same run, then a mask of two positions: 0, then a gap of u64::MAX (wraps to 0).
    let mut payload = vec![1u8, 0, 1, 2, 0];
    payload.extend_from_slice(&[0xFF; 9]);
    payload.push(0x01);
    let mut tail = bytes[section..section + 4].to_vec();
    tail.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    tail.extend_from_slice(&payload);
    let hostile = reframed(&bytes, at, section, &tail);
    assert_violation(&hostile, ReadLimits::default(), |v| {
        matches!(v, FormatViolation::Corrupt { .. })
    });
}

#[test]
fn a_patch_tile_whose_remainder_expands_past_the_cell_limit_is_refused() {
    // Single voxels stored at the start of coarse base cells: each leaves the rest of its
    // base cell to the remainder, dozens of aligned nodes per stored voxel.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("living.froct");
    LivingWriter::convert(&golden_path_of("golden-v1.2.froct"), &path).unwrap();
    let mut writer = LivingWriter::open(&path).unwrap();
    let base = writer.reader().base();
    let (base_cells, coarse) = (0..base.tiles().len())
        .map(|t| {
            let cells = base.read_tile(t).unwrap();
            let coarse: Vec<_> = cells.iter().filter(|c| c.depth < 16).cloned().collect();
            (cells, coarse)
        })
        .max_by_key(|(_, coarse)| coarse.len())
        .unwrap();
    assert!(!coarse.is_empty(), "the golden base has coarse cells");
    let mut segment = writer
        .begin_segment(golden_segment_axes()[0].clone())
        .unwrap();
    let mut encoder = segment.tile_encoder();
    for cell in &coarse {
        encoder
            .push(SegmentCell {
                start: cell.start,
                depth: 16,
                mask: None,
                content: SegmentContent::Constant(Occupancy::Occupied),
            })
            .unwrap();
    }
    segment
        .write_patch_tile(&encoder.finish().unwrap(), None)
        .unwrap();
    segment.commit().unwrap();
    drop(writer);
    let bytes = std::fs::read(&path).unwrap();
    let expanded = open_bytes(&bytes, ReadLimits::default())
        .unwrap()
        .read_segment_tile(0, 0)
        .unwrap()
        .len() as u64;
    // Every coarse cell splits into at least 2 nodes besides its stored voxel.
    let stored = coarse.len() as u64;
    let untouched = (base_cells.len() - coarse.len()) as u64;
    assert!(expanded >= untouched + 3 * stored, "{expanded}");
    // Limits the base tile and the stored cells fit in, the expansion does not.
    let limits = ReadLimits {
        max_cells_per_tile: expanded - 1,
        ..ReadLimits::DEFAULT
    };
    assert!(base_cells.len() as u64 <= limits.max_cells_per_tile);
    let reader = open_bytes(&bytes, limits).unwrap();
    let is_limit = |err: &FileError| {
        matches!(
            violation(err),
            FormatViolation::Limit { what, value, limit }
                if what.contains("remainder") && *value > *limit
        ) && err.to_string().starts_with("living.froct: ")
    };
    let err = reader.read_segment_tile(0, 0).unwrap_err();
    assert!(is_limit(&err), "{err}");
    let first = reader.base().header().axis.len();
    let err = reader.observed_states(first + 1).unwrap_err();
    assert!(is_limit(&err), "{err}");
}

#[test]
fn resealed_hostile_patch_tile_sections_are_typed_errors() {
    let (_dir, path, axis, _) = patch_file();
    let bytes = std::fs::read(&path).unwrap();
    let (at, body) = newest_record(&bytes);
    // The section closes the body: tag, flags, length 5, then runs `1, 0, 1` and the
    // remainder mask `1, 1` (one position: 1).
    let section = at + 24 + body - 13;
    assert_eq!(
        bytes[section..section + 13],
        [0x01, 0x02, 1, 0, 5, 0, 0, 0, 1, 0, 1, 1, 1]
    );
    let patched = |patch: &dyn Fn(&mut Vec<u8>)| {
        let mut hostile = bytes.clone();
        patch(&mut hostile);
        reseal_record(&mut hostile, at, body);
        hostile
    };
    let corrupt = |v: &FormatViolation| matches!(v, FormatViolation::Corrupt { .. });
    let payload = section + 8;
    // Runs past the tiles, empty, missing; a mask past the segment's samples, one
    // position too many, bytes after the mask.
    let axis_samples = u8::try_from(axis.len()).unwrap();
    for runs in [
        [1u8, 0, 2, 1, 1],
        [1, 1, 1, 1, 1],
        [1, 0, 0, 1, 1],
        [0, 0, 0, 1, 1],
        [1, 0, 1, 1, axis_samples],
        [1, 0, 1, 2, 1],
        [1, 0, 1, 0, 0],
    ] {
        assert_violation(
            &patched(&|b| b[payload..payload + 5].copy_from_slice(&runs)),
            ReadLimits::default(),
            corrupt,
        );
    }
    // More runs than tiles, and a varint running past the payload.
    assert_violation(&patched(&|b| b[payload] = 5), ReadLimits::default(), |v| {
        matches!(v, FormatViolation::Limit { .. })
    });
    assert_violation(
        &patched(&|b| b[payload + 2] = 0x80),
        ReadLimits::default(),
        |v| !matches!(v, FormatViolation::Checksum(_)),
    );
    // What the first 2.0 release does with a patch tile section: an unknown critical
    // segment record section (here 0x0203, which no release knows) is an unsupported
    // feature, never a plain tile.
    assert_violation(
        &patched(&|b| b[section] = 0x03),
        ReadLimits::default(),
        |v| matches!(v, FormatViolation::UnsupportedFeature(_)),
    );
    // The section twice: the record re-framed with a copy of it, the root's committed
    // length moved to the record's new end.
    let twice = reframed(&bytes, at, at + 24 + body, &bytes[section..section + 13]);
    assert_violation(&twice, ReadLimits::default(), corrupt);
    // A patch tile where the base has no tile: its entry's code moved past the base's last.
    let axis_len = encode_axis(&axis).len();
    let entry = at + 24 + axis_len + 4;
    let reader = open_bytes(&bytes, ReadLimits::default()).unwrap();
    let tile_size = froctomap_core::voxels_per_node(GOLDEN_TILE_DEPTH);
    let elsewhere = (0..)
        .map(|i| i * tile_size)
        .find(|&code| reader.base().tile_containing(MortonCode(code)).is_none())
        .unwrap();
    let moved = patched(&|b| b[entry..entry + 8].copy_from_slice(&elsewhere.to_le_bytes()));
    let err = open_bytes(&moved, ReadLimits::default()).unwrap_err();
    assert!(corrupt(violation(&err)), "{err}");
    assert!(err.to_string().contains("no base tile"), "{err}");
    // Cut anywhere in the segment: the file opens without it or is refused, never a panic.
    let base_end = reader_base_end(&bytes);
    for len in base_end..bytes.len() {
        match open_bytes(&bytes[..len], ReadLimits::default()) {
            Ok(reader) => assert_eq!(reader.segment_count(), 0),
            Err(err) => assert!(err.violation().is_some(), "{err}"),
        }
    }
}

/// A writer whose file was removed, or replaced by another file under its name, writes no
/// segment into it (it would be committed and lost): an error naming the path.
#[test]
fn a_writer_refuses_to_write_into_a_file_removed_or_replaced_under_it() {
    let (dir, path, _) = living_file(1);
    let axis = |writer: &LivingWriter| {
        let next = Timestamp(writer.reader().last_instant().0 + 1_000_000_000);
        TimeAxis::regular(next, 1_000_000_000, 1, vec![]).unwrap()
    };
    // Replaced: a copy renamed over the name.
    let mut writer = LivingWriter::open(&path).unwrap();
    let copy = dir.path().join("copy.froct");
    std::fs::copy(&path, &copy).unwrap();
    std::fs::rename(&copy, &path).unwrap();
    let err = writer.begin_segment(axis(&writer)).unwrap_err();
    assert!(matches!(err, FileError::Replaced { .. }), "{err}");
    assert!(err.to_string().contains("living.froct"), "{err}");
    drop(writer);
    // Removed.
    let mut writer = LivingWriter::open(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    let err = writer.begin_segment(axis(&writer)).unwrap_err();
    assert!(
        matches!(&err, FileError::Io { path: named, source } if named == &path
            && source.kind() == std::io::ErrorKind::NotFound),
        "{err}"
    );
}
