//! Shared by the recording targets: the input written to a temporary file (the readers take
//! paths), opened as a recording, and every map it lists fetched, under small limits.

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
}
