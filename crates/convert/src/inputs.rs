//! Which files make a series, and at what time each snapshot was taken.

use crate::context::Context;
use crate::error::{ConvertError, ManifestProblem, SnapshotError};
use crate::files::{refuse_special_file, special_kind};
use crate::glob_walk::recursive_matches;
use crate::recording::RecordedMap;
use crate::skip::SkippedInput;
use crate::time::{
    check_range, read_time, read_time_from_file_name, TimeError, Zone, EARLIEST_IN_NAME,
};
use froctomap_core::{calendar, Timestamp};
use froctomap_formats::natural_cmp;
use std::path::{Path, PathBuf};

/// One snapshot of a series: a map file, or a map of a recording the input holds open.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SeriesInput {
    /// The file (for a recorded map, the recording).
    pub path: PathBuf,
    /// When the snapshot was taken.
    pub time: Timestamp,
    /// The recorded map, when `path` is a recording.
    recorded: Option<RecordedMap>,
}

impl SeriesInput {
    /// The map file `path`, taken at `time`.
    pub fn new(path: PathBuf, time: Timestamp) -> Self {
        Self {
            path,
            time,
            recorded: None,
        }
    }

    /// Map `map` of the recording at `path`, taken at `time`.
    pub fn recorded_map(path: PathBuf, time: Timestamp, map: RecordedMap) -> Self {
        Self {
            path,
            time,
            recorded: Some(map),
        }
    }

    /// The recorded map this input stands for, if it is one.
    pub fn recorded(&self) -> Option<&RecordedMap> {
        self.recorded.as_ref()
    }

    /// `true` for a map of a recording (its header is not read by path).
    pub fn is_recorded(&self) -> bool {
        self.recorded.is_some()
    }
}

/// Where snapshot times come from.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub enum TimeSource {
    /// Manifests give times; plain files take theirs from their names.
    #[default]
    Auto,
    /// Every file's name holds its time (manifest times are ignored).
    FileNames,
    /// The files, in the order given (directories and globs in natural order), are taken at
    /// `start + i · step`.
    StartStep {
        /// Time of the first file.
        start: Timestamp,
        /// Nanoseconds between files.
        step_ns: i64,
    },
    /// The files, in the order given (directories and globs in natural order), take the
    /// times of this file one by one: one time per line (Unix seconds or ISO 8601), `#`
    /// comments allowed. Its count must be the number of files.
    TimesFile(PathBuf),
}

/// Where one input's time came from (shown by `build --dry-run`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum TimeOrigin {
    /// A manifest row.
    Manifest,
    /// The file's name.
    FileName,
    /// `start + i · step` by the file's place in the list.
    StartStep,
    /// A list of times, by the file's place in the list.
    TimesFile,
    /// A map recorded in a recording (a ROS bag…), at the time the recording gives it.
    Recorded,
}

impl std::fmt::Display for TimeOrigin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Manifest => "manifest",
            Self::FileName => "file name",
            Self::StartStep => "start + step",
            Self::TimesFile => "times file",
            Self::Recorded => "recording",
        })
    }
}

/// The files of a series with their times, sorted by time, and where each time came from.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct CollectedInputs {
    /// The snapshots, sorted by time.
    pub series: Vec<SeriesInput>,
    /// Where each snapshot's time came from (same order as `series`).
    pub origins: Vec<TimeOrigin>,
    /// Some time (in a name or a manifest) had no zone and was read in the given [`Zone`].
    pub zoneless: bool,
    /// Things the caller should pass on to the user.
    pub warnings: Vec<InputWarning>,
    /// Damaged parts of recordings left out (with [`RecordingOptions::skip_bad`]): the
    /// recording and why, as a build reports files it left out.
    ///
    /// [`RecordingOptions::skip_bad`]: crate::RecordingOptions::skip_bad
    pub skipped: Vec<SkippedInput>,
}

/// Something odd about the inputs that does not stop a build.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum InputWarning {
    /// A series directory's manifest leaves out map files that lie beside it.
    #[error("{} does not list {} map file(s) beside it: {}{}", manifest.display(), files.len(), files.iter().take(5).map(|f| f.display().to_string()).collect::<Vec<_>>().join(", "), if files.len() > 5 { ", ..." } else { "" })]
    Unlisted {
        /// The manifest.
        manifest: PathBuf,
        /// The map files it does not list.
        files: Vec<PathBuf>,
    },
    /// Something a recording's reader tolerated (e.g. zero stamps given recording times).
    #[error("{}: {message}", path.display())]
    Recording {
        /// The recording.
        path: PathBuf,
        /// What it tolerated.
        message: String,
    },
}

/// The name of a manifest inside a series directory.
pub const MANIFEST_NAME: &str = "manifest.csv";

