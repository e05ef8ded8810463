//! Surprise of each observed part of a snapshot under the file's model at one instant: the
//! snapshot's leaves and the file's cells are walked together in Morton order, one tile of
//! the file at a time, and every piece whose state the model found unlikely is kept.

use super::options::{AnomalyOptions, Expectation};
use super::report::AnomalyKind;
use froctomap_core::{voxels_per_node, Leaf, MortonCode, Occupancy, TREE_DEPTH};
use froctomap_file::{Cell, CellContent, FileError, FroctReader};
use froctomap_temporal::{PreparedModel, TimeAxis, Toggles};

/// An aligned cube of the snapshot whose observed state was surprising.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Piece {
    /// First voxel.
    pub start: MortonCode,
    /// Depth of the cube.
    pub depth: u8,
    /// What was observed against what was expected.
    pub kind: AnomalyKind,
    /// Surprise of each of its voxels, nats.
    pub surprise: f64,
}

impl Piece {
    pub(crate) fn voxels(&self) -> u64 {
        voxels_per_node(self.depth)
    }

    pub(crate) fn leaf(&self) -> Leaf {
        Leaf {
            start: self.start,
            depth: self.depth,
            log_odds: 0.0,
        }
    }
}

/// What scoring needs of the file and the instant.
pub(crate) struct Scorer<'a> {
    pub model: &'a dyn PreparedModel,
    pub axis: &'a TimeAxis,
    /// Seconds since the file's first sample.
    pub seconds: f64,
    /// The last sample at or before the instant (for [`Expectation::LastSeen`]).
    pub last_seen: Option<u32>,
    pub options: &'a AnomalyOptions,
}

impl Scorer<'_> {
    /// The probability the file gives a cell's voxels to be occupied at the instant
    /// (`None`: the cell counts as never seen), by the options' expectation.
    fn occupied_probability(&self, cell: &Cell) -> Option<f64> {
        let eps = self.options.error_rate;
        match self.options.expectation {
            Expectation::Model => Some(self.model_probability(cell)),
            Expectation::StaticMean => Some(self.mean(cell).clamp(eps, 1.0 - eps)),
            Expectation::LastSeen => {
                let state = cell.state_at(self.axis, self.model, self.last_seen?)?;
                Some(with_rate(state, eps))
            }
        }
    }

    /// A static or noisy cell's state, wrong at the rule of succession's rate `(k + 1) /
    /// (n + 2)` for `k` exceptions in `n` observed samples (a static cell's at most the error
    /// rate: a long history of one state makes a flip rarer than a short one); a model's
    /// `p(t)` kept within the error rate of 0 and 1.
    fn model_probability(&self, cell: &Cell) -> f64 {
        let eps = self.options.error_rate;
        let succession = |k: u64| {
            let n = observed_samples(cell, self.axis);
            ((k + 1) as f64 / (n + 2) as f64).min(0.5)
        };
        match &cell.content {
            CellContent::Constant(state) => with_rate(*state, succession(0).min(eps)),
            CellContent::ConstantExcept { state, exceptions } => with_rate(
                *state,
                succession(samples_inside(exceptions, self.axis.len())),
            ),
            CellContent::Modelled(voxel) => {
                let p = self.model.probability(voxel.parameters(), self.seconds);
                if p.is_finite() {
                    p.clamp(eps, 1.0 - eps)
                } else {
                    0.5
                }
            }
        }
    }

    /// The cell's mean occupancy over the file's history.
    fn mean(&self, cell: &Cell) -> f64 {
        match &cell.content {
            CellContent::Constant(state) => f64::from(u8::from(state.is_occupied())),
            CellContent::ConstantExcept { state, exceptions } => {
                let share = exception_share(exceptions, self.axis.len());
                if state.is_occupied() {
                    1.0 - share
                } else {
                    share
                }
            }
            CellContent::Modelled(voxel) => self.model.mean(voxel.parameters()),
        }
    }

    /// The surprising piece a cube observed in `state` makes, given the probability of
    /// occupied there, if its surprise passes the voxel threshold.
    fn judge(&self, start: u64, end: u64, state: Occupancy, occupied: f64, out: &mut Vec<Piece>) {
        let (kind, p) = if state.is_occupied() {
            (AnomalyKind::Appeared, occupied)
        } else {
            (AnomalyKind::Vanished, 1.0 - occupied)
        };
        let surprise = -p.ln();
        if surprise > self.options.voxel_threshold {
            for (start, depth) in aligned_cubes(start, end) {
                out.push(Piece {
                    start,
                    depth,
                    kind,
                    surprise,
                });
            }
        }
    }

    /// Space the file never observed: occupied there is as unlikely as against a static
    /// free cell; free there tells nothing.
    fn judge_unseen(&self, start: u64, end: u64, state: Occupancy, out: &mut Vec<Piece>) {
        if state.is_occupied() {
            self.judge(start, end, state, self.options.error_rate, out);
        }
    }
}

