//! What every command is handed: the user's settings and the program's plugins.

use froctomap_convert::Context;
use froctomap_formats::Backend;
use std::path::Path;

/// Settings shared by all commands.
pub struct Ui {
    /// Suppress warnings and summaries.
    pub quiet: bool,
    /// Preferred implementation of formats that have several (`--backend`).
    pub backend: Backend,
    /// The registered formats and models, and the limits.
    pub context: &'static Context,
}

/// `text` with control characters (and bidirectional overrides) escaped as `\u{1b}`, `\n`…,
/// so that a file name or a metadata value read from a file cannot move the cursor,
/// recolour the terminal or forge lines. Everything the CLI prints that it did not write
/// itself goes through here.
pub fn escaped(text: impl std::fmt::Display) -> String {
    let text = text.to_string();
    let unsafe_char =
        |c: char| c.is_control() || matches!(c, '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}');
    if !text.chars().any(unsafe_char) {
        return text;
    }
    let mut shown = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if unsafe_char(c) {
            shown.extend(c.escape_default());
        } else {
            shown.push(c);
        }
    }
    shown
}

impl Ui {
    pub(crate) fn warn(&self, path: &Path, warnings: &[String]) {
        if !self.quiet {
            for warning in warnings {
                eprintln!("warning: {}: {}", escaped(path.display()), escaped(warning));
            }
        }
    }

    pub(crate) fn note(&self, message: &str) {
        if !self.quiet {
            eprintln!("{message}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::escaped;

    #[test]
    fn control_characters_are_shown_escaped() {
        assert_eq!(escaped("room_12.bt"), "room_12.bt");
        assert_eq!(escaped("crème brûlée"), "crème brûlée");
        assert_eq!(
            escaped("a\u{1b}[2J\nerror: forged\r\u{7}"),
            "a\\u{1b}[2J\\nerror: forged\\r\\u{7}"
        );
        assert_eq!(escaped("txt.\u{202E}tb"), "txt.\\u{202e}tb");
    }
}
