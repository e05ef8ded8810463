//! What an anomaly search reports: connected regions of surprising voxels, their kind, and
//! the report holding them.

use crate::error::ConvertError;
use froctomap_core::{occupied_log_odds, Leaf, MortonCode, Snapshot, Timestamp};

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

/// What [`anomalies`](super::anomalies) found.
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

#[cfg(test)]
mod tests {
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
