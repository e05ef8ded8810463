//! The dynamic elements of a building: what each looks like and when it is there.
//!
//! Every element is a set of voxels that are *free* in the base map and become *occupied*
//! while the element is present (a closed door, a person standing at a spot, a box on the
//! floor, a machine at its station). When the element is absent the base map shows through,
//! so an element never removes a wall. Presence is a pure function of time (UTC) and the
//! series seed, so any frame can be computed on its own.

use crate::calendar::{day_number, is_weekday, second_of_day, unix_secs, weekday_of_day, DAY_SECS};
use crate::doors::DoorSeries;
use crate::geometry::{code_of, KeyBox};
use crate::rng::{below, chance, mix, splitmix, tag};
use froctomap_core::Timestamp;
use serde::{Deserialize, Serialize};
use std::fmt;

/// The kinds of change a series contains.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ElementKind {
    /// Door slabs: occupied when closed.
    Door,
    /// People: blobs at one of a few spots during working hours.
    Person,
    /// Chairs: moved between spots during working hours.
    Chair,
    /// Boxes left at a random spot for some days.
    Object,
    /// Machines: blocks present during their shift.
    Machine,
}

impl ElementKind {
    /// Every kind, in report order.
    pub const ALL: [ElementKind; 5] = [
        ElementKind::Door,
        ElementKind::Person,
        ElementKind::Chair,
        ElementKind::Object,
        ElementKind::Machine,
    ];

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            ElementKind::Door => "door",
            ElementKind::Person => "person",
            ElementKind::Chair => "chair",
            ElementKind::Object => "object",
            ElementKind::Machine => "machine",
        }
    }
}

impl fmt::Display for ElementKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A weekly time window: `weekday` (0 = Monday), seconds of day `[start, end)`, UTC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WeeklySlot {
    /// Day of the week, 0 = Monday.
    pub weekday: u8,
    /// Start, seconds after midnight UTC.
    pub start_secs: i64,
    /// End (exclusive), seconds after midnight UTC.
    pub end_secs: i64,
}

/// What opens and closes a door.
#[derive(Clone, Debug, PartialEq)]
pub enum DoorDriver {
    /// The real door recording, read `offset_weeks` weeks later than the frame time (so
    /// several doors share one recording without moving in lockstep).
    Real {
        /// Shift into the recording, in whole weeks.
        offset_weeks: u32,
    },
    /// An office: open from the occupant's arrival to departure on weekdays (random per day:
    /// arrival in the first working hour, departure in the last hour and a half), shut for
    /// 10-45 minutes at the start of an hour now and then (15 % of hours), open 10-14 h on
    /// one weekend day in ten; closed otherwise.
    Office,
    /// A meeting room: open during working hours on weekdays except during its weekly
    /// meetings (closed), closed at night and at weekends. Strictly periodic.
    MeetingRoom {
        /// The weekly meetings.
        meetings: Vec<WeeklySlot>,
    },
    /// A corridor (fire) door: open on weekdays from one hour before to one hour after
    /// working hours, closed otherwise.
    Corridor,
}

impl fmt::Display for DoorDriver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DoorDriver::Real { offset_weeks } => {
                write!(f, "real door series (shifted {offset_weeks} weeks)")
            }
            DoorDriver::Office => f.write_str("office schedule (daily)"),
            DoorDriver::MeetingRoom { meetings } => {
                write!(
                    f,
                    "meeting-room schedule ({} meetings a week)",
                    meetings.len()
                )
            }
            DoorDriver::Corridor => f.write_str("corridor schedule (weekdays)"),
        }
    }
}

/// A set of voxels, sorted by Morton code, with its bounding box.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Shape {
    pub(crate) codes: Vec<u64>,
    pub(crate) bounds: KeyBox,
}

impl Shape {
    pub(crate) fn from_keys(keys: impl IntoIterator<Item = [i32; 3]>, bounds: KeyBox) -> Self {
        let mut codes: Vec<u64> = keys.into_iter().filter_map(code_of).collect();
        codes.sort_unstable();
        codes.dedup();
        Self { codes, bounds }
    }

    pub(crate) fn solid(b: KeyBox) -> Self {
        Self::from_keys(b.keys(), b)
    }

    pub(crate) fn contains(&self, code: u64) -> bool {
        self.codes.binary_search(&code).is_ok()
    }
}

