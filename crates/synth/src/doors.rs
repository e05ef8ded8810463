//! The real door series: one office door's open/closed state every minute.
//!
//! The file (`shared/data/greg_door_2016_min/training_data.txt`, from the FreMEn/HyperTime
//! papers) has lines `unix_time state`, one per minute, state 1 = open and 0 = closed, over
//! ten weeks from Monday 2016-01-04 00:00 UTC, with a three-day recording outage.
//!
//! A generated series may be longer than the recording or start at another date, so the
//! series is *wrapped* over whole weeks: minute `m` after the recording's first minute reads
//! minute `m mod (weeks · 10080)`, which keeps weekday and time of day. Minutes the recording
//! lacks (the outage, a missing tail) are filled from the same minute of the nearest week
//! that has it, so filled minutes still look like that door on that weekday.

use crate::calendar::unix_secs;
use crate::error::SynthError;
use froctomap_core::Timestamp;
use std::path::Path;

const MINUTES_PER_WEEK: i64 = 7 * 24 * 60;
/// Longest recording accepted: ten years of minutes (10 MB of states).
const MAX_MINUTES: i64 = 520 * MINUTES_PER_WEEK;

/// A door's open/closed state per minute, wrapped over whole weeks.
///
/// ```
/// use froctomap_core::Timestamp;
/// use froctomap_synth::DoorSeries;
/// let text = "1451865600 0\n1451865660 1\n1451865720 1\n";
/// let door = DoorSeries::parse(text, "inline")?;
/// assert_eq!(door.recorded_at(Timestamp::from_secs(1_451_865_690)), Some(true));
/// assert!(!door.is_open_at(Timestamp::from_secs(1_451_865_600)));
/// # Ok::<(), froctomap_synth::SynthError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct DoorSeries {
    source: String,
    /// Unix seconds of the first recorded minute.
    start_secs: i64,
    /// Per minute over whole weeks: bit 0 = open, bit 1 = recorded (not filled).
    minutes: Vec<u8>,
    /// Minutes from the first to the last sample, inclusive.
    span: usize,
    samples: usize,
}

const OPEN: u8 = 1;
const RECORDED: u8 = 2;

