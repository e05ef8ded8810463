//! Instants as users write them: Unix seconds, ISO 8601, or embedded in file names.

use froctomap_core::{calendar, Timestamp};

/// Earliest instant froctomap accepts: 1970-01-01T00:00:00Z. Robot maps are not older.
pub const EARLIEST: Timestamp = Timestamp(0);
/// Latest instant froctomap accepts: 2200-01-01T00:00:00Z.
pub const LATEST: Timestamp = Timestamp(7_258_118_400 * 1_000_000_000);

/// Earliest time read from a file name: 1990-01-01T00:00:00Z. A name that reads as an
/// earlier time is almost always a frame number (`map_0000000041.bt` would be 41 s after
/// 1970), so such names are refused rather than given a silently wrong time.
pub const EARLIEST_IN_NAME: Timestamp = Timestamp(631_152_000 * 1_000_000_000);

/// Why a time could not be understood.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[error("cannot read {input:?} as a {what}: {reason}")]
pub struct TimeError {
    /// What was given.
    pub input: String,
    /// What it was read as: `"time"` or `"duration"`.
    pub what: &'static str,
    /// What is wrong.
    pub reason: String,
}

fn error(input: &str, reason: impl Into<String>) -> TimeError {
    TimeError {
        input: input.to_string(),
        what: "time",
        reason: reason.into(),
    }
}

/// A duration that could not be understood.
fn duration_error(input: &str, reason: impl Into<String>) -> TimeError {
    TimeError {
        what: "duration",
        ..error(input, reason)
    }
}

/// The zone in which a time without one (`2016-01-04 08:30`, a name like
/// `2024-03-01-10-15-00.bt`) is read: UTC unless the user says otherwise. Unix seconds and
/// times with `Z` or an offset are never affected.
///
/// ```
/// use froctomap_convert::{read_time, Zone};
/// use froctomap_core::Timestamp;
/// let paris_winter = Zone::named("+01:00").unwrap();
/// let read = read_time("2016-01-04T01:00:00", &paris_winter).unwrap();
/// assert_eq!(read.time, Timestamp::from_secs(1_451_865_600));
/// assert!(read.zoneless);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Zone(jiff::tz::TimeZone);

impl Default for Zone {
    fn default() -> Self {
        Self::utc()
    }
}

impl Zone {
    /// Coordinated Universal Time (the default).
    pub fn utc() -> Self {
        Self(jiff::tz::TimeZone::UTC)
    }

    /// `UTC`, `local` (the system's zone), a fixed offset (`+01:00`, `-0530`, `+02`) or an
    /// IANA name from the system's time zone database (`Europe/Berlin`).
    pub fn named(text: &str) -> Result<Self, TimeError> {
        let text = text.trim();
        if text.eq_ignore_ascii_case("utc") || text == "Z" {
            return Ok(Self::utc());
        }
        if text.eq_ignore_ascii_case("local") {
            return jiff::tz::TimeZone::try_system()
                .map(Self)
                .map_err(|e| error(text, format!("the system time zone is unknown: {e}")));
        }
        if let Some(seconds) = fixed_offset_seconds(text) {
            return jiff::tz::Offset::from_seconds(seconds)
                .map(|offset| Self(jiff::tz::TimeZone::fixed(offset)))
                .map_err(|e| error(text, e.to_string()));
        }
        jiff::tz::TimeZone::get(text).map(Self).map_err(|_| {
            error(
                text,
                "not a time zone (use UTC, local, an offset like +01:00, or a name like Europe/Berlin)",
            )
        })
    }

    /// Whether this is UTC, the reading of zone-less times when nothing is said.
    pub fn is_utc(&self) -> bool {
        self.0 == jiff::tz::TimeZone::UTC
    }

    /// The instant of a wall-clock time in this zone (`wall` is that time read as UTC).
    /// A time skipped or repeated by a daylight-saving change takes the earlier offset.
    fn instant(&self, input: &str, wall: Timestamp) -> Result<Timestamp, TimeError> {
        if self.is_utc() {
            return Ok(wall);
        }
        let out_of_range = || error(input, "is outside the supported range");
        let utc =
            jiff::Timestamp::from_nanosecond(i128::from(wall.0)).map_err(|_| out_of_range())?;
        let civil = jiff::tz::TimeZone::UTC.to_datetime(utc);
        let local = self
            .0
            .to_ambiguous_timestamp(civil)
            .compatible()
            .map_err(|_| out_of_range())?;
        i64::try_from(local.as_nanosecond())
            .map(Timestamp)
            .map_err(|_| out_of_range())
    }
}

