//! Outlier sets as sorted toggle positions.
//!
//! The outlier set of a voxel lists the samples where the exact state starts or stops
//! disagreeing with the model's thresholded prediction: the state at sample `i` is
//! `(p(i) > 0.5) XOR (number of toggles at or before i is odd)`. Only *observed* samples
//! must come out right; unknown samples in between may take either value, so a disagreement
//! run continues across a gap whenever the samples on both sides disagree, and the set built
//! by [`ToggleBuilder`] has the fewest toggles possible: one per change of the disagreement
//! bit along the observed samples (each placed at the first observed sample of the change).
//!
//! Encoding ([`Toggles::encode`]): a [`varint`](crate::varint) count, then the first position
//! and each following gap `position - previous - 1`, all varints. Short gaps take one byte.

use crate::varint::{self, Reader};
use crate::TemporalError;

/// Most toggles a decoder accepts for one voxel (one per sample of the longest axis).
pub const MAX_TOGGLES: u64 = u32::MAX as u64;

/// Strictly increasing sample indices where the outlier parity flips.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Toggles(Vec<u32>);

impl Toggles {
    /// No toggles: the model alone gives every state.
    pub const fn empty() -> Self {
        Self(Vec::new())
    }

    /// Toggles from positions that must be strictly increasing.
    ///
    /// ```
    /// use froctomap_temporal::Toggles;
    /// let t = Toggles::new(vec![3, 7])?;
    /// assert!(!t.parity_at(2) && t.parity_at(3) && t.parity_at(6) && !t.parity_at(7));
    /// assert!(Toggles::new(vec![7, 3]).is_err());
    /// # Ok::<(), froctomap_temporal::TemporalError>(())
    /// ```
    pub fn new(positions: Vec<u32>) -> Result<Self, TemporalError> {
        if positions.windows(2).any(|w| w[0] >= w[1]) {
            return Err(TemporalError::Malformed(
                "toggles (not strictly increasing)",
            ));
        }
        Ok(Self(positions))
    }

    /// The positions, increasing.
    pub fn as_slice(&self) -> &[u32] {
        &self.0
    }

    /// Number of toggles.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// `true` when there are no toggles.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// `true` when an odd number of toggles lie at or before `sample`, i.e. the exact state at
    /// `sample` is the opposite of the thresholded model.
    pub fn parity_at(&self, sample: u32) -> bool {
        self.0.partition_point(|&t| t <= sample) % 2 == 1
    }

    /// Appends the encoding to `out`.
    pub fn encode(&self, out: &mut Vec<u8>) {
        varint::write_u64(out, self.0.len() as u64);
        let mut next = 0u32;
        for &t in &self.0 {
            varint::write_u32(out, t - next);
            next = t.saturating_add(1);
        }
    }

    /// Bytes [`Toggles::encode`] produces.
    pub fn encoded_len(&self) -> usize {
        let mut next = 0u32;
        let mut len = varint::encoded_len(self.0.len() as u64);
        for &t in &self.0 {
            len += varint::encoded_len(u64::from(t - next));
            next = t.saturating_add(1);
        }
        len
    }

    /// Decodes toggles whose positions must all be below `sample_limit` (the axis length).
    /// Returns the toggles and the bytes consumed.
    pub fn decode(bytes: &[u8], sample_limit: u32) -> Result<(Self, usize), TemporalError> {
        let mut r = Reader::new(bytes);
        let toggles = Self::read(&mut r, sample_limit)?;
        Ok((toggles, r.position()))
    }

    pub(crate) fn read(r: &mut Reader<'_>, sample_limit: u32) -> Result<Self, TemporalError> {
        let count = r.count("toggle count", MAX_TOGGLES.min(u64::from(sample_limit)), 1)?;
        let mut positions = Vec::with_capacity(count);
        let mut next = 0u64;
        for _ in 0..count {
            // A hostile gap may overflow u64: checked, or positions would wrap and repeat.
            let pos = match next.checked_add(r.u64()?) {
                Some(pos) if pos < u64::from(sample_limit) => pos,
                _ => {
                    return Err(TemporalError::Malformed(
                        "toggles (position beyond the axis)",
                    ))
                }
            };
            // pos < sample_limit <= u32::MAX, so the conversion cannot fail.
            positions.push(pos as u32);
            next = pos + 1;
        }
        Ok(Self(positions))
    }
}

/// Builds the minimal toggle set from the disagreement bit of each observed sample, fed in
/// increasing sample order (unknown samples are simply not fed).
#[derive(Debug, Clone, Default)]
pub struct ToggleBuilder {
    parity: bool,
    positions: Vec<u32>,
    keep: bool,
    count: u64,
    bytes: usize,
    next: u32,
    disagreements: u64,
}

