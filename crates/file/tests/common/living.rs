//! Format 2.0 series for the tests: segments planned as a table of true states per cell and
//! sample (the independent model the reader must reproduce), turned into segment cells
//! against the base's frozen predictions, and appended.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use super::*;
use froctomap_core::{MortonCode, Occupancy, Timestamp, VoxelKey};
use froctomap_file::{Cell, CellContent, FroctReader, LivingWriter, SegmentCell, SegmentContent};
use froctomap_temporal::{ObservationsBuilder, TimeAxis, Toggles};
use std::path::Path;

/// How a planned cell is stored in its segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stored {
    /// Against the prediction of the base cell that contains it.
    Inherited,
    /// As this usual state with exceptions.
    Usual(Occupancy),
}

/// A cell of a segment and its true state at each of the segment's samples.
#[derive(Clone, Debug)]
pub struct PlannedCell {
    pub start: MortonCode,
    pub depth: u8,
    pub stored: Stored,
    pub truth: Vec<Option<Occupancy>>,
}

/// A segment: its samples and its cells (sorted).
#[derive(Clone, Debug)]
pub struct PlannedSegment {
    pub axis: TimeAxis,
    pub cells: Vec<PlannedCell>,
}

impl PlannedSegment {
    /// What a reader must report at the segment's sample `j`.
    pub fn expected(&self, j: u32) -> Vec<(MortonCode, u8, Occupancy)> {
        self.cells
            .iter()
            .filter_map(|c| c.truth[j as usize].map(|s| (c.start, c.depth, s)))
            .collect()
    }
}

/// A small deterministic generator.
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 33
    }
}

const HOUR: i64 = 3_600_000_000_000;

/// Three segments after the golden base: a regular one with a missing sample, one of
/// jittered explicit instants (ROS stamps), and a regular one off the base's grid.
pub fn golden_segment_axes() -> Vec<TimeAxis> {
    let base_end = golden_axis().end().0;
    let first = TimeAxis::regular(Timestamp(base_end + HOUR), HOUR, 20, vec![5]).unwrap();
    let mut rng = Lcg(7);
    let mut t = first.end().0;
    let jittered = (0..13)
        .map(|_| {
            t += HOUR + (rng.next() % 600) as i64 * 1_000_000_000 - 300_000_000_000;
            Timestamp(t)
        })
        .collect();
    let second = TimeAxis::explicit(jittered).unwrap();
    let third = TimeAxis::regular(
        Timestamp(second.end().0 + 17 * 60_000_000_000),
        HOUR,
        30,
        vec![],
    )
    .unwrap();
    vec![first, second, third]
}

/// The cells of segment `k` over `axis`: the golden cells carried on (the door keeps its
/// daily rhythm with deviations, the free block split in odd segments, the wall with one
/// flip, the noise as usual-state cells, the late region seen part of the time), and new
/// voxels in an existing and in a new tile.
pub fn golden_segment(k: u64, axis: &TimeAxis) -> PlannedSegment {
    let o = 32768u16;
    let voxel = |x: u16, y: u16, z: u16| VoxelKey::new(x, y, z).morton();
    let block =
        |x: u16, y: u16, z: u16, depth: u8| VoxelKey::new(x, y, z).morton().node_start(depth);
    let start = golden_axis().start();
    let n = axis.len();
    let mut rng = Lcg(100 + k);
    let hour_of = |j: u32| (axis.time(j).unwrap().secs_since(start) / 3600.0) as i64 % 24;
    let series = |f: &mut dyn FnMut(u32) -> Option<Occupancy>| -> Vec<Option<Occupancy>> {
        (0..n)
            .map(|j| if axis.is_missing(j) { None } else { f(j) })
            .collect()
    };
    let mut cells = Vec::new();
    let mut push = |start, depth, stored, truth: Vec<Option<Occupancy>>| {
        if truth.iter().any(Option::is_some) {
            cells.push(PlannedCell {
                start,
                depth,
                stored,
                truth,
            });
        }
    };
    if k % 2 == 1 {
        for child in 0..8u16 {
            let (x, y, z) = (o + 2 * (child & 1), o + (child & 2), o + (child & 4) / 2);
            push(
                block(x, y, z, 15),
                15,
                Stored::Inherited,
                series(&mut |j| Some(Occupancy::from(child == 3 && j % 4 == 1))),
            );
        }
    } else {
        push(
            block(o, o, o, 14),
            14,
            Stored::Inherited,
            series(&mut |_| Some(Occupancy::Free)),
        );
    }
    push(
        voxel(o + 4, o, o),
        16,
        Stored::Inherited,
        series(&mut |j| {
            let closed = !(8..18).contains(&hour_of(j));
            Some(Occupancy::from(closed != (rng.next() % 9 == 0)))
        }),
    );
    push(
        voxel(o + 5, o, o),
        16,
        Stored::Inherited,
        series(&mut |j| Some(Occupancy::from(j != 2))),
    );
    push(
        voxel(o + 5, o + 1, o),
        16,
        Stored::Usual(Occupancy::Occupied),
        series(&mut |_| Some(Occupancy::from(rng.next() % 5 != 0))),
    );
    push(
        voxel(o + 6, o, o),
        16,
        Stored::Usual(Occupancy::from(k % 2 == 0)),
        series(&mut |j| Some(Occupancy::from((k % 2 == 0) != (j == 1)))),
    );
    push(
        block(o + 16, o, o, 13),
        13,
        Stored::Inherited,
        series(&mut |j| (j >= n / 3).then(|| Occupancy::from(hour_of(j) >= 12))),
    );
    push(
        voxel(o + 100, o, o),
        16,
        Stored::Usual(Occupancy::Occupied),
        series(&mut |j| (j % 3 != 0).then_some(Occupancy::Occupied)),
    );
    cells.sort_by_key(|c| c.start);
    PlannedSegment {
        axis: axis.clone(),
        cells,
    }
}

