//! The generator: placement once, then any frame on demand.

use crate::calendar::{unix_secs, DAY_SECS};
use crate::compose::compose;
use crate::doors::DoorSeries;
use crate::elements::{
    chair_shape, person_shape, Chair, Clock, Door, DoorDriver, ElementKind, Machine, ObjectModel,
    Person, Shape, WeeklySlot,
};
use crate::error::SynthError;
use crate::geometry::{code_of, coords, leaf_box, BaseIndex, KeyBox, DENSE_LIMIT};
use crate::placement::Placer;
use crate::rng::{below, chance, mix, tag, BernoulliBlocks, SplitMix64};
use crate::spec::{SeriesSpec, Shift, Timing};
use froctomap_core::{MortonCode, Occupancy, Snapshot, Timestamp, VoxelKey};
use std::fmt;

mod floor;
pub use floor::EntropyFloor;

/// A frame of the series: its grid index and its time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FrameInfo {
    /// Index on the time grid (`0..count`); missed frames leave gaps.
    pub index: u64,
    /// Time of the frame (grid time plus jitter).
    pub time: Timestamp,
}

/// What changed in one frame relative to the base map, in voxels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Voxels occupied by closed doors.
    pub doors: u64,
    /// Voxels occupied by people.
    pub people: u64,
    /// Voxels occupied by chairs.
    pub chairs: u64,
    /// Voxels occupied by objects.
    pub objects: u64,
    /// Voxels occupied by machines.
    pub machines: u64,
    /// Surface voxels flipped by sensor noise.
    pub noise: u64,
    /// Known voxels of the base map left unknown by a partial view.
    pub unobserved: u64,
}

impl FrameStats {
    /// Voxels occupied by elements of `kind`.
    pub fn of(&self, kind: ElementKind) -> u64 {
        match kind {
            ElementKind::Door => self.doors,
            ElementKind::Person => self.people,
            ElementKind::Chair => self.chairs,
            ElementKind::Object => self.objects,
            ElementKind::Machine => self.machines,
        }
    }

    fn slot(&mut self, kind: ElementKind) -> &mut u64 {
        match kind {
            ElementKind::Door => &mut self.doors,
            ElementKind::Person => &mut self.people,
            ElementKind::Chair => &mut self.chairs,
            ElementKind::Object => &mut self.objects,
            ElementKind::Machine => &mut self.machines,
        }
    }

    /// Adds another frame's counts (for series totals).
    pub fn add(&mut self, other: &FrameStats) {
        for kind in ElementKind::ALL {
            *self.slot(kind) += other.of(kind);
        }
        self.noise += other.noise;
        self.unobserved += other.unobserved;
    }
}

/// One placed element, for reports and evaluation.
#[derive(Clone, Debug, PartialEq)]
pub struct ElementInfo {
    /// Its kind.
    pub kind: ElementKind,
    /// Its index among the elements of its kind.
    pub index: usize,
    /// Where it is and what drives it, in words.
    pub description: String,
    /// For doors: what opens and closes it.
    pub door_driver: Option<DoorDriver>,
    /// For machines: its shift.
    pub shift: Option<Shift>,
    /// Every voxel the element occupies at some time of the series (all spots of a person
    /// or chair; every stay of an object within the series), sorted.
    pub voxels: Vec<MortonCode>,
}

/// Per kind: how many elements were asked for and placed, and how many distinct voxels
/// they change over the series.
#[derive(Clone, Debug, PartialEq)]
pub struct KindSummary {
    /// The kind.
    pub kind: ElementKind,
    /// Elements the spec asked for.
    pub requested: usize,
    /// Elements placed (fewer when the map has no room for more).
    pub placed: usize,
    /// Distinct voxels these elements occupy at some time of the series.
    pub voxels: u64,
}

/// What a series changes: per element kind, plus noise and partial views.
#[derive(Clone, Debug, PartialEq)]
pub struct ChangeSummary {
    /// One entry per [`ElementKind`], in [`ElementKind::ALL`] order.
    pub kinds: Vec<KindSummary>,
    /// Surface voxels that noise may flip.
    pub noise_candidates: u64,
    /// Expected flips per frame (`candidates × surface_noise`).
    pub noise_flips_per_frame: f64,
    /// Expected number of frames with an unobserved region.
    pub partial_frames: f64,
    /// Known voxels of the base map.
    pub base_known_voxels: u64,
}

impl fmt::Display for ChangeSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for k in &self.kinds {
            writeln!(
                f,
                "{:<8} {:>3} of {:>3} placed, {:>8} distinct voxels",
                k.kind.name(),
                k.placed,
                k.requested,
                k.voxels
            )?;
        }
        writeln!(
            f,
            "noise    {} surface voxels, {:.1} flips per frame expected",
            self.noise_candidates, self.noise_flips_per_frame
        )?;
        write!(
            f,
            "partial  {:.1} frames with an unobserved region expected (base: {} known voxels)",
            self.partial_frames, self.base_known_voxels
        )
    }
}

