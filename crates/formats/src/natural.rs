//! The order in which listed files (a directory of maps, a glob's matches, a ROS 2 bag's
//! splits) are taken.

use std::cmp::Ordering;
use std::path::Path;

/// Orders names as people number them: runs of digits compare by value (`map_2` before
/// `map_10`), everything else by character; equal values with different zero padding, and
/// then the plain text, break ties so the order is total.
pub fn natural_cmp(a: &Path, b: &Path) -> Ordering {
    let (a, b) = (a.to_string_lossy(), b.to_string_lossy());
    let (mut x, mut y) = (a.as_bytes(), b.as_bytes());
    while let (Some(&p), Some(&q)) = (x.first(), y.first()) {
        if p.is_ascii_digit() && q.is_ascii_digit() {
            let run = |s: &[u8]| s.iter().take_while(|c| c.is_ascii_digit()).count();
            let (m, n) = (run(x), run(y));
            let strip = |s: &[u8]| {
                let zeros = s.iter().take_while(|&&c| c == b'0').count();
                s[zeros..].to_vec()
            };
            let (u, v) = (strip(&x[..m]), strip(&y[..n]));
            let by_value = u.len().cmp(&v.len()).then_with(|| u.cmp(&v));
            if by_value != Ordering::Equal {
                return by_value;
            }
            x = &x[m..];
            y = &y[n..];
        } else if p != q {
            return p.cmp(&q);
        } else {
            x = &x[1..];
            y = &y[1..];
        }
    }
    x.len().cmp(&y.len()).then_with(|| a.cmp(&b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn numbered_names_sort_naturally() {
        let mut names: Vec<PathBuf> = ["map_10.bt", "map_2.bt", "map_1.bt", "map_02.bt", "a.bt"]
            .iter()
            .map(PathBuf::from)
            .collect();
        names.sort_by(|a, b| natural_cmp(a, b));
        let names: Vec<_> = names.iter().map(|p| p.to_str().unwrap()).collect();
        assert_eq!(
            names,
            ["a.bt", "map_1.bt", "map_02.bt", "map_2.bt", "map_10.bt"]
        );
    }
}
