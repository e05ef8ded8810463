//! Writing a series to disk: one map file per present frame plus `manifest.csv`.
//!
//! Frames are generated and encoded in parallel in bounded batches (a few per worker), so
//! memory stays at a few frames whatever the series length. Every map file is written
//! atomically by the format registry; the manifest is written to a temporary file as the
//! frames complete and renamed into place only when all of them are on disk, so a
//! `manifest.csv` always describes a complete series.

use crate::calendar::{parse_unix_secs, unix_secs_text};
use crate::error::SynthError;
use crate::generator::{FrameInfo, FrameStats, Generator};
use froctomap_core::calendar::iso8601_basic;
use froctomap_core::{write_atomically, Timestamp};
use froctomap_formats::{FormatRegistry, WriteOptions};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Name of the manifest file written beside the frames.
pub const MANIFEST_NAME: &str = "manifest.csv";

/// How [`write_series`] writes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WriteSeriesOptions {
    /// Registry name of the map format (`bt` by default; `ot` keeps log-odds, which the
    /// generator's max-likelihood frames do not need).
    pub format: String,
    /// File name of each frame. `{time}` is the frame time in ISO 8601 basic form
    /// (`20160104T083000Z`, with a fraction of a second when there is one), `{index}` the grid
    /// index zero-padded to the width of the largest one, `{ext}` the format's extension.
    /// Must contain `{time}` or `{index}` so names are unique.
    pub file_pattern: String,
    /// Worker threads (0 = one per core).
    pub threads: usize,
}

impl Default for WriteSeriesOptions {
    fn default() -> Self {
        Self {
            format: "bt".into(),
            file_pattern: "frame_{time}.{ext}".into(),
            threads: 0,
        }
    }
}

/// One line of the manifest.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ManifestEntry {
    /// File path relative to the manifest's directory.
    pub path: PathBuf,
    /// Frame time.
    pub time: Timestamp,
    /// File size (0 when read back from a manifest, which does not store sizes).
    pub bytes: u64,
    /// Grid index (`None` when read back from a manifest).
    pub index: Option<u64>,
}

/// A written series: where, which files, how big, and what changed in it.
#[derive(Clone, Debug, PartialEq)]
pub struct SeriesManifest {
    /// Directory holding the frames and `manifest.csv`.
    pub dir: PathBuf,
    /// The frames in time order.
    pub entries: Vec<ManifestEntry>,
    /// Sum of the frame file sizes.
    pub total_bytes: u64,
    /// Summed per-frame changes (voxel-frames per kind).
    pub changes: FrameStats,
}

impl SeriesManifest {
    /// Path of the manifest file.
    pub fn manifest_path(&self) -> PathBuf {
        self.dir.join(MANIFEST_NAME)
    }

