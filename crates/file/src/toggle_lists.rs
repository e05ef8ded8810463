//! A tile's toggle lists (observation masks, outliers) as stored streams
//! ([FORMAT.md §5.4](../../../docs/FORMAT.md)): whole lists in format 1.0, lists cut into
//! blocks of samples in format 1.1 so that a query at one sample reads one block, and those
//! blocks range coded in format 1.2 ([`crate::toggle_code`]).

use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation};
use crate::limits::ToggleBudget;
use crate::toggle_code::{BlockEncoder, CodedListReader};
use froctomap_temporal::varint;

/// How a file stores toggle lists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToggleLayout {
    /// Format 1.0: every list whole, in one set of toggle columns per tile.
    Whole,
    /// Format 1.1: the time axis cut into blocks of this many samples (at least 1); per block,
    /// each list's parity at the block's start, whether it has positions inside the block,
    /// and those positions, as varint columns under the file's codec.
    Blocked(u32),
    /// Format 1.2: blocks as in 1.1, each list set's block coded as events (one-sample
    /// pulses as one) with an adaptive range coder instead of varints under the codec.
    Coded(u32),
}

impl ToggleLayout {
    /// froctomap's default: blocks of 256 samples, range coded (format 1.2).
    pub const DEFAULT: ToggleLayout = ToggleLayout::Coded(256);

    /// The layout of the latest format for blocks of `samples` samples: whole lists
    /// (format 1.0) for 0, else range-coded blocks (format 1.2).
    pub fn blocks_of(samples: u32) -> ToggleLayout {
        match samples {
            0 => ToggleLayout::Whole,
            samples => ToggleLayout::Coded(samples),
        }
    }

    /// Samples per block, `None` for whole lists.
    pub fn block_len(self) -> Option<u32> {
        match self {
            ToggleLayout::Whole => None,
            ToggleLayout::Blocked(len) | ToggleLayout::Coded(len) => Some(len),
        }
    }

    /// Number of blocks of an axis of `axis_len` samples (1 for the whole layout).
    pub(crate) fn blocks(self, axis_len: u32) -> u32 {
        match self {
            ToggleLayout::Whole => 1,
            ToggleLayout::Blocked(len) | ToggleLayout::Coded(len) => {
                axis_len.div_ceil(len.max(1)).max(1)
            }
        }
    }

    /// First sample and length of block `b`.
    pub(crate) fn block_span(self, b: u32, axis_len: u32) -> (u32, u32) {
        match self {
            ToggleLayout::Whole => (0, axis_len),
            ToggleLayout::Blocked(len) | ToggleLayout::Coded(len) => {
                let start = b.saturating_mul(len);
                (start, len.min(axis_len.saturating_sub(start)))
            }
        }
    }
}

/// Lists of toggles stored column-wise: each list's length, the gaps before toggles at even
/// positions (where a run of the other state starts) and those before odd positions (one
/// less than the run's length). Separating them lets zstd model each distribution on its
/// own: run starts are spread out, run lengths are mostly tiny (a one-sample flicker is 0).
///
/// Sparse columns (the blocked layout) give counts only for the lists with positions, and a
/// *lists* bitmap marking them (bit `l mod 8` of byte `⌊l/8⌋`): most lists have no toggle in
/// a given block.
#[derive(Default)]
struct ToggleColumns {
    sparse: bool,
    /// Lists pushed so far.
    lists: u64,
    present: Vec<u8>,
    counts: Vec<u8>,
    starts: Vec<u8>,
    lengths: Vec<u8>,
}

impl ToggleColumns {
    fn sparse() -> Self {
        Self {
            sparse: true,
            ..Self::default()
        }
    }

    /// Appends a list of positions, all `≥ origin`, gap-coded from `origin`.
    fn push(&mut self, positions: &[u32], origin: u32) {
        let index = self.lists;
        self.lists += 1;
        if self.sparse {
            if index % 8 == 0 {
                self.present.push(0);
            }
            if positions.is_empty() {
                return;
            }
            if let Some(byte) = self.present.last_mut() {
                *byte |= 1 << (index % 8);
            }
        }
        varint::write_u64(&mut self.counts, positions.len() as u64);
        let mut next = origin;
        for (k, &t) in positions.iter().enumerate() {
            let column = if k % 2 == 0 {
                &mut self.starts
            } else {
                &mut self.lengths
            };
            varint::write_u32(column, t - next);
            next = t.saturating_add(1);
        }
    }
}

