//! Format 1.2's coded toggle lists (the exceptions of constant cells): a list set's lists
//! in one toggle block coded as events with the adaptive [range coder](crate::range_coder)
//! ([FORMAT.md §5.5](../../../docs/FORMAT.md)).
//!
//! Per list: whether it is *quiet* (parity 0 at the block's start, no toggle in the block:
//! most lists, one decision); if not, its parity (not coded in block 0), then events until a
//! "no more" bit or the block's end: the gap to the next toggle (its bit length in an
//! adaptive bit tree, then the bits below the leading one as direct bits) and, unless the
//! toggle is the block's last sample, whether the next sample toggles back (a *pulse*: a
//! one-sample flicker costs one event instead of two toggles). Contexts: the list's state
//! before the event (even or odd number of toggles so far) and whether it is the list's
//! first event in the block. Decisions whose outcome is known are not coded.

use crate::error::{corrupt, FormatViolation};
use crate::limits::ToggleBudget;
use crate::range_coder::{Decoder, Encoder, Prob};

/// Gaps before a flip away from the usual state are coded uniformly below this many
/// samples: sensor noise flips anywhere alike.
const UNIFORM_LIMIT: u32 = 1 << 16;
/// Bits of a gap's exponent, its bit length `0..=32`.
const EXPONENT_BITS: u32 = 6;

/// The adaptive probabilities of one list set in one block.
#[derive(Clone)]
struct Contexts {
    /// Whether a list has parity 0 and no event in the block.
    quiet: Prob,
    parity: Prob,
    /// `[state][first event]`
    more: [[Prob; 2]; 2],
    /// `[state after the toggle]`
    pulse: [Prob; 2],
    /// `[state]`, nodes `1..64` of the exponent's bit tree.
    exponent: [[Prob; 1 << EXPONENT_BITS]; 2],
}

impl Default for Contexts {
    fn default() -> Self {
        Self {
            quiet: Prob::default(),
            parity: Prob::default(),
            more: [[Prob::default(); 2]; 2],
            pulse: [Prob::default(); 2],
            exponent: [[Prob::default(); 1 << EXPONENT_BITS]; 2],
        }
    }
}

/// Codes one block of a list set: [`push`](Self::push) each list, then
/// [`finish`](Self::finish).
pub(crate) struct BlockEncoder {
    coder: Encoder,
    contexts: Contexts,
    len: u32,
    code_parity: bool,
}

impl BlockEncoder {
    /// A block of `len` samples; `code_parity` is false for block 0 (parities are 0 there).
    pub(crate) fn new(len: u32, code_parity: bool) -> Self {
        Self {
            coder: Encoder::default(),
            contexts: Contexts::default(),
            len,
            code_parity,
        }
    }

    /// Codes a list: its parity at the block's start and its positions inside the block
    /// (strictly increasing, relative to the block's first sample, all `< len`).
    pub(crate) fn push(&mut self, parity: bool, positions: &[u32]) {
        let ctx = &mut self.contexts;
        // Block 0 codes no parity: it is 0 there.
        let parity = parity && self.code_parity;
        let quiet = !parity && positions.is_empty();
        self.coder.bit(&mut ctx.quiet, !quiet);
        if quiet {
            return;
        }
        if self.code_parity {
            self.coder.bit(&mut ctx.parity, parity);
        }
        let mut state = usize::from(parity);
        // Not quiet with parity 0: the list has an event, which is not coded.
        let mut first = usize::from(parity);
        let mut at = 0u32;
        let mut rest = positions;
        while at < self.len {
            let Some((&t, after)) = rest.split_first() else {
                self.coder.bit(&mut ctx.more[state][first], false);
                break;
            };
            if first == 1 || at > 0 {
                self.coder.bit(&mut ctx.more[state][first], true);
            }
            let max_gap = self.len - 1 - at;
            if state == 0 && max_gap < UNIFORM_LIMIT {
                self.coder.uniform(t - at, max_gap + 1);
            } else {
                encode_gap(&mut self.coder, &mut ctx.exponent[state], t - at, max_gap);
            }
            state ^= 1;
            rest = after;
            at = t + 1;
            if at < self.len {
                let pulse = rest.first() == Some(&at);
                self.coder.bit(&mut ctx.pulse[state], pulse);
                if pulse {
                    state ^= 1;
                    rest = &rest[1..];
                    at += 1;
                }
            }
            first = 0;
        }
    }

