//! `append-cost` without `--series`: the series generated in this process and recorded, as
//! `froctomap generate --stream | froctomap record` would, without the pipe or any map on
//! disk. One file is recorded from the start; at each base's length it is copied (the
//! base), and the `--hours` of maps right after each base are kept in memory as `.bt`
//! bytes, then recorded into fresh copies of their base, in rounds, timed. With
//! `--same-maps`, every base gets the hours after the longest instead: the same maps, but
//! after a gap of the difference, which the shorter files answer as `record` would, by
//! compacting when their span has doubled.

use crate::generate::step_seconds;
use crate::system::copy_file as copy;
use crate::tables::median_duration;
use anyhow::{bail, Context as _, Result};
use clap::Args;
use froctomap_convert::{
    group_thousands, CommitEvery, Context, RecordEvent, RecordOptions, RecordSummary, Recorder,
};
use froctomap_core::Timestamp;
use froctomap_file::LivingReader;
use froctomap_formats::ReadOptions;
use froctomap_synth::{encode_series, Generator, SeriesSpec, SpecOverrides, SynthError};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver};
use std::time::{Duration, Instant};

/// Options of `append-cost` without `--series`.
#[derive(Args, Debug)]
pub struct GeneratedArgs {
    /// Without --series: the time between generated maps.
    #[arg(long, default_value = "5s")]
    step: String,
    /// Without --series: the seed of the generated series (`froctomap generate --seed`).
    #[arg(long, default_value_t = 5)]
    seed: u64,
    /// Without --series: the real map the series is made from.
    #[arg(long, default_value = froctomap_synth::DEBIAN_GEB079, value_name = "FILE")]
    base_map: PathBuf,
    /// Without --series: when the recorder commits, a number of maps or a duration, as
    /// `froctomap record --commit-every` (the bases and the appends timed alike).
    #[arg(long, default_value = "5s", value_name = "N|DURATION")]
    commit_every: CommitEvery,
    /// Without --series: append the hours after the longest base to every base (the same
    /// maps) instead of the hours right after each base.
    #[arg(long)]
    same_maps: bool,
}

/// What to measure (`append-cost`'s options but the generator's).
pub struct Plan<'a> {
    /// Where the bases and their copies go.
    pub work: &'a Path,
    /// Lengths of the bases in days.
    pub base_days: &'a [f64],
    /// Hours of maps recorded into each base.
    pub hours: f64,
    /// Recordings per base.
    pub reps: usize,
}

/// A map's time and its `.bt` bytes.
type Map = (Timestamp, Vec<u8>);

/// A base recorded for the appends.
struct Base {
    days: f64,
    path: PathBuf,
    maps: usize,
    bytes: u64,
    segments: usize,
}

/// What `froctomap record` does with the default options but `--commit-every`.
fn record_options(args: &GeneratedArgs) -> RecordOptions {
    RecordOptions {
        commit_every: args.commit_every,
        ..RecordOptions::default()
    }
}

/// The office of `froctomap generate --step STEP --seed SEED --days DAYS`.
fn generator(context: &Context, args: &GeneratedArgs, days: f64) -> Result<Generator> {
    let base = context
        .formats()
        .read_file(&args.base_map, ReadOptions::default())
        .with_context(|| format!("reading the base map {}", args.base_map.display()))?
        .map
        .snapshot
        .to_max_likelihood();
    let spec = SpecOverrides {
        step_secs: Some(step_seconds(&args.step)?),
        days: Some(days),
        seed: Some(args.seed),
        ..SpecOverrides::default()
    }
    .apply(SeriesSpec::default())?;
    Ok(Generator::new(&base, spec, None)?)
}