/// The columns of one block of a set of toggle lists. [`ToggleLayout::Whole`] has no
/// parity or lists bitmap: those columns stay empty and are not stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Column {
    /// Each list's parity at the block's start (a bitmap).
    Parity,
    /// Which lists have positions in the block (a bitmap).
    Lists,
    /// The number of positions of each (listed) list.
    Counts,
    /// Gaps before the toggles at even positions.
    Starts,
    /// Gaps before the toggles at odd positions.
    Lengths,
    /// Format 1.2: the block's lists range coded.
    Code,
}

/// One block's encoded columns, by [`Column`].
#[derive(Default)]
pub(crate) struct ListColumns([Vec<u8>; 6]);

impl ListColumns {
    pub(crate) fn get(&self, column: Column) -> &[u8] {
        &self.0[column as usize]
    }
}

/// The columns of a set of toggle lists (each strictly increasing, below `axis_len`), per
/// block: the one block of the whole layout, or each block of the blocked ones.
#[cfg(test)]
pub(crate) fn encode_lists(
    lists: &[&[u32]],
    layout: ToggleLayout,
    axis_len: u32,
) -> Vec<ListColumns> {
    let mut encoder = ListsEncoder::columns(layout, axis_len);
    for list in lists {
        encoder.push(list);
    }
    encoder.finish()
}

/// A set of toggle lists (each strictly increasing, below the axis' length) encoded one list
/// at a time, per block of the layout: as varint columns ([`columns`](Self::columns)), or
/// range coded (format 1.2, [`coded`](Self::coded)). A list is cut into its blocks as it is
/// pushed, so a tile's lists need not be held until the tile is complete.
pub(crate) struct ListsEncoder {
    layout: ToggleLayout,
    axis_len: u32,
    /// Lists pushed so far.
    lists: usize,
    blocks: BlockEncoders,
}

enum BlockEncoders {
    /// Per block, the toggle columns and the lists' parity bitmap (empty in the whole layout).
    Columns(Vec<(ToggleColumns, Vec<u8>)>),
    /// Per block, the range coder; and a buffer for positions relative to a block's start.
    Coded(Vec<BlockEncoder>, Vec<u32>),
}

impl ListsEncoder {
    /// Lists stored as varint columns under the file's codec.
    pub(crate) fn columns(layout: ToggleLayout, axis_len: u32) -> Self {
        let blocks = (0..layout.blocks(axis_len))
            .map(|_| match layout {
                ToggleLayout::Whole => (ToggleColumns::default(), Vec::new()),
                ToggleLayout::Blocked(_) | ToggleLayout::Coded(_) => {
                    (ToggleColumns::sparse(), Vec::new())
                }
            })
            .collect();
        Self {
            layout,
            axis_len,
            lists: 0,
            blocks: BlockEncoders::Columns(blocks),
        }
    }

    /// Lists range coded per block (format 1.2).
    pub(crate) fn coded(layout: ToggleLayout, axis_len: u32) -> Self {
        let encoders = (0..layout.blocks(axis_len))
            .map(|b| BlockEncoder::new(layout.block_span(b, axis_len).1, b > 0))
            .collect();
        Self {
            layout,
            axis_len,
            lists: 0,
            blocks: BlockEncoders::Coded(encoders, Vec::new()),
        }
    }

