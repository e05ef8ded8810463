//! MCAP files with resealed hostile lengths (issue 29): a record, or a length inside one,
//! declaring 0xFFFFFFFF bytes — at the top level, in the summary, inside a chunk (its data
//! recompressed and its CRC recomputed) — gives a typed error naming the file, never an
//! abort on a 4 GiB allocation inside the `mcap` crate.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use froctomap_formats::{RecordedTime, RecordingOptions};
use froctomap_ros::MCAP;
use std::path::Path;

const MAGIC: &[u8] = b"\x89MCAP0\r\n";

fn fixture() -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/ros/two_maps_zstd.mcap"),
    )
    .unwrap()
}

/// The top-level records: (offset, opcode, body range).
fn records(bytes: &[u8]) -> Vec<(usize, u8, std::ops::Range<usize>)> {
    let mut out = Vec::new();
    let mut pos = MAGIC.len();
    while pos + 9 <= bytes.len() - MAGIC.len() {
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        out.push((pos, bytes[pos], pos + 9..pos + 9 + len));
        pos += 9 + len;
    }
    out
}

/// Recomputes the footer's summary CRC (the bytes from the summary to the footer's field
/// before it).
fn reseal(bytes: &mut [u8]) {
    let footer = bytes.len() - MAGIC.len() - 29;
    let summary = u64::from_le_bytes(bytes[footer + 9..footer + 17].try_into().unwrap()) as usize;
    if summary != 0 && summary <= footer {
        let crc = crc32fast::hash(&bytes[summary..footer + 9 + 16]);
        bytes[footer + 25..footer + 29].copy_from_slice(&crc.to_le_bytes());
    }
}

/// Reads every map: an error must name the file.
fn read_all(path: &Path) -> Result<usize, String> {
    let options = RecordingOptions::new(None, RecordedTime::Header);
    let recording = (MCAP.open)(path, &options, 1 << 30).map_err(|e| e.to_string())?;
    for i in 0..recording.times.len() {
        recording
            .maps
            .map_bytes(i, 1 << 30)
            .map_err(|e| e.to_string())?;
    }
    Ok(recording.times.len())
}

fn check(dir: &Path, bytes: &[u8], what: &str) -> Result<usize, String> {
    let path = dir.join("hostile.mcap");
    std::fs::write(&path, bytes).unwrap();
    let read = read_all(&path);
    if let Err(message) = &read {
        assert!(message.contains("hostile.mcap"), "{what}: {message}");
    }
    read
}

/// A chunk record rebuilt around `records` (zstd, CRC recomputed).
fn chunk(original: &[u8], records: &[u8]) -> Vec<u8> {
    let compression_len = u32::from_le_bytes(original[28..32].try_into().unwrap()) as usize;
    let mut body = original[..16].to_vec();
    body.extend((records.len() as u64).to_le_bytes());
    body.extend(crc32fast::hash(records).to_le_bytes());
    body.extend(&original[28..32 + compression_len]);
    let data = zstd::bulk::compress(records, 3).unwrap();
    body.extend((data.len() as u64).to_le_bytes());
    body.extend(data);
    body
}

fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
    let mut out = vec![opcode];
    out.extend((body.len() as u64).to_le_bytes());
    out.extend(body);
    out
}

#[test]
fn the_fixture_reads_and_has_schemas_channels_and_chunks_in_its_summary() {
    let bytes = fixture();
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(check(dir.path(), &bytes, "intact"), Ok(2));
    let ops: Vec<u8> = records(&bytes).iter().map(|r| r.1).collect();
    for op in [3, 4, 6, 8] {
        assert!(ops.contains(&op), "{ops:?}");
    }
}

/// The attack: a schema's or channel's string length, and a record's length, 0xFFFFFFFF.
#[test]
fn a_length_of_0xffffffff_is_a_typed_error_wherever_it_is() {
    let bytes = fixture();
    let dir = tempfile::tempdir().unwrap();
    let mut strings = 0;
    for (pos, opcode, body) in records(&bytes) {
        // The record's own length.
        for len in [0xFFFF_FFFFu64, u64::MAX] {
            let mut damaged = bytes.clone();
            damaged[pos + 1..pos + 9].copy_from_slice(&len.to_le_bytes());
            let _ = check(
                dir.path(),
                &damaged,
                &format!("record at {pos} of length {len:#x}"),
            );
        }
        // Every u32 inside its body.
        for at in body.start..body.end.saturating_sub(3) {
            let mut damaged = bytes.clone();
            damaged[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
            reseal(&mut damaged);
            let what = format!("record {opcode} at {pos}: u32 at {at}");
            let read = check(dir.path(), &damaged, &what);
            // The first string of a schema (its name) and of a channel (its topic).
            let first_string = match opcode {
                3 => body.start + 2,
                4 => body.start + 4,
                _ => usize::MAX,
            };
            if at == first_string {
                strings += 1;
                if let Err(message) = read {
                    assert!(
                        message.contains("a string runs past its record"),
                        "{what}: {message}"
                    );
                }
            }
        }
    }
    assert!(strings >= 2);
}

/// The same inside chunks: the records a chunk holds, with the summary dropped so that
/// the file is read record by record (its chunks recompressed to other lengths).
#[test]
fn lengths_inside_chunks_are_checked_before_parsing() {
    let bytes = fixture();
    let dir = tempfile::tempdir().unwrap();
    let top = records(&bytes);
    let mut inner_strings = 0;
    for (c, &(_, opcode, ref body)) in top.iter().enumerate() {
        if opcode != 6 {
            continue;
        }
        let original = &bytes[body.clone()];
        let compression_len = u32::from_le_bytes(original[28..32].try_into().unwrap()) as usize;
        let size = u64::from_le_bytes(original[16..24].try_into().unwrap()) as usize;
        let data = &original[32 + compression_len + 8..];
        let inner = zstd::bulk::decompress(data, size).unwrap();
        let inner_records = records(&[MAGIC, &inner, MAGIC].concat());
        for (pos, inner_op, inner_body) in inner_records {
            let first_string = match inner_op {
                3 => Some(inner_body.start + 2),
                4 => Some(inner_body.start + 4),
                _ => None,
            };
            for at in inner_body.start..inner_body.end.saturating_sub(3) {
                let mut damaged_inner = inner.clone();
                // Offsets were counted with a magic in front.
                let at_inner = at - MAGIC.len();
                damaged_inner[at_inner..at_inner + 4].copy_from_slice(&u32::MAX.to_le_bytes());
                // The file up to its data end, with the chunk replaced, and no summary.
                let mut file = MAGIC.to_vec();
                for (i, &(p, op, ref b)) in top.iter().enumerate() {
                    match op {
                        15 => {
                            file.extend(&bytes[p..b.end]);
                            break;
                        }
                        _ if i == c => file.extend(record(6, &chunk(original, &damaged_inner))),
                        _ => file.extend(&bytes[p..b.end]),
                    }
                }
                file.extend(record(2, &[0u8; 20]));
                file.extend(MAGIC);
                let what = format!("chunk {c}: record {inner_op} at {pos}: u32 at {at}");
                let read = check(dir.path(), &file, &what);
                if Some(at) == first_string {
                    inner_strings += 1;
                    let message = read.expect_err(&what);
                    assert!(
                        message.contains("a string runs past its record"),
                        "{what}: {message}"
                    );
                }
            }
        }
    }
    assert!(
        inner_strings >= 1,
        "the fixture's chunks hold schemas or channels"
    );
}
