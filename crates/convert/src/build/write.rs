//! Stage 5, encode and write: fitted tiles encoded with the file's codec and layout (in
//! parallel, [`TileEncoder`]) and written in Morton order to the output, atomically
//! ([`TileWriter`], which also sums the tiles' counts for the summary).

use super::counts::TileStats;
use crate::error::ConvertError;
#[cfg(test)]
use froctomap_file::encode_tile;
use froctomap_file::{
    Cell, EncodedTile, FroctWriter, Header, TileLayout, TileStreamEncoder, WrittenFile,
};
use froctomap_temporal::PreparedModel;
use serde_json::{Map, Value};
use std::path::Path;

/// Encodes the cells of a tile as the file stores them: whole ([`encode`](Self::encode)), or
/// pushed one at a time into a tile's streams ([`start`](Self::start), [`push`](Self::push),
/// [`finish`](Self::finish)).
pub(crate) struct TileEncoder<'a> {
    layout: TileLayout,
    model: &'a dyn PreparedModel,
}

impl<'a> TileEncoder<'a> {
    /// An encoder for a file of this layout whose dynamic cells `model` fitted.
    pub fn new(layout: TileLayout, model: &'a dyn PreparedModel) -> Self {
        Self { layout, model }
    }

    /// One tile's cells (in Morton order), encoded.
    #[cfg(test)]
    pub fn encode(&self, cells: &[Cell]) -> Result<EncodedTile, ConvertError> {
        encode_tile(&self.layout, cells, self.model).map_err(not_encoded)
    }

    /// The streams of a tile with no cells yet.
    pub fn start(&self) -> TileStreamEncoder {
        TileStreamEncoder::new(&self.layout, self.model)
    }

    /// Adds the next cell of the tile (in Morton order) to its streams.
    pub fn push(&self, tile: &mut TileStreamEncoder, cell: &Cell) -> Result<(), ConvertError> {
        tile.push(cell).map_err(not_encoded)
    }

    /// The tile whose cells were pushed, encoded.
    pub fn finish(&self, tile: TileStreamEncoder) -> Result<EncodedTile, ConvertError> {
        tile.finish().map_err(not_encoded)
    }
}

/// Cells the fit stage made that the file cannot hold: a bug, not bad input.
fn not_encoded(e: froctomap_file::TileEncodeError) -> ConvertError {
    ConvertError::Internal {
        what: "a tile could not be encoded",
        source: Some(e.into()),
    }
}

/// The output file, written tile by tile.
pub(crate) struct TileWriter {
    writer: FroctWriter,
    stats: TileStats,
}

impl TileWriter {
    /// Starts the file at `output` (in place once [`finish`](Self::finish)ed).
    pub fn create(output: &Path, header: &Header) -> Result<Self, ConvertError> {
        Ok(Self {
            writer: FroctWriter::create(output, header)?,
            stats: TileStats::default(),
        })
    }

    /// Writes the next tile (after the ones before in Morton order), with its counts.
    pub fn write(&mut self, tile: &EncodedTile, stats: &TileStats) -> Result<(), ConvertError> {
        self.writer.write_tile(tile)?;
        self.stats.add_tile(stats);
        Ok(())
    }

    /// The counts of the tiles written so far.
    pub fn stats(&self) -> &TileStats {
        &self.stats
    }

    /// Writes the index and the summary and puts the file in place.
    pub fn finish(self, summary: Map<String, Value>) -> Result<WrittenFile, ConvertError> {
        Ok(self.writer.finish(summary)?)
    }
}

#[cfg(test)]
mod tests {
    use super::super::accumulate::TileHistory;
    use super::super::fit::{cells_of_tiles, fit_and_write, TileFitter};
    use super::*;
    use crate::build::test_support::default_model;
    use crate::progress::Silent;
    use froctomap_core::{MortonCode, Occupancy};
    use froctomap_file::{CellContent, Codec, FroctReader};
    use froctomap_temporal::VoxelObservations;

    /// The header of a file of depth-14 tiles on a regular axis of `samples` seconds, and
    /// the default model prepared for that axis.
    fn file_header(samples: u32) -> (Header, Box<dyn PreparedModel>) {
        let setup = default_model(samples);
        let parameters = setup.model.encode_parameters();
        let header = Header::new(0.1, 14, setup.axis, setup.id, parameters, Codec::default());
        (header, setup.model)
    }

    #[test]
    fn tiles_written_read_back_as_given_and_counts_add_up() {
        let dir = tempfile::tempdir().unwrap();
        let output = dir.path().join("out.froct");
        let (header, prepared) = file_header(4);
        let tile_size = froctomap_core::voxels_per_node(14);
        let constant = |start, state| Cell {
            start: MortonCode(start),
            depth: 14,
            mask: None,
            content: CellContent::Constant(state),
        };
        let tiles = [
            vec![constant(0, Occupancy::Free)],
            vec![constant(3 * tile_size, Occupancy::Occupied)],
        ];
        let encoder = TileEncoder::new(header.tile_layout(), prepared.as_ref());
        let mut writer = TileWriter::create(&output, &header).unwrap();
        let mut one = TileStats::default();
        one.cells.static_free = 1;
        for cells in &tiles {
            writer.write(&encoder.encode(cells).unwrap(), &one).unwrap();
        }
        assert_eq!(writer.stats().cells.static_free, 2);
        assert!(!output.exists(), "in place only once finished");
        let written = writer.finish(Map::new()).unwrap();
        assert_eq!(
            written.file_bytes,
            std::fs::metadata(&output).unwrap().len()
        );
        let reader = FroctReader::open(&output).unwrap();
        assert_eq!(reader.tiles().len(), 2);
        for (i, cells) in tiles.iter().enumerate() {
            assert_eq!(&reader.read_tile(i).unwrap(), cells);
        }
    }

