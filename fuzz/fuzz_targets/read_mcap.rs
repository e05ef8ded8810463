//! The MCAP reader on arbitrary bytes. Each input is read as it is and, when that differs,
//! once more resealed: every chunk's records CRC cleared (0: not checked) and the summary's
//! CRC recomputed, so that mutated lengths reach the record parsers behind the checksums.
#![no_main]

mod recording;

use libfuzzer_sys::fuzz_target;

const MAGIC: &[u8] = b"\x89MCAP0\r\n";

fuzz_target!(|data: &[u8]| {
    recording::read_recording(&froctomap_ros::MCAP, data);
    let mut sealed = data.to_vec();
    if reseal(&mut sealed).is_some() && sealed != data {
        recording::read_recording(&froctomap_ros::MCAP, &sealed);
    }
});

/// Clears the chunks' CRCs and recomputes the summary's; `None` where the records do not
/// parse far enough.
fn reseal(bytes: &mut [u8]) -> Option<()> {
    let le64 = |b: &[u8], at: usize| -> Option<u64> {
        Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
    };
    let mut pos = MAGIC.len();
    while pos + 9 <= bytes.len() {
        let len = usize::try_from(le64(bytes, pos + 1)?).ok()?;
        let end = pos.checked_add(9)?.checked_add(len)?;
        if end > bytes.len() {
            break;
        }
        if bytes[pos] == 0x06 && len >= 28 {
            bytes[pos + 9 + 24..pos + 9 + 28].fill(0);
        }
        pos = end;
    }
    let footer = bytes.len().checked_sub(MAGIC.len() + 29)?;
    let summary = usize::try_from(le64(bytes, footer + 9)?).ok()?;
    if summary != 0 && summary <= footer {
        let crc = crc32fast::hash(&bytes[summary..footer + 9 + 16]);
        bytes[footer + 25..footer + 29].copy_from_slice(&crc.to_le_bytes());
    }
    Some(())
}
