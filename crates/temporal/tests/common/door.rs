//! Loader and evaluation of the real office-door series (`shared/data/greg_door_2016_min`),
//! shared by the door test and the `door_eval` example.

#![allow(dead_code)]

use froctomap_core::{Occupancy, Timestamp};
use froctomap_temporal::{
    ModelConfig, ObservationsBuilder, Order, OutlierMode, PreparedModel, TemporalModel, TimeAxis,
    VoxelObservations,
};
use std::error::Error;
use std::path::PathBuf;

/// Folder of the door data, beside the checkout.
pub fn data_dir() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/greg_door_2016_min"
    ))
}

/// The training series on both kinds of axis, plus held-out weeks.
pub struct Door {
    /// Regular one-minute grid over the training weeks, the outage listed as missing.
    pub regular_axis: TimeAxis,
    /// The training timestamps as they are.
    pub explicit_axis: TimeAxis,
    /// Observations on the regular axis.
    pub regular_obs: VoxelObservations,
    /// Observations on the explicit axis.
    pub explicit_obs: VoxelObservations,
    /// Held-out weeks 1..=4: (seconds since the training start, occupied?) pairs.
    pub weeks: Vec<Vec<(f64, bool)>>,
}

fn parse_state(s: &str) -> Result<bool, Box<dyn Error>> {
    match s.trim() {
        "0" => Ok(false),
        "1" => Ok(true),
        other => Err(format!("bad state {other:?}").into()),
    }
}

fn occupancy(b: bool) -> Occupancy {
    Occupancy::from(b)
}

/// Loads the training data and held-out weeks `1..=4`.
pub fn load() -> Result<Door, Box<dyn Error>> {
    let dir = data_dir();
    let text = std::fs::read_to_string(dir.join("training_data.txt"))?;
    let mut samples = Vec::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let mut parts = line.split_whitespace();
        let t: i64 = parts.next().ok_or("missing time")?.parse()?;
        let s = parse_state(parts.next().ok_or("missing state")?)?;
        samples.push((t, s));
    }
    let (t0, _) = *samples.first().ok_or("no training data")?;
    let (t_last, _) = *samples.last().ok_or("no training data")?;
    let step = 60;
    let count = u32::try_from((t_last - t0) / step + 1)?;
    let mut present = vec![false; count as usize];
    let mut regular = ObservationsBuilder::new();
    let mut explicit = ObservationsBuilder::new();
    for (k, &(t, s)) in samples.iter().enumerate() {
        if (t - t0) % step != 0 {
            return Err("training time off the one-minute grid".into());
        }
        let i = u32::try_from((t - t0) / step)?;
        present[i as usize] = true;
        regular.push(i, Some(occupancy(s)))?;
        explicit.push(u32::try_from(k)?, Some(occupancy(s)))?;
    }
    let missing = (0..count).filter(|&i| !present[i as usize]).collect();
    let regular_axis = TimeAxis::regular(
        Timestamp::from_secs(t0),
        step * 1_000_000_000,
        count,
        missing,
    )?;
    let explicit_axis = TimeAxis::explicit(
        samples
            .iter()
            .map(|&(t, _)| Timestamp::from_secs(t))
            .collect(),
    )?;
    let mut weeks = Vec::new();
    for k in 1..=4 {
        let times = std::fs::read_to_string(dir.join(format!("test_times_{k}.txt")))?;
        let states = std::fs::read_to_string(dir.join(format!("test_data_{k}.txt")))?;
        let mut week = Vec::new();
        for (t, s) in times
            .lines()
            .filter(|l| !l.trim().is_empty())
            .zip(states.lines().filter(|l| !l.trim().is_empty()))
        {
            let t: i64 = t.trim().parse()?;
            week.push(((t - t0) as f64, parse_state(s)?));
        }
        weeks.push(week);
    }
    Ok(Door {
        regular_axis,
        explicit_axis,
        regular_obs: regular.finish(),
        explicit_obs: explicit.finish(),
        weeks,
    })
}

/// RMSE of `p(t)` and binary error rate of `p(t) > 0.5` over one held-out week.
#[derive(Debug, Clone, Copy)]
pub struct Score {
    pub rmse: f64,
    pub binary: f64,
}

/// Scores a fitted voxel on a held-out week.
pub fn score(
    model: &dyn PreparedModel,
    voxel: &froctomap_temporal::FittedVoxel,
    week: &[(f64, bool)],
) -> Score {
    let mut sq = 0.0;
    let mut wrong = 0usize;
    for &(t, s) in week {
        let p = model.probability(voxel.parameters(), t);
        let target = if s { 1.0 } else { 0.0 };
        sq += (p - target) * (p - target);
        if (p > 0.5) != s {
            wrong += 1;
        }
    }
    let n = week.len().max(1) as f64;
    Score {
        rmse: (sq / n).sqrt(),
        binary: wrong as f64 / n,
    }
}

