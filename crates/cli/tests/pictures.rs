//! `render`, `history` and the `info` additions on a generated series whose doors the
//! generator knows: pictures are checked pixel by pixel against the input snapshots, the
//! door column against the generator's door, the voxel history against the frames.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_convert::{Context, TimeQuery};
use froctomap_core::{MortonCode, Occupancy, Snapshot, Timestamp, VoxelKey, KEY_ORIGIN};
use froctomap_formats::{ReadOptions, WriteOptions};
use froctomap_render::{
    is_occupied_shade, render_dynamics, render_map, MapFrame, MapTime, Picture, View, FREE,
    OCCUPIED_HIGH, PERIOD_HUES, UNKNOWN,
};
use froctomap_synth::{ElementKind, Generator, SeriesSpec, SpecOverrides};
use serde_json::Value;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

mod common;
use common::{fails, ok, s};

const RESOLUTION: f64 = 0.1;
const DAYS: f64 = 4.0;
const SEED: u64 = 3;
/// One door, schedules only, no people, objects, machines, noise or partial views.
const SCENARIO: &str = r#"{"doors": 1, "real_doors": 0, "people": 0, "chairs": 0,
    "objects": 0, "machines": 0, "surface_noise": 0.0, "partial_probability": 0.0}"#;

/// An 8 x 5 m floor at 0.1 m, 2.4 m high, without a ceiling: a corridor (y 0..2 m) behind
/// a wall with one doorway (x 3..3.9 m), two rooms; the far corner of the second room was
/// never seen (unknown).
fn office() -> Snapshot {
    let (nx, ny, nz) = (80u16, 50u16, 24u16);
    let mut voxels = Vec::new();
    for x in 0..nx {
        for y in 0..ny {
            if x >= 65 && y >= 40 {
                continue; // never observed
            }
            for z in 0..nz {
                let outer = x == 0 || x == nx - 1 || y == 0 || y == ny - 1;
                let doorway = (30..39).contains(&x) && z <= 20;
                let corridor_wall = y == 20 && !doorway;
                let room_wall = x == 55 && y > 20;
                let solid = z == 0 || outer || corridor_wall || room_wall;
                let key = VoxelKey::new(32768 + x, 32768 + y, 32768 + z);
                voxels.push((key.morton(), Occupancy::from(solid)));
            }
        }
    }
    Snapshot::from_voxel_states(RESOLUTION, voxels).unwrap()
}

struct Series {
    _dir: tempfile::TempDir,
    froct: PathBuf,
    base: PathBuf,
    generator: Generator,
    /// Frame files by time.
    frames: Vec<(Timestamp, PathBuf)>,
}

/// `generate` from the office, then `build`, once for every test.
fn series() -> &'static Series {
    static SERIES: OnceLock<Series> = OnceLock::new();
    SERIES.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let context = Context::with_default_plugins();
        let base = dir.path().join("office.bt");
        context
            .formats()
            .write_file(&office(), &base, WriteOptions::default())
            .unwrap();
        let scenario = dir.path().join("scenario.json");
        std::fs::write(&scenario, SCENARIO).unwrap();
        let out = dir.path().join("series");
        let seed = SEED.to_string();
        let days = DAYS.to_string();
        ok(&[
            "generate",
            "--base",
            s(&base),
            "--days",
            &days,
            "--step",
            "1h",
            "--seed",
            &seed,
            "--spec",
            s(&scenario),
            "-o",
            s(&out),
            "--quiet",
        ]);
        let froct = dir.path().join("office.froct");
        ok(&["build", s(&out), "-o", s(&froct), "--quiet"]);
        // The same scenario, for where the generator put its door.
        let spec = SpecOverrides {
            step_secs: Some(3600.0),
            days: Some(DAYS),
            seed: Some(SEED),
            jitter_secs: Some(0.0),
            missed_frames: Some(0.0),
            ..SpecOverrides::default()
        }
        .apply(serde_json::from_str::<SeriesSpec>(SCENARIO).unwrap())
        .unwrap();
        let generator = Generator::new(&office(), spec, None).unwrap();
        let mut frames: Vec<(Timestamp, PathBuf)> = generator
            .frames()
            .map(|f| {
                let name = format!(
                    "frame_{}.bt",
                    froctomap_core::calendar::iso8601_basic(f.time)
                );
                (f.time, out.join(name))
            })
            .collect();
        frames.sort();
        assert!(frames.iter().all(|(_, p)| p.exists()), "frame names");
        Series {
            _dir: dir,
            froct,
            base,
            generator,
            frames,
        }
    })
}

fn read_map(path: &Path) -> Snapshot {
    Context::with_default_plugins()
        .formats()
        .read_file(path, ReadOptions::default())
        .unwrap()
        .map
        .snapshot
}

