//! The building blocks of every report: markdown tables, how numbers are written, and the
//! rows the targets refer to. Plain text and arithmetic, below every measuring module.

use serde::Serialize;
use std::fmt::Write as _;

/// One way of storing the training series.
#[derive(Clone, Debug, Default, Serialize)]
pub struct StorageRow {
    /// What it is.
    pub name: String,
    /// Bytes.
    pub bytes: u64,
    /// Seconds it took to make (when measured).
    pub seconds: Option<f64>,
    /// Compression ratio against the raw states (voxels × snapshots, one bit each).
    pub vs_raw_states: Option<f64>,
    /// Model order of a froctomap file (`None`: not a froctomap file, or auto).
    pub order: Option<u8>,
}

/// Column alignment of a markdown table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Align {
    /// Left.
    Left,
    /// Right (numbers).
    Right,
}

/// Alignment of a table whose first column names the row and the others hold numbers.
pub fn label_then_numbers(columns: usize) -> Vec<Align> {
    let mut align = vec![Align::Right; columns];
    if let Some(first) = align.first_mut() {
        *first = Align::Left;
    }
    align
}

/// A markdown table. Cells containing `|` are escaped; short rows are padded.
pub fn table(headers: &[&str], align: &[Align], rows: &[Vec<String>]) -> String {
    let escape = |s: &str| s.replace('|', "\\|");
    let mut out = String::new();
    out.push('|');
    for h in headers {
        let _ = write!(out, " {} |", escape(h));
    }
    out.push_str("\n|");
    for i in 0..headers.len() {
        out.push_str(match align.get(i) {
            Some(Align::Right) => " ---: |",
            _ => " --- |",
        });
    }
    out.push('\n');
    for row in rows {
        out.push('|');
        for i in 0..headers.len() {
            let cell = row.get(i).map_or("", String::as_str);
            let _ = write!(out, " {} |", escape(cell));
        }
        out.push('\n');
    }
    out
}

/// Bytes in decimal megabytes with three significant decimals where small.
pub fn megabytes(bytes: u64) -> String {
    let mb = bytes as f64 / 1e6;
    if mb >= 100.0 {
        format!("{mb:.0} MB")
    } else if mb >= 1.0 {
        format!("{mb:.2} MB")
    } else {
        format!("{:.1} kB", bytes as f64 / 1e3)
    }
}

/// Memory in MiB.
pub fn mebibytes(bytes: Option<u64>) -> String {
    bytes.map_or_else(
        || "n/a".into(),
        |b| format!("{:.0} MiB", b as f64 / (1024.0 * 1024.0)),
    )
}

/// A duration: milliseconds below 10 s, else seconds.
pub fn duration(seconds: f64) -> String {
    if seconds < 10.0 {
        format!("{:.1} ms", seconds * 1e3)
    } else {
        format!("{seconds:.1} s")
    }
}

/// `a / b`, `None` when `b` is not positive.
pub fn ratio(a: f64, b: f64) -> Option<f64> {
    (b > 0.0 && a.is_finite()).then(|| a / b)
}

/// A ratio as `0.123×` (3 significant figures for small values).
pub fn times(r: Option<f64>) -> String {
    match r {
        None => "n/a".into(),
        Some(r) if r >= 100.0 => format!("{r:.0}×"),
        Some(r) if r >= 10.0 => format!("{r:.1}×"),
        Some(r) if r >= 0.1 => format!("{r:.2}×"),
        Some(r) => format!("{r:.3}×"),
    }
}

/// A percentage with two decimals (`-` when nothing was compared).
pub fn percent(p: Option<f64>) -> String {
    p.map_or_else(|| "-".into(), |p| format!("{p:.2} %"))
}

/// The median of `times` (mean of the middle two for even counts); zero for none.
pub fn median_duration(times: &[std::time::Duration]) -> std::time::Duration {
    let seconds: Vec<f64> = times.iter().map(std::time::Duration::as_secs_f64).collect();
    std::time::Duration::from_secs_f64(median(&seconds).unwrap_or(0.0))
}

/// The median (mean of the middle two for even counts); `None` for no values.
pub fn median(values: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    })
}

/// Names of the special rows the targets refer to.
pub mod rows {
    /// The raw `.bt` archive.
    pub const RAW: &str = "raw .bt files";
    /// `tar | zstd -19 --long=31`.
    pub const ZSTD: &str = "tar | zstd -19 --long=31";
    /// `tar | xz -9`.
    pub const XZ: &str = "tar | xz -9";
    /// froctomap lossless (auto order).
    pub const LOSSLESS: &str = "froctomap lossless (auto order ≤ 5)";
    /// The default build (lossless, native reader).
    pub const BUILD_NATIVE: &str = "build lossless (native reader, default)";
    /// The lossless build through the C++ reader.
    pub const BUILD_FFI: &str = "build lossless (C++ reader, --backend octomap)";
    /// The model of the lossless file.
    pub const MODEL_LOSSLESS: &str = "model (lossless file, auto order)";
    /// The two-state Markov model (a lossy file built with `--model markov`).
    pub const MARKOV: &str = "markov model (lossy file)";
    /// Its build.
    pub const MARKOV_BUILD: &str = "build lossy, markov model";
    /// Static-mean baseline.
    pub const STATIC_MEAN: &str = "static mean";
    /// Last-seen baseline.
    pub const LAST_SEEN: &str = "last seen";
    /// What the lossless file stores (its reconstruction must be exact).
    pub const STORED: &str = "stored (lossless file)";

    /// The lossy file with the order chosen per voxel (as the lossless default).
    pub const LOSSY_AUTO: &str = "froctomap lossy (auto order ≤ 5)";
    /// The name of a lossy file row with a fixed order.
    pub fn lossy(n: u8) -> String {
        format!("froctomap lossy, order {n}")
    }
}
