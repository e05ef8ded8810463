//! A map format the converters know nothing about gets the input check and the tiled,
//! parallel writing of retrieval through its descriptor's hooks (`MapFormat::header`,
//! `MapFormat::tiled_writer`), as OctoMap's `.bt` does.
//!
//! The toy format is text: `toy map`, `res R`, then one leaf per line, `START DEPTH o|f`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::{frame, time, RESOLUTION};
use froctomap_convert::{
    build, export, observed_map, write_observed_map, write_predicted_map, BuildOptions, Context,
    ConvertError, ExportMode, ExportOptions, SeriesInput, SeriesRead, Silent,
};
use froctomap_core::{voxels_per_node, Leaf, MortonCode, Occupancy, Snapshot};
use froctomap_file::FroctReader;
use froctomap_formats::{
    Backend, Capabilities, Confidence, FormatRegistry, MapFormat, MapHeader, MapPartWriter,
    MapReader, MapWriter, PluginError, ReadMap, ReadOptions, TiledMapWriter, WriteOptions,
    WrittenPart,
};
use froctomap_temporal::ModelRegistry;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

const MAGIC: &[u8] = b"toy map\n";

/// Parts started by the toy's tiled writer (only the retrieval test writes toy maps).
static PARTS: AtomicUsize = AtomicUsize::new(0);
/// Headers read by the toy's header hook.
static HEADERS: AtomicUsize = AtomicUsize::new(0);

const TOY: MapFormat = MapFormat {
    name: "toy",
    description: "a test's text map format",
    backend: Backend::Native,
    extensions: &["toy"],
    probe: |bytes| match bytes.starts_with(MAGIC) {
        true => Confidence::Certain,
        false => Confidence::No,
    },
    reader: Some(|| Box::new(ToyReader)),
    writer: Some(|| Box::new(ToyWriter)),
    differ: None,
    header: Some(toy_header),
    tiled_writer: Some(|| Box::new(ToyTiledWriter)),
    capabilities: Capabilities::NONE.with_states_only(),
};

fn toy_header(bytes: &[u8]) -> Option<MapHeader> {
    HEADERS.fetch_add(1, Ordering::Relaxed);
    let text = std::str::from_utf8(bytes.strip_prefix(MAGIC)?).ok()?;
    let resolution = text.lines().next()?.strip_prefix("res ")?.parse().ok()?;
    Some(MapHeader::new(resolution))
}

struct ToyReader;

impl MapReader for ToyReader {
    fn read(&self, bytes: &[u8]) -> Result<ReadMap, PluginError> {
        let resolution = toy_header(bytes).ok_or("no toy header")?.resolution;
        let text = std::str::from_utf8(&bytes[MAGIC.len()..])?;
        let mut leaves = Vec::new();
        for line in text.lines().skip(1) {
            let mut fields = line.split(' ');
            let (Some(start), Some(depth), Some(state), None) =
                (fields.next(), fields.next(), fields.next(), fields.next())
            else {
                return Err(format!("not a leaf: {line:?}").into());
            };
            let state = match state {
                "o" => Occupancy::Occupied,
                "f" => Occupancy::Free,
                _ => return Err(format!("not a state: {state:?}").into()),
            };
            leaves.push(Leaf {
                start: MortonCode(start.parse()?),
                depth: depth.parse()?,
                log_odds: state.log_odds(),
            });
        }
        let node_count = leaves.len() as u64;
        Ok(ReadMap {
            snapshot: Snapshot::from_leaves(resolution, leaves)?,
            node_count,
            warnings: Vec::new(),
        })
    }
}

/// The toy text of leaves' states.
fn toy_text(resolution: f64, leaves: &[Leaf], out: &mut dyn Write) -> std::io::Result<()> {
    out.write_all(MAGIC)?;
    writeln!(out, "res {resolution}")?;
    for leaf in leaves {
        let state = match leaf.occupancy() {
            Occupancy::Occupied => 'o',
            Occupancy::Free => 'f',
        };
        writeln!(out, "{} {} {state}", leaf.start.0, leaf.depth)?;
    }
    Ok(())
}

struct ToyWriter;

impl MapWriter for ToyWriter {
    fn write(&self, snapshot: &Snapshot, out: &mut dyn Write) -> Result<(), PluginError> {
        Ok(toy_text(snapshot.resolution(), snapshot.leaves(), out)?)
    }
}

