//! Whole-file passes over files of huge tiles (issue 16, items 1 and 3): `describe` (the
//! `info` cell count) and `evaluate` go through one tile's cells at a time, so their memory
//! is one tile's decoded bytes per thread, not the map's cells; `export` to a format that
//! holds a whole map writes one map at a time. A file of full tiles (every
//! voxel of a depth-8 tile a cell of its own) is a few kilobytes once compressed; building
//! its cells used to cost about a hundred bytes per cell.
//!
//! One test per binary: the counting allocator sees every thread of the process.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
// The one unsafe block: a global allocator that counts bytes and delegates to the system's.
#![allow(unsafe_code)]

use froctomap_convert::{
    describe, evaluate, export, write_map, write_observed_map, Context, ExportMode, ExportOptions,
    SeriesInput, Silent,
};
use froctomap_core::{Leaf, MortonCode, Snapshot, Timestamp};
use froctomap_file::{Cell, Codec, FroctReader, Header, ToggleLayout, FOOTER_LEN, PREAMBLE_LEN};
use froctomap_formats::{ReadOptions, WriteOptions};
use froctomap_temporal::{ModelConfig, ModelRegistry, TimeAxis};
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let now = CURRENT.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
            grew(new_size);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Most bytes allocated at once while `run` ran, above what was allocated before.
fn peak_during<R>(run: impl FnOnce() -> R) -> (R, usize) {
    let before = CURRENT.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let result = run();
    (result, PEAK.load(Ordering::Relaxed).saturating_sub(before))
}

const TILE_DEPTH: u8 = 8;
const RESOLUTION: f64 = 0.1;

