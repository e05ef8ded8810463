//! Deterministic series for the file tests: cells, their observations, and files made of them.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use froctomap_core::{MortonCode, Occupancy, Timestamp, VoxelKey};
use froctomap_file::{
    encode_tile, mask_from_ranges, Cell, CellContent, Codec, FroctWriter, Header, TileLayout,
    ToggleLayout,
};
use froctomap_temporal::{
    ModelConfig, ModelRegistry, OutlierMode, PreparedModel, TimeAxis, VoxelObservations,
};
use std::path::Path;

pub mod living;
pub mod resealed;

/// A cell and what was observed of it.
pub struct SeriesCell {
    pub start: MortonCode,
    pub depth: u8,
    pub observations: VoxelObservations,
}

/// The file cell for a series cell: constant when possible, else fitted.
pub fn to_cell(axis: &TimeAxis, model: &dyn PreparedModel, cell: &SeriesCell) -> Cell {
    let mask = mask_from_ranges(axis, &cell.observations.observed_ranges());
    let content = match cell.observations.is_constant() {
        Some(state) => CellContent::Constant(state),
        None => CellContent::Modelled(model.fit(&cell.observations).unwrap()),
    };
    Cell {
        start: cell.start,
        depth: cell.depth,
        mask,
        content,
    }
}

/// A cell stored as mostly occupied, with the samples where it was free as exceptions.
pub fn to_noise_cell(axis: &TimeAxis, cell: &SeriesCell) -> Cell {
    let mut toggles = Vec::new();
    let mut free = false;
    for sample in 0..axis.len() {
        let now = cell.observations.state_at(sample) == Some(Occupancy::Free);
        if now != free && cell.observations.state_at(sample).is_some() {
            toggles.push(sample);
            free = now;
        }
    }
    Cell {
        start: cell.start,
        depth: cell.depth,
        mask: mask_from_ranges(axis, &cell.observations.observed_ranges()),
        content: CellContent::ConstantExcept {
            state: Occupancy::Occupied,
            exceptions: froctomap_temporal::Toggles::new(toggles).unwrap(),
        },
    }
}

/// Writes cells (sorted) to a file, grouping them into tiles.
pub fn write_file(
    path: &Path,
    axis: &TimeAxis,
    model_name: &str,
    config: &ModelConfig,
    layout: TileLayout,
    cells: &[SeriesCell],
) -> Box<dyn PreparedModel> {
    write_file_with(path, axis, model_name, config, layout, cells, |_| false)
}

/// [`write_file`], storing the cells for which `noise` holds as constant with exceptions
/// (their usual state, the other samples as exceptions), as froctomap's build does for
/// sensor noise.
pub fn write_file_with(
    path: &Path,
    axis: &TimeAxis,
    model_name: &str,
    config: &ModelConfig,
    layout: TileLayout,
    cells: &[SeriesCell],
    noise: impl Fn(&SeriesCell) -> bool,
) -> Box<dyn PreparedModel> {
    let TileLayout {
        tile_depth,
        codec,
        toggles,
    } = layout;
    let registry = ModelRegistry::with_default_models();
    let model = registry.by_name(model_name).unwrap().create();
    let prepared = model.prepare(axis, config).unwrap();
    let mut header = Header::new(
        0.1,
        tile_depth,
        axis.clone(),
        model.id(),
        prepared.encode_parameters(),
        codec,
    );
    header.toggles = toggles;
    header
        .metadata
        .insert("creator".into(), "froctomap-file tests".into());
    let mut writer = FroctWriter::create(path, &header).unwrap();
    let file_cells: Vec<Cell> = cells
        .iter()
        .map(|c| {
            if noise(c) {
                to_noise_cell(axis, c)
            } else {
                to_cell(axis, prepared.as_ref(), c)
            }
        })
        .collect();
    let mut start = 0;
    while start < file_cells.len() {
        let tile = file_cells[start].start.node_start(tile_depth);
        let len = file_cells[start..]
            .iter()
            .take_while(|c| c.start.node_start(tile_depth) == tile)
            .count();
        let encoded = encode_tile(
            &header.tile_layout(),
            &file_cells[start..start + len],
            prepared.as_ref(),
        )
        .unwrap();
        writer.write_tile(&encoded).unwrap();
        start += len;
    }
    writer.finish(Default::default()).unwrap();
    prepared
}