/// One evaluated model: a label and its score on each held-out week.
pub struct Row {
    pub label: String,
    pub scores: Vec<Score>,
}

/// Fits `model` at `order` (`None`: a model without orders; lossy, since the outliers do
/// not affect prediction) and scores it.
pub fn evaluate(
    label: String,
    model: &dyn TemporalModel,
    axis: &TimeAxis,
    obs: &VoxelObservations,
    order: Option<Order>,
    weeks: &[Vec<(f64, bool)>],
) -> Result<Row, Box<dyn Error>> {
    let config = ModelConfig::default().with_outliers(OutlierMode::Lossy);
    let config = match order {
        Some(order) => order.apply(config),
        None => config,
    };
    let prepared = model.prepare(axis, &config)?;
    let voxel = prepared.fit(obs)?;
    let scores = weeks
        .iter()
        .map(|w| score(prepared.as_ref(), &voxel, w))
        .collect();
    Ok(Row { label, scores })
}

/// Every row of the evaluation: static, FreMEn regular orders 1..=5, FreMEn periods on the
/// explicit (irregular-capable) axis orders 1..=5.
pub fn evaluate_all(door: &Door) -> Result<Vec<Row>, Box<dyn Error>> {
    use froctomap_temporal::models::{FremenPeriods, FremenRegular, StaticMean};
    let mut rows = vec![evaluate(
        "static".into(),
        &StaticMean,
        &door.regular_axis,
        &door.regular_obs,
        None,
        &door.weeks,
    )?];
    for n in 1..=5 {
        rows.push(evaluate(
            format!("fremen-regular {n}"),
            &FremenRegular,
            &door.regular_axis,
            &door.regular_obs,
            Some(Order::Fixed(n)),
            &door.weeks,
        )?);
    }
    rows.push(evaluate(
        "fremen-regular auto (held-out, max 5)".into(),
        &FremenRegular,
        &door.regular_axis,
        &door.regular_obs,
        Some(Order::Auto { max: 5 }),
        &door.weeks,
    )?);
    for n in 1..=5 {
        rows.push(evaluate(
            format!("fremen-periods {n}"),
            &FremenPeriods,
            &door.explicit_axis,
            &door.explicit_obs,
            Some(Order::Fixed(n)),
            &door.weeks,
        )?);
    }
    rows.push(evaluate(
        "fremen-periods auto (held-out, max 5)".into(),
        &FremenPeriods,
        &door.explicit_axis,
        &door.explicit_obs,
        Some(Order::Auto { max: 5 }),
        &door.weeks,
    )?);
    Ok(rows)
}

/// Lossless encoding of the training weeks by one model and order.
pub struct Encoding {
    pub label: String,
    pub order: usize,
    pub bytes: usize,
    pub toggles: usize,
    pub model_errors: u64,
    pub components: Vec<f64>,
}

/// Encodes the training series losslessly with each model (fixed order 3 and auto).
pub fn encodings(door: &Door) -> Result<Vec<Encoding>, Box<dyn Error>> {
    use froctomap_temporal::models::{FremenPeriods, FremenRegular, StaticMean};
    let cases: [(&str, &dyn TemporalModel, &TimeAxis, &VoxelObservations); 3] = [
        ("static", &StaticMean, &door.regular_axis, &door.regular_obs),
        (
            "fremen-regular",
            &FremenRegular,
            &door.regular_axis,
            &door.regular_obs,
        ),
        (
            "fremen-periods",
            &FremenPeriods,
            &door.explicit_axis,
            &door.explicit_obs,
        ),
    ];
    let mut out = Vec::new();
    for (name, model, axis, obs) in cases {
        let orders: &[Order] = if name == "static" {
            &[Order::Fixed(0)]
        } else {
            &[
                Order::Fixed(1),
                Order::Fixed(3),
                Order::Fixed(5),
                Order::Auto { max: 5 },
            ]
        };
        for &order in orders {
            let config = if name == "static" {
                ModelConfig::default() // the mean only: no order option
            } else {
                order.apply(ModelConfig::default())
            };
            let prepared = model.prepare(axis, &config)?;
            let voxel = prepared.fit(obs)?;
            let mut bytes = Vec::new();
            prepared.encode_voxel(&voxel, &mut bytes);
            let periods: Vec<f64> = prepared
                .describe(voxel.parameters())?
                .periodic
                .iter()
                .map(|c| c.period_seconds)
                .collect();
            out.push(Encoding {
                label: format!("{name} {order:?}"),
                order: periods.len(),
                bytes: bytes.len(),
                toggles: voxel.toggles().len(),
                model_errors: voxel.model_errors().unwrap_or(0),
                components: periods,
            });
        }
    }
    Ok(out)
}
