//! The native `.ot` reader on arbitrary bytes.
#![no_main]

mod common;

use froctomap_octomap_codec::FileKind;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    common::check_reader(data, FileKind::Full);
});
