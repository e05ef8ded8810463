//! Options of the FreMEn-family models: order, its choice, and the candidate periods.

use crate::options::{invalid, ModelOptions, OptionDescriptor};
use crate::TemporalError;

/// How many spectral components a voxel keeps (options `order`, `max-order`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Order {
    /// At most this many (fewer when fewer usable frequencies exist or amplitudes quantise
    /// to zero). `Fixed(0)` is the mean alone.
    Fixed(u8),
    /// Chosen per voxel among `0..=max` by the `criterion` option:
    /// - [`OrderCriterion::Prediction`] (default): the order with the smallest held-out
    ///   squared error of `p(t)`: the model is fitted on the first `1 − holdout-fraction` of
    ///   the voxel's observed samples and scored (Brier score) on the rest (at most 512
    ///   evenly spaced held-out samples); the lowest order within 1 % of the best score wins
    ///   (a component must earn its place: noise-like voxels keep the mean alone); the
    ///   chosen order is then refitted on all samples. This targets prediction;
    ///   in lossless mode the outliers still make the states exact. The held-out part is
    ///   half the samples when a validation fit on the first half may still use the
    ///   voxel's longest eligible period (else `holdout-fraction`); the validation fit
    ///   uses only periods eligible for the voxel (`min-cycles`) of which its samples span
    ///   1.5 cycles, first to last. Where the held-out part spans a whole cycle of every period of
    ///   an order, that order may also be shrunk (`shrink`) and may exceed 5, but its
    ///   decisions (p > 0.5) that differ from the mean's must be right on the held-out part
    ///   significantly more often than wrong (net gain ≥ 2·√changes); where it does not,
    ///   only unshrunk orders up to 5 compete. No two chosen periods alias each other: a
    ///   candidate closer than `1/span` in frequency to a stronger chosen one, directly or
    ///   through the sampling grid, is skipped.
    /// - [`OrderCriterion::SmallestFile`] (lossless only; lossy falls back to prediction):
    ///   the order with the smallest encoded voxel (parameters + toggles), ties to the lower
    ///   order; the most compact exact representation. Block-like series (long runs) often
    ///   come out at order 0 or 1: toggles at the run edges are cheaper than sinusoids
    ///   whose threshold crossings miss the edges, so such files predict no better than the
    ///   mean.
    Auto {
        /// Highest order tried.
        max: u8,
    },
}

impl Order {
    /// `config` with the options (`order`, and `max-order` for `Auto`) that select this
    /// order.
    ///
    /// ```
    /// use froctomap_temporal::{ModelConfig, Order};
    /// let config = Order::Auto { max: 3 }.apply(ModelConfig::default());
    /// assert_eq!(config.options.get("order"), Some("auto"));
    /// assert_eq!(config.options.get("max-order"), Some("3"));
    /// ```
    pub fn apply(self, config: crate::ModelConfig) -> crate::ModelConfig {
        match self {
            Order::Fixed(n) => config.with_option(ORDER.key, n),
            Order::Auto { max } => config
                .with_option(ORDER.key, "auto")
                .with_option(MAX_ORDER.key, max),
        }
    }

    /// The highest number of components this order can give.
    pub fn max(self) -> u8 {
        match self {
            Order::Fixed(n) | Order::Auto { max: n } => n,
        }
    }
}

/// How [`Order::Auto`] chooses a voxel's order (option `criterion`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum OrderCriterion {
    /// Best held-out prediction (default, `prediction`): the file predicts as well as it can.
    #[default]
    Prediction,
    /// Smallest encoded voxel (lossless mode, `size`): the file is as small as it can be.
    SmallestFile,
}