    /// Adds the next list.
    pub(crate) fn push(&mut self, list: &[u32]) {
        let l = self.lists;
        self.lists += 1;
        let (layout, axis_len) = (self.layout, self.axis_len);
        let mut rest = list;
        match &mut self.blocks {
            BlockEncoders::Columns(blocks) => {
                let has_parity = layout != ToggleLayout::Whole;
                for (b, (column, parity)) in blocks.iter_mut().enumerate() {
                    let (start, len) = layout.block_span(b as u32, axis_len);
                    if has_parity && l % 8 == 0 {
                        parity.push(0);
                    }
                    if (list.len() - rest.len()) % 2 == 1 {
                        if let Some(byte) = parity.get_mut(l / 8) {
                            *byte |= 1 << (l % 8);
                        }
                    }
                    let inside = rest.partition_point(|&t| t < start + len);
                    column.push(&rest[..inside], start);
                    rest = &rest[inside..];
                }
            }
            BlockEncoders::Coded(encoders, relative) => {
                for (b, encoder) in encoders.iter_mut().enumerate() {
                    let (start, len) = layout.block_span(b as u32, axis_len);
                    let parity = (list.len() - rest.len()) % 2 == 1;
                    let inside = rest.partition_point(|&t| t < start + len);
                    relative.clear();
                    relative.extend(rest[..inside].iter().map(|&t| t - start));
                    encoder.push(parity, relative.as_slice());
                    rest = &rest[inside..];
                }
            }
        }
    }

    /// The columns of each block.
    pub(crate) fn finish(self) -> Vec<ListColumns> {
        match self.blocks {
            BlockEncoders::Columns(blocks) => blocks
                .into_iter()
                .map(|(column, parity)| {
                    ListColumns([
                        parity,
                        column.present,
                        column.counts,
                        column.starts,
                        column.lengths,
                        Vec::new(),
                    ])
                })
                .collect(),
            BlockEncoders::Coded(encoders, _) => encoders
                .into_iter()
                .map(|encoder| {
                    let mut columns: [Vec<u8>; 6] = Default::default();
                    columns[Column::Code as usize] = encoder.finish();
                    ListColumns(columns)
                })
                .collect(),
        }
    }
}

/// One block's streams of a list set, as read from a tile: its first sample, its parity
/// bitmap (empty in the whole layout), its lists bitmap (blocked layout) and its toggle
/// columns.
pub(crate) struct ListBlock<'a> {
    pub(crate) start: u32,
    pub(crate) parity: &'a [u8],
    /// The sparse columns' lists stream (blocked layout only).
    pub(crate) present: Option<&'a [u8]>,
    pub(crate) columns: [&'a [u8]; 3],
    /// The block's range-coded lists (coded layout only).
    pub(crate) code: &'a [u8],
}

/// Bit `index` of a bitmap (bit `index mod 8` of byte `⌊index/8⌋`), `None` past its end.
#[inline]
fn bit(bitmap: &[u8], index: u64) -> Option<bool> {
    let byte = bitmap.get(usize::try_from(index / 8).ok()?)?;
    Some(byte >> (index % 8) & 1 == 1)
}

/// `true` when a bitmap holds exactly `count` bits: `⌈count/8⌉` bytes, unused high bits 0.
fn holds_exactly(bitmap: &[u8], count: u64) -> bool {
    let used = count % 8;
    bitmap.len() as u64 == count.div_ceil(8)
        && bitmap
            .last()
            .is_none_or(|&last| used == 0 || last >> used == 0)
}

/// Blocks in buckets by the next list each holds toggles of: reading every list whole takes
/// each block from its bucket once per list it holds, at no cost growing with the blocks
/// (a heap cost log(blocks) each time, and a long history has thousands of blocks).
struct WaitingBlocks {
    /// Per list, the block put last in its bucket ([`NO_BLOCK`]: none).
    last: Vec<u32>,
    /// Per block, the block put in the same bucket before it.
    before: Vec<u32>,
    /// The blocks of the bucket being read (kept to reuse its allocation).
    taken: Vec<usize>,
}

const NO_BLOCK: u32 = u32::MAX;

impl WaitingBlocks {
    fn new(lists: usize, blocks: usize) -> Self {
        Self {
            last: vec![NO_BLOCK; lists],
            before: vec![NO_BLOCK; blocks],
            taken: Vec::new(),
        }
    }

    /// Puts `block` in the bucket of `list`; a list past the most read is never read, and
    /// what its block holds is refused when the reader finishes.
    fn put(&mut self, list: u64, block: usize) {
        let bucket = usize::try_from(list)
            .ok()
            .and_then(|l| self.last.get_mut(l));
        if let (Some(last), Some(before), Ok(id)) =
            (bucket, self.before.get_mut(block), u32::try_from(block))
        {
            *before = *last;
            *last = id;
        }
    }

