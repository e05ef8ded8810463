//! Spill data of a bounded-memory build: the runs an accumulating thread sets aside on disk
//! when its histories outgrow their share of the memory budget, read back tile by tile.
//!
//! Each thread writes one file in a [`SpillDir`]. A spill ([`SpillWriter::spill`]) hands out
//! every cell's runs in Morton order ([`SeriesHistory::spill`]); they are appended as one
//! segment per tile, whose place is kept in memory (16 bytes a tile per spill). Reading back
//! ([`SpillReader::runs_for`]) loads one tile's segments at a time and gives each cell of
//! the end the runs spilled for it or for the coarser cell it was split from, oldest spill
//! first — cells only ever get finer, so a spilled cell contains every cell later cut from
//! it.
//!
//! A segment is a list of cells: the cell's offset in its tile and depth, its number of
//! runs, then each run as varints (samples since the previous run's end, `len << 1 | state`).
//! The files are this build's own, but are still read with checks: damage gives an error,
//! never a panic or a huge allocation.

use crate::error::ConvertError;
use crate::history::{PackedCell, PackedObservations, SeriesHistory};
use froctomap_core::{voxels_per_node, MortonCode, Occupancy, TREE_DEPTH};
use froctomap_temporal::{varint, Run};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The name of every spill directory starts with this.
const SPILL_PREFIX: &str = ".froct-spill-";

/// Where a build spills: a directory in which a [`SpillDir`] is made at the first spill
/// (a build within its budget never writes there), removed when this is dropped.
#[derive(Debug)]
pub(crate) struct SpillPlace {
    parent: PathBuf,
    dir: std::sync::Mutex<Option<SpillDir>>,
}

impl SpillPlace {
    /// Spill data will go into a new directory inside `parent`. The spill directories that
    /// killed builds left there are removed now, whether this build spills or not.
    pub fn new(parent: &Path) -> Self {
        froctomap_core::remove_stale_temporary_dirs(parent, SPILL_PREFIX.as_ref());
        Self {
            parent: parent.to_path_buf(),
            dir: std::sync::Mutex::new(None),
        }
    }

    /// The spill directory, made on the first call.
    pub fn dir(&self) -> Result<PathBuf, ConvertError> {
        let mut dir = self
            .dir
            .lock()
            .map_err(|_| ConvertError::internal("a spilling thread panicked"))?;
        if dir.is_none() {
            *dir = Some(SpillDir::create(&self.parent)?);
        }
        Ok(dir
            .as_ref()
            .map(|d| d.path().to_path_buf())
            .unwrap_or_default())
    }
}

/// A temporary directory for the spill files of one build (`.froct-spill-…` in the chosen
/// directory), removed with everything in it when dropped — on success and on error — and
/// registered for removal if the process is stopped by a signal
/// ([`froctomap_core::cleanup`]). It is locked while the build lives, so the next build in
/// the same directory removes it if the process was killed (`kill -9`)
/// ([`froctomap_core::temporary_dir_in`]).
#[derive(Debug)]
pub(crate) struct SpillDir {
    dir: froctomap_core::TemporaryDir,
}

impl SpillDir {
    /// A new, empty spill directory inside `parent`.
    pub fn create(parent: &Path) -> Result<Self, ConvertError> {
        let dir =
            froctomap_core::temporary_dir_in(parent, SPILL_PREFIX.as_ref()).map_err(|source| {
                ConvertError::Spill {
                    path: parent.to_path_buf(),
                    source,
                }
            })?;
        Ok(Self { dir })
    }

    /// Where it is.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }
}

/// Where each tile's segments are in a spill file: offset and length, one per spill.
type Segments = BTreeMap<u64, Vec<(u64, u64)>>;

/// One accumulating thread's spill file, being written.
#[derive(Debug)]
pub(crate) struct SpillWriter {
    path: PathBuf,
    file: BufWriter<File>,
    tile_depth: u8,
    written: u64,
    segments: Segments,
    spills: usize,
}