    /// Reads a `manifest.csv` (header `path,time`; time in Unix seconds with up to nine
    /// decimals; paths relative to the manifest's directory). Sizes and indices are not
    /// stored, so they read as 0 and `None`.
    pub fn read(path: &Path) -> Result<SeriesManifest, SynthError> {
        let text = std::fs::read_to_string(path).map_err(|source| SynthError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let fail = |line: usize, reason: String| SynthError::Manifest {
            path: path.to_path_buf(),
            line,
            reason,
        };
        let mut lines = text.lines().enumerate();
        match lines.next() {
            Some((_, header)) if header.trim_end() == "path,time" => {}
            Some((_, header)) => {
                return Err(fail(
                    1,
                    format!("expected header `path,time`, found {header:?}"),
                ))
            }
            None => return Err(fail(1, "empty manifest (no header)".into())),
        }
        let mut entries = Vec::new();
        for (n, line) in lines {
            let line = line.trim_end_matches('\r');
            if line.is_empty() {
                continue;
            }
            let Some((file, time)) = line.rsplit_once(',') else {
                return Err(fail(n + 1, format!("expected `path,time`, found {line:?}")));
            };
            let time = parse_unix_secs(time).ok_or_else(|| {
                fail(
                    n + 1,
                    format!("time {time:?} is not Unix seconds with up to 9 decimals"),
                )
            })?;
            if file.is_empty() {
                return Err(fail(n + 1, "empty path".into()));
            }
            entries.push(ManifestEntry {
                path: PathBuf::from(file),
                time,
                bytes: 0,
                index: None,
            });
        }
        Ok(SeriesManifest {
            dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
            entries,
            total_bytes: 0,
            changes: FrameStats::default(),
        })
    }
}

/// Expands the file-name pattern for one frame.
fn file_name(pattern: &str, frame: FrameInfo, width: usize, ext: &str) -> String {
    pattern
        .replace("{time}", &iso8601_basic(frame.time))
        .replace("{index}", &format!("{:0width$}", frame.index))
        .replace("{ext}", ext)
}

/// Checks that a pattern makes unique, plain file names that need no CSV quoting.
fn check_pattern(pattern: &str) -> Result<(), SynthError> {
    let fail = |reason: &str| SynthError::InvalidPattern {
        pattern: pattern.to_string(),
        reason: reason.to_string(),
    };
    if !pattern.contains("{time}") && !pattern.contains("{index}") {
        return Err(fail(
            "needs {time} or {index} so that every frame gets its own name",
        ));
    }
    let rest = pattern
        .replace("{time}", "")
        .replace("{index}", "")
        .replace("{ext}", "");
    if rest.contains(['{', '}']) {
        return Err(fail("unknown placeholder (known: {time}, {index}, {ext})"));
    }
    // A placeholder is always present, so names are never `.`, `..` or `manifest.csv`.
    if rest.contains(['/', '\\', ',', '"', '\n', '\r']) {
        return Err(fail(
            "must be a plain file name (no path separators, commas, quotes or line breaks)",
        ));
    }
    Ok(())
}

/// Writes every present frame of `generator` into `dir` (created if needed) in the format of
/// `formats` named by `options.format`, and `dir/manifest.csv`. `progress(done, total)` is called from the
/// calling thread after each batch. Existing files of the same names are replaced.
///
/// ```
/// # use froctomap_core::{Occupancy, Snapshot, VoxelKey};
/// use froctomap_formats::FormatRegistry;
/// use froctomap_synth::{write_series, Generator, SeriesSpec, WriteSeriesOptions};
/// # let voxels = (0..16u16).flat_map(|x| (0..16u16).flat_map(move |y| (0..8u16).map(move |z| {
/// #     let state = Occupancy::from(z == 0);
/// #     (VoxelKey::new(32768 + x, 32768 + y, 32768 + z).morton(), state)
/// # })));
/// # let base = Snapshot::from_voxel_states(0.1, voxels)?;
/// let generator = Generator::new(&base, SeriesSpec { count: 3, ..SeriesSpec::default() }, None)?;
/// let dir = tempfile::tempdir()?;
/// let formats = FormatRegistry::with_default_formats();
/// let manifest = write_series(&formats, &generator, dir.path(), &WriteSeriesOptions::default(), &|_, _| {})?;
/// assert_eq!(manifest.entries.len(), 3);
/// assert_eq!(manifest.entries[0].path.to_str(), Some("frame_20160104T000000Z.bt"));
/// let csv = std::fs::read_to_string(dir.path().join("manifest.csv"))?;
/// assert!(csv.starts_with("path,time\nframe_20160104T000000Z.bt,1451865600\n"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_series(
    formats: &FormatRegistry,
    generator: &Generator,
    dir: &Path,
    options: &WriteSeriesOptions,
    progress: &dyn Fn(u64, u64),
) -> Result<SeriesManifest, SynthError> {
    check_pattern(&options.file_pattern)?;
    let format = *formats.by_name(&options.format, None)?;
    if format.writer.is_none() {
        return Err(SynthError::Format(
            froctomap_formats::FormatError::Unsupported {
                format: format.name,
                action: "written",
            },
        ));
    }
    let ext = format.extensions.first().copied().unwrap_or(format.name);
    std::fs::create_dir_all(dir).map_err(|source| SynthError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let width = (generator.spec().count.saturating_sub(1)).to_string().len();
    let write_options = WriteOptions {
        format: Some(format.name),
        backend: None,
    };

    let mut manifest = SeriesManifest {
        dir: dir.to_path_buf(),
        entries: Vec::new(),
        total_bytes: 0,
        changes: FrameStats::default(),
    };
    let manifest_path = dir.join(MANIFEST_NAME);
    // The closure can only return io errors; the real error is kept here.
    let mut failure: Option<SynthError> = None;
    let written = write_atomically(&manifest_path, |out| {
        out.write_all(b"path,time\n")?;
        let mut previous_name: Option<String> = None;
        let mut take = |(frame, name, bytes, stats): (FrameInfo, String, u64, FrameStats)| {
            // Names follow time order, so a repeat can only be the previous one.
            if previous_name.as_deref() == Some(name.as_str()) {
                return Err(SynthError::InvalidPattern {
                    pattern: options.file_pattern.clone(),
                    reason: format!("two frames are both named {name}"),
                });
            }
            writeln!(out, "{name},{}", unix_secs_text(frame.time)).map_err(|source| {
                SynthError::Io {
                    path: manifest_path.clone(),
                    source,
                }
            })?;
            manifest.total_bytes += bytes;
            manifest.changes.add(&stats);
            manifest.entries.push(ManifestEntry {
                path: PathBuf::from(&name),
                time: frame.time,
                bytes,
                index: Some(frame.index),
            });
            previous_name = Some(name);
            Ok(())
        };
        let make = |frame: FrameInfo| {
            let name = file_name(&options.file_pattern, frame, width, ext);
            let path = dir.join(&name);
            let (snapshot, stats) = generator.frame_with_stats(frame.index)?;
            formats.write_file(&snapshot, &path, write_options)?;
            let bytes = std::fs::metadata(&path)
                .map_err(|source| SynthError::Io {
                    path: path.clone(),
                    source,
                })?
                .len();
            Ok((frame, name, bytes, stats))
        };
        in_batches(generator, options.threads, progress, make, &mut take).map_err(|e| {
            failure = Some(e);
            std::io::Error::other("frame failed")
        })
    });
    match (failure, written) {
        (Some(e), _) => Err(e),
        (None, Err(e)) => Err(SynthError::Io {
            path: e.path,
            source: e.source,
        }),
        (None, Ok(())) => Ok(manifest),
    }
}

/// Makes every present frame of `generator` with `make` on `threads` workers (0: one per
/// core) in bounded batches (a few frames per worker, so memory holds a few frames
/// whatever the series length) and hands them to `take` in time order on the calling
/// thread, calling `progress(done, total)` after each batch.
fn in_batches<T: Send>(
    generator: &Generator,
    threads: usize,
    progress: &dyn Fn(u64, u64),
    make: impl Fn(FrameInfo) -> Result<T, SynthError> + Sync,
    take: &mut dyn FnMut(T) -> Result<(), SynthError>,
) -> Result<(), SynthError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| SynthError::ThreadPool(e.to_string()))?;
    let batch = 4 * pool.current_num_threads().max(1);
    let total = generator.frames().count() as u64;
    let mut frames = generator.frames();
    let mut done = 0u64;
    loop {
        let chunk: Vec<FrameInfo> = frames.by_ref().take(batch).collect();
        if chunk.is_empty() {
            return Ok(());
        }
        let results: Vec<Result<T, SynthError>> =
            pool.install(|| chunk.par_iter().map(|&frame| make(frame)).collect());
        for result in results {
            take(result?)?;
        }
        done += chunk.len() as u64;
        progress(done, total);
    }
}

