//! Each snapshot of a series as its changes from the one before, computed in parallel.
//!
//! Where the format can compare two files from their bytes (OctoMap's `.bt`/`.ot` through the
//! native codec), consecutive files are compared without decoding either, which is most of
//! the reading work of a build; other formats are read into leaves and compared with
//! [`froctomap_core::changes`]. Either way the result is the same list of changes.

use crate::error::SnapshotError;
use froctomap_core::{changes, Leaf, Snapshot, StateChange};
use froctomap_formats::{DiffState, FormatRegistry, MapDiff, PreviousFile, ReadOptions};
use rayon::prelude::*;
use std::borrow::Cow;
use std::path::Path;
use std::sync::Arc;

/// Why a file was refused, shared with the files byte-identical to it.
pub(crate) type Refusal = Arc<SnapshotError>;

/// A file accepted into the series, its changes from the file accepted before it.
#[derive(Debug)]
pub(crate) struct FileChanges {
    /// Ranges whose state changed (empty for a file identical to its predecessor).
    pub changes: Vec<StateChange>,
    /// What the reader tolerated.
    pub warnings: Vec<String>,
}

/// The last file accepted, carried from one batch to the next.
#[derive(Default)]
pub(crate) struct Accepted {
    /// Its bytes; `None` for a map not read from a file, until they are written.
    bytes: Option<Vec<u8>>,
    /// Its leaves, when it had to be decoded.
    leaves: Option<Vec<Leaf>>,
    /// What its format's differ kept, when it was compared from the bytes.
    state: Option<DiffState>,
    /// The map itself, when it was not read from a file.
    map: Option<Snapshot>,
}

impl Accepted {
    /// A map that was not read from a file (an existing `.froct`'s last observed map, which
    /// an append continues from): its leaves, and, once the first file to be compared with
    /// it is seen, its bytes in that file's format when the format compares files from
    /// their bytes ([`ChangeReader::batch`]).
    pub fn from_map(map: Snapshot) -> Self {
        Self {
            map: Some(map),
            ..Self::default()
        }
    }

    /// Its leaves, when at hand.
    fn leaves(&self) -> Option<&[Leaf]> {
        (self.leaves.as_deref()).or_else(|| self.map.as_ref().map(Snapshot::leaves))
    }
}

/// One file after the parallel stage.
enum FirstLook {
    /// Byte-identical to the file before it.
    Same,
    /// Of a format that compares files from their bytes: compared in time order next.
    Comparable,
    /// Decoded (its format has no byte-level comparison).
    Leaves(Vec<Leaf>, Vec<String>),
}

/// What is left to do for a file once its predecessor is known.
enum Plan {
    Done(FileChanges),
    /// Compare its decoded leaves with this accepted file's (`None`: the one carried from
    /// earlier batches).
    CompareWith(Option<usize>),
    Failed(Refusal),
}

/// Turns batches of files into changes.
pub(crate) struct ChangeReader<'a> {
    pub registry: &'a FormatRegistry,
    pub options: ReadOptions<'a>,
    /// The series' resolution; files of another are refused.
    pub resolution: Option<f64>,
}

