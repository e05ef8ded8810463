//! The recording sink: each map received is appended to the living map through
//! [`froctomap_convert::Recorder`], `froctomap record`'s commit path (segments committed
//! every so many maps or so much time, a missing file created from the first commit, maps
//! not later than the last one skipped and counted, bad maps left out).

use crate::{MapSink, ReceivedMap};
use froctomap_convert::{RecordError, RecordSummary, Recorder};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Which time a received map is recorded at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TimeSource {
    /// The message's `header.stamp` (the default; an unset stamp is refused).
    #[default]
    Header,
    /// The time the node received it (the system clock).
    Receive,
}

impl std::str::FromStr for TimeSource {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        match text.trim().to_ascii_lowercase().as_str() {
            "header" => Ok(Self::Header),
            "receive" => Ok(Self::Receive),
            _ => Err(format!("`{text}` is not a time source (header, receive)")),
        }
    }
}

/// Appends the maps received to a FROctomap file.
pub struct RecordingSink<'a> {
    recorder: Recorder<'a>,
    time_source: TimeSource,
    min_interval: Duration,
    last_taken: Option<Timestamp>,
    thinned: u64,
}

impl<'a> RecordingSink<'a> {
    /// Records into `recorder`'s file at the times `time_source` gives, taking at most one
    /// map per `min_interval` (zero: every map).
    pub fn new(recorder: Recorder<'a>, time_source: TimeSource, min_interval: Duration) -> Self {
        Self {
            recorder,
            time_source,
            min_interval,
            last_taken: None,
            thinned: 0,
        }
    }

    /// Commits if a commit by time is due; the node's loop calls it between receptions.
    pub fn tick(&mut self) -> Result<(), RecordError> {
        self.recorder.commit_if_due()
    }

    /// Maps left out by `--min-interval` so far.
    pub fn thinned(&self) -> u64 {
        self.thinned
    }

    /// The recording's counts so far.
    pub fn summary(&self) -> RecordSummary {
        self.recorder.summary()
    }

    /// Commits what is gathered and ends the recording.
    pub fn finish(self) -> Result<RecordSummary, RecordError> {
        self.recorder.finish()
    }
}

impl MapSink for RecordingSink<'_> {
    fn receive(
        &mut self,
        map: ReceivedMap,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let time = match self.time_source {
            TimeSource::Header if map.stamp.0 == 0 => {
                return Err("the message has no header.stamp (use --time-source receive)".into())
            }
            TimeSource::Header => map.stamp,
            TimeSource::Receive => {
                let now = SystemTime::now().duration_since(UNIX_EPOCH)?;
                Timestamp(i64::try_from(now.as_nanos())?)
            }
        };
        if let Some(last) = self.last_taken {
            let since = i128::from(time.0) - i128::from(last.0);
            if since > 0 && since < self.min_interval.as_nanos() as i128 {
                self.thinned += 1;
                return Ok(());
            }
        }
        if self.recorder.take_bytes(time, &map.file)? {
            self.last_taken = Some(time);
        } else {
            log::warn!(
                "the map at {} is not later than the last one taken: skipped ({} so far)",
                iso8601(time),
                self.recorder.summary().older
            );
        }
        Ok(())
    }
}
