//! Inputs left out with `skip_bad`: each with a typed reason a caller can route on (its
//! stable [`SkipReason::code`]) and the human message of the problem.
//!
//! The JSON of a [`SkippedInput`] (in `froctomap build --json`, `append --json` and the
//! Python reports) is `{"path": "...", "code": "...", "message": "..."}`.

use froctomap_core::Named;
use serde::{Serialize, Serializer};
use std::path::PathBuf;

/// Why an input was left out. Its [`code`](Self::code) is stable: scripts may match on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum SkipReason {
    /// The file could not be read (an I/O error, or not a regular file).
    Unreadable,
    /// The file is empty.
    Empty,
    /// The file is over a limit for one map (its bytes, or the tiles its known space covers).
    TooLarge,
    /// No registered format reads it (or it holds a series of maps, not one map).
    NotAMap,
    /// Its format recognised it but it is malformed (truncated, corrupt).
    Malformed,
    /// Its format reads it but its byte-level comparison refused it.
    NotCompared,
    /// Its resolution is not the series'.
    ResolutionMismatch,
    /// A damaged part of a recording, or a recorded map that could not be fetched.
    DamagedRecording,
    /// A fault of froctomap itself.
    Internal,
}

impl SkipReason {
    /// The stable machine name, as the JSON reports give it (its [`Named::name`]).
    pub fn code(self) -> &'static str {
        self.name()
    }
}

impl Named for SkipReason {
    const ALL: &'static [Self] = &[
        Self::Unreadable,
        Self::Empty,
        Self::TooLarge,
        Self::NotAMap,
        Self::Malformed,
        Self::NotCompared,
        Self::ResolutionMismatch,
        Self::DamagedRecording,
        Self::Internal,
    ];
    const WHAT: &'static str = "skip reason";

    fn name(self) -> &'static str {
        match self {
            Self::Unreadable => "unreadable",
            Self::Empty => "empty",
            Self::TooLarge => "too-large",
            Self::NotAMap => "not-a-map",
            Self::Malformed => "malformed",
            Self::NotCompared => "not-compared",
            Self::ResolutionMismatch => "resolution-mismatch",
            Self::DamagedRecording => "damaged-recording",
            Self::Internal => "internal",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Self::Unreadable => "The file could not be read",
            Self::Empty => "The file is empty",
            Self::TooLarge => "The file is over a limit for one map",
            Self::NotAMap => "No registered format reads it",
            Self::Malformed => "Its format recognised it but it is malformed",
            Self::NotCompared => "Its format's byte-level comparison refused it",
            Self::ResolutionMismatch => "Its resolution is not the series'",
            Self::DamagedRecording => "A damaged part of a recording",
            Self::Internal => "A fault of froctomap itself",
        }
    }
}

impl std::fmt::Display for SkipReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.code())
    }
}

impl std::str::FromStr for SkipReason {
    type Err = froctomap_core::UnknownName;

    fn from_str(code: &str) -> Result<Self, Self::Err> {
        froctomap_core::parse_named(code)
    }
}

impl Serialize for SkipReason {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.code())
    }
}

/// An input (a file, or the recording a damaged part came from) left out with `skip_bad`.
/// Displayed as `PATH: MESSAGE` (the path once); its JSON is `{"path", "code", "message"}`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[non_exhaustive]
pub struct SkippedInput {
    /// The input.
    pub path: PathBuf,
    /// Why, for routing.
    #[serde(rename = "code")]
    pub reason: SkipReason,
    /// Why, for people: the problem's own message.
    pub message: String,
}

impl SkippedInput {
    /// An input left out for `reason`, said by `message`.
    pub fn new(path: PathBuf, reason: SkipReason, message: String) -> Self {
        Self {
            path,
            reason,
            message,
        }
    }

    /// A damaged part of the recording at `path` its reader left out.
    pub fn recording_part(path: PathBuf, problem: &(dyn std::error::Error + 'static)) -> Self {
        Self::new(
            path,
            SkipReason::DamagedRecording,
            froctomap_core::error_message(problem),
        )
    }

    /// The stable code of its reason.
    pub fn code(&self) -> &'static str {
        self.reason.code()
    }
}

impl std::fmt::Display for SkippedInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Many messages (a format's, a recorded map's) name the input already.
        let name = self.path.display().to_string();
        match self.message.strip_prefix(&name) {
            Some(rest) if rest.starts_with(": ") => f.write_str(&self.message),
            _ => write!(f, "{name}: {}", self.message),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_unique_and_parse_back() {
        for &reason in SkipReason::ALL {
            assert_eq!(reason.code().parse::<SkipReason>(), Ok(reason));
            let same: Vec<_> = SkipReason::ALL
                .iter()
                .filter(|r| r.code() == reason.code())
                .collect();
            assert_eq!(same.len(), 1, "{reason:?}");
        }
        assert!("older".parse::<SkipReason>().is_err());
    }

    #[test]
    fn a_skipped_input_is_an_object_of_path_code_and_message() {
        let skipped = SkippedInput::new(
            PathBuf::from("a/map_1.bt"),
            SkipReason::ResolutionMismatch,
            "resolution 0.05 m differs from the series' 0.1 m".to_string(),
        );
        assert_eq!(
            serde_json::to_value(&skipped).unwrap(),
            serde_json::json!({
                "path": "a/map_1.bt",
                "code": "resolution-mismatch",
                "message": "resolution 0.05 m differs from the series' 0.1 m",
            })
        );
        assert_eq!(
            skipped.to_string(),
            "a/map_1.bt: resolution 0.05 m differs from the series' 0.1 m"
        );
        let named = "a/map_1.bt: not a map file of any known format (empty)";
        let skipped = SkippedInput::new(
            PathBuf::from("a/map_1.bt"),
            SkipReason::NotAMap,
            named.to_string(),
        );
        assert_eq!(skipped.to_string(), named);
    }
}
