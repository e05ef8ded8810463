//! What an open format 2.0 reader holds does not follow what its segments' records hold: a
//! patch tile's remainder masks (FORMAT.md §10.6, §10.7) are read again when a query needs
//! them, so a file of many segments opens in memory of its segment count, not of its
//! history; and opening reads the records one at a time, so its peak does not follow them
//! either. Measured with a counting allocator (this test binary's own).
#![allow(unsafe_code, clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::living::*;
use froctomap_core::{Occupancy, Timestamp};
use froctomap_file::{LivingReader, TileRemainder};
use froctomap_temporal::TimeAxis;
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};

/// The system allocator, counting the bytes live.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
/// The most `LIVE` has been since the last reset.
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call goes to the system allocator with the caller's own arguments.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
        PEAK.fetch_max(live, Ordering::Relaxed);
        // SAFETY: as the caller's contract.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: as the caller's contract.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Held by each test for its whole run: the counters are the process's, and a test running
/// beside another would count (or free) the other's bytes.
static ALONE: Mutex<()> = Mutex::new(());

fn alone() -> MutexGuard<'static, ()> {
    ALONE
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

const SEGMENTS: usize = 32;
const SAMPLES: u32 = 4096;

/// A 2.0 file of `SEGMENTS` segments of `SAMPLES` samples, each with one patch tile whose
/// remainder mask toggles `toggles` times.
fn living_with_masks(path: &Path, toggles: u32) {
    living_with_masks_in(path, toggles, SEGMENTS);
}

/// [`living_with_masks`] of `segments` segments.
fn living_with_masks_in(path: &Path, toggles: u32, segments: usize) {
    let (mut writer, _, base_cells) = golden_base_for_a_patch(path);
    let second = 1_000_000_000;
    let positions: Vec<u32> = (0..toggles).map(|i| i * (SAMPLES / toggles)).collect();
    for _ in 0..segments {
        let start = Timestamp(writer.reader().last_instant().0 + second);
        let axis = TimeAxis::regular(start, second, SAMPLES, vec![]).unwrap();
        let mut segment = writer.begin_segment(axis).unwrap();
        let mut encoder = segment.tile_encoder();
        encoder
            .push(stored_constant(&base_cells[0], Occupancy::Occupied))
            .unwrap();
        let remainder = TileRemainder::uniform(remainder_mask(&positions));
        segment
            .write_patch_tile_with(&encoder.finish().unwrap(), remainder)
            .unwrap();
        segment.commit().unwrap();
    }
}

/// Bytes an open reader of `path` holds.
fn held(path: &Path) -> (usize, LivingReader) {
    let before = LIVE.load(Ordering::SeqCst);
    let reader = LivingReader::open(path).unwrap();
    (LIVE.load(Ordering::SeqCst).saturating_sub(before), reader)
}

/// The most bytes opening `path` took at once.
fn opening_peak(path: &Path) -> usize {
    let before = LIVE.load(Ordering::SeqCst);
    PEAK.store(before, Ordering::SeqCst);
    drop(LivingReader::open(path).unwrap());
    PEAK.load(Ordering::SeqCst).saturating_sub(before)
}

/// Opening reads a segment's record when it decodes it, not every record first: its peak
/// grows with the largest record, not with their sum (before, a file of 1,206 hour
/// segments of the generated office opened at some 290 MB).
#[test]
fn opening_reads_one_record_at_a_time() {
    let _alone = alone();
    const MANY: usize = 128;
    let dir = tempfile::tempdir().unwrap();
    let (small, large) = (
        dir.path().join("small.froct"),
        dir.path().join("large.froct"),
    );
    living_with_masks_in(&small, 2, MANY);
    living_with_masks_in(&large, SAMPLES, MANY);
    let size = |p: &Path| std::fs::metadata(p).unwrap().len() as usize;
    // What the large masks add to each record.
    let per_record = (size(&large) - size(&small)) / MANY;
    assert!(per_record > 2048, "{per_record} B a record");
    let grown = opening_peak(&large).saturating_sub(opening_peak(&small));
    // Reading them all first grows it by about MANY records.
    assert!(
        grown < 16 * per_record,
        "opening's peak grew by {grown} B with {MANY} records {per_record} B larger each"
    );
}

#[test]
fn a_reader_holds_no_segments_remainder_masks() {
    let _alone = alone();
    let dir = tempfile::tempdir().unwrap();
    let (small, large) = (
        dir.path().join("small.froct"),
        dir.path().join("large.froct"),
    );
    living_with_masks(&small, 2);
    living_with_masks(&large, 2048);
    let (bytes_small, reader_small) = held(&small);
    let (bytes_large, reader_large) = held(&large);
    assert_eq!(reader_large.segment_count(), SEGMENTS);
    // Decoded, the large masks are 2,046 more positions per segment (at least 8 KiB each):
    // what the reader holds may differ by a small part of that.
    let grown = bytes_large.saturating_sub(bytes_small);
    assert!(
        grown < SEGMENTS * 1024,
        "{bytes_large} B held with large masks, {bytes_small} B with small ones"
    );
    // And they are read when asked for, as they were written.
    for k in [0, SEGMENTS - 1] {
        let mask = reader_large.remainder_mask(k, 0).unwrap().unwrap().unwrap();
        assert_eq!(mask.len(), 2048, "segment {k}");
        assert!(reader_small.is_patch_tile(k, 0));
    }
}
