//! Anomalies: what a new snapshot shows that the file's model did not expect.
//!
//! Every observed voxel of the snapshot is scored by its *surprise* under the model at the
//! snapshot's time, `−ln P(observed state)`: a dynamic cell's `p(t)` (kept within the error
//! rate of 0 and 1); a static cell's stored state, wrong at the rule of succession's rate
//! `1 / (n + 2)` after `n` observations (at most [`AnomalyOptions::error_rate`]); a noisy
//! cell's state, wrong at `(k + 1) / (n + 2)` after `k` exceptions; and space the file never
//! observed as if it were static free at the error rate (occupied there is surprising, free
//! tells nothing). Voxels above [`AnomalyOptions::voxel_threshold`] are grouped into
//! connected regions of one kind (appeared: occupied where free was expected; vanished:
//! free where occupied was). A region's score is the log-likelihood ratio of its voxels'
//! states between a vague alternative that gives each the threshold probability and the
//! model: the surprise beyond the threshold, summed. Regions of at least
//! [`AnomalyOptions::min_region_score`] are reported, most surprising first.
//!
//! The snapshot is held whole; the file is read one tile at a time (tiles in parallel).

mod regions;
mod score;

use crate::context::Context;
use crate::error::ConvertError;
use froctomap_core::{occupied_log_odds, Leaf, MortonCode, Snapshot, Timestamp};
use froctomap_file::FroctReader;
use froctomap_formats::ReadOptions;
use rayon::prelude::*;
use score::Scorer;
use std::path::Path;
use std::sync::Arc;

/// What a surprising region shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum AnomalyKind {
    /// Occupied where the model expected free space (or where nothing was ever seen).
    Appeared,
    /// Free where the model expected something.
    Vanished,
}

impl AnomalyKind {
    /// The kind as in JSON (`appeared`, `vanished`).
    pub fn name(self) -> &'static str {
        match self {
            AnomalyKind::Appeared => "appeared",
            AnomalyKind::Vanished => "vanished",
        }
    }
}

impl std::fmt::Display for AnomalyKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What a snapshot is compared with: the model at its time, or one of the simple
/// baselines the model has to beat.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Expectation {
    /// The file's model at the snapshot's time (static cells: their state).
    #[default]
    Model,
    /// Each cell's mean occupancy over the file's history, whatever the time.
    StaticMean,
    /// Each cell's state at the last snapshot at or before the time (the last seen map);
    /// cells not observed there count as never seen.
    LastSeen,
}

/// Thresholds of [`anomalies`]. Surprises are in nats (`−ln p`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct AnomalyOptions {
    /// The most a static cell's stored state is taken to be wrong in a new snapshot (less
    /// after many observations), how close to 0 or 1 a model's `p(t)` may get, and how
    /// likely occupied is in space never observed (default 0.01).
    pub error_rate: f64,
    /// A voxel is surprising above this surprise (default `ln 5` ≈ 1.6: the model gave its
    /// state less than a 20 % chance; FreMEn's few smooth periodic terms rarely go below
    /// that around a change, even for a door open at that hour every day).
    pub voxel_threshold: f64,
    /// Regions whose score (surprise beyond the voxel threshold, summed) is below this are
    /// not reported (default 20 nats, a few voxels of static structure flipped: single
    /// noisy voxels stay quiet).
    pub min_region_score: f64,
    /// What the snapshot is compared with (default the model).
    pub expectation: Expectation,
}

impl Default for AnomalyOptions {
    fn default() -> Self {
        Self {
            error_rate: 0.01,
            voxel_threshold: 5f64.ln(),
            min_region_score: 20.0,
            expectation: Expectation::Model,
        }
    }
}

impl AnomalyOptions {
    fn check(&self) -> Result<(), ConvertError> {
        let bad = |what: &'static str, value: f64| ConvertError::BadAnomalyOption { what, value };
        if !(self.error_rate > 0.0 && self.error_rate < 0.5) {
            return Err(bad("error rate (0 < rate < 0.5)", self.error_rate));
        }
        if !(self.voxel_threshold.is_finite() && self.voxel_threshold >= 0.0) {
            return Err(bad("voxel threshold (nats, ≥ 0)", self.voxel_threshold));
        }
        if !(self.min_region_score.is_finite() && self.min_region_score >= 0.0) {
            return Err(bad(
                "minimum region score (nats, ≥ 0)",
                self.min_region_score,
            ));
        }
        Ok(())
    }
}

/// One connected region of surprising voxels.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[non_exhaustive]
pub struct AnomalyRegion {
    /// Minimum corner of its bounding box, metres.
    pub min: [f64; 3],
    /// Maximum corner, metres.
    pub max: [f64; 3],
    /// Voxels in it.
    pub voxels: u64,
    /// Its voxels' surprise beyond the voxel threshold, summed, nats.
    pub score: f64,
    /// What it shows.
    pub kind: AnomalyKind,
    /// Its voxels as aligned cubes (Morton start, depth).
    #[serde(skip)]
    pub cubes: Vec<(MortonCode, u8)>,
}

/// What [`anomalies`] found.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct AnomalyReport {
    /// The instant the snapshot was scored at.
    pub time: Timestamp,
    /// Observed voxels of the snapshot.
    pub scored_voxels: u64,
    /// Voxels above the voxel threshold (in reported regions or not).
    pub surprising_voxels: u64,
    /// Regions of at least the minimum score, most surprising first.
    pub regions: Vec<AnomalyRegion>,
}

