//! An error and its causes as one line, the text both front ends (the command line and
//! Python) show.
//!
//! froctomap's own errors say each thing once: a message never repeats its cause, which is
//! the next link of the chain ([`said_twice`] finds a link that does, for tests). Foreign
//! errors are not all so kind: an `io::Error` made from another error, `mcap`'s and
//! `rusqlite`'s errors, zstd's (an `io::Error`) and PyO3's may show their cause in their own
//! text and return it from `source()` too, so [`error_message`] leaves out a cause whose text
//! the line already holds, and lets a cause that repeats the text before it with more
//! (rusqlite's `Error code 11: …` under its own `…`) take that text's place.

use std::error::Error;

/// The texts of `error` and its causes, outermost first.
pub fn error_chain<'a>(error: &'a (dyn Error + 'static)) -> impl Iterator<Item = String> + 'a {
    std::iter::successors(Some(error), |&e| e.source()).map(ToString::to_string)
}

/// `error` and its causes on one line, joined by `": "`, each text once (see the module's
/// note on foreign errors).
///
/// ```
/// let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
/// let error = froctomap_core::AtomicWriteError { path: "a.froct".into(), source: io };
/// assert_eq!(froctomap_core::error_message(&error), "cannot write a.froct: no such file");
/// ```
pub fn error_message(error: &(dyn Error + 'static)) -> String {
    let mut text = String::new();
    // Where the last text joined starts: a cause that repeats it with more (rusqlite's
    // `Error code 11: …` under its own `…`) takes its place.
    let mut last = 0;
    for part in error_chain(error) {
        if text.is_empty() {
            text = part;
        } else if part.contains(&text[last..]) {
            text.truncate(last);
            text.push_str(&part);
        } else if !text.contains(&part) {
            text.push_str(": ");
            last = text.len();
            text.push_str(&part);
        }
    }
    text
}

/// The first link of `error`'s chain that is empty or whose text an outer link already
/// holds (a message that also shows its cause), with that outer text: `None` when every
/// link says something and says it once.
pub fn said_twice(error: &(dyn Error + 'static)) -> Option<(String, String)> {
    let mut outer: Vec<String> = Vec::new();
    for part in error_chain(error) {
        if part.trim().is_empty() {
            return Some((outer.join(": "), part));
        }
        if let Some(holder) = outer
            .iter()
            .find(|o| o.contains(&part) || part.contains(o.as_str()))
        {
            return Some((holder.clone(), part));
        }
        outer.push(part);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("{path}: {source}")]
    struct Repeats {
        path: &'static str,
        #[source]
        source: std::io::Error,
    }

    fn io() -> std::io::Error {
        std::io::Error::new(std::io::ErrorKind::NotFound, "no such file")
    }

    #[test]
    fn a_repeated_cause_is_shown_once_and_found() {
        let repeating = Repeats {
            path: "a.froct",
            source: io(),
        };
        assert_eq!(error_message(&repeating), "a.froct: no such file");
        assert_eq!(
            said_twice(&repeating),
            Some((
                "a.froct: no such file".to_string(),
                "no such file".to_string()
            ))
        );
    }

    #[derive(Debug, thiserror::Error)]
    #[error("database disk image is malformed")]
    struct Short(#[source] std::io::Error);

    #[test]
    fn a_cause_repeating_its_parent_with_more_replaces_it() {
        let error = crate::AtomicWriteError {
            path: "a.db3".into(),
            source: std::io::Error::other(Short(std::io::Error::other(
                "Error code 11: database disk image is malformed",
            ))),
        };
        assert_eq!(
            error_message(&error),
            "cannot write a.db3: Error code 11: database disk image is malformed"
        );
        assert!(said_twice(&error).is_some());
    }

    #[test]
    fn causes_that_say_something_new_are_joined() {
        let error = crate::AtomicWriteError {
            path: "a.froct".into(),
            source: io(),
        };
        assert_eq!(said_twice(&error), None);
        assert_eq!(error_message(&error), "cannot write a.froct: no such file");
        assert_eq!(error_chain(&error).count(), 2);
    }
}
