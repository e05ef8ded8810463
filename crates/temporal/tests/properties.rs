//! Property tests: lossless reconstruction with gaps, spectra against a brute-force DFT,
//! agreement of the regular and irregular models, encoding round trips, hostile bytes.

#![allow(clippy::unwrap_used)]

use froctomap_core::{Occupancy, Timestamp};
use froctomap_temporal::models::{FremenPeriods, FremenRegular, StaticMean};
use froctomap_temporal::*;
use proptest::prelude::*;
use std::f64::consts::TAU;

const SECOND: i64 = 1_000_000_000;

/// A run-structured series of unknown / free / occupied samples, with a periodic tendency so
/// spectra have structure, and random noise so outliers exist.
fn series(max_len: usize) -> impl Strategy<Value = Vec<Option<bool>>> {
    (
        proptest::collection::vec((1usize..12, 0u8..10), 1..80),
        2usize..40,
        any::<u64>(),
    )
        .prop_map(move |(runs, period, seed)| {
            let mut out = Vec::new();
            let mut rng = seed | 1;
            for (len, kind) in runs {
                for _ in 0..len {
                    if out.len() >= max_len {
                        return out;
                    }
                    rng ^= rng << 13;
                    rng ^= rng >> 7;
                    rng ^= rng << 17;
                    let phase = (out.len() % period) * 2 < period;
                    out.push(match kind {
                        0 | 1 => None,
                        2 => Some(false),
                        3 => Some(true),
                        _ => Some(phase ^ (rng % 7 == 0)),
                    });
                }
            }
            out
        })
        .prop_filter("needs an observation", |s| s.iter().any(Option::is_some))
}

fn occupancy(b: bool) -> Occupancy {
    Occupancy::from(b)
}

fn observations(samples: &[Option<bool>]) -> VoxelObservations {
    let mut b = ObservationsBuilder::new();
    for (i, s) in samples.iter().enumerate() {
        b.push(i as u32, s.map(occupancy)).unwrap();
    }
    b.finish()
}

/// Long series with slow rhythms (periods of 100..3000 samples), noise and gaps: the outlier
/// pass skips most samples here, so reconstruction checks that skipping is exact.
fn long_series() -> impl Strategy<Value = Vec<Option<bool>>> {
    (
        2000usize..6000,
        100usize..3000,
        0.2f64..0.8,
        5u64..200,
        any::<u64>(),
    )
        .prop_map(|(n, period, duty, noise, seed)| {
            let mut rng = seed | 1;
            let mut hidden = 0usize;
            (0..n)
                .map(|i| -> Option<bool> {
                    rng ^= rng << 13;
                    rng ^= rng >> 7;
                    rng ^= rng << 17;
                    if hidden > 0 {
                        hidden -= 1;
                        return None;
                    }
                    if rng % 300 == 0 {
                        hidden = (rng >> 20) as usize % 200;
                    }
                    let phase = (i % period) as f64 / period as f64;
                    Some((phase < duty) ^ ((rng >> 32) % noise == 0))
                })
                .collect()
        })
        .prop_filter("needs an observation", |s: &Vec<Option<bool>>| {
            s.iter().any(Option::is_some)
        })
}

/// A regular 1 s axis over the samples; the leading unknown samples become missing snapshots.
fn regular_axis(samples: &[Option<bool>]) -> TimeAxis {
    let missing = samples.iter().take_while(|s| s.is_none()).count() as u32;
    TimeAxis::regular(
        Timestamp(7 * SECOND),
        SECOND,
        samples.len() as u32,
        (0..missing).collect(),
    )
    .unwrap()
}

/// A jittered axis: gaps of 0.5..1.5 s.
fn jittered_axis(len: usize, seed: u64) -> TimeAxis {
    let mut t = 1_700_000_000 * SECOND;
    let mut rng = seed | 1;
    let times = (0..len)
        .map(|_| {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            t += SECOND / 2 + (rng >> 11) as i64 % SECOND;
            Timestamp(t)
        })
        .collect();
    TimeAxis::explicit(times).unwrap()
}

/// Periods suited to short test axes (seconds), for the FreMEn models.
fn test_config(order: Order, mode: OutlierMode) -> ModelConfig {
    order
        .apply(ModelConfig::default())
        .with_outliers(mode)
        .with_option("periods", "3.3,7,11.5,24")
        .with_option("base-period", 60)
        .with_option("harmonics", 12)
}