/// A file named on the command line, before times are known.
struct Candidate {
    path: PathBuf,
    manifest_time: Option<Timestamp>,
    /// The manifest's time had no zone.
    manifest_zoneless: bool,
    /// A map of a recording (at `path`), at this time.
    recorded: Option<(Timestamp, RecordedMap)>,
}

impl Candidate {
    /// A plain file, its time still to be found.
    fn file(path: PathBuf) -> Self {
        Self {
            path,
            manifest_time: None,
            manifest_zoneless: false,
            recorded: None,
        }
    }
}

/// What collecting tells besides the inputs.
#[derive(Default)]
struct InputNotes {
    warnings: Vec<InputWarning>,
    skipped: Vec<SkippedInput>,
}

/// Adds `path` to `candidates`: the maps of a recording (of a format registered in
/// `context`) at their times, else the file itself.
fn push_file(
    context: &Context,
    path: PathBuf,
    candidates: &mut Vec<Candidate>,
    notes: &mut InputNotes,
) -> Result<(), ConvertError> {
    let Some(format) = context.formats().recording_for(&path) else {
        candidates.push(Candidate::file(path));
        return Ok(());
    };
    let recording = crate::recording::open_recording(context, format, &path)?;
    push_recording(path, recording, candidates, notes);
    Ok(())
}

/// The input that means standard input: a recording read as a stream.
pub const STDIN_INPUT: &str = "-";

/// Adds the maps of the recording streamed on `input` (standard input) to `candidates`:
/// its first bytes choose the format among those read from streams, which reads it to
/// its end.
fn push_stream(
    context: &Context,
    input: &mut dyn std::io::Read,
    candidates: &mut Vec<Candidate>,
    notes: &mut InputNotes,
) -> Result<(), ConvertError> {
    use std::io::Read;
    let mut head = Vec::new();
    input
        .take(froctomap_formats::PROBE_BYTES)
        .read_to_end(&mut head)
        .map_err(|source| ConvertError::StdinRead { source })?;
    let streamed: Vec<_> = context
        .formats()
        .recording_formats()
        .iter()
        .filter_map(|f| f.open_stream.map(|open| (f, open)))
        .collect();
    let chosen = streamed
        .iter()
        .map(|&(format, open)| ((format.probe)(&head), format, open))
        .filter(|(confidence, ..)| *confidence > froctomap_formats::Confidence::No)
        .max_by_key(|(confidence, ..)| *confidence);
    let Some((_, format, open)) = chosen else {
        let formats: Vec<&str> = streamed.iter().map(|(f, _)| f.name).collect();
        return Err(ConvertError::UnknownStream {
            formats: if formats.is_empty() {
                "none registered".to_string()
            } else {
                formats.join(", ")
            },
            start: describe_start(&head),
        });
    };
    let path = PathBuf::from(STDIN_INPUT);
    let mut whole = std::io::Cursor::new(head).chain(input);
    let limit = context.limits().max_map_file_bytes;
    let recording = open(&mut whole, context.recording_options(), limit).map_err(|source| {
        ConvertError::Recording {
            path: path.clone(),
            format: format.name,
            source,
        }
    })?;
    push_recording(path, recording, candidates, notes);
    Ok(())
}

/// How a stream that is nobody's starts, for its error.
fn describe_start(head: &[u8]) -> String {
    if head.is_empty() {
        return "it is empty".to_string();
    }
    let shown: String = String::from_utf8_lossy(&head[..head.len().min(16)])
        .chars()
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    format!("it starts with {shown:?}")
}

/// Adds the maps of an opened recording at `path` to `candidates`, its warnings and the
/// parts it left out to `notes`.
fn push_recording(
    path: PathBuf,
    recording: froctomap_formats::Recording,
    candidates: &mut Vec<Candidate>,
    notes: &mut InputNotes,
) {
    notes.skipped.extend(
        recording
            .skipped
            .iter()
            .map(|part| SkippedInput::recording_part(path.clone(), part.as_ref())),
    );
    notes.warnings.extend(
        recording
            .warnings
            .into_iter()
            .map(|message| InputWarning::Recording {
                path: path.clone(),
                message,
            }),
    );
    let maps = recording.maps;
    candidates.extend(
        recording
            .times
            .into_iter()
            .enumerate()
            .map(|(index, time)| Candidate {
                recorded: Some((time, RecordedMap::new(maps.clone(), index))),
                ..Candidate::file(path.clone())
            }),
    );
}

