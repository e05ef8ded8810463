//! The time axis shared by every voxel of a map series.

use crate::TemporalError;
use froctomap_core::Timestamp;

/// Which representation a [`TimeAxis`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AxisKind {
    /// Samples on a uniform grid `start + i·step`, some possibly missing.
    Regular,
    /// An explicit list of strictly increasing instants.
    Explicit,
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum Repr {
    Regular {
        start: Timestamp,
        step_ns: i64,
        count: u32,
        missing: Vec<u32>,
    },
    Explicit {
        times: Vec<Timestamp>,
    },
}

/// The instants of the snapshots of a series, indexed by *sample* `0..len()`.
///
/// Every voxel is observed (or not) at these samples, so per-axis work (trigonometric tables,
/// FFT plans) is done once per map. A regular axis may list *missing* grid samples where no
/// snapshot exists at all; every voxel is unknown there. Sample indices are `u32`.
///
/// ```
/// use froctomap_core::Timestamp;
/// use froctomap_temporal::TimeAxis;
/// let axis = TimeAxis::regular(Timestamp::from_secs(100), 60_000_000_000, 5, vec![2])?;
/// assert_eq!(axis.len(), 5);
/// assert_eq!(axis.time(3), Some(Timestamp::from_secs(280)));
/// assert_eq!(axis.seconds_since_start(3), Some(180.0));
/// assert!(axis.is_missing(2));
/// assert_eq!(axis.index_of(Timestamp::from_secs(160)), Some(1));
/// assert_eq!(axis.last_at_or_before(Timestamp::from_secs(239)), Some(1)); // 2 is missing
/// let explicit = TimeAxis::explicit(vec![Timestamp(5), Timestamp(9)])?;
/// assert_eq!(explicit.last_at_or_before(Timestamp(8)), Some(0));
/// # Ok::<(), froctomap_temporal::TemporalError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TimeAxis {
    repr: Repr,
}

impl TimeAxis {
    /// A uniform grid of `count` samples `start + i·step_ns`; `missing` lists the sample
    /// indices without any snapshot (sorted, unique, below `count`, not all of them).
    pub fn regular(
        start: Timestamp,
        step_ns: i64,
        count: u32,
        missing: Vec<u32>,
    ) -> Result<Self, TemporalError> {
        if step_ns <= 0 {
            return Err(TemporalError::InvalidAxis("step must be positive"));
        }
        if count == 0 {
            return Err(TemporalError::InvalidAxis("no samples"));
        }
        if start
            .0
            .checked_add((i64::from(count) - 1).saturating_mul(step_ns))
            .is_none()
            || (i64::from(count) - 1).checked_mul(step_ns).is_none()
        {
            return Err(TemporalError::InvalidAxis(
                "last sample beyond the representable time range",
            ));
        }
        if missing.windows(2).any(|w| w[0] >= w[1]) {
            return Err(TemporalError::InvalidAxis(
                "missing samples not sorted and unique",
            ));
        }
        if missing.last().is_some_and(|&m| m >= count) {
            return Err(TemporalError::InvalidAxis("missing sample beyond the axis"));
        }
        if missing.len() as u64 >= u64::from(count) {
            return Err(TemporalError::InvalidAxis("every sample is missing"));
        }
        Ok(Self {
            repr: Repr::Regular {
                start,
                step_ns,
                count,
                missing,
            },
        })
    }

    /// An axis of the given instants, which must be strictly increasing, non-empty and at most
    /// `u32::MAX` long.
    pub fn explicit(times: Vec<Timestamp>) -> Result<Self, TemporalError> {
        if times.is_empty() {
            return Err(TemporalError::InvalidAxis("no samples"));
        }
        if u32::try_from(times.len()).is_err() {
            return Err(TemporalError::InvalidAxis("more than u32::MAX samples"));
        }
        if times.windows(2).any(|w| w[0] >= w[1]) {
            return Err(TemporalError::InvalidAxis("times not strictly increasing"));
        }
        Ok(Self {
            repr: Repr::Explicit { times },
        })
    }

