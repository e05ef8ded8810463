//! What an open format 2.0 reader holds does not follow what its segments' records hold: a
//! patch tile's remainder masks (FORMAT.md §10.6, §10.7) are read again when a query needs
//! them, so a file of many segments opens in memory of its segment count, not of its
//! history. Measured with a counting allocator (this test binary's own).
#![allow(unsafe_code, clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::living::*;
use froctomap_core::{Occupancy, Timestamp};
use froctomap_file::{LivingReader, TileRemainder};
use froctomap_temporal::TimeAxis;
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The system allocator, counting the bytes live.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call goes to the system allocator with the caller's own arguments.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LIVE.fetch_add(layout.size(), Ordering::Relaxed);
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

const SEGMENTS: usize = 32;
const SAMPLES: u32 = 4096;

/// A 2.0 file of `SEGMENTS` segments of `SAMPLES` samples, each with one patch tile whose
/// remainder mask toggles `toggles` times.
fn living_with_masks(path: &Path, toggles: u32) {
    let (mut writer, _, base_cells) = golden_base_for_a_patch(path);
    let second = 1_000_000_000;
    let positions: Vec<u32> = (0..toggles).map(|i| i * (SAMPLES / toggles)).collect();
    for _ in 0..SEGMENTS {
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

#[test]
fn a_reader_holds_no_segments_remainder_masks() {
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