/// Only the options of `config` that `model` declares.
fn declared(model: &dyn TemporalModel, config: ModelConfig) -> ModelConfig {
    let registry = ModelRegistry::with_default_models();
    let Some(model) = registry.by_id(model.id()) else {
        return config;
    };
    let mut out = ModelConfig::default().with_outliers(config.outliers);
    for (key, value) in config.options.iter() {
        if model.options.iter().any(|o| o.key == key) {
            out = out.with_option(key, value);
        }
    }
    out
}

/// [`test_config`] with only the options `model` declares.
fn config_for(model: &ModelDescriptor, order: Order, mode: OutlierMode) -> ModelConfig {
    let mut config = ModelConfig::default().with_outliers(mode);
    for (key, value) in test_config(order, mode).options.iter() {
        if model.options.iter().any(|o| o.key == key) {
            config = config.with_option(key, value);
        }
    }
    config
}

fn orders() -> impl Strategy<Value = Order> {
    prop_oneof![
        (0u8..5).prop_map(Order::Fixed),
        (0u8..5).prop_map(|max| Order::Auto { max }),
    ]
}

fn check_lossless(
    descriptor: &ModelDescriptor,
    axis: &TimeAxis,
    samples: &[Option<bool>],
    order: Order,
    mode: OutlierMode,
) -> Result<(), TestCaseError> {
    let model = descriptor.create();
    let obs = observations(samples);
    let prepared = match model.prepare(axis, &config_for(descriptor, order, mode)) {
        Err(TemporalError::Unsupported { .. }) => return Ok(()), // e.g. FFT on jittered times
        other => other?,
    };
    let voxel = prepared.fit(&obs)?;
    let description = prepared.describe(voxel.parameters())?;
    prop_assert!(description.periodic.len() <= usize::from(order.max()));
    prop_assert_eq!(description.mean, prepared.mean(voxel.parameters()));
    prop_assert_eq!(
        prepared.parameters_len(voxel.parameters())?,
        voxel.parameters().len()
    );
    let mut bytes = vec![0xEE];
    prepared.encode_voxel(&voxel, &mut bytes);
    bytes.push(0xEE); // trailing bytes belong to the next voxel
    let reader = ModelRegistry::with_default_models().prepare_from_parameters(
        model.id(),
        axis,
        &prepared.encode_parameters(),
    )?;
    let (decoded, used) = reader.decode_voxel(&bytes[1..])?;
    prop_assert_eq!(used, bytes.len() - 2);
    prop_assert_eq!(&decoded, &voxel);
    let wrong = reader.reconstruction_error(&decoded, &obs);
    prop_assert_eq!(Some(wrong), voxel.model_errors());
    for (i, s) in samples.iter().enumerate() {
        let i = i as u32;
        prop_assert_eq!(
            reader.probability_at_sample(decoded.parameters(), i),
            prepared.probability_at_sample(voxel.parameters(), i)
        );
        if let (Some(s), OutlierMode::Lossless) = (s, mode) {
            prop_assert_eq!(
                reader.state_at_sample(&decoded, i),
                occupancy(*s),
                "sample {}",
                i
            );
        }
    }
    if mode == OutlierMode::Lossy {
        prop_assert!(voxel.toggles().is_empty());
    }
    Ok(())
}

