//! The time axis of a series of instants, and the samples a build leaves out of it.

use crate::error::ConvertError;
use crate::inputs::SeriesInput;
use froctomap_core::Timestamp;
use froctomap_temporal::TimeAxis;

/// The time axis of sorted, distinct instants: a regular grid (with missing samples) when
/// the instants lie on one with at most as many gaps as snapshots, else an explicit list.
pub fn axis_for_times(times: &[Timestamp]) -> Result<TimeAxis, ConvertError> {
    let first = *times.first().ok_or(ConvertError::NoInputs)?;
    let invalid = ConvertError::TimeAxis;
    if times.len() == 1 {
        return TimeAxis::regular(first, 1_000_000_000, 1, Vec::new()).map_err(invalid);
    }
    let gcd = times.windows(2).fold(0i64, |g, w| gcd(g, w[1].0 - w[0].0));
    let span = times[times.len() - 1].0 - first.0;
    let count = span / gcd.max(1) + 1;
    if gcd > 0 && count <= 2 * times.len() as i64 && count <= i64::from(u32::MAX) {
        let present: Vec<i64> = times.iter().map(|t| (t.0 - first.0) / gcd).collect();
        let mut missing = Vec::new();
        let mut next = 0usize;
        for i in 0..count {
            if present.get(next) == Some(&i) {
                next += 1;
            } else {
                missing.push(i as u32);
            }
        }
        return TimeAxis::regular(first, gcd, count as u32, missing).map_err(invalid);
    }
    TimeAxis::explicit(times.to_vec()).map_err(invalid)
}

fn gcd(a: i64, b: i64) -> i64 {
    if b == 0 {
        a.abs()
    } else {
        gcd(b, a % b)
    }
}

/// A regular axis with the samples in `absent` (sorted, including its own gaps) missing,
/// when some snapshots were left out; `None` when nothing changes (an explicit axis keeps
/// the instants, with nothing observed at them).
pub(super) fn with_absent_missing(
    axis: &TimeAxis,
    absent: &[u32],
) -> Result<Option<TimeAxis>, ConvertError> {
    match axis.step_ns() {
        Some(step) if absent.len() > axis.missing().len() => {
            TimeAxis::regular(axis.start(), step, axis.len(), absent.to_vec())
                .map(Some)
                .map_err(ConvertError::TimeAxis)
        }
        _ => Ok(None),
    }
}

/// The samples without a snapshot (sorted): the axis' own gaps and the inputs left out by
/// the check (`usable`) or by extraction (`refused`).
pub(super) fn samples_left_out(
    axis: &TimeAxis,
    inputs: &[SeriesInput],
    usable: &[bool],
    refused: &[u32],
) -> Vec<u32> {
    let mut absent: Vec<u32> = axis.missing().to_vec();
    absent.extend_from_slice(refused);
    absent.extend(
        inputs
            .iter()
            .zip(usable)
            .filter(|(_, &usable)| !usable)
            .filter_map(|(input, _)| axis.index_of(input.time)),
    );
    absent.sort_unstable();
    absent.dedup();
    absent
}
