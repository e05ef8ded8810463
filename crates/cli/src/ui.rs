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

impl Ui {
    pub(crate) fn warn(&self, path: &Path, warnings: &[String]) {
        if !self.quiet {
            for warning in warnings {
                eprintln!("warning: {}: {warning}", path.display());
            }
        }
    }

    pub(crate) fn note(&self, message: &str) {
        if !self.quiet {
            eprintln!("{message}");
        }
    }
}
