//! What series to generate: timing, size and the intensity of every kind of change.

use crate::calendar::{parse_utc, DAY_SECS};
use crate::error::SynthError;
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A daily window, in hours UTC, during which a machine is present (Monday to Friday).
/// `end_hour <= start_hour` means the shift runs past midnight into the next day.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Shift {
    /// Start, hours after midnight UTC (`0 <= start_hour < 24`).
    pub start_hour: f64,
    /// End, hours after midnight UTC (`0 < end_hour <= 24`).
    pub end_hour: f64,
}

/// The scenario of a generated series. `Default` is a small office: two days every 10 minutes
/// from Monday 2016-01-04 00:00 UTC (the first minute of the real door series), 6 doors,
/// 4 people with 4 chairs, 3 objects coming and going, 2 machines on early/late shifts,
/// light surface noise and occasional partial views.
///
/// Every field has a default, so a spec is easy to build with struct update syntax, and
/// (through serde) from a partial JSON/TOML document:
///
/// ```
/// use froctomap_synth::SeriesSpec;
/// let spec = SeriesSpec { seed: 7, people: 10, ..SeriesSpec::with_duration(28.0, 600.0) };
/// assert_eq!(spec.count, 28 * 144);
/// spec.validate()?;
/// # Ok::<(), froctomap_synth::SynthError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SeriesSpec {
    /// Time of grid frame 0 (serialised as `2016-01-04T00:00:00Z`).
    #[serde(with = "utc_text")]
    pub start: Timestamp,
    /// Seconds between grid frames (> 0; nanosecond precision).
    pub step_secs: f64,
    /// Number of grid frames (before missed ones are dropped).
    pub count: u64,
    /// Seed of every random choice; the same seed gives the same series on every platform.
    pub seed: u64,
    /// Each frame's time is its grid time plus a uniform offset in `±jitter_secs`
    /// (0 = regular grid). Must be less than half of `step_secs`, so order is kept.
    pub jitter_secs: f64,
    /// Probability that a grid frame is absent from the series (a missed recording).
    pub missed_frames: f64,
    /// Start of the working day, hours UTC (people, chairs, office and meeting-room doors).
    pub work_start_hour: f64,
    /// End of the working day, hours UTC.
    pub work_end_hour: f64,
    /// Doors to place in doorways (or across corridors).
    pub doors: usize,
    /// How many of the doors follow the real door series when one is given (the others follow
    /// office/meeting-room schedules).
    pub real_doors: usize,
    /// Real door series file (`unix_time state` lines, 1 = open), loaded by
    /// [`Generator::new`](crate::Generator::new) unless a series is passed to it directly.
    pub door_file: Option<PathBuf>,
    /// People moving between a few spots during working hours.
    pub people: usize,
    /// Chairs moved between spots during working hours.
    pub chairs: usize,
    /// Object slots: each repeatedly puts a box at a random spot for some days.
    pub objects: usize,
    /// Shortest stay of an object, in days.
    pub object_min_days: f64,
    /// Longest stay of an object, in days.
    pub object_max_days: f64,
    /// Machines (blocks present during their shift).
    pub machines: usize,
    /// Shifts, assigned to machines in turn.
    pub shifts: Vec<Shift>,
    /// Probability that a surface voxel (occupied next to free, or free next to occupied)
    /// flips for a single frame.
    pub surface_noise: f64,
    /// Probability that a frame misses a region (left unknown).
    pub partial_probability: f64,
    /// Size of that region as a fraction of the map's horizontal extent on each axis (the
    /// region spans all heights), in `(0, 1]`.
    pub partial_extent: f64,
}

impl Default for SeriesSpec {
    fn default() -> Self {
        Self {
            start: Timestamp::from_secs(1_451_865_600), // Monday 2016-01-04 00:00 UTC
            step_secs: 600.0,
            count: 288,
            seed: 1,
            jitter_secs: 0.0,
            missed_frames: 0.0,
            work_start_hour: 8.0,
            work_end_hour: 18.0,
            doors: 6,
            real_doors: 3,
            door_file: None,
            people: 4,
            chairs: 4,
            objects: 3,
            object_min_days: 1.0,
            object_max_days: 5.0,
            machines: 2,
            shifts: vec![
                Shift {
                    start_hour: 6.0,
                    end_hour: 14.0,
                },
                Shift {
                    start_hour: 14.0,
                    end_hour: 22.0,
                },
            ],
            surface_noise: 0.001,
            partial_probability: 0.05,
            partial_extent: 0.3,
        }
    }
}