/// `+01:00`, `-0530` or `+02` as seconds east of UTC.
fn fixed_offset_seconds(text: &str) -> Option<i32> {
    let sign = match text.as_bytes().first()? {
        b'+' => 1,
        b'-' => -1,
        _ => return None,
    };
    let digits: String = text[1..].chars().filter(|&c| c != ':').collect();
    if !digits.bytes().all(|b| b.is_ascii_digit()) || !matches!(digits.len(), 2 | 4) {
        return None;
    }
    let hours: i32 = digits[..2].parse().ok()?;
    let minutes: i32 = digits.get(2..).map_or(Some(0), |m| m.parse().ok())?;
    (hours <= 23 && minutes <= 59).then_some(sign * (hours * 3600 + minutes * 60))
}

/// A time read from text, and whether the text lacked a zone (and the reader's [`Zone`]
/// was applied): the front end says once that such times are read as UTC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadTime {
    /// The instant.
    pub time: Timestamp,
    /// The text was a wall-clock time without `Z` or an offset.
    pub zoneless: bool,
}

/// Checks that an instant is in the range froctomap accepts (1970 to 2200).
pub fn check_range(input: &str, t: Timestamp) -> Result<Timestamp, TimeError> {
    if t < EARLIEST || t > LATEST {
        return Err(error(
            input,
            format!(
                "{} is outside the supported range 1970-01-01 .. 2200-01-01",
                calendar::iso8601(t)
            ),
        ));
    }
    Ok(t)
}

/// Parses Unix seconds (`1451865600`, `1451865600.25`) or ISO 8601
/// (`2016-01-04T08:30:00Z`, `2016-01-04 08:30:00+01:00`, `2016-01-04`, `20160104T083000Z`).
/// A time without zone is UTC.
///
/// ```
/// use froctomap_convert::parse_time;
/// use froctomap_core::Timestamp;
/// assert_eq!(parse_time("1451865600").unwrap(), Timestamp::from_secs(1_451_865_600));
/// assert_eq!(parse_time("2016-01-04T00:00:00Z").unwrap(), Timestamp::from_secs(1_451_865_600));
/// assert_eq!(parse_time("2016-01-04T01:00:00+01:00").unwrap(), Timestamp::from_secs(1_451_865_600));
/// assert!(parse_time("99999999999999").is_err()); // year 5138
/// ```
pub fn parse_time(input: &str) -> Result<Timestamp, TimeError> {
    read_time(input, &Zone::utc()).map(|read| read.time)
}

/// [`parse_time`] reading a time without zone in `zone`, and saying whether it had none.
pub fn read_time(input: &str, zone: &Zone) -> Result<ReadTime, TimeError> {
    let text = input.trim();
    if text.is_empty() {
        return Err(error(input, "empty"));
    }
    let mut zoneless = false;
    let t = if text
        .bytes()
        .all(|b| b.is_ascii_digit() || b == b'.' || b == b'-' || b == b'+')
        && text.bytes().filter(|&b| b == b'-').count() <= 1
        && !text.get(1..).unwrap_or("").contains('-')
    {
        match calendar::parse_unix_seconds(text) {
            Some(t) => t,
            // Digits that do not fit 64-bit nanoseconds are far outside any useful range.
            None if text
                .trim_start_matches(['-', '+'])
                .split('.')
                .all(|p| p.bytes().all(|b| b.is_ascii_digit())) =>
            {
                return Err(error(
                    input,
                    "is outside the supported range 1970-01-01 .. 2200-01-01",
                ))
            }
            None => return Err(error(input, "not a number of seconds")),
        }
    } else {
        let (wall, zoned) = parse_iso(text).map_err(|reason| error(input, reason))?;
        zoneless = !zoned;
        if zoned {
            wall
        } else {
            zone.instant(input, wall)?
        }
    };
    Ok(ReadTime {
        time: check_range(input, t)?,
        zoneless,
    })
}