pub(crate) const ORDER: OptionDescriptor = OptionDescriptor {
    key: "order",
    help: "spectral components per voxel: a number 0-255, or `auto` to choose per voxel up to max-order",
    default: "auto",
};
pub(crate) const MAX_ORDER: OptionDescriptor = OptionDescriptor {
    key: "max-order",
    help: "highest order `order=auto` tries (orders above 5 only where a held-out part spanning whole cycles of their periods validates them)",
    default: "8",
};
pub(crate) const CRITERION: OptionDescriptor = OptionDescriptor {
    key: "criterion",
    help: "how `order=auto` chooses: `prediction` (best held-out prediction) or `size` (smallest lossless encoding)",
    default: "prediction",
};
pub(crate) const PERIODS: OptionDescriptor = OptionDescriptor {
    key: "periods",
    help: "extra candidate periods in seconds, comma-separated",
    default: "",
};
pub(crate) const BASE_PERIOD: OptionDescriptor = OptionDescriptor {
    key: "base-period",
    help: "base period of the default period set, in seconds",
    default: "604800",
};
pub(crate) const HARMONICS: OptionDescriptor = OptionDescriptor {
    key: "harmonics",
    help: "candidate periods base-period / k for k = 1..=harmonics (0 = none)",
    default: "48",
};
pub(crate) const MIN_CYCLES: OptionDescriptor = OptionDescriptor {
    key: "min-cycles",
    help: "a period is used for a voxel only when its observed samples cover that many cycles of it, counted from the first sample to the last plus one step (n samples s apart cover n·s)",
    default: "2",
};
pub(crate) const HOLDOUT_FRACTION: OptionDescriptor = OptionDescriptor {
    key: "holdout-fraction",
    help: "least fraction of each voxel's latest observed samples held out to choose the order, in (0, 1); half when a fit on the first half still keeps the longest eligible period",
    default: "0.25",
};

pub(crate) const SHRINK: OptionDescriptor = OptionDescriptor {
    key: "shrink",
    help: "`auto`: with order=auto, a held-out part spanning whole cycles of the order's periods may also shrink the amplitudes (by 0.8, 0.6, 0.4 or 0.2); `off`: amplitudes as estimated",
    default: "auto",
};

/// The FreMEn-family settings, parsed from [`ModelOptions`]; options a model does not
/// declare keep their defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectralOptions {
    /// Number of spectral components per voxel. Default `Auto { max: 8 }` (orders above
    /// 5 only where validated on a held-out part spanning whole cycles of their periods).
    pub order: Order,
    /// How `Order::Auto` picks each voxel's order. Default [`OrderCriterion::Prediction`].
    pub criterion: OrderCriterion,
    /// Extra candidate periods in seconds (`fremen-periods`). Default none.
    pub periods: Vec<f64>,
    /// Base period in seconds of the default period set. Default one week (604 800 s).
    pub base_period: f64,
    /// Harmonics of `base_period` in the default period set. Default 48 (one week down to
    /// 3.5 hours, including 1 day, 12 h, 8 h, 6 h and 4 h).
    pub harmonics: u32,
    /// A period is *eligible* for a voxel only when the time its observed samples cover is
    /// at least `min_cycles` periods long, counted from the first sample to the last plus
    /// one step (each sample stands for its step: `n` samples `s` apart cover `n·s`, so 2
    /// days of half-hourly samples hold exactly 2 days). Default 2 (issue 28: two whole
    /// cycles). Applies to DFT bins too. The validation fit of [`Order::Auto`] (on the
    /// earlier samples) uses only eligible periods, of which it must span 1.5 cycles (or
    /// `min_cycles`, when less), first sample to last.
    pub min_cycles: f64,
    /// Least fraction of each voxel's observed samples (the latest ones) held out to choose
    /// the order: half of them when a validation fit on the first half may still use the
    /// longest period eligible for the voxel, so that the held-out part holds as many whole cycles as
    /// the fit can spare. Default 0.25.
    pub holdout_fraction: f64,
    /// With [`Order::Auto`] and the prediction criterion, let the held-out samples also
    /// choose a factor (1, 0.8, 0.6, 0.4 or 0.2) the amplitudes are shrunk by, where the held-out
    /// part spans a whole cycle of every period of the order (see [`Order::Auto`]). Default
    /// on (`shrink=auto`); `shrink=off` keeps the amplitudes as estimated.
    pub shrink: bool,
}

impl Default for SpectralOptions {
    fn default() -> Self {
        Self {
            order: Order::Auto { max: 8 },
            criterion: OrderCriterion::Prediction,
            periods: Vec::new(),
            base_period: 604_800.0,
            harmonics: 48,
            min_cycles: 2.0,
            holdout_fraction: 0.25,
            shrink: true,
        }
    }
}

impl SpectralOptions {
    /// Most candidate periods accepted (harmonics plus extra periods).
    pub const MAX_PERIODS: usize = 4096;