/// Probability of occupied for a cell in `state` that is wrong at `rate`.
fn with_rate(state: Occupancy, rate: f64) -> f64 {
    if state.is_occupied() {
        1.0 - rate
    } else {
        rate
    }
}

/// Samples of `0..samples` inside a toggle list's odd runs (where its parity is set).
fn samples_inside(toggles: &Toggles, samples: u32) -> u64 {
    toggles
        .as_slice()
        .chunks(2)
        .map(|pair| {
            let end = pair.get(1).copied().unwrap_or(samples).min(samples);
            u64::from(end.saturating_sub(pair[0]))
        })
        .sum()
}

/// Share of the axis's samples inside the exceptions of a noisy cell.
fn exception_share(exceptions: &Toggles, samples: u32) -> f64 {
    samples_inside(exceptions, samples) as f64 / f64::from(samples.max(1))
}

/// Samples at which a cell was observed (missing samples of the axis are never observed;
/// a mask's runs may include some, which only makes the count a little high).
fn observed_samples(cell: &Cell, axis: &TimeAxis) -> u64 {
    match &cell.mask {
        None => u64::from(axis.len()).saturating_sub(axis.missing().len() as u64),
        Some(mask) => samples_inside(mask, axis.len()),
    }
}

/// The Morton range `[start, end)` cut into the fewest aligned cubes, in order.
pub(crate) fn aligned_cubes(mut start: u64, end: u64) -> impl Iterator<Item = (MortonCode, u8)> {
    std::iter::from_fn(move || {
        if start >= end {
            return None;
        }
        let mut depth = TREE_DEPTH;
        while depth > 0 {
            let size = voxels_per_node(depth - 1);
            if start % size != 0 || start + size > end {
                break;
            }
            depth -= 1;
        }
        let cube = (MortonCode(start), depth);
        start += voxels_per_node(depth);
        Some(cube)
    })
}

/// The snapshot's leaves that overlap the Morton range `[start, end)`.
fn leaves_in(leaves: &[Leaf], start: u64, end: u64) -> &[Leaf] {
    let first = leaves.partition_point(|l| l.end() <= start);
    let last = leaves.partition_point(|l| l.start.0 < end);
    leaves.get(first..last.max(first)).unwrap_or_default()
}

