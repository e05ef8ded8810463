//! Export into one recording (an MCAP file, say) through its format's [`RecordingWriter`]:
//! the maps are made one at a time in time order, each as its canonical `.bt` (the bytes a
//! `.bt` export writes) and its occupied cells with their shades, and handed to the writer,
//! so memory holds one map. The recording goes to a temporary file beside the output,
//! renamed over it once the writer finished; a recording that is a directory (a ROS 2 bag)
//! to a temporary directory beside it, renamed to it once complete (a directory already
//! there is refused, never replaced).
//!
//! [`RecordingWriter`]: froctomap_formats::RecordingWriter

use crate::error::ConvertError;
use crate::inputs::SeriesInput;
use crate::maps::{observed_bt, predicted_bt};
use crate::outputs::refuse_overwriting_input;
use crate::progress::Progress;
use crate::series_file::SeriesRead;
use froctomap_core::{
    temporary_beside, temporary_dir_beside, AtomicWriteError, Occupancy, Timestamp,
};
use froctomap_file::{CellContent, FroctReader};
use froctomap_formats::{
    CellShade, CreateRecording, CreateRecordingDir, ExportedKind, ExportedMap, OccupiedCell,
    PluginError, RecordingDir, RecordingFormat, RecordingSink, RecordingWriteOptions,
    RecordingWriter,
};
use rayon::prelude::*;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Writes the maps at `times` (retrieved at `samples[i]`, or predicted where `None`) into
/// one recording of `format` at `output`: a file through its
/// [`create`](RecordingFormat::create), else a new directory through its
/// [`create_dir`](RecordingFormat::create_dir); gives each map's entry (the recording's
/// path at the map's time) and the bytes written.
pub(crate) fn export_recording(
    reader: &dyn SeriesRead,
    output: &Path,
    format: &RecordingFormat,
    write_options: &RecordingWriteOptions,
    times: &[Timestamp],
    samples: &[Option<u32>],
    progress: &dyn Progress,
) -> Result<(Vec<SeriesInput>, u64), ConvertError> {
    refuse_overwriting_input(output, [reader.path()])?;
    let maps = Maps {
        reader,
        output,
        format,
        write_options,
        times,
        samples,
        progress,
    };
    let bytes = match (format.create, format.create_dir) {
        (Some(create), _) => maps.into_file(create)?,
        (None, Some(create_dir)) => maps.into_dir(create_dir)?,
        (None, None) => {
            return Err(ConvertError::internal(
                "a recording format without a writer",
            ))
        }
    };
    let files = times
        .iter()
        .map(|&time| SeriesInput::new(output.to_path_buf(), time))
        .collect();
    Ok((files, bytes))
}

/// The maps of an export into a recording, and where they go.
struct Maps<'a> {
    reader: &'a dyn SeriesRead,
    output: &'a Path,
    format: &'a RecordingFormat,
    write_options: &'a RecordingWriteOptions,
    times: &'a [Timestamp],
    samples: &'a [Option<u32>],
    progress: &'a dyn Progress,
}

