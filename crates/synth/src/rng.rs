//! Deterministic pseudo-randomness without floating-point transcendental functions.
//!
//! Every random choice of the generator is either drawn from a [`SplitMix64`] stream seeded
//! from the series seed (placement, done once) or from a stateless [`mix`] hash of
//! `(seed, purpose, a, b)` (anything that depends on time or on a frame index). The stateless
//! form is what makes a frame computable on its own: frame 90 000 needs no pass over frames
//! 0..90 000. Only integer arithmetic and exact IEEE operations (`+ - * /`, conversions of
//! 53-bit integers) are used, so the output is identical on every platform; `ln`/`exp` are
//! avoided because their last bit differs between C libraries.

/// The SplitMix64 finaliser: a bijective 64-bit mixer with good avalanche.
pub(crate) fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A stateless hash of a seed, a purpose tag and two coordinates (element, time slot...).
pub(crate) fn mix(seed: u64, tag: u64, a: u64, b: u64) -> u64 {
    let h = splitmix(seed ^ tag.wrapping_mul(0xD6E8_FEB8_6659_FD93));
    let h = splitmix(h ^ a);
    splitmix(h ^ b.wrapping_mul(0xA076_1D64_78BD_642F))
}

/// Purposes of [`mix`] calls, so unrelated decisions never share random bits.
pub(crate) mod tag {
    pub const MISSED: u64 = 1;
    pub const JITTER: u64 = 2;
    pub const NOISE: u64 = 3;
    pub const PARTIAL: u64 = 4;
    pub const OFFICE_DOOR: u64 = 5;
    pub const OFFICE_DOOR_HOUR: u64 = 6;
    pub const PERSON_DAY: u64 = 7;
    pub const PERSON_SLOT: u64 = 8;
    pub const CHAIR_HOUR: u64 = 9;
    pub const OBJECT_PERIOD: u64 = 10;
    pub const PLACEMENT: u64 = 11;
    pub const WEEKEND_VISIT: u64 = 12;
}

/// `u64::MAX + 1` scaled threshold for an event of probability `p`: `x < threshold(p)` for a
/// uniform `x` happens with probability `p` (exact for powers of two, within 2^-64 otherwise).
pub(crate) fn threshold(p: f64) -> u64 {
    if p >= 1.0 {
        u64::MAX
    } else if p > 0.0 {
        // Multiplying by a power of two is exact; the cast saturates.
        (p * 18_446_744_073_709_551_616.0) as u64
    } else {
        0
    }
}

/// `true` with probability `p`, from a uniform 64-bit value.
pub(crate) fn chance(x: u64, p: f64) -> bool {
    p >= 1.0 || x < threshold(p)
}

/// A uniform value in `0..n` from a uniform 64-bit value (Lemire's multiply-high; `n > 0`).
pub(crate) fn below(x: u64, n: u64) -> u64 {
    ((u128::from(x) * u128::from(n)) >> 64) as u64
}

/// A uniform value in `[0, 1)` with 53 random bits.
pub(crate) fn unit(x: u64) -> f64 {
    (x >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
}

/// A sequential generator for one-off choices (placement of elements).
#[derive(Clone, Debug)]
pub(crate) struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    pub(crate) fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        // `splitmix` adds the increment itself; undo it so this is textbook SplitMix64.
        splitmix(self.state.wrapping_sub(0x9E37_79B9_7F4A_7C15))
    }

    /// Uniform in `0..n` (`n > 0`).
    pub(crate) fn below(&mut self, n: u64) -> u64 {
        below(self.next_u64(), n)
    }

    /// Uniform in `[lo, hi)`.
    pub(crate) fn range_f64(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * unit(self.next_u64())
    }

    pub(crate) fn shuffle<T>(&mut self, items: &mut [T]) {
        for i in (1..items.len()).rev() {
            let j = self.below(i as u64 + 1) as usize;
            items.swap(i, j);
        }
    }
}