/// Surprising pieces of the snapshot inside one tile of the file. Holds one cell at a time.
pub(crate) fn score_tile(
    reader: &FroctReader,
    tile: usize,
    leaves: &[Leaf],
    scorer: &Scorer<'_>,
) -> Result<Vec<Piece>, FileError> {
    let Some(entry) = reader.tiles().get(tile) else {
        return Ok(Vec::new());
    };
    let tile_start = entry.code.0;
    let tile_end = tile_start + voxels_per_node(reader.header().tile_depth);
    // Leaves clipped to the tile: a leaf coarser than the tile becomes the tile.
    let parts: Vec<(u64, u64, Occupancy)> = leaves_in(leaves, tile_start, tile_end)
        .iter()
        .map(|l| {
            (
                l.start.0.max(tile_start),
                l.end().min(tile_end),
                l.occupancy(),
            )
        })
        .collect();
    let mut out = Vec::new();
    if parts.is_empty() {
        return Ok(out);
    }
    // `next` is the first part not yet fully judged, `pos` how far into it.
    let mut next = 0;
    let mut pos = 0u64;
    reader.visit_cells(tile, |cell| {
        let (cell_start, cell_end) = (cell.start.0, cell.end());
        let mut occupied = None;
        while let Some(&(start, end, state)) = parts.get(next) {
            let from = pos.max(start);
            if from >= cell_end {
                break;
            }
            if from < cell_start {
                scorer.judge_unseen(from, end.min(cell_start), state, &mut out);
            }
            let (lo, hi) = (from.max(cell_start), end.min(cell_end));
            if lo < hi {
                match *occupied.get_or_insert_with(|| scorer.occupied_probability(&cell)) {
                    Some(p) => scorer.judge(lo, hi, state, p, &mut out),
                    None => scorer.judge_unseen(lo, hi, state, &mut out),
                }
            }
            if end <= cell_end {
                next += 1;
                pos = 0;
            } else {
                pos = cell_end;
                break;
            }
        }
    })?;
    for &(start, end, state) in parts.get(next..).unwrap_or_default() {
        scorer.judge_unseen(pos.max(start), end, state, &mut out);
        pos = 0;
    }
    Ok(out)
}

/// Surprising pieces of the snapshot's occupied leaves outside every tile of the file
/// (space it never observed).
pub(crate) fn score_outside_tiles(
    reader: &FroctReader,
    leaves: &[Leaf],
    scorer: &Scorer<'_>,
) -> Vec<Piece> {
    let tiles = reader.tiles();
    let tile_len = voxels_per_node(reader.header().tile_depth);
    let mut out = Vec::new();
    for leaf in leaves.iter().filter(|l| l.occupancy().is_occupied()) {
        let (start, end) = (leaf.start.0, leaf.end());
        let mut cursor = start;
        let first = tiles.partition_point(|t| t.code.0 + tile_len <= start);
        for tile in tiles.get(first..).unwrap_or_default() {
            if tile.code.0 >= end {
                break;
            }
            if tile.code.0 > cursor {
                scorer.judge_unseen(cursor, tile.code.0, Occupancy::Occupied, &mut out);
            }
            cursor = cursor.max(tile.code.0 + tile_len);
        }
        if cursor < end {
            scorer.judge_unseen(cursor, end, Occupancy::Occupied, &mut out);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_cut_into_aligned_cubes() {
        let cubes: Vec<_> = aligned_cubes(7, 130).collect();
        let mut covered = 7;
        for &(start, depth) in &cubes {
            assert_eq!(start.0, covered);
            assert_eq!(start.0 % voxels_per_node(depth), 0);
            covered += voxels_per_node(depth);
        }
        assert_eq!(covered, 130);
        // 7, 8..64 (7 cubes of 8), 64..128, 128, 129
        assert_eq!(cubes.len(), 1 + 7 + 1 + 2);
        assert_eq!(
            aligned_cubes(0, MortonCode::END).collect::<Vec<_>>(),
            [(MortonCode(0), 0)]
        );
        assert_eq!(aligned_cubes(5, 5).count(), 0);
    }

    #[test]
    fn exception_share_counts_samples_between_toggles() {
        let t = Toggles::new(vec![2, 4, 8]).unwrap();
        assert!((exception_share(&t, 10) - 0.4).abs() < 1e-12);
        assert_eq!(exception_share(&Toggles::default(), 10), 0.0);
    }
}
