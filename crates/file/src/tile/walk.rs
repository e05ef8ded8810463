//! Reading a tile's decoded payload: a walk over its cells that decodes only what a query
//! needs, and the cells built from it.

use super::cell::{Cell, CellContent};
use super::model::{self, ModelStream};
use super::streams::{ListSet, PartKind, PartStreams, Stream, TileParts};
use super::{
    CLASS_FREE, CLASS_HAS_MASK, CLASS_HAS_OUTLIERS, CLASS_KIND_MASK, CLASS_MODELLED, CLASS_OCCUPIED,
};
use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation};
use crate::layout::TileLayout;
use crate::limits::ReadLimits;
use crate::toggle_lists::{ListReader, ToggleLayout};
use froctomap_core::{voxels_per_node, MortonCode, Occupancy, TREE_DEPTH};
use froctomap_temporal::{PreparedModel, TimeAxis, Toggles};
use std::sync::Arc;

/// What a payload walk needs of each cell's mask and outliers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum WalkNeed {
    /// Everything (to build [`Cell`]s).
    Everything,
    /// Only whether the cell is observed at this sample and its state there: masks are
    /// evaluated once per distinct mask, outlier lists only as far as the sample.
    StateAt(u32),
    /// Only the model (for predictions): masks and outliers are skipped undecoded.
    ModelOnly,
}

impl WalkNeed {
    /// The toggle blocks (format 1.1) this walk reads: all, the one holding the sample, or
    /// none.
    pub(crate) fn blocks(self, toggles: ToggleLayout, axis_len: u32) -> std::ops::Range<u32> {
        let count = toggles.blocks(axis_len);
        match (self, toggles) {
            (_, ToggleLayout::Whole) | (WalkNeed::ModelOnly, _) => 0..0,
            (WalkNeed::Everything, _) => 0..count,
            (WalkNeed::StateAt(sample), ToggleLayout::Blocked(len) | ToggleLayout::Coded(len)) => {
                let b = (sample / len.max(1)).min(count - 1);
                b..b + 1
            }
        }
    }
}

/// One cell as the payload walk sees it, borrowing from the tile instead of allocating.
pub(crate) struct CellRef<'a> {
    pub(crate) start: MortonCode,
    pub(crate) depth: u8,
    /// With [`WalkNeed::Everything`]: the cell's observation mask (shared by the tile), if
    /// it has one (a query at one sample gets `observed` instead).
    pub(crate) mask: Option<&'a Arc<Toggles>>,
    /// The constant state, or `None` for a modelled cell.
    pub(crate) constant: Option<Occupancy>,
    /// A modelled cell's parameter bytes (without outliers), for the file's model.
    pub(crate) model: Option<&'a [u8]>,
    /// With [`WalkNeed::Everything`]: the cell's outlier (or exception) toggles.
    pub(crate) outliers: &'a [u32],
    /// With [`WalkNeed::StateAt`]: whether the cell is observed at the sample, and whether
    /// an odd number of its outliers lie at or before it.
    pub(crate) observed: bool,
    pub(crate) outlier_parity: bool,
    /// Whatever the walk decoded: whether the cell has a mask (is not observed at every
    /// sample), and outliers (or exceptions).
    pub(crate) has_mask: bool,
    pub(crate) has_outliers: bool,
}

impl CellRef<'_> {
    /// With [`WalkNeed::StateAt`]: the state at the sample (meaningful when observed).
    #[inline]
    pub(crate) fn state(&self, model: &dyn PreparedModel, sample: u32) -> Occupancy {
        let base = match (self.constant, self.model) {
            (Some(state), _) => state,
            (None, Some(parameters)) => {
                Occupancy::from(model::probability_at_sample(model, parameters, sample) > 0.5)
            }
            (None, None) => Occupancy::Free,
        };
        if self.outlier_parity {
            !base
        } else {
            base
        }
    }

    /// Occupancy probability at any instant.
    #[inline]
    pub(crate) fn probability(&self, model: &dyn PreparedModel, seconds: f64) -> f64 {
        match (self.constant, self.model) {
            (Some(state), _) => f64::from(u8::from(state.is_occupied())),
            (None, Some(parameters)) => model::probability(model, parameters, seconds),
            (None, None) => 0.0,
        }
    }
}