    /// The block's code.
    pub(crate) fn finish(self) -> Vec<u8> {
        self.coder.finish()
    }
}

/// Tree levels of a gap's bit length when the gap is at most `max_gap`: the bit length of
/// the largest bit length (0 when the gap can only be 0).
fn levels(max_gap: u32) -> u32 {
    32 - (32 - max_gap.leading_zeros()).leading_zeros()
}

/// A gap `g ≤ max_gap` as its bit length `n` in the bit tree (most significant bit first;
/// only the [`levels`] the largest gap needs, the ones above are 0), then, for `n ≥ 2`, the
/// `n − 1` bits of `g` below its leading one as direct bits.
fn encode_gap(coder: &mut Encoder, tree: &mut [Prob; 1 << EXPONENT_BITS], gap: u32, max_gap: u32) {
    let n = 32 - gap.leading_zeros();
    let levels = levels(max_gap);
    let mut node = 1usize << (EXPONENT_BITS - levels);
    for k in (0..levels).rev() {
        let bit = n >> k & 1 == 1;
        coder.bit(&mut tree[node], bit);
        node = node * 2 + usize::from(bit);
    }
    if n > 1 {
        coder.direct_bits(gap - (1 << (n - 1)), n - 1);
    }
}

/// Decodes one block of a list set, list after list.
pub(crate) struct BlockDecoder<'a> {
    coder: Decoder<'a>,
    contexts: Box<Contexts>,
    len: u32,
    code_parity: bool,
    part: &'static str,
    /// The code, to check that a block no list is read from has none.
    code: &'a [u8],
    read_any: bool,
}

impl<'a> BlockDecoder<'a> {
    pub(crate) fn new(code: &'a [u8], len: u32, code_parity: bool, part: &'static str) -> Self {
        Self {
            coder: Decoder::new(code),
            contexts: Box::default(),
            len,
            code_parity,
            part,
            code,
            read_any: false,
        }
    }

    fn overrun(&self) -> Result<(), FormatViolation> {
        if self.coder.overrun() {
            return Err(corrupt(self.part, "toggle code runs past its end"));
        }
        Ok(())
    }

    /// Decodes the next list: returns its parity at the block's start and hands each
    /// position inside the block (relative to its first sample, increasing) to `toggle`.
    #[inline]
    pub(crate) fn next_list(
        &mut self,
        mut toggle: impl FnMut(u32),
    ) -> Result<bool, FormatViolation> {
        self.read_any = true;
        let ctx = &mut *self.contexts;
        if !self.coder.bit(&mut ctx.quiet) {
            self.overrun()?;
            return Ok(false);
        }
        let parity = self.code_parity && self.coder.bit(&mut ctx.parity);
        let mut state = usize::from(parity);
        let mut first = usize::from(parity);
        let mut at = 0u32;
        while at < self.len {
            if (first == 1 || at > 0) && !self.coder.bit(&mut ctx.more[state][first]) {
                break;
            }
            // `at < len`, so `len − 1 − at` cannot underflow.
            let max_gap = self.len - 1 - at;
            let gap = if state == 0 && max_gap < UNIFORM_LIMIT {
                self.coder.uniform(max_gap + 1)
            } else {
                decode_gap(&mut self.coder, &mut ctx.exponent[state], max_gap)
            };
            let Some(gap) = gap.filter(|&gap| gap <= max_gap) else {
                return Err(corrupt(self.part, "toggle beyond its block"));
            };
            let t = at + gap;
            toggle(t);
            state ^= 1;
            at = t + 1;
            if at < self.len && self.coder.bit(&mut ctx.pulse[state]) {
                toggle(at);
                state ^= 1;
                at += 1;
            }
            first = 0;
            // Each event costs at least a few thousandths of a bit: checking here bounds
            // the work by the bytes.
            if self.coder.overrun() {
                break;
            }
        }
        self.overrun()?;
        Ok(parity)
    }