fn brute_force(times: &[f64], samples: &[Option<bool>], period: f64) -> (f64, f64) {
    let observed: Vec<(f64, f64)> = times
        .iter()
        .zip(samples)
        .filter_map(|(t, s)| s.map(|s| (*t, if s { 1.0 } else { 0.0 })))
        .collect();
    let n = observed.len() as f64;
    let mean = observed.iter().map(|o| o.1).sum::<f64>() / n;
    let (mut re, mut im) = (0.0, 0.0);
    for (t, s) in observed {
        let angle = TAU * t / period;
        re += (s - mean) * angle.cos();
        im -= (s - mean) * angle.sin();
    }
    (re / n, im / n)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn lossless_reproduces_every_observed_sample(
        samples in series(400),
        order in orders(),
        lossy in any::<bool>(),
        seed in any::<u64>(),
    ) {
        let mode = if lossy { OutlierMode::Lossy } else { OutlierMode::Lossless };
        let regular = regular_axis(&samples);
        let jittered = jittered_axis(samples.len(), seed);
        // Every registered model, on every axis it supports.
        for model in ModelRegistry::with_default_models().iter() {
            check_lossless(model, &regular, &samples, order, mode)?;
            check_lossless(model, &jittered, &samples, order, mode)?;
        }
    }

    #[test]
    fn lossless_on_long_slow_series(samples in long_series(), auto in any::<bool>(), seed in any::<u64>()) {
        let order = if auto { Order::Auto { max: 4 } } else { Order::Fixed(3) };
        let n = samples.len() as f64;
        let regular = regular_axis(&samples);
        let jittered = jittered_axis(samples.len(), seed);
        for (model, axis) in [(&FremenRegular as &dyn TemporalModel, &regular), (&FremenPeriods, &regular), (&FremenPeriods, &jittered)] {
            let obs = observations(&samples);
            let config = order.apply(ModelConfig::default()).with_option("base-period", n / 2.0);
            let prepared = model.prepare(axis, &declared(model, config))?;
            let voxel = prepared.fit(&obs)?;
            // Errors counted with skipping equal a sample-by-sample count.
            prop_assert_eq!(Some(prepared.reconstruction_error(&voxel, &obs)), voxel.model_errors());
            for (i, s) in obs.iter() {
                prop_assert_eq!(prepared.state_at_sample(&voxel, i), s);
            }
        }
    }

    #[test]
    fn regular_spectrum_equals_brute_force_dft(samples in series(300)) {
        let axis = regular_axis(&samples);
        let obs = observations(&samples);
        let model = FremenRegular.prepare_regular(&axis, &ModelConfig::default())?;
        let spectrum = model.spectrum(&obs)?;
        let n = samples.len();
        prop_assert_eq!(spectrum.len(), n / 2 + 1);
        let times: Vec<f64> = (0..n).map(|i| i as f64).collect();
        for line in &spectrum {
            let k = line.frequency as f64;
            let (re, im) = if k == 0.0 { (0.0, 0.0) } else { brute_force(&times, &samples, n as f64 / k) };
            prop_assert!((line.re - re).abs() < 1e-9 && (line.im - im).abs() < 1e-9,
                "bin {}: fft ({}, {}) vs dft ({}, {})", k, line.re, line.im, re, im);
        }
    }

    #[test]
    fn periods_spectrum_equals_brute_force_dft(samples in series(300), seed in any::<u64>()) {
        let axis = jittered_axis(samples.len(), seed);
        let obs = observations(&samples);
        let model = FremenPeriods.prepare_periods(&axis, &test_config(Order::Fixed(3), OutlierMode::Lossless))?;
        let times: Vec<f64> = (0..samples.len() as u32).map(|i| axis.seconds_since_start(i).unwrap()).collect();
        for line in model.spectrum(&obs)? {
            let (re, im) = brute_force(&times, &samples, line.period_seconds);
            prop_assert!((line.re - re).abs() < 1e-9 && (line.im - im).abs() < 1e-9);
        }
    }

    /// On a regular axis, FreMEn-periods at the DFT bin periods is FreMEn-regular.
    #[test]
    fn regular_and_periods_models_agree(samples in series(301), order in 1u8..5) {
        let mut samples = samples;
        if samples.len() % 2 == 0 {
            samples.pop(); // odd length: no Nyquist bin, whose amplitude convention differs
        }
        prop_assume!(samples.len() >= 5);
        // Observe both ends so both models see the whole span.
        let last = samples.len() - 1;
        samples[0] = Some(samples[0].unwrap_or(false));
        samples[last] = Some(samples[last].unwrap_or(true));
        let n = samples.len();
        let step = 2.5;
        let axis = TimeAxis::regular(Timestamp(0), (step * 1e9) as i64, n as u32, vec![])?;
        let obs = observations(&samples);
        let config = ModelConfig::default().with_option("order", order).with_option("min-cycles", 1);
        let regular = FremenRegular.prepare_regular(&axis, &config)?;
        let bin_periods: Vec<String> = (1..=n / 2).map(|k| (n as f64 * step / k as f64).to_string()).collect();
        let config = config.with_option("harmonics", 0).with_option("periods", bin_periods.join(","));
        let periods = FremenPeriods.prepare_periods(&axis, &config)?;
        // Bin 1's period is the n samples' coverage (n·step): one cycle, both keep it.
        prop_assert_eq!(periods.periods().len(), n / 2);

        let reg = regular.spectrum(&obs)?;
        for line in periods.spectrum(&obs)? {
            let k = (n as f64 * step / line.period_seconds).round() as usize;
            prop_assert!((reg[k].re - line.re).abs() < 1e-9 && (reg[k].im - line.im).abs() < 1e-9);
        }

        // Same components unless the ranking has near-ties.
        let mut mags: Vec<f64> = reg.iter().skip(1).map(|l| l.magnitude()).collect();
        mags.sort_by(|a, b| b.total_cmp(a));
        let separated = mags.windows(2).take(usize::from(order)).all(|w| w[0] - w[1] > 1e-6);
        prop_assume!(separated);
        let fr = regular.fit(&obs)?;
        let fp = periods.fit(&obs)?;
        let order_of = |v: &FittedVoxel| SpectralParameters::decode(v.parameters()).map(|p| p.components.len());
        prop_assert_eq!(order_of(&fr)?, order_of(&fp)?);
        for t in (0..3 * n).map(|i| i as f64 * step * 0.7) {
            let (a, b) = (regular.probability(fr.parameters(), t), periods.probability(fp.parameters(), t));
            prop_assert!((a - b).abs() < 1e-3, "t {}: {} vs {}", t, a, b);
        }
    }

    /// `Auto` with the smallest-file criterion gives the smallest lossless encoding among
    /// the fixed orders.
    #[test]
    fn auto_smallest_file_is_smallest(samples in series(300), max in 0u8..5) {
        let axis = regular_axis(&samples);
        let obs = observations(&samples);
        for model in [&FremenRegular as &dyn TemporalModel, &FremenPeriods] {
            let size = |order| -> Result<usize, TemporalError> {
                let config = test_config(order, OutlierMode::Lossless).with_option("criterion", "size");
                let p = model.prepare(&axis, &declared(model, config))?;
                let mut out = Vec::new();
                p.encode_voxel(&p.fit(&obs)?, &mut out);
                Ok(out.len())
            };
            let auto = size(Order::Auto { max })?;
            let best = (0..=max).map(|m| size(Order::Fixed(m))).collect::<Result<Vec<_>, _>>()?;
            prop_assert_eq!(Some(&auto), best.iter().min());
        }
    }

    /// With the default prediction criterion, a lossless voxel keeps exactly the model a
    /// lossy file would keep (plus its outliers), so lossless files predict as well.
    #[test]
    fn auto_prediction_keeps_the_lossy_model_in_lossless_files(samples in series(300), max in 1u8..5) {
        let axis = regular_axis(&samples);
        let obs = observations(&samples);
        for model in [&FremenRegular as &dyn TemporalModel, &FremenPeriods] {
            let fit = |mode| -> Result<FittedVoxel, TemporalError> {
                let p = model.prepare(&axis, &declared(model, test_config(Order::Auto { max }, mode)))?;
                p.fit(&obs)
            };
            let (lossless, lossy) = (fit(OutlierMode::Lossless)?, fit(OutlierMode::Lossy)?);
            prop_assert_eq!(lossless.parameters(), lossy.parameters());
        }
    }

    /// Arbitrary bytes never panic a decoder, and what decodes re-encodes to the same bytes.
    #[test]
    fn hostile_bytes_are_rejected_cleanly(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
        let axis = TimeAxis::regular(Timestamp(0), SECOND, 100, vec![])?;
        for d in ModelRegistry::with_default_models().iter() {
            let model = d.create();
            let _ = model.prepare_from_parameters(&axis, &bytes);
            for mode in [OutlierMode::Lossless, OutlierMode::Lossy] {
                let prepared = model.prepare(&axis, &config_for(d, Order::Fixed(2), mode))?;
                if let Ok(len) = prepared.parameters_len(&bytes) {
                    prop_assert!(prepared.describe(&bytes[..len]).is_ok());
                    for t in [-1.0, 0.0, 50.5, 1e6, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                        let p = prepared.probability(&bytes[..len], t);
                        prop_assert!((0.0..=1.0).contains(&p));
                    }
                }
                if let Ok((voxel, used)) = prepared.decode_voxel(&bytes) {
                    let mut again = Vec::new();
                    prepared.encode_voxel(&voxel, &mut again);
                    prop_assert_eq!(&again[..], &bytes[..used]);
                    for i in 0..100 {
                        let p = prepared.probability_at_sample(voxel.parameters(), i);
                        prop_assert!((0.0..=1.0).contains(&p));
                    }
                }
            }
        }
    }
}