/// Parts are the leaves of a node; the join makes the map canonical, so that the file is the
/// one [`ToyWriter`] writes for the map reduced and split as the converters hand it over.
struct ToyTiledWriter;

struct ToyPart {
    node: std::ops::Range<u64>,
    leaves: Vec<Leaf>,
}

impl TiledMapWriter for ToyTiledWriter {
    fn part(&self, start: MortonCode, depth: u8) -> Result<Box<dyn MapPartWriter>, PluginError> {
        PARTS.fetch_add(1, Ordering::Relaxed);
        let node = start.0..start.0 + voxels_per_node(depth);
        Ok(Box::new(ToyPart {
            node,
            leaves: Vec::new(),
        }))
    }

    fn join(
        &self,
        resolution: f64,
        parts: Vec<WrittenPart>,
        out: &mut dyn Write,
    ) -> Result<u64, PluginError> {
        let mut leaves = Vec::new();
        for part in parts {
            let part = part.downcast::<Vec<Leaf>>().map_err(|_| "not a toy part")?;
            leaves.extend_from_slice(&part);
        }
        let map = Snapshot::from_leaves(resolution, leaves)?.into_canonical();
        toy_text(resolution, map.leaves(), out)?;
        Ok(map.leaves().len() as u64)
    }
}

impl MapPartWriter for ToyPart {
    fn push(&mut self, start: MortonCode, depth: u8, state: Occupancy) -> Result<(), PluginError> {
        let end = start.0 + voxels_per_node(depth);
        let after = self
            .leaves
            .last()
            .map_or(self.node.start, |l| l.start.0 + voxels_per_node(l.depth));
        if start.0 < after || end > self.node.end {
            return Err(format!("leaf at {} out of order or outside the part", start.0).into());
        }
        self.leaves.push(Leaf {
            start,
            depth,
            log_odds: state.log_odds(),
        });
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<WrittenPart, PluginError> {
        Ok(Box::new(self.leaves))
    }
}

fn toy_context(format: MapFormat) -> Context {
    let mut formats = FormatRegistry::new();
    formats.register(format).unwrap();
    Context::new(formats, ModelRegistry::with_default_models())
}

/// Frames `0..n` of the room as toy files; `resolution` gives each one's.
fn toy_series(dir: &Path, n: u32, resolution: impl Fn(u32) -> f64) -> Vec<SeriesInput> {
    (0..n)
        .map(|i| {
            let map = frame(i);
            let path = dir.join(format!("room{i:02}.toy"));
            let mut bytes = Vec::new();
            toy_text(resolution(i), map.leaves(), &mut bytes).unwrap();
            std::fs::write(&path, bytes).unwrap();
            SeriesInput::new(path, time(i))
        })
        .collect()
}

/// The toy's header gives the resolution before any file is decoded: a stray first file of
/// another resolution is told from the majority, as with `.bt`. Without the hook the first
/// file read sets the series' resolution and the build fails on the others.
#[test]
fn the_header_hook_checks_inputs_before_they_are_decoded() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = toy_series(dir.path(), 5, |i| if i == 0 { 0.2 } else { RESOLUTION });
    let out = dir.path().join("room.froct");
    let context = toy_context(TOY);
    let headers_before = HEADERS.load(Ordering::Relaxed);
    let strict = build(&context, &inputs, &out, &BuildOptions::default(), &Silent).unwrap_err();
    match strict {
        ConvertError::MixedResolution {
            first,
            first_resolution,
            second,
            second_resolution,
        } => {
            assert_eq!(
                (first, second),
                (inputs[1].path.clone(), inputs[0].path.clone())
            );
            assert_eq!((first_resolution, second_resolution), (RESOLUTION, 0.2));
        }
        other => panic!("{other:?}"),
    }
    assert!(HEADERS.load(Ordering::Relaxed) >= headers_before + inputs.len());
    assert!(!out.exists());

    let skip_bad = BuildOptions {
        skip_bad: true,
        ..Default::default()
    };
    let report = build(&context, &inputs, &out, &skip_bad, &Silent).unwrap();
    assert_eq!(report.used, 4);
    assert_eq!(report.skipped.len(), 1);
    assert_eq!(report.skipped[0].path, inputs[0].path);
    assert_eq!(report.skipped[0].code(), "resolution-mismatch");
    assert_eq!(
        report.skipped[0].message,
        "resolution 0.2 m differs from the series' 0.1 m"
    );
    assert_eq!(
        FroctReader::open(&out).unwrap().header().resolution,
        RESOLUTION
    );