    /// Empties the bucket of `list` into `blocks`, in block order.
    fn take(&mut self, list: usize, blocks: &mut Vec<usize>) {
        blocks.clear();
        let Some(last) = self.last.get_mut(list) else {
            return;
        };
        let mut block = std::mem::replace(last, NO_BLOCK);
        while block != NO_BLOCK {
            blocks.push(block as usize);
            block = self.before.get(block as usize).copied().unwrap_or(NO_BLOCK);
        }
        blocks.sort_unstable();
    }
}

/// Reads a tile's toggle lists in order from the blocks at hand: the single block of the
/// whole layout, every block (to read lists whole), or the one block holding a queried
/// sample.
pub(crate) struct ToggleListReader<'a> {
    layout: ToggleLayout,
    blocks: Vec<(&'a [u8], u32, ToggleColumnReader<'a>)>,
    /// Lists read so far.
    read: usize,
    part: &'static str,
    /// Reading whole lists in the blocked layout: the blocks by the next list each holds
    /// toggles of (filled on the first whole list). A list is read from the blocks listing
    /// it only, so that reading every list costs the toggles and the bitmaps' bytes, not
    /// lists × blocks.
    pending: Option<WaitingBlocks>,
    /// Most lists read (the tile's cells): the buckets of `pending`.
    max_read: usize,
    /// Per block, the lists with an odd number of toggles in it: the parity bitmaps of
    /// consecutive blocks must differ in exactly those lists (checked by [`finish`](Self::finish)).
    odd_lists: Vec<u64>,
    /// Toggles decoded so far, and the most allowed.
    budget: ToggleBudget,
}

impl<'a> ToggleListReader<'a> {
    /// A reader over `blocks` (in block order) of an axis of `axis_len` samples, reading at
    /// most `max_read` lists and decoding at most `max_toggles` toggles.
    pub(crate) fn new(
        blocks: Vec<ListBlock<'a>>,
        layout: ToggleLayout,
        axis_len: u32,
        part: &'static str,
        limits: (usize, u64),
    ) -> Self {
        let (max_read, max_toggles) = limits;
        let blocks: Vec<_> = blocks
            .into_iter()
            .map(|block| {
                let len = match layout {
                    ToggleLayout::Whole => axis_len,
                    ToggleLayout::Blocked(len) | ToggleLayout::Coded(len) => {
                        len.min(axis_len.saturating_sub(block.start))
                    }
                };
                let reader = ToggleColumnReader::new(block.columns, block.present, len, part);
                (block.parity, block.start, reader)
            })
            .collect();
        Self {
            layout,
            odd_lists: vec![0; blocks.len()],
            blocks,
            read: 0,
            part,
            pending: None,
            max_read,
            budget: ToggleBudget::new(max_toggles),
        }
    }

    /// Upper bound on the lists the streams can hold.
    pub(crate) fn max_lists(&self) -> usize {
        match (self.layout, self.blocks.first()) {
            (ToggleLayout::Whole, Some((_, _, reader))) => reader.max_lists(),
            (ToggleLayout::Blocked(_) | ToggleLayout::Coded(_), Some((parity, _, _))) => {
                parity.len() * 8
            }
            _ => usize::MAX,
        }
    }

    fn parity_bit(&self, parity: &[u8], list: usize) -> Result<bool, FormatViolation> {
        bit(parity, list as u64)
            .ok_or_else(|| corrupt(self.part, "parity bitmap shorter than the lists"))
    }

    /// Passes over the next list (undecoded in the whole layout, not read at all in the
    /// blocked one).
    pub(crate) fn skip_list(&mut self) -> Result<(), FormatViolation> {
        if self.layout == ToggleLayout::Whole {
            if let Some((_, _, reader)) = self.blocks.first_mut() {
                reader.skip_list()?;
            }
        }
        self.read += 1;
        Ok(())
    }