impl ToggleBuilder {
    /// A builder; with `keep_positions == false` it only counts (toggles, bytes, disagreements).
    pub fn new(keep_positions: bool) -> Self {
        Self {
            keep: keep_positions,
            ..Self::default()
        }
    }

    /// Feeds observed sample `sample` whose thresholded model state disagrees with the
    /// observation when `disagrees`.
    #[inline]
    pub fn push(&mut self, sample: u32, disagrees: bool) {
        if disagrees {
            self.disagreements += 1;
        }
        if disagrees != self.parity {
            self.toggle(sample);
        }
    }

    /// Feeds a run of `len` consecutive observed samples starting at `first` that all agree or
    /// all disagree.
    #[inline]
    pub fn push_run(&mut self, first: u32, len: u32, disagrees: bool) {
        if disagrees {
            self.disagreements += u64::from(len);
        }
        if disagrees != self.parity {
            self.toggle(first);
        }
    }

    fn toggle(&mut self, sample: u32) {
        self.parity = !self.parity;
        self.count += 1;
        self.bytes += varint::encoded_len(u64::from(sample.saturating_sub(self.next)));
        self.next = sample.saturating_add(1);
        if self.keep {
            self.positions.push(sample);
        }
    }

    /// Observed samples fed so far whose thresholded model state was wrong.
    pub fn disagreements(&self) -> u64 {
        self.disagreements
    }

    /// Toggles so far.
    pub fn toggle_count(&self) -> u64 {
        self.count
    }

    /// Bytes the toggles fed so far would encode to ([`Toggles::encoded_len`]).
    pub fn encoded_len(&self) -> usize {
        varint::encoded_len(self.count) + self.bytes
    }

    /// The toggles (empty when positions were not kept).
    pub fn finish(self) -> Toggles {
        Toggles(self.positions)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn encode_decode_round_trip(mut positions in proptest::collection::vec(0u32..5000, 0..50)) {
            positions.sort_unstable();
            positions.dedup();
            let t = Toggles::new(positions)?;
            let mut out = vec![0xAA];
            t.encode(&mut out);
            prop_assert_eq!(out.len() - 1, t.encoded_len());
            prop_assert_eq!(Toggles::decode(&out[1..], 5000)?, (t.clone(), out.len() - 1));
            for cut in 1..out.len() - 1 {
                prop_assert!(Toggles::decode(&out[1..cut], 5000).is_err());
            }
        }

        #[test]
        fn builder_is_minimal_and_exact(bits in proptest::collection::vec(any::<Option<bool>>(), 0..200)) {
            let mut b = ToggleBuilder::new(true);
            for (i, d) in bits.iter().enumerate() {
                if let Some(d) = d {
                    b.push(i as u32, *d);
                }
            }
            let bytes = b.encoded_len();
            let t = b.finish();
            prop_assert_eq!(t.encoded_len(), bytes);
            let observed: Vec<(usize, bool)> = bits.iter().enumerate().filter_map(|(i, d)| d.map(|d| (i, d))).collect();
            for &(i, d) in &observed {
                prop_assert_eq!(t.parity_at(i as u32), d);
            }
            // Lower bound: every change of the disagreement bit needs a toggle.
            let mut changes = 0;
            let mut prev = false;
            for &(_, d) in &observed {
                if d != prev { changes += 1; prev = d; }
            }
            prop_assert_eq!(t.len(), changes);
        }
    }

    #[test]
    fn decode_rejects_out_of_axis_and_huge_counts() {
        let t = Toggles::new(vec![10]).unwrap();
        let mut out = Vec::new();
        t.encode(&mut out);
        assert!(Toggles::decode(&out, 10).is_err());
        assert!(Toggles::decode(&out, 11).is_ok());
        assert!(Toggles::decode(&[0xFF, 0xFF, 0xFF, 0x7F], 100).is_err());
    }

    #[test]
    fn decode_rejects_gaps_that_overflow_the_position() {
        // Two toggles: position 5, then a gap of u64::MAX - 5, which wraps to 5 again when
        // added without a check (a non-increasing position that `encode` then underflows on).
        let mut out = Vec::new();
        varint::write_u64(&mut out, 2);
        varint::write_u64(&mut out, 5);
        varint::write_u64(&mut out, u64::MAX - 5);
        assert_eq!(
            Toggles::decode(&out, 100),
            Err(TemporalError::Malformed(
                "toggles (position beyond the axis)"
            ))
        );
        // A single gap of u64::MAX after position 0 as well.
        let mut out = Vec::new();
        varint::write_u64(&mut out, 2);
        varint::write_u64(&mut out, 0);
        varint::write_u64(&mut out, u64::MAX);
        assert!(Toggles::decode(&out, 100).is_err());
    }
}