fn golden_obs(series: impl IntoIterator<Item = (u32, Option<Occupancy>)>) -> VoxelObservations {
    let mut b = froctomap_temporal::ObservationsBuilder::new();
    let axis = golden_axis();
    for (i, s) in series {
        // No snapshot exists at a missing sample, so nothing can be observed there.
        b.push(i, s.filter(|_| !axis.is_missing(i))).unwrap();
    }
    b.finish()
}

/// The golden series: three days at one-hour steps (one snapshot missing), cells in three
/// tiles of depth 12: a daily door, a noisy surface voxel, static walls and free space, and
/// a region seen only on the second and third day.
pub fn golden_axis() -> TimeAxis {
    TimeAxis::regular(
        Timestamp::from_secs(1_700_000_000),
        3_600_000_000_000,
        72,
        vec![40],
    )
    .unwrap()
}

pub const GOLDEN_TILE_DEPTH: u8 = 12;

pub fn golden_cells() -> Vec<SeriesCell> {
    let o = 32768u16;
    let voxel = |x: u16, y: u16, z: u16| VoxelKey::new(x, y, z).morton();
    let block =
        |x: u16, y: u16, z: u16, depth: u8| VoxelKey::new(x, y, z).morton().node_start(depth);
    let all = |state: Occupancy| golden_obs((0..72).map(move |i| (i, Some(state))));
    let door = golden_obs((0..72).map(|i| {
        let hour = i % 24;
        (i, Some(Occupancy::from(!(8..18).contains(&hour))))
    }));
    let noisy =
        golden_obs((0..72).map(|i| (i, Some(Occupancy::from(!(i % 7 == 3 || i % 11 == 5))))));
    let late = golden_obs((24..72).map(|i| (i, Some(Occupancy::from(i % 24 >= 12)))));
    let gaps = golden_obs((0..72).map(|i| (i, (i % 10 < 6).then_some(Occupancy::Free))));
    let mut cells = vec![
        SeriesCell {
            start: block(o, o, o, 14),
            depth: 14,
            observations: all(Occupancy::Free),
        },
        SeriesCell {
            start: voxel(o + 4, o, o),
            depth: 16,
            observations: door,
        },
        SeriesCell {
            start: voxel(o + 5, o, o),
            depth: 16,
            observations: all(Occupancy::Occupied),
        },
        SeriesCell {
            start: voxel(o + 5, o + 1, o),
            depth: 16,
            observations: noisy,
        },
        SeriesCell {
            start: block(o + 16, o, o, 13),
            depth: 13,
            observations: late,
        },
        SeriesCell {
            start: block(o - 16, o, o, 15),
            depth: 15,
            observations: gaps,
        },
    ];
    cells.sort_by_key(|c| c.start);
    cells
}

/// Every setting spelled out, so a change of defaults does not change the golden file.
pub fn golden_config() -> ModelConfig {
    froctomap_temporal::Order::Auto { max: 3 }
        .apply(ModelConfig::default())
        .with_outliers(OutlierMode::Lossless)
        .with_option("criterion", "prediction")
}

/// The golden files: one per format version, each written with that version's layout.
pub const GOLDENS: [(&str, ToggleLayout); 3] = [
    ("golden-v1.0.froct", ToggleLayout::Whole),
    // Blocks of 16 samples: the 72-sample axis has five, the last one short.
    ("golden-v1.1.froct", ToggleLayout::Blocked(16)),
    ("golden-v1.2.froct", ToggleLayout::Coded(16)),
];

/// The golden series' noisy surface voxel: format 1.2 files store it as constant with
/// exceptions (its free samples), which 1.2 range codes; earlier ones fit it a model.
pub fn is_golden_noise(toggles: ToggleLayout, cell: &SeriesCell) -> bool {
    let o = 32768u16;
    matches!(toggles, ToggleLayout::Coded(_))
        && cell.start == VoxelKey::new(o + 5, o + 1, o).morton()
}

