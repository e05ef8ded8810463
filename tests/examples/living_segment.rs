//! Writes format 2.0 files with segments for the Python tests (tests/python/test_living.py),
//! while no command writes segments:
//!
//! * `living_segment convert BASE.froct OUT.froct`: a 2.0 file whose base is the 1.x file;
//! * `living_segment append OUT.froct PART.froct`: one segment holding the maps of the 1.x
//!   file PART (a build of later maps).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["convert", base, out] => {
            froctomap_file::LivingWriter::convert(Path::new(base), Path::new(out)).map(|_| ())
        }
        ["append", living, part] => froctomap_test_support::living::append_segment_from_build(
            Path::new(living),
            Path::new(part),
        ),
        _ => {
            eprintln!("usage: living_segment convert BASE OUT | append LIVING PART");
            std::process::exit(2);
        }
    };
    if let Err(e) = result {
        eprintln!("living_segment: {e}");
        std::process::exit(1);
    }
}