fn door_voxels(generator: &Generator) -> Vec<MortonCode> {
    let doors: Vec<_> = generator
        .elements()
        .into_iter()
        .filter(|e| e.kind == ElementKind::Door)
        .collect();
    assert_eq!(doors.len(), 1, "{:?}", generator.warnings());
    doors[0].voxels.clone()
}

/// Key column (x, y) of a metric point.
fn column_of(point: [f64; 2]) -> Option<(u32, u32)> {
    let key = |v: f64| {
        let k = v / RESOLUTION;
        // Too close to a voxel border to say which column a pixel centre falls in.
        ((k - k.round()).abs() > 1e-6).then(|| (k.floor() as i64 + i64::from(KEY_ORIGIN)) as u32)
    };
    Some((key(point[0])?, key(point[1])?))
}

/// Per key column of a map: (any occupied, any known), for every height or one z key.
fn columns(map: &Snapshot, z: Option<u32>) -> HashMap<(u32, u32), bool> {
    let mut out: HashMap<(u32, u32), bool> = HashMap::new();
    for leaf in map.leaves() {
        let lo = leaf.min_key();
        let edge = leaf.edge_voxels();
        if let Some(z) = z {
            if !(u32::from(lo.z)..u32::from(lo.z) + edge).contains(&z) {
                continue;
            }
        }
        for x in u32::from(lo.x)..u32::from(lo.x) + edge {
            for y in u32::from(lo.y)..u32::from(lo.y) + edge {
                *out.entry((x, y)).or_default() |= leaf.occupancy() == Occupancy::Occupied;
            }
        }
    }
    out
}

fn pixel(picture: &Picture, px: u32, py: u32) -> [u8; 3] {
    picture.image().get_pixel(px, py).0
}

/// Every map pixel against the column under it: occupied columns in the occupied shades,
/// known free ones free, the rest unknown. Returns how many pixels of each were seen.
fn check_against(
    picture: &Picture,
    expected: &HashMap<(u32, u32), bool>,
    slice: bool,
) -> [usize; 3] {
    let frame: MapFrame = *picture.frame().unwrap();
    let mut seen = [0; 3];
    for py in frame.top..frame.top + frame.height {
        for px in frame.left..frame.left + frame.width {
            let Some(column) = column_of(frame.point_at(px, py).unwrap()) else {
                continue;
            };
            let colour = pixel(picture, px, py);
            match expected.get(&column) {
                Some(true) => {
                    if slice {
                        assert_eq!(colour, OCCUPIED_HIGH, "{column:?}");
                    } else {
                        assert!(is_occupied_shade(colour), "{column:?}: {colour:?}");
                    }
                    seen[0] += 1;
                }
                Some(false) => {
                    assert_eq!(colour, FREE, "{column:?}");
                    seen[1] += 1;
                }
                None => {
                    assert_eq!(colour, UNKNOWN, "{column:?}");
                    seen[2] += 1;
                }
            }
        }
    }
    seen
}

#[test]
fn the_top_down_picture_shows_the_snapshot_column_by_column() {
    let series = series();
    let reader = Context::with_default_plugins()
        .open_froct(&series.froct)
        .unwrap();
    let (time, frame_file) = &series.frames[30];
    let when = MapTime::choose(&reader, TimeQuery::Instant(*time)).unwrap();
    assert!(
        matches!(when, MapTime::Retrieved { sample: 30, .. }),
        "{when:?}"
    );
    let picture = render_map(&reader, when, View::TopDown, 1200).unwrap();
    assert_eq!(picture.image().width(), 1200);
    let frame = picture.frame().unwrap();
    // The map keeps its shape: 8 x 5 m.
    let aspect = f64::from(frame.width) / f64::from(frame.height);
    assert!((aspect - 8.0 / 5.0).abs() < 0.01, "{frame:?}");
    let seen = check_against(&picture, &columns(&read_map(frame_file), None), false);
    // Every known column has a floor: occupied and unknown columns, no free one.
    assert!(seen[0] > 1000 && seen[2] > 1000, "{seen:?}");
    // Walls are darker than the floor alone.
    let wall = frame.pixel_at(0.05, 2.55).unwrap();
    let floor = frame.pixel_at(1.05, 1.05).unwrap();
    assert!(pixel(&picture, wall.0, wall.1)[0] < pixel(&picture, floor.0, floor.1)[0]);

    // The command writes the same picture, atomically, at the width asked for.
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("map.png");
    let at = froctomap_core::calendar::iso8601(*time);
    ok(&[
        "render",
        s(&series.froct),
        "--time",
        &at,
        "-o",
        s(&png),
        "--quiet",
    ]);
    let written = image::open(&png).unwrap().to_rgb8();
    assert_eq!(&written, picture.image());
    ok(&[
        "render",
        s(&series.froct),
        "--time",
        &at,
        "-o",
        s(&png),
        "--width",
        "500",
    ]);
    assert_eq!(image::open(&png).unwrap().width(), 500);
    let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(leftovers.len(), 1);
}