    /// Parses and validates the options `declared` by `model` (others are rejected).
    pub fn parse(
        model: &'static str,
        declared: &[OptionDescriptor],
        options: &ModelOptions,
    ) -> Result<Self, TemporalError> {
        options.check_keys(model, declared)?;
        let mut parsed = Self::default();
        let positive = |x: f64| x.is_finite() && x > 0.0;
        for option in declared {
            let value = options.value_of(option);
            let bad = |expected| invalid(model, option, value, expected);
            match option.key {
                "order" | "max-order" => {} // read together below
                "criterion" => {
                    parsed.criterion = match value {
                        "prediction" => OrderCriterion::Prediction,
                        "size" => OrderCriterion::SmallestFile,
                        _ => return Err(bad("`prediction` or `size`")),
                    }
                }
                "periods" => {
                    parsed.periods = value
                        .split(',')
                        .map(str::trim)
                        .filter(|p| !p.is_empty())
                        .map(|p| p.parse().ok().filter(|&p| positive(p)))
                        .collect::<Option<Vec<f64>>>()
                        .ok_or_else(|| bad("positive numbers of seconds, comma-separated"))?;
                }
                "base-period" => {
                    parsed.base_period =
                        options.parse(model, option, "a positive number of seconds")?;
                    if !positive(parsed.base_period) {
                        return Err(bad("a positive number of seconds"));
                    }
                }
                "shrink" => {
                    parsed.shrink = match value {
                        "auto" => true,
                        "off" => false,
                        _ => return Err(bad("`auto` or `off`")),
                    }
                }
                "harmonics" => parsed.harmonics = options.parse(model, option, "a whole number")?,
                "min-cycles" => {
                    parsed.min_cycles = options.parse(model, option, "a positive number")?;
                    if !positive(parsed.min_cycles) {
                        return Err(bad("a positive number"));
                    }
                }
                "holdout-fraction" => {
                    parsed.holdout_fraction = options.parse(model, option, "a number in (0, 1)")?;
                    if !(parsed.holdout_fraction > 0.0 && parsed.holdout_fraction < 1.0) {
                        return Err(bad("a number in (0, 1)"));
                    }
                }
                _ => {}
            }
        }
        if declared.contains(&ORDER) {
            let max: u8 = options.parse(model, &MAX_ORDER, "a number 0-255")?;
            parsed.order = match options.value_of(&ORDER) {
                "auto" => Order::Auto { max },
                _ => Order::Fixed(options.parse(model, &ORDER, "a number 0-255 or `auto`")?),
            };
        }
        if parsed.harmonics as usize + parsed.periods.len() > Self::MAX_PERIODS {
            return Err(TemporalError::InvalidConfig("too many candidate periods"));
        }
        Ok(parsed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Every spectral option: the ones `fremen-periods` declares.
    const ALL: &[OptionDescriptor] = crate::models::fremen_periods::DESCRIPTOR.options;

    fn parse(pairs: &[(&str, &str)]) -> Result<SpectralOptions, TemporalError> {
        let mut options = ModelOptions::new();
        for (k, v) in pairs {
            options.set(k, v);
        }
        SpectralOptions::parse("test", ALL, &options)
    }

    #[test]
    fn defaults_are_the_declared_defaults() {
        assert_eq!(parse(&[]), Ok(SpectralOptions::default()));
    }

    #[test]
    fn values_parse_and_bad_ones_are_named() {
        let o = parse(&[
            ("order", "3"),
            ("criterion", "size"),
            ("periods", "3600, 5e3"),
        ])
        .unwrap();
        assert_eq!(o.order, Order::Fixed(3));
        assert_eq!(o.criterion, OrderCriterion::SmallestFile);
        assert_eq!(o.periods, [3600.0, 5000.0]);
        assert_eq!(
            parse(&[("max-order", "2")]).unwrap().order,
            Order::Auto { max: 2 }
        );
        for (key, value) in [
            ("order", "many"),
            ("order", "256"),
            ("max-order", "-1"),
            ("criterion", "best"),
            ("periods", "1h"),
            ("periods", "0"),
            ("base-period", "NaN"),
            ("min-cycles", "0"),
            ("holdout-fraction", "1"),
            ("harmonics", "1.5"),
            ("shrink", "yes"),
        ] {
            match parse(&[(key, value)]) {
                Err(TemporalError::InvalidOption { key: k, .. }) => assert_eq!(k, key),
                other => panic!("{key}={value}: {other:?}"),
            }
        }
        assert!(matches!(
            parse(&[("colour", "red")]),
            Err(TemporalError::UnknownOption { .. })
        ));
        assert!(matches!(
            parse(&[("harmonics", "5000")]),
            Err(TemporalError::InvalidConfig(_))
        ));
    }
}
