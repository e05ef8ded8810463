//! Writing a file in one streaming pass.

use crate::error::FileError;
use crate::header::Header;
use crate::index::{encode_footer, encode_index, TileEntry};
#[cfg(doc)]
use crate::tile::encode_tile;
use crate::tile::{EncodedTile, StreamSizes};
use froctomap_core::TemporaryFile;
use serde_json::{Map, Value};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes a FROctomap file: header first, then tiles in increasing Morton order as they are
/// encoded, then index and footer on [`FroctWriter::finish`]. The writer seals each tile
/// itself: the index entry's checksum and stored length are computed from the bytes it
/// writes, and the decoded length comes from the [`EncodedTile`] that [`encode_tile`]
/// (its only maker) measured. The file is written to a
/// temporary name beside the destination and renamed only when complete, so an interrupted
/// or failed write leaves nothing behind (and never damages an existing file).
pub struct FroctWriter {
    path: PathBuf,
    out: BufWriter<TemporaryFile>,
    header_len: u64,
    offset: u64,
    entries: Vec<TileEntry>,
    streams: StreamSizes,
    stored_bytes: u64,
    cells: u64,
}

/// What [`FroctWriter::finish`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct WrittenFile {
    /// Total file length.
    pub file_bytes: u64,
    /// Preamble, header and header crc.
    pub header_bytes: u64,
    /// Index and footer.
    pub index_bytes: u64,
    /// Sum of stored tile bytes.
    pub tile_bytes: u64,
    /// Tiles written.
    pub tiles: u64,
    /// Cells written.
    pub cells: u64,
    /// Raw bytes per stream over all tiles.
    pub streams: StreamSizes,
}

impl FroctWriter {
    /// Starts a file at `path` (created atomically on [`finish`](Self::finish)).
    pub fn create(path: &Path, header: &Header) -> Result<Self, FileError> {
        header.validate().map_err(|source| FileError::Header {
            path: path.to_path_buf(),
            source,
        })?;
        let io = |source| FileError::Io {
            path: path.to_path_buf(),
            source,
        };
        let temp =
            froctomap_core::temporary_beside(path, std::ffi::OsStr::new(".froct-")).map_err(io)?;
        let mut out = BufWriter::with_capacity(1 << 20, temp);
        let bytes = header.encode();
        out.write_all(&bytes).map_err(io)?;
        Ok(Self {
            path: path.to_path_buf(),
            out,
            header_len: bytes.len() as u64,
            offset: bytes.len() as u64,
            entries: Vec::new(),
            streams: StreamSizes::default(),
            stored_bytes: 0,
            cells: 0,
        })
    }

    /// Appends a tile; tiles must come in strictly increasing Morton order.
    pub fn write_tile(&mut self, tile: &EncodedTile) -> Result<(), FileError> {
        let entry = seal_tile(&self.path, self.entries.last(), tile, self.offset)?;
        self.out
            .write_all(tile.stored())
            .map_err(|source| FileError::Io {
                path: self.path.clone(),
                source,
            })?;
        self.entries.push(entry);
        self.offset += u64::from(entry.stored_len);
        self.stored_bytes += u64::from(entry.stored_len);
        self.streams.add(tile.streams());
        self.cells += u64::from(tile.cell_count());
        Ok(())
    }

    /// Writes index and footer, syncs, and renames the file into place. `summary` is stored
    /// in the index (FORMAT.md §6) together with the writer's own byte counts.
    pub fn finish(mut self, mut summary: Map<String, Value>) -> Result<WrittenFile, FileError> {
        let streams = self.streams;
        let written = |index_bytes: u64| WrittenFile {
            file_bytes: self.offset + index_bytes,
            header_bytes: self.header_len,
            index_bytes,
            tile_bytes: self.stored_bytes,
            tiles: self.entries.len() as u64,
            cells: self.cells,
            streams,
        };
        let stream_json = serde_json::json!({
            "geometry": streams.geometry, "depth": streams.depth, "class": streams.class,
            "masks": streams.masks, "models": streams.models, "outliers": streams.outliers,
        });
        summary.insert("raw_stream_bytes".into(), stream_json);
        summary.insert("stored_tile_bytes".into(), Value::from(self.stored_bytes));
        summary.insert("cells".into(), Value::from(self.cells));
        let index = encode_index(&self.entries, &summary);
        let footer = encode_footer(self.offset, &index);
        let io = |source| FileError::Io {
            path: self.path.clone(),
            source,
        };
        self.out.write_all(&index).map_err(io)?;
        self.out.write_all(&footer).map_err(io)?;
        let result = written((index.len() + footer.len()) as u64);
        let temp = self.out.into_inner().map_err(|e| FileError::Io {
            path: self.path.clone(),
            source: e.into_error(),
        })?;
        temp.as_file().sync_all().map_err(|source| FileError::Io {
            path: self.path.clone(),
            source,
        })?;
        temp.persist(&self.path).map_err(|source| FileError::Io {
            path: self.path.clone(),
            source,
        })?;
        Ok(result)
    }
}

/// The index entry of `tile` written at `offset` after the tile `last`: checks the Morton
/// order and the stored length, and checksums the bytes to be written.
pub(crate) fn seal_tile(
    path: &Path,
    last: Option<&TileEntry>,
    tile: &EncodedTile,
    offset: u64,
) -> Result<TileEntry, FileError> {
    if let Some(last) = last.filter(|last| last.code >= tile.code()) {
        return Err(FileError::TileOrder {
            path: path.to_path_buf(),
            code: tile.code().0,
            previous: last.code.0,
        });
    }
    let stored = tile.stored();
    let stored_len = u32::try_from(stored.len()).map_err(|_| FileError::TileTooLarge {
        path: path.to_path_buf(),
        len: stored.len(),
    })?;
    let (first_sample, last_sample) = tile.sample_span();
    Ok(TileEntry {
        code: tile.code(),
        offset,
        stored_len,
        raw_len: tile.raw_len(),
        crc: crc32c::crc32c(stored),
        cell_count: tile.cell_count(),
        first_sample,
        last_sample,
    })
}