/// Expands command-line inputs into the files of a series with their times, sorted by time.
///
/// Each input is a directory (its `manifest.csv` if present, else every file with an
/// extension of a registered map format, sorted by name), a glob pattern (`maps/*.bt`), a
/// manifest CSV (`path,time` lines; paths relative to the manifest; times in Unix seconds or
/// ISO 8601; a header line is optional) or a single file. Duplicate times are an error naming
/// both files.
///
/// Directories are listed by the extensions of `context`'s map formats, so a format the
/// caller registered is picked up too. A `**` pattern does not enter directories reached
/// through symbolic links (a link to an ancestor would make the walk endless). A FIFO,
/// device or socket among the inputs or a manifest's rows is refused before it is opened.
///
/// A *recording* (a file or directory of a [`RecordingFormat`](froctomap_formats::RecordingFormat)
/// registered in `context`'s format registry, such as a ROS bag) given directly or matched by a glob is
/// expanded into its maps, one input each with the recording's path and the map's time
/// (read as `context`'s [`RecordingOptions`](crate::RecordingOptions) say); each such input
/// holds the opened recording, so the series can be built with any context. Their times are their own: `--start/--step`
/// and times files are refused with them.
///
/// [`STDIN_INPUT`] (`-`) is a recording streamed on standard input, of a format read from
/// streams (an MCAP stream with `froctomap-ros` registered): it is read to its end here,
/// its maps spooled to disk by the plugin (in [`RecordingOptions::spool_dir`]), and built
/// like a recording file. `-` may be given once.
///
/// [`RecordingOptions::spool_dir`]: crate::RecordingOptions::spool_dir
pub fn collect_inputs(
    context: &Context,
    inputs: &[PathBuf],
    times: TimeSource,
) -> Result<Vec<SeriesInput>, ConvertError> {
    Ok(collect_inputs_explained(context, inputs, times, &Zone::utc())?.series)
}

/// [`collect_inputs`], also saying where each time came from.
///
/// Directories and glob matches are listed in natural order (`map_2` before `map_10`: runs
/// of digits compare as numbers), which is the order `start + i · step` follows. A time read
/// from a name before [`EARLIEST_IN_NAME`] (1990) is refused as a frame number
/// ([`ConvertError::EarlyNameTime`]). Times without a zone, in names and manifests, are
/// read in `zone`.
pub fn collect_inputs_explained(
    context: &Context,
    inputs: &[PathBuf],
    times: TimeSource,
    zone: &Zone,
) -> Result<CollectedInputs, ConvertError> {
    let extensions: Vec<&str> = context
        .formats()
        .formats()
        .iter()
        .flat_map(|f| f.extensions.iter().copied())
        .collect();
    let mut candidates = Vec::new();
    let mut notes = InputNotes::default();
    if inputs
        .iter()
        .filter(|i| i.as_os_str() == STDIN_INPUT)
        .count()
        > 1
    {
        return Err(ConvertError::StdinTwice);
    }
    for input in inputs {
        let text = input.to_string_lossy();
        if input.as_os_str() == STDIN_INPUT {
            let mut stdin = std::io::stdin();
            if std::io::IsTerminal::is_terminal(&stdin) {
                // Nobody types MCAP: it would wait for keystrokes.
                return Err(ConvertError::StdinIsTerminal);
            }
            push_stream(context, &mut stdin, &mut candidates, &mut notes)?;
        } else if text.contains(['*', '?', '[']) && !input.exists() {
            let mut matched = if text.contains("**") {
                recursive_matches(&text)?
            } else {
                let paths = glob::glob(&text).map_err(|source| ConvertError::BadPattern {
                    pattern: text.to_string(),
                    source,
                })?;
                paths
                    .filter_map(Result::ok)
                    .filter(|p| p.is_file())
                    .collect()
            };
            if matched.is_empty() {
                return Err(ConvertError::NoMatch {
                    pattern: text.to_string(),
                });
            }
            matched.sort_by(|a, b| natural_cmp(a, b));
            for path in matched {
                push_file(context, path, &mut candidates, &mut notes)?;
            }
        } else if input.is_dir() && context.formats().recording_for(input).is_some() {
            push_file(context, input.clone(), &mut candidates, &mut notes)?;
        } else if input.is_dir() {
            let manifest = input.join(MANIFEST_NAME);
            if manifest.is_file() {
                let listed = read_manifest(&manifest, zone)?;
                let unlisted = unlisted_files(input, &extensions, &listed)?;
                if !unlisted.is_empty() {
                    notes.warnings.push(InputWarning::Unlisted {
                        manifest,
                        files: unlisted,
                    });
                }
                candidates.extend(listed);
            } else {
                let mut files = list_map_files(input, &extensions)?;
                if files.is_empty() {
                    return Err(ConvertError::NoMapFiles {
                        dir: input.clone(),
                        manifest: MANIFEST_NAME,
                        extensions: format!(".{}", extensions.join(", .")),
                    });
                }
                files.sort_by(|a, b| natural_cmp(a, b));
                candidates.extend(files.into_iter().map(Candidate::file));
            }
        } else if let Some(kind) = special_kind(input) {
            return Err(ConvertError::NotAFile {
                path: input.clone(),
                kind,
            });
        } else if input
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
        {
            candidates.extend(read_manifest(input, zone)?);
        } else if input.is_file() {
            push_file(context, input.clone(), &mut candidates, &mut notes)?;
        } else {
            return Err(ConvertError::NotFound {
                path: input.clone(),
            });
        }
    }
    collected(candidates, notes, times, zone)
}

