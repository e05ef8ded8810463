//! The format 2.0 reader on arbitrary bytes: opening (root slots, the base, the segment
//! chain), observed maps at the first, middle and last samples of the base and of every
//! segment, predicted maps, every segment tile read whole (a patch tile with the parts of
//! the base tile it leaves to the base, FORMAT.md §10.6, each observed by the mask its run
//! of base cells gives, §10.7; the corpus holds `golden-v2.0-remainder.froct`), every
//! remainder's masks looked up by rank, and a refresh, under small
//! limits. Each input is read as it is and, when that differs, once more with the header,
//! root slot and segment record checksums recomputed, so that mutations reach the decoders.
#![no_main]

use froctomap_file::{LivingReader, MemorySource, ReadLimits, ROOT_SLOTS_AT, ROOT_SLOT_LEN};
use froctomap_temporal::ModelRegistry;
use libfuzzer_sys::fuzz_target;
use std::sync::{Arc, OnceLock};

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
    max_segments: 1 << 6,
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
    let source = Arc::new(MemorySource::new(data.to_vec()));
    let Ok(mut reader) = LivingReader::from_source(source, LIMITS, models) else {
        return;
    };
    let mut starts = vec![0, reader.header().axis.len()];
    for k in 0..reader.segment_count() {
        if let Some((first, axis)) = reader.segment_axis(k) {
            starts.extend([first, first + axis.len() / 2, first + axis.len()]);
        }
        for tile in 0..reader.segment_tiles(k).len() {
            // A patch tile reads as at least its stored cells.
            if let Ok(cells) = reader.read_segment_tile(k, tile) {
                if reader.is_patch_tile(k, tile) {
                    let stored = reader.segment_tiles(k)[tile].cell_count as usize;
                    assert!(cells.len() >= stored);
                }
            }
            if let Ok(Some(remainder)) = reader.remainder(k, tile) {
                // Runs name only ranks the base tile has (checked at open), so few.
                let named = remainder.ranks_named();
                assert!(named <= LIMITS.max_cells_per_tile);
                for rank in 0..u32::try_from(named).unwrap_or(0) {
                    let _ = remainder.mask_of(rank);
                }
            }
        }
    }
    for sample in starts {
        for g in [sample.saturating_sub(1), sample] {
            let _ = reader.observed_states(g);
        }
    }
    for seconds in [0.0, 3600.0, -1e9] {
        let _ = reader.predicted_states(seconds);
    }
    assert!(matches!(reader.refresh(), Ok(false) | Err(_)));
}

/// Recomputes the header checksum, both root slots' and the segment records' along the
/// chain where the bytes let it find them (`None` when they do not).
fn reseal(bytes: &mut [u8]) -> Option<()> {
    let le32 = |b: &[u8], at: usize| {
        Some(u32::from_le_bytes(b.get(at..at.checked_add(4)?)?.try_into().ok()?))
    };
    let le64 = |b: &[u8], at: usize| {
        Some(u64::from_le_bytes(b.get(at..at.checked_add(8)?)?.try_into().ok()?))
    };
    let put = |b: &mut [u8], at: usize, crc: u32| -> Option<()> {
        b.get_mut(at..at.checked_add(4)?)?.copy_from_slice(&crc.to_le_bytes());
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
    for _ in 0..LIMITS.max_segments {
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
