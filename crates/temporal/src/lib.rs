//! Temporal models (work in progress).
