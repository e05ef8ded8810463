//! Format 1.2's range-coded exceptions (FORMAT.md §5.5), encoder and decoder together:
//! arbitrary exception lists of nearly constant cells, over an arbitrary axis cut into
//! arbitrary blocks, written as a 1.2 file and read back whole and at single samples, must
//! give the very lists and states. (Decoding hostile bytes is `read_froct`'s job.)
#![no_main]

use froctomap_core::{Occupancy, Timestamp, VoxelKey};
use froctomap_file::{
    encode_tile, Cell, CellContent, Codec, FroctReader, FroctWriter, Header, TileLayout,
    ToggleLayout,
};
use froctomap_temporal::{ModelConfig, ModelRegistry, TimeAxis, Toggles};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let [samples, block, rest @ ..] = data else {
        return;
    };
    let samples = u32::from(*samples) * 4 + 1;
    let block = u32::from(*block % 64) + 1;
    // Each cell's exceptions: bytes as gaps (a 0 gap after a position is a one-sample
    // flicker), a 0xFF byte ends a cell.
    let mut cells = Vec::new();
    for (i, list) in rest.split(|&b| b == 0xFF).take(64).enumerate() {
        let mut toggles = Vec::new();
        let mut at = 0u32;
        for &gap in list {
            let t = at + u32::from(gap % 32);
            if t >= samples {
                break;
            }
            toggles.push(t);
            at = t + 1;
        }
        if toggles.is_empty() {
            continue;
        }
        let o = 32768u16;
        cells.push(Cell {
            start: VoxelKey::new(o + i as u16 % 8, o + i as u16 / 8, o).morton(),
            depth: 16,
            mask: None,
            content: CellContent::ConstantExcept {
                state: if i % 3 == 0 { Occupancy::Free } else { Occupancy::Occupied },
                exceptions: Toggles::new(toggles).expect("increasing"),
            },
        });
    }
    if cells.is_empty() {
        return;
    }
    cells.sort_by_key(|c| c.start);
    let axis = TimeAxis::regular(Timestamp::from_secs(0), 1_000_000_000, samples, vec![])
        .expect("axis");
    let model = ModelRegistry::with_default_models()
        .by_name("fremen-periods")
        .expect("model")
        .create();
    let prepared = model.prepare(&axis, &ModelConfig::default()).expect("prepared");
    let mut header = Header::new(
        0.1,
        12,
        axis.clone(),
        model.id(),
        prepared.encode_parameters(),
        Codec::Raw,
    );
    header.toggles = ToggleLayout::Coded(block);
    let layout: TileLayout = header.tile_layout();
    let dir = std::env::temp_dir().join(format!("froct-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("exceptions.froct");
    let mut writer = FroctWriter::create(&path, &header).expect("writer");
    let tile = encode_tile(&layout, &cells, prepared.as_ref()).expect("encodes");
    writer.write_tile(&tile).expect("writes");
    writer.finish(Default::default()).expect("finishes");
    let reader = FroctReader::open(&path).expect("reads");
    assert_eq!(reader.read_tile(0).expect("whole tile"), cells);
    for sample in 0..samples {
        let mut leaves = Vec::new();
        reader
            .observed_leaves(0, sample, &mut leaves)
            .expect("one sample");
        let expected: Vec<_> = cells
            .iter()
            .map(|c| (c.start, c.state_at(&axis, prepared.as_ref(), sample)))
            .collect();
        let got: Vec<_> = leaves
            .iter()
            .map(|l| (l.start, Some(l.occupancy())))
            .collect();
        assert_eq!(got, expected, "sample {sample}");
    }
});