/// A new spill file at `path`, readable and writable; never one that already exists.
fn create_spill_file(path: &Path) -> Result<File, ConvertError> {
    File::options()
        .read(true)
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(|source| ConvertError::Spill {
            path: path.to_path_buf(),
            source,
        })
}

impl SpillWriter {
    /// A new spill file `part` in `dir`, for tiles of depth `tile_depth`.
    pub fn create(dir: &Path, part: usize, tile_depth: u8) -> Result<Self, ConvertError> {
        let path = dir.join(format!("part-{part}.spill"));
        let file = create_spill_file(&path)?;
        Ok(Self {
            path,
            file: BufWriter::with_capacity(1 << 20, file),
            tile_depth,
            written: 0,
            segments: Segments::new(),
            spills: 0,
        })
    }

    /// Moves what grows with the series out of `history` into the file.
    pub fn spill(&mut self, history: &mut SeriesHistory) -> Result<(), ConvertError> {
        let Self {
            file,
            tile_depth,
            written,
            segments,
            ..
        } = self;
        let mut tile: Option<u64> = None;
        let mut segment: Vec<u8> = Vec::new();
        let mut end_segment = |tile: u64, segment: &mut Vec<u8>| -> io::Result<()> {
            file.write_all(segment)?;
            let len = segment.len() as u64;
            segments.entry(tile).or_default().push((*written, len));
            *written += len;
            segment.clear();
            Ok(())
        };
        history
            .spill(|start, depth, runs| -> io::Result<()> {
                let this = MortonCode(start).node_start(*tile_depth).0;
                if let Some(previous) = tile.filter(|&t| t != this) {
                    end_segment(previous, &mut segment)?;
                }
                tile = Some(this);
                encode_cell(&mut segment, start - this, depth, runs);
                Ok(())
            })
            .and_then(|()| match tile {
                Some(last) => end_segment(last, &mut segment),
                None => Ok(()),
            })
            .map_err(|source| ConvertError::Spill {
                path: self.path.clone(),
                source,
            })?;
        self.spills += 1;
        Ok(())
    }

    /// Bytes written so far.
    #[cfg(test)]
    pub fn bytes(&self) -> u64 {
        self.written
    }

    /// Spills so far.
    pub fn spills(&self) -> usize {
        self.spills
    }

    /// The file, written out, to be read back.
    pub fn into_reader(self) -> Result<SpillReader, ConvertError> {
        let fail = |source| ConvertError::Spill {
            path: self.path.clone(),
            source,
        };
        let file = self.file.into_inner().map_err(|e| fail(e.into_error()))?;
        Ok(SpillReader {
            file,
            tile_depth: self.tile_depth,
            segments: self.segments,
            tile: None,
            cursors: Vec::new(),
            bytes: self.written,
            path: self.path,
        })
    }
}

fn encode_cell(out: &mut Vec<u8>, offset: u64, depth: u8, runs: &[Run]) {
    varint::write_u64(out, offset);
    out.push(depth);
    varint::write_u64(out, runs.len() as u64);
    let mut end = 0u32;
    for run in runs {
        varint::write_u32(out, run.first - end);
        varint::write_u64(
            out,
            u64::from(run.len) << 1 | u64::from(run.state.is_occupied()),
        );
        end = run.first + run.len;
    }
}

/// One accumulating thread's spill file, read back tile by tile in Morton order.
#[derive(Debug)]
pub(crate) struct SpillReader {
    path: PathBuf,
    file: File,
    tile_depth: u8,
    segments: Segments,
    /// The tile being read, and a cursor in each of its segments (one per spill).
    tile: Option<u64>,
    cursors: Vec<SegmentCursor>,
    bytes: u64,
}

impl SpillReader {
    /// Bytes spilled.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// The directory its file is in.
    pub fn dir(&self) -> PathBuf {
        self.path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default()
    }

