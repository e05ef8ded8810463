//! UTC calendar arithmetic on [`Timestamp`]s: day numbers, weekdays, time of day, and the
//! textual forms used in file names, manifests and specs.
//!
//! All schedules of the generator (working hours, shifts, meetings) are in UTC so that a
//! series means the same on every machine whatever its time zone. The date conversions are
//! Howard Hinnant's `days_from_civil` / `civil_from_days`, integer-only and exact over the
//! whole `Timestamp` range.

use froctomap_core::Timestamp;

/// Seconds per day.
pub const DAY_SECS: i64 = 86_400;
/// Seconds per week.
pub const WEEK_SECS: i64 = 7 * DAY_SECS;
const NANOS: i64 = Timestamp::NANOS_PER_SEC;

/// Whole seconds since the epoch, rounded down (also for instants before 1970).
pub fn unix_secs(t: Timestamp) -> i64 {
    t.0.div_euclid(NANOS)
}

/// Days since 1970-01-01 (UTC), rounded down.
pub fn day_number(t: Timestamp) -> i64 {
    unix_secs(t).div_euclid(DAY_SECS)
}

/// Seconds since midnight UTC, `0..86400`.
pub fn second_of_day(t: Timestamp) -> i64 {
    unix_secs(t).rem_euclid(DAY_SECS)
}

/// Day of the week of a day number: 0 = Monday … 6 = Sunday (1970-01-01 was a Thursday).
pub fn weekday_of_day(day: i64) -> u8 {
    // rem_euclid(7) is in 0..7.
    (day + 3).rem_euclid(7) as u8
}

/// Day of the week of an instant: 0 = Monday … 6 = Sunday.
///
/// ```
/// use froctomap_synth::calendar::{parse_utc, weekday};
/// let monday = parse_utc("2016-01-04T00:00:00Z").unwrap();
/// assert_eq!(weekday(monday), 0);
/// ```
pub fn weekday(t: Timestamp) -> u8 {
    weekday_of_day(day_number(t))
}

/// `true` Monday to Friday.
pub fn is_weekday(day: i64) -> bool {
    weekday_of_day(day) < 5
}

pub use froctomap_core::calendar::{civil_from_days, days_from_civil};

/// Parses `YYYY-MM-DDTHH:MM:SS[.fffffffff]Z` (a space may replace the `T`; the `Z` may be
/// omitted, the time is UTC either way) or a date alone, `YYYY-MM-DD` (midnight).
///
/// ```
/// use froctomap_synth::calendar::parse_utc;
/// assert_eq!(parse_utc("2016-01-04").unwrap().0, 1_451_865_600_000_000_000);
/// assert_eq!(parse_utc("1970-01-01T00:00:01.5Z").unwrap().0, 1_500_000_000);
/// assert!(parse_utc("2016-02-30").is_none());
/// ```
pub fn parse_utc(text: &str) -> Option<Timestamp> {
    froctomap_core::calendar::parse_iso8601(text)
}

/// Unix seconds with up to nine decimals, no trailing zeros: `1451865600`, `1451865600.5`,
/// `-0.25`. This is the time column of `manifest.csv`; [`parse_unix_secs`] reads it back
/// exactly (no floating point on the way).
///
/// ```
/// use froctomap_core::Timestamp;
/// use froctomap_synth::calendar::{parse_unix_secs, unix_secs_text};
/// let t = Timestamp(1_451_865_600_123_000_000);
/// assert_eq!(unix_secs_text(t), "1451865600.123");
/// assert_eq!(parse_unix_secs("1451865600.123"), Some(t));
/// ```
pub fn unix_secs_text(t: Timestamp) -> String {
    froctomap_core::calendar::unix_seconds(t)
}

/// Parses [`unix_secs_text`]'s form (an optional `-`, digits, optionally `.` and 1–9 digits).
pub fn parse_unix_secs(text: &str) -> Option<Timestamp> {
    froctomap_core::calendar::parse_unix_seconds(text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::calendar::{iso8601, iso8601_basic};

    #[test]
    fn civil_round_trip_and_known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(2016, 1, 4), 16_804);
        assert_eq!(civil_from_days(16_804), (2016, 1, 4));
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
        for day in (-800_000..800_000).step_by(997) {
            let (y, m, d) = civil_from_days(day);
            assert_eq!(days_from_civil(y, m, d), day);
        }
        assert_eq!(weekday_of_day(16_804), 0); // 2016-01-04 was a Monday
        assert_eq!(weekday_of_day(0), 3); // 1970-01-01 was a Thursday
        assert_eq!(weekday_of_day(-1), 2);
    }

    #[test]
    fn text_forms() {
        let t = Timestamp(1_451_896_200_000_000_000); // 2016-01-04 08:30:00
        assert_eq!(iso8601_basic(t), "20160104T083000Z");
        assert_eq!(iso8601(t), "2016-01-04T08:30:00Z");
        assert_eq!(parse_utc("2016-01-04T08:30:00Z"), Some(t));
        assert_eq!(parse_utc("2016-01-04 08:30"), Some(t));
        let frac = Timestamp(t.0 + 120_000_000);
        assert_eq!(iso8601_basic(frac), "20160104T083000.12Z");
        assert_eq!(parse_utc(&iso8601(frac)), Some(frac));
        let before = Timestamp(-1_500_000_000);
        assert_eq!(iso8601(before), "1969-12-31T23:59:58.5Z");
        assert_eq!(unix_secs_text(before), "-1.5");
        assert_eq!(parse_unix_secs("-1.5"), Some(before));
        assert_eq!(unix_secs_text(Timestamp(5)), "0.000000005");
        assert_eq!(parse_unix_secs("0.000000005"), Some(Timestamp(5)));
        for bad in ["", "1.", ".5", "1.0000000001", "1e3", "1.-5"] {
            assert_eq!(parse_unix_secs(bad), None, "{bad}");
        }
        assert!(parse_utc("2016-13-01").is_none());
        assert!(parse_utc("2016-01-01T24:00:00Z").is_none());
    }
}
