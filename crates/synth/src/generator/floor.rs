//! The entropy floor of a generated series: how many bits the generator's random draws put
//! into what a sensor observed, i.e. the shortest any lossless coder could store the series
//! in on average if it knew everything about the generator except the outcomes of its draws
//! (the base map, the spec, the placement and the real door recording are side information).
//!
//! Each process is counted where its outcome is visible in the observed frames; what a
//! partial view hides carries nothing. The terms, in bits:
//!
//! * **noise** (exact): per frame, the self-information of the realised flips among the
//!   surface candidates the frame observes, `k·log2(1/p) + (N_obs − k)·log2(1/(1−p))`; its
//!   expectation `N_obs·H_b(p)` is reported beside it.
//! * **partial views** (exact for the draw; the box position counts as `log2` of its possible
//!   positions, which slightly overstates it when positions remove the same known voxels):
//!   per frame `−log2(1−q)` or `−log2 q + log2(positions)`.
//! * **frame timing** (exact): missed frames `−log2` of their probability per grid frame, and
//!   jitter `log2(2·jitter + 1)` per frame (both 0 in the benchmark).
//! * **schedules** (upper bounds of each draw's visible part): a person's or office door's
//!   daily arrival and departure, quantised to the first frame at or after them; a person's
//!   15-minute spot choice, where a frame of the slot falls in the realised day; a chair's
//!   hourly spot; an office door's hourly call (frames it shuts); a weekend visit; an
//!   object's stay (whether, where, how big, start and length in frames). Each draw is
//!   counted on its own, so a draw whose effect another one masks (an arrival hidden by a
//!   person away) is counted in full, as is one inside a partial view.
//! * **real doors**: the recording is data, not a draw; its sampled states are counted at
//!   their empirical first-order Markov entropy (a stand-in: a coder knowing the door's
//!   weekly habits would need less).
//!
//! Meeting-room and corridor doors and machines follow fixed schedules (0 bits); one-off
//! placement choices (tens of bytes for a whole series) are not counted.

use super::Generator;
use crate::calendar::{day_number, is_weekday, unix_secs, DAY_SECS};
use crate::elements::{
    away_percent, day_window, DoorDriver, ARRIVAL_MINUTES, CALL_CHANCE, CALL_LENGTHS,
    CALL_MIN_MINUTES, DEPARTURE_MINUTES, OBJECT_CHANCE, PERSON_SLOT, WEEKEND_VISIT_CHANCE,
};
use crate::geometry::coords;
use crate::rng::tag;
use froctomap_core::{MortonCode, Timestamp};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;

/// The entropy floor of a span of frames, by process, in bits (see the module docs of
/// [`Generator::entropy_floor`] for what each term counts).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct EntropyFloor {
    /// Frames observed (grid frames of the span not missed).
    pub frames: u64,
    /// Sensor noise: self-information of the realised flips in observed voxels.
    pub noise_bits: f64,
    /// Its expectation, `Σ N_obs·H_b(p)`.
    pub noise_expected_bits: f64,
    /// Flips in observed voxels, over all frames.
    pub noise_flips: u64,
    /// Surface candidates observed, summed over frames (`Σ N_obs`).
    pub noise_observed_candidates: u64,
    /// Partial views: whether a frame is one, and where its box is.
    pub partial_bits: f64,
    /// Missed frames and time jitter.
    pub timing_bits: f64,
    /// People: daily arrival/departure and 15-minute spots.
    pub people_bits: f64,
    /// Chairs: hourly spots.
    pub chair_bits: f64,
    /// Office doors: daily arrival/departure, calls, weekend visits.
    pub office_door_bits: f64,
    /// Objects: each period's stay.
    pub object_bits: f64,
    /// Doors on the real recording (empirical first-order Markov entropy of their sampled
    /// states).
    pub real_door_bits: f64,
}

impl EntropyFloor {
    /// Every term, in bits.
    pub fn total_bits(&self) -> f64 {
        self.noise_bits
            + self.partial_bits
            + self.timing_bits
            + self.schedule_bits()
            + self.real_door_bits
    }