    /// Whether an odd number of the next list's positions are `≤ sample`, from the first
    /// block at hand (the one holding the sample).
    #[inline]
    pub(crate) fn parity_at(&mut self, sample: u32) -> Result<bool, FormatViolation> {
        let list = self.read;
        self.read += 1;
        let Some((parity, start, reader)) = self.blocks.first_mut() else {
            return Ok(false);
        };
        let within = reader.parity_at(sample.saturating_sub(*start))?;
        if self.layout == ToggleLayout::Whole {
            return Ok(within);
        }
        let parity = *parity;
        Ok(self.parity_bit(parity, list)? ^ within)
    }

    /// Reads the next list whole into `positions` (cleared first). In the blocked layout
    /// only the blocks listing it are visited; their parity bits are checked here for the
    /// blocks after them and by [`finish`](Self::finish) for the others.
    pub(crate) fn next_list_into(
        &mut self,
        positions: &mut Vec<u32>,
    ) -> Result<(), FormatViolation> {
        positions.clear();
        let list = self.read;
        self.read += 1;
        if self.layout == ToggleLayout::Whole {
            if let Some((_, _, reader)) = self.blocks.first_mut() {
                reader.next_list_into(positions)?;
            }
            return self.budget.spend(positions.len() as u64);
        }
        let pending = match &mut self.pending {
            Some(pending) => pending,
            None => {
                let mut waiting = WaitingBlocks::new(self.max_read, self.blocks.len());
                for (b, (_, _, reader)) in self.blocks.iter().enumerate() {
                    if let Some(next) = reader.next_listed() {
                        // Lists passed over before (none in a walk) are read with this one.
                        waiting.put(next.max(list as u64), b);
                    }
                }
                self.pending.insert(waiting)
            }
        };
        let mut scratch = Vec::new();
        // Each block's next list only grows, and every list is read in turn: the blocks
        // waiting for this one are all there are with toggles of it.
        let mut listing = std::mem::take(&mut pending.taken);
        pending.take(list, &mut listing);
        for &b in &listing {
            let (parity, start, reader) = &mut self.blocks[b];
            let parity = bit(parity, list as u64)
                .ok_or_else(|| corrupt(self.part, "parity bitmap shorter than the lists"))?;
            if parity != (positions.len() % 2 == 1) {
                return Err(corrupt(
                    self.part,
                    "a block's parity bit disagrees with the toggles before it",
                ));
            }
            reader.skip_to(list as u64);
            reader.next_list_into(&mut scratch)?;
            positions.extend(scratch.iter().map(|&t| *start + t));
            if scratch.len() % 2 == 1 {
                self.odd_lists[b] += 1;
            }
            if let Some(next) = reader.next_listed() {
                pending.put(next, b);
            }
        }
        pending.taken = listing;
        self.budget.spend(positions.len() as u64)
    }

    /// Checks that the blocks at hand held exactly the lists read.
    pub(crate) fn finish(&mut self) -> Result<(), FormatViolation> {
        let whole_lists = self.pending.is_some();
        for (parity, start, reader) in &mut self.blocks {
            if whole_lists {
                // Lists a block does not list were not visited in it.
                reader.skip_to(self.read as u64);
            }
            reader.finish()?;
            if self.layout == ToggleLayout::Whole {
                continue;
            }
            if !holds_exactly(parity, self.read as u64) {
                return Err(corrupt(self.part, "parity bitmap does not fit the lists"));
            }
            if *start == 0 && parity.iter().any(|&b| b != 0) {
                return Err(corrupt(
                    self.part,
                    "parity before the first sample must be even",
                ));
            }
        }
        // The lists with odd toggles in a block were checked to flip their parity bit at
        // the next block: no other bit may flip.
        for (pair, &odd) in self.blocks.windows(2).zip(&self.odd_lists) {
            let flipped: u64 = pair[0]
                .0
                .iter()
                .zip(pair[1].0)
                .map(|(a, b)| u64::from((a ^ b).count_ones()))
                .sum();
            if flipped != odd {
                return Err(corrupt(
                    self.part,
                    "a block's parity bit disagrees with the toggles before it",
                ));
            }
        }
        Ok(())
    }
}

