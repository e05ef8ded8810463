//! A scenario as a front end assembles it from its options: a [`SeriesSpec`] read from JSON
//! (or the default one), then the values the user gave on top. One place for how options
//! combine, shared by `froctomap generate` and `froctomap-bench generate`.

use crate::error::SynthError;
use crate::spec::{frames_for, SeriesSpec};
use froctomap_core::Timestamp;
use std::path::{Path, PathBuf};

/// Values that replace a scenario's own, each only when given.
///
/// ```
/// use froctomap_synth::{SeriesSpec, SpecOverrides};
/// let spec = SpecOverrides {
///     step_secs: Some(1800.0),
///     days: Some(2.0),
///     seed: Some(7),
///     ..SpecOverrides::default()
/// }
/// .apply(SeriesSpec::default())?;
/// assert_eq!((spec.count, spec.seed), (96, 7));
/// # Ok::<(), froctomap_synth::SynthError>(())
/// ```
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SpecOverrides {
    /// Seconds between frames.
    pub step_secs: Option<f64>,
    /// Length of the series in days (frames at the step, see [`frames_for`]).
    pub days: Option<f64>,
    /// Number of grid frames (wins over `days`).
    pub count: Option<u64>,
    /// Time of the first frame.
    pub start: Option<Timestamp>,
    /// Seed of every random choice.
    pub seed: Option<u64>,
    /// Uniform jitter of each frame time, seconds.
    pub jitter_secs: Option<f64>,
    /// Probability that a frame is missed.
    pub missed_frames: Option<f64>,
    /// The real door recording: `Some(None)` for none (all doors on schedules).
    pub door_file: Option<Option<PathBuf>>,
    /// Doors.
    pub doors: Option<usize>,
    /// People.
    pub people: Option<usize>,
    /// Object slots.
    pub objects: Option<usize>,
    /// Machines.
    pub machines: Option<usize>,
    /// Per-frame flip probability of surface voxels.
    pub surface_noise: Option<f64>,
    /// Probability of a partial view.
    pub partial_probability: Option<f64>,
}

impl SpecOverrides {
    /// `spec` with the given values replaced, validated.
    pub fn apply(&self, mut spec: SeriesSpec) -> Result<SeriesSpec, SynthError> {
        if let Some(step) = self.step_secs {
            spec.step_secs = step;
        }
        match (self.count, self.days) {
            (Some(count), _) => spec.count = count,
            (None, Some(days)) => spec.count = frames_for(days, spec.step_secs),
            (None, None) => {}
        }
        let replace = |field: &mut f64, value: Option<f64>| {
            if let Some(v) = value {
                *field = v;
            }
        };
        replace(&mut spec.jitter_secs, self.jitter_secs);
        replace(&mut spec.missed_frames, self.missed_frames);
        replace(&mut spec.surface_noise, self.surface_noise);
        replace(&mut spec.partial_probability, self.partial_probability);
        for (field, value) in [
            (&mut spec.doors, self.doors),
            (&mut spec.people, self.people),
            (&mut spec.objects, self.objects),
            (&mut spec.machines, self.machines),
        ] {
            if let Some(v) = value {
                *field = v;
            }
        }
        if let Some(start) = self.start {
            spec.start = start;
        }
        if let Some(seed) = self.seed {
            spec.seed = seed;
        }
        if let Some(door_file) = &self.door_file {
            spec.door_file.clone_from(door_file);
        }
        spec.validate()?;
        Ok(spec)
    }
}

impl SeriesSpec {
    /// A scenario saved as JSON (a serialised `SeriesSpec`), not yet validated.
    pub fn from_json_file(path: &Path) -> Result<SeriesSpec, SynthError> {
        let text = std::fs::read_to_string(path).map_err(|source| SynthError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|source| SynthError::SpecJson {
            path: path.to_path_buf(),
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn count_wins_over_days_and_absent_values_keep_the_scenario() {
        let base = SeriesSpec::default();
        let spec = SpecOverrides {
            step_secs: Some(600.0),
            days: Some(1.0),
            count: Some(5),
            ..SpecOverrides::default()
        }
        .apply(base.clone())
        .unwrap();
        assert_eq!(spec.count, 5);
        assert_eq!(
            (spec.doors, spec.door_file.clone()),
            (base.doors, base.door_file.clone())
        );
        let none = SpecOverrides {
            door_file: Some(None),
            jitter_secs: Some(1.0),
            ..SpecOverrides::default()
        }
        .apply(base)
        .unwrap();
        assert_eq!((none.door_file, none.jitter_secs), (None, 1.0));
        let bad = SpecOverrides {
            missed_frames: Some(2.0),
            ..SpecOverrides::default()
        };
        assert!(bad.apply(SeriesSpec::default()).is_err());
    }

    #[test]
    fn a_scenario_that_is_not_json_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scenario.json");
        std::fs::write(&path, "{ not json").unwrap();
        let err = SeriesSpec::from_json_file(&path).unwrap_err();
        assert!(matches!(err, SynthError::SpecJson { .. }));
        assert!(err.to_string().contains("scenario.json"), "{err}");
    }
}
