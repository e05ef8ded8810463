//! Times one retrieval and one prediction in-process against one upstream read of a `.bt`.
#![allow(clippy::unwrap_used, clippy::expect_used)]
use froctomap_convert::{observed_map, predicted_map};
use froctomap_file::FroctReader;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let reader = FroctReader::open(args[1].as_ref()).unwrap();
    let bt = std::fs::read(&args[2]).unwrap();
    let n = 20;
    for _ in 0..2 {
        let t = Instant::now();
        for _ in 0..n {
            let s = observed_map(&reader, 2000).unwrap();
            let c = s.canonical();
            let _ = froctomap_octomap_codec::encode_binary(&c);
        }
        let retrieve = t.elapsed() / n;
        let t = Instant::now();
        for _ in 0..n {
            let s = observed_map(&reader, 2000).unwrap();
            std::hint::black_box(s);
        }
        let observed = t.elapsed() / n;
        let t = Instant::now();
        for _ in 0..n {
            std::hint::black_box(
                predicted_map(&reader, froctomap_core::Timestamp::from_secs(1_454_500_000))
                    .unwrap(),
            );
        }
        let predicted = t.elapsed() / n;
        let t = Instant::now();
        for _ in 0..n {
            std::hint::black_box(froctomap_octomap_ffi::OcTree::read_binary(&bt).unwrap());
        }
        let upstream = t.elapsed() / n;
        println!("retrieve+encode {retrieve:?}, observed map {observed:?}, predicted map {predicted:?}, upstream read {upstream:?}");
    }
}
