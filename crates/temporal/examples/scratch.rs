#![allow(missing_docs, clippy::unwrap_used)]
use froctomap_core::{Occupancy, Timestamp};
use froctomap_temporal::*;
fn main() {
    let step = 600_000_000_000;
    let axis = TimeAxis::regular(Timestamp::from_secs(0), step, 3 * 7 * 144, vec![]).unwrap();
    let mut b = ObservationsBuilder::new();
    for i in 0..axis.len() {
        let (day, slot) = (i / 144, i % 144);
        let state = (day % 7 < 5 && (48..108).contains(&slot)) ^ (i % 97 == 0);
        let known = day != 3;
        b.push(
            i,
            known.then_some(if state {
                Occupancy::Occupied
            } else {
                Occupancy::Free
            }),
        )
        .unwrap();
    }
    let obs = b.finish();
    let registry = ModelRegistry::with_default_models();
    for name in ["static", "fremen-regular", "fremen-periods"] {
        for order in [
            Order::Auto { max: 5 },
            Order::Fixed(1),
            Order::Fixed(3),
            Order::Fixed(5),
        ] {
            let model = registry.by_name(name).unwrap().create();
            let prepared = model
                .prepare(&axis, &ModelConfig::default().with_order(order))
                .unwrap();
            let voxel = prepared.fit(&obs).unwrap();
            let mut bytes = Vec::new();
            prepared.encode_voxel(&voxel, &mut bytes);
            let monday_noon = (21.0 * 86_400.0) + 12.0 * 3600.0;
            println!("{name} {order:?}: mean {:.3} comps {:?} toggles {} bytes {} errors {:?} p(mon)={:.3} p(sun)={:.3}",
                voxel.mean(), voxel.components(), voxel.toggles().len(), bytes.len(), voxel.model_errors(),
                prepared.probability(&voxel, monday_noon), prepared.probability(&voxel, monday_noon + 6.0*86400.0));
        }
    }
}