/// Generates the frames of one series from a base map and a [`SeriesSpec`].
///
/// Placement happens once in [`new`](Self::new); afterwards every frame is a pure function of
/// `(spec, base, index)`, so frames can be produced in any order, in parallel, and one at a
/// time (memory does not grow with `count`).
///
/// ```
/// use froctomap_core::{Occupancy, Snapshot, VoxelKey};
/// use froctomap_synth::{Generator, SeriesSpec};
/// # fn room() -> Snapshot {
/// #     let mut voxels = Vec::new();
/// #     for x in 0..60u16 { for y in 0..40u16 { for z in 0..26u16 {
/// #         let wall = x == 0 || x == 59 || y == 0 || y == 39 || (x == 30 && !(16..26).contains(&y));
/// #         let state = Occupancy::from(z == 0 || z == 25 || wall);
/// #         voxels.push((VoxelKey::new(32768 + x, 32768 + y, 32768 + z).morton(), state));
/// #     }}}
/// #     Snapshot::from_voxel_states(0.1, voxels).unwrap()
/// # }
/// let base: Snapshot = room(); // a 6 x 4 m room at 0.1 m with a doorway in a middle wall
/// let spec = SeriesSpec { count: 24, doors: 1, ..SeriesSpec::default() };
/// let generator = Generator::new(&base, spec, None)?;
/// let first = generator.frames().next().unwrap();
/// let map = generator.frame(first.index)?;
/// assert_eq!(map.resolution(), 0.1);
/// assert_eq!(generator.frame(first.index)?, map); // deterministic
/// # Ok::<(), froctomap_synth::SynthError>(())
/// ```
pub struct Generator {
    spec: SeriesSpec,
    timing: Timing,
    clock: Clock,
    base: Snapshot,
    bounds: KeyBox,
    door_series: Option<DoorSeries>,
    doors: Vec<Door>,
    people: Vec<Person>,
    chairs: Vec<Chair>,
    objects: ObjectModel,
    machines: Vec<Machine>,
    /// Surface voxels with their base state, sorted by code.
    noise: Vec<(u64, Occupancy)>,
    noise_sampler: BernoulliBlocks,
    warnings: Vec<String>,
    /// [`frames`](Generator::frames) starts at the first frame at or after this time.
    frames_from: Option<Timestamp>,
}

impl fmt::Debug for Generator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Generator")
            .field("spec", &self.spec)
            .field("doors", &self.doors.len())
            .field("people", &self.people.len())
            .field("chairs", &self.chairs.len())
            .field("object_spots", &self.objects.pool.len())
            .field("machines", &self.machines.len())
            .field("noise_candidates", &self.noise.len())
            .finish()
    }
}

impl Generator {
    /// Places every element of `spec` in `base` (taken in maximum-likelihood states).
    ///
    /// Doors listed in `spec.real_doors` follow `door_series` when given, else the file named
    /// by `spec.door_file` (loaded here), else schedules. When the map has no room for
    /// everything the spec asks for, fewer elements are placed and
    /// [`warnings`](Self::warnings) says so.
    pub fn new(
        base: &Snapshot,
        spec: SeriesSpec,
        door_series: Option<DoorSeries>,
    ) -> Result<Self, SynthError> {
        spec.validate()?;
        let timing = spec.timing()?;
        let door_series = match (door_series, &spec.door_file) {
            (Some(series), _) => Some(series),
            (None, Some(path)) => Some(DoorSeries::load(path)?),
            (None, None) => None,
        };
        let base = base.to_max_likelihood();
        let index = BaseIndex::new(&base, DENSE_LIMIT).ok_or(SynthError::EmptyBase)?;
        let resolution = base.resolution();
        let clock = Clock {
            seed: spec.seed,
            work_start: (spec.work_start_hour * 3600.0).round() as i64,
            work_end: (spec.work_end_hour * 3600.0).round() as i64,
        };
        let mut warnings = Vec::new();
        let mut doors = Vec::new();
        let mut people = Vec::new();
        let mut chairs = Vec::new();
        let mut machines = Vec::new();
        let period_days = spec.object_max_days.ceil() as i64 + 2;
        let mut objects = ObjectModel {
            pool: Vec::new(),
            phases: Vec::new(),
            period_days,
            min_secs: (spec.object_min_days * DAY_SECS as f64).round() as i64,
            max_secs: (spec.object_max_days * DAY_SECS as f64).round() as i64,
            min_size: [1; 3],
        };
        match Placer::new(&index, resolution, mix(spec.seed, tag::PLACEMENT, 0, 0)) {
            None => warnings
                .push("the base map has no floor (no occupied voxels); no elements placed".into()),
            Some(mut placer) => {
                if placer.floor_cell_count() == 0 {
                    warnings.push("no free floor found; only doors can be placed".into());
                }
                doors = place_doors(&mut placer, &spec, door_series.is_some(), &clock);
                machines = place_machines(&mut placer, &spec);
                people = place_people(&mut placer, &spec);
                chairs = place_chairs(&mut placer, &spec);
                place_objects(&mut placer, &spec, &mut objects);
            }
        }
        let shortfalls = [
            (
                "doors (doorways or corridor sections)",
                spec.doors,
                doors.len(),
            ),
            ("machines", spec.machines, machines.len()),
            ("people", spec.people, people.len()),
            ("chairs", spec.chairs, chairs.len()),
        ];
        for (what, wanted, placed) in shortfalls {
            if placed < wanted {
                warnings.push(format!(
                    "room for {placed} of {wanted} {what} only in the base map"
                ));
            }
        }
        if spec.objects > 0 && objects.pool.is_empty() {
            warnings.push("no free floor spot for objects; objects disabled".into());
        }
        let noise = if spec.surface_noise > 0.0 {
            surface_voxels(&base, &index).unwrap_or_else(|| {
                warnings.push(format!(
                    "more than {MAX_NOISE_CANDIDATES} surface voxels; surface noise disabled"
                ));
                Vec::new()
            })
        } else {
            Vec::new()
        };
        let bounds = index.bounds;
        let spec_noise = spec.surface_noise;
        drop(index);
        Ok(Self {
            spec,
            timing,
            clock,
            base,
            bounds,
            door_series,
            doors,
            people,
            chairs,
            objects,
            machines,
            noise,
            noise_sampler: BernoulliBlocks::new(spec_noise),
            warnings,
            frames_from: None,
        })
    }

