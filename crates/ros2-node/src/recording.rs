//! The recording sink: each map received is appended to the living map through
//! [`froctomap_convert::Recorder`], `froctomap record`'s commit path (segments committed
//! every so many maps or so much time, a missing file created from the first commit, maps
//! not later than the last one skipped and counted, bad maps left out).

use crate::sink::{MapSink, ReceivedMap};
use froctomap_convert::{RecordError, RecordSummary, Recorder};
use froctomap_core::calendar::iso8601;
use froctomap_core::Timestamp;
use std::time::Duration;

/// Which time a received map is recorded at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TimeSource {
    /// The message's `header.stamp` (the default; an unset stamp is refused).
    #[default]
    Header,
    /// The time the node received it ([`ReceivedMap::received`]: the system clock, or
    /// `/clock`'s with `use_sim_time`).
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

/// A commit failed for a reason of the file's or the disk's (not a bad map's, those are left
/// out): the maps gathered since the last commit are lost.
#[derive(Debug, thiserror::Error)]
#[error("commit failed, {lost} map(s) gathered since the last commit lost")]
pub struct CommitFailed {
    /// Maps lost (taken, neither committed nor left out as bad).
    pub lost: u64,
    /// Why.
    #[source]
    pub source: Box<RecordError>,
}

/// Appends the maps received to a FROctomap file.
pub struct RecordingSink<'a> {
    recorder: Recorder<'a>,
    time_source: TimeSource,
    min_interval: Duration,
    last_taken: Option<Timestamp>,
    thinned: u64,
    lost: u64,
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
            lost: 0,
        }
    }

    /// Commits if a commit by time is due; the node's loop calls it between receptions.
    pub fn tick(&mut self) -> Result<(), CommitFailed> {
        self.counting_lost(false, |recorder| recorder.commit_if_due().map(|()| true))
            .map(|_| ())
    }

    /// Maps left out by `--min-interval` so far.
    pub fn thinned(&self) -> u64 {
        self.thinned
    }

    /// Maps lost to failed commits so far.
    pub fn lost(&self) -> u64 {
        self.lost
    }

    /// Runs `step` (which may take one map, `takes_map`, and commit); when it fails, counts
    /// the maps it lost: those gathered (the one taken included) that were neither committed
    /// nor left out as bad. A map refused before it was taken (the segment limit) counts too.
    fn counting_lost(
        &mut self,
        takes_map: bool,
        step: impl FnOnce(&mut Recorder<'a>) -> Result<bool, RecordError>,
    ) -> Result<bool, CommitFailed> {
        let before = (self.recorder.pending(), self.recorder.summary());
        step(&mut self.recorder).map_err(|source| {
            let after = self.recorder.summary();
            let taken = takes_map && after.older == before.1.older;
            let gathered = before.0 as u64 + u64::from(taken);
            let kept = (after.committed_maps - before.1.committed_maps) as u64
                + (after.bad - before.1.bad)
                + self.recorder.pending() as u64;
            let lost = gathered.saturating_sub(kept);
            self.lost += lost;
            CommitFailed {
                lost,
                source: Box::new(source),
            }
        })
    }

    /// The recording's counts so far.
    pub fn summary(&self) -> RecordSummary {
        self.recorder.summary()
    }

    /// Commits what is gathered and ends the recording at once: a background compaction
    /// still running is abandoned (the file keeps every commit; the next run compacts).
    pub fn finish(mut self) -> Result<RecordSummary, CommitFailed> {
        self.counting_lost(false, |recorder| recorder.commit().map(|()| true))?;
        self.recorder.stop().map_err(|source| CommitFailed {
            lost: 0,
            source: Box::new(source),
        })
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
            TimeSource::Receive => map
                .received
                .ok_or("no receive time: /clock has not said one yet (use_sim_time)")?,
        };
        if let Some(last) = self.last_taken {
            let since = i128::from(time.0) - i128::from(last.0);
            if since > 0 && since < self.min_interval.as_nanos() as i128 {
                self.thinned += 1;
                return Ok(());
            }
        }
        if self.counting_lost(true, |recorder| recorder.take_bytes(time, &map.file))? {
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{SystemTime, UNIX_EPOCH};

    fn now() -> Timestamp {
        let since = SystemTime::now().duration_since(UNIX_EPOCH).expect("clock");
        Timestamp(since.as_nanos() as i64)
    }
    use froctomap_convert::{CommitEvery, Context, FroctFile, RecordOptions, SeriesRead};

    fn map(stamp_s: i64) -> ReceivedMap {
        let fixture = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/octomap/few_voxels.bt");
        ReceivedMap {
            stamp: Timestamp(stamp_s * 1_000_000_000),
            frame_id: "map".to_string(),
            received: Some(now()),
            binary: true,
            file: std::fs::read(fixture).expect("the fixture"),
        }
    }

    fn sink<'a>(
        context: &'a Context,
        file: &std::path::Path,
        source: TimeSource,
        min: u64,
    ) -> RecordingSink<'a> {
        sink_committing_every(context, file, source, min, 1)
    }

    /// A sink committing every `maps` maps, bad maps left out as the node does.
    fn sink_committing_every<'a>(
        context: &'a Context,
        file: &std::path::Path,
        source: TimeSource,
        min: u64,
        maps: usize,
    ) -> RecordingSink<'a> {
        let options = RecordOptions::for_live_source(CommitEvery::Maps(maps));
        let recorder = Recorder::open(context, file, options).expect("open");
        RecordingSink::new(recorder, source, Duration::from_secs(min))
    }

    #[test]
    fn header_stamps_are_thinned_by_min_interval_and_unset_ones_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join("living.froct");
        let context = Context::with_default_plugins();
        let mut sink = sink(&context, &file, TimeSource::Header, 10);
        assert!(sink.receive(map(0)).is_err(), "an unset stamp is refused");
        for s in [
            1_700_000_000,
            1_700_000_004,
            1_700_000_011,
            1_700_000_011,
            1_700_000_005,
        ] {
            sink.receive(map(s)).expect("taken or skipped");
        }
        assert_eq!(sink.thinned(), 1, "4 s after the last one taken");
        let summary = sink.finish().expect("finish");
        assert_eq!((summary.committed_maps, summary.older), (2, 2));
        let reader = FroctFile::open(&file).expect("the file");
        let times: Vec<_> = (0..reader.sample_count())
            .filter(|&s| !reader.is_missing(s))
            .filter_map(|s| reader.sample_time(s))
            .collect();
        assert_eq!(times, [map(1_700_000_000).stamp, map(1_700_000_011).stamp]);
    }

    #[test]
    fn a_failed_commit_is_reported_with_the_maps_it_lost() {
        let dir = tempfile::tempdir().expect("tempdir");
        let home = dir.path().join("living");
        std::fs::create_dir(&home).expect("mkdir");
        let file = home.join("living.froct");
        let context = Context::with_default_plugins();
        let mut sink = sink_committing_every(&context, &file, TimeSource::Header, 0, 3);
        for s in 0..3 {
            sink.receive(map(1_700_000_000 + s)).expect("the base");
        }
        sink.receive(map(1_700_000_003)).expect("gathered");
        sink.receive(map(1_700_000_004)).expect("gathered");
        // The file's directory is gone (as a full or lost disk): the commit cannot be
        // written, and the three maps gathered for it are lost, not only the last one.
        std::fs::remove_dir_all(&home).expect("remove");
        let error = sink
            .receive(map(1_700_000_005))
            .expect_err("the commit fails");
        let failed = error
            .downcast_ref::<CommitFailed>()
            .unwrap_or_else(|| panic!("a failed commit: {error}"));
        assert_eq!(failed.lost, 3, "{failed}");
        assert!(!failed.source.is_bad_map(), "{failed}");
        assert_eq!(sink.lost(), 3);
        assert_eq!(sink.summary().committed_maps, 3);
    }

    #[test]
    fn receive_time_without_a_clock_time_is_refused() {
        // use_sim_time before the first /clock message: no "now" to record at.
        let dir = tempfile::tempdir().expect("tempdir");
        let context = Context::with_default_plugins();
        let mut sink = sink(
            &context,
            &dir.path().join("l.froct"),
            TimeSource::Receive,
            0,
        );
        let mut early = map(0);
        early.received = None;
        let refused = sink.receive(early).expect_err("refused");
        assert!(refused.to_string().contains("/clock"), "{refused}");
        let mut sim = map(0);
        sim.received = Some(Timestamp(1_600_000_000_000_000_000));
        sink.receive(sim).expect("taken at /clock's time");
        sink.finish().expect("finish");
        let reader = FroctFile::open(&dir.path().join("l.froct")).expect("the file");
        assert_eq!(reader.last_instant(), Timestamp(1_600_000_000_000_000_000));
    }

    #[test]
    fn receive_time_records_at_the_clock() {
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join("living.froct");
        let context = Context::with_default_plugins();
        let before = SystemTime::now().duration_since(UNIX_EPOCH).expect("clock");
        let mut sink = sink(&context, &file, TimeSource::Receive, 0);
        sink.receive(map(0)).expect("an unset stamp is fine here");
        sink.finish().expect("finish");
        let after = SystemTime::now().duration_since(UNIX_EPOCH).expect("clock");
        let reader = FroctFile::open(&file).expect("the file");
        // Within the two clock readings (a second either side: not a timing check).
        let t = reader.last_instant().0.div_euclid(1_000_000_000) as u64;
        assert!(t + 1 >= before.as_secs() && t <= after.as_secs() + 1, "{t}");
    }
}