/// Every present frame of `generator` as a map file in `format` (a writable format of
/// `formats`), in time order: `take(frame, bytes, stats)` on the calling thread, the frames
/// made and encoded on `threads` workers (0: one per core) a few at a time, so memory holds
/// a few frames whatever the series length. What `froctomap generate --stream` writes as a
/// stream without files.
///
/// ```
/// # use froctomap_core::{Occupancy, Snapshot, VoxelKey};
/// use froctomap_formats::FormatRegistry;
/// use froctomap_synth::{encode_series, Generator, SeriesSpec};
/// # let voxels = (0..16u16).flat_map(|x| (0..16u16).flat_map(move |y| (0..8u16).map(move |z| {
/// #     let state = Occupancy::from(z == 0);
/// #     (VoxelKey::new(32768 + x, 32768 + y, 32768 + z).morton(), state)
/// # })));
/// # let base = Snapshot::from_voxel_states(0.1, voxels)?;
/// let generator = Generator::new(&base, SeriesSpec { count: 3, ..SeriesSpec::default() }, None)?;
/// let formats = FormatRegistry::with_default_formats();
/// let mut times = Vec::new();
/// encode_series(&formats, &generator, "bt", 0, &|_, _| {}, &mut |frame, bytes, _| {
///     assert!(bytes.starts_with(b"# Octomap OcTree binary file"));
///     times.push(frame.time);
///     Ok(())
/// })?;
/// assert_eq!(times.len(), 3);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn encode_series(
    formats: &FormatRegistry,
    generator: &Generator,
    format: &str,
    threads: usize,
    progress: &dyn Fn(u64, u64),
    take: &mut dyn FnMut(FrameInfo, Vec<u8>, FrameStats) -> Result<(), SynthError>,
) -> Result<(), SynthError> {
    let format = *formats.by_name(format, None)?;
    let Some(make_writer) = format.writer else {
        return Err(SynthError::Format(
            froctomap_formats::FormatError::Unsupported {
                format: format.name,
                action: "written",
            },
        ));
    };
    let make = |frame: FrameInfo| {
        let (snapshot, stats) = generator.frame_with_stats(frame.index)?;
        let mut bytes = Vec::new();
        make_writer()
            .write(&snapshot, &mut bytes)
            .map_err(|source| froctomap_formats::FormatError::Encode {
                path: PathBuf::from(format!("frame {}", frame.index)),
                format: format.name,
                source,
            })?;
        Ok((frame, bytes, stats))
    };
    in_batches(generator, threads, progress, make, &mut |(
        frame,
        bytes,
        stats,
    )| {
        take(frame, bytes, stats)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns() {
        for good in ["frame_{time}.{ext}", "{index}.bt", "x_{index}_{time}.{ext}"] {
            check_pattern(good).unwrap();
        }
        for bad in [
            "frame.bt",
            "a/{time}.bt",
            "{time},x",
            "{when}.bt",
            "{index}\n",
        ] {
            assert!(check_pattern(bad).is_err(), "{bad}");
        }
        let frame = FrameInfo {
            index: 7,
            time: Timestamp::from_secs(1_451_896_200),
        };
        assert_eq!(
            file_name("f_{index}_{time}.{ext}", frame, 4, "bt"),
            "f_0007_20160104T083000Z.bt"
        );
    }

    #[test]
    fn manifest_errors_name_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(MANIFEST_NAME);
        std::fs::write(&path, "path,time\na.bt,12.5\nb.bt,x\n").unwrap();
        let err = SeriesManifest::read(&path).unwrap_err().to_string();
        assert!(
            err.ends_with(
                "manifest.csv: line 3: time \"x\" is not Unix seconds with up to 9 decimals"
            ),
            "{err}"
        );
        std::fs::write(&path, "file,t\n").unwrap();
        assert!(SeriesManifest::read(&path).is_err());
        std::fs::write(&path, "path,time\na.bt,12.5\n").unwrap();
        let m = SeriesManifest::read(&path).unwrap();
        assert_eq!(m.entries[0].time, Timestamp(12_500_000_000));
        assert_eq!(m.dir, dir.path());
    }
}
