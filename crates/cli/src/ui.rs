//! What every command is handed: the user's settings and the program's plugins.

use anyhow::Context as _;
use froctomap_convert::{read_time, Context, TimeQuery, Zone};
use froctomap_core::Timestamp;
use froctomap_formats::Backend;
use std::cell::Cell;
use std::path::Path;

/// Settings shared by all commands.
pub struct Ui {
    /// Suppress warnings and summaries.
    pub quiet: bool,
    /// Preferred implementation of formats that have several (`--backend`).
    pub backend: Backend,
    /// The registered formats and models, and the limits.
    pub context: &'static Context,
    /// Where times without a zone are read (`--tz`; UTC when not given).
    pub zone: Zone,
    /// `--tz` was given, so reading zone-less times in `zone` needs no notice.
    pub zone_given: bool,
    /// The notice that zone-less times are UTC was printed.
    pub told_zoneless: Cell<bool>,
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

    /// Says once per run, unless `--tz` was given, that a time without a zone was read as
    /// UTC: a wall-clock time taken for UTC is off by hours without any other sign.
    pub(crate) fn read_zoneless(&self, zoneless: bool) {
        if zoneless && !self.zone_given && !self.told_zoneless.replace(true) {
            self.note(
                "note: times without a zone are read as UTC (--tz ZONE or --tz local to change)",
            );
        }
    }

    /// A time given by the user for `option`, read in `--tz`.
    pub(crate) fn time(&self, text: &str, option: &str) -> anyhow::Result<Timestamp> {
        let read = read_time(text, &self.zone).with_context(|| option.to_string())?;
        self.read_zoneless(read.zoneless);
        Ok(read.time)
    }

    /// A `--time` query (an instant or `index:N`), read in `--tz`.
    pub(crate) fn time_query(&self, text: &str) -> anyhow::Result<TimeQuery> {
        let (query, zoneless) = TimeQuery::read(text, &self.zone)?;
        self.read_zoneless(zoneless);
        Ok(query)
    }
}

/// A report as the pretty JSON `--json` prints: its floats without the noise of binary
/// arithmetic ([`froctomap_convert::tidy_floats`]), as the Python package returns them.
pub fn json_report(report: &impl serde::Serialize) -> serde_json::Result<String> {
    let mut value = serde_json::to_value(report)?;
    froctomap_convert::tidy_floats(&mut value);
    serde_json::to_string_pretty(&value)
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