    /// The same series with [`frames`](Self::frames) (and so what
    /// [`encode_series`](crate::encode_series) and [`write_series`](crate::write_series)
    /// make) starting at the first frame at or after `time`: a long run that stopped
    /// resumes where it was without making the frames before. Every frame is deterministic
    /// per `(seed, index)`, so these are the very maps a run from the start gives from
    /// `time` on (unlike another `start` in the spec, which moves the whole series).
    pub fn with_frames_from(mut self, time: Timestamp) -> Self {
        self.frames_from = Some(time);
        self
    }

    /// The spec the series follows.
    pub fn spec(&self) -> &SeriesSpec {
        &self.spec
    }

    /// The base map, in maximum-likelihood states.
    pub fn base(&self) -> &Snapshot {
        &self.base
    }

    /// The real door series in use, if any.
    pub fn door_series(&self) -> Option<&DoorSeries> {
        self.door_series.as_ref()
    }

    /// What placement could not do as asked.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    fn check_index(&self, index: u64) -> Result<(), SynthError> {
        if index < self.spec.count {
            Ok(())
        } else {
            Err(SynthError::FrameOutOfRange {
                index,
                count: self.spec.count,
            })
        }
    }

    /// `true` when grid frame `index` is dropped as missed.
    pub fn is_missed(&self, index: u64) -> bool {
        self.spec.missed_frames > 0.0
            && chance(
                mix(self.spec.seed, tag::MISSED, index, 0),
                self.spec.missed_frames,
            )
    }

    /// Time of grid frame `index` (with jitter), also for missed frames.
    pub fn frame_time(&self, index: u64) -> Result<Timestamp, SynthError> {
        self.check_index(index)?;
        Ok(self.time_unchecked(index))
    }

    fn time_unchecked(&self, index: u64) -> Timestamp {
        // validate() checked that start + (count - 1) * step ± jitter fits in i64.
        let grid = i128::from(self.spec.start.0) + i128::from(self.timing.step) * i128::from(index);
        let jitter = if self.timing.jitter > 0 {
            let span = 2 * self.timing.jitter as u64 + 1;
            below(mix(self.spec.seed, tag::JITTER, index, 0), span) as i64 - self.timing.jitter
        } else {
            0
        };
        Timestamp((grid + i128::from(jitter)) as i64)
    }

    /// The frames of the series, in time order (strictly increasing), missed frames left out,
    /// from the time given to [`with_frames_from`](Self::with_frames_from) if any.
    /// Lazy: nothing is held per frame.
    pub fn frames(&self) -> impl Iterator<Item = FrameInfo> + '_ {
        let from = self.frames_from.unwrap_or(Timestamp(i64::MIN));
        // The grid frame at `from`, less one for jitter; the rest is skipped by time.
        let first = match self.timing.step {
            step if step > 0 => {
                let offset = i128::from(from.0) - i128::from(self.spec.start.0);
                u64::try_from(offset / i128::from(step) - 1).unwrap_or(0)
            }
            _ => 0,
        };
        (first.min(self.spec.count)..self.spec.count)
            .filter(|&i| !self.is_missed(i))
            .map(|i| FrameInfo {
                index: i,
                time: self.time_unchecked(i),
            })
            .skip_while(move |frame| frame.time < from)
    }

    /// The map of frame `index`: the base map with every element present at the frame's
    /// time, this frame's surface noise, and without its unobserved region. Deterministic
    /// per `(seed, index)`, independent of every other frame.
    pub fn frame(&self, index: u64) -> Result<Snapshot, SynthError> {
        self.frame_with_stats(index).map(|(snapshot, _)| snapshot)
    }

    /// [`frame`](Self::frame) with counts of what changed.
    pub fn frame_with_stats(&self, index: u64) -> Result<(Snapshot, FrameStats), SynthError> {
        self.check_index(index)?;
        if self.is_missed(index) {
            return Err(SynthError::MissedFrame { index });
        }
        self.compose(index, true)
    }

    /// The world at grid frame `index` without sensor effects: base map plus elements, no
    /// noise, nothing unobserved. Defined for missed frames too (the world went on).
    pub fn truth_frame(&self, index: u64) -> Result<Snapshot, SynthError> {
        self.check_index(index)?;
        self.compose(index, false).map(|(snapshot, _)| snapshot)
    }

    /// True state of one voxel at grid frame `index` (see [`truth_frame`](Self::truth_frame)).
    pub fn truth_state(&self, index: u64, key: VoxelKey) -> Result<Option<Occupancy>, SynthError> {
        Ok(self.truth_state_at(self.frame_time(index)?, key))
    }

    /// True state of one voxel at any time, also between or beyond the frames (for scoring
    /// predictions).
    pub fn truth_state_at(&self, time: Timestamp, key: VoxelKey) -> Option<Occupancy> {
        let code = key.morton().0;
        let mut occupied = false;
        self.for_each_present(time, |_, shape| {
            occupied |= shape.bounds.contains(coords(key)) && shape.contains(code);
        });
        if occupied {
            Some(Occupancy::Occupied)
        } else {
            self.base.state_at(MortonCode(code))
        }
    }

    /// The box frame `index` does not observe, if it is a partial view.
    pub fn unobserved_region(&self, index: u64) -> Option<KeyBox> {
        let p = self.spec.partial_probability;
        let r = mix(self.spec.seed, tag::PARTIAL, index, 0);
        if p <= 0.0 || !chance(r, p) {
            return None;
        }
        let b = self.bounds;
        let mut min = b.min;
        let mut max = b.max;
        let mut r = SplitMix64::new(r);
        for a in 0..2 {
            let extent = b.max[a] - b.min[a];
            let size =
                ((f64::from(extent) * self.spec.partial_extent).round() as i32).clamp(1, extent);
            min[a] = b.min[a] + r.below((extent - size + 1) as u64) as i32;
            max[a] = min[a] + size;
        }
        Some(KeyBox { min, max })
    }

    /// Calls `f` with every element shape present at `time`.
    fn for_each_present(&self, time: Timestamp, mut f: impl FnMut(ElementKind, &Shape)) {
        let series = self.door_series.as_ref();
        for (id, door) in self.doors.iter().enumerate() {
            if door.closed(id, time, &self.clock, series) {
                f(ElementKind::Door, &door.shape);
            }
        }
        for (id, person) in self.people.iter().enumerate() {
            if let Some(spot) = person.spot(id, time, &self.clock) {
                if let Some(shape) = person.spots.get(spot) {
                    f(ElementKind::Person, shape);
                }
            }
        }
        for (id, chair) in self.chairs.iter().enumerate() {
            if let Some(shape) = chair.spots.get(chair.spot(id, time, &self.clock)) {
                f(ElementKind::Chair, shape);
            }
        }
        for slot in 0..self.objects.phases.len() {
            if let Some(b) = self.objects.present(slot, time, self.spec.seed) {
                f(ElementKind::Object, &Shape::solid(b));
            }
        }
        for machine in &self.machines {
            if machine.present(time) {
                f(ElementKind::Machine, &machine.shape);
            }
        }
    }

    fn compose(&self, index: u64, observed: bool) -> Result<(Snapshot, FrameStats), SynthError> {
        let time = self.time_unchecked(index);
        let mut stats = FrameStats::default();
        let mut occupied: Vec<u64> = Vec::new();
        self.for_each_present(time, |kind, shape| {
            *stats.slot(kind) += shape.codes.len() as u64;
            occupied.extend_from_slice(&shape.codes);
        });
        occupied.sort_unstable();
        occupied.dedup();
        let flips = if observed {
            self.noise_flips(index)
        } else {
            Vec::new()
        };
        stats.noise = flips.len() as u64;
        // Elements set voxels occupied; noise flips the state a voxel would have had.
        let mut overrides = Vec::with_capacity(occupied.len() + flips.len());
        let (mut i, mut j) = (0, 0);
        while i < occupied.len() || j < flips.len() {
            let e = occupied.get(i).copied();
            let n = flips.get(j).copied();
            match (e, n) {
                (Some(e), Some((n, _))) if e == n => {
                    overrides.push((e, Occupancy::Free));
                    i += 1;
                    j += 1;
                }
                (Some(e), Some((n, _))) if e < n => {
                    overrides.push((e, Occupancy::Occupied));
                    i += 1;
                }
                (Some(e), None) => {
                    overrides.push((e, Occupancy::Occupied));
                    i += 1;
                }
                (_, Some((n, base))) => {
                    overrides.push((n, !base));
                    j += 1;
                }
                (None, None) => break,
            }
        }
        let unobserved = if observed {
            self.unobserved_region(index)
        } else {
            None
        };
        let mut leaves = Vec::with_capacity(self.base.leaves().len() + 8 * overrides.len());
        let removed = compose(
            self.base.leaves(),
            &overrides,
            unobserved.as_ref(),
            &mut leaves,
        );
        stats.unobserved = removed.voxels;
        let snapshot = Snapshot::from_leaves(self.base.resolution(), leaves)?;
        Ok((snapshot, stats))
    }

    /// Surface voxels flipping in frame `index`, with their base state, sorted.
    fn noise_flips(&self, index: u64) -> Vec<(u64, Occupancy)> {
        let p = self.spec.surface_noise;
        if p <= 0.0 {
            return Vec::new();
        }
        let mut rng = SplitMix64::new(mix(self.spec.seed, tag::NOISE, index, 0));
        let mut flips = Vec::new();
        self.noise_sampler.sample(&mut rng, self.noise.len(), |i| {
            if let Some(&candidate) = self.noise.get(i) {
                flips.push(candidate);
            }
        });
        flips
    }

    /// Voxels element `index` of `kind` occupies at `time` (empty when absent or no such
    /// element).
    pub fn occupied_by(&self, kind: ElementKind, index: usize, time: Timestamp) -> Vec<MortonCode> {
        let series = self.door_series.as_ref();
        let shape: Option<Shape> = match kind {
            ElementKind::Door => self
                .doors
                .get(index)
                .filter(|d| d.closed(index, time, &self.clock, series))
                .map(|d| d.shape.clone()),
            ElementKind::Person => self.people.get(index).and_then(|p| {
                p.spot(index, time, &self.clock)
                    .and_then(|s| p.spots.get(s).cloned())
            }),
            ElementKind::Chair => self
                .chairs
                .get(index)
                .and_then(|c| c.spots.get(c.spot(index, time, &self.clock)).cloned()),
            ElementKind::Object => (index < self.objects.phases.len())
                .then(|| self.objects.present(index, time, self.spec.seed))
                .flatten()
                .map(Shape::solid),
            ElementKind::Machine => self
                .machines
                .get(index)
                .filter(|m| m.present(time))
                .map(|m| m.shape.clone()),
        };
        shape.map_or_else(Vec::new, |s| s.codes.into_iter().map(MortonCode).collect())
    }

    /// Series time span `[first, last]` (grid ± jitter).
    fn span(&self) -> (Timestamp, Timestamp) {
        let first = Timestamp(self.spec.start.0.saturating_sub(self.timing.jitter));
        let last = self.time_unchecked(self.spec.count - 1);
        (first, Timestamp(last.0.saturating_add(self.timing.jitter)))
    }

    /// Voxels of object slot `slot` over the series: every stay overlapping the span.
    fn object_voxels(&self, slot: usize) -> Vec<u64> {
        let (first, last) = self.span();
        let (s0, s1) = (unix_secs(first), unix_secs(last));
        let mut codes = Vec::new();
        let p0 = self.objects.period_at(slot, first);
        let p1 = self.objects.period_at(slot, last);
        for period in p0..=p1 {
            if let Some(a) = self.objects.appearance(slot, period, self.spec.seed) {
                if a.start <= s1 && a.end > s0 {
                    codes.extend(Shape::solid(a.bounds).codes);
                }
            }
        }
        codes.sort_unstable();
        codes.dedup();
        codes
    }

    /// Every placed element with where it is, what drives it and every voxel it can occupy
    /// during the series.
    pub fn elements(&self) -> Vec<ElementInfo> {
        let res = self.base.resolution();
        let centre = |b: &KeyBox| {
            let c = VoxelKey::new(
                ((b.min[0] + b.max[0]) / 2).clamp(0, 65535) as u16,
                ((b.min[1] + b.max[1]) / 2).clamp(0, 65535) as u16,
                b.min[2].clamp(0, 65535) as u16,
            )
            .center(res);
            format!("({:.2}, {:.2}, {:.2}) m", c[0], c[1], c[2])
        };
        let union = |shapes: &[Shape]| {
            let mut codes: Vec<u64> = shapes
                .iter()
                .flat_map(|s| s.codes.iter().copied())
                .collect();
            codes.sort_unstable();
            codes.dedup();
            codes.into_iter().map(MortonCode).collect::<Vec<_>>()
        };
        let mut out = Vec::new();
        for (i, d) in self.doors.iter().enumerate() {
            out.push(ElementInfo {
                kind: ElementKind::Door,
                index: i,
                description: format!(
                    "{} {:.2} m wide at {}, {}",
                    if d.across_corridor {
                        "corridor door"
                    } else {
                        "door"
                    },
                    d.width_m,
                    centre(&d.shape.bounds),
                    d.driver
                ),
                door_driver: Some(d.driver.clone()),
                shift: None,
                voxels: union(std::slice::from_ref(&d.shape)),
            });
        }
        for (i, p) in self.people.iter().enumerate() {
            let spots: Vec<String> = p.spots.iter().map(|s| centre(&s.bounds)).collect();
            out.push(ElementInfo {
                kind: ElementKind::Person,
                index: i,
                description: format!("person with spots {}", spots.join(", ")),
                door_driver: None,
                shift: None,
                voxels: union(&p.spots),
            });
        }
        for (i, c) in self.chairs.iter().enumerate() {
            let spots: Vec<String> = c.spots.iter().map(|s| centre(&s.bounds)).collect();
            out.push(ElementInfo {
                kind: ElementKind::Chair,
                index: i,
                description: format!("chair with spots {}", spots.join(", ")),
                door_driver: None,
                shift: None,
                voxels: union(&c.spots),
            });
        }
        for slot in 0..self.objects.phases.len() {
            out.push(ElementInfo {
                kind: ElementKind::Object,
                index: slot,
                description: format!(
                    "object slot: stays of {}-{} days in every {}-day period, at {} spots",
                    self.spec.object_min_days,
                    self.spec.object_max_days,
                    self.objects.period_days,
                    self.objects.pool.len()
                ),
                door_driver: None,
                shift: None,
                voxels: self
                    .object_voxels(slot)
                    .into_iter()
                    .map(MortonCode)
                    .collect(),
            });
        }
        for (i, m) in self.machines.iter().enumerate() {
            let shift = Shift {
                start_hour: m.shift.0 as f64 / 3600.0,
                end_hour: m.shift.1 as f64 / 3600.0,
            };
            out.push(ElementInfo {
                kind: ElementKind::Machine,
                index: i,
                description: format!(
                    "machine {}x{}x{} voxels at {}, weekdays {:.1}-{:.1} h UTC",
                    m.shape.bounds.max[0] - m.shape.bounds.min[0],
                    m.shape.bounds.max[1] - m.shape.bounds.min[1],
                    m.shape.bounds.max[2] - m.shape.bounds.min[2],
                    centre(&m.shape.bounds),
                    shift.start_hour,
                    shift.end_hour
                ),
                door_driver: None,
                shift: Some(shift),
                voxels: union(std::slice::from_ref(&m.shape)),
            });
        }
        out
    }

    /// What the series changes, per kind (distinct voxels over the series), plus noise and
    /// partial views (expected values).
    pub fn change_summary(&self) -> ChangeSummary {
        let elements = self.elements();
        let requested = |kind| match kind {
            ElementKind::Door => self.spec.doors,
            ElementKind::Person => self.spec.people,
            ElementKind::Chair => self.spec.chairs,
            ElementKind::Object => self.spec.objects,
            ElementKind::Machine => self.spec.machines,
        };
        let kinds = ElementKind::ALL
            .iter()
            .map(|&kind| {
                let mut codes: Vec<MortonCode> = elements
                    .iter()
                    .filter(|e| e.kind == kind)
                    .flat_map(|e| e.voxels.iter().copied())
                    .collect();
                codes.sort_unstable();
                codes.dedup();
                KindSummary {
                    kind,
                    requested: requested(kind),
                    placed: elements.iter().filter(|e| e.kind == kind).count(),
                    voxels: codes.len() as u64,
                }
            })
            .collect();
        let stats = self.base.stats();
        ChangeSummary {
            kinds,
            noise_candidates: self.noise.len() as u64,
            noise_flips_per_frame: self.noise.len() as f64 * self.spec.surface_noise,
            partial_frames: self.spec.count as f64
                * (1.0 - self.spec.missed_frames)
                * self.spec.partial_probability,
            base_known_voxels: stats.free_voxels + stats.occupied_voxels,
        }
    }
}