#[test]
fn truncated_voxels_and_parameters_fail_cleanly() {
    let samples: Vec<Option<bool>> = (0..500)
        .map(|i| (i % 50 != 7).then_some((i % 24 < 9) ^ (i % 31 == 0)))
        .collect();
    let axis = regular_axis(&samples);
    let obs = observations(&samples);
    for d in ModelRegistry::with_default_models().iter() {
        let prepared = d
            .create()
            .prepare(
                &axis,
                &config_for(d, Order::Fixed(4), OutlierMode::Lossless),
            )
            .unwrap();
        let voxel = prepared.fit(&obs).unwrap();
        assert!(!voxel.toggles().is_empty());
        let mut bytes = Vec::new();
        prepared.encode_voxel(&voxel, &mut bytes);
        for cut in 0..bytes.len() {
            assert!(
                prepared.decode_voxel(&bytes[..cut]).is_err(),
                "{} cut {cut}",
                d.name
            );
        }
        let params = prepared.encode_parameters();
        for cut in 0..params.len() {
            assert!(
                d.create()
                    .prepare_from_parameters(&axis, &params[..cut])
                    .is_err(),
                "{} parameters cut {cut}",
                d.name
            );
        }
    }
}

#[test]
fn regular_model_rejects_explicit_axes_and_bad_observations() {
    let explicit = jittered_axis(10, 3);
    assert!(matches!(
        FremenRegular.prepare(&explicit, &ModelConfig::default()),
        Err(TemporalError::Unsupported { .. })
    ));
    let axis = TimeAxis::regular(Timestamp(0), SECOND, 10, vec![4]).unwrap();
    let model = FremenRegular
        .prepare(&axis, &ModelConfig::default())
        .unwrap();
    let beyond = VoxelObservations::from_runs([(8, 3, Occupancy::Free)]).unwrap();
    assert!(model.fit(&beyond).is_err());
    let at_missing = VoxelObservations::from_runs([(3, 2, Occupancy::Free)]).unwrap();
    assert!(model.fit(&at_missing).is_err());
    let bad = ModelConfig::default().with_option("min-cycles", f64::NAN);
    assert!(matches!(
        FremenPeriods.prepare(&axis, &bad),
        Err(TemporalError::InvalidOption {
            key: "min-cycles",
            ..
        })
    ));
    let unknown = ModelConfig::default().with_option("order", 2);
    assert!(matches!(
        StaticMean.prepare(&axis, &unknown),
        Err(TemporalError::UnknownOption { .. })
    ));
}

/// The held-out order choice finds a clean daily rhythm and keeps noise at low order.
#[test]
fn auto_lossy_uses_held_out_error() {
    let day = 96; // 15-minute samples
    let n = 28 * day;
    let axis = TimeAxis::regular(Timestamp(0), 900 * SECOND, n as u32, vec![]).unwrap();
    let rhythm: Vec<Option<bool>> = (0..n)
        .map(|i| Some((36..68).contains(&(i % day))))
        .collect();
    let config = ModelConfig::default()
        .with_option("harmonics", 28)
        .with_outliers(OutlierMode::Lossy);
    for model in [&FremenRegular as &dyn TemporalModel, &FremenPeriods] {
        let prepared = model
            .prepare(&axis, &declared(model, config.clone()))
            .unwrap();
        let voxel = prepared.fit(&observations(&rhythm)).unwrap();
        let order = prepared
            .describe(voxel.parameters())
            .unwrap()
            .periodic
            .len();
        assert!(order >= 1, "{}", model.name());
        assert!(voxel.model_errors().unwrap() < n as u64 / 20);
        assert!(voxel.toggles().is_empty());
    }
}
