//! Lossless files depend on the decoder thresholding `p` exactly as the encoder did, so the
//! evaluation of `p` at samples is part of the format: these pins fail if the deterministic
//! trigonometry or the summation order ever changes (which would need a new model id or
//! parameter version, never a silent change). The values are identical in debug and release
//! builds, which also shows that no fused multiply-add crept in.

#![allow(clippy::unwrap_used)]

use froctomap_core::Timestamp;
use froctomap_temporal::models::{FremenPeriods, FremenRegular};
use froctomap_temporal::*;

#[test]
fn deterministic_trig_bits() {
    let pins: [(f64, u64, u64); 6] = [
        (0.1, 0x3fe9e3779b97f4a8, 0x3fe2cf2304755a5e),
        (0.3, 0xbfd3c6ef372fe94e, 0x3fee6f0e13445500),
        (0.7, 0xbfd3c6ef372fe954, 0xbfee6f0e134454ff),
        (0.123456789, 0x3fe6d8832e5981ec, 0x3fe6682e33636dbf),
        (12345.678, 0xbfdbf9b468956943, 0xbfecc7ed85aa7580),
        (-0.4, 0xbfe9e3779b97f4a8, 0xbfe2cf2304755a5d),
    ];
    for (x, c, s) in pins {
        let (cos, sin) = trig::cos_sin_turns(x);
        assert_eq!((cos.to_bits(), sin.to_bits()), (c, s), "turns {x}");
    }
}

#[test]
fn probability_at_samples_bits() {
    let parameters = SpectralParameters {
        mean_q: 12345,
        components: vec![
            Component {
                frequency: 3,
                amplitude_q: 30000,
                phase_q: 1234,
            },
            Component {
                frequency: 1,
                amplitude_q: 9000,
                phase_q: 60000,
            },
        ],
    }
    .encode();
    // One week of minutes.
    let axis = TimeAxis::regular(Timestamp(0), 60_000_000_000, 10_080, vec![]).unwrap();
    let pins = [
        (
            FremenRegular
                .prepare(&axis, &ModelConfig::default())
                .unwrap(),
            0xfef19d2f8d4e9636u64,
        ),
        (
            FremenPeriods
                .prepare(&axis, &ModelConfig::default())
                .unwrap(),
            0xe5672e1c6016f769,
        ),
    ];
    for (model, pin) in pins {
        // FNV-1a over the bit patterns of p at every sample.
        let mut hash = 0xcbf29ce484222325u64;
        for i in 0..axis.len() {
            hash ^= model.probability_at_sample(&parameters, i).to_bits();
            hash = hash.wrapping_mul(0x100000001b3);
        }
        assert_eq!(hash, pin, "model {}", model.id());
    }
}
