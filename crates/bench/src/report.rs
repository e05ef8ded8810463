//! The results of one benchmark run, their markdown rendering and the verdict on each target.
//!
//! Everything here is plain data and arithmetic, so it is unit-tested without running
//! anything; `results.json` is the serialised [`Results`].

use crate::child_build::BuildRow;
use crate::system::Machine;
use crate::tables::{
    duration, label_then_numbers, mebibytes, megabytes, percent, ratio, rows, table, times, Align,
    StorageRow,
};
use froctomap_convert::group_thousands;
use serde::Serialize;
use std::fmt::Write as _;

/// Everything one `froctomap-bench run` measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Results {
    /// Where it ran.
    pub machine: Machine,
    /// What it ran on.
    pub dataset: Dataset,
    /// Bytes of each way of storing the training series.
    pub storage: Vec<StorageRow>,
    /// Build, read, retrieve and predict times.
    pub time: TimeResults,
    /// Peak memory of builds of two series lengths.
    pub memory: Vec<MemoryRow>,
    /// Reconstruction and prediction errors per file.
    pub accuracy: Vec<AccuracyRow>,
    /// Baselines' errors (from the lossless file's data).
    pub baselines: Vec<AccuracyRow>,
    /// The targets, each with its measured value.
    pub targets: Vec<Target>,
    /// Wall time of the whole run, seconds.
    pub total_seconds: f64,
    /// The generator's entropy floor and the lossless sizes against it.
    pub floor: Option<crate::floor::FloorSection>,
}

/// The benchmark series.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Dataset {
    /// Base map path.
    pub base: String,
    /// Real door series path.
    pub door_file: String,
    /// Generator seed.
    pub seed: u64,
    /// Seconds between frames.
    pub step_seconds: f64,
    /// Training span in days.
    pub train_days: f64,
    /// Held-out span in days (right after the training span).
    pub heldout_days: f64,
    /// Training snapshots (the files every storage and time row is measured on).
    pub train_frames: usize,
    /// Held-out ground-truth maps.
    pub heldout_frames: usize,
    /// First and last training time (ISO 8601).
    pub first: String,
    /// Last training time.
    pub last: String,
    /// Bytes of the training `.bt` files.
    pub bt_bytes: u64,
    /// Leaves of the base map.
    pub base_leaves: usize,
    /// Voxels the lossless file describes (its cells' voxels).
    pub voxels: u64,
    /// Of those, voxels that changed state at least once.
    pub dynamic_voxels: u64,
    /// One line per placed element kind (`door: 6 of 6 ...`).
    pub elements: Vec<String>,
    /// Training snapshots used as reconstruction ground truth.
    pub reconstruction_truths: usize,
    /// Held-out maps used as prediction ground truth.
    pub prediction_truths: usize,
    /// Seconds spent generating the series.
    pub generate_seconds: f64,
}

/// Times.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TimeResults {
    /// Seconds for the C++ library to read every training `.bt` (parallel over `threads`).
    pub cpp_read_all_seconds: f64,
    /// Leaves the C++ library read in all (a check that it did the work).
    pub cpp_read_leaves: u64,
    /// Builds (lossless native, lossless with the C++ reader, lossy orders, memory runs).
    pub builds: Vec<BuildRow>,
    /// Median seconds of one C++ read of one `.bt` (file read + `readBinary`).
    pub cpp_read_one_seconds: f64,
    /// Median seconds of one native (Rust) read of the same `.bt`.
    pub native_read_one_seconds: f64,
    /// Median seconds of one retrieval (open file, observed map, write `.bt`), in-process.
    pub retrieve_seconds: f64,
    /// Median seconds of one prediction (open file, predicted map, write `.bt`), in-process.
    pub predict_seconds: f64,
    /// Median wall seconds of `froctomap retrieve` (a process), when the CLI was found.
    pub cli_retrieve_seconds: Option<f64>,
    /// Median wall seconds of `froctomap predict`.
    pub cli_predict_seconds: Option<f64>,
    /// Runs behind each median.
    pub repeats: usize,
    /// Sample index retrieved.
    pub retrieve_sample: u32,
}

/// Peak memory of a build at one series length.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MemoryRow {
    /// Snapshots.
    pub frames: usize,
    /// Days covered.
    pub days: f64,
    /// Peak resident memory, bytes.
    pub peak_memory_bytes: Option<u64>,
    /// Build seconds.
    pub seconds: f64,
    /// Output bytes.
    pub file_bytes: u64,
}