/// Parses the ISO 8601 forms froctomap accepts, and whether a zone was given; the error
/// says what is wrong.
fn parse_iso(text: &str) -> Result<(Timestamp, bool), String> {
    let (t, rest, zoned) = calendar::parse_iso8601_prefix_zoned(text)
        .ok_or("not Unix seconds or an ISO 8601 date/time")?;
    if !rest.is_empty() {
        return Err(format!("unexpected {rest:?} after the time"));
    }
    Ok((t, zoned))
}

/// Finds an instant in a file name: an ISO 8601 date-time (`frame_2016-01-04T08-30-00Z.bt`,
/// `20160104T083000Z`, `2016-01-04_08:30:00`) or a run of Unix time digits (10 digits =
/// seconds, 13 = milliseconds, 16 = microseconds, 19 = nanoseconds; seconds may carry a
/// fraction: `scan_1451865600.250.bt`). Returns `None` when the name holds no time. A time
/// before [`EARLIEST_IN_NAME`] is returned as read: [`collect_inputs`](crate::collect_inputs)
/// refuses it.
///
/// ```
/// use froctomap_convert::time_from_file_name;
/// use froctomap_core::Timestamp;
/// assert_eq!(time_from_file_name("map_1451865600.bt"), Some(Timestamp::from_secs(1_451_865_600)));
/// assert_eq!(time_from_file_name("map_1451865600123.bt"), Some(Timestamp(1_451_865_600_123_000_000)));
/// assert_eq!(time_from_file_name("frame_20160104T000000Z.bt"), Some(Timestamp::from_secs(1_451_865_600)));
/// assert_eq!(time_from_file_name("office-2016-01-04T00-00-00.ot"), Some(Timestamp::from_secs(1_451_865_600)));
/// assert_eq!(time_from_file_name("2024-03-01-10-15-00.bt"), Some(Timestamp::from_secs(1_709_288_100)));
/// assert_eq!(time_from_file_name("map_0042.bt"), None);
/// ```
pub fn time_from_file_name(name: &str) -> Option<Timestamp> {
    read_time_from_file_name(name, &Zone::utc()).map(|read| read.time)
}

/// [`time_from_file_name`] reading a date-time without zone in `zone`, and saying whether
/// it had none (Unix digits never lack one).
pub fn read_time_from_file_name(name: &str, zone: &Zone) -> Option<ReadTime> {
    let bytes = name.as_bytes();
    // ISO first: a date with a time part wins over a bare digit run.
    for start in 0..bytes.len() {
        if start > 0 && bytes[start - 1].is_ascii_digit() {
            continue;
        }
        let Some(candidate) = name.get(start..).map(rosbag_separator_as_t) else {
            continue;
        };
        if let Some((t, rest, zoned)) = calendar::parse_iso8601_prefix_zoned(&candidate) {
            // The rewrite keeps lengths, so `rest` maps back onto `name`.
            let consumed = candidate.len() - rest.len();
            // A bare 8-digit date could be anything; require a time part or separators.
            let text = &candidate[..consumed];
            if (text.contains('T')
                || text.contains('t')
                || text.contains('-')
                || text.contains('_'))
                && !rest.as_bytes().first().is_some_and(u8::is_ascii_digit)
            {
                let t = if zoned { Ok(t) } else { zone.instant(name, t) };
                if let Ok(t) = t.and_then(|t| check_range(name, t)) {
                    return Some(ReadTime {
                        time: t,
                        zoneless: !zoned,
                    });
                }
            }
        }
    }
    // Then Unix digits.
    let mut i = 0;
    while i < bytes.len() {
        if !bytes[i].is_ascii_digit() {
            i += 1;
            continue;
        }
        let start = i;
        while i < bytes.len() && bytes[i].is_ascii_digit() {
            i += 1;
        }
        let digits = &name[start..i];
        let mut frac = "";
        if digits.len() == 10 && bytes.get(i) == Some(&b'.') {
            let fstart = i + 1;
            let mut j = fstart;
            while j < bytes.len() && bytes[j].is_ascii_digit() {
                j += 1;
            }
            if j > fstart && j - fstart <= 9 {
                frac = &name[fstart..j];
                i = j;
            }
        }
        let value: i64 = match digits.parse() {
            Ok(v) => v,
            Err(_) => continue,
        };
        let nanos = match digits.len() {
            10 => {
                let f: i64 = if frac.is_empty() {
                    0
                } else {
                    format!("{frac:0<9}").parse().unwrap_or(0)
                };
                value
                    .checked_mul(1_000_000_000)
                    .and_then(|v| v.checked_add(f))
            }
            13 => value.checked_mul(1_000_000),
            16 => value.checked_mul(1_000),
            19 => Some(value),
            _ => None,
        };
        if let Some(t) = nanos.map(Timestamp) {
            if check_range(name, t).is_ok() {
                return Some(ReadTime {
                    time: t,
                    zoneless: false,
                });
            }
        }
    }
    None
}

