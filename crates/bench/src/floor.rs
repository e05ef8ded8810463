//! The entropy floor in the benchmark: the generator's own count of the bits its random
//! draws put into the observed training series ([`Generator::entropy_floor`]), and every
//! lossless way of storing the series against it.
//!
//! `run` adds the section to its report; `froctomap-bench floor` computes it alone (and,
//! with `--measure`, builds the lossless file, `tar | zstd` and times a retrieval, for a
//! quick before/after comparison of file formats on one series).

use crate::series_args::SeriesArgs;
use crate::system::tar_through;
use crate::tables::{duration, label_then_numbers, megabytes, table, times, StorageRow};
use anyhow::{bail, Context, Result};
use clap::Args;
use froctomap_convert::group_thousands as group;
use froctomap_file::FroctReader;
use froctomap_formats::ReadOptions;
use froctomap_synth::EntropyFloor;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One lossless way of storing the series against the floor.
#[derive(Clone, Debug, Serialize)]
pub struct FloorRow {
    /// What it is.
    pub name: String,
    /// Bytes.
    pub bytes: u64,
    /// `bytes / floor bytes`.
    pub vs_floor: Option<f64>,
}

/// The floor and the lossless sizes against it.
#[derive(Clone, Debug, Serialize)]
pub struct FloorSection {
    /// The floor, by process.
    pub floor: EntropyFloor,
    /// Its total, bytes.
    pub floor_bytes: f64,
    /// The static base map, which the floor takes as known but every file must hold once:
    /// `zstd -19` of the base map file, bytes (a reference, not a bound).
    pub base_map_bytes: Option<u64>,
    /// Lossless storage rows against it.
    pub rows: Vec<FloorRow>,
}

/// One row's bytes against the floor plus the base map.
fn with_base(bytes: u64, floor_bytes: f64, base: Option<u64>) -> Option<f64> {
    base.and_then(|b| crate::tables::ratio(bytes as f64, floor_bytes + b as f64))
}

/// `zstd -19` of the base map file, bytes.
pub fn base_map_bytes(path: &Path) -> Result<u64> {
    let out = std::process::Command::new("zstd")
        .args(["-19", "-q", "-c"])
        .arg(path)
        .stdin(std::process::Stdio::null())
        .output()
        .context("cannot start zstd")?;
    if !out.status.success() {
        bail!("zstd -19 {} failed ({})", path.display(), out.status);
    }
    Ok(out.stdout.len() as u64)
}

impl FloorSection {
    /// The floor against the lossless rows of `storage` (raw files, archives and lossless
    /// froctomap files; lossy files do not reproduce the series, so the floor does not
    /// bound them and they are left out).
    pub fn new(floor: EntropyFloor, storage: &[StorageRow], base_map_bytes: Option<u64>) -> Self {
        let floor_bytes = floor.bytes();
        let rows = storage
            .iter()
            .filter(|r| !r.name.contains("lossy"))
            .map(|r| FloorRow {
                name: r.name.clone(),
                bytes: r.bytes,
                vs_floor: crate::tables::ratio(r.bytes as f64, floor_bytes),
            })
            .collect();
        Self {
            floor,
            floor_bytes,
            base_map_bytes,
            rows,
        }
    }

    /// The section as markdown.
    pub fn markdown(&self) -> String {
        let f = &self.floor;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "\n## Entropy floor\n\nWhat the generator's random draws put into the {} observed \
             training snapshots (docs/BENCHMARKS.md, \"The entropy floor\"): **{} bytes**. \
             Sensor noise: {} flips among {} observed surface-voxel readings.\n",
            group(f.frames),
            group(self.floor_bytes.round() as u64),
            group(f.noise_flips),
            group(f.noise_observed_candidates),
        );
        let total = f.total_bits().max(f64::MIN_POSITIVE);
        let terms: Vec<Vec<String>> = f
            .terms()
            .into_iter()
            .map(|(name, bits)| {
                vec![
                    name.to_string(),
                    group((bits / 8.0).round() as u64),
                    format!("{:.2} %", 100.0 * bits / total),
                ]
            })
            .collect();
        out.push_str(&table(
            &["process", "bytes", "share"],
            &label_then_numbers(3),
            &terms,
        ));
        if !self.rows.is_empty() {
            out.push('\n');
            let rows: Vec<Vec<String>> = self
                .rows
                .iter()
                .map(|r| {
                    vec![
                        r.name.clone(),
                        group(r.bytes),
                        megabytes(r.bytes),
                        times(r.vs_floor),
                        times(with_base(r.bytes, self.floor_bytes, self.base_map_bytes)),
                    ]
                })
                .collect();
            out.push_str(&table(
                &[
                    "lossless storage",
                    "bytes",
                    "size",
                    "× floor",
                    "× (floor + base map)",
                ],
                &label_then_numbers(5),
                &rows,
            ));
        }
        if let Some(base) = self.base_map_bytes {
            let _ = writeln!(
                out,
                "
Base map: {} bytes under `zstd -19` (static; the floor takes it as known, every \
                 file holds it once).",
                group(base)
            );
        }
        out
    }
}