/// Error rates in percent over the three voxel sets (`None`: nothing compared).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Errors {
    /// All compared voxels.
    pub all: Option<f64>,
    /// Voxels occupied in the truth or ever occupied in the data.
    pub non_empty: Option<f64>,
    /// Voxels whose state changed in the data.
    pub dynamic: Option<f64>,
}

impl Errors {
    /// From `froctomap_convert`'s counts.
    pub fn from_rates(rates: &froctomap_convert::ErrorRates) -> Self {
        Self {
            all: rates.all.percent(),
            non_empty: rates.non_empty.percent(),
            dynamic: rates.dynamic.percent(),
        }
    }
}

/// Errors of one method (a file's model, or a baseline).
#[derive(Clone, Debug, Default, Serialize)]
pub struct AccuracyRow {
    /// Method and file.
    pub name: String,
    /// Fixed order (`None`: auto, or a baseline).
    pub order: Option<u8>,
    /// Reconstruction error on training snapshots.
    pub reconstruction: Errors,
    /// Prediction error on held-out ground truth.
    pub prediction: Errors,
}

/// One target of the issue and how it went.
#[derive(Clone, Debug, Serialize)]
pub struct Target {
    /// The target as the issue states it.
    pub target: String,
    /// What was measured.
    pub measured: String,
    /// Met or not (`None`: not measured).
    pub met: Option<bool>,
}

impl Results {
    fn storage(&self, name: &str) -> Option<&StorageRow> {
        self.storage.iter().find(|r| r.name == name)
    }

    fn build(&self, name: &str) -> Option<&BuildRow> {
        self.time.builds.iter().find(|r| r.name == name)
    }

    fn accuracy_row(&self, name: &str) -> Option<&AccuracyRow> {
        self.accuracy
            .iter()
            .chain(&self.baselines)
            .find(|r| r.name == name)
    }

    /// Judges every target of the issue from the measurements.
    pub fn judge(&self) -> Vec<Target> {
        let mut out = Vec::new();
        // Storage.
        let lossless = self.storage(rows::LOSSLESS).map(|r| r.bytes as f64);
        let zstd = self.storage(rows::ZSTD).map(|r| r.bytes as f64);
        let r = lossless.zip(zstd).and_then(|(a, b)| ratio(a, b));
        out.push(Target {
            target: "lossless file ≤ 0.4 × tar | zstd -19 --long=31".into(),
            measured: format!("{} of the zstd archive", times(r)),
            met: r.map(|r| r <= 0.4),
        });
        // Build vs the C++ read-only time.
        let read = self.time.cpp_read_all_seconds;
        for (name, limit, label) in [
            (rows::BUILD_FFI, 1.2, "while the C++ (FFI) reader is used"),
            (rows::BUILD_NATIVE, 0.1, "with the native codec"),
        ] {
            let r = self.build(name).and_then(|b| ratio(b.seconds, read));
            out.push(Target {
                target: format!("build ≤ {limit} × the C++ read-only time {label}"),
                measured: format!(
                    "{} ({} vs {})",
                    times(r),
                    self.build(name)
                        .map_or("n/a".into(), |b| duration(b.seconds)),
                    duration(read)
                ),
                met: r.map(|r| r <= limit),
            });
        }
        let r = ratio(self.time.retrieve_seconds, self.time.cpp_read_one_seconds);
        out.push(Target {
            target: "retrieve of one snapshot ≤ 0.3 × one C++ read".into(),
            measured: format!(
                "{} ({} vs {})",
                times(r),
                duration(self.time.retrieve_seconds),
                duration(self.time.cpp_read_one_seconds)
            ),
            met: r.map(|r| r <= 0.3),
        });
        // Prediction on dynamic voxels.
        let dynamic = |name: &str| self.accuracy_row(name).and_then(|r| r.prediction.dynamic);
        let model = dynamic(rows::MODEL_LOSSLESS);
        let mean = dynamic(rows::STATIC_MEAN);
        let last = dynamic(rows::LAST_SEEN);
        out.push(Target {
            target: "prediction error on dynamic voxels below static mean and last seen".into(),
            measured: format!(
                "model {} vs static mean {} and last seen {}",
                percent(model),
                percent(mean),
                percent(last)
            ),
            met: match (model, mean, last) {
                (Some(m), Some(a), Some(b)) => Some(m < a && m < b),
                _ => None,
            },
        });
        // Memory.
        let mut memory: Vec<&MemoryRow> = self
            .memory
            .iter()
            .filter(|m| m.peak_memory_bytes.is_some())
            .collect();
        memory.sort_by_key(|m| m.frames);
        let (measured, met) = match (memory.first(), memory.last()) {
            (Some(short), Some(long)) if long.frames > short.frames => {
                let growth = ratio(
                    long.peak_memory_bytes.unwrap_or(0) as f64,
                    short.peak_memory_bytes.unwrap_or(0) as f64,
                );
                (
                    format!(
                        "{} for {} snapshots, {} for {} ({} the memory for {} the snapshots)",
                        mebibytes(short.peak_memory_bytes),
                        group_thousands(short.frames as u64),
                        mebibytes(long.peak_memory_bytes),
                        group_thousands(long.frames as u64),
                        times(growth),
                        times(ratio(long.frames as f64, short.frames as f64)),
                    ),
                    growth.map(|g| g <= MEMORY_GROWTH_LIMIT),
                )
            }
            _ => ("n/a".into(), None),
        };
        out.push(Target {
            target: format!(
                "peak memory independent of the number of snapshots (here: ≤ {MEMORY_GROWTH_LIMIT} × between the two lengths)"
            ),
            measured,
            met,
        });
        out
    }