    /// Which representation this axis uses.
    pub fn kind(&self) -> AxisKind {
        match self.repr {
            Repr::Regular { .. } => AxisKind::Regular,
            Repr::Explicit { .. } => AxisKind::Explicit,
        }
    }

    /// Number of samples (including missing grid samples).
    pub fn len(&self) -> u32 {
        match &self.repr {
            Repr::Regular { count, .. } => *count,
            // Checked at construction.
            Repr::Explicit { times } => times.len() as u32,
        }
    }

    /// Always `false`: an axis has at least one sample. (Provided for API symmetry.)
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Instant of sample `i`; `None` beyond the axis.
    pub fn time(&self, i: u32) -> Option<Timestamp> {
        match &self.repr {
            Repr::Regular {
                start,
                step_ns,
                count,
                ..
            } => (i < *count).then(|| Timestamp(start.0 + i64::from(i) * step_ns)),
            Repr::Explicit { times } => times.get(i as usize).copied(),
        }
    }

    /// Seconds from the first sample to sample `i`; `None` beyond the axis.
    ///
    /// This is the time variable of every model: computed from integer nanoseconds, so it is
    /// the same `f64` on every machine.
    pub fn seconds_since_start(&self, i: u32) -> Option<f64> {
        let t = self.time(i)?;
        Some(t.secs_since(self.start()))
    }

    /// `true` when sample `i` has no snapshot (a listed missing grid sample, or beyond the axis).
    pub fn is_missing(&self, i: u32) -> bool {
        match &self.repr {
            Repr::Regular { count, missing, .. } => {
                i >= *count || missing.binary_search(&i).is_ok()
            }
            Repr::Explicit { times } => i as usize >= times.len(),
        }
    }

    /// The sample whose instant is exactly `t` (for a regular axis this includes missing grid
    /// samples, which have an instant but no snapshot).
    pub fn index_of(&self, t: Timestamp) -> Option<u32> {
        match &self.repr {
            Repr::Regular {
                start,
                step_ns,
                count,
                ..
            } => {
                let offset = t.0.checked_sub(start.0)?;
                if offset < 0 || offset % step_ns != 0 {
                    return None;
                }
                let i = u32::try_from(offset / step_ns).ok()?;
                (i < *count).then_some(i)
            }
            Repr::Explicit { times } => times.binary_search(&t).ok().map(|i| i as u32),
        }
    }

    /// The last sample with a snapshot at or before `t` (missing grid samples are skipped);
    /// `None` when `t` is before the first such sample.
    pub fn last_at_or_before(&self, t: Timestamp) -> Option<u32> {
        match &self.repr {
            Repr::Regular {
                start,
                step_ns,
                count,
                missing,
            } => {
                let offset = i128::from(t.0) - i128::from(start.0);
                if offset < 0 {
                    return None;
                }
                let grid = (offset / i128::from(*step_ns)).min(i128::from(*count) - 1);
                let mut i = u32::try_from(grid).ok()?;
                // Step back over missing samples: walk the sorted missing list backwards.
                let mut k = missing.partition_point(|&m| m <= i);
                while k > 0 && missing.get(k - 1) == Some(&i) {
                    i = i.checked_sub(1)?;
                    k -= 1;
                }
                Some(i)
            }
            Repr::Explicit { times } => {
                let k = times.partition_point(|&x| x <= t);
                k.checked_sub(1).map(|i| i as u32)
            }
        }
    }

    /// Instant of the first sample.
    pub fn start(&self) -> Timestamp {
        match &self.repr {
            Repr::Regular { start, .. } => *start,
            Repr::Explicit { times } => times.first().copied().unwrap_or_default(),
        }
    }

