//! Enums whose variants have stable names (command-line values, Python arguments, JSON):
//! the library lists them once, and every front end parses and lists them from here, so
//! that a new variant is one change in one place.

/// An enum of named variants, each with a one-line description (for `--help`).
///
/// ```
/// use froctomap_core::{parse_named, Named, UnknownName};
/// #[derive(Clone, Copy, Debug, PartialEq)]
/// enum Side { Left, Right }
/// impl Named for Side {
///     const ALL: &'static [Self] = &[Side::Left, Side::Right];
///     const WHAT: &'static str = "side";
///     fn name(self) -> &'static str { match self { Side::Left => "left", Side::Right => "right" } }
///     fn description(self) -> &'static str { "a side" }
/// }
/// assert_eq!(parse_named::<Side>("right"), Ok(Side::Right));
/// let err: UnknownName = parse_named::<Side>("up").unwrap_err();
/// assert_eq!(err.to_string(), "unknown side `up` (known: left, right)");
/// ```
pub trait Named: Copy + 'static {
    /// Every variant, in the order front ends list them.
    const ALL: &'static [Self];
    /// What a variant is, for messages ("expectation", "export mode").
    const WHAT: &'static str;
    /// The stable name.
    fn name(self) -> &'static str;
    /// One line on what the variant means.
    fn description(self) -> &'static str;

    /// Every name, in the order of [`ALL`](Self::ALL).
    fn names() -> Vec<&'static str> {
        Self::ALL.iter().map(|v| v.name()).collect()
    }
}

/// A name that no variant of a [`Named`] enum has.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} `{given}` (known: {})", known.join(", "))]
pub struct UnknownName {
    /// What was being named.
    pub what: &'static str,
    /// The name given.
    pub given: String,
    /// The names there are.
    pub known: Vec<&'static str>,
}

/// The variant named `name` (what every `FromStr` of a [`Named`] enum does).
pub fn parse_named<T: Named>(name: &str) -> Result<T, UnknownName> {
    T::ALL
        .iter()
        .copied()
        .find(|v| v.name() == name)
        .ok_or_else(|| UnknownName {
            what: T::WHAT,
            given: name.to_string(),
            known: T::names(),
        })
}
