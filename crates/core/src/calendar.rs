//! Calendar arithmetic and the textual forms of instants: ISO 8601 (extended and basic) and
//! Unix seconds. Proleptic Gregorian calendar, UTC, no leap seconds (as Unix time).

use crate::time::Timestamp;

const NANOS: i64 = Timestamp::NANOS_PER_SEC;

/// Days from 1970-01-01 to a date (Howard Hinnant's `days_from_civil`).
///
/// ```
/// assert_eq!(froctomap_core::calendar::days_from_civil(2016, 1, 4), 16_804);
/// ```
pub fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let m = i64::from(month);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(day) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The date `(year, month, day)` of a day count since 1970-01-01.
///
/// ```
/// assert_eq!(froctomap_core::calendar::civil_from_days(-1), (1969, 12, 31));
/// ```
pub fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

/// Days in a month of a year.
pub fn days_in_month(year: i64, month: u32) -> u32 {
    match month {
        2 if (year % 4 == 0 && year % 100 != 0) || year % 400 == 0 => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// Date, time of day and nanoseconds of an instant.
fn parts(t: Timestamp) -> ((i64, u32, u32), (i64, i64, i64), i64) {
    let secs = t.0.div_euclid(NANOS);
    let sod = secs.rem_euclid(86_400);
    (
        civil_from_days(secs.div_euclid(86_400)),
        (sod / 3600, sod / 60 % 60, sod % 60),
        t.0.rem_euclid(NANOS),
    )
}

/// A fraction of a second without trailing zeros, with its dot (`""` for zero).
fn fraction(nanos: i64) -> String {
    if nanos == 0 {
        return String::new();
    }
    format!(".{}", format!("{nanos:09}").trim_end_matches('0'))
}

/// ISO 8601 extended form, UTC: `2016-01-04T08:30:00Z`, with a fraction of a second only
/// when there is one.
///
/// ```
/// use froctomap_core::{calendar, Timestamp};
/// assert_eq!(calendar::iso8601(Timestamp::from_secs(1_451_896_200)), "2016-01-04T08:30:00Z");
/// assert_eq!(calendar::iso8601(Timestamp(1_500_000_000)), "1970-01-01T00:00:01.5Z");
/// ```
pub fn iso8601(t: Timestamp) -> String {
    let ((y, mo, d), (h, mi, s), nanos) = parts(t);
    format!(
        "{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}{}Z",
        fraction(nanos)
    )
}

/// ISO 8601 basic form for file names: `20160104T083000Z`.
pub fn iso8601_basic(t: Timestamp) -> String {
    let ((y, mo, d), (h, mi, s), nanos) = parts(t);
    format!(
        "{y:04}{mo:02}{d:02}T{h:02}{mi:02}{s:02}{}Z",
        fraction(nanos)
    )
}

/// Unix seconds with up to nine decimals, no trailing zeros: `1451865600.25`.
///
/// ```
/// use froctomap_core::{calendar, Timestamp};
/// let t = Timestamp(-1_500_000_000);
/// assert_eq!(calendar::unix_seconds(t), "-1.5");
/// assert_eq!(calendar::parse_unix_seconds("-1.5"), Some(t));
/// ```
pub fn unix_seconds(t: Timestamp) -> String {
    let sign = if t.0 < 0 { "-" } else { "" };
    let magnitude = i128::from(t.0).unsigned_abs();
    let nanos = (magnitude % NANOS as u128) as i64;
    format!("{sign}{}{}", magnitude / NANOS as u128, fraction(nanos))
}

/// Parses Unix seconds: an optional sign, digits, optionally `.` and at most nine digits.
/// `None` for anything else or beyond the representable range.
pub fn parse_unix_seconds(text: &str) -> Option<Timestamp> {
    let (negative, body) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text.strip_prefix('+').unwrap_or(text)),
    };
    let (int, frac) = body.split_once('.').unwrap_or((body, ""));
    if int.is_empty()
        || !int.bytes().all(|b| b.is_ascii_digit())
        || !frac.bytes().all(|b| b.is_ascii_digit())
        || frac.len() > 9
        || (body.contains('.') && frac.is_empty())
    {
        return None;
    }
    let secs: i64 = int.parse().ok()?;
    let nanos: i64 = if frac.is_empty() {
        0
    } else {
        format!("{frac:0<9}").parse().ok()?
    };
    let total = secs.checked_mul(NANOS)?.checked_add(nanos)?;
    Some(Timestamp(if negative { -total } else { total }))
}

