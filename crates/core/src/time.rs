//! Instants on the time axis of a map series.

use std::fmt;

/// An instant, in whole nanoseconds since the Unix epoch (UTC).
///
/// Integer nanoseconds represent ROS stamps and file-name times exactly, so time axes
/// survive a round trip through the file format bit for bit; models work in `f64` seconds
/// relative to the start of a series.
///
/// ```
/// use froctomap_core::Timestamp;
/// let t = Timestamp::from_secs(1_451_865_600);
/// assert_eq!(t.as_secs_f64(), 1_451_865_600.0);
/// assert_eq!(Timestamp::from_secs_f64(1.5), Some(Timestamp(1_500_000_000)));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Timestamp(pub i64);

impl Timestamp {
    /// Nanoseconds per second.
    pub const NANOS_PER_SEC: i64 = 1_000_000_000;

    /// From whole seconds since the epoch (saturating at the representable range).
    pub const fn from_secs(secs: i64) -> Self {
        Timestamp(secs.saturating_mul(Self::NANOS_PER_SEC))
    }

    /// From fractional seconds, rounded to the nearest nanosecond; `None` when not finite or
    /// outside the representable range (about years 1678..2262).
    pub fn from_secs_f64(secs: f64) -> Option<Self> {
        let nanos = (secs * 1e9).round();
        // i64::MAX as f64 rounds up to 2^63, so the upper bound must be exclusive.
        (nanos.is_finite() && nanos >= i64::MIN as f64 && nanos < i64::MAX as f64)
            .then_some(Timestamp(nanos as i64))
    }

    /// Seconds since the epoch as `f64` (sub-microsecond precision for present-day times).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 / 1e9
    }

    /// Seconds from `earlier` to `self`, as `f64`.
    pub fn secs_since(self, earlier: Timestamp) -> f64 {
        // i128 avoids overflow for instants far apart.
        (i128::from(self.0) - i128::from(earlier.0)) as f64 / 1e9
    }
}

impl fmt::Display for Timestamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let secs = self.0.div_euclid(Self::NANOS_PER_SEC);
        let nanos = self.0.rem_euclid(Self::NANOS_PER_SEC);
        if nanos == 0 {
            write!(f, "{secs}s")
        } else {
            write!(f, "{secs}.{nanos:09}s")
        }
    }
}