impl ChangeReader<'_> {
    /// For each file of a batch (in time order, with its bytes or why they could not be read)
    /// its changes from the last file before it that was accepted, or why it is refused. A
    /// file identical to its predecessor shares its fate. `carried` holds the last file
    /// accepted by earlier batches and is updated.
    ///
    /// Files whose format compares files from their bytes are compared in time order, each
    /// with the one before, reusing what the differ kept of that one; other files are decoded
    /// and their leaves compared, in parallel.
    pub fn batch(
        &self,
        paths: &[&Path],
        raw: &[Result<Vec<u8>, Refusal>],
        carried: &mut Option<Accepted>,
    ) -> Vec<Result<FileChanges, Refusal>> {
        if let (Some(accepted), Some(&path), Some(Ok(bytes))) =
            (carried.as_mut(), paths.first(), raw.first())
        {
            self.write_unwritten(accepted, path, bytes);
        }
        let mut carried_state = carried.as_mut().and_then(|a| a.state.take());
        let carried_bytes = carried.as_ref().and_then(|a| a.bytes.as_deref());
        let looks: Vec<Result<FirstLook, Refusal>> = (0..raw.len())
            .into_par_iter()
            .map(|k| {
                let bytes = raw[k].as_ref().map_err(Clone::clone)?;
                let before = match k {
                    0 => carried_bytes,
                    _ => raw[k - 1].as_deref().ok(),
                };
                if before == Some(bytes.as_slice()) {
                    return Ok(FirstLook::Same);
                }
                match self.registry.format_of(paths[k], bytes, self.options) {
                    Ok(format) if format.differ.is_some() => Ok(FirstLook::Comparable),
                    _ => {
                        let (leaves, warnings) =
                            self.read_leaves(paths[k], bytes).map_err(Arc::new)?;
                        Ok(FirstLook::Leaves(leaves, warnings))
                    }
                }
            })
            .collect();
        // In time order: which accepted file each one follows, and the byte comparisons.
        let mut plans: Vec<Plan> = Vec::with_capacity(looks.len());
        let mut last: Option<usize> = None;
        let mut states: Vec<Option<DiffState>> = Vec::with_capacity(looks.len());
        // The leaves (and reader warnings) of the files that were decoded.
        let mut decoded: Vec<Option<(Vec<Leaf>, Vec<String>)>> = Vec::with_capacity(looks.len());
        for (k, look) in looks.into_iter().enumerate() {
            let mut state = None;
            let mut leaves = None;
            let plan = match look {
                Err(reason) => Plan::Failed(reason),
                Ok(FirstLook::Same) => match k.checked_sub(1).map(|j| &plans[j]) {
                    Some(Plan::Failed(reason)) => match reason.as_ref() {
                        SnapshotError::SameAsRefused(_) => Plan::Failed(reason.clone()),
                        _ => Plan::Failed(Arc::new(SnapshotError::SameAsRefused(reason.clone()))),
                    },
                    _ => {
                        // The same bytes: what the differ kept of the predecessor holds.
                        state = match k {
                            0 => carried_state.take(),
                            _ => states[k - 1].take(),
                        };
                        Plan::Done(FileChanges {
                            changes: Vec::new(),
                            warnings: Vec::new(),
                        })
                    }
                },
                Ok(FirstLook::Leaves(read, warnings)) => {
                    leaves = Some((read, warnings));
                    Plan::CompareWith(last)
                }
                Ok(FirstLook::Comparable) => {
                    let before = match last {
                        Some(j) => raw[j].as_deref().ok().map(|bytes| PreviousFile {
                            bytes,
                            state: states[j].as_ref(),
                        }),
                        None => carried_bytes.map(|bytes| PreviousFile {
                            bytes,
                            state: carried_state.as_ref(),
                        }),
                    };
                    let bytes = raw[k].as_deref().unwrap_or_default();
                    match self.compare_bytes(paths[k], before, bytes) {
                        Ok(Some((changes, diff))) => {
                            state = diff.state;
                            Plan::Done(FileChanges {
                                changes,
                                warnings: diff.warnings,
                            })
                        }
                        // The file before is of another format.
                        Ok(None) => match self.read_leaves(paths[k], bytes) {
                            Ok(read) => {
                                leaves = Some(read);
                                Plan::CompareWith(last)
                            }
                            Err(reason) => Plan::Failed(Arc::new(reason)),
                        },
                        Err(reason) => Plan::Failed(Arc::new(reason)),
                    }
                }
            };
            if !matches!(plan, Plan::Failed(_)) {
                last = Some(k);
            }
            plans.push(plan);
            states.push(state);
            decoded.push(leaves);
        }
        // Leaves compared with their predecessor's, in parallel.
        let outcomes: Vec<Result<FileChanges, Refusal>> = plans
            .into_par_iter()
            .enumerate()
            .map(|(k, plan)| match plan {
                Plan::Done(done) => Ok(done),
                Plan::Failed(reason) => Err(reason),
                Plan::CompareWith(j) => {
                    let (leaves, warnings) = decoded[k].as_ref().ok_or_else(|| {
                        Arc::new(SnapshotError::Internal(
                            "a file to compare by its leaves was not decoded",
                        ))
                    })?;
                    let (before_bytes, before_leaves) = match j {
                        Some(j) => (
                            raw[j].as_deref().ok(),
                            decoded[j].as_ref().map(|(l, _)| l.as_slice()),
                        ),
                        None => (carried_bytes, carried.as_ref().and_then(Accepted::leaves)),
                    };
                    let before = self
                        .leaves_before(paths[k], before_bytes, before_leaves)
                        .map_err(Arc::new)?;
                    Ok(FileChanges {
                        changes: changes(&before, leaves),
                        warnings: warnings.clone(),
                    })
                }
            })
            .collect();
        // Carry the last accepted file into the next batch.
        match last {
            Some(j) => {
                if let Ok(bytes) = &raw[j] {
                    *carried = Some(Accepted {
                        bytes: Some(bytes.clone()),
                        leaves: decoded[j].take().map(|(leaves, _)| leaves),
                        state: states[j].take(),
                        map: None,
                    });
                }
            }
            None => {
                if let Some(accepted) = carried {
                    accepted.state = carried_state;
                }
            }
        }
        outcomes
    }

    /// Writes a map not read from a file (`accepted`) in the format of `bytes`, the first
    /// file to be compared with it, when that format compares files from their bytes: the
    /// file is then compared from the bytes too (its format's own [`MapWriter`] wrote the
    /// map, so no format is named here). Otherwise, or when the writer fails, the map stays
    /// leaves only and the file is decoded and compared by its leaves.
    ///
    /// [`MapWriter`]: froctomap_formats::MapWriter
    fn write_unwritten(&self, accepted: &mut Accepted, path: &Path, bytes: &[u8]) {
        let (None, Some(map)) = (&accepted.bytes, &accepted.map) else {
            return;
        };
        let Ok(format) = self.registry.format_of(path, bytes, self.options) else {
            return;
        };
        let (Some(_), Some(make_writer)) = (format.differ, format.writer) else {
            return;
        };
        let mut written = Vec::new();
        if make_writer().write(map, &mut written).is_ok() {
            accepted.bytes = Some(written);
        }
    }

    /// Compares from the bytes; `Ok(None)` when the formats do not allow it. A file the
    /// differ refuses is read to have the reader word the error.
    fn compare_bytes(
        &self,
        path: &Path,
        before: Option<PreviousFile<'_>>,
        bytes: &[u8],
    ) -> Result<Option<(Vec<StateChange>, MapDiff)>, SnapshotError> {
        let mut changes = Vec::new();
        let compared = self
            .registry
            .diff_bytes(path, before, bytes, self.options, &mut |c| changes.push(c));
        match compared {
            Ok(Some(outcome)) => {
                self.check_resolution(outcome.diff.resolution)?;
                Ok(Some((changes, outcome.diff)))
            }
            Ok(None) => Ok(None),
            Err(error) => match self.read_leaves(path, bytes) {
                Err(reason) => Err(reason),
                Ok(_) => Err(SnapshotError::NotCompared(error)),
            },
        }
    }

    fn leaves_before<'b>(
        &self,
        path: &Path,
        bytes: Option<&[u8]>,
        leaves: Option<&'b [Leaf]>,
    ) -> Result<Cow<'b, [Leaf]>, SnapshotError> {
        Ok(match (leaves, bytes) {
            (Some(leaves), _) => Cow::Borrowed(leaves),
            (None, Some(bytes)) => Cow::Owned(self.read_leaves(path, bytes)?.0),
            (None, None) => Cow::Borrowed(&[]),
        })
    }

    fn read_leaves(
        &self,
        path: &Path,
        bytes: &[u8],
    ) -> Result<(Vec<Leaf>, Vec<String>), SnapshotError> {
        let read = self
            .registry
            .read_bytes(path, bytes, self.options)
            .map_err(SnapshotError::Format)?;
        self.check_resolution(read.map.snapshot.resolution())?;
        Ok((read.map.snapshot.into_leaves(), read.map.warnings))
    }

    fn check_resolution(&self, resolution: f64) -> Result<(), SnapshotError> {
        match self.resolution {
            Some(series) if series != resolution => Err(SnapshotError::Resolution {
                found: resolution,
                series,
            }),
            _ => Ok(()),
        }
    }
}