    // The same format without the hook: the stray first file decides, 4 of 5 are refused.
    let headless = toy_context(MapFormat {
        header: None,
        ..TOY
    });
    let out = dir.path().join("headless.froct");
    match build(&headless, &inputs, &out, &skip_bad, &Silent).unwrap_err() {
        ConvertError::MostlySkipped { skipped, .. } => assert_eq!(skipped.len(), 4),
        other => panic!("{other:?}"),
    }
}

/// Retrieval and export write the toy format through its tiled writer, one part per tile of
/// the file, and the file holds the map the toy's whole-map writer writes: the input frame's
/// states.
#[test]
fn the_tiled_writer_hook_writes_retrieved_maps_tile_by_tile() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = toy_series(dir.path(), 4, |_| RESOLUTION);
    let out = dir.path().join("room.froct");
    let context = toy_context(TOY);
    let options = BuildOptions {
        tile_depth: 13,
        ..Default::default()
    };
    build(&context, &inputs, &out, &options, &Silent).unwrap();
    let reader = FroctReader::open(&out).unwrap();
    let registry = context.formats();
    let read = |path: &Path| {
        registry
            .read_file(path, ReadOptions::default())
            .unwrap()
            .map
            .snapshot
    };

    for sample in 0..4u32 {
        let tiles = reader.observed_tiles(sample).len();
        assert!(tiles > 8, "the room spans many depth-13 tiles: {tiles}");
        let tiled = dir.path().join(format!("tiled{sample}.toy"));
        let parts_before = PARTS.load(Ordering::Relaxed);
        let written =
            write_observed_map(&context, &reader, sample, &tiled, WriteOptions::default()).unwrap();
        assert_eq!(PARTS.load(Ordering::Relaxed) - parts_before, tiles);
        // The whole map, reduced and split as the converters hand it to a writer.
        let whole = dir.path().join(format!("whole{sample}.toy"));
        let map = observed_map(&reader, sample).unwrap();
        registry
            .write_file(
                &map.to_max_likelihood().canonical(),
                &whole,
                WriteOptions::default(),
            )
            .unwrap();
        assert_eq!(
            std::fs::read(&tiled).unwrap(),
            std::fs::read(&whole).unwrap()
        );
        let back = read(&tiled);
        assert_eq!(written.leaves, back.leaves().len());
        assert!(back.same_voxel_states(&frame(sample)), "sample {sample}");
    }

    // A prediction goes the same way.
    let predicted = dir.path().join("predicted.toy");
    let parts_before = PARTS.load(Ordering::Relaxed);
    write_predicted_map(
        &context,
        &reader,
        time(1),
        &predicted,
        WriteOptions::default(),
    )
    .unwrap();
    assert_eq!(
        PARTS.load(Ordering::Relaxed) - parts_before,
        reader.predicted_tiles().len()
    );
    assert!(!read(&predicted).is_empty());

    // Export writes its maps in parallel through the hook; a copy of the format without it
    // writes whole maps, the same bytes.
    let export_options = ExportOptions {
        from: time(0),
        to: time(3),
        every_ns: 3_600_000_000_000,
        mode: ExportMode::Retrieve,
        format: "toy".into(),
        backend: None,
        prefix: "room".into(),
        overwrite: false,
        recording: Default::default(),
    };
    let exported = |context: &Context, name: &str| -> Vec<PathBuf> {
        let dir = dir.path().join(name);
        export(context, &reader, &dir, &export_options, &Silent)
            .unwrap()
            .files
            .into_iter()
            .map(|f| f.path)
            .collect()
    };
    let parts_before = PARTS.load(Ordering::Relaxed);
    let tiled = exported(&context, "tiled");
    assert!(PARTS.load(Ordering::Relaxed) > parts_before);
    let untiled = toy_context(MapFormat {
        tiled_writer: None,
        ..TOY
    });
    let whole = exported(&untiled, "whole");
    assert_eq!(tiled.len(), 4);
    for (a, b) in tiled.iter().zip(&whole) {
        assert_eq!(std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
    }
}
