//! The plugins of this program, registered once and handed to every command.

use froctomap_convert::Context;
use froctomap_core::{parse_named, Named};
use std::sync::OnceLock;

/// The formats, models and limits every command uses (the option parsers too, so that the
/// values they accept are the registered ones).
pub fn context() -> &'static Context {
    static CONTEXT: OnceLock<Context> = OnceLock::new();
    CONTEXT.get_or_init(|| {
        let mut context = Context::with_default_plugins();
        // ROS 1 bags, MCAP files and ROS 2 bag directories as sources of timed maps.
        // Distinct names: a clash would be a bug of this program, seen by its tests.
        let _ = froctomap_ros::register(context.formats_mut());
        context
    })
}

/// A parser of `--format` values that accepts the writable formats' names and lists them
/// in the help and in its error.
pub fn writable_format() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(context().formats().writable_names())
}

/// A parser of `export --format` values: the writable map formats and the recording formats
/// that can be written (`mcap`).
pub fn export_format() -> clap::builder::PossibleValuesParser {
    let mut names = context().formats().writable_names();
    names.extend(
        context()
            .formats()
            .recording_formats()
            .iter()
            .filter(|f| f.writable())
            .map(|f| f.name),
    );
    clap::builder::PossibleValuesParser::new(names)
}

/// The value parser of a library enum: its names and descriptions (what `--help` and the
/// shell completions list), each parsed by the library, so that a new variant needs no
/// change here.
pub fn named<T: Named + Send + Sync>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    PossibleValuesParser::new(
        T::ALL
            .iter()
            .map(|v| PossibleValue::new(v.name()).help(v.description())),
    )
    .try_map(|name| parse_named::<T>(&name))
}

/// The writable recording format whose extension `path` has (`out.mcap`: `mcap`).
pub fn recording_format_of(path: &std::path::Path) -> Option<&'static str> {
    context()
        .formats()
        .writable_recording_for(path)
        .map(|f| f.name)
}