    /// A stream of `count` tiles, each one cell observed free then occupied.
    fn tile_stream(count: u64) -> impl Iterator<Item = Result<TileHistory, ConvertError>> + Send {
        let tile_size = froctomap_core::voxels_per_node(14);
        (0..count).map(move |i| {
            let runs = vec![(0, 2, Occupancy::Free), (2, 2, Occupancy::Occupied)];
            Ok(TileHistory::new(vec![(
                MortonCode(i * tile_size),
                14,
                VoxelObservations::from_runs(runs)?,
            )]))
        })
    }

    #[test]
    fn a_stream_of_tiles_is_fitted_and_written_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let output = dir.path().join("out.froct");
        let (header, prepared) = file_header(4);
        let fitter = TileFitter::new(&header.axis, prepared.as_ref());
        let encoder = TileEncoder::new(header.tile_layout(), prepared.as_ref());
        let mut writer = TileWriter::create(&output, &header).unwrap();
        // More tiles than one parallel batch holds.
        let count = 9 * rayon::current_num_threads() as u64;
        let cells = cells_of_tiles(tile_stream(count));
        fit_and_write(cells, 14, &fitter, &encoder, &mut writer, &Silent).unwrap();
        assert_eq!(writer.stats().cells.dynamic, count);
        writer.finish(Map::new()).unwrap();
        let reader = FroctReader::open(&output).unwrap();
        let starts: Vec<u64> = (0..reader.tiles().len())
            .map(|i| reader.read_tile(i).unwrap()[0].start.0)
            .collect();
        let expected: Vec<u64> = tile_stream(count)
            .map(|t| t.unwrap().unpacked()[0].0 .0)
            .collect();
        assert_eq!(starts, expected);
    }

    /// A tile of depth 10 holding `cells` voxels observed over `samples` samples: constant,
    /// flipping and noisy cells, some seen late or with gaps (masked), in Morton order.
    fn varied_tile(cells: u64, samples: u32) -> TileHistory {
        TileHistory::new(
            (0..cells)
                .map(|i| {
                    let mut runs = Vec::new();
                    let mut t = (i % 3) as u32;
                    let mut occupied = i % 2 == 0;
                    while t < samples {
                        let len = (1 + ((i * 7 + u64::from(t)) % 5) as u32).min(samples - t);
                        let state = if occupied {
                            Occupancy::Occupied
                        } else {
                            Occupancy::Free
                        };
                        runs.push((t, len, state));
                        t += len + u32::from(i % 4 == 0);
                        occupied ^= i % 7 != 0;
                    }
                    let observations = VoxelObservations::from_runs(runs).unwrap();
                    (MortonCode(i), 16, observations)
                })
                .collect(),
        )
    }

    #[test]
    fn cells_streamed_chunk_by_chunk_encode_as_the_whole_tile() {
        // More cells than a fitting chunk, so one tile's streams grow over several chunks.
        let tile = varied_tile(5_000, 64);
        let setup = default_model(64);
        let header = Header::new(
            0.1,
            10,
            setup.axis.clone(),
            setup.id,
            setup.model.encode_parameters(),
            Codec::default(),
        );
        let prepared = setup.model.as_ref();
        let fitter = TileFitter::new(&header.axis, prepared);
        let encoder = TileEncoder::new(header.tile_layout(), prepared);
        let dir = tempfile::tempdir().unwrap();
        let streamed = dir.path().join("streamed.froct");
        let mut writer = TileWriter::create(&streamed, &header).unwrap();
        let cells = cells_of_tiles(std::iter::once(Ok(varied_tile(5_000, 64))));
        fit_and_write(cells, 10, &fitter, &encoder, &mut writer, &Silent).unwrap();
        let counts = writer.stats().clone();
        writer.finish(Map::new()).unwrap();

        let whole = dir.path().join("whole.froct");
        let fitted = fitter.fit(&tile).unwrap();
        assert!(fitted.stats.cells.dynamic > 1_000 && fitted.stats.cells.unknown_sometimes > 1_000);
        let mut whole_tile = TileStats::default();
        whole_tile.add_tile(&fitted.stats);
        assert_eq!(counts, whole_tile);
        let mut writer = TileWriter::create(&whole, &header).unwrap();
        writer
            .write(&encoder.encode(&fitted.cells).unwrap(), &fitted.stats)
            .unwrap();
        writer.finish(Map::new()).unwrap();
        assert_eq!(
            std::fs::read(&streamed).unwrap(),
            std::fs::read(&whole).unwrap()
        );
        let reader = FroctReader::open(&streamed).unwrap();
        assert_eq!(reader.read_tile(0).unwrap(), fitted.cells);
    }

    #[test]
    fn an_error_in_the_tile_stream_stops_the_writing() {
        let dir = tempfile::tempdir().unwrap();
        let (header, prepared) = file_header(4);
        let fitter = TileFitter::new(&header.axis, prepared.as_ref());
        let encoder = TileEncoder::new(header.tile_layout(), prepared.as_ref());
        let output = dir.path().join("out.froct");
        let mut writer = TileWriter::create(&output, &header).unwrap();
        let failing = tile_stream(3).chain(std::iter::once(Err(ConvertError::internal("test"))));
        let result = fit_and_write(
            cells_of_tiles(failing),
            14,
            &fitter,
            &encoder,
            &mut writer,
            &Silent,
        );
        assert!(matches!(
            result,
            Err(ConvertError::Internal { what: "test", .. })
        ));
    }
}