/// The maps of an opened `recording` as a series (sorted by time; two maps of one time are
/// an error), named `path` in messages: a source of maps handed over one at a time, e.g.
/// Python's `build` given an iterable of `(time, bytes)` spooled into a
/// [`MapSpool`](froctomap_formats::MapSpool).
pub fn collect_recording(
    path: PathBuf,
    recording: froctomap_formats::Recording,
) -> Result<CollectedInputs, ConvertError> {
    let mut candidates = Vec::new();
    let mut notes = InputNotes::default();
    push_recording(path, recording, &mut candidates, &mut notes);
    collected(candidates, notes, TimeSource::Auto, &Zone::utc())
}

/// The candidates with their times, sorted by time.
fn collected(
    candidates: Vec<Candidate>,
    notes: InputNotes,
    times: TimeSource,
    zone: &Zone,
) -> Result<CollectedInputs, ConvertError> {
    if candidates.is_empty() {
        return Err(match notes.skipped.into_iter().next() {
            Some(SkippedInput { path, message, .. }) => ConvertError::AllSkipped {
                path,
                problem: message,
            },
            None => ConvertError::NoInputs,
        });
    }
    // Manifest rows too: a FIFO among them would stall the build.
    if let Some((path, kind)) = candidates
        .iter()
        .filter(|c| c.recorded.is_none())
        .find_map(|c| special_kind(&c.path).map(|kind| (&c.path, kind)))
    {
        return Err(ConvertError::NotAFile {
            path: path.clone(),
            kind,
        });
    }
    let zoneless = candidates.iter().any(|c| c.manifest_zoneless);
    if let (TimeSource::StartStep { .. } | TimeSource::TimesFile(_), Some(recorded)) =
        (&times, candidates.iter().find(|c| c.recorded.is_some()))
    {
        return Err(ConvertError::RecordingTimes {
            path: recorded.path.clone(),
        });
    }
    let (mut timed, names_zoneless) = assign_times(candidates, times, zone)?;
    timed.sort_by(|(a, _), (b, _)| a.time.cmp(&b.time).then_with(|| a.path.cmp(&b.path)));
    if let Some(pair) = timed.windows(2).find(|w| w[0].0.time == w[1].0.time) {
        return Err(ConvertError::DuplicateTime {
            first: pair[0].0.path.clone(),
            second: pair[1].0.path.clone(),
            time: pair[0].0.time,
        });
    }
    let (series, origins) = timed.into_iter().unzip();
    Ok(CollectedInputs {
        series,
        origins,
        zoneless: zoneless || names_zoneless,
        warnings: notes.warnings,
        skipped: notes.skipped,
    })
}

