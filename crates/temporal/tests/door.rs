//! The real office door (`shared/data/greg_door_2016_min`): FreMEn must predict held-out
//! weeks better than the static mean, and lossless mode must reproduce all ten training weeks.

mod common;

use common::door;
use froctomap_temporal::{ModelConfig, ModelRegistry, Order, OutlierMode, TemporalModel};

#[test]
fn fremen_beats_static_mean_rmse_on_held_out_weeks() {
    let data = door::load().expect("door data beside the checkout (../shared)");
    assert_eq!(data.weeks.len(), 4);
    assert!(data.weeks.iter().all(|w| w.len() > 9000));
    let rows = door::evaluate_all(&data).unwrap();
    let baseline = &rows[0];
    assert_eq!(baseline.label, "static");
    for row in &rows[1..] {
        for (week, (s, b)) in row.scores.iter().zip(&baseline.scores).enumerate() {
            assert!(
                s.rmse < b.rmse,
                "{} week {}: RMSE {:.4} not below static {:.4}",
                row.label,
                week + 1,
                s.rmse,
                b.rmse
            );
        }
    }
}

#[test]
fn lossless_reproduces_the_training_weeks() {
    let data = door::load().expect("door data beside the checkout (../shared)");
    let registry = ModelRegistry::with_default_models();
    let cases: [(
        &str,
        &froctomap_temporal::TimeAxis,
        &froctomap_temporal::VoxelObservations,
    ); 3] = [
        ("static", &data.regular_axis, &data.regular_obs),
        ("fremen-regular", &data.regular_axis, &data.regular_obs),
        ("fremen-periods", &data.explicit_axis, &data.explicit_obs),
    ];
    for (name, axis, obs) in cases {
        let model: Box<dyn TemporalModel> = registry.by_name(name).unwrap().create();
        for order in [Order::Fixed(3), Order::Auto { max: 5 }] {
            let config = if name == "static" {
                ModelConfig::default() // the mean only: no order
            } else {
                order.apply(ModelConfig::default())
            };
            let prepared = model.prepare(axis, &config).unwrap();
            let voxel = prepared.fit(obs).unwrap();
            let mut bytes = Vec::new();
            prepared.encode_voxel(&voxel, &mut bytes);
            let reader = registry
                .prepare_from_parameters(model.id(), axis, &prepared.encode_parameters())
                .unwrap();
            assert_eq!(reader.outlier_mode(), OutlierMode::Lossless);
            let (decoded, used) = reader.decode_voxel(&bytes).unwrap();
            assert_eq!(used, bytes.len());
            let wrong = obs
                .iter()
                .filter(|&(i, s)| reader.state_at_sample(&decoded, i) != s)
                .count();
            assert_eq!(wrong, 0, "{name} {order:?}");
            // Far smaller than one bit per observed minute.
            assert!(
                bytes.len() * 8 < obs.observed_count() as usize / 4,
                "{name}: {} bytes",
                bytes.len()
            );
        }
    }
}
