//! Expanding a recursive `**` pattern by walking the directory tree without following
//! symbolic links to directories: a link to an ancestor (`sub/up -> ..`) would otherwise make
//! the walk endless, and two such links make it exponential.

use crate::error::ConvertError;
use glob::{MatchOptions, Pattern};
use std::path::{Component, Path, PathBuf};

/// The regular files (symbolic links to files included) that `pattern` matches below the
/// literal directory it starts with, sorted. Directories reached through symbolic links are
/// not entered.
pub(crate) fn recursive_matches(pattern: &str) -> Result<Vec<PathBuf>, ConvertError> {
    let compiled = Pattern::new(pattern).map_err(|source| ConvertError::BadPattern {
        pattern: pattern.to_string(),
        source,
    })?;
    let options = MatchOptions {
        case_sensitive: true,
        require_literal_separator: true,
        require_literal_leading_dot: false,
    };
    let mut matched = Vec::new();
    let mut pending = vec![literal_prefix(Path::new(pattern))];
    while let Some(dir) = pending.pop() {
        // Unreadable directories are passed over, as the glob walk does.
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let Ok(kind) = entry.file_type() else {
                continue;
            };
            let path = entry.path();
            if kind.is_dir() {
                pending.push(path);
            } else if (kind.is_file() || (kind.is_symlink() && path.is_file()))
                && compiled.matches_path_with(&path, options)
            {
                matched.push(path);
            }
        }
    }
    matched.sort();
    Ok(matched)
}

/// The directories of `pattern` before its first component with a wildcard (`.` if none).
fn literal_prefix(pattern: &Path) -> PathBuf {
    let literal: PathBuf = pattern
        .components()
        .take_while(|c| match c {
            Component::Normal(name) => !name.to_string_lossy().contains(['*', '?', '[']),
            _ => true,
        })
        .collect();
    if literal.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        literal
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn links_to_ancestors_are_not_walked() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("a").join("sub");
        std::fs::create_dir_all(&sub).unwrap();
        std::fs::write(sub.join("x.bt"), b"map").unwrap();
        std::fs::write(dir.path().join("a").join("y.bt"), b"map").unwrap();
        std::fs::write(sub.join("notes.txt"), b"text").unwrap();
        // Two links to ancestors: following them, the walk would never end.
        std::os::unix::fs::symlink("..", sub.join("up")).unwrap();
        std::os::unix::fs::symlink("../..", sub.join("top")).unwrap();
        // A link to a file is a file.
        std::os::unix::fs::symlink("x.bt", sub.join("z.bt")).unwrap();
        let pattern = format!("{}/**/*.bt", dir.path().join("a").display());
        let found = recursive_matches(&pattern).unwrap();
        assert_eq!(
            found,
            vec![
                dir.path().join("a/sub/x.bt"),
                dir.path().join("a/sub/z.bt"),
                dir.path().join("a/y.bt"),
            ]
        );
    }

    #[test]
    fn the_walk_starts_at_the_literal_directories() {
        assert_eq!(
            literal_prefix(Path::new("maps/2016/**/*.bt")),
            Path::new("maps/2016")
        );
        assert_eq!(literal_prefix(Path::new("**/*.bt")), Path::new("."));
        assert_eq!(literal_prefix(Path::new("/data/s*/**")), Path::new("/data"));
    }
}