/// Most surface voxels kept for noise (16 bytes each); a map with more gets no noise.
const MAX_NOISE_CANDIDATES: usize = 1 << 23;

/// Occupied voxels with a free face neighbour and free voxels with an occupied face
/// neighbour: where a range sensor's readings flicker. Only the outer shell of a coarse
/// occupied leaf can touch free space, so only the shell is visited. `None` when there are
/// more than [`MAX_NOISE_CANDIDATES`].
fn surface_voxels(base: &Snapshot, index: &BaseIndex<'_>) -> Option<Vec<(u64, Occupancy)>> {
    const FACES: [[i32; 3]; 6] = [
        [-1, 0, 0],
        [1, 0, 0],
        [0, -1, 0],
        [0, 1, 0],
        [0, 0, -1],
        [0, 0, 1],
    ];
    let mut out = Vec::new();
    for leaf in base.leaves() {
        if leaf.occupancy() != Occupancy::Occupied {
            continue;
        }
        let b = leaf_box(leaf);
        let edge = (b.max[0] - b.min[0]) as usize;
        if 6 * edge * edge > MAX_NOISE_CANDIDATES {
            return None;
        }
        let mut visit = |k: [i32; 3]| {
            let mut surface = false;
            for d in FACES {
                let n = [k[0] + d[0], k[1] + d[1], k[2] + d[2]];
                if index.is_free(n) {
                    surface = true;
                    if let Some(c) = code_of(n) {
                        out.push((c, Occupancy::Free));
                    }
                }
            }
            if surface {
                if let Some(c) = code_of(k) {
                    out.push((c, Occupancy::Occupied));
                }
            }
        };
        for z in b.min[2]..b.max[2] {
            let cap = z == b.min[2] || z == b.max[2] - 1;
            for y in b.min[1]..b.max[1] {
                if cap || y == b.min[1] || y == b.max[1] - 1 {
                    for x in b.min[0]..b.max[0] {
                        visit([x, y, z]);
                    }
                } else {
                    visit([b.min[0], y, z]);
                    if b.max[0] - 1 > b.min[0] {
                        visit([b.max[0] - 1, y, z]);
                    }
                }
            }
        }
        if out.len() > 2 * MAX_NOISE_CANDIDATES {
            return None;
        }
    }
    out.sort_unstable_by_key(|&(c, _)| c);
    out.dedup_by_key(|&mut (c, _)| c);
    (out.len() <= MAX_NOISE_CANDIDATES).then_some(out)
}

