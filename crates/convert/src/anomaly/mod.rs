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

mod options;
mod regions;
mod report;
mod score;

use crate::context::Context;
use crate::error::ConvertError;
use froctomap_core::{Snapshot, Timestamp};
use froctomap_file::FroctReader;
use froctomap_formats::ReadOptions;
use rayon::prelude::*;
use score::Scorer;
use std::path::Path;
use std::sync::Arc;

pub use options::{AnomalyOptions, Expectation};
pub use report::{AnomalyKind, AnomalyRegion, AnomalyReport};

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