impl DoorSeries {
    /// Reads a door file. Errors name the file and the line.
    pub fn load(path: &Path) -> Result<Self, SynthError> {
        let text = std::fs::read_to_string(path).map_err(|source| SynthError::DoorSeriesIo {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses door-file text; `source` names it in errors. Blank lines and lines starting
    /// with `#` are skipped; times must increase; several samples in one minute keep the last.
    pub fn parse(text: &str, source: &str) -> Result<Self, SynthError> {
        let fail = |line: usize, reason: String| SynthError::DoorSeriesParse {
            source_name: source.to_string(),
            line,
            reason,
        };
        let mut samples = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let mut fields = line.split_whitespace();
            let (Some(time), Some(state), None) = (fields.next(), fields.next(), fields.next())
            else {
                return Err(fail(
                    n + 1,
                    format!("expected `unix_time state`, found {line:?}"),
                ));
            };
            let time: i64 = time
                .parse()
                .map_err(|_| fail(n + 1, format!("time {time:?} is not whole Unix seconds")))?;
            let open = match state {
                "1" => true,
                "0" => false,
                other => {
                    return Err(fail(
                        n + 1,
                        format!("state {other:?} is neither 0 (closed) nor 1 (open)"),
                    ))
                }
            };
            if let Some(&(previous, _, _)) = samples.last() {
                if time <= previous {
                    return Err(fail(
                        n + 1,
                        format!("time {time} does not increase (previous {previous})"),
                    ));
                }
            }
            samples.push((time, open, n + 1));
        }
        let pairs: Vec<(i64, bool)> = samples.iter().map(|&(t, s, _)| (t, s)).collect();
        Self::build(&pairs, source, |i| samples.get(i).map_or(0, |s| s.2))
    }

    /// A series from `(unix_seconds, open)` samples in increasing time order.
    pub fn from_samples(samples: &[(i64, bool)], source: &str) -> Result<Self, SynthError> {
        if let Some(i) = samples.windows(2).position(|w| w[1].0 <= w[0].0) {
            return Err(SynthError::DoorSeriesParse {
                source_name: source.to_string(),
                line: i + 2,
                reason: "sample times do not increase".into(),
            });
        }
        Self::build(samples, source, |i| i + 1)
    }

    fn build(
        samples: &[(i64, bool)],
        source: &str,
        line_of: impl Fn(usize) -> usize,
    ) -> Result<Self, SynthError> {
        let fail = |line: usize, reason: String| SynthError::DoorSeriesParse {
            source_name: source.to_string(),
            line,
            reason,
        };
        let (Some(&(first, _)), Some(&(last, _))) = (samples.first(), samples.last()) else {
            return Err(fail(0, "no samples".into()));
        };
        let span_minutes = (i128::from(last) - i128::from(first)) / 60 + 1;
        if span_minutes > i128::from(MAX_MINUTES) {
            return Err(fail(
                line_of(samples.len() - 1),
                format!("the recording spans more than {MAX_MINUTES} minutes"),
            ));
        }
        // Bounded by MAX_MINUTES above.
        let span = span_minutes as i64;
        let weeks = (span + MINUTES_PER_WEEK - 1) / MINUTES_PER_WEEK;
        let total = (weeks * MINUTES_PER_WEEK) as usize;
        let mut minutes = vec![0u8; total];
        for &(t, open) in samples {
            let m = ((t - first) / 60) as usize;
            minutes[m] = RECORDED | u8::from(open);
        }
        // Fill unrecorded minutes from the same minute of the nearest recorded week, looking
        // one week back, then forward, then two weeks back...
        let week = MINUTES_PER_WEEK as usize;
        for m in 0..total {
            if minutes[m] & RECORDED != 0 {
                continue;
            }
            let mut filled = None;
            for k in 1..weeks as usize {
                let back = (m + total - (k * week) % total) % total;
                let forward = (m + k * week) % total;
                if minutes[back] & RECORDED != 0 {
                    filled = Some(minutes[back] & OPEN);
                    break;
                }
                if minutes[forward] & RECORDED != 0 {
                    filled = Some(minutes[forward] & OPEN);
                    break;
                }
            }
            // No week has this minute: hold the previous minute's state.
            minutes[m] = filled.unwrap_or_else(|| {
                if m == 0 {
                    // Minute 0 always holds the first sample.
                    0
                } else {
                    minutes[m - 1] & OPEN
                }
            });
        }
        Ok(Self {
            source: source.to_string(),
            start_secs: first,
            minutes,
            span: span as usize,
            samples: samples.len(),
        })
    }

    /// Where the series came from (file name or the name given).
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Time of the first sample.
    pub fn start(&self) -> Timestamp {
        Timestamp::from_secs(self.start_secs)
    }

    /// Number of samples read.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Whole weeks the series wraps over.
    pub fn weeks(&self) -> usize {
        self.minutes.len() / MINUTES_PER_WEEK as usize
    }

    /// Fraction of recorded minutes with the door open.
    pub fn open_fraction(&self) -> f64 {
        let (open, recorded) = self.minutes.iter().fold((0u64, 0u64), |(o, r), &m| {
            if m & RECORDED != 0 {
                (o + u64::from(m & OPEN), r + 1)
            } else {
                (o, r)
            }
        });
        open as f64 / recorded.max(1) as f64
    }

    /// Index into the wrapped minutes of `time` shifted by `offset_minutes`.
    fn minute_index(&self, time: Timestamp, offset_minutes: i64) -> usize {
        let minute = (unix_secs(time) - self.start_secs).div_euclid(60);
        let total = self.minutes.len() as i64;
        // rem_euclid of a positive modulus is in 0..total.
        (minute.rem_euclid(total) + offset_minutes.rem_euclid(total)).rem_euclid(total) as usize
    }

    /// The door's state at any time (wrapped over whole weeks, gaps filled); `true` = open.
    pub fn is_open_at(&self, time: Timestamp) -> bool {
        self.is_open_shifted(time, 0)
    }

    /// As [`is_open_at`](Self::is_open_at), reading the series `offset_minutes` later, which
    /// is how several doors share one recording without moving in lockstep.
    pub fn is_open_shifted(&self, time: Timestamp, offset_minutes: i64) -> bool {
        self.minutes
            .get(self.minute_index(time, offset_minutes))
            .is_some_and(|m| m & OPEN != 0)
    }

    /// The recorded state at `time`: `None` outside the recording or in a minute it lacks.
    pub fn recorded_at(&self, time: Timestamp) -> Option<bool> {
        let minute = (unix_secs(time) - self.start_secs).div_euclid(60);
        let m = *self.minutes.get(usize::try_from(minute).ok()?)?;
        (usize::try_from(minute).ok()? < self.span && m & RECORDED != 0).then_some(m & OPEN != 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_source_and_line() {
        let err = DoorSeries::parse("100 0\n160 2\n", "door.txt").unwrap_err();
        assert_eq!(
            err.to_string(),
            "door.txt: line 2: state \"2\" is neither 0 (closed) nor 1 (open)"
        );
        let err = DoorSeries::parse("100 0\n\n100 1\n", "d").unwrap_err();
        assert!(err
            .to_string()
            .starts_with("d: line 3: time 100 does not increase"));
        let err = DoorSeries::parse("100\n", "d").unwrap_err();
        assert!(err
            .to_string()
            .contains("line 1: expected `unix_time state`"));
        let err = DoorSeries::parse("x 1\n", "d").unwrap_err();
        assert!(err.to_string().contains("not whole Unix seconds"));
        assert!(DoorSeries::parse("# only a comment\n", "d").is_err());
        let missing = DoorSeries::load(Path::new("/nonexistent/door.txt")).unwrap_err();
        assert!(missing
            .to_string()
            .starts_with("/nonexistent/door.txt: cannot read"));
    }

    #[test]
    fn wraps_over_weeks_and_fills_gaps_from_other_weeks() {
        // Two weeks of minutes; the door is open in week 0 at minute 10 only, and week 1
        // misses minutes 0..20 entirely.
        let week = MINUTES_PER_WEEK;
        let mut samples = Vec::new();
        for m in 0..2 * week {
            if m >= week && m < week + 20 {
                continue;
            }
            samples.push((m * 60, m == 10));
        }
        let door = DoorSeries::from_samples(&samples, "test").unwrap();
        assert_eq!(door.weeks(), 2);
        let at = |minute: i64| Timestamp::from_secs(minute * 60 + 30);
        assert!(door.is_open_at(at(10)));
        assert!(!door.is_open_at(at(11)));
        assert_eq!(door.recorded_at(at(week + 10)), None);
        // Filled from week 0.
        assert!(door.is_open_at(at(week + 10)));
        // Wrapped: week 2 reads week 0; before the start reads the last week.
        assert!(door.is_open_at(at(2 * week + 10)));
        assert!(door.is_open_at(at(-week + 10)));
        assert!(door.is_open_shifted(at(week + 10), week));
        assert!(!door.is_open_shifted(at(10), 1));
    }
}
