//! Realistic, deterministic long-term map series for demos, end-to-end tests and benchmarks.
//!
//! `froctomap-synth` takes one real OctoMap (by default the FR-079 corridor scan
//! `geb079.bt`) as the static building and generates a series of snapshots of it as a robot
//! revisiting the building for weeks would record them: things a building really has change
//! on the daily and weekly rhythms of the people in it, and the sensor adds its own effects.
//!
//! # The scenario model
//!
//! The base map is taken in maximum-likelihood states (occupied/free, as a `.bt` holds).
//! *Elements* are placed once, from the series seed, where they make physical sense; each is
//! a set of voxels that are free in the base map and occupied while the element is present
//! (when absent, the base map shows through):
//!
//! | kind | shape and place | when present |
//! |---|---|---|
//! | door | 1-voxel slab filling a doorway (a 0.6–1.4 m gap in a wall with jambs, floor and open space on both sides, up to 2 m), or a corridor cross-section (1.4–3.2 m) | closed: the **real door recording** (state 1 = open) for `real_doors` doors, each shifted by whole weeks; else an office schedule (daily arrival/departure, short calls, rare weekend visits), a meeting-room schedule (weekly meetings) or, across corridors, weekdays ±1 h around working hours |
//! | person | 0.45 × 0.32 m elliptic body with a head, 1.6–1.85 m, at 3 floor spots (desk first) | weekdays between a random arrival in the first working hour and a departure in the last 1.5 h; per 15-minute slot at the desk, another spot or away (mostly away at lunch) |
//! | chair | 0.5 × 0.5 × 0.9 m office chair (feet, post, seat, backrest), 2 floor spots | always somewhere: at spot 0 outside working hours, at a random spot per working hour |
//! | object | box of 0.25–0.6 m × 0.25–0.6 m × 0.25–0.8 m at one of a pool of free floor spots | in each period of `ceil(object_max_days) + 2` days, with probability 0.8, one stay of `object_min_days..object_max_days` days at a random spot, size and time |
//! | machine | solid block of 0.8–1.2 × 0.6–1.0 × 1.0–1.6 m at a floor spot | weekdays during its shift (`shifts` in turn: 6–14, 14–22 h by default; overnight shifts allowed) |
//!
//! Floor spots rest on occupied floor voxels (the floor is the most populated horizontal
//! level of the lower half of the map), are known free for the whole element, keep a free
//! ring from walls, and never overlap another element or a doorway. All times are UTC.
//!
//! Sensor effects come on top, per frame: *surface noise* flips each voxel on the boundary
//! between occupied and free space (occupied with a free face neighbour, or free with an
//! occupied one) for that single frame with probability `surface_noise`; a *partial view*
//! (probability `partial_probability`) leaves a box of `partial_extent` of the map's
//! horizontal extent, all heights, unobserved: its leaves are absent from that frame, unknown
//! rather than free. Frame times follow a grid of `step_secs` from `start`, optionally
//! jittered (`jitter_secs`, order kept) and with frames missed at random (`missed_frames`).
//!
//! # Determinism and streaming
//!
//! Placement uses a seeded SplitMix64 stream; everything later is a stateless hash of
//! `(seed, purpose, element, time slot or frame index)`, with integer and exact IEEE
//! arithmetic only. So [`Generator::frame`] is a pure function of the spec, the base map and
//! the index: frames can be made in any order, in parallel, and the same seed gives the same
//! series on every platform. Memory does not depend on the series length; [`write_series`]
//! writes in bounded parallel batches.
//!
//! A frame is built by merging the base map's Morton-sorted leaves with the frame's sorted
//! voxel overrides, splitting a coarse base leaf only where an override falls in it
//! (about 3 ms for a geb079 frame, dominated by copying and validating its 428 k leaves).
//!
//! ```
//! use froctomap_core::{Occupancy, Snapshot, VoxelKey};
//! use froctomap_synth::{ElementKind, Generator, SeriesSpec};
//!
//! // A 4 x 3 m room at 0.1 m: floor, walls, ceiling.
//! let mut voxels = Vec::new();
//! for x in 0..40u16 { for y in 0..30u16 { for z in 0..26u16 {
//!     let solid = z == 0 || z == 25 || x == 0 || x == 39 || y == 0 || y == 29;
//!     let state = Occupancy::from(solid);
//!     voxels.push((VoxelKey::new(32768 + x, 32768 + y, 32768 + z).morton(), state));
//! }}}
//! let base = Snapshot::from_voxel_states(0.1, voxels)?;
//!
//! let spec = SeriesSpec { seed: 3, doors: 0, machines: 1, ..SeriesSpec::with_duration(1.0, 3600.0) };
//! let generator = Generator::new(&base, spec, None)?;
//! let machine = &generator.elements().into_iter().find(|e| e.kind == ElementKind::Machine).unwrap();
//! let at_10h = generator.frame(10)?; // Monday 10:00 UTC: the early shift (6-14 h) is on
//! assert!(machine.voxels.iter().all(|&v| at_10h.state_at(v) == Some(Occupancy::Occupied)));
//! let at_3h = generator.truth_frame(3)?; // 03:00: no shift
//! assert!(machine.voxels.iter().all(|&v| at_3h.state_at(v) == Some(Occupancy::Free)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod calendar;
mod compose;
mod doors;
mod elements;
mod error;
mod generator;
mod geometry;
mod overrides;
mod placement;
mod rng;
mod series;
mod spec;

pub use doors::DoorSeries;

/// Where Debian's liboctomap-dev puts the FR-079 corridor scan, the default base map of a
/// generated series (the command line's `generate --base`).
pub const DEBIAN_GEB079: &str = "/usr/share/doc/liboctomap-dev/examples/data/geb079.bt";
pub use elements::{DoorDriver, ElementKind, WeeklySlot};
pub use error::SynthError;
pub use generator::{
    ChangeSummary, ElementInfo, EntropyFloor, FrameInfo, FrameStats, Generator, KindSummary,
};
pub use geometry::KeyBox;
pub use overrides::SpecOverrides;
pub use series::{
    encode_series, write_series, ManifestEntry, SeriesManifest, WriteSeriesOptions, MANIFEST_NAME,
};
pub use spec::{frames_for, SeriesSpec, Shift, MAX_ELEMENTS, MAX_FRAMES};