/// Largest number of grid frames (far above paper scale; keeps index arithmetic trivially safe).
pub const MAX_FRAMES: u64 = 1 << 40;

impl SeriesSpec {
    /// The default scenario over `days` days with one grid frame every `step_secs` seconds.
    pub fn with_duration(days: f64, step_secs: f64) -> Self {
        Self {
            step_secs,
            count: frames_for(days, step_secs),
            ..Self::default()
        }
    }

    /// Checks every field; [`Generator::new`](crate::Generator::new) calls this too.
    pub fn validate(&self) -> Result<(), SynthError> {
        self.timing().map(|_| ())?;
        probability("missed_frames", self.missed_frames)?;
        probability("surface_noise", self.surface_noise)?;
        probability("partial_probability", self.partial_probability)?;
        if !(self.partial_extent > 0.0 && self.partial_extent <= 1.0) {
            return Err(invalid(
                "partial_extent",
                format!("{} is not in (0, 1]", self.partial_extent),
            ));
        }
        hour("work_start_hour", self.work_start_hour)?;
        hour("work_end_hour", self.work_end_hour)?;
        if self.work_end_hour <= self.work_start_hour || self.work_end_hour > 24.0 {
            return Err(invalid(
                "work_end_hour",
                format!(
                    "{} must be after work_start_hour ({}) and at most 24",
                    self.work_end_hour, self.work_start_hour
                ),
            ));
        }
        if !(self.object_min_days > 0.0
            && self.object_min_days <= self.object_max_days
            && self.object_max_days <= 365.0)
        {
            return Err(invalid(
                "object_min_days",
                format!(
                    "need 0 < object_min_days ({}) <= object_max_days ({}) <= 365",
                    self.object_min_days, self.object_max_days
                ),
            ));
        }
        if self.machines > 0 && self.shifts.is_empty() {
            return Err(invalid("shifts", "machines need at least one shift".into()));
        }
        for shift in &self.shifts {
            hour("shifts", shift.start_hour)?;
            if !(shift.end_hour > 0.0 && shift.end_hour <= 24.0) {
                return Err(invalid(
                    "shifts",
                    format!("end hour {} is not in (0, 24]", shift.end_hour),
                ));
            }
        }
        for (field, n) in [
            ("doors", self.doors),
            ("people", self.people),
            ("chairs", self.chairs),
            ("objects", self.objects),
            ("machines", self.machines),
        ] {
            if n > MAX_ELEMENTS {
                return Err(invalid(field, format!("{n} is more than {MAX_ELEMENTS}")));
            }
        }
        Ok(())
    }

    /// Step and jitter in nanoseconds, checked against each other and the time range.
    pub(crate) fn timing(&self) -> Result<Timing, SynthError> {
        let step = nanos("step_secs", self.step_secs)?;
        if step < 1 {
            return Err(invalid(
                "step_secs",
                format!("{} is not a positive duration", self.step_secs),
            ));
        }
        let jitter = nanos("jitter_secs", self.jitter_secs)?;
        if jitter < 0 || jitter.saturating_mul(2) >= step {
            return Err(invalid(
                "jitter_secs",
                format!(
                    "{} must be at least 0 and less than half of step_secs ({}), so frames keep their order",
                    self.jitter_secs, self.step_secs
                ),
            ));
        }
        if self.count == 0 || self.count > MAX_FRAMES {
            return Err(invalid(
                "count",
                format!("{} is not in 1..={MAX_FRAMES}", self.count),
            ));
        }
        // The last frame time (plus jitter) must be representable.
        let span = i128::from(step) * i128::from(self.count - 1) + i128::from(jitter);
        let last = i128::from(self.start.0) + span;
        let first = i128::from(self.start.0) - i128::from(jitter);
        if last > i128::from(i64::MAX) || first < i128::from(i64::MIN) {
            return Err(invalid(
                "count",
                "the series runs past the representable time range".into(),
            ));
        }
        Ok(Timing { step, jitter })
    }
}

