//! Export into one recording (an MCAP file, say) through its format's [`RecordingWriter`]:
//! the maps are made one at a time in time order, each as its canonical `.bt` (the bytes a
//! `.bt` export writes) and its occupied cells with their shades, and handed to the writer,
//! so memory holds one map. The recording goes to a temporary file beside the output,
//! renamed over it once the writer finished.
//!
//! [`RecordingWriter`]: froctomap_formats::RecordingWriter

use crate::error::ConvertError;
use crate::inputs::SeriesInput;
use crate::maps::{observed_bt, predicted_bt};
use crate::outputs::refuse_overwriting_input;
use crate::progress::Progress;
use crate::series_file::SeriesRead;
use froctomap_core::{temporary_beside, AtomicWriteError, Occupancy, Timestamp};
use froctomap_file::{CellContent, FroctReader};
use froctomap_formats::{
    CellShade, ExportedKind, ExportedMap, OccupiedCell, RecordingFormat, RecordingWriteOptions,
};
use rayon::prelude::*;
use std::io::BufWriter;
use std::path::Path;

/// Writes the maps at `times` (retrieved at `samples[i]`, or predicted where `None`) into
/// one recording of `format` at `output`; gives each map's entry (the recording's path at
/// the map's time) and the bytes written.
pub(crate) fn export_recording(
    reader: &dyn SeriesRead,
    output: &Path,
    format: &RecordingFormat,
    write_options: &RecordingWriteOptions,
    times: &[Timestamp],
    samples: &[Option<u32>],
    progress: &dyn Progress,
) -> Result<(Vec<SeriesInput>, u64), ConvertError> {
    let create = format
        .create
        .ok_or_else(|| ConvertError::internal("a recording format without a writer"))?;
    refuse_overwriting_input(output, [reader.path()])?;
    let io = |source| AtomicWriteError {
        path: output.to_path_buf(),
        source,
    };
    let failed = |at: Option<Timestamp>, source| ConvertError::RecordingWrite {
        path: output.to_path_buf(),
        format: format.name,
        at,
        source,
    };
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(output.file_name().unwrap_or_default());
    prefix.push(".");
    let temp = temporary_beside(output, &prefix).map_err(io)?;
    let sink = BufWriter::new(temp.as_file().try_clone().map_err(io)?);
    let mut writer = create(Box::new(sink), write_options).map_err(|e| failed(None, e))?;
    progress.stage("exporting maps", times.len() as u64);
    for (&time, &sample) in times.iter().zip(samples) {
        crate::progress::stop_if_cancelled(progress)?;
        let (bt, kind) = match sample {
            Some(sample) => (
                observed_bt(reader, sample)?,
                ExportedKind::Retrieved { sample },
            ),
            None => (predicted_bt(reader, time)?, ExportedKind::Predicted),
        };
        let occupied = occupied_cells_above(reader, kind, time, write_options.threshold)?;
        let map = ExportedMap::new(time, kind, reader.header().resolution, &bt, &occupied);
        writer.write_map(&map).map_err(|e| failed(Some(time), e))?;
        progress.advance(1);
    }
    writer.finish().map_err(|e| failed(None, e))?;
    temp.as_file().sync_all().map_err(io)?;
    temp.persist(output).map_err(io)?;
    let bytes = std::fs::metadata(output).map(|m| m.len()).unwrap_or(0);
    let files = times
        .iter()
        .map(|&time| SeriesInput::new(output.to_path_buf(), time))
        .collect();
    Ok((files, bytes))
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
