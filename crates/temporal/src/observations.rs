//! One voxel's observations along the time axis, as runs.

use crate::TemporalError;
use froctomap_core::Occupancy;

/// `len` consecutive samples starting at `first`, all observed in `state`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Run {
    /// First sample of the run.
    pub first: u32,
    /// Number of samples (at least 1).
    pub len: u32,
    /// The state observed at every sample of the run.
    pub state: Occupancy,
}

impl Run {
    /// One past the last sample, as `u64` (a run may end at `u32::MAX + 1`).
    pub fn end(&self) -> u64 {
        u64::from(self.first) + u64::from(self.len)
    }
}

/// Which samples of the axis one voxel was observed in, and in which state.
///
/// Stored as sorted, non-overlapping, maximal runs: memory is proportional to the number of
/// state changes and gaps, not to the number of samples. Samples no run covers are *unknown*
/// (not observed, or no snapshot), never implicitly free.
///
/// ```
/// use froctomap_core::Occupancy::{Free, Occupied};
/// use froctomap_temporal::ObservationsBuilder;
/// let mut b = ObservationsBuilder::new();
/// for (sample, state) in [(0, Some(Free)), (1, Some(Free)), (2, None), (3, Some(Occupied))] {
///     b.push(sample, state)?;
/// }
/// let obs = b.finish();
/// assert_eq!(obs.runs().len(), 2);
/// assert_eq!(obs.state_at(2), None);
/// assert_eq!(obs.state_at(3), Some(Occupied));
/// assert_eq!((obs.observed_count(), obs.occupied_count()), (3, 1));
/// assert_eq!(obs.is_constant(), None);
/// # Ok::<(), froctomap_temporal::TemporalError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct VoxelObservations {
    runs: Vec<Run>,
    observed: u64,
    occupied: u64,
}

impl VoxelObservations {
    /// Observations from runs given as `(first_sample, len, state)`, sorted and
    /// non-overlapping. Touching runs of equal state are merged; zero-length runs are an error.
    pub fn from_runs(
        runs: impl IntoIterator<Item = (u32, u32, Occupancy)>,
    ) -> Result<Self, TemporalError> {
        let mut out = Self::default();
        for (first, len, state) in runs {
            if len == 0 {
                return Err(TemporalError::InvalidObservations {
                    reason: "empty run",
                    sample: u64::from(first),
                });
            }
            if u64::from(first) + u64::from(len) > 1 << 32 {
                return Err(TemporalError::InvalidObservations {
                    reason: "run beyond the largest sample index",
                    sample: u64::from(first),
                });
            }
            if let Some(last) = out.runs.last() {
                if u64::from(first) < last.end() {
                    return Err(TemporalError::InvalidObservations {
                        reason: "runs overlap or are not sorted",
                        sample: u64::from(first),
                    });
                }
            }
            out.append(first, len, state);
        }
        Ok(out)
    }

    fn append(&mut self, first: u32, len: u32, state: Occupancy) {
        self.observed += u64::from(len);
        if state == Occupancy::Occupied {
            self.occupied += u64::from(len);
        }
        if let Some(last) = self.runs.last_mut() {
            if last.state == state && last.end() == u64::from(first) {
                // Merged length <= 2^32 - first_of_last; fits u32 unless the axis is
                // pathological, in which case keep separate runs.
                if let Some(merged) = last.len.checked_add(len) {
                    last.len = merged;
                    return;
                }
            }
        }
        self.runs.push(Run { first, len, state });
    }

    /// The runs, sorted by sample.
    pub fn runs(&self) -> &[Run] {
        &self.runs
    }

    /// The observed state at `sample`, or `None` when unknown.
    pub fn state_at(&self, sample: u32) -> Option<Occupancy> {
        let k = self.runs.partition_point(|r| r.first <= sample);
        let run = self.runs.get(k.checked_sub(1)?)?;
        (u64::from(sample) < run.end()).then_some(run.state)
    }

    /// Number of observed samples.
    pub fn observed_count(&self) -> u64 {
        self.observed
    }

    /// Number of samples observed occupied.
    pub fn occupied_count(&self) -> u64 {
        self.occupied
    }

    /// The state when every observed sample has the same one (`None` when there are no
    /// observations or both states occur).
    pub fn is_constant(&self) -> Option<Occupancy> {
        if self.observed == 0 {
            None
        } else if self.occupied == 0 {
            Some(Occupancy::Free)
        } else if self.occupied == self.observed {
            Some(Occupancy::Occupied)
        } else {
            None
        }
    }

    /// First and last observed sample.
    pub fn observed_range(&self) -> Option<(u32, u32)> {
        let first = self.runs.first()?.first;
        let last = self.runs.last()?;
        Some((first, (last.end() - 1) as u32))
    }

    /// The observed sample ranges `[first, end)`, whatever the state: touching runs of
    /// different states join into one range.
    ///
    /// ```
    /// use froctomap_core::Occupancy::{Free, Occupied};
    /// let obs = froctomap_temporal::VoxelObservations::from_runs([(0, 2, Free), (2, 1, Occupied), (5, 1, Free)])?;
    /// assert_eq!(obs.observed_ranges(), vec![(0, 3), (5, 6)]);
    /// # Ok::<(), froctomap_temporal::TemporalError>(())
    /// ```
    pub fn observed_ranges(&self) -> Vec<(u32, u64)> {
        let mut ranges: Vec<(u32, u64)> = Vec::new();
        for run in &self.runs {
            match ranges.last_mut() {
                Some(last) if last.1 == u64::from(run.first) => last.1 = run.end(),
                _ => ranges.push((run.first, run.end())),
            }
        }
        ranges
    }