/// Writes a golden file to `path`.
pub fn write_golden(path: &Path, toggles: ToggleLayout) -> Box<dyn PreparedModel> {
    write_file_with(
        path,
        &golden_axis(),
        "fremen-periods",
        &golden_config(),
        TileLayout {
            tile_depth: GOLDEN_TILE_DEPTH,
            codec: Codec::Zstd { level: 19 },
            toggles,
        },
        &golden_cells(),
        |cell| is_golden_noise(toggles, cell),
    )
}

/// Path of a golden file by name.
pub fn golden_path_of(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/froct")
        .join(name)
}

/// The golden file of the current version.
pub fn golden_path() -> std::path::PathBuf {
    golden_path_of(GOLDENS[1].0)
}

/// Recomputes every tile checksum, the index checksum and the footer checksum, so that a
/// damaged tile passes every checksum and its content is parsed.
pub fn reseal(bytes: &mut [u8]) {
    use froctomap_file::{FOOTER_LEN, TILE_ENTRY_LEN};
    let le64 = |b: &[u8]| u64::from_le_bytes(b.try_into().unwrap()) as usize;
    let le32 = |b: &[u8]| u32::from_le_bytes(b.try_into().unwrap()) as usize;
    let footer = bytes.len() - FOOTER_LEN;
    let index = le64(&bytes[footer..footer + 8]);
    let index_len = le64(&bytes[footer + 8..footer + 16]);
    let tiles = le32(&bytes[index..index + 4]);
    for t in 0..tiles {
        let entry = index + 4 + t * TILE_ENTRY_LEN;
        let offset = le64(&bytes[entry + 8..entry + 16]);
        let stored = le32(&bytes[entry + 16..entry + 20]);
        let crc = crc32c::crc32c(&bytes[offset..offset + stored]);
        bytes[entry + 24..entry + 28].copy_from_slice(&crc.to_le_bytes());
    }
    let crc = crc32c::crc32c(&bytes[index..index + index_len]);
    bytes[footer + 16..footer + 20].copy_from_slice(&crc.to_le_bytes());
    let crc = crc32c::crc32c(&bytes[footer..footer + 20]);
    bytes[footer + 20..footer + 24].copy_from_slice(&crc.to_le_bytes());
}

/// Offset of the payload of the header section `tag` (1 MAP, 2 TIME_AXIS, …, FORMAT.md §3).
pub fn header_section(bytes: &[u8], tag: u16) -> usize {
    let le32 = |b: &[u8]| u32::from_le_bytes(b.try_into().unwrap()) as usize;
    let end = 16 + le32(&bytes[12..16]);
    let mut at = 16;
    while at < end {
        let len = le32(&bytes[at + 4..at + 8]);
        if u16::from_le_bytes([bytes[at], bytes[at + 1]]) == tag {
            return at + 8;
        }
        at += 8 + len;
    }
    panic!("no header section {tag}");
}

/// Recomputes the header checksum after the header was patched.
pub fn reseal_header(bytes: &mut [u8]) {
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let crc = crc32c::crc32c(&bytes[..16 + len]);
    bytes[16 + len..16 + len + 4].copy_from_slice(&crc.to_le_bytes());
}

/// Offset of tile `t`'s index entry.
pub fn index_entry(bytes: &[u8], t: usize) -> usize {
    let footer = bytes.len() - froctomap_file::FOOTER_LEN;
    let index = u64::from_le_bytes(bytes[footer..footer + 8].try_into().unwrap()) as usize;
    index + 4 + t * froctomap_file::TILE_ENTRY_LEN
}

/// The golden series written raw (no zstd), so that damage reaches the tile parser instead of
/// the decompressor, in a given toggle layout.
pub fn raw_golden_file(toggles: froctomap_file::ToggleLayout) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("raw.froct");
    write_file_with(
        &path,
        &golden_axis(),
        "fremen-periods",
        &golden_config(),
        froctomap_file::TileLayout {
            tile_depth: GOLDEN_TILE_DEPTH,
            codec: froctomap_file::Codec::Raw,
            toggles,
        },
        &golden_cells(),
        |cell| is_golden_noise(toggles, cell),
    );
    std::fs::read(&path).unwrap()
}