    /// Checks that the lists decoded used the block's code exactly.
    pub(crate) fn finish(&self) -> Result<(), FormatViolation> {
        self.overrun()?;
        if !self.read_any && !self.code.is_empty() {
            return Err(corrupt(self.part, "toggle code without lists"));
        }
        if !self.coder.used_all() {
            return Err(corrupt(self.part, "toggle code has bytes no list uses"));
        }
        Ok(())
    }
}

/// A gap, `None` for a bit length beyond 32.
fn decode_gap(
    coder: &mut Decoder<'_>,
    tree: &mut [Prob; 1 << EXPONENT_BITS],
    max_gap: u32,
) -> Option<u32> {
    let levels = levels(max_gap);
    let mut node = 1usize << (EXPONENT_BITS - levels);
    for _ in 0..levels {
        node = node * 2 + usize::from(coder.bit(&mut tree[node]));
    }
    let n = (node - (1 << EXPONENT_BITS)) as u32;
    match n {
        0 => Some(0),
        1..=32 => Some((1u32 << (n - 1)) | coder.direct_bits(n - 1)),
        _ => None,
    }
}

/// Reads a list set's lists from the coded blocks at hand (format 1.2), list after list.
pub(crate) struct CodedListReader<'a> {
    /// Each block's first sample and decoder.
    blocks: Vec<(u32, BlockDecoder<'a>)>,
    part: &'static str,
    budget: ToggleBudget,
}