/// The frozen prediction of the base cell containing `start` at `seconds`, from the base's
/// cells.
pub fn base_prediction(
    base: &FroctReader,
    cells: &[Cell],
    start: MortonCode,
    seconds: f64,
) -> Occupancy {
    let cell = cells
        .iter()
        .find(|c| c.start.0 <= start.0 && start.0 < c.end())
        .expect("an inherited cell lies inside a base cell");
    match &cell.content {
        CellContent::Constant(state) | CellContent::ConstantExcept { state, .. } => *state,
        CellContent::Modelled(voxel) => {
            Occupancy::from(base.model().probability(voxel.parameters(), seconds) > 0.5)
        }
    }
}

/// Toggles at the observed samples where `differs` changes (from false).
fn toggles_where(truth: &[Option<Occupancy>], differs: impl Fn(u32, Occupancy) -> bool) -> Toggles {
    let mut parity = false;
    let mut toggles = Vec::new();
    for (j, state) in truth.iter().enumerate() {
        if let Some(state) = state {
            if differs(j as u32, *state) != parity {
                parity = !parity;
                toggles.push(j as u32);
            }
        }
    }
    Toggles::new(toggles).unwrap()
}

/// The segment cells of a planned segment, against the base's predictions.
pub fn segment_cells(
    plan: &PlannedSegment,
    base: &FroctReader,
    base_cells: &[Cell],
) -> Vec<SegmentCell> {
    let base_start = base.header().axis.start();
    plan.cells
        .iter()
        .map(|cell| {
            let mut observations = ObservationsBuilder::new();
            for (j, state) in cell.truth.iter().enumerate() {
                observations.push(j as u32, *state).unwrap();
            }
            let mask = froctomap_file::mask_from_ranges(
                &plan.axis,
                &observations.finish().observed_ranges(),
            );
            let content = match cell.stored {
                Stored::Inherited => SegmentContent::Inherited {
                    outliers: toggles_where(&cell.truth, |j, state| {
                        let seconds = plan.axis.time(j).unwrap().secs_since(base_start);
                        state != base_prediction(base, base_cells, cell.start, seconds)
                    }),
                },
                Stored::Usual(usual) => {
                    let exceptions = toggles_where(&cell.truth, |_, state| state != usual);
                    if exceptions.is_empty() {
                        SegmentContent::Constant(usual)
                    } else {
                        SegmentContent::ConstantExcept {
                            state: usual,
                            exceptions,
                        }
                    }
                }
            };
            SegmentCell {
                start: cell.start,
                depth: cell.depth,
                mask,
                content,
            }
        })
        .collect()
}

/// Every cell of a file's base, in Morton order.
pub fn all_cells(base: &FroctReader) -> Vec<Cell> {
    (0..base.tiles().len())
        .flat_map(|t| base.read_tile(t).unwrap())
        .collect()
}

/// Appends a planned segment to the 2.0 file at `path` (tiles of the golden depth).
pub fn append_planned(path: &Path, plan: &PlannedSegment) -> froctomap_file::Root {
    let mut writer = LivingWriter::open(path).unwrap();
    let base = writer.reader().base();
    let base_cells = all_cells(base);
    let cells = segment_cells(plan, base, &base_cells);
    let mut segment = writer.begin_segment(plan.axis.clone()).unwrap();
    let mut at = 0;
    while at < cells.len() {
        let tile = cells[at].start.node_start(GOLDEN_TILE_DEPTH);
        let len = cells[at..]
            .iter()
            .take_while(|c| c.start.node_start(GOLDEN_TILE_DEPTH) == tile)
            .count();
        segment.push_tile(cells[at..at + len].to_vec()).unwrap();
        at += len;
    }
    segment.commit().unwrap()
}

/// The golden 2.0 file: the 1.2 golden file converted, then the first `segments` planned
/// segments appended. Returns the plans.
pub fn write_living_golden(path: &Path, segments: usize) -> Vec<PlannedSegment> {
    LivingWriter::convert(&golden_path_of("golden-v1.2.froct"), path).unwrap();
    let plans: Vec<PlannedSegment> = golden_segment_axes()
        .iter()
        .take(segments)
        .enumerate()
        .map(|(k, axis)| golden_segment(k as u64, axis))
        .collect();
    for plan in &plans {
        append_planned(path, plan);
    }
    plans
}