#[test]
fn a_slice_shows_the_voxels_at_that_height() {
    let series = series();
    let reader = Context::with_default_plugins()
        .open_froct(&series.froct)
        .unwrap();
    let (time, frame_file) = &series.frames[12];
    let when = MapTime::choose(&reader, TimeQuery::Instant(*time)).unwrap();
    let picture = render_map(&reader, when, View::slice("z=1.05").unwrap(), 800).unwrap();
    let z = (1.05f64 / RESOLUTION).floor() as u32 + KEY_ORIGIN as u32;
    let seen = check_against(&picture, &columns(&read_map(frame_file), Some(z)), true);
    assert!(seen.iter().all(|&n| n > 100), "{seen:?}");
}

#[test]
fn outside_the_span_the_picture_is_the_prediction() {
    let series = series();
    let context = Context::with_default_plugins();
    let reader = context.open_froct(&series.froct).unwrap();
    let end = reader.header().axis.end();
    let later = Timestamp(end.0 + 3 * 86_400_000_000_000);
    let when = MapTime::choose(&reader, TimeQuery::Instant(later)).unwrap();
    assert_eq!(when, MapTime::Predicted(later));
    let picture = render_map(&reader, when, View::TopDown, 1000).unwrap();
    let predicted = froctomap_convert::predicted_map(&reader, later).unwrap();
    check_against(&picture, &columns(&predicted.canonical(), None), false);
}