impl Maps<'_> {
    /// The recording's writer failed (at the map for `at`).
    fn failed(&self, at: Option<Timestamp>, source: PluginError) -> ConvertError {
        ConvertError::RecordingWrite {
            path: self.output.to_path_buf(),
            format: self.format.name,
            at,
            source,
        }
    }

    fn io(&self, source: std::io::Error) -> AtomicWriteError {
        AtomicWriteError {
            path: self.output.to_path_buf(),
            source,
        }
    }

    /// Into a temporary file beside the output, renamed over it; the bytes written.
    fn into_file(self, create: CreateRecording) -> Result<u64, ConvertError> {
        let mut prefix = std::ffi::OsString::from(".");
        prefix.push(self.output.file_name().unwrap_or_default());
        prefix.push(".");
        let temp = temporary_beside(self.output, &prefix).map_err(|e| self.io(e))?;
        let sink = BufWriter::new(temp.as_file().try_clone().map_err(|e| self.io(e))?);
        let writer =
            create(Box::new(sink), self.write_options).map_err(|e| self.failed(None, e))?;
        self.write_all(writer)?;
        temp.as_file().sync_all().map_err(|e| self.io(e))?;
        temp.persist(self.output).map_err(|e| self.io(e))?;
        Ok(std::fs::metadata(self.output).map_or(0, |m| m.len()))
    }

    /// Into a temporary directory beside the output, renamed to it (which must not exist);
    /// the bytes of its files.
    fn into_dir(self, create_dir: CreateRecordingDir) -> Result<u64, ConvertError> {
        if self.output.symlink_metadata().is_ok() {
            return Err(ConvertError::OutputExists {
                path: self.output.to_path_buf(),
            });
        }
        let temp = temporary_dir_beside(self.output).map_err(|e| self.io(e))?;
        let dir = NewFiles {
            dir: temp.path().to_path_buf(),
            name: self
                .output
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned(),
        };
        let writer =
            create_dir(Box::new(dir), self.write_options).map_err(|e| self.failed(None, e))?;
        self.write_all(writer)?;
        let bytes = dir_bytes(temp.path());
        temp.persist_new(self.output).map_err(|source| {
            if source.kind() == std::io::ErrorKind::AlreadyExists {
                ConvertError::OutputExists {
                    path: self.output.to_path_buf(),
                }
            } else {
                self.io(source).into()
            }
        })?;
        Ok(bytes)
    }

    /// Makes each map and hands it to `writer`, then finishes the recording.
    fn write_all(&self, mut writer: Box<dyn RecordingWriter>) -> Result<(), ConvertError> {
        let reader = self.reader;
        self.progress
            .stage("exporting maps", self.times.len() as u64);
        for (&time, &sample) in self.times.iter().zip(self.samples) {
            crate::progress::stop_if_cancelled(self.progress)?;
            let (bt, kind) = match sample {
                Some(sample) => (
                    observed_bt(reader, sample)?,
                    ExportedKind::Retrieved { sample },
                ),
                None => (predicted_bt(reader, time)?, ExportedKind::Predicted),
            };
            let occupied = occupied_cells_above(reader, kind, time, self.write_options.threshold)?;
            let map = ExportedMap::new(time, kind, reader.header().resolution, &bt, &occupied);
            writer
                .write_map(&map)
                .map_err(|e| self.failed(Some(time), e))?;
            self.progress.advance(1);
        }
        writer.finish().map_err(|e| self.failed(None, e))
    }
}

/// The files of a directory recording being written: new files in the export's temporary
/// directory.
struct NewFiles {
    dir: PathBuf,
    name: String,
}

impl RecordingDir for NewFiles {
    fn name(&self) -> &str {
        &self.name
    }

    fn create_file(&mut self, name: &str) -> Result<Box<dyn RecordingSink>, PluginError> {
        let plain = Path::new(name).file_name().is_some_and(|n| n == name);
        if !plain {
            return Err(format!("{name:?} is not a plain file name").into());
        }
        let file = std::fs::File::create_new(self.dir.join(name))?;
        Ok(Box::new(BufWriter::new(file)))
    }
}

/// The bytes of the files in `dir` (not in its subdirectories).
fn dir_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .filter_map(Result::ok)
        .filter_map(|entry| entry.metadata().ok())
        .filter(std::fs::Metadata::is_file)
        .map(|m| m.len())
        .sum()
}

/// The occupied cells of the map of `kind` at `time`, in Morton order, with their shades
/// (what an export into a recording draws): a retrieved cell occupied in its observed state
/// at the sample, [`CellShade::Dynamic`] when its state changes over the span (known for a
/// file without segments; a living file's are [`CellShade::Static`] until compacted), a
/// predicted one where `p(t) > 0.5`, with `p`.
pub fn occupied_cells_at(
    reader: &dyn SeriesRead,
    kind: ExportedKind,
    time: Timestamp,
) -> Result<Vec<OccupiedCell>, ConvertError> {
    occupied_cells_above(reader, kind, time, 0.5)
}

