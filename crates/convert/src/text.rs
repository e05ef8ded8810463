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
