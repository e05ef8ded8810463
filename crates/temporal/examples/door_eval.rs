//! Trains on the real office-door series and prints, for held-out weeks 1–4, the RMSE of
//! `p(t)` and the binary error of the static mean and FreMEn at orders 1–5, as markdown.
//!
//! `cargo run --release -p froctomap-temporal --example door_eval`

#[path = "../tests/common/door.rs"]
mod door;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let data = door::load()?;
    let rows = door::evaluate_all(&data)?;
    println!(
        "Training: {} observed minutes over {} grid samples; held-out weeks 1-4.\n",
        data.regular_obs.observed_count(),
        data.regular_axis.len()
    );
    let weeks = data.weeks.len();
    print!("| model |");
    for w in 1..=weeks {
        print!(" week {w} RMSE | week {w} binary |");
    }
    println!();
    print!("|---|");
    for _ in 0..weeks {
        print!("---|---|");
    }
    println!();
    for row in &rows {
        print!("| {} |", row.label);
        for s in &row.scores {
            print!(" {:.4} | {:.2}% |", s.rmse, 100.0 * s.binary);
        }
        println!();
    }
    Ok(())
}