    /// The whole report as markdown.
    pub fn markdown(&self) -> String {
        let mut out = String::new();
        self.series_markdown(&mut out);
        self.storage_markdown(&mut out);
        self.builds_markdown(&mut out);
        self.one_snapshot_markdown(&mut out);
        self.memory_markdown(&mut out);
        self.accuracy_markdown(&mut out);
        self.targets_markdown(&mut out);
        let _ = writeln!(out, "\nTotal benchmark time: {:.0} s.", self.total_seconds);
        out
    }

    /// The series, its elements and the machine.
    fn series_markdown(&self, out: &mut String) {
        let d = &self.dataset;
        let _ = writeln!(
            out,
            "## Series\n\n{} training snapshots ({} days every {} s, {} .. {}) of `{}` \
             ({} leaves) with doors driven by `{}` (seed {}), plus {} held-out days right after \
             ({} ground-truth maps). Raw `.bt` files: {} bytes. Voxels: {} ({} dynamic). \
             Generated in {:.0} s.\n",
            group_thousands(d.train_frames as u64),
            d.train_days,
            d.step_seconds,
            d.first,
            d.last,
            d.base,
            group_thousands(d.base_leaves as u64),
            d.door_file,
            d.seed,
            d.heldout_days,
            group_thousands(d.heldout_frames as u64),
            group_thousands(d.bt_bytes),
            group_thousands(d.voxels),
            group_thousands(d.dynamic_voxels),
            d.generate_seconds,
        );
        for line in &d.elements {
            let _ = writeln!(out, "* {line}");
        }
        let m = &self.machine;
        let _ = writeln!(
            out,
            "\nMachine: {} ({} CPUs, {} threads used), {:.1} GiB memory, Linux {}; {}.\n",
            m.cpu,
            m.cpus,
            m.threads,
            m.memory_bytes as f64 / (1024.0 * 1024.0 * 1024.0),
            m.kernel,
            m.tools.join(", ")
        );
    }

    /// The storage table.
    fn storage_markdown(&self, out: &mut String) {
        let d = &self.dataset;
        out.push_str("## Storage\n\n");
        let raw = d.bt_bytes as f64;
        let rows: Vec<Vec<String>> = self
            .storage
            .iter()
            .map(|r| {
                vec![
                    r.name.clone(),
                    group_thousands(r.bytes),
                    megabytes(r.bytes),
                    times(ratio(raw, r.bytes as f64)),
                    times(r.vs_raw_states),
                    r.seconds.map_or_else(|| "-".into(), duration),
                ]
            })
            .collect();
        out.push_str(&table(
            &[
                "storage",
                "bytes",
                "size",
                "vs raw .bt",
                "vs raw states (1 bit/voxel/snapshot)",
                "time to make",
            ],
            &label_then_numbers(6),
            &rows,
        ));
    }

    /// The C++ read of all inputs and the builds against it.
    fn builds_markdown(&self, out: &mut String) {
        let d = &self.dataset;
        let m = &self.machine;
        let t = &self.time;
        let _ = writeln!(
            out,
            "\n## Time\n\nC++ library (`OcTree::readBinary`) reading all {} training files on {} threads: \
             {} ({} leaves).\n",
            group_thousands(d.train_frames as u64),
            m.threads,
            duration(t.cpp_read_all_seconds),
            group_thousands(t.cpp_read_leaves)
        );
        let rows: Vec<Vec<String>> = t
            .builds
            .iter()
            .map(|b| {
                vec![
                    b.name.clone(),
                    group_thousands(b.frames as u64),
                    duration(b.seconds),
                    duration(b.read_seconds),
                    duration(b.model_seconds),
                    times(ratio(b.seconds, t.cpp_read_all_seconds)),
                    mebibytes(b.peak_memory_bytes),
                    group_thousands(b.file_bytes),
                ]
            })
            .collect();
        out.push_str(&table(
            &[
                "build",
                "snapshots",
                "wall",
                "reading",
                "modelling",
                "vs C++ read of all inputs",
                "peak memory",
                "bytes",
            ],
            &label_then_numbers(8),
            &rows,
        ));
    }

