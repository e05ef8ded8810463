//! The stable ids files record for temporal models.

use std::fmt;

/// Stable numeric id of a temporal model, recorded in files. Never reuse a retired id.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ModelId(pub u16);

impl ModelId {
    /// [`StaticMean`](crate::models::StaticMean): the mean only.
    pub const STATIC: ModelId = ModelId(0);
    /// [`FremenRegular`](crate::models::FremenRegular): FreMEn over all DFT bins of a regular axis.
    pub const FREMEN_REGULAR: ModelId = ModelId(1);
    /// [`FremenPeriods`](crate::models::FremenPeriods): FreMEn at a candidate period set, any axis.
    pub const FREMEN_PERIODS: ModelId = ModelId(2);
}

impl fmt::Display for ModelId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}