    /// Appends to `out` the runs spilled for the cell at `start` (or the coarser cells it
    /// was split from), oldest first. Cells are asked for in Morton order.
    pub fn runs_for(&mut self, start: u64, out: &mut Vec<Run>) -> Result<(), ConvertError> {
        let tile = MortonCode(start).node_start(self.tile_depth).0;
        if self.tile != Some(tile) {
            self.tile = Some(tile);
            let segments = self.segments.remove(&tile).unwrap_or_default();
            // A long series spills many times: the buffers of all the tile's segments
            // together stay within READ_BACK_BUFFERS, whatever the number of spills.
            let chunk = (READ_BACK_BUFFERS / segments.len().max(1))
                .clamp(MIN_SEGMENT_BUFFER, SEGMENT_BUFFER);
            self.cursors = segments
                .into_iter()
                .map(|(offset, len)| SegmentCursor::new(tile, offset, len).buffering(chunk))
                .collect();
        }
        let fail = |source| ConvertError::Spill {
            path: self.path.clone(),
            source,
        };
        for cursor in &mut self.cursors {
            if let Some(runs) = cursor.runs_for(start, &mut self.file).map_err(fail)? {
                decode_runs(runs, out).map_err(fail)?;
            }
        }
        Ok(())
    }
}

impl Drop for SpillReader {
    /// What was spilled is read back once: the file goes as soon as it is no longer read,
    /// rather than with the spill directory at the end of the build.
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// The finished cells of a build that spilled, written out in Morton order once the
/// series is read (see `Accumulated::into_cells`), so that the accumulator's cells are
/// freed before the fit stage, which then reads them back one at a time
/// ([`CellFileReader`]). A record per cell: its start (u64), depth (u8), number of runs
/// and bytes of packed runs (u64 each, little-endian), then the packed runs.
#[derive(Debug)]
pub(crate) struct CellFileWriter {
    path: PathBuf,
    file: BufWriter<File>,
}

/// Bytes of a cell record before its packed runs.
const CELL_RECORD_HEAD: usize = 8 + 1 + 8 + 8;

impl CellFileWriter {
    /// A new, empty cell file in `dir` for the cells of range `part` of the accumulation.
    pub fn create(dir: &Path, part: usize) -> Result<Self, ConvertError> {
        let path = dir.join(format!("cells-{part}.spill"));
        let file = create_spill_file(&path)?;
        Ok(Self {
            path,
            file: BufWriter::with_capacity(1 << 20, file),
        })
    }

    /// Appends a cell (after the ones before, in Morton order).
    pub fn push(&mut self, (start, depth, packed): &PackedCell) -> Result<(), ConvertError> {
        let bytes = packed.packed_bytes();
        let mut head = [0u8; CELL_RECORD_HEAD];
        head[..8].copy_from_slice(&start.0.to_le_bytes());
        head[8] = *depth;
        head[9..17].copy_from_slice(&(packed.run_count() as u64).to_le_bytes());
        head[17..].copy_from_slice(&(bytes.len() as u64).to_le_bytes());
        self.file
            .write_all(&head)
            .and_then(|()| self.file.write_all(bytes))
            .map_err(|source| ConvertError::Spill {
                path: self.path.clone(),
                source,
            })
    }