/// The times of `candidates`, and whether a name's time had no zone.
fn assign_times(
    candidates: Vec<Candidate>,
    times: TimeSource,
    zone: &Zone,
) -> Result<(Vec<(SeriesInput, TimeOrigin)>, bool), ConvertError> {
    match times {
        TimeSource::StartStep { start, step_ns } => candidates
            .into_iter()
            .enumerate()
            .map(|(i, c)| {
                let t = (i as i64)
                    .checked_mul(step_ns)
                    .and_then(|offset| start.0.checked_add(offset))
                    .map(Timestamp)
                    .ok_or_else(|| ConvertError::InputTime {
                        path: c.path.clone(),
                        source: TimeError {
                            input: format!("start + {i} steps"),
                            what: "time",
                            reason: "runs past the year 2262".into(),
                        },
                    })?;
                check_range(&c.path.to_string_lossy(), t)?;
                Ok((SeriesInput::new(c.path, t), TimeOrigin::StartStep))
            })
            .collect::<Result<_, _>>()
            .map(|timed| (timed, false)),
        TimeSource::TimesFile(list) => {
            let (listed, zoneless) = read_times_file(&list, zone)?;
            if listed.len() != candidates.len() {
                return Err(ConvertError::TimesCount {
                    list,
                    times: listed.len(),
                    files: candidates.len(),
                });
            }
            let timed = candidates
                .into_iter()
                .zip(listed)
                .map(|(c, time)| {
                    let input = SeriesInput::new(c.path, time);
                    (input, TimeOrigin::TimesFile)
                })
                .collect();
            Ok((timed, zoneless))
        }
        TimeSource::Auto | TimeSource::FileNames => {
            let use_manifest = times == TimeSource::Auto;
            let mut out = Vec::with_capacity(candidates.len());
            let mut unnamed = Vec::new();
            let mut zoneless = false;
            for c in candidates {
                if let Some((time, map)) = c.recorded {
                    let input = SeriesInput::recorded_map(c.path, time, map);
                    out.push((input, TimeOrigin::Recorded));
                    continue;
                }
                let from_manifest = c.manifest_time.filter(|_| use_manifest);
                let from_name = || {
                    c.path
                        .file_name()
                        .and_then(|n| n.to_str())
                        .and_then(|name| read_time_from_file_name(name, zone))
                };
                match from_manifest {
                    Some(time) => out.push((SeriesInput::new(c.path, time), TimeOrigin::Manifest)),
                    None => match from_name() {
                        Some(read) if read.time < EARLIEST_IN_NAME => {
                            return Err(ConvertError::EarlyNameTime {
                                path: c.path,
                                time: read.time,
                            })
                        }
                        Some(read) => {
                            zoneless |= read.zoneless;
                            let input = SeriesInput::new(c.path, read.time);
                            out.push((input, TimeOrigin::FileName))
                        }
                        None => unnamed.push(c.path),
                    },
                }
            }
            if !unnamed.is_empty() {
                return Err(ConvertError::NoTimes { files: unnamed });
            }
            Ok((out, zoneless))
        }
    }
}

/// How messages name an input: its path, or for a recorded map
/// `recording/topic@time` (a name without an extension, so that no reader takes the
/// recording's extension for the map's).
pub(crate) fn input_name(input: &SeriesInput) -> PathBuf {
    match input.recorded() {
        None => input.path.clone(),
        Some(recorded) => {
            let time = froctomap_core::calendar::iso8601(input.time).replace('.', ",");
            let topic = recorded.topic().trim_matches('/').replace('.', "_");
            input.path.join(format!("{topic}@{time}"))
        }
    }
}

/// The bytes of an input's map: the file, or the recorded map it holds.
pub(crate) fn snapshot_bytes(input: &SeriesInput, limit: u64) -> Result<Vec<u8>, SnapshotError> {
    match input.recorded() {
        None => crate::files::read_input(&input.path, limit),
        Some(recorded) => recorded.map_bytes(limit),
    }
}

fn list_map_files(dir: &Path, extensions: &[&str]) -> Result<Vec<PathBuf>, ConvertError> {
    let io = |source| ConvertError::Unlistable {
        path: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let known = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| extensions.iter().any(|k| k.eq_ignore_ascii_case(e)));
        if known && path.is_file() {
            files.push(path);
        }
    }
    Ok(files)
}

/// The map files in `dir` that `listed` (its manifest's rows) leaves out.
fn unlisted_files(
    dir: &Path,
    extensions: &[&str],
    listed: &[Candidate],
) -> Result<Vec<PathBuf>, ConvertError> {
    let canonical = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let listed: std::collections::HashSet<PathBuf> =
        listed.iter().map(|c| canonical(&c.path)).collect();
    let mut files: Vec<PathBuf> = list_map_files(dir, extensions)?
        .into_iter()
        .filter(|f| !listed.contains(&canonical(f)))
        .collect();
    files.sort_by(|a, b| natural_cmp(a, b));
    Ok(files)
}

/// The times of a `--times-file`, and whether one had no zone.
fn read_times_file(list: &Path, zone: &Zone) -> Result<(Vec<Timestamp>, bool), ConvertError> {
    refuse_special_file(list)?;
    let text = std::fs::read_to_string(list).map_err(|source| ConvertError::Unlistable {
        path: list.to_path_buf(),
        source,
    })?;
    let mut zoneless = false;
    let mut times = Vec::new();
    for (number, line) in data_lines(&text) {
        let read = read_time(line, zone).map_err(|e| ConvertError::ManifestLine {
            manifest: list.to_path_buf(),
            line: number,
            problem: e.into(),
        })?;
        zoneless |= read.zoneless;
        times.push(read.time);
    }
    Ok((times, zoneless))
}

/// Names a header may give the path column.
const PATH_COLUMNS: &[&str] = &["path", "file", "filename", "file_name"];
/// Names a header may give the time column.
const TIME_COLUMNS: &[&str] = &["time", "stamp", "t", "timestamp", "unix_time"];

