//! Every kind of change behaves as specified: doors follow the real recording or their
//! schedules, people/chairs/machines/objects keep their windows, partial views only hide,
//! surface noise flickers on surfaces.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use froctomap_core::{MortonCode, Occupancy, Snapshot, Timestamp};
use froctomap_synth::calendar::{day_number, is_weekday, second_of_day, weekday};
use froctomap_synth::{
    DoorDriver, DoorSeries, ElementInfo, ElementKind, Generator, SeriesSpec, Shift,
};

/// No sensor effects, so frames show the world as it is.
fn quiet(spec: SeriesSpec) -> SeriesSpec {
    SeriesSpec {
        surface_noise: 0.0,
        partial_probability: 0.0,
        ..spec
    }
}

fn states(frame: &Snapshot, voxels: &[MortonCode]) -> (usize, usize) {
    let occupied = voxels
        .iter()
        .filter(|&&v| frame.state_at(v) == Some(Occupancy::Occupied))
        .count();
    let free = voxels
        .iter()
        .filter(|&&v| frame.state_at(v) == Some(Occupancy::Free))
        .count();
    (occupied, free)
}

fn of_kind(generator: &Generator, kind: ElementKind) -> Vec<ElementInfo> {
    generator
        .elements()
        .into_iter()
        .filter(|e| e.kind == kind)
        .collect()
}

#[test]
fn doors_follow_the_real_door_series() {
    let raw = common::raw_door_states(&common::door_file());
    let spec = quiet(SeriesSpec {
        count: 10 * 7 * 144, // ten weeks every 10 minutes from 2016-01-04 00:00
        doors: 2,
        real_doors: 2,
        door_file: Some(common::door_file()),
        people: 0,
        chairs: 0,
        objects: 0,
        machines: 0,
        ..SeriesSpec::default()
    });
    let generator = Generator::new(&common::office(), spec, None).unwrap();
    let doors = of_kind(&generator, ElementKind::Door);
    assert_eq!(doors.len(), 2, "{:?}", generator.warnings());
    // Pick frames at recorded minutes: six with door 0 open and six closed, spread out.
    let frames: Vec<_> = generator.frames().collect();
    let minute = |t: Timestamp| t.0.div_euclid(60_000_000_000) * 60;
    let mut open: Vec<_> = frames
        .iter()
        .filter(|f| raw.get(&minute(f.time)) == Some(&true))
        .collect();
    let mut closed: Vec<_> = frames
        .iter()
        .filter(|f| raw.get(&minute(f.time)) == Some(&false))
        .collect();
    assert!(open.len() > 100 && closed.len() > 1000);
    let (open_step, closed_step) = (open.len() / 6, closed.len() / 6);
    open = open.into_iter().step_by(open_step).take(6).collect();
    closed = closed.into_iter().step_by(closed_step).take(6).collect();
    for f in open.into_iter().chain(closed) {
        let frame = generator.frame(f.index).unwrap();
        for door in &doors {
            let Some(DoorDriver::Real { offset_weeks }) = door.door_driver else {
                panic!("door {} is not driven by the recording", door.index);
            };
            let read_at = minute(f.time) + i64::from(offset_weeks) * 7 * 86_400;
            let Some(&is_open) = raw.get(&read_at) else {
                continue; // that minute is in the outage; filled values are tested elsewhere
            };
            let (occupied, free) = states(&frame, &door.voxels);
            let n = door.voxels.len();
            if is_open {
                assert_eq!((occupied, free), (0, n), "door {} at {:?}", door.index, f);
            } else {
                assert_eq!((occupied, free), (n, 0), "door {} at {:?}", door.index, f);
            }
        }
    }
    // Passing the series in directly is the same as naming the file in the spec.
    let series = DoorSeries::load(&common::door_file()).unwrap();
    let direct = Generator::new(
        &common::office(),
        SeriesSpec {
            door_file: None,
            ..generator.spec().clone()
        },
        Some(series),
    )
    .unwrap();
    assert_eq!(direct.frame(500).unwrap(), generator.frame(500).unwrap());
}

