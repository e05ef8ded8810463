//! Stage 1, input check: every input's header, read in parallel by its format's header hook
//! ([`MapFormat::header`](froctomap_formats::MapFormat::header)), so that an unreadable file
//! or a mixed resolution stops the build (or is left out with `skip_bad`) before anything is
//! decoded.
//!
//! In: the series. Out: [`CheckedInputs`], which inputs go on to extraction and the series'
//! resolution when a header gave it.

use crate::error::{ConvertError, SnapshotError};
use crate::inputs::SeriesInput;
use crate::progress::Progress;
use froctomap_core::{voxels_per_node, StateChange};
use froctomap_formats::{FormatRegistry, ReadOptions, PROBE_BYTES};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The header check of a series.
pub(crate) struct InputCheck<'a> {
    /// The formats that read the headers.
    pub formats: &'a FormatRegistry,
    /// How the inputs are read (a forced format).
    pub read: ReadOptions<'a>,
    /// Leave unreadable files and files of another resolution out instead of stopping.
    pub skip_bad: bool,
    /// The series' resolution as the user gave it; `None`: the one most headers give.
    pub resolution: Option<f64>,
    /// Go on with `skip_bad` when more than half of the inputs are left out.
    pub allow_mostly_skipped: bool,
}

/// What the header check decided.
#[derive(Debug, Default)]
pub(crate) struct CheckedInputs {
    /// Per input, `false` when it was left out.
    pub usable: Vec<bool>,
    /// Inputs left out, and why.
    pub skipped: Vec<(PathBuf, String)>,
    /// The series' resolution: the one given, else the one most headers give (the earliest
    /// file's on a tie); `None` when no header gives one and none was given.
    pub resolution: Option<f64>,
    /// An input of that resolution, named when another one differs.
    pub resolution_file: Option<usize>,
}

impl InputCheck<'_> {
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
                    header_resolution(&input.path, self.formats, self.read)
                };
                progress.advance(1);
                resolution
            })
            .collect();
        self.decide(inputs, headers)
    }

    /// The check of maps to be added to `file`, whose `resolution` (this check's) fixes
    /// the series': inputs of another one are refused naming the file (or left out with
    /// `skip_bad`), whatever most of them give.
    pub fn run_for_file(
        &self,
        inputs: &[SeriesInput],
        file: &Path,
        resolution: f64,
        progress: &dyn Progress,
    ) -> Result<CheckedInputs, ConvertError> {
        self.run(inputs, &SeriesInput::is_recorded, progress)
            .map_err(|e| match e {
                ConvertError::Snapshot { path, source } => match *source {
                    SnapshotError::Resolution { found, .. } => ConvertError::MixedResolution {
                        first: file.to_path_buf(),
                        first_resolution: resolution,
                        second: path,
                        second_resolution: found,
                    },
                    _ => ConvertError::Snapshot { path, source },
                },
                other => other,
            })
    }

    /// Decides from each input's header resolution (`None`: the header does not tell).
    /// The series' resolution is chosen from all headers before any file is judged, so a
    /// stray file at the start does not decide it; with `skip_bad` every bad file is listed.
    fn decide(
        &self,
        inputs: &[SeriesInput],
        headers: Vec<Result<Option<f64>, SnapshotError>>,
    ) -> Result<CheckedInputs, ConvertError> {
        let (resolution, resolution_file) = match self.resolution {
            Some(given) => (
                Some(given),
                headers
                    .iter()
                    .position(|h| matches!(h, Ok(Some(r)) if *r == given)),
            ),
            None => match majority_resolution(&headers) {
                Some((r, i)) => (Some(r), Some(i)),
                None => (None, None),
            },
        };
        let mut checked = CheckedInputs {
            usable: vec![true; inputs.len()],
            resolution,
            resolution_file,
            ..CheckedInputs::default()
        };
        for (i, header) in headers.into_iter().enumerate() {
            let refusal = match (header, resolution) {
                (Ok(None), _) | (Ok(Some(_)), None) => continue,
                (Ok(Some(found)), Some(series)) if found == series => continue,
                (Ok(Some(found)), Some(series)) => match resolution_file {
                    Some(first) if !self.skip_bad => {
                        return Err(ConvertError::MixedResolution {
                            first: inputs[first].path.clone(),
                            first_resolution: series,
                            second: inputs[i].path.clone(),
                            second_resolution: found,
                        })
                    }
                    _ => SnapshotError::Resolution { found, series },
                },
                (Err(reason), _) => reason,
            };
            if !self.skip_bad {
                return Err(ConvertError::Snapshot {
                    path: inputs[i].path.clone(),
                    source: Arc::new(refusal),
                });
            }
            checked.skipped.push((
                inputs[i].path.clone(),
                froctomap_core::error_message(&refusal),
            ));
            checked.usable[i] = false;
        }
        refuse_mostly_skipped(
            inputs.len(),
            &checked.skipped,
            checked.resolution,
            self.allow_mostly_skipped,
        )?;
        Ok(checked)
    }
}