    /// Reading, retrieving and predicting one snapshot against one C++ read.
    fn one_snapshot_markdown(&self, out: &mut String) {
        let t = &self.time;
        let one = t.cpp_read_one_seconds;
        let mut rows = vec![
            vec![
                "C++ read of one .bt (file + `readBinary`)".to_string(),
                duration(one),
                times(Some(1.0)),
            ],
            vec![
                "native read of one .bt (froctomap codec)".to_string(),
                duration(t.native_read_one_seconds),
                times(ratio(t.native_read_one_seconds, one)),
            ],
            vec![
                "retrieve one snapshot (open, observed map, write .bt)".to_string(),
                duration(t.retrieve_seconds),
                times(ratio(t.retrieve_seconds, one)),
            ],
            vec![
                "predict one snapshot (open, predicted map, write .bt)".to_string(),
                duration(t.predict_seconds),
                times(ratio(t.predict_seconds, one)),
            ],
        ];
        for (name, v) in [
            ("`froctomap retrieve` process, wall", t.cli_retrieve_seconds),
            ("`froctomap predict` process, wall", t.cli_predict_seconds),
        ] {
            rows.push(vec![
                name.to_string(),
                v.map_or_else(|| "not run".into(), duration),
                times(v.and_then(|v| ratio(v, one))),
            ]);
        }
        let _ = writeln!(
            out,
            "\nOne snapshot (sample {}; medians of {} runs, in-process unless noted):\n",
            t.retrieve_sample, t.repeats
        );
        out.push_str(&table(
            &["operation", "time", "vs one C++ read"],
            &label_then_numbers(3),
            &rows,
        ));
    }

    /// Peak memory against the series length.
    fn memory_markdown(&self, out: &mut String) {
        out.push_str("\n## Peak memory vs series length\n\n");
        let rows: Vec<Vec<String>> = self
            .memory
            .iter()
            .map(|r| {
                vec![
                    group_thousands(r.frames as u64),
                    format!("{:.1}", r.days),
                    mebibytes(r.peak_memory_bytes),
                    duration(r.seconds),
                    group_thousands(r.file_bytes),
                ]
            })
            .collect();
        out.push_str(&table(
            &[
                "snapshots",
                "days",
                "peak memory (lossless build)",
                "build time",
                "file bytes",
            ],
            &[
                Align::Right,
                Align::Right,
                Align::Right,
                Align::Right,
                Align::Right,
            ],
            &rows,
        ));
    }

    /// The accuracy table, baselines included.
    fn accuracy_markdown(&self, out: &mut String) {
        let d = &self.dataset;
        let _ = writeln!(
            out,
            "\n## Accuracy\n\nError rates (wrong voxels / compared voxels). Reconstruction: the model \
             alone (no outliers) against {} training snapshots; prediction: against the {} \
             ground-truth maps of the {} held-out days.\n",
            d.reconstruction_truths, d.prediction_truths, d.heldout_days
        );
        let rows: Vec<Vec<String>> = self
            .accuracy
            .iter()
            .chain(&self.baselines)
            .map(|r| {
                vec![
                    r.name.clone(),
                    percent(r.reconstruction.all),
                    percent(r.reconstruction.non_empty),
                    percent(r.reconstruction.dynamic),
                    percent(r.prediction.all),
                    percent(r.prediction.non_empty),
                    percent(r.prediction.dynamic),
                ]
            })
            .collect();
        out.push_str(&table(
            &[
                "method",
                "reconstruction: all",
                "non-empty",
                "dynamic",
                "prediction: all",
                "non-empty",
                "dynamic",
            ],
            &label_then_numbers(7),
            &rows,
        ));
    }

    /// The targets and their verdicts.
    fn targets_markdown(&self, out: &mut String) {
        out.push_str("\n## Targets\n\n");
        let rows: Vec<Vec<String>> = self
            .targets
            .iter()
            .map(|t| {
                vec![
                    t.target.clone(),
                    t.measured.clone(),
                    match t.met {
                        Some(true) => "met".into(),
                        Some(false) => "**missed**".into(),
                        None => "not measured".into(),
                    },
                ]
            })
            .collect();
        out.push_str(&table(
            &["target", "measured", "verdict"],
            &[Align::Left, Align::Left, Align::Left],
            &rows,
        ));
    }
}