/// The tile's distinct masks, as far as a walk needs them.
struct MaskTable {
    distinct: usize,
    /// With [`WalkNeed::StateAt`]: whether the sample is on the axis and not missing, and
    /// whether each mask observes it (evaluated once per mask, not per cell, and without
    /// decoding a mask past the sample).
    sample_present: bool,
    observed: Vec<bool>,
    /// With [`WalkNeed::Everything`]: the masks.
    masks: Vec<Arc<Toggles>>,
}

impl MaskTable {
    fn read(
        mask_count: &[u8],
        lists: &mut ListReader<'_>,
        cells: usize,
        need: WalkNeed,
        axis: &TimeAxis,
    ) -> Result<Self, FormatViolation> {
        let mut mask_count = Cursor::new(mask_count, "tile masks");
        let distinct = mask_count.varint()?;
        if distinct > cells as u64 || distinct > lists.max_lists() as u64 {
            return Err(corrupt(
                "tile masks",
                format!("{distinct} distinct masks cannot fit"),
            ));
        }
        if !mask_count.is_empty() {
            return Err(corrupt("tile", "a stream has bytes no cell uses"));
        }
        let distinct = distinct as usize;
        let mut table = Self {
            distinct,
            sample_present: false,
            observed: Vec::new(),
            masks: Vec::new(),
        };
        match need {
            WalkNeed::StateAt(sample) => {
                table.sample_present = sample < axis.len() && !axis.is_missing(sample);
                table.observed = (0..distinct)
                    .map(|_| lists.parity_at(sample))
                    .collect::<Result<_, _>>()?;
            }
            WalkNeed::ModelOnly => {
                for _ in 0..distinct {
                    lists.skip_list()?;
                }
            }
            WalkNeed::Everything => {
                let mut scratch = Vec::new();
                table.masks.reserve(distinct);
                for _ in 0..distinct {
                    lists.next_list_into(&mut scratch)?;
                    if scratch.is_empty() {
                        return Err(corrupt(
                            "tile masks",
                            "a mask under which a cell is never observed",
                        ));
                    }
                    let toggles = Toggles::new(scratch.clone())
                        .map_err(|e| corrupt("tile masks", e.to_string()))?;
                    table.masks.push(Arc::new(toggles));
                }
            }
        }
        Ok(table)
    }

    /// The mask of a cell that refers to one (its index read from `refs`): the mask itself
    /// where the walk decoded masks, and whether it observes the queried sample.
    fn of_cell(
        &self,
        refs: &mut Cursor<'_>,
    ) -> Result<(Option<&Arc<Toggles>>, bool), FormatViolation> {
        let id = refs.varint()?;
        let index = usize::try_from(id)
            .ok()
            .filter(|&i| i < self.distinct)
            .ok_or_else(|| {
                corrupt(
                    "tile masks",
                    format!("mask index {id} beyond the {} masks", self.distinct),
                )
            })?;
        let observed = self.observed.get(index).copied().unwrap_or(false);
        Ok((self.masks.get(index), observed))
    }
}

/// Where the cells of a tile lie: gaps read from the geometry stream, checked against the
/// cells' depths and the tile.
struct Geometry<'a> {
    gaps: Cursor<'a>,
    previous_end: u64,
    tile_end: u64,
    tile_depth: u8,
}