/// The resolution most headers give, and the first input giving it (the earliest such
/// input's resolution on a tie).
fn majority_resolution(headers: &[Result<Option<f64>, SnapshotError>]) -> Option<(f64, usize)> {
    // (resolution, files, first file), in order of first appearance.
    let mut counts: Vec<(f64, usize, usize)> = Vec::new();
    for (i, header) in headers.iter().enumerate() {
        if let Ok(Some(r)) = header {
            match counts.iter_mut().find(|(known, _, _)| known == r) {
                Some((_, n, _)) => *n += 1,
                None => counts.push((*r, 1, i)),
            }
        }
    }
    // `max_by_key` keeps the last of equal counts: search from the back for the earliest.
    counts
        .iter()
        .rev()
        .max_by_key(|(_, n, _)| *n)
        .map(|&(r, _, first)| (r, first))
}

/// Refuses to go on when more than half of `inputs` inputs were left out (a series built
/// from a few stray files of another resolution, say), unless `allow`.
pub(crate) fn refuse_mostly_skipped(
    inputs: usize,
    skipped: &[(PathBuf, String)],
    resolution: Option<f64>,
    allow: bool,
) -> Result<(), ConvertError> {
    if allow || skipped.len() * 2 <= inputs {
        return Ok(());
    }
    Err(ConvertError::MostlySkipped {
        inputs,
        skipped: skipped.to_vec(),
        resolution,
    })
}

/// How many tiles one snapshot's known space may cover. A history cell is never coarser
/// than a tile, so every tile a change covers holds at least one cell: an 18-byte `.bt` of
/// one root leaf would make 2^30 cells at tile depth 10, while a real map's leaves lie in
/// comparatively few tiles (its cells within them are bounded by its leaves, that is by
/// its bytes). Counted from the changes before they are accumulated, in time linear in the
/// changes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileBudget {
    /// The build's tile depth.
    pub tile_depth: u8,
    /// [`Limits::max_snapshot_tiles`](crate::Limits).
    pub max_tiles: u64,
}

impl TileBudget {
    /// Refuses changes to known states that cover more than `max_tiles` distinct tiles
    /// (changes to unknown only change cells already there).
    pub fn check(&self, changes: &[StateChange]) -> Result<(), SnapshotError> {
        let tile = voxels_per_node(self.tile_depth);
        let mut tiles = 0u64;
        // Changes are sorted and disjoint: a tile is counted again only by the change that
        // starts in the tile where the one before ended.
        let mut last_counted: Option<u64> = None;
        for change in changes.iter().filter(|c| c.new.is_some()) {
            let Some(last) = change.end.checked_sub(1).filter(|&l| l >= change.start) else {
                continue;
            };
            let (first_tile, last_tile) = (change.start / tile, last / tile);
            let first_new = match last_counted {
                Some(counted) if counted >= first_tile => counted + 1,
                _ => first_tile,
            };
            if last_tile >= first_new {
                tiles = tiles.saturating_add(last_tile - first_new + 1);
                last_counted = Some(last_tile);
            }
            if tiles > self.max_tiles {
                return Err(SnapshotError::TooManyTiles {
                    tile_depth: self.tile_depth,
                    limit: self.max_tiles,
                });
            }
        }
        Ok(())
    }
}

