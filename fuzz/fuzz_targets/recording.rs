//! Shared by the recording targets: the input written to a temporary file (the readers take
//! paths), opened as a recording, and every map it lists fetched, under small limits; for a
//! format read from streams (MCAP), the same bytes read as a stream on standard input too.

use froctomap_formats::{RecordedTime, RecordingFormat, RecordingOptions};
use std::io::Write;

/// Small enough that no input can make one run slow or large.
const LIMIT: u64 = 1 << 22;

/// Reads `data` as `format` every way the build does: any outcome but a panic or an abort;
/// an error names the file.
pub fn read_recording(format: &RecordingFormat, data: &[u8]) {
    let Ok(mut file) = tempfile::NamedTempFile::new() else {
        return;
    };
    if file.write_all(data).and_then(|()| file.flush()).is_err() {
        return;
    }
    let name = file.path().display().to_string();
    for time in [RecordedTime::Header, RecordedTime::Log] {
        let options = RecordingOptions::new(None, time);
        let recording = match (format.open)(file.path(), &options, LIMIT) {
            Ok(recording) => recording,
            Err(e) => {
                assert!(e.to_string().contains(&name), "{e}");
                continue;
            }
        };
        for i in 0..recording.times.len() {
            if let Err(e) = recording.maps.map_bytes(i, LIMIT) {
                assert!(e.to_string().contains(&name), "{e}");
            }
        }
    }
    if let Some(open_stream) = format.open_stream {
        read_stream(open_stream, data);
    }
}

/// Reads `data` as a stream (`-`), spooled in a temporary directory: any outcome but a
/// panic or an abort; an error names the stream, and the spool goes with the recording.
fn read_stream(open_stream: froctomap_formats::OpenStream, data: &[u8]) {
    let Ok(spool) = tempfile::tempdir() else {
        return;
    };
    let named = |e: &dyn std::error::Error| {
        let text = e.to_string();
        assert!(
            text.starts_with("-: ") || text.starts_with("MCAP stream on standard input"),
            "{text}"
        );
    };
    for time in [RecordedTime::Header, RecordedTime::Log] {
        let options = RecordingOptions::new(None, time)
            .with_skip_bad(true)
            .with_spool_dir(Some(spool.path().to_path_buf()));
        match open_stream(&mut &data[..], &options, LIMIT) {
            Ok(recording) => {
                for i in 0..recording.times.len() {
                    if let Err(e) = recording.maps.map_bytes(i, LIMIT) {
                        named(&*e);
                    }
                }
            }
            Err(e) => named(&*e),
        }
        assert!(std::fs::read_dir(spool.path()).map_or(true, |mut d| d.next().is_none()));
    }
}