fn place_doors(
    placer: &mut Placer<'_, '_>,
    spec: &SeriesSpec,
    real: bool,
    clock: &Clock,
) -> Vec<Door> {
    let sites = placer.place_doors(spec.doors);
    let mut doors = Vec::new();
    let mut real_used = 0u32;
    let mut schedule_used = 0usize;
    for site in sites {
        let driver = if real && (real_used as usize) < spec.real_doors {
            real_used += 1;
            DoorDriver::Real {
                offset_weeks: real_used - 1,
            }
        } else if site.across_corridor {
            DoorDriver::Corridor
        } else {
            schedule_used += 1;
            if schedule_used % 2 == 1 {
                DoorDriver::Office
            } else {
                DoorDriver::MeetingRoom {
                    meetings: meetings(&mut placer.rng, clock),
                }
            }
        };
        doors.push(Door {
            shape: Shape::solid(site.slab),
            driver,
            width_m: site.width_m,
            across_corridor: site.across_corridor,
        });
    }
    doors
}

/// Two to four weekly meetings of 1, 1.5 or 2 hours within working hours.
fn meetings(rng: &mut SplitMix64, clock: &Clock) -> Vec<WeeklySlot> {
    let n = 2 + rng.below(3);
    let half_hours = ((clock.work_end - clock.work_start) / 1800).max(1);
    (0..n)
        .map(|_| {
            let length = 1800 * (2 + rng.below(3) as i64);
            let start = clock.work_start + 1800 * rng.below(half_hours as u64) as i64;
            WeeklySlot {
                weekday: rng.below(5) as u8,
                start_secs: start,
                end_secs: (start + length).min(clock.work_end),
            }
        })
        .collect()
}