/// A standing person in a footprint box: an elliptic body, and a narrower head in the top
/// sixth.
pub(crate) fn person_shape(b: KeyBox) -> Shape {
    let size = [0, 1, 2].map(|a| b.max[a] - b.min[a]);
    let head_from = b.min[2] + size[2] - (size[2] / 6).max(1);
    let keys = b.keys().filter(|k| {
        let radius = if k[2] >= head_from { 0.55 } else { 1.0 };
        inside_ellipse(b, *k, radius)
    });
    Shape::from_keys(keys.collect::<Vec<_>>(), b)
}

/// `true` when the voxel centre lies in the ellipse inscribed in the box footprint, scaled.
fn inside_ellipse(b: KeyBox, k: [i32; 3], scale: f64) -> bool {
    let axis = |a: usize| {
        let half = f64::from(b.max[a] - b.min[a]) / 2.0;
        let centre = f64::from(b.min[a]) + half;
        let d = f64::from(k[a]) + 0.5 - centre;
        let r = (half * scale).max(0.5);
        (d / r) * (d / r)
    };
    axis(0) + axis(1) <= 1.0
}

/// An office chair in a footprint box: a cross of feet, a central post, the seat at
/// `seat` voxels above the floor and a backrest along the `back` side (0..4: -x, +x, -y, +y).
pub(crate) fn chair_shape(b: KeyBox, seat: i32, back: u8) -> Shape {
    let size = [0, 1, 2].map(|a| b.max[a] - b.min[a]);
    let centre = [b.min[0] + size[0] / 2, b.min[1] + size[1] / 2];
    let seat_z = b.min[2] + seat.clamp(1, size[2] - 1);
    let keys = b.keys().filter(|k| {
        let z = k[2];
        let feet = z == b.min[2] && (k[0] == centre[0] || k[1] == centre[1]);
        let post = z < seat_z && k[0] == centre[0] && k[1] == centre[1];
        let seat_plate = z == seat_z;
        let back_plate = z > seat_z
            && match back {
                0 => k[0] == b.min[0],
                1 => k[0] == b.max[0] - 1,
                2 => k[1] == b.min[1],
                _ => k[1] == b.max[1] - 1,
            };
        feet || post || seat_plate || back_plate
    });
    Shape::from_keys(keys.collect::<Vec<_>>(), b)
}

/// Working hours and the seed: what every schedule needs.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Clock {
    pub(crate) seed: u64,
    /// Seconds of day the working day starts and ends.
    pub(crate) work_start: i64,
    pub(crate) work_end: i64,
}

/// Seconds since midnight and the day number of an instant.
fn day_and_time(t: Timestamp) -> (i64, i64) {
    (day_number(t), second_of_day(t))
}

pub(crate) struct Door {
    pub(crate) shape: Shape,
    pub(crate) driver: DoorDriver,
    pub(crate) width_m: f64,
    pub(crate) across_corridor: bool,
}

impl Door {
    /// `true` when the door is closed (its slab occupied) at `t`.
    pub(crate) fn closed(
        &self,
        id: usize,
        t: Timestamp,
        clock: &Clock,
        series: Option<&DoorSeries>,
    ) -> bool {
        let (day, sod) = day_and_time(t);
        match (&self.driver, series) {
            (DoorDriver::Real { offset_weeks }, Some(series)) => {
                !series.is_open_shifted(t, i64::from(*offset_weeks) * 7 * 24 * 60)
            }
            // A real door without a series (cannot happen through Generator::new) acts as an
            // office door rather than failing a frame.
            (DoorDriver::Real { .. }, None) | (DoorDriver::Office, _) => {
                !office_open(id, day, sod, clock)
            }
            (DoorDriver::MeetingRoom { meetings }, _) => {
                let working = is_weekday(day) && sod >= clock.work_start && sod < clock.work_end;
                let weekday = weekday_of_day(day);
                let meeting = meetings
                    .iter()
                    .any(|m| m.weekday == weekday && sod >= m.start_secs && sod < m.end_secs);
                !working || meeting
            }
            (DoorDriver::Corridor, _) => {
                !(is_weekday(day) && sod >= clock.work_start - 3600 && sod < clock.work_end + 3600)
            }
        }
    }
}

/// Minutes of the working day's first hour in which an arrival falls, and of its last
/// hour and a half in which a departure falls (uniform draws).
pub(crate) const ARRIVAL_MINUTES: u64 = 60;
pub(crate) const DEPARTURE_MINUTES: u64 = 90;

/// The arrival and departure (seconds of day) of one occupant (`purpose` = person or office
/// door) on day `day`: one draw per day.
pub(crate) fn day_window(clock: &Clock, purpose: u64, id: u64, day: i64) -> (i64, i64) {
    let r = mix(clock.seed, purpose, id, day as u64);
    let arrive = clock.work_start + 60 * below(r, ARRIVAL_MINUTES) as i64;
    let leave = clock.work_end - 60 * below(splitmix(r), DEPARTURE_MINUTES) as i64;
    (arrive, leave)
}

