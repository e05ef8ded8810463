//! Deterministic cosine and sine of angles given in turns.
//!
//! Lossless outlier sets are computed by thresholding `p(t)` at 0.5 at every observed sample,
//! and the decoder must get the *same* bit for every sample, on any machine. `f64::cos` is not
//! guaranteed to round identically across platforms and libm versions, so the models evaluate
//! `p` only through [`cos_sin_turns`], which uses IEEE-754 basic operations (`+ - * floor`)
//! in a fixed order: exact reduction to a quarter turn (multiplying by 4 and subtracting an
//! integer are exact), then Taylor polynomials on `[0, π/4]` in Horner form. Rust never fuses
//! a multiply and an add into an FMA unless asked (`mul_add`), so the result is bit-identical
//! on every target with IEEE binary64 arithmetic (all 64-bit tier-1 targets; not x87).
//!
//! Accuracy (not needed for determinism, but nice): absolute error below 1e-15, and the
//! results never exceed 1 in magnitude.
//!
//! ```
//! use froctomap_temporal::trig::cos_sin_turns;
//! let (c, s) = cos_sin_turns(0.125); // 45 degrees
//! assert!((c - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-15);
//! assert!((s - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-15);
//! assert_eq!(cos_sin_turns(3.0), (1.0, 0.0));
//! ```

use std::f64::consts::FRAC_PI_2;

// Taylor coefficients 1/k!; each a correctly rounded constant division.
const C2: f64 = 1.0 / 2.0;
const C4: f64 = 1.0 / 24.0;
const C6: f64 = 1.0 / 720.0;
const C8: f64 = 1.0 / 40_320.0;
const C10: f64 = 1.0 / 3_628_800.0;
const C12: f64 = 1.0 / 479_001_600.0;
const C14: f64 = 1.0 / 87_178_291_200.0;
const C16: f64 = 1.0 / 20_922_789_888_000.0;
const S3: f64 = 1.0 / 6.0;
const S5: f64 = 1.0 / 120.0;
const S7: f64 = 1.0 / 5_040.0;
const S9: f64 = 1.0 / 362_880.0;
const S11: f64 = 1.0 / 39_916_800.0;
const S13: f64 = 1.0 / 6_227_020_800.0;
const S15: f64 = 1.0 / 1_307_674_368_000.0;
const S17: f64 = 1.0 / 355_687_428_096_000.0;

/// cos θ for θ in [0, π/4]; truncation error < (π/4)^18/18! ≈ 2e-17.
#[inline]
fn cos_poly(theta: f64) -> f64 {
    let z = theta * theta;
    1.0 - z * (C2 - z * (C4 - z * (C6 - z * (C8 - z * (C10 - z * (C12 - z * (C14 - z * C16)))))))
}

/// sin θ for θ in [0, π/4]; truncation error < (π/4)^19/19! ≈ 1e-18.
#[inline]
fn sin_poly(theta: f64) -> f64 {
    let z = theta * theta;
    theta
        * (1.0
            - z * (S3
                - z * (S5 - z * (S7 - z * (S9 - z * (S11 - z * (S13 - z * (S15 - z * S17))))))))
}

/// `floor` without a libm call: exact, since truncating a float below 2^52 in magnitude to an
/// integer is exact and larger floats are integers already.
#[inline]
fn floor(x: f64) -> f64 {
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = (x as i64) as f64;
        if t > x {
            t - 1.0
        } else {
            t
        }
    } else {
        x
    }
}

/// `(cos 2πx, sin 2πx)` for `x` in turns, computed deterministically (see the module docs).
///
/// Any finite `x` is accepted; arguments beyond 2^52 in magnitude are whole turns. A
/// non-finite `x` gives `(NaN, NaN)`.
#[inline]
pub fn cos_sin_turns(x: f64) -> (f64, f64) {
    if !x.is_finite() {
        return (f64::NAN, f64::NAN);
    }
    let mut r = x - floor(x); // in [0, 1]; 1 only through rounding of tiny negative x
    if r >= 1.0 {
        r = 0.0;
    }
    let q4 = r * 4.0; // exact
    let q = floor(q4);
    let f = q4 - q; // exact, in [0, 1): position inside the quarter turn
    let (c, s) = if f <= 0.5 {
        let theta = f * FRAC_PI_2;
        (cos_poly(theta), sin_poly(theta))
    } else {
        // cos(θ) = sin(π/2 − θ); 1 − f is exact for f in [0.5, 1].
        let theta = (1.0 - f) * FRAC_PI_2;
        (sin_poly(theta), cos_poly(theta))
    };
    // Rotate by q quarter turns.
    if q < 1.0 {
        (c, s)
    } else if q < 2.0 {
        (-s, c)
    } else if q < 3.0 {
        (-c, -s)
    } else {
        (s, -c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn matches_std_and_is_bounded(x in -1.0e6f64..1.0e6) {
            let (c, s) = cos_sin_turns(x);
            let angle = std::f64::consts::TAU * (x - x.floor());
            prop_assert!((c - angle.cos()).abs() < 1e-14, "cos {x}");
            prop_assert!((s - angle.sin()).abs() < 1e-14, "sin {x}");
            prop_assert!(c.abs() <= 1.0 && s.abs() <= 1.0);
        }
    }

    #[test]
    fn floor_matches_std() {
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            1e15 + 0.5,
            -1e15 - 0.5,
            2f64.powi(53),
            -7.25,
            3.999_999_999_999_999_6,
        ] {
            assert_eq!(floor(x), x.floor(), "{x}");
        }
    }

    #[test]
    fn exact_at_quarter_turns_and_symmetric() {
        assert_eq!(cos_sin_turns(0.0), (1.0, 0.0));
        assert_eq!(cos_sin_turns(0.25), (0.0, 1.0));
        assert_eq!(cos_sin_turns(0.75), (0.0, -1.0));
        assert_eq!(cos_sin_turns(0.5), (-1.0, -0.0));
        assert_eq!(cos_sin_turns(-1e-300).0, 1.0);
        let (c1, s1) = cos_sin_turns(0.1);
        let (c2, s2) = cos_sin_turns(-0.1);
        assert!((c1 - c2).abs() < 1e-15 && (s1 + s2).abs() < 1e-15);
        assert!(cos_sin_turns(f64::NAN).0.is_nan());
    }
}