#[test]
fn machines_people_and_chairs_keep_their_windows() {
    let spec = quiet(SeriesSpec {
        // A week from Monday 00:05 every 30 minutes, plus the next Monday morning.
        start: Timestamp::from_secs(1_451_865_900),
        step_secs: 1800.0,
        count: 8 * 48,
        doors: 0,
        people: 3,
        chairs: 2,
        objects: 0,
        machines: 3,
        shifts: vec![
            Shift {
                start_hour: 6.0,
                end_hour: 14.0,
            },
            Shift {
                start_hour: 14.0,
                end_hour: 22.0,
            },
            Shift {
                start_hour: 22.0,
                end_hour: 6.0,
            },
        ],
        ..SeriesSpec::default()
    });
    let generator = Generator::new(&common::office(), spec, None).unwrap();
    let machines = of_kind(&generator, ElementKind::Machine);
    let people = of_kind(&generator, ElementKind::Person);
    let chairs = of_kind(&generator, ElementKind::Chair);
    assert_eq!(
        (machines.len(), people.len(), chairs.len()),
        (3, 3, 2),
        "{:?}",
        generator.warnings()
    );
    let mut person_seen = 0;
    for f in generator.frames() {
        let frame = generator.frame(f.index).unwrap();
        let (day, sod) = (day_number(f.time), second_of_day(f.time));
        let hour = sod / 3600;
        for m in &machines {
            let shift = m.shift.unwrap();
            let (start, end) = (shift.start_hour as i64, shift.end_hour as i64);
            let expected = if start < end {
                is_weekday(day) && (start..end).contains(&hour)
            } else {
                (is_weekday(day) && hour >= start) || (is_weekday(day - 1) && hour < end)
            };
            let (occupied, free) = states(&frame, &m.voxels);
            let n = m.voxels.len();
            let want = if expected { (n, 0) } else { (0, n) };
            assert_eq!((occupied, free), want, "machine {} at {}", m.index, f.time);
        }
        let working = weekday(f.time) < 5 && (8..18).contains(&hour);
        for p in &people {
            let (occupied, _) = states(&frame, &p.voxels);
            if !working {
                assert_eq!(occupied, 0, "person {} present at {}", p.index, f.time);
            }
            // At most one spot at a time: never more than the largest spot's voxels.
            let at = generator.occupied_by(ElementKind::Person, p.index, f.time);
            assert_eq!(occupied, at.len());
            assert!(at.len() < p.voxels.len());
            person_seen += usize::from(occupied > 0);
        }
        for c in &chairs {
            let at = generator.occupied_by(ElementKind::Chair, c.index, f.time);
            let (occupied, free) = states(&frame, &c.voxels);
            // Always exactly one of its spots.
            assert!(!at.is_empty());
            assert_eq!((occupied, free), (at.len(), c.voxels.len() - at.len()));
        }
    }
    // People do show up during working hours (3 people x 5 days x 20 slots, mostly present).
    assert!(person_seen > 150, "{person_seen}");
}

#[test]
fn schedule_doors_and_objects_keep_their_rules() {
    let spec = quiet(SeriesSpec {
        step_secs: 3600.0,
        count: 28 * 24,
        doors: 4,
        real_doors: 0,
        people: 0,
        chairs: 0,
        objects: 2,
        object_min_days: 1.0,
        object_max_days: 3.0,
        machines: 0,
        ..SeriesSpec::default()
    });
    let generator = Generator::new(&common::office(), spec, None).unwrap();
    let doors = of_kind(&generator, ElementKind::Door);
    assert_eq!(doors.len(), 4);
    let mut closed_in_hours = 0;
    let mut object_runs: Vec<Vec<(u64, bool)>> = vec![Vec::new(); 2];
    for f in generator.frames() {
        let frame = generator.frame(f.index).unwrap();
        let (day, sod) = (day_number(f.time), second_of_day(f.time));
        let working = is_weekday(day) && (8 * 3600..18 * 3600).contains(&sod);
        for d in &doors {
            let (occupied, free) = states(&frame, &d.voxels);
            let closed = occupied == d.voxels.len();
            assert!(closed || free == d.voxels.len(), "door half closed");
            match d.door_driver.as_ref().unwrap() {
                DoorDriver::MeetingRoom { meetings } => {
                    let in_meeting = meetings.iter().any(|m| {
                        m.weekday == weekday(f.time) && (m.start_secs..m.end_secs).contains(&sod)
                    });
                    assert_eq!(closed, !working || in_meeting, "meeting room at {}", f.time);
                    closed_in_hours += usize::from(working && closed);
                }
                DoorDriver::Corridor => {
                    let open = is_weekday(day) && (7 * 3600..19 * 3600).contains(&sod);
                    assert_eq!(closed, !open, "corridor door at {}", f.time);
                }
                DoorDriver::Office => {
                    // Closed at night on weekdays; open hours lie within working hours.
                    if is_weekday(day) && !working {
                        assert!(closed, "office door open at {}", f.time);
                    }
                }
                DoorDriver::Real { .. } => panic!("no door series given"),
            }
        }
        for (slot, runs) in object_runs.iter_mut().enumerate() {
            let here = !generator
                .occupied_by(ElementKind::Object, slot, f.time)
                .is_empty();
            runs.push((f.index, here));
        }
    }
    // Two doorways (office, meeting room) and two corridor doors.
    let drivers: Vec<_> = doors
        .iter()
        .map(|d| d.door_driver.clone().unwrap())
        .collect();
    assert!(drivers.iter().any(|d| matches!(d, DoorDriver::Office)));
    assert!(drivers
        .iter()
        .any(|d| matches!(d, DoorDriver::MeetingRoom { .. })));
    assert!(
        drivers
            .iter()
            .filter(|d| matches!(d, DoorDriver::Corridor))
            .count()
            == 2
    );
    assert!(
        closed_in_hours > 0,
        "meetings never closed the meeting room"
    );
    // Objects stay between 1 and 3 days (runs cut by the series ends aside), and do come.
    for runs in &object_runs {
        let mut stays = Vec::new();
        let mut current = 0;
        for (i, &(_, here)) in runs.iter().enumerate() {
            if here {
                current += 1;
            }
            if (!here || i == runs.len() - 1) && current > 0 {
                let touches_end = i == runs.len() - 1 || i + 1 == current;
                if !touches_end {
                    stays.push(current);
                }
                current = 0;
            }
        }
        assert!(!stays.is_empty(), "object never came");
        for hours in stays {
            assert!((23..=73).contains(&hours), "stay of {hours} h");
        }
    }
}