/// [`occupied_cells_at`], a predicted cell drawn where `p(t) > threshold` (the export's
/// `--threshold`; retrieved maps are unchanged).
pub fn occupied_cells_above(
    reader: &dyn SeriesRead,
    kind: ExportedKind,
    time: Timestamp,
    threshold: f64,
) -> Result<Vec<OccupiedCell>, ConvertError> {
    match reader.whole_body() {
        Some(whole) => occupied_cells(whole, kind, time, threshold),
        None => occupied_states(reader, kind, time, threshold),
    }
}

/// The occupied cells of a map of a 2.0 file with segments, whose cells' histories are not in
/// one body: a predicted cell with its `p(t)` (as [`SeriesRead::predicted_leaves`] gives
/// it), a retrieved one as [`CellShade::Static`] (whether it changes is known after
/// `compact`).
fn occupied_states(
    reader: &dyn SeriesRead,
    kind: ExportedKind,
    time: Timestamp,
    threshold: f64,
) -> Result<Vec<OccupiedCell>, ConvertError> {
    let mut occupied = Vec::new();
    match kind {
        ExportedKind::Retrieved { sample } => {
            for tile in 0..reader.observed_tiles(sample).len() {
                reader.visit_observed(sample, tile, &mut |start, depth, state| {
                    if state.is_occupied() {
                        occupied.push(OccupiedCell {
                            start,
                            depth,
                            shade: CellShade::Static,
                        });
                    }
                })?;
            }
        }
        ExportedKind::Predicted => {
            let seconds = time.secs_since(reader.header().axis.start());
            let mut leaves = Vec::new();
            for (code, _) in reader.predicted_tiles() {
                leaves.clear();
                // The probability itself in place of its log-odds.
                reader.predicted_leaves(code, seconds, &|p| p as f32, &mut leaves)?;
                occupied.extend(
                    leaves
                        .iter()
                        .filter(|l| f64::from(l.log_odds) > threshold)
                        .map(|l| OccupiedCell {
                            start: l.start,
                            depth: l.depth,
                            shade: CellShade::Probability(l.log_odds),
                        }),
                );
            }
        }
    }
    Ok(occupied)
}

/// The occupied cells of a map, in Morton order, with their shades: a retrieved cell is
/// occupied in its observed state at the sample (the `.bt`'s occupied leaves), dynamic when
/// its state changes over the span; a predicted one where `p(t) > threshold` (0.5: as the
/// `.bt`).
/// Tiles are walked in parallel, a few at a time.
pub(crate) fn occupied_cells(
    reader: &FroctReader,
    kind: ExportedKind,
    time: Timestamp,
    threshold: f64,
) -> Result<Vec<OccupiedCell>, ConvertError> {
    let axis = &reader.header().axis;
    let model = reader.model();
    let seconds = time.secs_since(axis.start());
    let tiles = reader.tiles();
    let chunk = 4 * rayon::current_num_threads().max(1);
    let mut occupied = Vec::new();
    for (first, entries) in tiles.chunks(chunk).enumerate() {
        let per_tile = entries
            .par_iter()
            .enumerate()
            .map(|(i, entry)| {
                let mut out = Vec::new();
                if let ExportedKind::Retrieved { sample } = kind {
                    if !entry.may_observe(sample) {
                        return Ok(out);
                    }
                }
                reader.visit_cells(first * chunk + i, |cell| {
                    let shade = match kind {
                        ExportedKind::Retrieved { sample } => {
                            if cell.state_at(axis, model, sample) != Some(Occupancy::Occupied) {
                                return;
                            }
                            match cell.content {
                                CellContent::Constant(_) => CellShade::Static,
                                _ => CellShade::Dynamic,
                            }
                        }
                        ExportedKind::Predicted => {
                            let p = cell.probability(model, seconds);
                            if p <= threshold {
                                return;
                            }
                            CellShade::Probability(p as f32)
                        }
                    };
                    out.push(OccupiedCell {
                        start: cell.start,
                        depth: cell.depth,
                        shade,
                    });
                })?;
                Ok(out)
            })
            .collect::<Result<Vec<_>, ConvertError>>()?;
        for tile_cells in per_tile {
            occupied.extend_from_slice(&tile_cells);
        }
    }
    Ok(occupied)
}