    /// The file, written out, to be read back from its start.
    pub fn into_reader(self) -> Result<CellFileReader, ConvertError> {
        let path = self.path;
        let fail = |source| ConvertError::Spill {
            path: path.clone(),
            source,
        };
        let mut file = self.file.into_inner().map_err(|e| fail(e.into_error()))?;
        let len = file.seek(SeekFrom::End(0)).map_err(fail)?;
        file.seek(SeekFrom::Start(0)).map_err(fail)?;
        Ok(CellFileReader {
            file: BufReader::with_capacity(1 << 18, file),
            left: len,
            end_of_last: 0,
            failed: false,
            path,
        })
    }
}

/// A cell file read back, cell by cell; removed when dropped. Read with checks (damage gives
/// an error, never a panic or a huge allocation).
#[derive(Debug)]
pub(crate) struct CellFileReader {
    path: PathBuf,
    file: BufReader<File>,
    /// Bytes not read yet.
    left: u64,
    /// One past the last voxel of the cell read before.
    end_of_last: u64,
    failed: bool,
}

impl CellFileReader {
    fn read_cell(&mut self) -> io::Result<PackedCell> {
        let mut head = [0u8; CELL_RECORD_HEAD];
        if self.left < CELL_RECORD_HEAD as u64 {
            return Err(damaged("a cell cut short"));
        }
        self.file.read_exact(&mut head)?;
        self.left -= CELL_RECORD_HEAD as u64;
        let word = |at: usize| {
            let mut bytes = [0u8; 8];
            bytes.copy_from_slice(&head[at..at + 8]);
            u64::from_le_bytes(bytes)
        };
        let (start, depth, runs, len) = (word(0), head[8], word(9), word(17));
        if depth > TREE_DEPTH {
            return Err(damaged("a cell deeper than the tree"));
        }
        if start < self.end_of_last {
            return Err(damaged("cells out of order"));
        }
        self.end_of_last = start
            .checked_add(voxels_per_node(depth))
            .ok_or_else(|| damaged("a cell beyond space"))?;
        if len > self.left {
            return Err(damaged("a cell cut short"));
        }
        let mut bytes = vec![0u8; len as usize];
        self.file.read_exact(&mut bytes)?;
        self.left -= len;
        let runs = usize::try_from(runs).map_err(|_| damaged("more runs than bytes"))?;
        let packed = PackedObservations::from_packed(bytes.into_boxed_slice(), runs)
            .ok_or_else(|| damaged("more runs than bytes"))?;
        Ok((MortonCode(start), depth, packed))
    }
}

impl Iterator for CellFileReader {
    type Item = Result<PackedCell, ConvertError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed || self.left == 0 {
            return None;
        }
        let cell = self.read_cell().map_err(|source| {
            self.failed = true;
            ConvertError::Spill {
                path: self.path.clone(),
                source,
            }
        });
        Some(cell)
    }
}

impl Drop for CellFileReader {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Bytes read from a segment at a time.
const SEGMENT_BUFFER: usize = 16 << 10;
/// Bytes read from a segment at a time at least.
const MIN_SEGMENT_BUFFER: usize = 1 << 10;
/// Bytes of buffers for all the segments of a tile (one per spill) together, as long as
/// each gets [`MIN_SEGMENT_BUFFER`].
const READ_BACK_BUFFERS: usize = 1 << 20;

/// A position in one spill's segment of a tile, read a few kilobytes at a time: the cells
/// of the segment are passed in Morton order, holding one cell's runs (packed) at a time,
/// so that reading back a tile of a long series costs a buffer per spill, not the tile's
/// history.
#[derive(Debug)]
struct SegmentCursor {
    /// Bytes read at a time.
    chunk: usize,
    tile: u64,
    /// File offset of the bytes not yet in `buffer`, and the segment's end.
    next: u64,
    end: u64,
    buffer: Vec<u8>,
    at: usize,
    /// The cell read last: its start, its end and its runs as spilled.
    cell: Option<(u64, u64, Vec<u8>)>,
}

impl SegmentCursor {
    fn new(tile: u64, offset: u64, len: u64) -> Self {
        Self {
            chunk: SEGMENT_BUFFER,
            tile,
            next: offset,
            end: offset.saturating_add(len),
            buffer: Vec::new(),
            at: 0,
            cell: None,
        }
    }

    /// Bytes of the segment not yet read.
    fn remaining(&self) -> u64 {
        (self.end - self.next) + (self.buffer.len() - self.at) as u64
    }