#[test]
fn partial_views_only_hide() {
    let spec = SeriesSpec {
        count: 12,
        surface_noise: 0.0,
        partial_probability: 1.0,
        partial_extent: 0.4,
        ..SeriesSpec::default()
    };
    let generator = Generator::new(&common::office(), spec, None).unwrap();
    for i in 0..12 {
        let (frame, stats) = generator.frame_with_stats(i).unwrap();
        let truth = generator.truth_frame(i).unwrap();
        let region = generator.unobserved_region(i).unwrap();
        let mut known = 0u64;
        for (code, state) in frame.voxels() {
            assert_eq!(truth.state_at(code), Some(state), "voxel {code:?} changed");
            let k = code.key();
            assert!(!region.contains([i32::from(k.x), i32::from(k.y), i32::from(k.z)]));
            known += 1;
        }
        let truth_known = truth.voxels().count() as u64;
        assert!(stats.unobserved > 0);
        assert_eq!(known, truth_known - stats.unobserved);
    }
}

#[test]
fn surface_noise_flickers_on_surfaces_for_single_frames() {
    let spec = SeriesSpec {
        count: 4,
        surface_noise: 0.02,
        partial_probability: 0.0,
        doors: 0,
        people: 0,
        chairs: 0,
        objects: 0,
        machines: 0,
        ..SeriesSpec::default()
    };
    let base = common::office();
    let generator = Generator::new(&base, spec, None).unwrap();
    let candidates = generator.change_summary().noise_candidates as f64;
    let flipped = |i: u64| -> Vec<MortonCode> {
        let frame = generator.frame(i).unwrap();
        frame
            .voxels()
            .filter(|&(c, s)| base.state_at(c) != Some(s))
            .map(|(c, _)| c)
            .collect()
    };
    let first = flipped(0);
    let second = flipped(1);
    let expected = candidates * 0.02;
    assert!(
        (first.len() as f64 - expected).abs() < 5.0 * expected.sqrt(),
        "{} flips, {expected} expected",
        first.len()
    );
    // Every flip is next to the opposite state in the base map.
    for &code in &first {
        let k = code.key();
        let state = base.state_at(code).unwrap();
        let has_opposite = [
            (-1i32, 0i32, 0i32),
            (1, 0, 0),
            (0, -1, 0),
            (0, 1, 0),
            (0, 0, -1),
            (0, 0, 1),
        ]
        .iter()
        .any(|&(dx, dy, dz)| {
            let n = froctomap_core::VoxelKey::new(
                (i32::from(k.x) + dx) as u16,
                (i32::from(k.y) + dy) as u16,
                (i32::from(k.z) + dz) as u16,
            );
            base.state_at(n.morton()).is_some_and(|s| s != state)
        });
        assert!(has_opposite, "{code:?} is not on a surface");
    }
    // Flicker: consecutive frames share only chance overlaps (~2 %).
    let common_flips = first
        .iter()
        .filter(|c| second.binary_search(c).is_ok())
        .count();
    assert!(
        common_flips * 10 < first.len(),
        "{common_flips} of {}",
        first.len()
    );
}