/// Reads a list set's lists, from varint columns or range-coded blocks (format 1.2's
/// exceptions).
pub(crate) enum ListReader<'a> {
    Columns(ToggleListReader<'a>),
    Coded(CodedListReader<'a>),
}

impl<'a> ListReader<'a> {
    /// A reader over `blocks` (the one block of the whole layout, or the blocks at hand):
    /// their range-coded streams when `coded`, else their columns.
    pub(crate) fn new(
        blocks: Vec<ListBlock<'a>>,
        layout: ToggleLayout,
        coded: bool,
        axis_len: u32,
        part: &'static str,
        limits: (usize, u64),
    ) -> Self {
        let max_toggles = limits.1;
        match (layout, coded) {
            (ToggleLayout::Coded(len), true) => ListReader::Coded(CodedListReader::new(
                blocks.into_iter().map(|block| {
                    let samples = len.min(axis_len.saturating_sub(block.start));
                    (block.start, samples, block.code)
                }),
                part,
                max_toggles,
            )),
            // The coded layout keeps its other lists in 1.1's columns.
            (ToggleLayout::Coded(len), false) => ListReader::Columns(ToggleListReader::new(
                blocks,
                ToggleLayout::Blocked(len),
                axis_len,
                part,
                limits,
            )),
            _ => ListReader::Columns(ToggleListReader::new(
                blocks, layout, axis_len, part, limits,
            )),
        }
    }

    /// Upper bound on the lists the streams can hold.
    pub(crate) fn max_lists(&self) -> usize {
        match self {
            ListReader::Columns(reader) => reader.max_lists(),
            ListReader::Coded(_) => usize::MAX,
        }
    }

    pub(crate) fn skip_list(&mut self) -> Result<(), FormatViolation> {
        match self {
            ListReader::Columns(reader) => reader.skip_list(),
            ListReader::Coded(reader) => reader.skip_list(),
        }
    }

    #[inline]
    pub(crate) fn parity_at(&mut self, sample: u32) -> Result<bool, FormatViolation> {
        match self {
            ListReader::Columns(reader) => reader.parity_at(sample),
            ListReader::Coded(reader) => reader.parity_at(sample),
        }
    }

    pub(crate) fn next_list_into(
        &mut self,
        positions: &mut Vec<u32>,
    ) -> Result<(), FormatViolation> {
        match self {
            ListReader::Columns(reader) => reader.next_list_into(positions),
            ListReader::Coded(reader) => reader.next_list_into(positions),
        }
    }

    pub(crate) fn finish(&mut self) -> Result<(), FormatViolation> {
        match self {
            ListReader::Columns(reader) => reader.finish(),
            ListReader::Coded(reader) => reader.finish(),
        }
    }
}

/// Reads [`ToggleColumns`] back, validating every position against the span they cover.
pub(crate) struct ToggleColumnReader<'a> {
    /// Sparse columns: the lists bitmap and the index of the next list.
    present: Option<&'a [u8]>,
    index: u64,
    counts: Cursor<'a>,
    starts: Cursor<'a>,
    lengths: Cursor<'a>,
    axis_len: u32,
    part: &'static str,
}