/// Most elements of one kind (placement cost grows with it).
pub const MAX_ELEMENTS: usize = 10_000;

/// Grid frames covering `days` days at one frame every `step_secs` seconds (at least 1).
///
/// ```
/// assert_eq!(froctomap_synth::frames_for(2.0, 600.0), 288);
/// ```
pub fn frames_for(days: f64, step_secs: f64) -> u64 {
    let n = (days * DAY_SECS as f64 / step_secs).round();
    if n.is_finite() && n >= 1.0 {
        (n as u64).min(MAX_FRAMES)
    } else {
        1
    }
}

/// Step and jitter of a validated spec, in nanoseconds.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Timing {
    pub(crate) step: i64,
    pub(crate) jitter: i64,
}

fn invalid(field: &'static str, reason: String) -> SynthError {
    SynthError::InvalidSpec { field, reason }
}

fn probability(field: &'static str, p: f64) -> Result<(), SynthError> {
    if (0.0..=1.0).contains(&p) {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("{p} is not a probability in [0, 1]"),
        ))
    }
}

fn hour(field: &'static str, h: f64) -> Result<(), SynthError> {
    if (0.0..24.0).contains(&h) {
        Ok(())
    } else {
        Err(invalid(field, format!("hour {h} is not in [0, 24)")))
    }
}

fn nanos(field: &'static str, secs: f64) -> Result<i64, SynthError> {
    let n = (secs * 1e9).round();
    if n.is_finite() && n.abs() < 9.0e18 {
        Ok(n as i64)
    } else {
        Err(invalid(field, format!("{secs} seconds is out of range")))
    }
}

/// Serde adapter: a [`Timestamp`] as ISO 8601 UTC text.
mod utc_text {
    use super::*;
    use serde::{Deserializer, Serializer};

    pub fn serialize<S: Serializer>(t: &Timestamp, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&iso8601(*t))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Timestamp, D::Error> {
        let text = String::deserialize(d)?;
        parse_utc(&text).ok_or_else(|| {
            serde::de::Error::custom(format!(
                "invalid time {text:?} (expected e.g. 2016-01-04T00:00:00Z)"
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_round_trips_through_json() {
        let spec = SeriesSpec::default();
        spec.validate().unwrap();
        let json = serde_json::to_string(&spec).unwrap();
        assert!(
            json.contains("\"start\":\"2016-01-04T00:00:00Z\""),
            "{json}"
        );
        let back: SeriesSpec = serde_json::from_str(&json).unwrap();
        assert_eq!(back, spec);
        let partial: SeriesSpec = serde_json::from_str(r#"{"seed": 9, "people": 0}"#).unwrap();
        assert_eq!((partial.seed, partial.people, partial.doors), (9, 0, 6));
        assert!(serde_json::from_str::<SeriesSpec>(r#"{"peple": 1}"#).is_err());
    }

    #[test]
    fn rejects_bad_fields() {
        let bad = [
            SeriesSpec {
                step_secs: 0.0,
                ..SeriesSpec::default()
            },
            SeriesSpec {
                jitter_secs: 300.0,
                ..SeriesSpec::default()
            },
            SeriesSpec {
                missed_frames: 1.5,
                ..SeriesSpec::default()
            },
            SeriesSpec {
                count: 0,
                ..SeriesSpec::default()
            },
            SeriesSpec {
                work_end_hour: 7.0,
                ..SeriesSpec::default()
            },
            SeriesSpec {
                object_min_days: 3.0,
                object_max_days: 2.0,
                ..SeriesSpec::default()
            },
            SeriesSpec {
                partial_extent: 0.0,
                ..SeriesSpec::default()
            },
            SeriesSpec {
                start: Timestamp(i64::MAX - 10),
                ..SeriesSpec::default()
            },
            SeriesSpec {
                shifts: vec![],
                ..SeriesSpec::default()
            },
        ];
        for spec in bad {
            let err = spec.validate().unwrap_err();
            assert!(matches!(err, SynthError::InvalidSpec { .. }), "{err}");
        }
        let ok = SeriesSpec {
            jitter_secs: 299.0,
            ..SeriesSpec::default()
        };
        ok.validate().unwrap();
    }
}