/// What a reader must report at every global sample of the golden base and `plans`.
pub fn expected_maps(plans: &[PlannedSegment]) -> Vec<Vec<(MortonCode, u8, Occupancy)>> {
    let axis = golden_axis();
    let base_cells = golden_cells();
    let mut maps: Vec<_> = (0..axis.len())
        .map(|i| {
            base_cells
                .iter()
                .filter(|_| !axis.is_missing(i))
                .filter_map(|c| c.observations.state_at(i).map(|s| (c.start, c.depth, s)))
                .collect()
        })
        .collect();
    for plan in plans {
        maps.extend((0..plan.axis.len()).map(|j| plan.expected(j)));
    }
    maps
}

/// `cell` stored whole in a segment, in one state throughout.
pub fn stored_constant(cell: &Cell, state: Occupancy) -> SegmentCell {
    SegmentCell {
        start: cell.start,
        depth: cell.depth,
        mask: None,
        content: SegmentContent::Constant(state),
    }
}

/// What both patch golden files start from: the 1.2 golden file converted at `path`, its
/// writer, the first golden segment axis, and the cells of the base's largest tile (the
/// tile the patch covers).
pub fn golden_base_for_a_patch(path: &Path) -> (LivingWriter, TimeAxis, Vec<Cell>) {
    LivingWriter::convert(&golden_path_of("golden-v1.2.froct"), path).unwrap();
    let axis = golden_segment_axes()[0].clone();
    let writer = LivingWriter::open(path).unwrap();
    let base = writer.reader().base();
    let largest = (0..base.tiles().len())
        .max_by_key(|&t| base.tiles()[t].cell_count)
        .unwrap();
    let base_cells = base.read_tile(largest).unwrap();
    (writer, axis, base_cells)
}

/// The patch golden file (format 2.0 with a patch tile, FORMAT.md §10.6): the 1.2 golden file
/// converted, then one segment of `golden_segment_axes()[0]` (which has a missing sample)
/// whose only tile is a patch tile over the base's largest tile: its first base cell stored
/// occupied throughout, its second stored free and observed at sample 0 only, everything
/// else left to the base from sample 1 on (the remainder's mask). Returns the segment's
/// axis and the base tile's cells.
pub fn write_patch_golden(path: &Path) -> (TimeAxis, Vec<Cell>) {
    let (mut writer, axis, base_cells) = golden_base_for_a_patch(path);
    assert!(base_cells.len() >= 3);
    let mut segment = writer.begin_segment(axis.clone()).unwrap();
    let mut encoder = segment.tile_encoder();
    encoder
        .push(stored_constant(&base_cells[0], Occupancy::Occupied))
        .unwrap();
    encoder
        .push(SegmentCell {
            start: base_cells[1].start,
            depth: base_cells[1].depth,
            mask: Some(std::sync::Arc::new(Toggles::new(vec![0, 1]).unwrap())),
            content: SegmentContent::Constant(Occupancy::Free),
        })
        .unwrap();
    let from_1 = std::sync::Arc::new(Toggles::new(vec![1]).unwrap());
    segment
        .write_patch_tile(&encoder.finish().unwrap(), Some(from_1))
        .unwrap();
    segment.commit().unwrap();
    (axis, base_cells)
}

/// The remainder golden file (format 2.0 with remainder runs, FORMAT.md §10.7): the golden
/// 1.2 base converted, then a segment of `golden_segment_axes()[0]` (20 samples,
/// sample 5 missing) whose one tile is a patch tile over the base's largest tile (4 cells):
/// base cell 0 stored occupied throughout; base cell 1 left to the mask `[0, 1]` (sample 0
/// only), base cell 2 to no sample, every other one to the default `[1]` (from sample 1).
pub fn write_remainder_golden(path: &Path) -> (TimeAxis, Vec<Cell>) {
    let (mut writer, axis, base_cells) = golden_base_for_a_patch(path);
    assert!(base_cells.len() >= 4, "{}", base_cells.len());
    let mut segment = writer.begin_segment(axis.clone()).unwrap();
    let mut encoder = segment.tile_encoder();
    encoder
        .push(stored_constant(&base_cells[0], Occupancy::Occupied))
        .unwrap();
    let remainder = froctomap_file::TileRemainder {
        default: remainder_mask(&[1]),
        masks: vec![remainder_mask(&[0, 1])],
        runs: vec![
            froctomap_file::RemainderRun {
                first: 1,
                len: 1,
                mask: 1,
            },
            froctomap_file::RemainderRun {
                first: 2,
                len: 1,
                mask: 0,
            },
        ],
    };
    segment
        .write_patch_tile_with(&encoder.finish().unwrap(), remainder)
        .unwrap();
    segment.commit().unwrap();
    (axis, base_cells)
}

/// A remainder mask of these positions.
pub fn remainder_mask(positions: &[u32]) -> Option<std::sync::Arc<Toggles>> {
    Some(std::sync::Arc::new(
        Toggles::new(positions.to_vec()).unwrap(),
    ))
}