    /// The schedules' drawn terms (people, chairs, office doors, objects).
    pub fn schedule_bits(&self) -> f64 {
        self.people_bits + self.chair_bits + self.office_door_bits + self.object_bits
    }

    /// [`total_bits`](Self::total_bits) in bytes.
    pub fn bytes(&self) -> f64 {
        self.total_bits() / 8.0
    }

    /// The terms as `(name, bits)`, in report order.
    pub fn terms(&self) -> Vec<(&'static str, f64)> {
        vec![
            ("sensor noise (exact)", self.noise_bits),
            ("partial views", self.partial_bits),
            ("missed frames and jitter", self.timing_bits),
            ("people (bound)", self.people_bits),
            ("chairs (bound)", self.chair_bits),
            ("office doors (bound)", self.office_door_bits),
            ("objects (bound)", self.object_bits),
            ("real doors (Markov-1)", self.real_door_bits),
        ]
    }
}

impl fmt::Display for EntropyFloor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "entropy floor over {} frames: {:.0} bytes",
            self.frames,
            self.bytes()
        )?;
        for (name, bits) in self.terms() {
            writeln!(f, "  {name:<26} {:>14.0} bytes", bits / 8.0)?;
        }
        write!(
            f,
            "  ({} flips among {} observed candidate voxels; expected noise {:.0} bytes)",
            self.noise_flips,
            self.noise_observed_candidates,
            self.noise_expected_bits / 8.0
        )
    }
}

/// `−log2 p`, 0 for impossible outcomes (never drawn).
fn surprise(p: f64) -> f64 {
    if p > 0.0 {
        -p.log2()
    } else {
        0.0
    }
}

/// Binary entropy in bits.
fn binary_entropy(p: f64) -> f64 {
    p * surprise(p) + (1.0 - p) * surprise(1.0 - p)
}

/// Entropy in bits of a distribution given by counts.
fn entropy_of_counts<'a>(counts: impl IntoIterator<Item = &'a u64>) -> f64 {
    let counts: Vec<u64> = counts.into_iter().copied().filter(|&c| c > 0).collect();
    let total: u64 = counts.iter().sum();
    if total == 0 {
        return 0.0;
    }
    counts
        .iter()
        .map(|&c| {
            let p = c as f64 / total as f64;
            p * surprise(p)
        })
        .sum()
}

/// The observed frame times (Unix seconds, sorted) and what quantises them.
struct Samples {
    secs: Vec<i64>,
}

impl Samples {
    /// Index of the first frame at or after `t`: two instants with the same index are
    /// indistinguishable in the frames.
    fn first_at_or_after(&self, t: i64) -> usize {
        self.secs.partition_point(|&s| s < t)
    }

    /// Frames in `[from, to)`.
    fn count(&self, from: i64, to: i64) -> usize {
        self.first_at_or_after(to)
            .saturating_sub(self.first_at_or_after(from))
    }

    /// Entropy of the frame index at or after `base + 60·m`, `m` uniform in `0..minutes`
    /// (`sign` −1 counts back from `base`).
    fn minute_draw_entropy(&self, base: i64, sign: i64, minutes: u64) -> f64 {
        let mut counts: BTreeMap<usize, u64> = BTreeMap::new();
        for m in 0..minutes as i64 {
            *counts
                .entry(self.first_at_or_after(base + sign * 60 * m))
                .or_default() += 1;
        }
        entropy_of_counts(counts.values())
    }
}

