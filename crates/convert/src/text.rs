//! Number forms for human-readable output, shared by the CLI and the benchmark report.

/// A count with its thousands grouped by commas.
///
/// ```
/// assert_eq!(froctomap_convert::group_thousands(1_136_432), "1,136,432");
/// assert_eq!(froctomap_convert::group_thousands(999), "999");
/// ```
pub fn group_thousands(value: u64) -> String {
    let digits = value.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// `value` without the noise of binary arithmetic in its last digits (`-94 × 0.08` is
/// `-7.5200000000000005`; this gives `-7.52`): rounded to 15 significant digits, but never
/// to fewer than 9 decimals, so that Unix seconds keep their nanoseconds. For reports read
/// by people and scripts (`--json`), never for values read back as data.
///
/// ```
/// use froctomap_convert::tidy_float;
/// assert_eq!(tidy_float(-94.0 * 0.08), -7.52);
/// assert_eq!(tidy_float(0.1 + 0.2), 0.3);
/// assert_eq!(tidy_float(1e-15), 1e-15);
/// assert_eq!(tidy_float(1451865600.123456789), 1451865600.123456789);
/// ```
pub fn tidy_float(value: f64) -> f64 {
    if !value.is_finite() || value == 0.0 {
        return value;
    }
    let decimals = (14 - value.abs().log10().floor() as i32).max(9);
    if decimals > 300 {
        return value;
    }
    format!("{value:.*}", decimals as usize)
        .parse()
        .unwrap_or(value)
}

/// [`tidy_float`] applied to every number of a JSON value that is not an integer.
pub fn tidy_floats(value: &mut serde_json::Value) {
    use serde_json::Value;
    match value {
        Value::Number(number) if !(number.is_i64() || number.is_u64()) => {
            if let Some(tidy) = number
                .as_f64()
                .map(tidy_float)
                .and_then(serde_json::Number::from_f64)
            {
                *number = tidy;
            }
        }
        Value::Array(items) => items.iter_mut().for_each(tidy_floats),
        Value::Object(fields) => fields.values_mut().for_each(tidy_floats),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn thousands_are_grouped() {
        assert_eq!(super::group_thousands(0), "0");
        assert_eq!(super::group_thousands(999), "999");
        assert_eq!(super::group_thousands(1000), "1,000");
        assert_eq!(super::group_thousands(845_123_456), "845,123,456");
    }
}