/// Rosbag-style names separate date and time with `-` (`2024-03-01-10-15-00`), which ISO
/// 8601 reads as a date followed by junk: the separator is read as `T` so the time of day
/// is not silently dropped.
fn rosbag_separator_as_t(text: &str) -> std::borrow::Cow<'_, str> {
    let b = text.as_bytes();
    let date = b.len() > 11
        && b[..4].iter().all(u8::is_ascii_digit)
        && b[4] == b'-'
        && b[5..7].iter().all(u8::is_ascii_digit)
        && b[7] == b'-'
        && b[8..10].iter().all(u8::is_ascii_digit);
    if date && b[10] == b'-' && b[11].is_ascii_digit() {
        std::borrow::Cow::Owned(format!("{}T{}", &text[..10], &text[11..]))
    } else {
        std::borrow::Cow::Borrowed(text)
    }
}

/// Parses a duration: a number with unit `ns`, `ms`, `s`, `min`/`m`, `h`, `d`, `w`
/// (`10min`, `1.5h`, `600`) — a bare number is seconds. Returns nanoseconds.
///
/// ```
/// assert_eq!(froctomap_convert::parse_duration("10min"), Ok(600_000_000_000));
/// assert_eq!(froctomap_convert::parse_duration("1.5h"), Ok(5_400_000_000_000));
/// assert_eq!(
///     froctomap_convert::parse_duration("0s").unwrap_err().to_string(),
///     "cannot read \"0s\" as a duration: zero; give a positive duration such as 1s or 10min"
/// );
/// ```
pub fn parse_duration(input: &str) -> Result<i64, TimeError> {
    let text = input.trim();
    let split = text
        .find(|c: char| c.is_ascii_alphabetic())
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| duration_error(input, "not a duration like 10min, 1.5h or 600"))?;
    let unit_ns = match unit.trim() {
        "ns" => 1.0,
        "us" | "µs" => 1e3,
        "ms" => 1e6,
        "" | "s" | "sec" => 1e9,
        "m" | "min" => 60e9,
        "h" => 3600e9,
        "d" => 86_400e9,
        "w" => 604_800e9,
        other => {
            return Err(duration_error(
                input,
                format!("unknown unit {other:?} (use ns, ms, s, min, h, d or w)"),
            ))
        }
    };
    let ns = (value * unit_ns).round();
    if ns == 0.0 {
        return Err(duration_error(
            input,
            "zero; give a positive duration such as 1s or 10min",
        ));
    }
    if !(ns.is_finite() && ns > 0.0 && ns < 9.2e18) {
        return Err(duration_error(
            input,
            "must be positive and below 290 years",
        ));
    }
    Ok(ns as i64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::calendar::{iso8601, iso8601_basic};
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn iso_round_trips(secs in 0i64..7_258_118_399, nanos in 0i64..1_000_000_000) {
            let t = Timestamp(secs * 1_000_000_000 + nanos);
            prop_assert_eq!(parse_time(&iso8601(t)), Ok(t));
            prop_assert_eq!(time_from_file_name(&format!("frame_{}.bt", iso8601_basic(t))), Some(t));
        }

        #[test]
        fn unix_seconds_round_trip(secs in 0i64..7_258_118_399) {
            prop_assert_eq!(parse_time(&secs.to_string()), Ok(Timestamp::from_secs(secs)));
        }
    }

    #[test]
    fn invalid_times_say_why() {
        for bad in [
            "",
            "yesterday",
            "2016-13-01",
            "2016-02-30T00:00:00Z",
            "2016-01-04T25:00:00Z",
            "1e9",
            "2016-01-04T00:00:00Zjunk",
        ] {
            assert!(parse_time(bad).is_err(), "{bad}");
        }
        let err = parse_time("-5").unwrap_err().to_string();
        assert!(err.contains("outside the supported range"), "{err}");
        let err = parse_time("9999999999999").unwrap_err().to_string();
        assert!(err.contains("outside the supported range"), "{err}");
    }

    #[test]
    fn known_dates() {
        assert_eq!(
            iso8601(Timestamp::from_secs(1_451_865_600)),
            "2016-01-04T00:00:00Z"
        );
        assert_eq!(iso8601(Timestamp(1_500_000_000)), "1970-01-01T00:00:01.5Z");
        assert_eq!(
            parse_time("2000-02-29").unwrap(),
            Timestamp::from_secs(951_782_400)
        );
        assert_eq!(
            parse_time("2016-01-04 08:30:00").unwrap(),
            Timestamp::from_secs(1_451_896_200)
        );
        assert_eq!(
            parse_time("20160104T083000Z").unwrap(),
            Timestamp::from_secs(1_451_896_200)
        );
    }

    #[test]
    fn rosbag_names_keep_their_time_of_day() {
        let ten_fifteen = Some(Timestamp::from_secs(1_709_288_100));
        assert_eq!(time_from_file_name("2024-03-01-10-15-00.bt"), ten_fifteen);
        assert_eq!(
            time_from_file_name("run_2024-03-01-10-15-00.bt"),
            ten_fifteen
        );
        assert_eq!(time_from_file_name("2024-03-01_10-15-00.bt"), ten_fifteen);
        assert_eq!(time_from_file_name("2024-03-01_10:15:00.bt"), ten_fifteen);
        // A date alone still reads as midnight.
        assert_eq!(
            time_from_file_name("map-2024-03-01.bt"),
            Some(Timestamp::from_secs(1_709_251_200))
        );
        // Frame numbers read as 1970 times here; collect_inputs refuses them.
        let frame = time_from_file_name("map_0000000041.bt").unwrap();
        assert!(frame < EARLIEST_IN_NAME);
    }

    #[test]
    fn zones_apply_only_to_zoneless_times() {
        let plus_one = Zone::named("+01:00").unwrap();
        let midnight_utc = Timestamp::from_secs(1_451_865_600);
        let read = read_time("2016-01-04T01:00:00", &plus_one).unwrap();
        assert_eq!((read.time, read.zoneless), (midnight_utc, true));
        let read = read_time("2016-01-04T00:00:00Z", &plus_one).unwrap();
        assert_eq!((read.time, read.zoneless), (midnight_utc, false));
        let read = read_time("1451865600", &plus_one).unwrap();
        assert_eq!((read.time, read.zoneless), (midnight_utc, false));
        assert!(read_time("2016-01-04", &Zone::utc()).unwrap().zoneless);
        assert_eq!(Zone::named("utc").unwrap(), Zone::utc());
        assert_eq!(
            Zone::named("-0530").unwrap(),
            Zone::named("-05:30").unwrap()
        );
        assert!(Zone::named("+25:00").is_err());
        assert!(Zone::named("Mars/Olympus_Mons").is_err());
        assert!(Zone::named("local").is_ok());
        let read = read_time_from_file_name("2016-01-04-01-00-00.bt", &plus_one).unwrap();
        assert_eq!((read.time, read.zoneless), (midnight_utc, true));
    }

    #[test]
    fn durations() {
        assert_eq!(parse_duration("600"), Ok(600_000_000_000));
        assert_eq!(parse_duration("2d"), Ok(172_800_000_000_000));
        assert!(parse_duration("0s").is_err());
        assert!(parse_duration("5 fortnights").is_err());
    }
}
