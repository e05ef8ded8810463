//! An adaptive binary range coder ([FORMAT.md §5.5](../../../docs/FORMAT.md)): the entropy
//! coder of format 1.2's toggle lists.
//!
//! It is the classic carry-propagating range coder of LZMA with adaptive bit probabilities:
//! a 32-bit `range`, a 33-bit `low`, bytes shifted out from the top, and per-context
//! probabilities of a 0 bit in 16-bit fixed point. A probability moves half way towards the
//! first bits it codes, then by ever smaller steps down to 1/128 (a running average that
//! settles), and stays within `[64, 65472] / 65536`. Two changes make short streams (one
//! per toggle block) cheap: the always-zero first byte is not stored, and the final bytes
//! are chosen to end in as many zero bytes as possible, which are not stored either (a
//! decoder reads zeros past the end). A decoder may read at most [`PAD`] bytes past the end,
//! so the work of decoding is bounded by the bytes: every decision costs at least ~0.0014
//! bits.
//!
//! Written here rather than taken from a crate: the entropy-coding crates (`constriction`,
//! for one) code symbols with models built per symbol, where this needs a few hundred
//! adaptive binary contexts evaluated per decision on a query's hot path.

/// Bits of a probability: `p(0) = prob / 2^PROB_BITS`.
const PROB_BITS: u32 = 16;
/// The smallest step a probability moves by: `1 / 2^MAX_SHIFT` of the way to a coded bit.
const MAX_SHIFT: u32 = 7;
/// Probabilities stay within `[PROB_MIN, 2^PROB_BITS − PROB_MIN]`.
const PROB_MIN: u32 = 64;
/// Probability of a 0 that a fresh context starts with: one half.
const PROB_INIT: u16 = 1 << (PROB_BITS - 1);
/// Below this, `range` is shifted out by a byte.
const TOP: u32 = 1 << 24;
/// Bytes a decoder may read past the end of its stream (they read as zeros).
pub(crate) const PAD: usize = 4;

/// An adaptive probability: the chance of a 0 bit in 16-bit fixed point, and how many bits
/// it has coded (up to the count where its step stops shrinking).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Prob {
    p: u16,
    seen: u8,
}

impl Default for Prob {
    fn default() -> Self {
        Prob {
            p: PROB_INIT,
            seen: 0,
        }
    }
}

/// Bits coded after which a probability moves by its smallest step.
const SETTLED: u8 = (1 << MAX_SHIFT) - 2;

impl Prob {
    /// Moves `1 / 2^shift` of the way towards `bit`, `shift = ⌊log2(seen + 2)⌋` capped at
    /// [`MAX_SHIFT`], then clamps.
    #[inline]
    fn update(&mut self, bit: bool) {
        let shift = if self.seen < SETTLED {
            let shift = (u32::from(self.seen) + 2).ilog2();
            self.seen += 1;
            shift
        } else {
            MAX_SHIFT
        };
        let p = u32::from(self.p);
        let p = if bit {
            p - (p >> shift)
        } else {
            p + (((1 << PROB_BITS) - p) >> shift)
        };
        // Within u16: at most 2^16 − PROB_MIN.
        self.p = p.clamp(PROB_MIN, (1 << PROB_BITS) - PROB_MIN) as u16;
    }
}

/// Encodes bits into bytes.
pub(crate) struct Encoder {
    low: u64,
    range: u32,
    /// The byte waiting for a possible carry, and how many 0xFF bytes follow it.
    cache: u8,
    pending: u64,
    /// The first byte shifted out is always 0 and is not stored.
    first: bool,
    out: Vec<u8>,
}

impl Default for Encoder {
    fn default() -> Self {
        Self {
            low: 0,
            range: u32::MAX,
            cache: 0,
            pending: 1,
            first: true,
            out: Vec::new(),
        }
    }
}

impl Encoder {
    /// Codes `bit` with the adaptive probability `prob`, and adapts it.
    #[inline]
    pub(crate) fn bit(&mut self, prob: &mut Prob, bit: bool) {
        let bound = (self.range >> PROB_BITS) * u32::from(prob.p);
        if bit {
            self.low += u64::from(bound);
            self.range -= bound;
        } else {
            self.range = bound;
        }
        prob.update(bit);
        self.normalize();
    }