pub fn recorded_append_cost(
    context: &Context,
    args: &Plan<'_>,
    generated: &GeneratedArgs,
) -> Result<()> {
    let mut base_days = args.base_days.to_vec();
    base_days.sort_by(f64::total_cmp);
    let longest = *base_days.last().context("no --base-days")?;
    let generator = generator(context, generated, longest + args.hours / 24.0)?;
    let hours = Duration::from_secs_f64(args.hours * 3600.0);
    let start = generator
        .frames()
        .next()
        .context("the generated series has no map")?
        .time;
    let at = |days: f64| Timestamp(start.0 + (days * 86_400e9) as i64);
    std::fs::create_dir_all(args.work)?;
    let frames = generator.frames().count();
    eprintln!(
        "generating {} maps (every {}, seed {}) and recording the bases",
        group_thousands(frames as u64),
        generated.step,
        generated.seed
    );
    let started = Instant::now();
    let (bases, new) = std::thread::scope(|scope| -> Result<_> {
        let (send, maps) = sync_channel::<Map>(64);
        let generator = &generator;
        let producer = scope.spawn(move || {
            encode_series(
                context.formats(),
                generator,
                "bt",
                0,
                &|_, _| {},
                &mut |frame, bytes, _| {
                    send.send((frame.time, bytes))
                        .map_err(|_| SynthError::Sink("the recorder stopped".into()))
                },
            )
        });
        let boundaries: Vec<(f64, Timestamp)> = base_days.iter().map(|&d| (d, at(d))).collect();
        let recorded = record_bases(context, args.work, generated, &boundaries, hours, maps);
        let generated = producer
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        match (recorded, generated) {
            (Ok(recorded), Ok(())) => Ok(recorded),
            // The generator stopped because the recorder did: the recorder's error says why.
            (Err(error), Ok(()) | Err(SynthError::Sink(_))) => Err(error),
            // The recorder ran out of maps because the generator failed.
            (_, Err(error)) => Err(error.into()),
        }
    })?;
    eprintln!(
        "generated and recorded in {:.0} s",
        started.elapsed().as_secs_f64()
    );
    let appended = |k: usize| {
        if generated.same_maps {
            &new[new.len() - 1]
        } else {
            &new[k]
        }
    };
    let count = appended(0).len();
    if (0..bases.len()).any(|k| appended(k).len() != count || count == 0) {
        bail!("the bases have not the same number of maps after them: shorten --hours");
    }
    println!(
        "recording the {} maps ({} h) after {} into copies of each base (commits every {}), {} times",
        count,
        args.hours,
        if generated.same_maps { "the longest base" } else { "each base" },
        generated.commit_every,
        args.reps
    );
    let mut times: Vec<Vec<Duration>> = vec![Vec::new(); bases.len()];
    let mut summaries = vec![RecordSummary::default(); bases.len()];
    for round in 0..args.reps {
        for (k, base) in bases.iter().enumerate() {
            let (elapsed, summary) = time_record(context, generated, &base.path, appended(k))?;
            eprintln!(
                "round {round}, {} d: {:.3} s ({} commits, {} compactions)",
                base.days,
                elapsed.as_secs_f64(),
                summary.commits,
                summary.compactions
            );
            times[k].push(elapsed);
            summaries[k] = summary;
        }
    }
    print_table(&bases, times, &summaries, count);
    Ok(())
}

