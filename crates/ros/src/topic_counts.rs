//! The shape of a recording's per-topic counts, shared by `describe` (which tallies them)
//! and the readers that count from their indexes (`sqlite_bag`).

/// A topic: name, type, encoding.
pub(crate) type TopicKey = (String, String, String);

/// The first and last log times of some messages (`None`: no message).
pub(crate) type Span = Option<(i64, i64)>;