fn place_machines(placer: &mut Placer<'_, '_>, spec: &SeriesSpec) -> Vec<Machine> {
    let mut machines = Vec::new();
    for m in 0..spec.machines {
        let size = [
            placer.random_voxels(0.8, 1.2),
            placer.random_voxels(0.6, 1.0),
            placer.random_voxels(1.0, 1.6),
        ];
        let margin = placer.voxels(0.4);
        let Some(b) = placer.place_on_floor(size, margin) else {
            break;
        };
        let shift = spec
            .shifts
            .get(m % spec.shifts.len().max(1))
            .copied()
            .unwrap_or(Shift {
                start_hour: 6.0,
                end_hour: 14.0,
            });
        machines.push(Machine {
            shape: Shape::solid(b),
            shift: (
                (shift.start_hour * 3600.0).round() as i64,
                (shift.end_hour * 3600.0).round() as i64,
            ),
        });
    }
    machines
}

fn place_people(placer: &mut Placer<'_, '_>, spec: &SeriesSpec) -> Vec<Person> {
    let mut people = Vec::new();
    for _ in 0..spec.people {
        let height = placer.random_voxels(1.6, 1.85);
        let (w, d) = (placer.voxels(0.45), placer.voxels(0.32));
        let margin = placer.voxels(0.3);
        let mut spots = Vec::new();
        for _ in 0..3 {
            // Facing along x or y.
            let size = if placer.rng.below(2) == 0 {
                [w, d, height]
            } else {
                [d, w, height]
            };
            if let Some(b) = placer.place_on_floor(size, margin) {
                spots.push(person_shape(b));
            }
        }
        if spots.is_empty() {
            break;
        }
        people.push(Person { spots });
    }
    people
}