impl Generator {
    /// The entropy floor of grid frames `frames` (clamped to the series), as observed: see
    /// [`EntropyFloor`] and the crate docs. Takes about as long as sampling every frame's
    /// noise (no map is composed).
    pub fn entropy_floor(&self, frames: Range<u64>) -> EntropyFloor {
        let range = frames.start.min(self.spec.count)..frames.end.min(self.spec.count);
        let observed: Vec<u64> = range.clone().filter(|&i| !self.is_missed(i)).collect();
        let mut floor = self.per_frame_terms(&range, &observed);
        let samples = Samples {
            secs: observed
                .iter()
                .map(|&i| unix_secs(self.time_unchecked(i)))
                .collect(),
        };
        floor.frames = observed.len() as u64;
        if let (Some(&first), Some(&last)) = (samples.secs.first(), samples.secs.last()) {
            let days =
                day_number(Timestamp::from_secs(first))..=day_number(Timestamp::from_secs(last));
            self.schedule_terms(&samples, days, &mut floor);
            floor.real_door_bits = self.real_door_bits(&observed);
        }
        floor
    }

    /// Noise, partial views and timing, frame by frame (in parallel).
    fn per_frame_terms(&self, range: &Range<u64>, observed: &[u64]) -> EntropyFloor {
        let p = self.spec.surface_noise;
        let q = self.spec.partial_probability;
        let (flip_bits, keep_bits) = (surprise(p), surprise(1.0 - p));
        let mut floor = observed
            .par_iter()
            .map(|&index| {
                let mut f = EntropyFloor::default();
                let region = self.unobserved_region(index);
                if q > 0.0 {
                    f.partial_bits = match &region {
                        None => surprise(1.0 - q),
                        Some(_) => {
                            surprise(q)
                                + self
                                    .partial_positions()
                                    .iter()
                                    .map(|&n| n.log2())
                                    .sum::<f64>()
                        }
                    };
                }
                if p > 0.0 && !self.noise.is_empty() {
                    let visible = |code: u64| {
                        region
                            .as_ref()
                            .is_none_or(|b| !b.contains(coords(MortonCode(code).key())))
                    };
                    let candidates = match &region {
                        None => self.noise.len() as u64,
                        Some(_) => self.noise.iter().filter(|&&(c, _)| visible(c)).count() as u64,
                    };
                    let flips = self
                        .noise_flips(index)
                        .iter()
                        .filter(|&&(c, _)| visible(c))
                        .count() as u64;
                    f.noise_flips = flips;
                    f.noise_observed_candidates = candidates;
                    f.noise_bits =
                        flips as f64 * flip_bits + (candidates - flips) as f64 * keep_bits;
                    f.noise_expected_bits = candidates as f64 * binary_entropy(p);
                }
                if self.timing.jitter > 0 {
                    f.timing_bits = ((2 * self.timing.jitter + 1) as f64).log2();
                }
                f
            })
            .reduce(EntropyFloor::default, |mut a, b| {
                a.noise_bits += b.noise_bits;
                a.noise_expected_bits += b.noise_expected_bits;
                a.noise_flips += b.noise_flips;
                a.noise_observed_candidates += b.noise_observed_candidates;
                a.partial_bits += b.partial_bits;
                a.timing_bits += b.timing_bits;
                a
            });
        let missed = self.spec.missed_frames;
        if missed > 0.0 {
            let dropped = range.end - range.start - observed.len() as u64;
            floor.timing_bits +=
                dropped as f64 * surprise(missed) + observed.len() as f64 * surprise(1.0 - missed);
        }
        floor
    }

    /// Possible positions of a partial view's box along x and y (as
    /// [`unobserved_region`](Self::unobserved_region) draws them).
    fn partial_positions(&self) -> [f64; 2] {
        let b = self.bounds;
        [0, 1].map(|a| {
            let extent = b.max[a] - b.min[a];
            let size =
                ((f64::from(extent) * self.spec.partial_extent).round() as i32).clamp(1, extent);
            f64::from(extent - size + 1)
        })
    }

