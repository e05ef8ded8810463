//! The plugin registries handed to every call.

use froctomap_convert::Context;
use std::sync::OnceLock;

/// The formats, models and recording sources every call uses, registered once (as the CLI's
/// `plugins::context`).
pub(crate) fn context() -> &'static Context {
    static CONTEXT: OnceLock<Context> = OnceLock::new();
    CONTEXT.get_or_init(|| {
        let mut context = Context::with_default_plugins();
        // Distinct names: a clash would be a bug of this program, seen by its tests.
        let _ = froctomap_ros::register(context.formats_mut());
        context
    })
}
