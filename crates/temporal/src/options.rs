//! Model options as data: each model declares its options (key, help, default) on its
//! descriptor and parses their text values itself, so callers (command lines, bindings)
//! handle every model alike.

use crate::TemporalError;
use std::fmt::Display;
use std::str::FromStr;

/// One option a model accepts, as listed on its [`ModelDescriptor`](crate::ModelDescriptor).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OptionDescriptor {
    /// Key, as in `key=value`.
    pub key: &'static str,
    /// One line for `--help` and listings (what the value means, its accepted forms).
    pub help: &'static str,
    /// The value used when the option is not given.
    pub default: &'static str,
}

/// Option values as `key=value` text, for the model to parse (later values replace earlier
/// ones).
///
/// ```
/// use froctomap_temporal::ModelOptions;
/// let mut options = ModelOptions::new();
/// options.set("order", 3);
/// options.set_assignment("max-order=7")?;
/// options.set("order", "auto");
/// assert_eq!(options.get("order"), Some("auto"));
/// assert_eq!(options.iter().count(), 2);
/// assert!(options.set_assignment("no equals sign").is_err());
/// # Ok::<(), froctomap_temporal::TemporalError>(())
/// ```
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ModelOptions {
    values: Vec<(String, String)>,
}

impl ModelOptions {
    /// No options: every model uses its defaults.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets `key` to `value` (its text form).
    pub fn set(&mut self, key: &str, value: impl Display) {
        let value = value.to_string();
        match self.values.iter_mut().find(|(k, _)| k == key) {
            Some((_, v)) => *v = value,
            None => self.values.push((key.to_string(), value)),
        }
    }

    /// Sets an option from `key=value` text.
    pub fn set_assignment(&mut self, assignment: &str) -> Result<(), TemporalError> {
        let (key, value) = assignment
            .split_once('=')
            .filter(|(k, _)| !k.is_empty())
            .ok_or_else(|| TemporalError::MalformedOption(assignment.to_string()))?;
        self.set(key.trim(), value.trim());
        Ok(())
    }

    /// The value given for `key`.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.values
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Every given option, in the order first set.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &str)> {
        self.values.iter().map(|(k, v)| (k.as_str(), v.as_str()))
    }

    /// Fails on a key that `declared` does not list.
    pub fn check_keys(
        &self,
        model: &'static str,
        declared: &[OptionDescriptor],
    ) -> Result<(), TemporalError> {
        match self
            .values
            .iter()
            .find(|(k, _)| !declared.iter().any(|d| d.key == k))
        {
            Some((key, _)) => Err(TemporalError::UnknownOption {
                model,
                key: key.clone(),
            }),
            None => Ok(()),
        }
    }

    /// The value of a declared option: the given one, else its default.
    pub fn value_of<'a>(&'a self, option: &'a OptionDescriptor) -> &'a str {
        self.get(option.key).unwrap_or(option.default)
    }

    /// Parses a declared option's value (given or default) as `T`; `expected` says what is
    /// accepted, for the error.
    pub fn parse<T: FromStr>(
        &self,
        model: &'static str,
        option: &OptionDescriptor,
        expected: &'static str,
    ) -> Result<T, TemporalError> {
        let value = self.value_of(option);
        value
            .parse()
            .map_err(|_| invalid(model, option, value, expected))
    }
}

/// The error for a value a model does not accept.
pub(crate) fn invalid(
    model: &'static str,
    option: &OptionDescriptor,
    value: &str,
    expected: &'static str,
) -> TemporalError {
    TemporalError::InvalidOption {
        model,
        key: option.key,
        value: value.to_string(),
        expected,
    }
}