/// Records the maps before the longest base into one file, copying it to a base at each
/// boundary (the recorder finished first, so that the copy is what a `record` run of that
/// length leaves); returns the bases and, for each, the maps within `hours` after it.
fn record_bases(
    context: &Context,
    work: &Path,
    generated: &GeneratedArgs,
    boundaries: &[(f64, Timestamp)],
    hours: Duration,
    maps: Receiver<Map>,
) -> Result<(Vec<Base>, Vec<Vec<Map>>)> {
    let growing = work.join("recorded.froct");
    std::fs::remove_file(&growing).ok();
    let open = || -> Result<Recorder<'_>> {
        let mut recorder = Recorder::open(context, &growing, record_options(generated))?;
        recorder.on_event(|event| {
            if let RecordEvent::Compacted(report) = event {
                eprintln!(
                    "  compacted: {} samples, {} bytes",
                    group_thousands(u64::from(report.samples)),
                    group_thousands(report.bytes)
                );
            }
        });
        Ok(recorder)
    };
    let mut recorder = Some(open()?);
    let mut bases = Vec::new();
    let mut after: Vec<Vec<Map>> = vec![Vec::new(); boundaries.len()];
    let mut taken = 0usize;
    let started = Instant::now();
    for (time, bytes) in maps {
        while let Some(&(days, boundary)) = boundaries.get(bases.len()) {
            if time < boundary {
                break;
            }
            if let Some(recorder) = recorder.take() {
                recorder.finish()?;
            }
            let path = work.join(format!("base-{days}d.froct"));
            copy(&growing, &path)?;
            let segments = LivingReader::open(&path)?.segment_count();
            let bytes = std::fs::metadata(&path)?.len();
            eprintln!(
                "base of {days} d: {} maps, {} bytes, {segments} segments ({:.0} s)",
                group_thousands(taken as u64),
                group_thousands(bytes),
                started.elapsed().as_secs_f64()
            );
            bases.push(Base {
                days,
                path,
                maps: taken,
                bytes,
                segments,
            });
            if bases.len() < boundaries.len() {
                recorder = Some(open()?);
            }
        }
        for (&(_, boundary), after) in boundaries.iter().zip(&mut after) {
            let offset = u64::try_from(time.0 - boundary.0).ok();
            if offset.is_some_and(|ns| ns < hours.as_nanos() as u64) {
                after.push((time, bytes.clone()));
            }
        }
        if let Some(recorder) = &mut recorder {
            recorder.take_bytes(time, &bytes)?;
            taken += 1;
            if taken % 17_280 == 0 {
                eprintln!(
                    "  {} maps recorded ({:.0} s)",
                    group_thousands(taken as u64),
                    started.elapsed().as_secs_f64()
                );
            }
        }
    }
    std::fs::remove_file(&growing).ok();
    if bases.len() < boundaries.len() {
        bail!(
            "the generated series ended before day {}",
            boundaries[bases.len()].0
        );
    }
    Ok((bases, after))
}

/// Records `maps` into a copy of `base` as `froctomap record` does; the wall time from
/// opening to the last commit (and any compaction it triggered).
fn time_record(
    context: &Context,
    args: &GeneratedArgs,
    base: &Path,
    maps: &[Map],
) -> Result<(Duration, RecordSummary)> {
    let work = base.with_extension("work.froct");
    copy(base, &work)?;
    let started = Instant::now();
    let mut recorder = Recorder::open(context, &work, record_options(args))?;
    for (time, bytes) in maps {
        recorder.take_bytes(*time, bytes)?;
    }
    let summary = recorder.finish()?;
    let elapsed = started.elapsed();
    std::fs::remove_file(&work).ok();
    if summary.committed_maps != maps.len() {
        bail!(
            "{} of {} maps committed into {}",
            summary.committed_maps,
            maps.len(),
            base.display()
        );
    }
    Ok((elapsed, summary))
}

fn print_table(bases: &[Base], times: Vec<Vec<Duration>>, summaries: &[RecordSummary], n: usize) {
    println!("| base | maps | file bytes | segments | record (median) | maps/s | commits | compactions |");
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    let mut medians = Vec::new();
    for ((base, times), summary) in bases.iter().zip(times).zip(summaries) {
        let median = median_duration(&times);
        println!(
            "| {} d | {} | {} | {} | {:.3} s | {:.0} | {} | {} |",
            base.days,
            base.maps,
            base.bytes,
            base.segments,
            median.as_secs_f64(),
            n as f64 / median.as_secs_f64(),
            summary.commits,
            summary.compactions
        );
        medians.push((base.days, median));
    }
    if let (Some(first), Some(last)) = (medians.first(), medians.last()) {
        println!(
            "ratio {} d / {} d: {:.2}×",
            last.0,
            first.0,
            last.1.as_secs_f64() / first.1.as_secs_f64()
        );
    }
}