impl Geometry<'_> {
    /// The start of the next cell, of depth `depth`.
    fn next_start(&mut self, depth: u8) -> Result<MortonCode, FormatViolation> {
        let gap = self.gaps.varint()?;
        let tile_depth = self.tile_depth;
        if !(tile_depth..=TREE_DEPTH).contains(&depth) {
            return Err(corrupt(
                "tile",
                format!("cell depth {depth} outside {tile_depth}..=16"),
            ));
        }
        let start = self
            .previous_end
            .checked_add(gap)
            .filter(|s| s & (voxels_per_node(depth) - 1) == 0)
            .ok_or_else(|| corrupt("tile", "cell not aligned to its depth"))?;
        let end = start + voxels_per_node(depth);
        if end > self.tile_end {
            return Err(corrupt("tile", "cell outside its tile"));
        }
        self.previous_end = end;
        Ok(MortonCode(start))
    }
}

/// The list readers of the list sets (masks, outliers, format 1.2's coded exceptions) over
/// the blocks at hand.
fn list_readers<'a>(
    cells: &PartStreams<'a>,
    blocks: &[(u32, PartStreams<'a>)],
    toggles: ToggleLayout,
    axis_len: u32,
    limits: (usize, u64),
) -> [ListReader<'a>; 3] {
    [
        (ListSet::Masks, "tile masks"),
        (ListSet::Outliers, "tile outliers"),
        (ListSet::Exceptions, "tile exceptions"),
    ]
    .map(|(set, part)| {
        let blocks = match toggles {
            ToggleLayout::Whole => vec![cells.list_block(set, 0)],
            ToggleLayout::Blocked(_) | ToggleLayout::Coded(_) => blocks
                .iter()
                .map(|(b, p)| p.list_block(set, toggles.block_span(*b, axis_len).0))
                .collect(),
        };
        let coded = set == ListSet::Exceptions;
        ListReader::new(blocks, toggles, coded, axis_len, part, limits)
    })
}

/// Parses a tile payload, handing each cell to `visit` in Morton order, decoding only what
/// `need` asks for. Validates the structure it reads; allocates per distinct mask and per
/// modelled cell only.
pub(crate) fn walk_payload(
    parts: &TileParts<'_>,
    code: MortonCode,
    layout: &TileLayout,
    model: &dyn PreparedModel,
    limits: &ReadLimits,
    need: WalkNeed,
    mut visit: impl FnMut(CellRef<'_>),
) -> Result<usize, FormatViolation> {
    let axis = model.axis();
    let (count, cells) = PartStreams::read(
        parts.cells,
        PartKind::cells_of(layout.toggles),
        limits.max_cells_per_tile,
    )?;
    if count == 0 {
        return Err(corrupt("tile", "no cells"));
    }
    let [mut masks, mut outliers, mut exceptions] = list_readers(
        &cells,
        &parts.blocks,
        layout.toggles,
        axis.len(),
        // A cell has at most one list of each set.
        (count, limits.max_toggles_per_tile),
    );
    let coded = matches!(layout.toggles, ToggleLayout::Coded(_));
    let (depths, classes) = (cells.get(Stream::Depth), cells.get(Stream::Class));
    if depths.len() != count || classes.len() != count {
        return Err(corrupt(
            "tile",
            "depth or class stream does not hold one byte per cell",
        ));
    }
    let mask_table = MaskTable::read(cells.get(Stream::MaskCount), &mut masks, count, need, axis)?;
    let mut mask_refs = Cursor::new(cells.get(Stream::MaskRefs), "tile masks");
    let mut geometry = Geometry {
        gaps: Cursor::new(cells.get(Stream::Geometry), "tile geometry"),
        previous_end: code.0,
        tile_end: code.0 + voxels_per_node(layout.tile_depth),
        tile_depth: layout.tile_depth,
    };
    let mut models = ModelStream::new(cells.get(Stream::Models), model);
    let mut scratch = Vec::new();
    for (&depth, &class) in depths.iter().zip(classes) {
        let start = geometry.next_start(depth)?;
        if class & !(CLASS_KIND_MASK | CLASS_HAS_MASK | CLASS_HAS_OUTLIERS) != 0 {
            return Err(corrupt("tile", format!("reserved class bits {class:#x}")));
        }
        let (mask, mask_observed) = if class & CLASS_HAS_MASK != 0 {
            mask_table.of_cell(&mut mask_refs)?
        } else {
            (None, true)
        };
        let mut outlier_parity = false;
        let mut has_list = false;
        if class & CLASS_HAS_OUTLIERS != 0 {
            // Format 1.2 codes the exceptions of constant cells apart.
            let lists = if coded && class & CLASS_KIND_MASK != CLASS_MODELLED {
                &mut exceptions
            } else {
                &mut outliers
            };
            match need {
                WalkNeed::Everything => {
                    has_list = true;
                    lists.next_list_into(&mut scratch)?;
                    if scratch.is_empty() {
                        return Err(corrupt(
                            "tile outliers",
                            "an empty outlier list is stored by leaving the flag clear",
                        ));
                    }
                }
                WalkNeed::StateAt(sample) => outlier_parity = lists.parity_at(sample)?,
                WalkNeed::ModelOnly => lists.skip_list()?,
            }
        }
        // A modelled cell passes its parameter bytes in place: the model delimits and
        // validates them, and evaluates them without decoding.
        let (constant, model_ref) = match class & CLASS_KIND_MASK {
            CLASS_FREE => (Some(Occupancy::Free), None),
            CLASS_OCCUPIED => (Some(Occupancy::Occupied), None),
            CLASS_MODELLED => (None, Some(models.next_parameters()?)),
            _ => return Err(corrupt("tile", "invalid cell class 3")),
        };
        visit(CellRef {
            start,
            depth,
            mask,
            constant,
            model: model_ref,
            // Not `&scratch` for every cell: storing its cleared length and loading it back
            // with the pointer stalled the loop (a store-to-load forwarding failure).
            outliers: if has_list { &scratch } else { &[] },
            observed: mask_table.sample_present && mask_observed,
            outlier_parity,
            has_mask: class & CLASS_HAS_MASK != 0,
            has_outliers: class & CLASS_HAS_OUTLIERS != 0,
        });
    }
    if !geometry.gaps.is_empty() || !mask_refs.is_empty() || !models.is_done() {
        return Err(corrupt("tile", "a stream has bytes no cell uses"));
    }
    masks.finish()?;
    outliers.finish()?;
    exceptions.finish()?;
    Ok(count)
}

/// Parses a tile payload, handing each cell, built, to `visit` in Morton order. Holds one
/// cell at a time: a caller that needs the tile's cells collects them.
pub(crate) fn visit_payload_cells(
    parts: &TileParts<'_>,
    code: MortonCode,
    layout: &TileLayout,
    model: &dyn PreparedModel,
    limits: &ReadLimits,
    mut visit: impl FnMut(Cell),
) -> Result<usize, FormatViolation> {
    let mut invalid = None;
    let count = walk_payload(
        parts,
        code,
        layout,
        model,
        limits,
        WalkNeed::Everything,
        |cell: CellRef<'_>| {
            let outliers = if cell.outliers.is_empty() {
                None
            } else {
                match Toggles::new(cell.outliers.to_vec()) {
                    Ok(t) => Some(t),
                    Err(e) => {
                        invalid.get_or_insert(e.to_string());
                        None
                    }
                }
            };
            let content = match (cell.constant, cell.model, outliers) {
                (Some(state), _, None) => CellContent::Constant(state),
                (Some(state), _, Some(exceptions)) => {
                    CellContent::ConstantExcept { state, exceptions }
                }
                (None, Some(parameters), outliers) => {
                    CellContent::Modelled(model::with_outliers(parameters, outliers))
                }
                (None, None, _) => return,
            };
            visit(Cell {
                start: cell.start,
                depth: cell.depth,
                mask: cell.mask.cloned(),
                content,
            });
        },
    )?;
    if let Some(detail) = invalid {
        return Err(corrupt("tile outliers", detail));
    }
    Ok(count)
}