    /// The same, reading `chunk` bytes at a time.
    fn buffering(self, chunk: usize) -> Self {
        Self { chunk, ..self }
    }

    /// Reads on until `need` bytes are buffered or the segment ends.
    fn fill(&mut self, source: &mut (impl Read + Seek), need: usize) -> io::Result<()> {
        if self.buffer.len() - self.at >= need || self.next >= self.end {
            return Ok(());
        }
        self.buffer.drain(..self.at);
        self.at = 0;
        let more = (self.end - self.next).min(self.chunk.max(need) as u64) as usize;
        let have = self.buffer.len();
        self.buffer.resize(have + more, 0);
        source.seek(SeekFrom::Start(self.next))?;
        source.read_exact(&mut self.buffer[have..])?;
        self.next += more as u64;
        Ok(())
    }

    /// The next varint of the segment, with its bytes appended to `copy` if given.
    fn varint(
        &mut self,
        source: &mut (impl Read + Seek),
        copy: Option<&mut Vec<u8>>,
    ) -> io::Result<u64> {
        self.fill(source, varint::MAX_LEN_U64)?;
        let bytes = &self.buffer[self.at..];
        let (value, len) = varint::read_u64(bytes).map_err(|_| damaged("a bad number"))?;
        if let Some(copy) = copy {
            copy.extend_from_slice(&bytes[..len]);
        }
        self.at += len;
        Ok(value)
    }

    /// The runs spilled in this segment for the cell at `start` (inside a spilled cell,
    /// which may be coarser), if any. Cells are asked for in Morton order.
    fn runs_for(
        &mut self,
        start: u64,
        source: &mut (impl Read + Seek),
    ) -> io::Result<Option<&[u8]>> {
        loop {
            if let Some((first, end, _)) = &self.cell {
                if start < *end {
                    let inside = *first <= start;
                    return Ok(self.cell.as_ref().filter(|_| inside).map(|c| &c.2[..]));
                }
            }
            if self.remaining() == 0 {
                self.cell = None;
                return Ok(None);
            }
            self.read_cell(source)?;
        }
    }