/// Options of `froctomap-bench floor`.
#[derive(Args, Debug)]
pub struct FloorArgs {
    #[command(flatten)]
    series: SeriesArgs,
    /// Where the series is (reused when it matches, else generated there). Without it the
    /// floor is computed from the generator alone, writing nothing (any size, e.g.
    /// paper-week, in about a minute).
    #[arg(long, required_if_eq("measure", "true"))]
    data: Option<PathBuf>,
    /// Where floor.json, floor.md and (with --measure) the built file go.
    #[arg(long, default_value = "target/bench-floor")]
    out: PathBuf,
    /// Also build the lossless file, archive the series with tar | zstd -19 --long=31 and
    /// time retrieving one snapshot, against the floor.
    #[arg(long)]
    measure: bool,
    /// With --measure, leave out tar | zstd (slow on long series; its size does not depend
    /// on froctomap's format, so a second measurement of the same series can skip it).
    #[arg(long)]
    no_archive: bool,
    /// Runs behind the retrieval median.
    #[arg(long, default_value_t = 9, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeats: u32,
    /// Memory budget of the build, MiB (default: the build's).
    #[arg(long)]
    memory_mib: Option<u64>,
}

/// What `floor --measure` measured besides the sizes.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FloorTimes {
    /// Wall seconds of the lossless build (child process).
    pub build_seconds: f64,
    /// Peak memory of the build.
    pub build_peak_memory_bytes: Option<u64>,
    /// Median seconds to retrieve the middle snapshot (open, observed map, write .bt).
    pub retrieve_seconds: f64,
    /// Median seconds of one C++ read of that snapshot.
    pub cpp_read_one_seconds: f64,
    /// Seconds of tar | zstd (`None`: skipped).
    pub zstd_seconds: Option<f64>,
}

/// `froctomap-bench floor`.
pub fn floor_command(args: &FloorArgs) -> Result<()> {
    let started = Instant::now();
    let note = |m: &str| eprintln!("[{:>6.0} s] {m}", started.elapsed().as_secs_f64());
    let Some(data) = &args.data else {
        let (generator, _, _, train_count) = args.series.generator()?;
        let floor = generator.entropy_floor(0..train_count);
        let section = FloorSection::new(floor, &[], Some(base_map_bytes(&args.series.base)?));
        return write_report(args, train_count as usize, &section, None);
    };
    let series = args.series.prepare(data, &note)?;
    let train = &series.written.train;
    note(&format!(
        "series: {} training snapshots in {}",
        train.len(),
        data.display()
    ));
    let floor = series.generator.entropy_floor(0..series.train_count);
    note(&format!("floor computed ({:.0} bytes)", floor.bytes()));
    let mut bt_bytes = 0;
    for input in train {
        bt_bytes += std::fs::metadata(&input.path)
            .with_context(|| format!("reading {}", input.path.display()))?
            .len();
    }
    let mut storage = vec![StorageRow {
        name: crate::tables::rows::RAW.into(),
        bytes: bt_bytes,
        ..StorageRow::default()
    }];
    let mut measured = None;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    if args.measure {
        let zstd = if args.no_archive {
            None
        } else {
            note("tar | zstd -19 --long=31 -T0");
            let zstd = tar_through(
                &data.join("train"),
                "zstd",
                &["-19", "--long=31", "-T0", "-q", "-c"],
            )?;
            storage.push(StorageRow {
                name: crate::tables::rows::ZSTD.into(),
                bytes: zstd.bytes,
                ..StorageRow::default()
            });
            Some(zstd)
        };
        note("building lossless");
        let lossless = args.out.join("lossless.froct");
        let build = crate::child_build::spawn_build(
            crate::tables::rows::LOSSLESS,
            &data.join("train").join("manifest.csv"),
            &lossless,
            &crate::child_build::ChildModel::fremen(None, 5),
            false,
            false,
            args.memory_mib,
        )?;
        storage.push(StorageRow {
            name: crate::tables::rows::LOSSLESS.into(),
            bytes: build.file_bytes,
            ..StorageRow::default()
        });
        note("timing one retrieval");
        let (retrieve_seconds, cpp_read_one_seconds) =
            time_retrieval(&lossless, train, args.repeats, &args.out)?;
        measured = Some(FloorTimes {
            build_seconds: build.seconds,
            build_peak_memory_bytes: build.peak_memory_bytes,
            retrieve_seconds,
            cpp_read_one_seconds,
            zstd_seconds: zstd.map(|z| z.seconds),
        });
    }
    let section = FloorSection::new(floor, &storage, Some(base_map_bytes(&args.series.base)?));
    write_report(args, train.len(), &section, measured.as_ref())
}

