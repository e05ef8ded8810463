//! Random maps and series through the file: lossless is bit-exact at every observed sample,
//! unknown stays unknown, and lossy keeps masks and geometry.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use froctomap_core::{MortonCode, Occupancy, Snapshot, Timestamp, VoxelKey};
use froctomap_file::{Codec, FroctReader, TileLayout, ToggleLayout};
use froctomap_temporal::{
    ModelConfig, ModelRegistry, ObservationsBuilder, Order, OutlierMode, TimeAxis,
};
use proptest::prelude::*;

const TILE_DEPTH: u8 = 13;

/// Random non-overlapping cells below a few random tiles, by random subdivision.
fn cells_strategy() -> impl Strategy<Value = Vec<(MortonCode, u8)>> {
    let tile_size = 1u64 << (3 * (16 - u32::from(TILE_DEPTH)));
    (
        proptest::collection::btree_set(0u64..4096, 1..4),
        any::<u64>(),
    )
        .prop_map(move |(tiles, seed)| {
            let mut rng = seed | 1;
            let mut next = move || {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                rng
            };
            let mut cells = Vec::new();
            for t in tiles {
                let origin = VoxelKey::new(30000, 30000, 30000)
                    .morton()
                    .node_start(TILE_DEPTH)
                    .0
                    + t * tile_size;
                let mut stack = vec![(origin, TILE_DEPTH)];
                while let Some((start, depth)) = stack.pop() {
                    let roll = next() % 10;
                    if depth < 16 && roll < 4 {
                        let child = 1u64 << (3 * (16 - u32::from(depth) - 1));
                        for i in (0..8).rev() {
                            stack.push((start + i * child, depth + 1));
                        }
                    } else if roll < 8 {
                        cells.push((MortonCode(start), depth));
                    }
                }
            }
            cells.sort();
            cells
        })
}

fn axis_strategy() -> impl Strategy<Value = TimeAxis> {
    prop_oneof![
        (2u32..120, proptest::collection::btree_set(0u32..120, 0..5)).prop_map(|(n, missing)| {
            let missing: Vec<u32> = missing.into_iter().filter(|&m| m < n && m > 0).collect();
            TimeAxis::regular(
                Timestamp::from_secs(1_600_000_000),
                600_000_000_000,
                n,
                missing,
            )
            .unwrap()
        }),
        proptest::collection::vec(1i64..2_000_000_000_000, 1..100).prop_map(|gaps| {
            let mut t = 1_600_000_000_000_000_000i64;
            TimeAxis::explicit(
                gaps.into_iter()
                    .map(|g| {
                        t += g;
                        Timestamp(t)
                    })
                    .collect(),
            )
            .unwrap()
        }),
    ]
}

/// A random series: state changes and gaps at random samples.
fn series(axis: &TimeAxis, seed: u64) -> froctomap_temporal::VoxelObservations {
    let mut rng = seed | 1;
    let mut b = ObservationsBuilder::new();
    let mut state = Some(Occupancy::from(seed % 2 != 0));
    let volatility = seed % 5;
    for i in 0..axis.len() {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        let roll = rng % 20;
        if roll < volatility {
            state = match state {
                Some(Occupancy::Free) => Some(Occupancy::Occupied),
                Some(Occupancy::Occupied) => None,
                None => Some(Occupancy::Free),
            };
        }
        b.push(i, state.filter(|_| !axis.is_missing(i))).unwrap();
    }
    // Every cell must be observed at least once.
    if b.clone().finish().observed_count() == 0 {
        let first = (0..axis.len()).find(|&i| !axis.is_missing(i)).unwrap();
        let mut b = ObservationsBuilder::new();
        b.push(first, Some(Occupancy::Occupied)).unwrap();
        return b.finish();
    }
    b.finish()
}

/// Both toggle layouts; blocks from one sample (every block boundary) to past the axis.
fn toggles_strategy() -> impl Strategy<Value = ToggleLayout> {
    prop_oneof![
        Just(ToggleLayout::Whole),
        (1u32..24).prop_map(ToggleLayout::Blocked),
        (1u32..24).prop_map(ToggleLayout::Coded),
        Just(ToggleLayout::DEFAULT),
    ]
}

