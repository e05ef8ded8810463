//! Stage 2, change extraction: the checked inputs, read in parallel batches and turned into
//! their changes from the snapshot accepted before each ([`ChangeReader`]: from the bytes
//! where the format allows, else by decoding).
//!
//! In: the series and [`CheckedInputs`]. Out: an iterator of [`ChangeBatch`]es, one per batch
//! of inputs (possibly empty), each the accepted snapshots' `(sample, changes)` in time order;
//! then [`Extracted`], the tally of what was used, skipped and warned about. Memory holds one
//! batch of files; the accumulator consumes the batches as they come.

use super::check::{CheckedInputs, TileBudget};
use crate::context::Context;
use crate::error::ConvertError;
use crate::inputs::{input_name, snapshot_bytes, SeriesInput};
use crate::progress::Progress;
use crate::snapshot_changes::{Accepted, ChangeReader, Refusal};
use froctomap_core::StateChange;
use froctomap_formats::ReadOptions;
use froctomap_temporal::TimeAxis;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// One accepted snapshot: its sample on the time axis and where it differs from the
/// snapshot accepted before it (sorted, disjoint ranges; empty when identical).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct SampleChanges {
    pub sample: u32,
    pub changes: Vec<StateChange>,
}

/// The accepted snapshots of one batch of inputs, in time order.
pub(crate) type ChangeBatch = Vec<SampleChanges>;

/// What extraction used and left out, once every batch is through.
#[derive(Debug, Default)]
pub(crate) struct Extracted {
    /// Snapshots accepted.
    pub used: usize,
    /// Bytes of the files accepted.
    pub input_bytes: u64,
    /// Files refused with `skip_bad`, and why.
    pub skipped: Vec<(PathBuf, String)>,
    /// The samples of those files.
    pub absent: Vec<u32>,
    /// Reader warnings (file, message).
    pub warnings: Vec<(PathBuf, String)>,
    /// The series' resolution (from the headers, else from the first file read); `None` when
    /// no file was read.
    pub resolution: Option<f64>,
}

/// How to extract.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ExtractOptions<'a> {
    /// How to read the maps.
    pub read: ReadOptions<'a>,
    /// Leave refused files out (listed in the tally) instead of stopping.
    pub skip_bad: bool,
    /// Inputs per batch (read in parallel; bounds memory).
    pub batch: usize,
    /// How many tiles one snapshot may cover.
    pub tiles: TileBudget,
}

/// The change extraction of a series, an iterator of batches.
pub(crate) struct ChangeExtractor<'a> {
    context: &'a Context,
    options: ExtractOptions<'a>,
    inputs: &'a [SeriesInput],
    usable: &'a [bool],
    axis: &'a TimeAxis,
    progress: &'a dyn Progress,
    /// The first input of the next batch.
    next: usize,
    /// The last snapshot accepted, which the next one is compared with.
    previous: Option<Accepted>,
    /// The file that set the series' resolution, named when another one differs.
    first_path: Option<PathBuf>,
    /// A batch handed out before the inputs' (an append's starting map).
    seed: Option<ChangeBatch>,
    tally: Extracted,
}

impl<'a> ChangeExtractor<'a> {
    /// Extraction of the inputs `checked` left in, on `axis` (which has every input's time).
    pub fn new(
        context: &'a Context,
        options: ExtractOptions<'a>,
        inputs: &'a [SeriesInput],
        checked: &'a CheckedInputs,
        axis: &'a TimeAxis,
        progress: &'a dyn Progress,
    ) -> Self {
        Self {
            context,
            options,
            inputs,
            usable: &checked.usable,
            axis,
            progress,
            next: 0,
            previous: None,
            seed: None,
            first_path: checked.resolution_file.map(|i| inputs[i].path.clone()),
            tally: Extracted {
                resolution: checked.resolution,
                ..Extracted::default()
            },
        }
    }

    /// Extraction that continues a series: `start` (the map `previous` holds, as its changes
    /// from nothing, at its sample) is handed out as the first batch, the first input is
    /// compared with `previous` instead of with nothing, and inputs of another resolution
    /// than `resolution`, which `origin` set, are refused naming `origin`. This is how an
    /// append continues from the file's last observed map. The tally counts inputs only.
    pub fn continuing(
        mut self,
        start: SampleChanges,
        previous: Accepted,
        resolution: f64,
        origin: &Path,
    ) -> Self {
        self.seed = Some(vec![start]);
        self.previous = Some(previous);
        self.of_file(resolution, origin)
    }