/// Largest peak-memory growth between the two series lengths that still counts as
/// "independent of the number of snapshots".
pub const MEMORY_GROWTH_LIMIT: f64 = 1.25;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tables::median;

    #[test]
    fn tables_render_as_markdown() {
        let t = table(
            &["a", "b|c"],
            &[Align::Left, Align::Right],
            &[vec!["x".into(), "1".into()], vec!["only".into()]],
        );
        assert_eq!(t, "| a | b\\|c |\n| --- | ---: |\n| x | 1 |\n| only |  |\n");
    }

    #[test]
    fn numbers_format() {
        assert_eq!(megabytes(2_430_000), "2.43 MB");
        assert_eq!(megabytes(845_000_000), "845 MB");
        assert_eq!(megabytes(61_500), "61.5 kB");
        assert_eq!(duration(0.0715), "71.5 ms");
        assert_eq!(duration(32.04), "32.0 s");
        assert_eq!(times(Some(0.0361)), "0.036×");
        assert_eq!(times(Some(0.36)), "0.36×");
        assert_eq!(times(Some(347.6)), "348×");
        assert_eq!(times(None), "n/a");
        assert_eq!(percent(Some(1.234)), "1.23 %");
        assert_eq!(percent(None), "-");
        assert_eq!(mebibytes(Some(3 * 1024 * 1024)), "3 MiB");
    }

    #[test]
    fn medians_and_ratios() {
        assert_eq!(median(&[]), None);
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&[f64::NAN, 5.0]), Some(5.0));
        assert_eq!(ratio(1.0, 0.0), None);
        assert_eq!(ratio(1.0, 4.0), Some(0.25));
    }

    fn sample() -> Results {
        let storage = |name: &str, bytes| StorageRow {
            name: name.into(),
            bytes,
            ..StorageRow::default()
        };
        let build = |name: &str, seconds| BuildRow {
            name: name.into(),
            seconds,
            ..BuildRow::default()
        };
        let prediction = |name: &str, dynamic| AccuracyRow {
            name: name.into(),
            prediction: Errors {
                dynamic: Some(dynamic),
                ..Errors::default()
            },
            ..AccuracyRow::default()
        };
        let memory = |frames, peak| MemoryRow {
            frames,
            peak_memory_bytes: Some(peak),
            ..MemoryRow::default()
        };
        Results {
            storage: vec![
                storage(rows::RAW, 1000),
                storage(rows::ZSTD, 100),
                storage(rows::LOSSLESS, 36),
            ],
            time: TimeResults {
                cpp_read_all_seconds: 100.0,
                builds: vec![
                    build(rows::BUILD_NATIVE, 11.0),
                    build(rows::BUILD_FFI, 110.0),
                ],
                cpp_read_one_seconds: 0.08,
                retrieve_seconds: 0.02,
                ..TimeResults::default()
            },
            accuracy: vec![prediction(rows::MODEL_LOSSLESS, 10.0)],
            baselines: vec![
                prediction(rows::STATIC_MEAN, 12.0),
                prediction(rows::LAST_SEEN, 9.0),
            ],
            memory: vec![memory(4000, 1300), memory(1000, 1000)],
            ..Results::default()
        }
    }

    #[test]
    fn targets_are_judged_from_the_measurements() {
        let verdicts: Vec<Option<bool>> = sample().judge().iter().map(|t| t.met).collect();
        // zstd 0.36 ok; FFI build 1.1 ok; native 0.11 missed; retrieve 0.25 ok;
        // prediction 10 % not below last seen 9 %; memory 1.3× over the limit.
        assert_eq!(
            verdicts,
            [
                Some(true),
                Some(true),
                Some(false),
                Some(true),
                Some(false),
                Some(false)
            ]
        );
        let empty: Vec<Option<bool>> = Results::default().judge().iter().map(|t| t.met).collect();
        assert!(empty.iter().all(Option::is_none), "{empty:?}");
    }

    #[test]
    fn markdown_has_every_section() {
        let mut r = sample();
        r.targets = r.judge();
        let md = r.markdown();
        for heading in [
            "## Series",
            "## Storage",
            "## Time",
            "## Peak memory",
            "## Accuracy",
            "## Targets",
        ] {
            assert!(md.contains(heading), "{heading} missing");
        }
        assert!(md.contains("| tar \\| zstd -19 --long=31 | 100 |"), "{md}");
        assert!(md.contains("**missed**"));
    }
}