impl<'a> CodedListReader<'a> {
    /// A reader over blocks given as (first sample, samples, code), in block order.
    pub(crate) fn new(
        blocks: impl IntoIterator<Item = (u32, u32, &'a [u8])>,
        part: &'static str,
        max_toggles: u64,
    ) -> Self {
        Self {
            blocks: blocks
                .into_iter()
                .map(|(start, len, code)| (start, BlockDecoder::new(code, len, start > 0, part)))
                .collect(),
            part,
            budget: ToggleBudget::new(max_toggles),
        }
    }

    /// Passes over the next list (decoding it from the blocks at hand, if any).
    pub(crate) fn skip_list(&mut self) -> Result<(), FormatViolation> {
        for b in 0..self.blocks.len() {
            let mut toggles = 0u64;
            self.blocks[b].1.next_list(|_| toggles += 1)?;
            self.count(toggles)?;
        }
        Ok(())
    }

    /// Counts the toggles of a list in one block, plus one for the visit: an empty list
    /// costs the coder next to nothing, so visits are bounded like toggles (FORMAT.md §9).
    fn count(&mut self, toggles: u64) -> Result<(), FormatViolation> {
        self.budget.spend(toggles + 1)
    }

    /// Whether an odd number of the next list's positions are `≤ sample`, from the first
    /// block at hand (the one holding the sample).
    #[inline]
    pub(crate) fn parity_at(&mut self, sample: u32) -> Result<bool, FormatViolation> {
        let Some((start, decoder)) = self.blocks.first_mut() else {
            return Ok(false);
        };
        let within = sample.saturating_sub(*start);
        let mut odd = false;
        let parity = decoder.next_list(|t| odd ^= t <= within)?;
        Ok(parity ^ odd)
    }

    /// Reads the next list whole into `positions` (cleared first) from every block at
    /// hand, checking each block's parity bit against the positions before it.
    pub(crate) fn next_list_into(
        &mut self,
        positions: &mut Vec<u32>,
    ) -> Result<(), FormatViolation> {
        positions.clear();
        let part = self.part;
        for b in 0..self.blocks.len() {
            let (start, decoder) = &mut self.blocks[b];
            let start = *start;
            let before = positions.len();
            let parity = decoder.next_list(|t| positions.push(start + t))?;
            if parity != (before % 2 == 1) {
                return Err(corrupt(
                    part,
                    "a block's parity bit disagrees with the toggles before it",
                ));
            }
            self.count((positions.len() - before) as u64)?;
        }
        Ok(())
    }

    /// Checks that the lists read used each block's code exactly (a block no list was read
    /// from must be empty).
    pub(crate) fn finish(&self) -> Result<(), FormatViolation> {
        for (_, decoder) in &self.blocks {
            decoder.finish()?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip(len: u32, code_parity: bool, lists: &[(bool, Vec<u32>)]) -> usize {
        let mut encoder = BlockEncoder::new(len, code_parity);
        for (parity, positions) in lists {
            encoder.push(*parity, positions);
        }
        let code = encoder.finish();
        let mut decoder = BlockDecoder::new(&code, len, code_parity, "test");
        for (parity, positions) in lists {
            let mut got = Vec::new();
            let p = decoder.next_list(|t| got.push(t)).unwrap();
            assert_eq!((p, &got), (*parity && code_parity, positions));
        }
        decoder.finish().unwrap();
        code.len()
    }

    #[test]
    fn lists_read_back_whatever_their_shape() {
        let len = 256;
        let lists = vec![
            (false, vec![]),
            (false, vec![17, 18]),
            (true, vec![0, 1, 2, 255]),
            (true, vec![255]),
            (false, (0..256).collect()),
            (false, (0..256).step_by(2).collect()),
            (false, vec![254, 255]),
            (true, vec![3, 100, 101, 200]),
        ];
        for code_parity in [false, true] {
            roundtrip(len, code_parity, &lists);
        }
        roundtrip(1, true, &[(true, vec![0]), (false, vec![])]);
        roundtrip(u32::MAX, true, &[(true, vec![0, u32::MAX - 1])]);
        assert_eq!(roundtrip(256, false, &[]), 0);
    }

    #[test]
    fn sparse_pulses_cost_close_to_their_entropy() {
        // 2,000 lists, each with a one-sample pulse at a pseudo-random place in one block of
        // four: log2(256) ≈ 8 bits for the place, H(1/4) ≈ 0.81 bits per list for whether.
        let mut state = 12345u32;
        let lists: Vec<(bool, Vec<u32>)> = (0..2000)
            .map(|_| {
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                let place = (state >> 8) % 255;
                let pulse = (state >> 20) % 4 == 0;
                (
                    false,
                    if pulse {
                        vec![place, place + 1]
                    } else {
                        vec![]
                    },
                )
            })
            .collect();
        let bytes = roundtrip(256, true, &lists);
        let floor = (500.0 * 8.0 + 2000.0 * 0.81) / 8.0;
        assert!((bytes as f64) < floor * 1.1, "{bytes} bytes, floor {floor}");
    }

    #[test]
    fn damaged_codes_end_in_errors_or_lists() {
        let mut encoder = BlockEncoder::new(64, true);
        for i in 0..20 {
            encoder.push(i % 3 == 0, &[i as u32, i as u32 + 1, 40]);
        }
        let code = encoder.finish();
        for at in 0..code.len() {
            for bit in 0..8 {
                let mut damaged = code.clone();
                damaged[at] ^= 1 << bit;
                let mut decoder = BlockDecoder::new(&damaged, 64, true, "test");
                for _ in 0..20 {
                    let mut last = None;
                    let result = decoder.next_list(|t| {
                        assert!(t < 64 && last.is_none_or(|l| t > l));
                        last = Some(t);
                    });
                    if result.is_err() {
                        break;
                    }
                }
            }
        }
        // Garbage over a huge block ends after a few events, in lists or an error.
        for byte in [0x00, 0x55, 0xFF] {
            let garbage = [byte; 8];
            let mut decoder = BlockDecoder::new(&garbage, u32::MAX, true, "test");
            let mut events = 0;
            for _ in 0..100 {
                if decoder.next_list(|_| events += 1).is_err() {
                    break;
                }
            }
            assert!(events < 100_000, "{events}");
        }
    }
}
