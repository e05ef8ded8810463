#![allow(missing_docs, clippy::unwrap_used)]
use froctomap_core::{Occupancy, Timestamp};
use froctomap_temporal::models::*;
use froctomap_temporal::*;
use std::time::Instant;
fn main() {
    let n = 100_000u32;
    let step_ns = 28 * 86_400 * 1_000_000_000i64 / i64::from(n);
    let axis = TimeAxis::regular(Timestamp(0), step_ns, n, vec![]).unwrap();
    let mut b = ObservationsBuilder::new();
    let mut rng = 12345u64;
    for i in 0..n {
        rng ^= rng << 13; rng ^= rng >> 7; rng ^= rng << 17;
        let t = f64::from(i) * step_ns as f64 / 1e9;
        let hour = (t / 3600.0) % 24.0;
        let weekday = (t / 86_400.0) % 7.0 < 5.0;
        let s = (weekday && (8.0..18.0).contains(&hour)) ^ (rng % 50 == 0);
        b.push(i, Some(if s { Occupancy::Occupied } else { Occupancy::Free })).unwrap();
    }
    let obs = b.finish();
    println!("runs {}", obs.runs().len());
    let reg = FremenRegular.prepare_regular(&axis, &ModelConfig::default()).unwrap();
    let per = FremenPeriods.prepare_periods(&axis, &ModelConfig::default()).unwrap();
    reg.spectrum(&obs).unwrap(); per.spectrum(&obs).unwrap();
    let reps = 200;
    let t = Instant::now(); for _ in 0..reps { reg.spectrum(&obs).unwrap(); } println!("reg spectrum {:.3} ms", t.elapsed().as_secs_f64()*1e3/reps as f64);
    let t = Instant::now(); for _ in 0..reps { per.spectrum(&obs).unwrap(); } println!("per spectrum {:.3} ms", t.elapsed().as_secs_f64()*1e3/reps as f64);
    for order in [Order::Fixed(0), Order::Fixed(1), Order::Fixed(3), Order::Fixed(5), Order::Auto{max:5}] {
        for (name, m) in [("reg", &reg as &dyn PreparedModel), ("per", &per)] {
            let cfg = ModelConfig::default().with_order(order);
            let mm = if name == "reg" { FremenRegular.prepare(&axis, &cfg).unwrap() } else { FremenPeriods.prepare(&axis, &cfg).unwrap() };
            let _ = m;
            mm.fit(&obs).unwrap();
            let t = Instant::now(); let mut v = None; for _ in 0..reps/4 { v = Some(mm.fit(&obs).unwrap()); }
            let v = v.unwrap();
            println!("{name} {order:?} fit {:.3} ms order {} toggles {} errors {:?}", t.elapsed().as_secs_f64()*1e3/(reps/4) as f64, v.order(), v.toggles().len(), v.model_errors());
        }
    }
}