    /// Codes the `count` low bits of `value`, most significant first, each with
    /// probability one half.
    pub(crate) fn direct_bits(&mut self, value: u32, count: u32) {
        for i in (0..count).rev() {
            self.range >>= 1;
            if value >> i & 1 == 1 {
                self.low += u64::from(self.range);
            }
            self.normalize();
        }
    }

    /// Codes `value < count` with probability `1 / count` each (`count ≤ 2^16`): the range
    /// is cut into `count` parts of `⌊range / count⌋` (the remainder is not used).
    pub(crate) fn uniform(&mut self, value: u32, count: u32) {
        let part = self.range / count;
        self.low += u64::from(value) * u64::from(part);
        self.range = part;
        self.normalize();
    }

    #[inline]
    fn normalize(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    fn shift_low(&mut self) {
        if self.low < 0xFF00_0000 || self.low >= 1 << 32 {
            let carry = (self.low >> 32) as u8;
            let mut byte = self.cache;
            while self.pending > 0 {
                let out = byte.wrapping_add(carry);
                if self.first {
                    self.first = false;
                } else {
                    self.out.push(out);
                }
                byte = 0xFF;
                self.pending -= 1;
            }
            self.cache = (self.low >> 24) as u8;
        }
        self.pending += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    /// The coded bytes: the final interval is closed on the value in it with the most
    /// trailing zero bits, and trailing zero bytes are dropped (a decoder reads zeros past
    /// the end, at most [`PAD`] of them).
    pub(crate) fn finish(mut self) -> Vec<u8> {
        let end = self.low + u64::from(self.range);
        for zeros in (0..=32).rev() {
            let mask = (1u64 << zeros) - 1;
            let value = (self.low + mask) & !mask;
            if value < end {
                self.low = value;
                break;
            }
        }
        let before = self.out.len();
        for _ in 0..5 {
            self.shift_low();
        }
        // Only the flushed bytes may be dropped, so that a decoder never reads more than
        // PAD bytes past the end.
        let keep = before.max(self.out.len().saturating_sub(PAD));
        while self.out.len() > keep && self.out.last() == Some(&0) {
            self.out.pop();
        }
        self.out
    }
}

/// Decodes bits from bytes produced by [`Encoder`]. Never panics: damaged bytes decode
/// to some bits, and reading more than [`PAD`] bytes past the end is reported by
/// [`overrun`](Self::overrun).
pub(crate) struct Decoder<'a> {
    bytes: &'a [u8],
    pos: usize,
    range: u32,
    code: u32,
}

impl<'a> Decoder<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        let mut decoder = Self {
            bytes,
            pos: 0,
            range: u32::MAX,
            code: 0,
        };
        for _ in 0..4 {
            decoder.code = decoder.code << 8 | u32::from(decoder.next_byte());
        }
        decoder
    }

    #[inline]
    fn next_byte(&mut self) -> u8 {
        let byte = self.bytes.get(self.pos).copied().unwrap_or(0);
        self.pos += 1;
        byte
    }

    /// Decodes a bit with the adaptive probability `prob`, and adapts it.
    #[inline]
    pub(crate) fn bit(&mut self, prob: &mut Prob) -> bool {
        let bound = (self.range >> PROB_BITS) * u32::from(prob.p);
        let bit = if self.code < bound {
            self.range = bound;
            false
        } else {
            self.code -= bound;
            self.range -= bound;
            true
        };
        prob.update(bit);
        self.normalize();
        bit
    }

    /// Decodes `count` bits of probability one half, most significant first.
    pub(crate) fn direct_bits(&mut self, count: u32) -> u32 {
        let mut value = 0u32;
        for _ in 0..count {
            self.range >>= 1;
            let bit = self.code >= self.range;
            if bit {
                self.code -= self.range;
            }
            value = value << 1 | u32::from(bit);
            self.normalize();
        }
        value
    }

    /// Decodes a value coded by [`Encoder::uniform`] (`1 ≤ count ≤ 2^16`); `None` when
    /// the code lies in the unused remainder (damaged bytes).
    pub(crate) fn uniform(&mut self, count: u32) -> Option<u32> {
        let part = self.range / count;
        let value = self.code / part;
        if value >= count {
            return None;
        }
        self.code -= value * part;
        self.range = part;
        self.normalize();
        Some(value)
    }

    #[inline]
    fn normalize(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.code = self.code << 8 | u32::from(self.next_byte());
        }
    }

    /// `true` once the decoder has read more than [`PAD`] bytes past the end: the bits
    /// since are not in the stream.
    #[inline]
    pub(crate) fn overrun(&self) -> bool {
        self.pos > self.bytes.len() + PAD
    }

    /// `true` when the decoder used every byte of the stream (a stream longer than what
    /// was decoded from it holds bytes no decision used).
    pub(crate) fn used_all(&self) -> bool {
        self.pos >= self.bytes.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic stream of bits of varying skew, with their contexts.
    fn bits(n: usize) -> Vec<(usize, bool)> {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        (0..n)
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let context = i % 3;
                let threshold = [2u64, 50, 97][context];
                (context, state % 100 < threshold)
            })
            .collect()
    }

    fn roundtrip(input: &[(usize, bool)], direct: bool) -> Vec<u8> {
        let mut probs = [Prob::default(); 3];
        let mut encoder = Encoder::default();
        for (i, &(context, bit)) in input.iter().enumerate() {
            encoder.bit(&mut probs[context], bit);
            if direct && i % 5 == 0 {
                encoder.direct_bits(i as u32 & 0x3FF, 10);
                encoder.uniform(i as u32 % 300, 300);
                encoder.uniform(0, 1);
                encoder.uniform(i as u32 % 65536, 65536);
            }
        }
        let bytes = encoder.finish();
        let mut probs = [Prob::default(); 3];
        let mut decoder = Decoder::new(&bytes);
        for (i, &(context, bit)) in input.iter().enumerate() {
            assert_eq!(decoder.bit(&mut probs[context]), bit, "bit {i}");
            if direct && i % 5 == 0 {
                assert_eq!(decoder.direct_bits(10), i as u32 & 0x3FF);
                assert_eq!(decoder.uniform(300), Some(i as u32 % 300));
                assert_eq!(decoder.uniform(1), Some(0));
                assert_eq!(decoder.uniform(65536), Some(i as u32 % 65536));
            }
            assert!(!decoder.overrun());
        }
        assert!(decoder.used_all());
        bytes
    }

    #[test]
    fn bits_read_back_and_skewed_bits_cost_little() {
        for n in [0, 1, 2, 7, 100, 10_000] {
            roundtrip(&bits(n), false);
            roundtrip(&bits(n), true);
        }
        // 10,000 bits of which two thirds are strongly skewed: far below a bit each.
        let bytes = roundtrip(&bits(30_000), false);
        assert!(bytes.len() < 30_000 / 8 / 2, "{}", bytes.len());
        // Nothing coded, or only likely zeros: nothing stored.
        assert!(Encoder::default().finish().is_empty());
        let mut prob = Prob::default();
        let mut encoder = Encoder::default();
        for _ in 0..20 {
            encoder.bit(&mut prob, false);
        }
        assert!(encoder.finish().len() <= 1);
    }

    #[test]
    fn every_carry_and_flush_case_reads_back() {
        // Long runs of likely and unlikely bits push `low` to the carry boundary.
        let mut input = Vec::new();
        for run in 0..40 {
            for _ in 0..run * 7 {
                input.push((run % 3, run % 2 == 0));
            }
            input.push((run % 3, run % 2 == 1));
        }
        for cut in 0..input.len().min(600) {
            roundtrip(&input[..cut], cut % 2 == 0);
        }
    }

    #[test]
    fn garbage_decodes_without_panicking_and_overruns_are_seen() {
        let mut decoder = Decoder::new(&[0xFF; 3]);
        let mut prob = Prob { p: 1, seen: 0 };
        let mut steps = 0;
        while !decoder.overrun() {
            decoder.bit(&mut prob);
            decoder.direct_bits(31);
            let _ = decoder.uniform(65536);
            steps += 1;
        }
        assert!(steps < 100);
    }
}