    /// Reads the next cell of the segment into `cell`.
    fn read_cell(&mut self, source: &mut (impl Read + Seek)) -> io::Result<()> {
        let offset = self.varint(source, None)?;
        self.fill(source, 1)?;
        let depth = *self
            .buffer
            .get(self.at)
            .ok_or_else(|| damaged("a cell cut short"))?;
        self.at += 1;
        if depth > TREE_DEPTH {
            return Err(damaged("a cell deeper than the tree"));
        }
        let start = self
            .tile
            .checked_add(offset)
            .ok_or_else(|| damaged("a cell beyond space"))?;
        let end = start
            .checked_add(voxels_per_node(depth))
            .ok_or_else(|| damaged("a cell beyond space"))?;
        if self
            .cell
            .as_ref()
            .is_some_and(|(_, previous_end, _)| start < *previous_end)
        {
            return Err(damaged("cells out of order"));
        }
        let count = self.varint(source, None)?;
        // Every run takes two bytes at least.
        if count > self.remaining() / 2 {
            return Err(damaged("more runs than bytes"));
        }
        let mut runs = match self.cell.take() {
            Some((_, _, mut bytes)) => {
                bytes.clear();
                bytes
            }
            None => Vec::new(),
        };
        for _ in 0..count {
            self.varint(source, Some(&mut runs))?;
            self.varint(source, Some(&mut runs))?;
        }
        self.cell = Some((start, end, runs));
        Ok(())
    }
}

fn damaged(what: &'static str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, format!("damaged: {what}"))
}

/// Appends the runs packed in `bytes` (a cell's, by [`encode_cell`]) to `out`.
fn decode_runs(bytes: &[u8], out: &mut Vec<Run>) -> io::Result<()> {
    let bad = |_| damaged("a bad number");
    let mut reader = varint::Reader::new(bytes);
    let mut run_end = 0u32;
    while reader.remaining() > 0 {
        let gap = reader.u32().map_err(bad)?;
        let packed = reader.u64().map_err(bad)?;
        let first = run_end
            .checked_add(gap)
            .ok_or_else(|| damaged("a run beyond the axis"))?;
        let len = u32::try_from(packed >> 1).map_err(|_| damaged("a run too long"))?;
        run_end = first
            .checked_add(len)
            .ok_or_else(|| damaged("a run beyond the axis"))?;
        out.push(Run {
            first,
            len,
            state: Occupancy::from(packed & 1 == 1),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(first: u32, len: u32, occupied: bool) -> Run {
        Run {
            first,
            len,
            state: Occupancy::from(occupied),
        }
    }

    #[test]
    fn cells_read_back_get_the_runs_of_the_cells_they_were_cut_from() {
        let tile = voxels_per_node(12);
        let cell = voxels_per_node(14);
        // A coarse cell (an eighth of a depth-12 tile: eight depth-14 cells), then a finer one after a gap; a
        // buffer's worth of padding before the segment, so that reads cross refills.
        let pad = SEGMENT_BUFFER + 7;
        let mut segment = vec![0xEE; pad];
        encode_cell(&mut segment, 0, 13, &[run(0, 3, false), run(5, 2, true)]);
        let first_len = (segment.len() - pad) as u64;
        let long: Vec<Run> = (0..5000).map(|i| run(2 * i, 1, i % 2 == 0)).collect();
        encode_cell(&mut segment, 9 * cell, 14, &long);
        let len = (segment.len() - pad) as u64;
        let mut source = io::Cursor::new(segment.clone());
        let mut cursor = SegmentCursor::new(tile, pad as u64, len).buffering(MIN_SEGMENT_BUFFER);
        let mut runs_of = |start| {
            let mut runs = Vec::new();
            if let Some(bytes) = cursor.runs_for(tile + start, &mut source).unwrap() {
                decode_runs(bytes, &mut runs).unwrap();
            }
            runs
        };
        // Offsets are from the tile's start; every cell cut from the coarse one gets its runs.
        assert_eq!(runs_of(0), [run(0, 3, false), run(5, 2, true)]);
        assert_eq!(runs_of(7 * cell), [run(0, 3, false), run(5, 2, true)]);
        assert!(runs_of(8 * cell).is_empty());
        assert_eq!(runs_of(9 * cell), long);
        assert!(runs_of(10 * cell).is_empty());
        // Segments cut inside a cell or forged are errors, not panics or huge allocations.
        for cut in (1..len).filter(|&cut| cut != first_len) {
            let mut cursor = SegmentCursor::new(tile, pad as u64, cut);
            let mut source = io::Cursor::new(segment.clone());
            let read = (|| -> io::Result<()> {
                cursor.runs_for(tile, &mut source)?;
                cursor.runs_for(tile + 9 * cell, &mut source)?;
                Ok(())
            })();
            assert!(read.is_err(), "cut {cut}");
        }
        let mut forged = Vec::new();
        varint::write_u64(&mut forged, 0);
        forged.push(3);
        varint::write_u64(&mut forged, u64::MAX);
        let read = |forged: &Vec<u8>| {
            let mut cursor = SegmentCursor::new(0, 0, forged.len() as u64);
            let mut source = io::Cursor::new(forged.clone());
            cursor.runs_for(0, &mut source).map(|_| ())
        };
        assert!(read(&forged).is_err());
        forged[1] = TREE_DEPTH + 1;
        assert!(read(&forged).is_err());
    }

    #[test]
    fn cell_files_give_back_their_cells_and_refuse_damage() {
        let dir = tempfile::tempdir().unwrap();
        let packed = |runs: &[(u32, u32, bool)]| {
            PackedObservations::pack(runs.iter().map(|&(f, l, o)| (f, l, Occupancy::from(o))))
        };
        let cells: Vec<PackedCell> = vec![
            (MortonCode(0), 15, packed(&[(0, 3, false), (5, 2, true)])),
            (MortonCode(8), 16, packed(&[])),
            (MortonCode(64), 14, packed(&[(1, 1, true)])),
        ];
        let mut writer = CellFileWriter::create(dir.path(), 3).unwrap();
        for cell in &cells {
            writer.push(cell).unwrap();
        }
        let reader = writer.into_reader().unwrap();
        let path = dir.path().join("cells-3.spill");
        let bytes = std::fs::read(&path).unwrap();
        let back: Vec<PackedCell> = reader.map(Result::unwrap).collect();
        assert_eq!(back, cells);
        assert!(!path.exists(), "the file goes with its reader");
        // Cut anywhere, or with a forged count, depth or order: an error, never a panic.
        let read_back = |bytes: &[u8]| -> Result<usize, ConvertError> {
            std::fs::write(&path, bytes).unwrap();
            let file = File::options().read(true).write(true).open(&path).unwrap();
            let reader = CellFileWriter {
                path: path.clone(),
                file: BufWriter::new(file),
            }
            .into_reader()?;
            reader
                .collect::<Result<Vec<_>, _>>()
                .map(|cells| cells.len())
        };
        assert_eq!(read_back(&bytes).unwrap(), 3);
        for cut in 1..bytes.len() {
            let whole = [0, CELL_RECORD_HEAD + 4, 2 * CELL_RECORD_HEAD + 4];
            if !whole.contains(&cut) {
                assert!(read_back(&bytes[..cut]).is_err(), "cut at {cut}");
            }
        }
        let mut forged = bytes.clone();
        forged[9..17].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(read_back(&forged).is_err());
        let mut forged = bytes.clone();
        forged[8] = TREE_DEPTH + 1;
        assert!(read_back(&forged).is_err());
        let mut forged = bytes.clone();
        forged[CELL_RECORD_HEAD + 4..CELL_RECORD_HEAD + 12].copy_from_slice(&0u64.to_le_bytes());
        assert!(read_back(&forged).is_err(), "cells out of order");
    }

    #[test]
    fn spill_files_give_back_what_was_spilled_tile_by_tile() {
        use froctomap_core::{Occupancy::Free, StateChange};
        let dir = tempfile::tempdir().unwrap();
        let spill_dir = SpillDir::create(dir.path()).unwrap();
        let tile_depth = 15; // 8 voxels a tile
        let mut history = SeriesHistory::new(tile_depth);
        let mut writer = SpillWriter::create(spill_dir.path(), 0, tile_depth).unwrap();
        let change = |start, end, new| StateChange { start, end, new };
        history
            .apply_changes(0, &[change(0, 16, Some(Free))])
            .unwrap();
        history
            .apply_changes(1, &[change(0, 16, Some(Occupancy::Occupied))])
            .unwrap();
        writer.spill(&mut history).unwrap();
        // Splits the first tile's cell after the spill.
        history
            .apply_changes(2, &[change(3, 4, Some(Free))])
            .unwrap();
        writer.spill(&mut history).unwrap();
        assert_eq!(writer.spills(), 2);
        assert!(writer.bytes() > 0);
        let mut reader = writer.into_reader().unwrap();
        let mut runs = Vec::new();
        reader.runs_for(3, &mut runs).unwrap();
        assert_eq!(runs, [run(0, 1, false), run(1, 1, true)]);
        runs.clear();
        reader.runs_for(8, &mut runs).unwrap();
        assert_eq!(runs, [run(0, 1, false)]);
        let path = spill_dir.path().to_path_buf();
        assert!(path.join("part-0.spill").exists());
        drop(reader);
        drop(spill_dir);
        assert!(
            !path.exists(),
            "the spill directory is removed when dropped"
        );
    }
}