#[test]
fn the_door_is_coloured_as_dynamic_and_walls_grey() {
    let series = series();
    let reader = Context::with_default_plugins()
        .open_froct(&series.froct)
        .unwrap();
    let picture = render_dynamics(&reader, 1200).unwrap();
    let frame = picture.frame().unwrap();
    let door: HashSet<(u16, u16)> = door_voxels(&series.generator)
        .iter()
        .map(|v| (v.key().x, v.key().y))
        .collect();
    assert!(!door.is_empty());
    for &(x, y) in &door {
        let centre = VoxelKey::new(x, y, 32768).center(RESOLUTION);
        let (px, py) = frame.pixel_at(centre[0], centre[1]).unwrap();
        let colour = pixel(&picture, px, py);
        // The only dynamic thing is the door, so it takes the first hue, tinted by how
        // often it is closed: blue above green above red, like PERIOD_HUES[0].
        let hue = PERIOD_HUES[0];
        assert!(hue[2] > hue[1] && hue[1] > hue[0]);
        assert!(
            colour[2] > colour[1] && colour[1] > colour[0],
            "door column ({x}, {y}): {colour:?}"
        );
    }
    for (x, y) in [(0.05, 1.0), (5.55, 3.5), (1.0, 2.05)] {
        let (px, py) = frame.pixel_at(x, y).unwrap();
        assert!(
            is_occupied_shade(pixel(&picture, px, py)),
            "wall at ({x}, {y})"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("changes.png");
    ok(&["render", s(&series.froct), "--dynamics", "-o", s(&png)]);
    assert_eq!(&image::open(&png).unwrap().to_rgb8(), picture.image());
}

#[test]
fn history_of_a_door_voxel_recovers_its_daily_period() {
    let series = series();
    let door = door_voxels(&series.generator);
    let voxel = door[door.len() / 2];
    let c = voxel.key().center(RESOLUTION);
    let at = format!("--at={},{},{}", c[0], c[1], c[2]);
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("voxel.png");
    let json: Value = serde_json::from_str(&ok(&[
        "history",
        s(&series.froct),
        &at,
        "--json",
        "-o",
        s(&png),
    ]))
    .unwrap();
    assert_eq!(json["class"], "dynamic");
    let period = json["model"]["periodic"][0]["period_seconds"]
        .as_f64()
        .unwrap();
    assert!(
        (period - 86_400.0).abs() < 1.0,
        "strongest period {period} s"
    );
    assert_eq!(json["model"]["periodic"][0]["period"], "1 day");
    // Every sample's state is the frame's, and the outliers are where p disagrees.
    let samples = json["samples"].as_array().unwrap();
    assert_eq!(samples.len(), series.frames.len());
    for (sample, (_, file)) in samples.iter().zip(&series.frames) {
        let state = match read_map(file).state_at(voxel) {
            Some(Occupancy::Occupied) => Value::from("occupied"),
            Some(Occupancy::Free) => Value::from("free"),
            None => Value::Null,
        };
        assert_eq!(sample["state"], state);
        let p = sample["p"].as_f64().unwrap();
        let disagrees = (state == "occupied") != (p > 0.5);
        assert_eq!(sample["outlier"], Value::from(disagrees), "{sample}");
    }
    let plot = image::open(&png).unwrap();
    assert_eq!((plot.width(), plot.height()), (1000, 620));
    // The table says the same.
    let table = ok(&["history", s(&series.froct), &at]);
    assert!(table.contains("class:     dynamic"), "{table}");
    assert!(table.contains("strongest first: 1 day"), "{table}");
}

#[test]
fn info_gives_bounds_periods_and_the_door_as_a_dynamic_region() {
    let series = series();
    let info: Value = serde_json::from_str(&ok(&["info", s(&series.froct), "--json"])).unwrap();
    let bounds = office().known_bounds().unwrap();
    for a in 0..3 {
        assert!((info["bounds_m"]["min"][a].as_f64().unwrap() - bounds.min[a]).abs() < 1e-9);
        assert!((info["bounds_m"]["max"][a].as_f64().unwrap() - bounds.max[a]).abs() < 1e-9);
    }
    let periods = info["periods"].as_array().unwrap();
    assert_eq!(periods[0]["period"], "1 day", "{periods:?}");
    let door = door_voxels(&series.generator);
    let region = &info["dynamic_regions"][0];
    for v in &door {
        let c = v.key().center(RESOLUTION);
        for a in 0..3 {
            let (lo, hi) = (
                region["min"][a].as_f64().unwrap(),
                region["max"][a].as_f64().unwrap(),
            );
            assert!(lo < c[a] && c[a] < hi, "door voxel {c:?} outside {region}");
        }
    }
    let text = ok(&["info", s(&series.froct)]);
    assert!(
        text.contains("bounds:          x [0.00, 8.00]  y [0.00, 5.00]"),
        "{text}"
    );
    assert!(text.contains("dynamic regions: "), "{text}");
}

#[test]
fn bad_inputs_get_clear_errors() {
    let series = series();
    let f = s(&series.froct);
    let outside = fails(&["history", f, "--at", "50,50,1"]);
    assert!(outside.contains("no cell at (50, 50, 1) m"), "{outside}");
    let later = fails(&[
        "history",
        f,
        "--at",
        "1,1,0.05",
        "--from",
        "2030-01-01T00:00:00Z",
    ]);
    assert!(later.contains("no sample between"), "{later}");
    assert!(fails(&["history", f, "--at", "1,1"]).contains("X,Y,Z"));
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("x.png");
    assert!(fails(&[
        "render",
        f,
        "--time",
        "last",
        "--slice",
        "y=1",
        "-o",
        s(&png)
    ])
    .contains("expected z=HEIGHT"));
    assert!(fails(&[
        "render",
        f,
        "--time",
        "last",
        "--slice",
        "z=40",
        "-o",
        s(&png)
    ])
    .contains("outside the map's heights"));
    assert!(fails(&[
        "render",
        f,
        "--time",
        "last",
        "--width",
        "20",
        "-o",
        s(&png)
    ])
    .contains("picture width 20 px"));
    let before = std::fs::read(f).unwrap();
    assert!(fails(&["render", f, "--dynamics", "-o", f]).contains("destroy the input"));
    assert_eq!(std::fs::read(f).unwrap(), before);
    let map = fails(&["render", s(&series.base), "--dynamics", "-o", s(&png)]);
    assert!(map.contains("map file"), "{map}");
    assert!(!png.exists());
}

/// `FROCTOMAP_FONT` is the user's choice: a file that is not a font, or no file, stops
/// `render` with the variable and the file named, and no picture, rather than drawing with
/// another font.
#[test]
fn a_font_variable_naming_no_font_is_an_error() {
    let series = series();
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("x.png");
    let not_a_font = dir.path().join("notes.ttf");
    std::fs::write(&not_a_font, "not a font\n").unwrap();
    for (font, problem) in [
        (not_a_font.clone(), "not a TrueType font"),
        (dir.path().join("missing.ttf"), "No such file"),
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_froctomap"))
            .args(["render", s(&series.froct), "--time", "last", "-o", s(&png)])
            .env("FROCTOMAP_FONT", &font)
            .stdin(std::process::Stdio::null())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{stderr}");
        let named = format!("FROCTOMAP_FONT={}", font.display());
        assert!(
            stderr.contains(&named) && stderr.contains(problem),
            "{stderr}"
        );
        assert!(!png.exists());
    }
}
