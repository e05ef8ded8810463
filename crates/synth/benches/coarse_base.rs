//! Setting up a generator on degenerate bases: the whole tree as one coarse leaf (free or
//! occupied), which must be handled without walking its 2^48 voxels. Prints the time of
//! `Generator::new` per case as a markdown table.
//!
//! `cargo bench -p froctomap-synth`. The unit test `degenerate_maps_give_warnings_not_hangs`
//! checks the behaviour; this only measures it (timings are never asserted).

use froctomap_core::{Leaf, MortonCode, Occupancy, Snapshot};
use froctomap_synth::{Generator, SeriesSpec};
use std::error::Error;
use std::time::Instant;

fn main() -> Result<(), Box<dyn Error>> {
    let spec = SeriesSpec {
        count: 2,
        partial_probability: 0.0,
        ..SeriesSpec::default()
    };
    println!("| base | Generator::new | warnings |");
    println!("| --- | ---: | ---: |");
    for state in [Occupancy::Free, Occupancy::Occupied] {
        let root = Snapshot::from_leaves(
            0.1,
            vec![Leaf {
                start: MortonCode(0),
                depth: 0,
                log_odds: state.log_odds(),
            }],
        )?;
        let started = Instant::now();
        let generator = Generator::new(&root, spec.clone(), None)?;
        let elapsed = started.elapsed();
        println!(
            "| one {state} leaf at depth 0 | {:.1} ms | {} |",
            elapsed.as_secs_f64() * 1e3,
            generator.warnings().len()
        );
    }
    Ok(())
}