fn varint(out: &mut Vec<u8>, mut value: u64) {
    while value >= 0x80 {
        out.push(value as u8 | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

/// The payload (FORMAT.md §5.2, whole toggle lists) of a tile whose first `cells` voxels
/// are each a free cell observed at every sample.
fn free_voxels_payload(cells: u64) -> Vec<u8> {
    let n = cells as usize;
    let mut out = Vec::with_capacity(3 * n + 32);
    varint(&mut out, cells);
    for byte in [0u8, 16, 0] {
        // Geometry (no gaps), depths (one voxel each), classes (free, no mask or outliers).
        varint(&mut out, cells);
        out.resize(out.len() + n, byte);
    }
    // No masks (mask count 0, no refs), no mask lists, no models, no outlier lists.
    out.extend([1, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    out
}

/// A file of `tiles` depth-8 tiles of `cells` free voxels each, on a two-sample axis, in
/// format 1.0 with zstd: the header comes from the library's writer, tiles, index and footer
/// are laid out here (no summary, so that `describe` counts the cells).
fn file_of_full_tiles(path: &Path, tiles: u64, cells: u64) -> TimeAxis {
    let axis = TimeAxis::regular(
        Timestamp::from_secs(1_700_000_000),
        3_600_000_000_000,
        2,
        vec![],
    )
    .unwrap();
    let model = ModelRegistry::with_default_models()
        .by_name("fremen-periods")
        .unwrap()
        .create();
    let prepared = model.prepare(&axis, &ModelConfig::default()).unwrap();
    let mut header = Header::new(
        RESOLUTION,
        TILE_DEPTH,
        axis.clone(),
        model.id(),
        prepared.encode_parameters(),
        Codec::Zstd { level: 3 },
    );
    header.toggles = ToggleLayout::Whole;
    froctomap_file::FroctWriter::create(path, &header)
        .unwrap()
        .finish(Default::default())
        .unwrap();
    let written = std::fs::read(path).unwrap();
    let header_len = u32::from_le_bytes(written[12..16].try_into().unwrap()) as usize;
    let mut bytes = written[..PREAMBLE_LEN + header_len + 4].to_vec();

    let payload = free_voxels_payload(cells);
    let stored = zstd::bulk::compress(&payload, 3).unwrap();
    let mut index = (tiles as u32).to_le_bytes().to_vec();
    for t in 0..tiles {
        let offset = bytes.len() as u64;
        bytes.extend_from_slice(&stored);
        index.extend((t << (3 * (16 - TILE_DEPTH))).to_le_bytes());
        index.extend(offset.to_le_bytes());
        for value in [
            stored.len() as u32,
            payload.len() as u32,
            crc32c::crc32c(&stored),
            cells as u32,
            0,
            axis.len() - 1,
        ] {
            index.extend(value.to_le_bytes());
        }
    }
    let index_offset = bytes.len() as u64;
    bytes.extend_from_slice(&index);
    let mut footer = [0u8; FOOTER_LEN];
    footer[0..8].copy_from_slice(&index_offset.to_le_bytes());
    footer[8..16].copy_from_slice(&(index.len() as u64).to_le_bytes());
    footer[16..20].copy_from_slice(&crc32c::crc32c(&index).to_le_bytes());
    let crc = crc32c::crc32c(&footer[0..20]);
    footer[20..24].copy_from_slice(&crc.to_le_bytes());
    footer[24..32].copy_from_slice(&froctomap_file::END_MAGIC);
    bytes.extend_from_slice(&footer);
    std::fs::write(path, bytes).unwrap();
    axis
}

#[test]
fn counting_and_evaluating_hold_one_tile_not_the_map() {
    const TILES: u64 = 4;
    const CELLS: u64 = 1 << 20;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("full.froct");
    let axis = file_of_full_tiles(&path, TILES, CELLS);
    assert!(std::fs::metadata(&path).unwrap().len() < 64 << 10);
    let context = Context::with_default_plugins();
    let reader = FroctReader::open(&path).unwrap();

    // A bound well below one tile's cells held at once (the map's cells are four times
    // that): two threads each hold a tile's decoded bytes, three per cell.
    let bound = 24 << 20;
    assert!(CELLS as usize * std::mem::size_of::<Cell>() > bound);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();

    let (info, peak) = peak_during(|| pool.install(|| describe(&context, &reader, true)));
    let info = info.unwrap();
    assert_eq!(info.cells.static_free, TILES * CELLS);
    assert_eq!(info.voxels.total(), TILES * CELLS);
    assert!(peak < bound, "counting cells allocated {peak} bytes");

    // A ground truth: an occupied and a free voxel in the first tile (the file says free),
    // and a voxel of a tile the file does not have.
    let leaf = |code: u64, log_odds: f32| Leaf {
        start: MortonCode(code),
        depth: 16,
        log_odds,
    };
    let outside = TILES << (3 * (16 - TILE_DEPTH));
    let truth = Snapshot::from_leaves(
        RESOLUTION,
        vec![leaf(0, 2.0), leaf(1, -2.0), leaf(outside, 2.0)],
    )
    .unwrap();
    let truth_path = dir.path().join("truth.bt");
    write_map(&context, &truth, &truth_path, WriteOptions::default()).unwrap();
    let truths = [SeriesInput::new(truth_path, axis.end())];
    let (report, peak) = peak_during(|| {
        pool.install(|| evaluate(&context, &reader, &truths, ReadOptions::default(), &Silent))
    });
    let report = report.unwrap();
    assert!(peak < bound, "evaluating allocated {peak} bytes");
    assert_eq!((report.inside, report.outside), (1, 0));
    assert_eq!(report.unmodelled_voxels, 1);
    for (method, rates) in &report.reconstruction {
        // Every method says free: wrong on the occupied voxel only.
        assert_eq!((rates.all.wrong, rates.all.total), (1, 2), "{method}");
        // The free voxel is never occupied in the file nor the truth.
        assert_eq!(
            (rates.non_empty.wrong, rates.non_empty.total),
            (1, 1),
            "{method}"
        );
        assert_eq!(rates.dynamic.total, 0, "{method}");
    }

    // An export to a format that holds a whole map while writing it (`.ot`) writes one map
    // at a time: two maps cost what one does, not twice that.
    let one = dir.path().join("one.ot");
    let (written, single) = peak_during(|| {
        pool.install(|| write_observed_map(&context, &reader, 0, &one, WriteOptions::default()))
    });
    written.unwrap();
    let options = ExportOptions {
        from: axis.start(),
        to: axis.end(),
        every_ns: 3_600_000_000_000,
        mode: ExportMode::Predict,
        format: "ot".into(),
        backend: None,
        prefix: "map".into(),
        overwrite: false,
        recording: Default::default(),
    };
    let out = dir.path().join("export");
    let (report, peak) =
        peak_during(|| pool.install(|| export(&context, &reader, &out, &options, &Silent)));
    assert_eq!(report.unwrap().files.len(), 2);
    assert!(
        peak < single + single / 2,
        "exporting two maps allocated {peak} bytes, one map {single}"
    );
}
