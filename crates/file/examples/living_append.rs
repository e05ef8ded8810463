//! Times format 2.0 commits as the history grows: appends SEGMENTS one-sample segments (a
//! tile of CELLS constant cells each) to a converted 1.x file and prints the median commit
//! time (tiles written, record, two fdatasyncs) of the first and of the last tenth, their
//! ratio, and the time to open a writer and a reader at the end, against the same at the
//! start. The container's share of the living map's promise: a commit's cost follows the
//! segment, not the history; opening walks every record once.
//!
//! `cargo run --release -p froctomap-file --example living_append -- BASE.froct SEGMENTS CELLS`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use froctomap_core::{MortonCode, Occupancy, Timestamp};
use froctomap_file::{LivingReader, LivingWriter, SegmentCell, SegmentContent};
use froctomap_temporal::TimeAxis;
use std::path::Path;
use std::time::{Duration, Instant};

fn median(mut times: Vec<Duration>) -> Duration {
    times.sort_unstable();
    times[times.len() / 2]
}

fn open_times(path: &Path) -> (Duration, Duration) {
    let runs = 9;
    let mut writer = Vec::new();
    let mut reader = Vec::new();
    for _ in 0..runs {
        let t = Instant::now();
        drop(LivingWriter::open(path).unwrap());
        writer.push(t.elapsed());
        let t = Instant::now();
        drop(LivingReader::open(path).unwrap());
        reader.push(t.elapsed());
    }
    (median(writer), median(reader))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, base, segments, cells] = &args[..] else {
        panic!("usage: living_append BASE.froct SEGMENTS CELLS");
    };
    let segments: usize = segments.parse().unwrap();
    let cells: u64 = cells.parse().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("living.froct");
    LivingWriter::convert(Path::new(base), &path).unwrap();
    let (writer_open_0, reader_open_0) = open_times(&path);
    let mut writer = LivingWriter::open(&path).unwrap();
    let step = 5_000_000_000;
    let mut next = writer
        .reader()
        .sample_time(writer.reader().sample_count() - 1)
        .unwrap()
        .0;
    let tile = 0x7000_0000_0000u64; // a tile of its own, far from the base's
    let mut commits = Vec::with_capacity(segments);
    for k in 0..segments {
        next += step;
        let axis = TimeAxis::regular(Timestamp(next), step, 1, vec![]).unwrap();
        let t = Instant::now();
        let mut segment = writer.begin_segment(axis).unwrap();
        segment
            .push_tile((0..cells).map(|c| SegmentCell {
                start: MortonCode(tile + c),
                depth: 16,
                mask: None,
                content: SegmentContent::Constant(Occupancy::from((c + k as u64) % 3 == 0)),
            }))
            .unwrap();
        segment.commit().unwrap();
        commits.push(t.elapsed());
    }
    drop(writer);
    let tenth = (segments / 10).max(1);
    let first = median(commits[..tenth].to_vec());
    let last = median(commits[segments - tenth..].to_vec());
    let (writer_open, reader_open) = open_times(&path);
    let bytes = std::fs::metadata(&path).unwrap().len();
    println!("{segments} segments of {cells} cells, file {bytes} B");
    println!(
        "commit median: first tenth {first:?}, last tenth {last:?}, ratio {:.2}",
        last.as_secs_f64() / first.as_secs_f64()
    );
    println!(
        "open writer {writer_open_0:?} → {writer_open:?} ({:.1}×), reader {reader_open_0:?} → {reader_open:?} ({:.1}×)",
        writer_open.as_secs_f64() / writer_open_0.as_secs_f64(),
        reader_open.as_secs_f64() / reader_open_0.as_secs_f64()
    );
}