    /// People, chairs, office doors and objects over the days `days`.
    fn schedule_terms(
        &self,
        samples: &Samples,
        days: std::ops::RangeInclusive<i64>,
        floor: &mut EntropyFloor,
    ) {
        let clock = &self.clock;
        let (start, end) = (clock.work_start, clock.work_end);
        // A day's arrival/departure draw, as the frames see it.
        let window_bits = |day0: i64| {
            samples.minute_draw_entropy(day0 + start, 1, ARRIVAL_MINUTES)
                + samples.minute_draw_entropy(day0 + end, -1, DEPARTURE_MINUTES)
        };
        for day in days {
            let day0 = day * DAY_SECS;
            if !is_weekday(day) {
                let visit = samples.count(day0 + 10 * 3600, day0 + 14 * 3600) > 0;
                let offices = self.office_doors().count();
                if visit {
                    floor.office_door_bits += offices as f64 * binary_entropy(WEEKEND_VISIT_CHANCE);
                }
                continue;
            }
            if samples.count(day0 + start, day0 + end) == 0 {
                continue;
            }
            for (id, person) in self.people.iter().enumerate() {
                if person.spots.is_empty() {
                    continue;
                }
                floor.people_bits += window_bits(day0);
                let (arrive, leave) = day_window(clock, tag::PERSON_DAY, id as u64, day);
                let mut slot = arrive / PERSON_SLOT;
                while slot * PERSON_SLOT < leave {
                    let from = (slot * PERSON_SLOT).max(arrive);
                    let to = ((slot + 1) * PERSON_SLOT).min(leave);
                    if samples.count(day0 + from, day0 + to) > 0 {
                        floor.people_bits += slot_entropy(away_percent(from), person.spots.len());
                    }
                    slot += 1;
                }
            }
            for chair in &self.chairs {
                if chair.spots.len() < 2 {
                    continue;
                }
                let mut hour = start / 3600;
                while hour * 3600 < end {
                    let from = (hour * 3600).max(start);
                    let to = ((hour + 1) * 3600).min(end);
                    if samples.count(day0 + from, day0 + to) > 0 {
                        floor.chair_bits += (chair.spots.len() as f64).log2();
                    }
                    hour += 1;
                }
            }
            for id in self.office_doors() {
                floor.office_door_bits += window_bits(day0);
                let (arrive, leave) = day_window(clock, tag::OFFICE_DOOR, id as u64, day);
                let mut hour = arrive / 3600;
                while hour * 3600 < leave {
                    floor.office_door_bits += call_entropy(samples, day0, hour, arrive, leave);
                    hour += 1;
                }
            }
        }
        floor.object_bits = self.object_bits(samples);
    }

    /// Indices of the doors on office schedules.
    fn office_doors(&self) -> impl Iterator<Item = usize> + '_ {
        let real_without_series = self.door_series.is_none();
        self.doors.iter().enumerate().filter_map(move |(id, d)| {
            matches!(
                (&d.driver, real_without_series),
                (DoorDriver::Office, _) | (DoorDriver::Real { .. }, true)
            )
            .then_some(id)
        })
    }

    /// Every object slot's stays within the frames: whether each period has one, and where,
    /// how big, when and how long it is, in frames.
    fn object_bits(&self, samples: &Samples) -> f64 {
        let model = &self.objects;
        let (Some(&first), Some(&last)) = (samples.secs.first(), samples.secs.last()) else {
            return 0.0;
        };
        if model.pool.is_empty() {
            return 0.0;
        }
        let step = samples
            .secs
            .windows(2)
            .map(|w| w[1] - w[0])
            .min()
            .unwrap_or(DAY_SECS)
            .max(1) as f64;
        let period_secs = model.period_days * DAY_SECS;
        let mean_duration = (model.min_secs + model.max_secs) as f64 / 2.0;
        // Start and length, quantised to frames: uniform over the frames they can fall on.
        let timing = ((period_secs as f64 - mean_duration) / step)
            .max(1.0)
            .log2()
            + ((model.max_secs - model.min_secs) as f64 / step + 1.0).log2();
        let mut bits = 0.0;
        for slot in 0..model.phases.len() {
            let from = model.period_at(slot, Timestamp::from_secs(first));
            let to = model.period_at(slot, Timestamp::from_secs(last));
            for period in from..=to {
                bits += binary_entropy(OBJECT_CHANCE);
                let Some(stay) = model.appearance(slot, period, self.spec.seed) else {
                    continue;
                };
                if samples.count(stay.start, stay.end) == 0 {
                    continue;
                }
                // Every pool box has the largest object size.
                let spot = model.pool.first().copied().unwrap_or(stay.bounds);
                let sizes: f64 = (0..3)
                    .map(|a| {
                        let max = spot.max[a] - spot.min[a];
                        f64::from(max - model.min_size[a].min(max) + 1).log2()
                    })
                    .sum();
                bits += (model.pool.len() as f64).log2() + sizes + timing;
            }
        }
        bits
    }

    /// Empirical first-order Markov entropy of each real-recording door's sampled states.
    fn real_door_bits(&self, observed: &[u64]) -> f64 {
        let Some(series) = self.door_series.as_ref() else {
            return 0.0;
        };
        let mut bits = 0.0;
        for (id, door) in self.doors.iter().enumerate() {
            if !matches!(door.driver, DoorDriver::Real { .. }) {
                continue;
            }
            let mut transitions = [[0u64; 2]; 2];
            let mut previous: Option<bool> = None;
            for &i in observed {
                let closed = door.closed(id, self.time_unchecked(i), &self.clock, Some(series));
                if let Some(p) = previous {
                    transitions[usize::from(p)][usize::from(closed)] += 1;
                }
                previous = Some(closed);
            }
            for row in &transitions {
                bits += (row[0] + row[1]) as f64 * entropy_of_counts(row);
            }
            // The first state.
            bits += 1.0;
        }
        bits
    }
}

