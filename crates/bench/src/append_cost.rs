//! `froctomap-bench append-cost`: what adding the same maps costs as a file's history grows
//! (issue 26). The same `--hours` of maps, right after the longest base, are appended to
//! files built on the first `--base-days` (each a plain 1.2 build) `--reps` times each (in
//! rounds over the bases, so that the machine's load touches all alike), in
//! two ways measured in the same run: as one format 2.0 segment (`append_segment`: the
//! base converted beforehand, outside the timing) and by the 1.x rebuild-append (`append`:
//! every cell refitted on its whole history). Prints the median wall time of each and the
//! ratio of the longest base's median to the shortest's.
//!
//! Without `--series` the series is generated in this process (the FR-079 office of
//! `froctomap generate`, every `--step`, seed `--seed`; no map on disk) and the bases are
//! what `froctomap record` makes of it (commits every `--commit-every`, automatic
//! compaction on; each base a copy of the one file recorded from the start). The maps
//! after the longest base are then recorded into copies of each base as `record` does
//! (its `Recorder`, the maps taken as bytes, commits and any compaction they trigger all
//! timed): median wall time, maps per second, ratio.

use anyhow::{bail, Context as _, Result};
use clap::Args;
use froctomap_convert::{
    append, append_segment, build, collect_inputs, AppendOptions, BuildOptions, Context,
    SeriesInput, Silent, TimeSource,
};
use froctomap_file::LivingWriter;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

mod recorded;
use crate::system::copy_file as copy;
use crate::tables::median_duration;
use recorded::{recorded_append_cost, GeneratedArgs, Plan};

/// Options of `append-cost`.
#[derive(Args, Debug)]
pub struct AppendCostArgs {
    /// A generated series (its directory with manifest.csv, from `generate`), covering the
    /// longest base and the hours appended after it.
    /// Without it, the series is generated here (see --step).
    #[arg(long)]
    series: Option<PathBuf>,
    /// Where the bases and their copies go (created; a few files of the bases' size).
    #[arg(long)]
    work: PathBuf,
    /// Lengths of the bases, days from the series' start (comma-separated).
    #[arg(long, value_delimiter = ',', default_values_t = [1.0, 6.0])]
    base_days: Vec<f64>,
    /// Hours of maps appended, right after the longest base.
    #[arg(long, default_value_t = 2.0)]
    hours: f64,
    /// Appends per base and way.
    #[arg(long, default_value_t = 5)]
    reps: usize,
    #[command(flatten)]
    generated: GeneratedArgs,
}

/// Times one append of `new` to a copy of `base` as a segment (the copy converted to 2.0
/// beforehand, outside the timing), then one as a rebuild; with the bytes each added.
fn time_appends(
    context: &Context,
    base: &Path,
    new: &[SeriesInput],
) -> Result<(Duration, Duration, [i64; 2])> {
    let options = AppendOptions::default();
    let work = base.with_extension("work.froct");
    copy(base, &work)?;
    LivingWriter::convert(&work, &work)?;
    let started = Instant::now();
    let mut writer = LivingWriter::open(&work)?;
    let report = append_segment(context, &mut writer, new, &options, &Silent)?;
    drop(writer);
    let segment = started.elapsed();
    if report.added != new.len() {
        bail!("{} of {} maps added", report.added, new.len());
    }
    copy(base, &work)?;
    let started = Instant::now();
    let rebuilt = append(context, &work, new, &options, &Silent)?;
    let rebuild = started.elapsed();
    std::fs::remove_file(&work).ok();
    let added = |after: u64, before: u64| after as i64 - before as i64;
    Ok((
        segment,
        rebuild,
        [
            added(report.file_bytes, report.bytes_before),
            added(rebuilt.file_bytes, rebuilt.bytes_before),
        ],
    ))
}

pub fn append_cost(args: &AppendCostArgs) -> Result<()> {
    let context = Context::with_default_plugins();
    let Some(series) = &args.series else {
        let plan = Plan {
            work: &args.work,
            base_days: &args.base_days,
            hours: args.hours,
            reps: args.reps,
        };
        return recorded_append_cost(&context, &plan, &args.generated);
    };
    let series = collect_inputs(&context, std::slice::from_ref(series), TimeSource::Auto)?;
    let start = series.first().context("an empty series")?.time;
    let at = |days: f64| start.0 + (days * 86_400e9) as i64;
    let longest = args.base_days.iter().copied().fold(0.0, f64::max);
    let (from, to) = (at(longest), at(longest + args.hours / 24.0));
    let new: Vec<SeriesInput> = series
        .iter()
        .filter(|i| (from..to).contains(&i.time.0))
        .cloned()
        .collect();
    if new.is_empty() {
        bail!(
            "the series has no map in the {} h after day {longest}",
            args.hours
        );
    }
    std::fs::create_dir_all(&args.work)?;
    println!(
        "appending {} maps ({} h after day {longest}), {} times per base",
        new.len(),
        args.hours,
        args.reps
    );
    let mut bases = Vec::new();
    for &days in &args.base_days {
        let inputs: Vec<SeriesInput> = series
            .iter()
            .filter(|i| i.time.0 < at(days))
            .cloned()
            .collect();
        let base = args.work.join(format!("base-{days}d.froct"));
        let started = Instant::now();
        let built = build(&context, &inputs, &base, &BuildOptions::default(), &Silent)?;
        bases.push((
            days,
            base,
            inputs.len(),
            built.file_bytes,
            started.elapsed(),
        ));
    }
    // Rounds over every base, so that a change in the machine's load touches all alike.
    let mut times: Vec<(Vec<Duration>, Vec<Duration>)> = vec![Default::default(); bases.len()];
    let mut added = vec![[0i64; 2]; bases.len()];
    for round in 0..args.reps {
        for (k, (days, base, ..)) in bases.iter().enumerate() {
            let (segment, rebuild, bytes) = time_appends(&context, base, &new)?;
            added[k] = bytes;
            eprintln!(
                "round {round}, {days} d: segment {:.3} s, rebuild {:.3} s",
                segment.as_secs_f64(),
                rebuild.as_secs_f64()
            );
            times[k].0.push(segment);
            times[k].1.push(rebuild);
        }
    }
    println!("| base | maps | file bytes | build s | segment append (median) | rebuild append (median) | bytes added: segment | bytes added: rebuild |");
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    let mut medians = Vec::new();
    for (((days, _, maps, bytes, build_time), (segment, rebuild)), added) in
        bases.iter().zip(times).zip(added)
    {
        let (segment, rebuild) = (median_duration(&segment), median_duration(&rebuild));
        println!(
            "| {days} d | {maps} | {bytes} | {:.1} | {:.3} s | {:.3} s | {} | {} |",
            build_time.as_secs_f64(),
            segment.as_secs_f64(),
            rebuild.as_secs_f64(),
            added[0],
            added[1]
        );
        medians.push((*days, segment, rebuild));
    }
    if let (Some(first), Some(last)) = (medians.first(), medians.last()) {
        println!(
            "ratio {} d / {} d: segment append {:.2}×, rebuild append {:.2}×",
            last.0,
            first.0,
            last.1.as_secs_f64() / first.1.as_secs_f64(),
            last.2.as_secs_f64() / first.2.as_secs_f64()
        );
    }
    Ok(())
}
