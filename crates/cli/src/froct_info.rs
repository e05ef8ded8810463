//! `info` of a FROctomap file: its header, axis, model, cell classes and sizes.

use crate::ui::{escaped, Ui};
use anyhow::Result;
use froctomap_convert::{describe_series, group_thousands, ClassCounts, FroctInfo};
use serde_json::Value;
use std::path::Path;

/// The FROctomap file at `path` described on standard output (as JSON with `json`).
pub fn froct_info(ui: &Ui, path: &Path, json: bool, count: bool) -> Result<()> {
    let file = ui.context.open_series(path)?;
    let info = describe_series(ui.context, &file, count)?;
    if json {
        outln!("{}", crate::ui::json_report(&info)?)?;
        return Ok(());
    }
    let n = group_thousands;
    outln!(
        "file:            {} ({} bytes, FROctomap {})",
        escaped(info.file.display()),
        n(info.size.file),
        info.version
    )?;
    if let Some(living) = &info.living {
        let samples: Vec<String> = living
            .segments
            .iter()
            .map(|s| n(u64::from(s.samples)))
            .collect();
        outln!(
            "living map:      base of {} samples ({} bytes) + {} segment(s){}; {} bytes committed (commit {})",
            n(u64::from(living.base_samples)),
            n(living.base_len),
            living.segments.len(),
            if samples.is_empty() {
                String::new()
            } else if samples.len() <= 8 {
                format!(" of {} samples", samples.join(", "))
            } else {
                format!(
                    " of {}, … {} samples (--json lists them)",
                    samples[..4].join(", "),
                    samples[samples.len() - 2..].join(", ")
                )
            },
            n(living.committed_len),
            living.sequence
        )?;
        if !living.segments.is_empty() {
            outln!(
                "                 cells and dynamics below describe the base; `froctomap compact` folds the segments in"
            )?;
        }
    }
    outln!(
        "resolution:      {} m, tiles of depth {} ({} tiles), {}",
        info.resolution_m,
        info.tile_depth,
        info.tiles,
        info.toggle_block.map_or_else(
            || "toggle lists whole".to_string(),
            |samples| format!("toggle lists in blocks of {samples} samples")
        )
    )?;
    let t = &info.time;
    outln!(
        "time:            {} .. {} ({:.1} days), {} samples{}{}",
        t.start,
        t.end,
        t.span_seconds / 86_400.0,
        n(u64::from(t.samples)),
        t.step_seconds
            .map_or_else(|| ", irregular".to_string(), |s| format!(" every {s} s")),
        if t.missing > 0 {
            format!(", {} missing", t.missing)
        } else {
            String::new()
        }
    )?;
    outln!(
        "model:           {} ({})",
        escaped(&info.model),
        escaped(info.outliers)
    )?;
    outln!("cells:           {}", class_counts(&info.cells))?;
    outln!("voxels:          {}", class_counts(&info.voxels))?;
    outln!(
        "size:            header {} + tiles {} + index {} bytes",
        n(info.size.header),
        n(info.size.tiles),
        n(info.size.index)
    )?;
    if let Value::Object(streams) = &info.size.raw_streams {
        let parts: Vec<String> = streams
            .iter()
            .map(|(k, v)| format!("{} {}", escaped(k), n(v.as_u64().unwrap_or(0))))
            .collect();
        outln!("raw streams:     {}", parts.join(", "))?;
    }
    if let (Some(files), Some(bytes), Some(ratio)) =
        (info.input_files, info.input_bytes, info.ratio_vs_inputs)
    {
        outln!(
            "compression:     {ratio:.1}x vs the {} input files ({} bytes)",
            n(files),
            n(bytes)
        )?;
    }
    outln!(
        "vs raw states:   {:.1}x (1 bit per voxel per sample)",
        info.ratio_vs_raw_states
    )?;
    print_dynamics(&info)?;
    if let Some(creator) = info.metadata.get("creator").and_then(Value::as_str) {
        let created = info.metadata.get("created").and_then(Value::as_str);
        outln!(
            "created:         {} by {}",
            escaped(created.unwrap_or("?")),
            escaped(creator)
        )?;
    }
    Ok(())
}

/// Bounds, periods and the largest dynamic regions.
fn print_dynamics(info: &FroctInfo) -> std::io::Result<()> {
    let n = group_thousands;
    let span = |min: [f64; 3], max: [f64; 3]| {
        format!(
            "x [{:.2}, {:.2}]  y [{:.2}, {:.2}]  z [{:.2}, {:.2}] m",
            min[0], max[0], min[1], max[1], min[2], max[2]
        )
    };
    match &info.bounds_m {
        Some(b) => outln!(
            "bounds:          {} ({:.1} x {:.1} x {:.1} m)",
            span(b.min, b.max),
            b.max[0] - b.min[0],
            b.max[1] - b.min[1],
            b.max[2] - b.min[2]
        )?,
        None => outln!("bounds:          none (no cells)")?,
    }
    if info.periods.is_empty() {
        outln!("periods:         none (no modelled cells)")?;
    } else {
        let modelled: u64 = info.periods.iter().map(|p| p.cells).sum();
        outln!(
            "periods:         strongest period of the {} modelled cells (the other {} dynamic cells flip rarely):",
            n(modelled),
            n(info.cells.dynamic.saturating_sub(modelled))
        )?;
        const SHOWN: usize = 8;
        for period in info.periods.iter().take(SHOWN) {
            outln!(
                "  {:<14} {} cells ({} voxels)",
                period.period,
                n(period.cells),
                n(period.voxels)
            )?;
        }
        if info.periods.len() > SHOWN {
            let rest = &info.periods[SHOWN..];
            outln!(
                "  {} other periods: {} cells ({} voxels; --json lists them)",
                rest.len(),
                n(rest.iter().map(|p| p.cells).sum()),
                n(rest.iter().map(|p| p.voxels).sum())
            )?;
        }
    }
    if info.dynamic_region_count > 0 {
        outln!(
            "dynamic regions: {} connected regions of dynamic voxels; the largest:",
            n(info.dynamic_region_count as u64)
        )?;
        for region in &info.dynamic_regions {
            outln!(
                "  {:>9} voxels  {}",
                n(region.voxels),
                span(region.min, region.max)
            )?;
        }
    }
    Ok(())
}

/// `N (a static free, b static occupied, c dynamic, d sometimes unknown)`.
pub(crate) fn class_counts(c: &ClassCounts) -> String {
    let n = group_thousands;
    format!(
        "{} ({} static free, {} static occupied, {} dynamic, {} sometimes unknown)",
        n(c.total()),
        n(c.static_free),
        n(c.static_occupied),
        n(c.dynamic),
        n(c.unknown_sometimes)
    )
}