/// Where the path and time are in a manifest's rows.
enum Columns {
    /// `path,time`: the time after the last comma, so paths may hold commas.
    PathThenTime,
    /// Named by a header, in any order, other columns ignored.
    Named { path: usize, time: usize },
}

/// Reads a manifest: a `path,time` row per file; `#` comments, a UTF-8 byte order mark and
/// CRLF line ends allowed. A first row whose last field is not a time is a header: its
/// columns are then found by name (`path`/`file`, `time`/`stamp`/`t`/`unix_time`) in any
/// order, and other columns are ignored.
fn read_manifest(manifest: &Path, zone: &Zone) -> Result<Vec<Candidate>, ConvertError> {
    refuse_special_file(manifest)?;
    let text = std::fs::read_to_string(manifest).map_err(|source| ConvertError::Unlistable {
        path: manifest.to_path_buf(),
        source,
    })?;
    let base = manifest.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    let mut columns: Option<Columns> = None;
    for (number, line) in data_lines(&text) {
        let bad = |problem| ConvertError::ManifestLine {
            manifest: manifest.to_path_buf(),
            line: number,
            problem,
        };
        if columns.is_none() {
            let header = header_columns(line).map_err(bad)?;
            let is_header = header.is_some();
            columns = Some(header.unwrap_or(Columns::PathThenTime));
            if is_header {
                continue;
            }
        }
        let Some(layout) = &columns else { continue };
        let (path, time) = match *layout {
            Columns::PathThenTime => line
                .rsplit_once(',')
                .ok_or_else(|| bad(ManifestProblem::NotPathTime))?,
            Columns::Named { path, time } => {
                let fields: Vec<&str> = line.split(',').collect();
                let field = |column: usize| {
                    fields
                        .get(column)
                        .copied()
                        .ok_or_else(|| bad(ManifestProblem::MissingField { column: column + 1 }))
                };
                (field(path)?, field(time)?)
            }
        };
        let read = read_time(time, zone).map_err(|e| bad(e.into()))?;
        let path = PathBuf::from(path.trim().trim_matches('"'));
        let path = if path.is_absolute() {
            path
        } else {
            base.join(path)
        };
        out.push(Candidate {
            manifest_time: Some(read.time),
            manifest_zoneless: read.zoneless,
            ..Candidate::file(path)
        });
    }
    if out.is_empty() {
        return Err(ConvertError::EmptyManifest {
            manifest: manifest.to_path_buf(),
        });
    }
    Ok(out)
}

/// The non-blank, non-comment lines of a text file with their numbers (from 1), a byte
/// order mark and `\r` line ends removed.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.lines()
        .enumerate()
        .map(|(i, line)| (i + 1, line.trim()))
        .filter(|(_, line)| !line.is_empty() && !line.starts_with('#'))
}

/// The columns a first row names, or `None` when it is data (its last field is a time, or
/// it names no known column).
fn header_columns(line: &str) -> Result<Option<Columns>, ManifestProblem> {
    let last = line.rsplit(',').next().unwrap_or(line);
    if crate::time::parse_time(last).is_ok() {
        return Ok(None);
    }
    let names: Vec<String> = line
        .split(',')
        .map(|name| name.trim().trim_matches('"').to_ascii_lowercase())
        .collect();
    let find = |wanted: &'static str, known: &[&str]| {
        names
            .iter()
            .position(|name| known.contains(&name.as_str()))
            .ok_or(ManifestProblem::MissingColumn {
                wanted,
                names: if wanted == "path" {
                    "path, file"
                } else {
                    "time, stamp, t, unix_time"
                },
            })
    };
    let (path, time) = (find("path", PATH_COLUMNS), find("time", TIME_COLUMNS));
    if path.is_err() && time.is_err() {
        // No known name: a data row with a bad time, which the caller reports as such.
        return Ok(None);
    }
    let (path, time) = (path?, time?);
    Ok(Some(if names.len() == 2 && path == 0 && time == 1 {
        Columns::PathThenTime
    } else {
        Columns::Named { path, time }
    }))
}