/// Share of office hours with a call (door shut at the start of the hour), and the
/// shortest call and the number of call lengths, in minutes.
pub(crate) const CALL_CHANCE: f64 = 0.15;
pub(crate) const CALL_MIN_MINUTES: i64 = 10;
pub(crate) const CALL_LENGTHS: u64 = 35;
/// Share of weekend days with a visit (10:00-14:00) to an office.
pub(crate) const WEEKEND_VISIT_CHANCE: f64 = 0.1;

fn office_open(id: usize, day: i64, sod: i64, clock: &Clock) -> bool {
    let id = id as u64;
    if !is_weekday(day) {
        // Someone drops by on one weekend day in ten, 10:00-14:00.
        let r = mix(clock.seed, tag::WEEKEND_VISIT, id, day as u64);
        return chance(r, WEEKEND_VISIT_CHANCE) && (10 * 3600..14 * 3600).contains(&sod);
    }
    let (arrive, leave) = day_window(clock, tag::OFFICE_DOOR, id, day);
    if sod < arrive || sod >= leave {
        return false;
    }
    // Now and then the door is shut for a call at the start of an hour.
    let hour = sod / 3600;
    let h = mix(
        clock.seed,
        tag::OFFICE_DOOR_HOUR,
        id,
        (day * 24 + hour) as u64,
    );
    let shut_minutes = CALL_MIN_MINUTES + below(splitmix(h), CALL_LENGTHS) as i64;
    !(chance(h, CALL_CHANCE) && sod % 3600 < shut_minutes * 60)
}

/// Time slots of people, in seconds.
pub(crate) const PERSON_SLOT: i64 = 15 * 60;

/// Percent chance that a person is away in the slot holding second of day `sod` (mostly
/// away at lunch, 12-13 h); when not away, at the desk in two thirds of the slots.
pub(crate) fn away_percent(sod: i64) -> i64 {
    if (12 * 3600..13 * 3600).contains(&sod) {
        60
    } else {
        15
    }
}

pub(crate) struct Person {
    /// Spot 0 is the desk.
    pub(crate) spots: Vec<Shape>,
}

impl Person {
    /// The spot the person occupies at `t`, if present.
    pub(crate) fn spot(&self, id: usize, t: Timestamp, clock: &Clock) -> Option<usize> {
        let (day, sod) = day_and_time(t);
        if !is_weekday(day) || self.spots.is_empty() {
            return None;
        }
        let id = id as u64;
        let (arrive, leave) = day_window(clock, tag::PERSON_DAY, id, day);
        if sod < arrive || sod >= leave {
            return None;
        }
        let slot = sod / PERSON_SLOT;
        let s = mix(clock.seed, tag::PERSON_SLOT, id, (day * 96 + slot) as u64);
        let away = away_percent(sod);
        let roll = below(s, 100) as i64;
        if roll < away {
            None
        } else if roll < away + (100 - away) * 2 / 3 || self.spots.len() == 1 {
            Some(0)
        } else {
            Some(1 + below(splitmix(s), self.spots.len() as u64 - 1) as usize)
        }
    }
}

pub(crate) struct Chair {
    /// Spot 0 is where the chair stands outside working hours.
    pub(crate) spots: Vec<Shape>,
}

impl Chair {
    /// The spot of the chair at `t` (chairs are always somewhere).
    pub(crate) fn spot(&self, id: usize, t: Timestamp, clock: &Clock) -> usize {
        let (day, sod) = day_and_time(t);
        if !is_weekday(day) || sod < clock.work_start || sod >= clock.work_end {
            return 0;
        }
        let hour = sod / 3600;
        let r = mix(
            clock.seed,
            tag::CHAIR_HOUR,
            id as u64,
            (day * 24 + hour) as u64,
        );
        below(r, self.spots.len().max(1) as u64) as usize
    }
}

/// Probability that an object slot has a stay in a period.
pub(crate) const OBJECT_CHANCE: f64 = 0.8;

/// The object slots' shared parameters.
pub(crate) struct ObjectModel {
    /// Free floor boxes of the largest object size; each appearance picks one.
    pub(crate) pool: Vec<KeyBox>,
    /// Per slot, the day its first period starts (mod `period_days`).
    pub(crate) phases: Vec<i64>,
    pub(crate) period_days: i64,
    pub(crate) min_secs: i64,
    pub(crate) max_secs: i64,
    /// Smallest object edge (x, y, z) in voxels; sizes range up to the pool box size.
    pub(crate) min_size: [i32; 3],
}