fn check(
    model: &str,
    outliers: OutlierMode,
    axis: TimeAxis,
    geometry: Vec<(MortonCode, u8)>,
    seed: u64,
    toggles: ToggleLayout,
) {
    let cells: Vec<SeriesCell> = geometry
        .iter()
        .enumerate()
        .map(|(i, &(start, depth))| SeriesCell {
            start,
            depth,
            observations: series(&axis, seed.wrapping_add(i as u64 * 7919)),
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("series.froct");
    let config = ModelConfig::default().with_outliers(outliers);
    let declares_order = ModelRegistry::with_default_models()
        .by_name(model)
        .is_some_and(|d| d.options.iter().any(|o| o.key == "order"));
    let config = if declares_order {
        Order::Auto { max: 3 }.apply(config)
    } else {
        config
    };
    write_file(
        &path,
        &axis,
        model,
        &config,
        TileLayout {
            tile_depth: TILE_DEPTH,
            codec: Codec::Zstd { level: 3 },
            toggles,
        },
        &cells,
    );
    let reader = FroctReader::open(&path).unwrap();
    let mut decoded = Vec::new();
    for tile in 0..reader.tiles().len() {
        decoded.extend(reader.read_tile(tile).unwrap());
    }
    assert_eq!(decoded.len(), cells.len());
    for (cell, truth) in decoded.iter().zip(&cells) {
        assert_eq!((cell.start, cell.depth), (truth.start, truth.depth));
        for sample in 0..axis.len() {
            let expected = truth.observations.state_at(sample);
            let got = cell.state_at(&axis, reader.model(), sample);
            match outliers {
                OutlierMode::Lossless => assert_eq!(got, expected, "sample {sample}"),
                OutlierMode::Lossy => {
                    assert_eq!(got.is_some(), expected.is_some(), "mask at {sample}")
                }
            }
        }
    }
    // A query at one sample (the retrieval path: masks and outliers read only up to the
    // sample, in its block) agrees with the observations at every sample.
    for sample in 0..axis.len() {
        let mut leaves = Vec::new();
        for tile in 0..reader.tiles().len() {
            reader.observed_leaves(tile, sample, &mut leaves).unwrap();
        }
        let expected: Vec<(MortonCode, Option<Occupancy>)> = cells
            .iter()
            .filter_map(|c| {
                let state = c.observations.state_at(sample);
                state.map(|s| (c.start, Some(s)))
            })
            .collect();
        let got: Vec<(MortonCode, Option<Occupancy>)> = leaves
            .iter()
            .map(|l| (l.start, Some(l.occupancy())))
            .collect();
        match outliers {
            OutlierMode::Lossless => assert_eq!(got, expected, "sample {sample}"),
            OutlierMode::Lossy => assert_eq!(
                got.iter().map(|g| g.0).collect::<Vec<_>>(),
                expected.iter().map(|e| e.0).collect::<Vec<_>>(),
                "observed cells at {sample}"
            ),
        }
    }
    // The whole-map view agrees with the cells.
    for sample in [0, axis.len() / 2, axis.len() - 1] {
        let mut leaves = Vec::new();
        for tile in 0..reader.tiles().len() {
            reader.observed_leaves(tile, sample, &mut leaves).unwrap();
        }
        let snapshot = Snapshot::from_leaves(reader.header().resolution, leaves).unwrap();
        let known = cells
            .iter()
            .filter(|c| c.observations.state_at(sample).is_some())
            .count();
        assert_eq!(snapshot.leaves().len(), known);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn lossless_periods_model_is_exact(axis in axis_strategy(), geometry in cells_strategy(), seed: u64, toggles in toggles_strategy()) {
        check("fremen-periods", OutlierMode::Lossless, axis, geometry, seed, toggles);
    }

    #[test]
    fn lossless_static_model_is_exact(axis in axis_strategy(), geometry in cells_strategy(), seed: u64, toggles in toggles_strategy()) {
        check("static", OutlierMode::Lossless, axis, geometry, seed, toggles);
    }

    #[test]
    fn lossless_markov_model_is_exact(axis in axis_strategy(), geometry in cells_strategy(), seed: u64, toggles in toggles_strategy()) {
        check("markov", OutlierMode::Lossless, axis, geometry, seed, toggles);
    }

    #[test]
    fn lossy_files_keep_geometry_and_masks(axis in axis_strategy(), geometry in cells_strategy(), seed: u64, toggles in toggles_strategy()) {
        check("fremen-periods", OutlierMode::Lossy, axis, geometry, seed, toggles);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn lossless_regular_fft_model_is_exact(n in 2u32..150, geometry in cells_strategy(), seed: u64, toggles in toggles_strategy()) {
        let axis = TimeAxis::regular(Timestamp::from_secs(0), 60_000_000_000, n, vec![]).unwrap();
        check("fremen-regular", OutlierMode::Lossless, axis, geometry, seed, toggles);
    }
}
