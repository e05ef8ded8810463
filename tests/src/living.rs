//! Format 2.0 files with segments for the tests of the readers and `compact`, written by
//! hand while nothing above the file crate writes segments: each segment holds the maps of a
//! 1.x build of later maps, its cells stored constant with their changes as exceptions over
//! the segment's samples (what an ingest may store for any cell).

use froctomap_core::Occupancy;
use froctomap_file::{
    CellContent, FileError, FroctReader, LivingWriter, SegmentCell, SegmentContent,
};
use froctomap_temporal::Toggles;
use std::path::Path;

/// Commits one segment to the 2.0 file `living` holding the maps of the 1.x file `part` (a
/// build of maps later than `living`'s, with the same tile layout): its axis is the
/// segment's, its cells the segment's cells.
pub fn append_segment_from_build(living: &Path, part: &Path) -> Result<(), FileError> {
    let part = FroctReader::open(part)?;
    let axis = part.header().axis.clone();
    let mut writer = open_writer(living)?;
    let mut segment = writer.begin_segment(axis.clone())?;
    for tile in 0..part.tiles().len() {
        let cells: Vec<SegmentCell> = part
            .read_tile(tile)?
            .into_iter()
            .map(|cell| {
                let content = match &cell.content {
                    CellContent::Constant(state) => SegmentContent::Constant(*state),
                    CellContent::ConstantExcept { state, exceptions } => {
                        SegmentContent::ConstantExcept {
                            state: *state,
                            exceptions: exceptions.clone(),
                        }
                    }
                    CellContent::Modelled(_) => {
                        // The observed states, as the first one flipped at each change.
                        let states: Vec<(u32, Occupancy)> = (0..axis.len())
                            .filter_map(|i| cell.state_at(&axis, part.model(), i).map(|o| (i, o)))
                            .collect();
                        let first = states.first().map_or(Occupancy::Free, |s| s.1);
                        let mut now = first;
                        let mut toggles = Vec::new();
                        for &(i, state) in &states {
                            if state != now {
                                toggles.push(i);
                                now = state;
                            }
                        }
                        SegmentContent::ConstantExcept {
                            state: first,
                            exceptions: Toggles::new(toggles).expect("increasing positions"),
                        }
                    }
                };
                SegmentCell {
                    start: cell.start,
                    depth: cell.depth,
                    mask: cell.mask.clone(),
                    content,
                }
            })
            .collect();
        segment.push_tile(cells)?;
    }
    segment.commit()?;
    Ok(())
}

/// [`LivingWriter::open`], waiting a little while another thread of the test process
/// spawns a program: the child holds a copy of every descriptor until it executes, and so
/// the lock of a writer this thread just dropped.
fn open_writer(living: &Path) -> Result<LivingWriter, FileError> {
    let mut tries = 0;
    loop {
        match LivingWriter::open(living) {
            Err(FileError::Locked { .. }) if tries < 200 => {
                tries += 1;
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            result => return result,
        }
    }
}