    /// Extraction of maps to be added to the file `origin`: inputs of another resolution
    /// than `resolution` (the file's) are refused naming `origin`. (The first input is still
    /// compared with nothing: a segment of a format 2.0 file starts its own histories.)
    pub fn of_file(mut self, resolution: f64, origin: &Path) -> Self {
        self.tally.resolution = Some(resolution);
        self.first_path = Some(origin.to_path_buf());
        self
    }

    /// The tally, once the batches are through.
    pub fn finish(self) -> Extracted {
        self.tally
    }

    /// The changes of the usable inputs among `chunk` (indices into the series).
    fn extract(&mut self, chunk: &[usize]) -> Result<ChangeBatch, ConvertError> {
        let registry = self.context.formats();
        let limit = self.context.limits().max_map_file_bytes;
        let inputs = self.inputs;
        let raw: Vec<Result<Vec<u8>, Refusal>> = chunk
            .par_iter()
            .map(|&i| snapshot_bytes(&inputs[i], limit).map_err(Arc::new))
            .collect();
        // When the series' resolution is not known from the headers, the first file sets it.
        if self.tally.resolution.is_none() {
            if let (Some(&i), Some(Ok(bytes))) = (chunk.first(), raw.first()) {
                if let Ok(read) = registry.read_bytes(&inputs[i].path, bytes, self.options.read) {
                    self.tally.resolution = Some(read.map.snapshot.resolution());
                }
            }
        }
        let reader = ChangeReader {
            registry,
            options: self.options.read,
            resolution: self.tally.resolution,
        };
        let names: Vec<PathBuf> = chunk.iter().map(|&i| input_name(&inputs[i])).collect();
        let paths: Vec<&Path> = names.iter().map(PathBuf::as_path).collect();
        let outcomes = reader.batch(&paths, &raw, &mut self.previous);
        let mut accepted = Vec::with_capacity(outcomes.len());
        for (k, outcome) in outcomes.into_iter().enumerate() {
            let input = &inputs[chunk[k]];
            let sample = self
                .axis
                .index_of(input.time)
                .ok_or_else(|| ConvertError::internal("a time not on the axis"))?;
            match outcome {
                Ok(read) => {
                    self.options.tiles.check(&read.changes).map_err(|e| {
                        ConvertError::Snapshot {
                            path: input.path.clone(),
                            source: Arc::new(e),
                        }
                    })?;
                    let tally = &mut self.tally;
                    tally
                        .warnings
                        .extend(read.warnings.into_iter().map(|w| (input.path.clone(), w)));
                    tally.input_bytes += raw[k].as_ref().map_or(0, |b| b.len() as u64);
                    tally.used += 1;
                    accepted.push(SampleChanges {
                        sample,
                        changes: read.changes,
                    });
                }
                Err(reason) if self.options.skip_bad => {
                    self.tally
                        .skipped
                        .push((input.path.clone(), froctomap_core::error_message(&reason)));
                    self.tally.absent.push(sample);
                    self.progress.advance(1);
                }
                Err(reason) => return Err(self.refusal(&input.path, reason)),
            }
        }
        Ok(accepted)
    }

    /// The error for a refused file: a resolution other than the series' names the file that
    /// set it.
    fn refusal(&self, path: &Path, reason: Refusal) -> ConvertError {
        match (reason.resolution_mismatch(), &self.first_path) {
            (Some((series, found)), Some(first)) => ConvertError::MixedResolution {
                first: first.clone(),
                first_resolution: series,
                second: path.to_path_buf(),
                second_resolution: found,
            },
            _ => ConvertError::Snapshot {
                path: path.to_path_buf(),
                source: reason,
            },
        }
    }
}

