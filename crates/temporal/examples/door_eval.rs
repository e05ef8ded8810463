//! Trains on the real office-door series and prints, for held-out weeks 1–4, the RMSE of
//! `p(t)` and the binary error of the static mean and FreMEn at orders 1–5 (plus the
//! held-out auto order), and the lossless encoding of the training weeks, as markdown.
//!
//! `cargo run --release -p froctomap-temporal --example door_eval`

#[path = "../tests/common/door.rs"]
mod door;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let data = door::load()?;
    let rows = door::evaluate_all(&data)?;
    println!(
        "Training: {} observed minutes ({} grid samples, {} missing); held-out weeks 1-4.\n",
        data.regular_obs.observed_count(),
        data.regular_axis.len(),
        data.regular_axis.missing().len()
    );
    let weeks = data.weeks.len();
    print!("| model |");
    for w in 1..=weeks {
        print!(" wk{w} RMSE | wk{w} binary |");
    }
    println!();
    print!("|---|");
    for _ in 0..weeks {
        print!("---:|---:|");
    }
    println!();
    let baseline = rows.first().map(|r| r.scores.clone()).unwrap_or_default();
    for (k, row) in rows.iter().enumerate() {
        print!("| {} |", row.label);
        for (s, b) in row.scores.iter().zip(&baseline) {
            let mark = if k == 0 || s.rmse < b.rmse {
                ""
            } else {
                " (not below static)"
            };
            print!(" {:.4}{mark} | {:.2}% |", s.rmse, 100.0 * s.binary);
        }
        println!();
    }

    println!(
        "\nLossless encoding of the {} training samples (1 bit each = {} bytes):\n",
        data.regular_obs.observed_count(),
        data.regular_obs.observed_count().div_ceil(8)
    );
    println!("| model, order | kept | bytes | toggles | lossy errors | periods (h) |");
    println!("|---|---:|---:|---:|---:|---|");
    for e in door::encodings(&data)? {
        let periods: Vec<String> = e
            .components
            .iter()
            .map(|p| format!("{:.1}", p / 3600.0))
            .collect();
        println!(
            "| {} | {} | {} | {} | {} | {} |",
            e.label,
            e.order,
            e.bytes,
            e.toggles,
            e.model_errors,
            periods.join(", ")
        );
    }
    Ok(())
}