    /// Every observed sample with its state, in order.
    pub fn iter(&self) -> impl Iterator<Item = (u32, Occupancy)> + '_ {
        self.runs
            .iter()
            .flat_map(|r| (0..r.len).map(move |k| (r.first + k, r.state)))
    }

    /// The observations restricted to samples below `end` (a prefix in time).
    pub fn truncated(&self, end: u32) -> Self {
        let mut out = Self::default();
        for r in &self.runs {
            if r.first >= end {
                break;
            }
            let len = (u64::from(end) - u64::from(r.first)).min(u64::from(r.len)) as u32;
            out.append(r.first, len, r.state);
        }
        out
    }

    /// The sample before which the first `count` observed samples lie (so that
    /// `truncated(result)` keeps exactly `count` of them).
    pub(crate) fn sample_after_observed(&self, count: u64) -> u32 {
        let mut left = count;
        for r in &self.runs {
            if left <= u64::from(r.len) {
                return (u64::from(r.first) + left).min(u64::from(u32::MAX)) as u32;
            }
            left -= u64::from(r.len);
        }
        self.runs
            .last()
            .map_or(0, |r| r.end().min(u64::from(u32::MAX)) as u32)
    }
}

/// Builds [`VoxelObservations`] from samples pushed in increasing order, e.g. while streaming
/// snapshots; memory grows only with the number of runs.
#[derive(Debug, Clone, Default)]
pub struct ObservationsBuilder {
    obs: VoxelObservations,
    next: u64,
}

impl ObservationsBuilder {
    /// An empty builder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records the state of `sample` (`None` = unknown). Samples must be strictly increasing
    /// across calls, including unknown ones.
    pub fn push(&mut self, sample: u32, state: Option<Occupancy>) -> Result<(), TemporalError> {
        if u64::from(sample) < self.next {
            return Err(TemporalError::InvalidObservations {
                reason: "samples not pushed in increasing order",
                sample: u64::from(sample),
            });
        }
        self.next = u64::from(sample) + 1;
        if let Some(state) = state {
            self.obs.append(sample, 1, state);
        }
        Ok(())
    }

    /// The observations built so far.
    pub fn finish(self) -> VoxelObservations {
        self.obs
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use Occupancy::{Free, Occupied};

    fn state(b: Option<bool>) -> Option<Occupancy> {
        b.map(|b| if b { Occupied } else { Free })
    }

    proptest! {
        #[test]
        fn builder_matches_samples(samples in proptest::collection::vec(any::<Option<bool>>(), 0..300)) {
            let mut b = ObservationsBuilder::new();
            for (i, s) in samples.iter().enumerate() {
                b.push(i as u32, state(*s))?;
            }
            let obs = b.finish();
            for (i, s) in samples.iter().enumerate() {
                prop_assert_eq!(obs.state_at(i as u32), state(*s));
            }
            prop_assert_eq!(obs.observed_count(), samples.iter().filter(|s| s.is_some()).count() as u64);
            prop_assert_eq!(obs.occupied_count(), samples.iter().filter(|s| **s == Some(true)).count() as u64);
            // Runs are maximal: neighbours that touch differ in state.
            for w in obs.runs().windows(2) {
                prop_assert!(w[0].end() < u64::from(w[1].first) || w[0].state != w[1].state);
            }
            let rebuilt = VoxelObservations::from_runs(obs.runs().iter().map(|r| (r.first, r.len, r.state)))?;
            prop_assert_eq!(&rebuilt, &obs);
            let cut = samples.len() as u32 / 2;
            let t = obs.truncated(cut);
            for (i, s) in samples.iter().enumerate() {
                let expect = if (i as u32) < cut { state(*s) } else { None };
                prop_assert_eq!(t.state_at(i as u32), expect);
            }
            let k = obs.observed_count() / 3;
            prop_assert_eq!(obs.truncated(obs.sample_after_observed(k)).observed_count(), k);
        }
    }

    #[test]
    fn invalid_inputs() {
        assert!(VoxelObservations::from_runs([(0, 0, Free)]).is_err());
        assert!(VoxelObservations::from_runs([(5, 2, Free), (6, 1, Occupied)]).is_err());
        assert!(VoxelObservations::from_runs([(u32::MAX, 2, Free)]).is_err());
        let mut b = ObservationsBuilder::new();
        b.push(3, None).unwrap();
        assert!(b.push(3, Some(Free)).is_err());
        let obs = VoxelObservations::from_runs([(0, 2, Free), (2, 3, Free), (9, 1, Free)]).unwrap();
        assert_eq!(obs.runs().len(), 2);
        assert_eq!(obs.is_constant(), Some(Free));
        assert_eq!(obs.observed_range(), Some((0, 9)));
        assert_eq!(VoxelObservations::default().is_constant(), None);
    }
}