    /// Instant of the last sample.
    pub fn end(&self) -> Timestamp {
        self.time(self.len() - 1).unwrap_or_default()
    }

    /// Seconds from the first to the last sample.
    pub fn span_seconds(&self) -> f64 {
        self.end().secs_since(self.start())
    }

    /// Seconds between samples: the grid step of a regular axis, the mean spacing of an
    /// explicit one (0 for a single sample).
    ///
    /// ```
    /// use froctomap_core::Timestamp;
    /// use froctomap_temporal::TimeAxis;
    /// let regular = TimeAxis::regular(Timestamp::from_secs(0), 600_000_000_000, 10, vec![])?;
    /// assert_eq!(regular.mean_step_seconds(), 600.0);
    /// let times = [0, 100, 400].map(Timestamp::from_secs).to_vec();
    /// assert_eq!(TimeAxis::explicit(times)?.mean_step_seconds(), 200.0);
    /// # Ok::<(), froctomap_temporal::TemporalError>(())
    /// ```
    pub fn mean_step_seconds(&self) -> f64 {
        match &self.repr {
            Repr::Regular { step_ns, .. } => *step_ns as f64 / 1e9,
            Repr::Explicit { times } if times.len() > 1 => {
                self.span_seconds() / (times.len() - 1) as f64
            }
            Repr::Explicit { .. } => 0.0,
        }
    }

    /// Grid step of a regular axis, in nanoseconds.
    pub fn step_ns(&self) -> Option<i64> {
        match &self.repr {
            Repr::Regular { step_ns, .. } => Some(*step_ns),
            Repr::Explicit { .. } => None,
        }
    }

    /// Missing grid samples of a regular axis (empty for an explicit axis).
    pub fn missing(&self) -> &[u32] {
        match &self.repr {
            Repr::Regular { missing, .. } => missing,
            Repr::Explicit { .. } => &[],
        }
    }

    /// The instants of an explicit axis.
    pub fn times(&self) -> Option<&[Timestamp]> {
        match &self.repr {
            Repr::Regular { .. } => None,
            Repr::Explicit { times } => Some(times),
        }
    }

    /// Seconds covered by the samples `first..=last`: from the first to the last plus one
    /// step, since each sample stands for its step (n samples `s` apart cover `n·s`). What a
    /// period's cycles are counted in when deciding whether a voxel may use it (`min-cycles`).
    pub(crate) fn coverage_seconds(&self, first: u32, last: u32) -> f64 {
        self.sample_seconds(last) - self.sample_seconds(first) + self.mean_step_seconds()
    }

    /// Seconds since the start for any sample index: extrapolated along the grid beyond the
    /// end of a regular axis, the last instant beyond the end of an explicit axis.
    pub(crate) fn sample_seconds(&self, i: u32) -> f64 {
        match &self.repr {
            Repr::Regular { step_ns, .. } => (i128::from(i) * i128::from(*step_ns)) as f64 / 1e9,
            Repr::Explicit { times } => {
                let t = times
                    .get(i as usize)
                    .or(times.last())
                    .copied()
                    .unwrap_or_default();
                t.secs_since(self.start())
            }
        }
    }

    /// How many samples `j` in `from..end` (a prefix, as times increase) lie at most
    /// `limit_ns` nanoseconds after sample `anchor ≤ from`. Exact integer arithmetic.
    pub(crate) fn samples_within(&self, anchor: u32, from: u32, end: u64, limit_ns: i64) -> u32 {
        let available = end.saturating_sub(u64::from(from));
        if limit_ns < 0 || from < anchor {
            return 0;
        }
        let count = match &self.repr {
            Repr::Regular { step_ns, .. } => {
                let offset = u64::from(from - anchor);
                let max_steps = (limit_ns / step_ns) as u64;
                if offset > max_steps {
                    0
                } else {
                    (max_steps - offset + 1).min(available)
                }
            }
            Repr::Explicit { times } => {
                let stop = (end.min(times.len() as u64)) as usize;
                match (times.get(anchor as usize), times.get(from as usize..stop)) {
                    (Some(t0), Some(slice)) => {
                        slice.partition_point(|t| t.0.saturating_sub(t0.0) <= limit_ns) as u64
                    }
                    _ => 0,
                }
            }
        };
        count.min(available) as u32
    }

