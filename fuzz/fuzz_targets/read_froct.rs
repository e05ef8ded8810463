//! The `.froct` reader on arbitrary bytes: opening, every tile read every way (whole, at
//! single samples, predicted), under small limits. Each input is read as it is and, when
//! that differs, once more with every checksum recomputed, so that mutations reach the
//! decoders behind the checksums (a checksum is not a security boundary).
#![no_main]

use froctomap_file::{FroctReader, MemorySource, ReadLimits, FOOTER_LEN, TILE_ENTRY_LEN};
use froctomap_temporal::ModelRegistry;
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

/// Small enough that no input can make one run slow or large.
const LIMITS: ReadLimits = ReadLimits {
    max_header_bytes: 1 << 16,
    max_samples: 1 << 12,
    max_model_parameter_bytes: 1 << 16,
    max_tiles: 1 << 8,
    max_tile_bytes: 1 << 20,
    max_cells_per_tile: 1 << 12,
    max_index_bytes: 1 << 16,
    max_toggle_blocks: 1 << 10,
    max_total_cells: 1 << 14,
    max_toggles_per_tile: 1 << 16,
    ..ReadLimits::DEFAULT
};

fuzz_target!(|data: &[u8]| {
    read_every_way(data);
    let mut sealed = data.to_vec();
    if reseal(&mut sealed).is_some() && sealed != data {
        read_every_way(&sealed);
    }
});

fn read_every_way(data: &[u8]) {
    static MODELS: OnceLock<ModelRegistry> = OnceLock::new();
    let models = MODELS.get_or_init(ModelRegistry::with_default_models);
    let Ok(reader) = FroctReader::from_source(MemorySource::new(data.to_vec()), LIMITS, models)
    else {
        return;
    };
    let samples = reader.header().axis.len();
    let mut leaves = Vec::new();
    for tile in 0..reader.tiles().len() {
        let whole = reader.read_tile(tile);
        for sample in [0, samples / 2, samples.saturating_sub(1), samples] {
            leaves.clear();
            let observed = reader.observed_leaves(tile, sample, &mut leaves);
            // A tile that decodes whole is readable at every sample.
            if whole.is_ok() {
                assert!(observed.is_ok(), "tile {tile} decodes whole but not at {sample}");
            }
        }
        for seconds in [0.0, 3600.0, -1e9] {
            leaves.clear();
            let _ = reader.predicted_leaves(tile, seconds, &|p| p as f32, &mut leaves);
        }
        let _ = reader.tile_streams(tile);
    }
}

/// Recomputes the header, tile, index and footer checksums where the bytes let it find
/// them (`None` when they do not).
fn reseal(bytes: &mut [u8]) -> Option<()> {
    let le32 = |b: &[u8], at: usize| Some(u32::from_le_bytes(b.get(at..at.checked_add(4)?)?.try_into().ok()?));
    let le64 = |b: &[u8], at: usize| Some(u64::from_le_bytes(b.get(at..at.checked_add(8)?)?.try_into().ok()?));
    let put = |b: &mut [u8], at: usize, crc: u32| -> Option<()> {
        b.get_mut(at..at.checked_add(4)?)?.copy_from_slice(&crc.to_le_bytes());
        Some(())
    };
    let header_end = 16usize.checked_add(le32(bytes, 12)? as usize)?;
    let crc = crc32c::crc32c(bytes.get(..header_end)?);
    put(bytes, header_end, crc)?;
    let footer = bytes.len().checked_sub(FOOTER_LEN)?;
    let index = usize::try_from(le64(bytes, footer)?).ok()?;
    let index_len = usize::try_from(le64(bytes, footer + 8)?).ok()?;
    let tiles = le32(bytes, index)? as usize;
    for t in 0..tiles.min(LIMITS.max_tiles as usize) {
        let entry = index.checked_add(4 + t * TILE_ENTRY_LEN)?;
        let offset = usize::try_from(le64(bytes, entry + 8)?).ok()?;
        let stored = le32(bytes, entry + 16)? as usize;
        let crc = crc32c::crc32c(bytes.get(offset..offset.checked_add(stored)?)?);
        put(bytes, entry + 24, crc)?;
    }
    let crc = crc32c::crc32c(bytes.get(index..index.checked_add(index_len)?)?);
    put(bytes, footer + 16, crc)?;
    let crc = crc32c::crc32c(bytes.get(footer..footer + 20)?);
    put(bytes, footer + 20, crc)
}