/// Entropy of one 15-minute spot choice of a person with `spots` spots.
fn slot_entropy(away: i64, spots: usize) -> f64 {
    let away = away as f64 / 100.0;
    if spots <= 1 {
        return binary_entropy(away);
    }
    let desk = ((100 - (away * 100.0) as i64) * 2 / 3) as f64 / 100.0;
    let other = (1.0 - away - desk) / (spots - 1) as f64;
    away * surprise(away) + desk * surprise(desk) + (spots - 1) as f64 * other * surprise(other)
}

/// Entropy of an office door's call in hour `hour` of a day: how many frames of the hour
/// (within the occupant's realised day) it shuts.
fn call_entropy(samples: &Samples, day0: i64, hour: i64, arrive: i64, leave: i64) -> f64 {
    let from = (hour * 3600).max(arrive);
    let to = ((hour + 1) * 3600).min(leave);
    if samples.count(day0 + from, day0 + to) == 0 {
        return 0.0;
    }
    let mut counts: BTreeMap<usize, f64> = BTreeMap::new();
    *counts.entry(0).or_default() += 1.0 - CALL_CHANCE;
    for m in 0..CALL_LENGTHS as i64 {
        let shut_end = (hour * 3600 + (CALL_MIN_MINUTES + m) * 60).min(to);
        let shut = samples.count(day0 + from, day0 + shut_end.max(from));
        *counts.entry(shut).or_default() += CALL_CHANCE / CALL_LENGTHS as f64;
    }
    counts.values().map(|&p| p * surprise(p)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entropies() {
        assert!((binary_entropy(0.5) - 1.0).abs() < 1e-12);
        assert_eq!(binary_entropy(0.0), 0.0);
        assert!((entropy_of_counts(&[1, 1, 1, 1]) - 2.0).abs() < 1e-12);
        // Away 15 %, desk 56 %, two other spots 14.5 % each.
        let h = slot_entropy(15, 3);
        let expected = [0.15, 0.56, 0.145, 0.145]
            .iter()
            .map(|&p: &f64| -p * p.log2())
            .sum::<f64>();
        assert!((h - expected).abs() < 1e-12);
        let samples = Samples {
            secs: (0..10).map(|k| k * 600).collect(),
        };
        // Minutes 0..60 after 0 s: frame 0 (minute 0) or 1..=5 (ten minutes each, the
        // first of each ten landing on the frame itself).
        let h = samples.minute_draw_entropy(0, 1, 60);
        let counts = [1u64, 10, 10, 10, 10, 10, 9];
        assert!((h - entropy_of_counts(&counts)).abs() < 1e-12, "{h}");
    }
}