/// Writes a manifest (`path,time` with Unix seconds) for files relative to `dir`.
pub fn manifest_text(dir: &Path, entries: &[SeriesInput]) -> String {
    let mut out = String::from("path,time\n");
    for e in entries {
        let rel = e.path.strip_prefix(dir).unwrap_or(&e.path);
        out.push_str(&format!(
            "{},{}\n",
            rel.display(),
            calendar::unix_seconds(e.time)
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn touch(dir: &Path, names: &[&str]) {
        for name in names {
            std::fs::write(dir.join(name), b"").unwrap();
        }
    }

    #[test]
    fn start_and_step_follow_natural_order() {
        let dir = tempfile::tempdir().unwrap();
        let names: Vec<String> = (1..=12).map(|i| format!("map_{i}.bt")).collect();
        touch(
            dir.path(),
            &names.iter().map(String::as_str).collect::<Vec<_>>(),
        );
        let collected = collect_inputs_explained(
            &Context::with_default_plugins(),
            &[dir.path().to_path_buf()],
            TimeSource::StartStep {
                start: Timestamp::from_secs(1_700_000_000),
                step_ns: 1_000_000_000,
            },
            &Zone::utc(),
        )
        .unwrap();
        for (i, input) in collected.series.iter().enumerate() {
            assert_eq!(input.path, dir.path().join(format!("map_{}.bt", i + 1)));
            assert_eq!(input.time, Timestamp::from_secs(1_700_000_000 + i as i64));
        }
        assert!(collected
            .origins
            .iter()
            .all(|&o| o == TimeOrigin::StartStep));
    }

    #[test]
    fn frame_numbers_are_not_taken_for_1970_times() {
        let dir = tempfile::tempdir().unwrap();
        touch(dir.path(), &["map_0000000041.bt", "map_0000000042.bt"]);
        let context = Context::with_default_plugins();
        let err =
            collect_inputs(&context, &[dir.path().to_path_buf()], TimeSource::Auto).unwrap_err();
        assert!(matches!(err, ConvertError::EarlyNameTime { .. }), "{err}");
        assert!(err.to_string().contains("before 1990"), "{err}");
        // The same files with explicit times are fine.
        let ok = collect_inputs(
            &context,
            &[dir.path().to_path_buf()],
            TimeSource::StartStep {
                start: Timestamp::from_secs(1_700_000_000),
                step_ns: 60_000_000_000,
            },
        )
        .unwrap();
        assert_eq!(ok.len(), 2);
    }

    #[test]
    fn origins_say_where_times_came_from() {
        let dir = tempfile::tempdir().unwrap();
        touch(dir.path(), &["a.bt", "scan_2024-03-01-10-15-00.bt"]);
        std::fs::write(dir.path().join("list.csv"), "path,time\na.bt,1700000000\n").unwrap();
        let collected = collect_inputs_explained(
            &Context::with_default_plugins(),
            &[
                dir.path().join("list.csv"),
                dir.path().join("scan_2024-03-01-10-15-00.bt"),
            ],
            TimeSource::Auto,
            &Zone::utc(),
        )
        .unwrap();
        assert!(collected.zoneless);
        assert_eq!(
            collected.origins,
            [TimeOrigin::Manifest, TimeOrigin::FileName]
        );
        assert_eq!(
            collected.series[1].time,
            Timestamp::from_secs(1_709_288_100)
        );
    }
}

#[cfg(test)]
mod zone_tests {
    use super::*;

    #[test]
    fn zoneless_names_and_manifest_times_are_read_in_the_given_zone() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("2024-03-01-10-15-00.bt"), b"").unwrap();
        std::fs::write(dir.path().join("b.bt"), b"").unwrap();
        std::fs::write(dir.path().join("m.csv"), "b.bt,2024-03-01T12:00:00\n").unwrap();
        let inputs = [
            dir.path().join("2024-03-01-10-15-00.bt"),
            dir.path().join("m.csv"),
        ];
        let context = Context::with_default_plugins();
        let plus_one = Zone::named("+01:00").unwrap();
        let collected =
            collect_inputs_explained(&context, &inputs, TimeSource::Auto, &plus_one).unwrap();
        assert!(collected.zoneless);
        assert_eq!(
            collected.series[0].time,
            Timestamp::from_secs(1_709_288_100 - 3600)
        );
        assert_eq!(
            collected.series[1].time,
            Timestamp::from_secs(1_709_294_400 - 3600)
        );
        // Unix digits in names carry no zone question.
        std::fs::write(dir.path().join("map_1709288100.bt"), b"").unwrap();
        let unix = collect_inputs_explained(
            &context,
            &[dir.path().join("map_1709288100.bt")],
            TimeSource::Auto,
            &plus_one,
        )
        .unwrap();
        assert!(!unix.zoneless);
        assert_eq!(unix.series[0].time, Timestamp::from_secs(1_709_288_100));
    }
}

#[cfg(test)]
mod manifest_tests {
    use super::*;

    fn series(dir: &Path, inputs: &[PathBuf], times: TimeSource) -> CollectedInputs {
        collect_inputs_explained(
            &Context::with_default_plugins(),
            inputs,
            times,
            &Zone::utc(),
        )
        .unwrap_or_else(|e| panic!("{e} in {}", dir.display()))
    }

    fn touch(dir: &Path, names: &[&str]) {
        for name in names {
            std::fs::write(dir.join(name), b"").unwrap();
        }
    }

    #[test]
    fn headers_name_their_columns_in_any_order() {
        let dir = tempfile::tempdir().unwrap();
        touch(dir.path(), &["a.bt", "b.bt"]);
        let expected = [
            (dir.path().join("a.bt"), Timestamp::from_secs(1_700_000_000)),
            (dir.path().join("b.bt"), Timestamp::from_secs(1_700_000_600)),
        ];
        for text in [
            "file,stamp\na.bt,1700000000\nb.bt,1700000600\n",
            "path,unix_time\na.bt,1700000000\nb.bt,1700000600\n",
            "\u{feff}stamp,note,File\r\n1700000000,first,a.bt\r\n1700000600,,b.bt\r\n",
            "# made by hand\n\nt,path\n1700000000,a.bt\n2023-11-14T22:23:20Z,b.bt\n",
            "a.bt,1700000000\r\nb.bt,1700000600\r\n",
        ] {
            let manifest = dir.path().join("list.csv");
            std::fs::write(&manifest, text).unwrap();
            let got = series(dir.path(), &[manifest], TimeSource::Auto);
            let got: Vec<_> = got.series.into_iter().map(|i| (i.path, i.time)).collect();
            assert_eq!(got, expected, "{text:?}");
        }
    }

    #[test]
    fn bad_manifests_say_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        touch(dir.path(), &["a.bt"]);
        let manifest = dir.path().join("list.csv");
        let context = Context::with_default_plugins();
        let read = |text: &str| {
            std::fs::write(&manifest, text).unwrap();
            let err = collect_inputs(&context, std::slice::from_ref(&manifest), TimeSource::Auto)
                .unwrap_err();
            froctomap_core::error_message(&err)
        };
        let err = read("file,note\na.bt,x\n");
        assert!(
            err.contains(":1:") && err.contains("no time column"),
            "{err}"
        );
        let err = read("a.bt,yesterday\n");
        assert!(err.contains(":1:") && err.contains("yesterday"), "{err}");
        let err = read("note,time,path\nx,1700000000\n");
        assert!(err.contains(":2:") && err.contains("column 3"), "{err}");
    }

    #[test]
    fn a_times_file_times_the_files_in_order() {
        let dir = tempfile::tempdir().unwrap();
        touch(dir.path(), &["map_1.bt", "map_2.bt", "map_10.bt"]);
        let list = dir.path().join("stamps.txt");
        std::fs::write(
            &list,
            "# stamps\n1700000000\n1700000060\r\n2023-11-14T22:15:20Z\n",
        )
        .unwrap();
        let got = series(
            dir.path(),
            &[dir.path().to_path_buf()],
            TimeSource::TimesFile(list.clone()),
        );
        let names: Vec<_> = got
            .series
            .iter()
            .map(|i| {
                (
                    i.path.file_name().unwrap().to_str().unwrap(),
                    i.time.0 / 1_000_000_000,
                )
            })
            .collect();
        assert_eq!(
            names,
            [
                ("map_1.bt", 1_700_000_000),
                ("map_2.bt", 1_700_000_060),
                ("map_10.bt", 1_700_000_120)
            ]
        );
        assert!(got.origins.iter().all(|&o| o == TimeOrigin::TimesFile));
        std::fs::write(&list, "1700000000\n").unwrap();
        let err = collect_inputs(
            &Context::with_default_plugins(),
            &[dir.path().to_path_buf()],
            TimeSource::TimesFile(list),
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                ConvertError::TimesCount {
                    times: 1,
                    files: 3,
                    ..
                }
            ),
            "{err}"
        );
    }

    #[test]
    fn a_manifest_that_leaves_out_map_files_is_reported() {
        let dir = tempfile::tempdir().unwrap();
        touch(dir.path(), &["a.bt", "b.bt", "c.ot", "notes.txt"]);
        std::fs::write(
            dir.path().join(MANIFEST_NAME),
            "path,time\n./a.bt,1700000000\n",
        )
        .unwrap();
        let got = series(dir.path(), &[dir.path().to_path_buf()], TimeSource::Auto);
        assert_eq!(got.series.len(), 1);
        assert_eq!(
            got.warnings,
            [InputWarning::Unlisted {
                manifest: dir.path().join(MANIFEST_NAME),
                files: vec![dir.path().join("b.bt"), dir.path().join("c.ot")],
            }]
        );
        std::fs::write(
            dir.path().join(MANIFEST_NAME),
            "path,time\na.bt,1700000000\nb.bt,1700000001\nc.ot,1700000002\n",
        )
        .unwrap();
        let got = series(dir.path(), &[dir.path().to_path_buf()], TimeSource::Auto);
        assert!(got.warnings.is_empty());
    }
}