/// Prints the section (and the times) and writes floor.json and floor.md.
fn write_report(
    args: &FloorArgs,
    train_frames: usize,
    section: &FloorSection,
    measured: Option<&FloorTimes>,
) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let mut markdown = section.markdown();
    if let Some(t) = measured {
        let _ =
            writeln!(
            markdown,
            "\nLossless build {} (peak {}), retrieve one snapshot {} ({} of one C++ read, {}); \
             tar | zstd {}.",
            duration(t.build_seconds),
            crate::tables::mebibytes(t.build_peak_memory_bytes),
            duration(t.retrieve_seconds),
            times(crate::tables::ratio(t.retrieve_seconds, t.cpp_read_one_seconds)),
            duration(t.cpp_read_one_seconds),
            t.zstd_seconds.map_or_else(|| "skipped".into(), duration),
        );
    }
    std::fs::write(
        args.out.join("floor.json"),
        serde_json::to_string_pretty(&serde_json::json!({
            "size": args.series.size,
            "train_frames": train_frames,
            "floor": section,
            "times": measured,
        }))?,
    )?;
    std::fs::write(args.out.join("floor.md"), &markdown)?;
    println!("{markdown}");
    Ok(())
}

/// Medians of retrieving the middle snapshot from `file` and of one C++ read of its input;
/// checks that the retrieved map is the input.
fn time_retrieval(
    file: &Path,
    train: &[froctomap_convert::SeriesInput],
    repeats: u32,
    scratch: &Path,
) -> Result<(f64, f64)> {
    let context = froctomap_convert::Context::with_default_plugins();
    let mid = train
        .get(train.len() / 2)
        .context("no training snapshots")?;
    let sample = FroctReader::open(file)?
        .header()
        .axis
        .index_of(mid.time)
        .context("the middle snapshot is not on the file's axis")?;
    let retrieved = scratch.join("retrieved.bt");
    let retrieve = crate::child_build::timed(repeats, || {
        crate::child_build::retrieve_once(&context, file, sample, &retrieved)
    })?;
    let cpp = crate::child_build::timed(repeats, || {
        let bytes = std::fs::read(&mid.path)?;
        std::hint::black_box(froctomap_octomap_ffi::OcTree::read_binary(&bytes)?);
        Ok(())
    })?;
    let registry = context.formats();
    let back = registry.read_file(&retrieved, ReadOptions::default())?;
    let original = registry.read_file(&mid.path, ReadOptions::default())?;
    if back.map.snapshot.to_max_likelihood().canonical()
        != original.map.snapshot.to_max_likelihood().canonical()
    {
        bail!("the retrieved snapshot differs from the input it was built from");
    }
    Ok((retrieve, cpp))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lossless_rows_only_against_the_floor() {
        let floor = EntropyFloor {
            frames: 2,
            noise_bits: 8000.0,
            people_bits: 800.0,
            ..EntropyFloor::default()
        };
        let row = |name: &str, bytes| StorageRow {
            name: name.into(),
            bytes,
            ..StorageRow::default()
        };
        let storage = [
            row(crate::tables::rows::ZSTD, 3300),
            row(crate::tables::rows::LOSSLESS, 2200),
            row(&crate::tables::rows::lossy(2), 100),
        ];
        let section = FloorSection::new(floor, &storage, Some(1000));
        assert_eq!(section.floor_bytes, 1100.0);
        let names: Vec<&str> = section.rows.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(
            names,
            [crate::tables::rows::ZSTD, crate::tables::rows::LOSSLESS]
        );
        assert_eq!(section.rows[1].vs_floor, Some(2.0));
        assert_eq!(with_base(4200, 1100.0, Some(1000)), Some(2.0));
        let md = section.markdown();
        assert!(
            md.contains("| froctomap lossless (auto order ≤ 5) | 2,200 | 2.2 kB | 2.00× | 1.05× |"),
            "{md}"
        );
        assert!(md.contains("| people (bound) | 100 |"), "{md}");
    }
}