impl<'a> ToggleColumnReader<'a> {
    fn new(
        columns: [&'a [u8]; 3],
        present: Option<&'a [u8]>,
        axis_len: u32,
        part: &'static str,
    ) -> Self {
        let [counts, starts, lengths] = columns;
        Self {
            present,
            index: 0,
            counts: Cursor::new(counts, part),
            starts: Cursor::new(starts, part),
            lengths: Cursor::new(lengths, part),
            axis_len,
            part,
        }
    }

    /// The next list at or after the current one that the lists bitmap marks (sparse
    /// columns), scanning the bitmap a byte at a time.
    fn next_listed(&self) -> Option<u64> {
        let present = self.present?;
        let mut at = self.index;
        loop {
            let byte = *present.get(usize::try_from(at / 8).ok()?)?;
            let rest = byte >> (at % 8);
            if rest != 0 {
                return Some(at + u64::from(rest.trailing_zeros()));
            }
            at = (at / 8 + 1) * 8;
        }
    }

    /// Passes over lists the bitmap does not mark, up to `list` (sparse columns).
    fn skip_to(&mut self, list: u64) {
        self.index = self.index.max(list);
    }

    /// Upper bound on the lists left (each takes at least one count byte).
    fn max_lists(&self) -> usize {
        self.counts.remaining()
    }

    #[inline]
    fn count(&mut self) -> Result<u64, FormatViolation> {
        if let Some(present) = self.present {
            let index = self.index;
            self.index += 1;
            let listed = bit(present, index)
                .ok_or_else(|| corrupt(self.part, "lists bitmap shorter than the lists"))?;
            if !listed {
                return Ok(0);
            }
        }
        let left = (self.starts.remaining() + self.lengths.remaining()) as u64;
        let count = self.counts.varint()?;
        if count > left || count > u64::from(self.axis_len) {
            return Err(corrupt(self.part, format!("{count} toggles cannot fit")));
        }
        if count == 0 {
            // Whole lists are never empty (an empty mask or outlier list is stored by
            // leaving the cell's flag clear), nor is a list the lists bitmap marks.
            return Err(corrupt(
                self.part,
                if self.present.is_some() {
                    "a listed list without toggles"
                } else {
                    "an empty list is stored by leaving the cell's flag clear"
                },
            ));
        }
        Ok(count)
    }

    /// Passes over the next list, checking its positions as
    /// [`next_list_into`](Self::next_list_into) does without keeping them.
    fn skip_list(&mut self) -> Result<(), FormatViolation> {
        let count = self.count()?;
        let mut next = 0u64;
        for k in 0..count {
            next = self.next_position(k, next)? + 1;
        }
        Ok(())
    }

    /// Whether an odd number of the next list's positions are `≤ sample`: the fast path of
    /// a query at one sample. Every position is decoded and checked as
    /// [`next_list_into`](Self::next_list_into) checks it (a position past the span, or
    /// one whose gap overflows, is an error), so that a damaged list never reads as a
    /// different map than the full walk would accept; only the positions are not kept.
    #[inline]
    fn parity_at(&mut self, sample: u32) -> Result<bool, FormatViolation> {
        let count = self.count()?;
        let sample = u64::from(sample);
        let mut odd = false;
        let mut next = 0u64;
        for k in 0..count {
            let position = self.next_position(k, next)?;
            odd ^= position <= sample;
            next = position + 1;
        }
        Ok(odd)
    }

    /// The list's position `k` (from the starts column for even `k`, the lengths column
    /// for odd), `next` being one past the position before it: checked against the span.
    #[inline]
    fn next_position(&mut self, k: u64, next: u64) -> Result<u64, FormatViolation> {
        let column = if k % 2 == 0 {
            &mut self.starts
        } else {
            &mut self.lengths
        };
        next.checked_add(column.varint()?)
            .filter(|&position| position < u64::from(self.axis_len))
            .ok_or_else(|| corrupt(self.part, "toggle beyond the time axis"))
    }

    /// Reads the next list into `positions` (cleared first), reusing its allocation.
    fn next_list_into(&mut self, positions: &mut Vec<u32>) -> Result<(), FormatViolation> {
        positions.clear();
        let count = self.count()?;
        positions.reserve(count as usize);
        let mut next = 0u64;
        for k in 0..count {
            // Below the span's length, a u32.
            let position = self.next_position(k, next)?;
            positions.push(position as u32);
            next = position + 1;
        }
        Ok(())
    }

    fn finish(&self) -> Result<(), FormatViolation> {
        let lists_done = self
            .present
            .is_none_or(|bits| holds_exactly(bits, self.index));
        if lists_done && self.counts.is_empty() && self.starts.is_empty() && self.lengths.is_empty()
        {
            Ok(())
        } else {
            Err(corrupt(self.part, "bytes no list uses"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lists over 12 samples in blocks of 4: list 1 toggles once in block 0, so its parity
    /// bit is set in blocks 1 and 2.
    const LISTS: [&[u32]; 3] = [&[1, 5], &[3], &[2, 9]];
    const LAYOUT: ToggleLayout = ToggleLayout::Blocked(4);

    fn blocks_of(columns: &[ListColumns]) -> Vec<ListBlock<'_>> {
        blocks_in(columns, LAYOUT, 12)
    }

    fn blocks_in(
        columns: &[ListColumns],
        layout: ToggleLayout,
        axis_len: u32,
    ) -> Vec<ListBlock<'_>> {
        columns
            .iter()
            .enumerate()
            .map(|(b, c)| ListBlock {
                start: layout.block_span(b as u32, axis_len).0,
                parity: c.get(Column::Parity),
                present: Some(c.get(Column::Lists)),
                columns: [
                    c.get(Column::Counts),
                    c.get(Column::Starts),
                    c.get(Column::Lengths),
                ],
                code: &[],
            })
            .collect()
    }

    fn read_whole(columns: &[ListColumns]) -> Result<Vec<Vec<u32>>, FormatViolation> {
        let blocks = blocks_of(columns);
        let mut reader = ToggleListReader::new(blocks, LAYOUT, 12, "lists", (LISTS.len(), 100));
        let mut lists = Vec::new();
        for _ in LISTS {
            let mut positions = Vec::new();
            reader.next_list_into(&mut positions)?;
            lists.push(positions);
        }
        reader.finish()?;
        Ok(lists)
    }

    #[test]
    fn whole_lists_read_back_and_every_parity_bit_is_checked() {
        let columns = encode_lists(&LISTS, LAYOUT, 12);
        assert_eq!(read_whole(&columns).unwrap(), LISTS.map(<[u32]>::to_vec));
        // Flipping any parity bit of any block is found, whether or not the list has
        // toggles in the blocks around it.
        for block in 0..columns.len() {
            for list in 0..LISTS.len() {
                let mut damaged = encode_lists(&LISTS, LAYOUT, 12);
                damaged[block].0[Column::Parity as usize][0] ^= 1 << list;
                let err = read_whole(&damaged).unwrap_err();
                assert!(err.to_string().contains("parity"), "{block} {list}: {err}");
            }
        }
    }

    #[test]
    fn toggles_beyond_the_limit_are_refused() {
        let columns = encode_lists(&LISTS, LAYOUT, 12);
        let blocks = blocks_of(&columns);
        let mut reader = ToggleListReader::new(blocks, LAYOUT, 12, "lists", (LISTS.len(), 2));
        let mut positions = Vec::new();
        reader.next_list_into(&mut positions).unwrap();
        let err = reader.next_list_into(&mut positions).unwrap_err();
        assert!(
            matches!(
                err,
                FormatViolation::Limit {
                    value: 3,
                    limit: 2,
                    ..
                }
            ),
            "{err}"
        );
    }

    proptest::proptest! {
        /// Lists spread over many blocks (a list in several, several in one, blocks with
        /// none) read back whole, and their parity at any sample is the count before it.
        #[test]
        fn lists_over_many_blocks_read_back_whole(
            lists in proptest::collection::vec(
                proptest::collection::btree_set(0u32..200, 1..12), 1..40),
            block in 1u32..16,
            sample in 0u32..200,
        ) {
            let lists: Vec<Vec<u32>> = lists.into_iter().map(|l| l.into_iter().collect()).collect();
            let refs: Vec<&[u32]> = lists.iter().map(Vec::as_slice).collect();
            let layout = ToggleLayout::Blocked(block);
            let columns = encode_lists(&refs, layout, 200);
            let mut whole = ToggleListReader::new(blocks_in(&columns, layout, 200), layout, 200, "lists", (lists.len(), 1 << 20));
            for list in &lists {
                let mut positions = Vec::new();
                whole.next_list_into(&mut positions).unwrap();
                proptest::prop_assert_eq!(&positions, list);
            }
            whole.finish().unwrap();
            // At one sample: the block holding it alone.
            let at = (sample / block) as usize;
            let mut one = ToggleListReader::new(blocks_in(&columns, layout, 200).into_iter().skip(at).take(1).collect(), layout, 200, "lists", (lists.len(), 1 << 20));
            for list in &lists {
                let odd = list.iter().filter(|&&t| t <= sample).count() % 2 == 1;
                proptest::prop_assert_eq!(one.parity_at(sample).unwrap(), odd);
            }
        }
    }
}