impl Iterator for ChangeExtractor<'_> {
    type Item = Result<ChangeBatch, ConvertError>;

    fn next(&mut self) -> Option<Self::Item> {
        if let Some(seed) = self.seed.take() {
            return Some(Ok(seed));
        }
        if self.next >= self.inputs.len() {
            return None;
        }
        let end = (self.next + self.options.batch.max(1)).min(self.inputs.len());
        let chunk: Vec<usize> = (self.next..end).filter(|&i| self.usable[i]).collect();
        self.next = end;
        Some(self.extract(&chunk))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::SnapshotError;
    use crate::progress::Silent;
    use froctomap_core::{Leaf, Occupancy, Snapshot, Timestamp, VoxelKey};
    use froctomap_formats::WriteOptions;

    fn snapshot(resolution: f64, occupied: &[u16]) -> Snapshot {
        let leaves = (0..8u16)
            .map(|x| {
                let state = Occupancy::from(occupied.contains(&x));
                Leaf::voxel(VoxelKey::new(32768 + x, 32768, 32768), state.log_odds())
            })
            .collect();
        Snapshot::from_leaves(resolution, leaves).unwrap()
    }

    /// Writes the snapshots as `.bt` files one second apart.
    fn write(dir: &Path, context: &Context, snapshots: &[Snapshot]) -> Vec<SeriesInput> {
        snapshots
            .iter()
            .enumerate()
            .map(|(i, snapshot)| {
                let path = dir.join(format!("map{i}.bt"));
                context
                    .formats()
                    .write_file(snapshot, &path, WriteOptions::default())
                    .unwrap();
                SeriesInput::new(path, Timestamp::from_secs(i as i64))
            })
            .collect()
    }

    fn extractor<'a>(
        context: &'a Context,
        inputs: &'a [SeriesInput],
        checked: &'a CheckedInputs,
        axis: &'a TimeAxis,
        skip_bad: bool,
        batch: usize,
    ) -> ChangeExtractor<'a> {
        let options = ExtractOptions {
            read: ReadOptions::default(),
            skip_bad,
            batch,
            tiles: TileBudget {
                tile_depth: 10,
                max_tiles: u64::MAX,
            },
        };
        ChangeExtractor::new(context, options, inputs, checked, axis, &Silent)
    }

    fn axis(inputs: &[SeriesInput]) -> TimeAxis {
        let times: Vec<Timestamp> = inputs.iter().map(|i| i.time).collect();
        crate::axis_for_times(&times).unwrap()
    }

    #[test]
    fn batches_carry_each_snapshots_changes_from_the_one_before() {
        let dir = tempfile::tempdir().unwrap();
        let context = Context::with_default_plugins();
        let maps = [
            snapshot(0.1, &[0, 1]),
            snapshot(0.1, &[0, 1]),
            snapshot(0.1, &[1, 2]),
        ];
        let inputs = write(dir.path(), &context, &maps);
        let axis = axis(&inputs);
        let checked = CheckedInputs {
            usable: vec![true; 3],
            ..CheckedInputs::default()
        };
        // Batches of two: the third file is compared with the second across the boundary.
        let mut extractor = extractor(&context, &inputs, &checked, &axis, false, 2);
        let batches: Vec<ChangeBatch> = extractor.by_ref().map(Result::unwrap).collect();
        assert_eq!(batches.len(), 2);
        let all: Vec<&SampleChanges> = batches.iter().flatten().collect();
        let samples: Vec<u32> = all.iter().map(|s| s.sample).collect();
        assert_eq!(samples, [0, 1, 2]);
        let expected =
            |before: &[Leaf], after: &Snapshot| froctomap_core::changes(before, after.leaves());
        assert_eq!(all[0].changes, expected(&[], &maps[0]));
        assert!(
            all[1].changes.is_empty(),
            "an identical file changes nothing"
        );
        assert_eq!(all[2].changes, expected(maps[1].leaves(), &maps[2]));
        let tally = extractor.finish();
        assert_eq!(tally.used, 3);
        assert_eq!(tally.resolution, Some(0.1), "the first file sets it");
        assert!(tally.skipped.is_empty() && tally.absent.is_empty());
    }

    #[test]
    fn a_file_of_another_resolution_is_refused_or_skipped() {
        let dir = tempfile::tempdir().unwrap();
        let context = Context::with_default_plugins();
        let maps = [
            snapshot(0.1, &[0]),
            snapshot(0.2, &[0]),
            snapshot(0.1, &[1]),
        ];
        let inputs = write(dir.path(), &context, &maps);
        let axis = axis(&inputs);
        let checked = CheckedInputs {
            usable: vec![true; 3],
            resolution: Some(0.1),
            resolution_file: Some(0),
            ..CheckedInputs::default()
        };
        let extractor = |skip_bad| extractor(&context, &inputs, &checked, &axis, skip_bad, 8);
        match extractor(false).next() {
            Some(Err(ConvertError::MixedResolution {
                first,
                second,
                second_resolution,
                ..
            })) => {
                assert_eq!(
                    (first, second),
                    (inputs[0].path.clone(), inputs[1].path.clone())
                );
                assert_eq!(second_resolution, 0.2);
            }
            other => panic!("{other:?}"),
        }
        let mut lenient = extractor(true);
        let batch = lenient.next().unwrap().unwrap();
        assert!(lenient.next().is_none());
        let samples: Vec<u32> = batch.iter().map(|s| s.sample).collect();
        assert_eq!(samples, [0, 2]);
        let tally = lenient.finish();
        assert_eq!(tally.absent, [1]);
        assert_eq!(tally.skipped[0].0, inputs[1].path);
        assert_eq!(
            tally.skipped[0].1,
            SnapshotError::Resolution {
                found: 0.2,
                series: 0.1
            }
            .to_string()
        );
    }
}
