//! Benchmark sizes: how many days to train on, to hold out, and the shorter series of the
//! peak-memory comparison.

use anyhow::{bail, Result};

/// The spans of one benchmark run, in days.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// Training series (every storage and time row is measured on it).
    pub train_days: f64,
    /// Held-out days right after it (prediction ground truth).
    pub heldout_days: f64,
    /// The shorter prefix built again for the memory comparison.
    pub short_days: f64,
    /// The time between snapshots the size stands for (`paper-*`: the paper's 5 s), instead
    /// of `--step`.
    pub step: Option<&'static str>,
    /// Also build the first half for the memory comparison (¼, ½ and the whole series).
    pub half_too: bool,
}

/// Reads `ci`, `week`, `4weeks`, `<n>weeks`, `<n>d`/`<n>days`, a plain number of days, or
/// the paper's sampling, one snapshot every 5 s (whatever `--step` says): `paper-day`
/// (17,280 snapshots, about 3.6 GB of .bt) and `paper-week` (120,960, about 25 GB), whose
/// memory comparison builds ¼, ½ and the whole series.
///
/// `ci` is two training days and one held-out day (a few minutes on two cores); every
/// other size holds out two days. The memory comparison builds a quarter of the series
/// again (half for series under four days).
pub fn plan(size: &str, heldout_days: Option<f64>) -> Result<Plan> {
    let s = size.trim().to_ascii_lowercase();
    let paper = s.starts_with("paper-");
    let (train, default_heldout) = match s.as_str() {
        "ci" => (2.0, 1.0),
        "week" => (7.0, 2.0),
        // A held-out day at 5 s is 17,280 more snapshots: half a day is plenty.
        "paper-day" => (1.0, 0.5),
        "paper-week" => (7.0, 0.5),
        _ => {
            let days = if let Some(n) = s
                .strip_suffix("weeks")
                .or_else(|| s.strip_suffix("week"))
                .or_else(|| s.strip_suffix('w'))
            {
                number(n, size)? * 7.0
            } else if let Some(n) = s.strip_suffix("days").or_else(|| s.strip_suffix('d')) {
                number(n, size)?
            } else {
                number(&s, size)?
            };
            (days, 2.0)
        }
    };
    if !(train > 0.0 && train <= 3650.0) {
        bail!("--size {size}: the training span must be more than 0 and at most 3650 days");
    }
    let heldout = heldout_days.unwrap_or(default_heldout);
    if !(heldout > 0.0 && heldout <= 365.0) {
        bail!("--heldout-days {heldout}: must be more than 0 and at most 365");
    }
    let short = if train >= 4.0 {
        train / 4.0
    } else {
        train / 2.0
    };
    let short = if paper { train / 4.0 } else { short };
    Ok(Plan {
        train_days: train,
        heldout_days: heldout,
        short_days: short,
        step: paper.then_some("5s"),
        half_too: paper,
    })
}

fn number(text: &str, size: &str) -> Result<f64> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => {
            bail!("--size {size:?}: expected ci, week, 4weeks, <n>weeks, <n>d or a number of days")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes() {
        let p = plan("ci", None).unwrap();
        assert_eq!(
            (p.train_days, p.heldout_days, p.short_days),
            (2.0, 1.0, 1.0)
        );
        assert_eq!(plan("week", None).unwrap().train_days, 7.0);
        let p = plan("4weeks", None).unwrap();
        assert_eq!(
            (p.train_days, p.heldout_days, p.short_days),
            (28.0, 2.0, 7.0)
        );
        assert_eq!(plan("12w", None).unwrap().train_days, 84.0);
        assert_eq!(plan("1week", None).unwrap().train_days, 7.0);
        assert_eq!(plan("3d", Some(0.5)).unwrap().heldout_days, 0.5);
        assert_eq!(plan("10", None).unwrap().train_days, 10.0);
        assert_eq!(plan("3days", None).unwrap().short_days, 1.5);
        let p = plan("paper-day", None).unwrap();
        assert_eq!(
            (p.train_days, p.short_days, p.step, p.half_too),
            (1.0, 0.25, Some("5s"), true)
        );
        assert_eq!(plan("paper-week", None).unwrap().train_days, 7.0);
        assert_eq!(plan("week", None).unwrap().step, None);
        for bad in ["", "x", "0", "-1", "nan", "weeks", "99999", "paper-year"] {
            assert!(plan(bad, None).is_err(), "{bad}");
        }
        assert!(plan("ci", Some(0.0)).is_err());
    }
}
