//! Stage 1, input check: every input's header, read in parallel, so that an unreadable file
//! or a mixed resolution stops the build (or is left out with `skip_bad`) before anything is
//! decoded.
//!
//! In: the series. Out: [`CheckedInputs`], which inputs go on to extraction and the series'
//! resolution when a header gave it.

use crate::error::{ConvertError, SnapshotError};
use crate::inputs::SeriesInput;
use crate::progress::Progress;
use froctomap_formats::PROBE_BYTES;
use froctomap_octomap_codec::{detect_kind, parse_header, FileKind};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The header check of a series.
pub(crate) struct InputCheck {
    /// Leave unreadable files and files of another resolution out instead of stopping.
    pub skip_bad: bool,
}

/// What the header check decided.
#[derive(Debug, Default)]
pub(crate) struct CheckedInputs {
    /// Per input, `false` when it was left out.
    pub usable: Vec<bool>,
    /// Inputs left out, and why.
    pub skipped: Vec<(PathBuf, String)>,
    /// The series' resolution, from the first header that gives one, and that input's index.
    pub resolution: Option<(f64, usize)>,
}

impl InputCheck {
    /// Reads every input's header (in parallel, one progress unit each) and decides.
    /// Maps of a recording (`recorded`) have no header to check here: their reading decides.
    pub fn run(
        &self,
        inputs: &[SeriesInput],
        recorded: &(dyn Fn(&SeriesInput) -> bool + Sync),
        progress: &dyn Progress,
    ) -> Result<CheckedInputs, ConvertError> {
        progress.stage("checking inputs", inputs.len() as u64);
        let headers: Vec<Result<Option<f64>, SnapshotError>> = inputs
            .par_iter()
            .map(|input| {
                let resolution = if recorded(input) {
                    Ok(None)
                } else {
                    header_resolution(&input.path)
                };
                progress.advance(1);
                resolution
            })
            .collect();
        self.decide(inputs, headers)
    }

    /// Decides from each input's header resolution (`None`: the header does not tell).
    fn decide(
        &self,
        inputs: &[SeriesInput],
        headers: Vec<Result<Option<f64>, SnapshotError>>,
    ) -> Result<CheckedInputs, ConvertError> {
        let mut checked = CheckedInputs {
            usable: vec![true; inputs.len()],
            ..CheckedInputs::default()
        };
        for (i, header) in headers.into_iter().enumerate() {
            let refusal = match header {
                Ok(None) => continue,
                Ok(Some(found)) => match checked.resolution {
                    None => {
                        checked.resolution = Some((found, i));
                        continue;
                    }
                    Some((series, _)) if series == found => continue,
                    Some((series, first)) if !self.skip_bad => {
                        return Err(ConvertError::MixedResolution {
                            first: inputs[first].path.clone(),
                            first_resolution: series,
                            second: inputs[i].path.clone(),
                            second_resolution: found,
                        })
                    }
                    Some((series, _)) => SnapshotError::Resolution { found, series },
                },
                Err(reason) if !self.skip_bad => {
                    return Err(ConvertError::Snapshot {
                        path: inputs[i].path.clone(),
                        source: Arc::new(reason),
                    })
                }
                Err(reason) => reason,
            };
            checked
                .skipped
                .push((inputs[i].path.clone(), refusal.to_string()));
            checked.usable[i] = false;
        }
        Ok(checked)
    }
}

/// A file's resolution from its first bytes, when its format is OctoMap's.
fn header_resolution(path: &Path) -> Result<Option<f64>, SnapshotError> {
    use std::io::Read;
    let metadata = std::fs::metadata(path).map_err(SnapshotError::Io)?;
    super::refuse_special(path, &metadata)?;
    let mut head = Vec::with_capacity(PROBE_BYTES as usize);
    std::fs::File::open(path)
        .and_then(|f| f.take(PROBE_BYTES).read_to_end(&mut head))
        .map_err(SnapshotError::Io)?;
    if head.is_empty() {
        return Err(SnapshotError::Empty);
    }
    let kind = detect_kind(&head).unwrap_or(FileKind::Binary);
    match parse_header(&head, kind) {
        Ok(header) => Ok(Some(header.resolution)),
        // Not an OctoMap header (another format, or a long header): the full read decides.
        Err(_) => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::Timestamp;

    fn series(n: usize) -> Vec<SeriesInput> {
        (0..n)
            .map(|i| SeriesInput {
                path: PathBuf::from(format!("map{i}.bt")),
                time: Timestamp::from_secs(i as i64),
            })
            .collect()
    }

    #[test]
    fn the_first_resolution_found_is_the_series_and_others_are_refused_or_skipped() {
        let inputs = series(4);
        let headers = || vec![Ok(None), Ok(Some(0.1)), Ok(Some(0.1)), Ok(Some(0.05))];
        let strict = InputCheck { skip_bad: false };
        match strict.decide(&inputs, headers()) {
            Err(ConvertError::MixedResolution {
                first,
                first_resolution,
                second,
                second_resolution,
            }) => {
                assert_eq!(first, inputs[1].path);
                assert_eq!(second, inputs[3].path);
                assert_eq!((first_resolution, second_resolution), (0.1, 0.05));
            }
            other => panic!("{other:?}"),
        }
        let lenient = InputCheck { skip_bad: true };
        let checked = lenient.decide(&inputs, headers()).unwrap();
        assert_eq!(checked.usable, [true, true, true, false]);
        assert_eq!(checked.resolution, Some((0.1, 1)));
        assert_eq!(checked.skipped.len(), 1);
        assert_eq!(checked.skipped[0].0, inputs[3].path);
        assert_eq!(
            checked.skipped[0].1,
            "resolution 0.05 m differs from the series' 0.1 m"
        );
    }

    #[test]
    fn unreadable_headers_stop_the_build_or_are_skipped() {
        let inputs = series(3);
        let headers = || vec![Err(SnapshotError::Empty), Ok(Some(0.2)), Ok(None)];
        match (InputCheck { skip_bad: false }).decide(&inputs, headers()) {
            Err(ConvertError::Snapshot { path, source }) => {
                assert_eq!(path, inputs[0].path);
                assert!(matches!(*source, SnapshotError::Empty));
            }
            other => panic!("{other:?}"),
        }
        let checked = (InputCheck { skip_bad: true })
            .decide(&inputs, headers())
            .unwrap();
        assert_eq!(checked.usable, [false, true, true]);
        assert_eq!(checked.resolution, Some((0.2, 1)));
        assert_eq!(checked.skipped[0].1, SnapshotError::Empty.to_string());
    }

    #[test]
    fn headers_give_the_resolution_or_leave_it_to_the_full_read() {
        let dir = tempfile::tempdir().unwrap();
        let empty = dir.path().join("empty.bt");
        std::fs::write(&empty, b"").unwrap();
        assert!(matches!(
            header_resolution(&empty),
            Err(SnapshotError::Empty)
        ));
        let other = dir.path().join("other.xyz");
        std::fs::write(&other, b"not a map header").unwrap();
        assert_eq!(header_resolution(&other).unwrap(), None);
        let bt = dir.path().join("map.bt");
        std::fs::write(
            &bt,
            b"# Octomap OcTree binary file\nid OcTree\nsize 0\nres 0.05\ndata\n",
        )
        .unwrap();
        assert_eq!(header_resolution(&bt).unwrap(), Some(0.05));
        assert!(matches!(
            header_resolution(&dir.path().join("missing.bt")),
            Err(SnapshotError::Io(_))
        ));
    }
}
