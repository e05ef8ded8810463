//! The formats built into this crate, registered in one place above both the registry and
//! the format plugins (so that neither reaches up into the other).

use crate::error::DuplicateName;
#[cfg(feature = "octomap-upstream")]
use crate::octomap_upstream;
use crate::{octomap_native, registry::FormatRegistry};

/// Registers every format enabled at compile time, preferred backends first: the native
/// Rust codec is the default for `.bt`/`.ot`, the upstream C++ library stays selectable
/// with backend `octomap`. Refuses (like every registration) a name already registered.
pub fn register_default_formats(registry: &mut FormatRegistry) -> Result<(), DuplicateName> {
    registry.register(octomap_native::BINARY)?;
    registry.register(octomap_native::FULL)?;
    #[cfg(feature = "octomap-upstream")]
    registry.register(octomap_upstream::BINARY)?;
    #[cfg(feature = "octomap-upstream")]
    registry.register(octomap_upstream::FULL)?;
    Ok(())
}

impl FormatRegistry {
    /// A registry with every format enabled at compile time.
    pub fn with_default_formats() -> Self {
        let mut registry = Self::new();
        // Built-in names and backends are distinct (a test registers them twice).
        let _ = register_default_formats(&mut registry);
        registry
    }
}