fn place_chairs(placer: &mut Placer<'_, '_>, spec: &SeriesSpec) -> Vec<Chair> {
    let mut chairs = Vec::new();
    let size = [placer.voxels(0.5), placer.voxels(0.5), placer.voxels(0.9)];
    let seat = placer.voxels(0.45);
    let margin = placer.voxels(0.2);
    for _ in 0..spec.chairs {
        let mut spots = Vec::new();
        for _ in 0..2 {
            let back = placer.rng.below(4) as u8;
            if let Some(b) = placer.place_on_floor(size, margin) {
                spots.push(chair_shape(b, seat, back));
            }
        }
        if spots.is_empty() {
            break;
        }
        chairs.push(Chair { spots });
    }
    chairs
}

fn place_objects(placer: &mut Placer<'_, '_>, spec: &SeriesSpec, objects: &mut ObjectModel) {
    if spec.objects == 0 {
        return;
    }
    // Boxes up to 0.6 x 0.6 x 0.8 m: what fits beside people in a 2 m corridor.
    let max = [placer.voxels(0.6), placer.voxels(0.6), placer.voxels(0.8)];
    objects.min_size = [
        placer.voxels(0.25),
        placer.voxels(0.25),
        placer.voxels(0.25),
    ];
    let margin = placer.voxels(0.2);
    for _ in 0..(3 * spec.objects).max(8) {
        if let Some(b) = placer.place_on_floor(max, margin) {
            objects.pool.push(b);
        }
    }
    if objects.pool.is_empty() {
        return;
    }
    for _ in 0..spec.objects {
        let phase = placer.rng.below(objects.period_days as u64) as i64;
        objects.phases.push(phase);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::{Leaf, TREE_DEPTH};

    #[test]
    fn surface_of_coarse_leaves_equals_voxel_by_voxel() {
        let k = |x: u16, y: u16, z: u16| VoxelKey::new(32768 + x, 32768 + y, 32768 + z);
        let occupied = Occupancy::Occupied.log_odds();
        let free = Occupancy::Free.log_odds();
        // An 8^3 occupied block, a 4^3 occupied block inside free space, free around.
        let coarse = Snapshot::from_leaves(
            0.1,
            vec![
                Leaf::containing(k(0, 0, 0), 13, occupied),
                Leaf::containing(k(8, 0, 0), 13, free),
                Leaf::containing(k(0, 8, 0), 14, free),
                Leaf::containing(k(4, 8, 0), 14, occupied),
                Leaf::voxel(k(0, 0, 8), free),
            ],
        )
        .unwrap();
        let fine = Snapshot::from_voxel_states(0.1, coarse.voxels()).unwrap();
        assert!(fine.leaves().iter().all(|l| l.depth == TREE_DEPTH));
        let a = surface_voxels(&coarse, &BaseIndex::new(&coarse, DENSE_LIMIT).unwrap()).unwrap();
        let b = surface_voxels(&fine, &BaseIndex::new(&fine, 0).unwrap()).unwrap();
        assert_eq!(a, b);
        // The occupied 8^3 block meets the free 8^3 block on its +x face: both sides of
        // that face are surface voxels; the block's interior is not.
        assert!(a
            .iter()
            .any(|&(c, s)| c == k(7, 3, 3).morton().0 && s == Occupancy::Occupied));
        assert!(a
            .iter()
            .any(|&(c, s)| c == k(8, 3, 3).morton().0 && s == Occupancy::Free));
        assert!(!a.iter().any(|&(c, _)| c == k(3, 3, 3).morton().0));
    }

    #[test]
    fn degenerate_maps_give_warnings_not_hangs() {
        let spec = SeriesSpec {
            count: 2,
            partial_probability: 0.0,
            ..SeriesSpec::default()
        };
        let empty = Snapshot::empty(0.1).unwrap();
        assert!(matches!(
            Generator::new(&empty, spec.clone(), None),
            Err(SynthError::EmptyBase)
        ));
        for state in [Occupancy::Free, Occupancy::Occupied] {
            // The whole tree as one leaf: 2^48 voxels.
            let root = Snapshot::from_leaves(
                0.1,
                vec![Leaf {
                    start: MortonCode(0),
                    depth: 0,
                    log_odds: state.log_odds(),
                }],
            )
            .unwrap();
            // A generator that walked the leaf's 2^48 voxels would never return; how long
            // the coarse case takes is measured by `cargo bench -p froctomap-synth`.
            let generator = Generator::new(&root, spec.clone(), None).unwrap();
            assert!(!generator.warnings().is_empty());
            assert!(generator.elements().is_empty());
            // No elements and no noise (no surface, or one too large): the map as it was.
            assert!(generator.frame(1).unwrap().same_voxel_states(&root));
        }
    }
}
