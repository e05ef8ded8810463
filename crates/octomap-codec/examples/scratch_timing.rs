#![allow(missing_docs, clippy::unwrap_used)]
use froctomap_octomap_codec::*;
use std::time::Instant;
fn main() {
    let bytes = std::fs::read("/usr/share/doc/liboctomap-dev/examples/data/geb079.bt").unwrap();
    for _ in 0..3 {
        let t = Instant::now();
        let mut n = 0u64;
        scan(&bytes, None, ReadLimits::default(), &mut |_l| n += 1).unwrap();
        let a = t.elapsed();
        let t = Instant::now();
        let d = decode(&bytes, None, ReadLimits::default()).unwrap();
        let b = t.elapsed();
        let t = Instant::now();
        let s = froctomap_core::Snapshot::from_leaves(0.08, d.leaves).unwrap();
        let c = t.elapsed();
        let t = Instant::now();
        let e = encode_binary(&s);
        let e2 = t.elapsed();
        let t = Instant::now();
        let f = encode_full(&s);
        let f2 = t.elapsed();
        println!("scan {a:?} decode {b:?} from_leaves {c:?} enc_bt {e2:?} enc_ot {f2:?} {n} {} {}", e.len(), f.len());
    }
}