/// Draws independent Bernoulli(`p`) events over many items with about one random draw per
/// 64 items when `p` is small, exactly: a draw decides where the first event of a block of
/// 64 falls (or that there is none), from thresholds of the geometric distribution
/// `P(first <= j) = 1 - (1-p)^(j+1)`; the items after the first event get one draw each.
/// The thresholds are products of `1-p`, exact IEEE operations, so platforms agree.
#[derive(Clone, Debug)]
pub(crate) struct BernoulliBlocks {
    p: f64,
    /// `threshold(P(first event at index <= j))` for j in 0..64.
    first: Vec<u64>,
}

const BLOCK: usize = 64;

impl BernoulliBlocks {
    pub(crate) fn new(p: f64) -> Self {
        let mut none = 1.0f64;
        let first = (0..BLOCK)
            .map(|_| {
                none *= 1.0 - p;
                threshold(1.0 - none)
            })
            .collect();
        Self { p, first }
    }

    /// Calls `hit(i)` for each `i` in `0..n` that the event selects, in increasing order.
    pub(crate) fn sample(&self, rng: &mut SplitMix64, n: usize, mut hit: impl FnMut(usize)) {
        if self.p <= 0.0 {
            return;
        }
        let last = self.first.last().copied().unwrap_or(0);
        let mut start = 0;
        while start < n {
            let len = BLOCK.min(n - start);
            let u = rng.next_u64();
            // `first` increases, so the first event is the first j with u below its threshold.
            if u < last || self.p >= 1.0 {
                let j = self.first.partition_point(|&t| t <= u);
                if j < len {
                    hit(start + j);
                    for k in j + 1..len {
                        if chance(rng.next_u64(), self.p) {
                            hit(start + k);
                        }
                    }
                }
            }
            start += len;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix_matches_reference_values() {
        // First outputs of the reference SplitMix64 seeded with 1234567 (Vigna's splitmix64.c).
        let mut rng = SplitMix64::new(1_234_567);
        assert_eq!(rng.next_u64(), 6_457_827_717_110_365_317);
        assert_eq!(rng.next_u64(), 3_203_168_211_198_807_973);
    }

    #[test]
    fn chance_and_below_are_calibrated() {
        let n = 200_000u64;
        let hits = (0..n).filter(|&i| chance(mix(7, 1, i, 0), 0.1)).count() as f64;
        assert!((hits / n as f64 - 0.1).abs() < 0.005);
        assert!(!chance(0, 0.0));
        assert!(chance(u64::MAX, 1.0));
        let mut counts = [0u32; 3];
        for i in 0..30_000 {
            counts[below(mix(1, 2, i, 3), 3) as usize] += 1;
        }
        assert!(
            counts.iter().all(|&c| (9_500..10_500).contains(&c)),
            "{counts:?}"
        );
        assert!((0..1000).all(|i| (0.0..1.0).contains(&unit(mix(0, 0, i, 0)))));
    }

    #[test]
    fn blocked_bernoulli_is_calibrated_per_position() {
        for p in [0.001, 0.05, 0.5, 1.0] {
            let blocks = BernoulliBlocks::new(p);
            // Whole blocks, so early and late positions are equally many.
            let n = 1024;
            let rounds = if p < 0.01 { 2000 } else { 200 };
            let mut counts = vec![0u32; n];
            let mut rng = SplitMix64::new(42);
            for _ in 0..rounds {
                let mut previous = None;
                blocks.sample(&mut rng, n, |i| {
                    assert!(previous.is_none_or(|q| q < i));
                    previous = Some(i);
                    counts[i] += 1;
                });
            }
            let total: u32 = counts.iter().sum();
            let expected = p * (n * rounds) as f64;
            assert!(
                (f64::from(total) - expected).abs() <= 4.0 * expected.sqrt() + 1.0,
                "p {p}: {total} vs {expected}"
            );
            // Early and late positions of a block are equally likely.
            let early: u32 = (0..n).filter(|i| i % 64 < 32).map(|i| counts[i]).sum();
            let late = total - early;
            let diff = f64::from(early) - f64::from(late);
            assert!(
                diff.abs() <= 5.0 * f64::from(total).sqrt() + 1.0,
                "p {p}: {early} vs {late}"
            );
        }
    }
}
