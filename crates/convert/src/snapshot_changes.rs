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

/// The files of one batch, in time order, and the bytes of the last file accepted before it.
struct Batch<'b> {
    paths: &'b [&'b Path],
    raw: &'b [Result<Vec<u8>, Refusal>],
    carried_bytes: Option<&'b [u8]>,
}

impl<'b> Batch<'b> {
    /// The bytes of file `k`, or `None` when they could not be read.
    fn bytes(&self, k: usize) -> Option<&'b [u8]> {
        self.raw[k].as_deref().ok()
    }
}

/// The files of a batch once each knows the accepted file it follows (in time order).
struct Planned {
    plans: Vec<Plan>,
    /// What the differ kept of each file compared from its bytes.
    states: Vec<Option<DiffState>>,
    /// The leaves (and reader warnings) of the files that were decoded.
    decoded: Vec<Option<(Vec<Leaf>, Vec<String>)>>,
    /// The last file accepted so far.
    last: Option<usize>,
}

impl Planned {
    fn with_capacity(files: usize) -> Self {
        Self {
            plans: Vec::with_capacity(files),
            states: Vec::with_capacity(files),
            decoded: Vec::with_capacity(files),
            last: None,
        }
    }

    /// Records the plan of the next file, what the differ kept of it and its leaves.
    fn push(
        &mut self,
        plan: Plan,
        state: Option<DiffState>,
        leaves: Option<(Vec<Leaf>, Vec<String>)>,
    ) {
        if !matches!(plan, Plan::Failed(_)) {
            self.last = Some(self.plans.len());
        }
        self.plans.push(plan);
        self.states.push(state);
        self.decoded.push(leaves);
    }
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
        let batch = Batch {
            paths,
            raw,
            carried_bytes: carried.as_ref().and_then(|a| a.bytes.as_deref()),
        };
        let looks = self.first_looks(&batch);
        // In time order: which accepted file each one follows, and the byte comparisons.
        let mut planned = Planned::with_capacity(looks.len());
        for (k, look) in looks.into_iter().enumerate() {
            self.plan(&batch, &mut planned, k, look, &mut carried_state);
        }
        let Planned {
            plans,
            mut states,
            mut decoded,
            last,
        } = planned;
        let carried_leaves = carried.as_ref().and_then(Accepted::leaves);
        let outcomes = self.compare_leaves(&batch, plans, &decoded, carried_leaves);
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

    /// The parallel stage: which files repeat their predecessor, which compare from their
    /// bytes, and the leaves of the others.
    fn first_looks(&self, batch: &Batch<'_>) -> Vec<Result<FirstLook, Refusal>> {
        (0..batch.raw.len())
            .into_par_iter()
            .map(|k| {
                let bytes = batch.raw[k].as_ref().map_err(Clone::clone)?;
                let before = match k {
                    0 => batch.carried_bytes,
                    _ => batch.bytes(k - 1),
                };
                if before == Some(bytes.as_slice()) {
                    return Ok(FirstLook::Same);
                }
                match self.registry.format_of(batch.paths[k], bytes, self.options) {
                    Ok(format) if format.differ.is_some() => Ok(FirstLook::Comparable),
                    _ => {
                        let (leaves, warnings) =
                            self.read_leaves(batch.paths[k], bytes).map_err(Arc::new)?;
                        Ok(FirstLook::Leaves(leaves, warnings))
                    }
                }
            })
            .collect()
    }

    /// Plans file `k` of the batch after its first `look`, comparing it from its bytes with
    /// the last accepted file where the format allows.
    fn plan(
        &self,
        batch: &Batch<'_>,
        planned: &mut Planned,
        k: usize,
        look: Result<FirstLook, Refusal>,
        carried_state: &mut Option<DiffState>,
    ) {
        let mut state = None;
        let mut leaves = None;
        let plan = match look {
            Err(reason) => Plan::Failed(reason),
            Ok(FirstLook::Same) => match k.checked_sub(1).map(|j| &planned.plans[j]) {
                Some(Plan::Failed(reason)) => match reason.as_ref() {
                    SnapshotError::SameAsRefused(_) => Plan::Failed(reason.clone()),
                    _ => Plan::Failed(Arc::new(SnapshotError::SameAsRefused(reason.clone()))),
                },
                _ => {
                    // The same bytes: what the differ kept of the predecessor holds.
                    state = match k {
                        0 => carried_state.take(),
                        _ => planned.states[k - 1].take(),
                    };
                    Plan::Done(FileChanges {
                        changes: Vec::new(),
                        warnings: Vec::new(),
                    })
                }
            },
            Ok(FirstLook::Leaves(read, warnings)) => {
                leaves = Some((read, warnings));
                Plan::CompareWith(planned.last)
            }
            Ok(FirstLook::Comparable) => {
                let before = match planned.last {
                    Some(j) => batch.bytes(j).map(|bytes| PreviousFile {
                        bytes,
                        state: planned.states[j].as_ref(),
                    }),
                    None => batch.carried_bytes.map(|bytes| PreviousFile {
                        bytes,
                        state: carried_state.as_ref(),
                    }),
                };
                let bytes = batch.bytes(k).unwrap_or_default();
                match self.compare_bytes(batch.paths[k], before, bytes) {
                    Ok(Some((changes, diff))) => {
                        state = diff.state;
                        Plan::Done(FileChanges {
                            changes,
                            warnings: diff.warnings,
                        })
                    }
                    // The file before is of another format.
                    Ok(None) => match self.read_leaves(batch.paths[k], bytes) {
                        Ok(read) => {
                            leaves = Some(read);
                            Plan::CompareWith(planned.last)
                        }
                        Err(reason) => Plan::Failed(Arc::new(reason)),
                    },
                    Err(reason) => Plan::Failed(Arc::new(reason)),
                }
            }
        };
        planned.push(plan, state, leaves);
    }

    /// The last stage: leaves compared with their predecessor's, in parallel
    /// (`carried_leaves`: those of the file carried from earlier batches, if decoded).
    fn compare_leaves(
        &self,
        batch: &Batch<'_>,
        plans: Vec<Plan>,
        decoded: &[Option<(Vec<Leaf>, Vec<String>)>],
        carried_leaves: Option<&[Leaf]>,
    ) -> Vec<Result<FileChanges, Refusal>> {
        plans
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
                            batch.bytes(j),
                            decoded[j].as_ref().map(|(l, _)| l.as_slice()),
                        ),
                        None => (batch.carried_bytes, carried_leaves),
                    };
                    let before = self
                        .leaves_before(batch.paths[k], before_bytes, before_leaves)
                        .map_err(Arc::new)?;
                    Ok(FileChanges {
                        changes: changes(&before, leaves),
                        warnings: warnings.clone(),
                    })
                }
            })
            .collect()
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