/// A file's resolution from its first bytes, when its format has a header that gives it.
fn header_resolution(
    path: &Path,
    formats: &FormatRegistry,
    read: ReadOptions<'_>,
) -> Result<Option<f64>, SnapshotError> {
    use std::io::Read;
    let metadata = std::fs::metadata(path).map_err(SnapshotError::Io)?;
    crate::files::refuse_special(path, &metadata)?;
    let mut head = Vec::with_capacity(PROBE_BYTES as usize);
    std::fs::File::open(path)
        .and_then(|f| f.take(PROBE_BYTES).read_to_end(&mut head))
        .map_err(SnapshotError::Io)?;
    if head.is_empty() {
        return Err(SnapshotError::Empty);
    }
    // No format recognises the first bytes, or its header is not in them: the full read
    // decides.
    let header = formats
        .format_of(path, &head, read)
        .ok()
        .and_then(|format| format.header)
        .and_then(|header| header(&head));
    Ok(header.map(|h| h.resolution))
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::Timestamp;

    /// The decisions are taken from header resolutions given to them.
    static NO_FORMATS: std::sync::LazyLock<FormatRegistry> =
        std::sync::LazyLock::new(FormatRegistry::new);

    fn series(n: usize) -> Vec<SeriesInput> {
        (0..n)
            .map(|i| {
                SeriesInput::new(
                    PathBuf::from(format!("map{i}.bt")),
                    Timestamp::from_secs(i as i64),
                )
            })
            .collect()
    }

    fn check(skip_bad: bool) -> InputCheck<'static> {
        InputCheck {
            formats: &NO_FORMATS,
            read: ReadOptions::default(),
            skip_bad,
            resolution: None,
            allow_mostly_skipped: false,
        }
    }

    #[test]
    fn the_resolution_most_headers_give_is_the_series_and_others_are_refused_or_skipped() {
        let inputs = series(4);
        let headers = || vec![Ok(None), Ok(Some(0.1)), Ok(Some(0.1)), Ok(Some(0.05))];
        let strict = check(false);
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
        let lenient = check(true);
        let checked = lenient.decide(&inputs, headers()).unwrap();
        assert_eq!(checked.usable, [true, true, true, false]);
        assert_eq!(checked.resolution, Some(0.1));
        assert_eq!(checked.resolution_file, Some(1));
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
        match check(false).decide(&inputs, headers()) {
            Err(ConvertError::Snapshot { path, source }) => {
                assert_eq!(path, inputs[0].path);
                assert!(matches!(*source, SnapshotError::Empty));
            }
            other => panic!("{other:?}"),
        }
        let checked = check(true).decide(&inputs, headers()).unwrap();
        assert_eq!(checked.usable, [false, true, true]);
        assert_eq!(checked.resolution, Some(0.2));
        assert_eq!(checked.skipped[0].1, SnapshotError::Empty.to_string());
    }

    /// Issue 16 item 13: a 0.1 m file first in a series of 0.05 m files used to set the
    /// series' resolution, so that `--skip-bad` kept 2 of 30 files and succeeded.
    #[test]
    fn a_stray_first_file_does_not_set_the_resolution() {
        let inputs = series(30);
        let headers = || {
            (0..30)
                .map(|i| Ok(Some(if i == 0 || i == 17 { 0.1 } else { 0.05 })))
                .collect::<Vec<_>>()
        };
        let checked = check(true).decide(&inputs, headers()).unwrap();
        assert_eq!(checked.resolution, Some(0.05));
        assert_eq!(checked.resolution_file, Some(1));
        let skipped: Vec<&PathBuf> = checked.skipped.iter().map(|(p, _)| p).collect();
        assert_eq!(skipped, [&inputs[0].path, &inputs[17].path]);
        assert_eq!(checked.usable.iter().filter(|u| **u).count(), 28);
        // Without --skip-bad, the error names the stray file against a majority one.
        match check(false).decide(&inputs, headers()) {
            Err(ConvertError::MixedResolution { first, second, .. }) => {
                assert_eq!(
                    (first, second),
                    (inputs[1].path.clone(), inputs[0].path.clone())
                );
            }
            other => panic!("{other:?}"),
        }
        // The user's resolution wins: 28 of 30 left out is refused, listing all of them,
        // unless allowed.
        let given = |allow_mostly_skipped| InputCheck {
            resolution: Some(0.1),
            allow_mostly_skipped,
            ..check(true)
        };
        match given(false).decide(&inputs, headers()) {
            Err(err @ ConvertError::MostlySkipped { .. }) => {
                let ConvertError::MostlySkipped {
                    inputs: n,
                    ref skipped,
                    resolution,
                } = err
                else {
                    unreachable!()
                };
                assert_eq!((n, skipped.len(), resolution), (30, 28, Some(0.1)));
                let text = err.to_string();
                assert!(
                    text.starts_with("28 of 30 inputs would be left out"),
                    "{text}"
                );
                for i in (1..30).filter(|&i| i != 17) {
                    assert!(
                        text.contains(&format!("map{i}.bt: resolution 0.05 m")),
                        "{text}"
                    );
                }
            }
            other => panic!("{other:?}"),
        }
        let checked = given(true).decide(&inputs, headers()).unwrap();
        assert_eq!(checked.resolution, Some(0.1));
        assert_eq!(checked.resolution_file, Some(0));
        assert_eq!(checked.usable.iter().filter(|u| **u).count(), 2);
    }

    #[test]
    fn ties_go_to_the_earliest_and_a_given_resolution_need_not_be_in_the_series() {
        let inputs = series(4);
        let headers = || vec![Ok(None), Ok(Some(0.2)), Ok(Some(0.1)), Ok(Some(0.1))];
        let tie = || vec![Ok(Some(0.2)), Ok(Some(0.1)), Ok(Some(0.1)), Ok(Some(0.2))];
        let checked = check(true).decide(&inputs, tie()).unwrap();
        assert_eq!(
            (checked.resolution, checked.resolution_file),
            (Some(0.2), Some(0))
        );
        // Exactly half left out is still a series.
        assert_eq!(checked.skipped.len(), 2);
        let checked = check(true).decide(&inputs, headers()).unwrap();
        assert_eq!(
            (checked.resolution, checked.resolution_file),
            (Some(0.1), Some(2))
        );
        assert_eq!(checked.skipped.len(), 1);
        let given = InputCheck {
            resolution: Some(0.5),
            ..check(false)
        };
        match given.decide(&inputs, headers()) {
            Err(ConvertError::Snapshot { path, source }) => {
                assert_eq!(path, inputs[1].path);
                assert!(matches!(
                    *source,
                    SnapshotError::Resolution {
                        found: 0.2,
                        series: 0.5
                    }
                ));
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn changes_count_the_distinct_tiles_they_cover() {
        use froctomap_core::{Occupancy, StateChange};
        let budget = |max_tiles| TileBudget {
            tile_depth: 15,
            max_tiles,
        };
        let change = |start, end, new| StateChange { start, end, new };
        let known = Some(Occupancy::Free);
        // Depth-15 tiles hold 8 voxels: [4, 20) covers tiles 0-2, [20, 22) and [23, 24)
        // tile 2 again, [32, 33) tile 4; a change to unknown covers nothing new.
        let changes = [
            change(4, 20, known),
            change(20, 22, Some(Occupancy::Occupied)),
            change(23, 24, known),
            change(32, 33, known),
            change(40, 4000, None),
        ];
        assert!(budget(4).check(&changes).is_ok());
        assert!(matches!(
            budget(3).check(&changes),
            Err(SnapshotError::TooManyTiles {
                tile_depth: 15,
                limit: 3
            })
        ));
        // The whole space is 8^15 depth-15 tiles: counted without a walk over them.
        let root = [change(0, 1 << 48, known)];
        assert!(budget(u64::MAX).check(&root).is_ok());
        assert!(budget(1 << 45).check(&root).is_ok());
        assert!(budget((1 << 45) - 1).check(&root).is_err());
    }

    #[test]
    fn headers_give_the_resolution_or_leave_it_to_the_full_read() {
        let dir = tempfile::tempdir().unwrap();
        let (formats, read) = (
            FormatRegistry::with_default_formats(),
            ReadOptions::default(),
        );
        let empty = dir.path().join("empty.bt");
        std::fs::write(&empty, b"").unwrap();
        assert!(matches!(
            header_resolution(&empty, &formats, read),
            Err(SnapshotError::Empty)
        ));
        let other = dir.path().join("other.xyz");
        std::fs::write(&other, b"not a map header").unwrap();
        assert_eq!(header_resolution(&other, &formats, read).unwrap(), None);
        let bt = dir.path().join("map.bt");
        std::fs::write(
            &bt,
            b"# Octomap OcTree binary file\nid OcTree\nsize 0\nres 0.05\ndata\n",
        )
        .unwrap();
        assert_eq!(header_resolution(&bt, &formats, read).unwrap(), Some(0.05));
        assert!(matches!(
            header_resolution(&dir.path().join("missing.bt"), &formats, read),
            Err(SnapshotError::Io(_))
        ));
    }
}