/// Parses a whole ISO 8601 instant (see [`parse_iso8601_prefix`]).
///
/// ```
/// use froctomap_core::{calendar, Timestamp};
/// assert_eq!(calendar::parse_iso8601("2016-01-04"), Some(Timestamp::from_secs(1_451_865_600)));
/// assert_eq!(calendar::parse_iso8601("2016-01-04 09:30:00+01:00"), Some(Timestamp::from_secs(1_451_896_200)));
/// assert_eq!(calendar::parse_iso8601("2016-02-30"), None);
/// ```
pub fn parse_iso8601(text: &str) -> Option<Timestamp> {
    match parse_iso8601_prefix(text.trim())? {
        (t, "") => Some(t),
        _ => None,
    }
}

struct Digits<'a> {
    s: &'a [u8],
    pos: usize,
}

impl Digits<'_> {
    fn number(&mut self, len: usize) -> Option<u32> {
        let digits = self.s.get(self.pos..self.pos + len)?;
        if !digits.iter().all(u8::is_ascii_digit) {
            return None;
        }
        self.pos += len;
        digits
            .iter()
            .try_fold(0u32, |acc, d| Some(acc * 10 + u32::from(d - b'0')))
    }

    fn eat(&mut self, options: &[u8]) -> Option<u8> {
        let c = *self.s.get(self.pos)?;
        if options.contains(&c) {
            self.pos += 1;
            Some(c)
        } else {
            None
        }
    }
}

/// An ISO 8601 instant at the start of `text`, and what follows it: extended
/// (`2016-01-04T08:30:00.5Z`) or basic (`20160104T083000Z`); `T`, `t`, `_` or a space
/// before the time; a `Z`, a `±HH:MM` offset or nothing (UTC); a date alone is midnight.
pub fn parse_iso8601_prefix(text: &str) -> Option<(Timestamp, &str)> {
    parse_iso8601_prefix_zoned(text).map(|(t, rest, _)| (t, rest))
}

/// [`parse_iso8601_prefix`], also saying whether the text named its zone (`Z` or an offset):
/// `false` when the wall-clock time was read as UTC for want of one.
pub fn parse_iso8601_prefix_zoned(text: &str) -> Option<(Timestamp, &str, bool)> {
    let mut d = Digits {
        s: text.as_bytes(),
        pos: 0,
    };
    let year = d.number(4)?;
    let extended = d.eat(b"-").is_some();
    let month = d.number(2)?;
    if extended {
        d.eat(b"-")?;
    }
    let day = d.number(2)?;
    if !(1..=12).contains(&month) || day == 0 || day > days_in_month(i64::from(year), month) {
        return None;
    }
    let mut secs_of_day = 0i64;
    let mut nanos = 0i64;
    let mut offset = 0i64;
    let mut zoned = false;
    let before_time = d.pos;
    if d.eat(b"T t_").is_some() {
        let time_start = d.pos;
        let parsed = (|| {
            let h = d.number(2)?;
            if extended {
                d.eat(b":-")?;
            }
            let m = d.number(2)?;
            let mut s = 0;
            let colon = if extended {
                d.eat(b":-").is_some()
            } else {
                true
            };
            if colon {
                if let Some(v) = d.number(2) {
                    s = v;
                } else if extended {
                    return None;
                }
            }
            if h > 23 || m > 59 || s > 60 {
                return None;
            }
            Some((h, m, s))
        })();
        match parsed {
            Some((h, m, s)) => {
                secs_of_day = i64::from(h) * 3600 + i64::from(m) * 60 + i64::from(s);
                let fraction_follows = d.s.get(d.pos + 1).is_some_and(u8::is_ascii_digit);
                if fraction_follows && d.eat(b".,").is_some() {
                    let start = d.pos;
                    while d.s.get(d.pos).is_some_and(u8::is_ascii_digit) {
                        d.pos += 1;
                    }
                    let frac = std::str::from_utf8(&d.s[start..d.pos]).ok()?;
                    if frac.is_empty() || frac.len() > 9 {
                        return None;
                    }
                    nanos = format!("{frac:0<9}").parse().ok()?;
                }
                if d.eat(b"Zz").is_some() {
                    zoned = true;
                } else if let Some(sign) = d.eat(b"+-") {
                    let oh = i64::from(d.number(2)?);
                    d.eat(b":");
                    let om = i64::from(d.number(2)?);
                    offset = (oh * 3600 + om * 60) * if sign == b'-' { -1 } else { 1 };
                    zoned = true;
                }
            }
            None => {
                d.pos = if time_start > before_time {
                    before_time
                } else {
                    time_start
                }
            }
        }
    }
    let days = days_from_civil(i64::from(year), month, day);
    let secs = days * 86_400 + secs_of_day - offset;
    let t = Timestamp(secs.checked_mul(1_000_000_000)?.checked_add(nanos)?);
    Some((t, text.get(d.pos..)?, zoned))
}