impl AnomalyReport {
    /// The voxels of the reported regions as an occupied map of `resolution` (what `-o`
    /// writes for rviz/octovis; vanished voxels are occupied too, so that viewers show them).
    pub fn to_map(&self, resolution: f64) -> Result<Snapshot, ConvertError> {
        let leaves = self
            .regions
            .iter()
            .flat_map(|r| &r.cubes)
            .map(|&(start, depth)| Leaf {
                start,
                depth,
                log_odds: occupied_log_odds(),
            })
            .collect();
        Snapshot::from_leaves(resolution, leaves).map_err(|e| ConvertError::Internal {
            what: "anomalous voxels overlap",
            source: Some(Box::new(e)),
        })
    }
}

/// Scores `snapshot` (of the file's resolution) against the file's model at `t` and returns
/// its surprising regions. The file is read one tile at a time.
///
/// ```no_run
/// use froctomap_convert::*;
/// use std::path::Path;
/// let context = Context::with_default_plugins();
/// let reader = context.open_froct(Path::new("office.froct"))?;
/// let now = Path::new("scan_2016-01-20T10-00-00.bt");
/// let snapshot = read_snapshot(&context, &reader, now)?;
/// let t = time_from_file_name("scan_2016-01-20T10-00-00.bt").unwrap();
/// let report = anomalies(&reader, &snapshot, t, &AnomalyOptions::default())?;
/// for region in &report.regions {
///     println!("{:?} {:?}..{:?} {:.1}", region.kind, region.min, region.max, region.score);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn anomalies(
    reader: &FroctReader,
    snapshot: &Snapshot,
    t: Timestamp,
    options: &AnomalyOptions,
) -> Result<AnomalyReport, ConvertError> {
    options.check()?;
    check_time(reader, t)?;
    let header = reader.header();
    if snapshot.resolution() != header.resolution {
        return Err(ConvertError::SnapshotResolution {
            snapshot: None,
            resolution: snapshot.resolution(),
            file: reader.path().to_path_buf(),
            file_resolution: header.resolution,
        });
    }
    let scorer = Scorer {
        model: reader.model(),
        axis: &header.axis,
        seconds: t.secs_since(header.axis.start()),
        last_seen: header.axis.last_at_or_before(t),
        options,
    };
    let leaves = snapshot.leaves();
    let mut pieces: Vec<score::Piece> = (0..reader.tiles().len())
        .into_par_iter()
        .map(|tile| score::score_tile(reader, tile, leaves, &scorer))
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .flatten()
        .collect();
    pieces.extend(score::score_outside_tiles(reader, leaves, &scorer));
    let stats = snapshot.stats();
    let surprising_voxels = pieces.iter().map(score::Piece::voxels).sum();
    let mut regions: Vec<AnomalyRegion> = [AnomalyKind::Appeared, AnomalyKind::Vanished]
        .into_iter()
        .flat_map(|kind| {
            regions::regions(&pieces, kind, header.resolution, options.voxel_threshold)
        })
        .filter(|r| r.score >= options.min_region_score)
        .collect();
    regions.sort_by(|a, b| {
        b.score.total_cmp(&a.score).then(
            a.min
                .partial_cmp(&b.min)
                .unwrap_or(std::cmp::Ordering::Equal),
        )
    });
    Ok(AnomalyReport {
        time: t,
        scored_voxels: stats.occupied_voxels + stats.free_voxels,
        surprising_voxels,
        regions,
    })
}

/// Reads a snapshot to score against `reader`'s file: errors name the snapshot (unreadable,
/// not a map, too large, another resolution).
pub fn read_snapshot(
    context: &Context,
    reader: &FroctReader,
    path: &Path,
) -> Result<Snapshot, ConvertError> {
    let bytes =
        crate::files::read_input(path, context.limits().max_map_file_bytes).map_err(|e| {
            ConvertError::Snapshot {
                path: path.to_path_buf(),
                source: Arc::new(e),
            }
        })?;
    let snapshot = context
        .formats()
        .read_bytes(path, &bytes, ReadOptions::default())
        .map_err(ConvertError::Read)?
        .map
        .snapshot;
    let resolution = reader.header().resolution;
    if snapshot.resolution() != resolution {
        return Err(ConvertError::SnapshotResolution {
            snapshot: Some(path.to_path_buf()),
            resolution: snapshot.resolution(),
            file: reader.path().to_path_buf(),
            file_resolution: resolution,
        });
    }
    Ok(snapshot.into_max_likelihood())
}

/// The model knows nothing before the file's first snapshot: anomalies are judged at or
/// after it (any later instant is a prediction).
fn check_time(reader: &FroctReader, t: Timestamp) -> Result<(), ConvertError> {
    let axis = &reader.header().axis;
    crate::time::check_range("the snapshot's time", t)?;
    if t < axis.start() {
        return Err(ConvertError::AnomalyTimeBeforeFile {
            file: reader.path().to_path_buf(),
            time: t,
            start: axis.start(),
            end: axis.end(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod kind_tests {
    use super::AnomalyKind;

    #[test]
    fn kind_names_are_the_json_names() {
        for kind in [AnomalyKind::Appeared, AnomalyKind::Vanished] {
            let json = serde_json::to_value(kind).unwrap_or_default();
            assert_eq!(json.as_str(), Some(kind.name()));
            assert_eq!(kind.to_string(), kind.name());
        }
    }
}