/// One stay of an object: `[start, end)` in Unix seconds at a box.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Appearance {
    pub(crate) start: i64,
    pub(crate) end: i64,
    pub(crate) bounds: KeyBox,
}

impl ObjectModel {
    /// The stay of slot `slot` in period `period`, if the object comes in that period.
    pub(crate) fn appearance(&self, slot: usize, period: i64, seed: u64) -> Option<Appearance> {
        if self.pool.is_empty() {
            return None;
        }
        let phase = *self.phases.get(slot)?;
        let r = mix(seed, tag::OBJECT_PERIOD, slot as u64, period as u64);
        if !chance(r, OBJECT_CHANCE) {
            return None;
        }
        let r1 = splitmix(r);
        let duration =
            (self.min_secs + below(r1, (self.max_secs - self.min_secs) as u64 + 1) as i64) / 60
                * 60;
        let period_secs = self.period_days * DAY_SECS;
        let r2 = splitmix(r1);
        let offset = below(r2, (period_secs - duration).max(1) as u64) as i64 / 60 * 60;
        let r3 = splitmix(r2);
        let spot = self.pool[below(r3, self.pool.len() as u64) as usize];
        let mut r4 = splitmix(r3);
        let size = [0, 1, 2].map(|a| {
            let max = spot.max[a] - spot.min[a];
            let lo = self.min_size[a].min(max);
            r4 = splitmix(r4);
            lo + below(r4, (max - lo + 1) as u64) as i32
        });
        let start = (phase + period * self.period_days) * DAY_SECS + offset;
        Some(Appearance {
            start,
            end: start + duration,
            bounds: KeyBox::new(spot.min, size),
        })
    }

    /// The period of slot `slot` containing `t`.
    pub(crate) fn period_at(&self, slot: usize, t: Timestamp) -> i64 {
        let phase = self.phases.get(slot).copied().unwrap_or(0);
        (day_number(t) - phase).div_euclid(self.period_days)
    }

    /// The box slot `slot` occupies at `t`, if any.
    pub(crate) fn present(&self, slot: usize, t: Timestamp, seed: u64) -> Option<KeyBox> {
        let secs = unix_secs(t);
        let a = self.appearance(slot, self.period_at(slot, t), seed)?;
        (a.start <= secs && secs < a.end).then_some(a.bounds)
    }
}

pub(crate) struct Machine {
    pub(crate) shape: Shape,
    /// Seconds of day; `end <= start` runs past midnight.
    pub(crate) shift: (i64, i64),
}

impl Machine {
    pub(crate) fn present(&self, t: Timestamp) -> bool {
        let (day, sod) = day_and_time(t);
        shift_active(self.shift, day, sod)
    }
}

/// `true` when a weekday shift `(start, end)` covers second `sod` of day `day`.
pub(crate) fn shift_active((start, end): (i64, i64), day: i64, sod: i64) -> bool {
    if start < end {
        is_weekday(day) && sod >= start && sod < end
    } else {
        (is_weekday(day) && sod >= start) || (is_weekday(day - 1) && sod < end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_are_plausible() {
        let b = KeyBox::new([100, 100, 100], [5, 4, 21]);
        let person = person_shape(b);
        // Body wider than the head, all inside the box.
        assert!(person.codes.len() > 200 && person.codes.len() < 5 * 4 * 21);
        let chair = chair_shape(KeyBox::new([0, 0, 0], [6, 6, 11]), 5, 1);
        assert!(chair.codes.len() > 36 + 5);
        let block = Shape::solid(KeyBox::new([3, 3, 3], [2, 2, 2]));
        assert_eq!(block.codes.len(), 8);
        assert!(block.contains(code_of([4, 4, 4]).unwrap()));
    }

    #[test]
    fn night_shift_crosses_midnight() {
        let monday = 16_804; // 2016-01-04
        let night = (22 * 3600, 6 * 3600);
        assert!(shift_active(night, monday, 23 * 3600));
        assert!(shift_active(night, monday + 1, 3600)); // Tuesday 01:00, Monday's shift
        assert!(!shift_active(night, monday, 3600)); // Monday 01:00: Sunday had no shift
        assert!(!shift_active(night, monday + 5, 23 * 3600)); // Saturday
        assert!(shift_active(night, monday + 5, 3600)); // Saturday 01:00, Friday's shift
    }
}