    /// Checks that observations lie on the axis and avoid missing samples.
    pub(crate) fn check(&self, obs: &crate::VoxelObservations) -> Result<(), TemporalError> {
        if let Some(last) = obs.runs().last() {
            if last.end() > u64::from(self.len()) {
                return Err(TemporalError::InvalidObservations {
                    reason: "observation beyond the axis",
                    sample: last.end() - 1,
                });
            }
        }
        if !self.missing().is_empty() {
            for run in obs.runs() {
                if self.missing_in(run.first, run.len) > 0 {
                    return Err(TemporalError::InvalidObservations {
                        reason: "observation at a missing sample",
                        sample: u64::from(run.first),
                    });
                }
            }
        }
        Ok(())
    }

    /// Number of missing samples in `first..first + len`.
    pub(crate) fn missing_in(&self, first: u32, len: u32) -> usize {
        let missing = self.missing();
        let end = u64::from(first) + u64::from(len);
        let lo = missing.partition_point(|&m| m < first);
        let hi = missing.partition_point(|&m| u64::from(m) < end);
        hi.saturating_sub(lo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation() {
        let t0 = Timestamp(0);
        assert!(TimeAxis::regular(t0, 0, 3, vec![]).is_err());
        assert!(TimeAxis::regular(t0, 1, 0, vec![]).is_err());
        assert!(TimeAxis::regular(t0, 1, 3, vec![2, 1]).is_err());
        assert!(TimeAxis::regular(t0, 1, 3, vec![3]).is_err());
        assert!(TimeAxis::regular(t0, 1, 2, vec![0, 1]).is_err());
        assert!(TimeAxis::regular(Timestamp(i64::MAX - 5), 3, 3, vec![]).is_err());
        assert!(TimeAxis::regular(Timestamp(i64::MAX - 6), 3, 3, vec![]).is_ok());
        assert!(TimeAxis::explicit(vec![]).is_err());
        assert!(TimeAxis::explicit(vec![Timestamp(1), Timestamp(1)]).is_err());
    }

    #[test]
    fn lookups() {
        let axis = TimeAxis::regular(Timestamp(10), 5, 6, vec![0, 3, 4]).unwrap();
        assert_eq!(axis.end(), Timestamp(35));
        assert_eq!(axis.last_at_or_before(Timestamp(9)), None);
        assert_eq!(axis.last_at_or_before(Timestamp(10)), None); // sample 0 is missing
        assert_eq!(axis.last_at_or_before(Timestamp(34)), Some(2));
        assert_eq!(axis.last_at_or_before(Timestamp(1000)), Some(5));
        assert_eq!(axis.index_of(Timestamp(12)), None);
        assert_eq!(axis.index_of(Timestamp(40)), None);
        assert_eq!(axis.index_of(Timestamp(25)), Some(3));
        assert_eq!(axis.time(6), None);
        assert_eq!(axis.missing_in(2, 3), 2);
        assert_eq!(axis.missing_in(5, 1), 0);
        assert!(axis.is_missing(6));
        let e = TimeAxis::explicit(vec![Timestamp(-5), Timestamp(7), Timestamp(100)]).unwrap();
        assert_eq!(e.span_seconds(), 105e-9);
        assert_eq!(e.index_of(Timestamp(7)), Some(1));
        assert_eq!(e.last_at_or_before(Timestamp(99)), Some(1));
        assert_eq!(e.last_at_or_before(Timestamp(-6)), None);
        assert_eq!(e.seconds_since_start(2), Some(105e-9));
    }
}
