//! Resampling onto one uniform time base by linear interpolation.
//!
//! Grid: from the latest channel start to the earliest channel end, `t_j = t_start + j / fs`
//! (computed from `j`, never accumulated, so a 1-hour run has no drift).
//!
//! Long-gap rule (ingest.max_gap_ms): a grid time that falls strictly inside a hole between two
//! kept samples further apart than `max_gap_s` gets NaN in that channel and `valid = false`;
//! the hole is listed as a [`Gap`]. We chose masking over splitting the run: the time base stays
//! one uniform grid, later stages work on [`RunLog::valid_segments`](super::RunLog), and the
//! samples on both sides of a gap keep their place in time.

use std::borrow::Cow;

use rayon::prelude::*;
use std::path::Path;

use super::{Gap, IngestError, RawChannel, Warning, WarningKind};
use crate::config::IngestConfig;

/// Bound on the error of linear interpolation between samples `h` seconds apart of a signal
/// whose second derivative is bounded by `max_abs_second_derivative` (unit/s²): `M h² / 8`.
pub fn linear_interpolation_bound(max_abs_second_derivative: f64, h: f64) -> f64 {
    max_abs_second_derivative * h * h / 8.0
}

pub(super) struct ChannelStats {
    pub rate_hz: f64,
    pub max_step_s: f64,
    pub min: f64,
    pub max: f64,
}

pub(super) struct Resampled {
    pub time_s: Vec<f64>,
    /// In [`crate::format::Signal::ALL`] order.
    pub columns: Vec<Vec<f64>>,
    pub valid: Vec<bool>,
    pub gaps: Vec<Gap>,
    pub warnings: Vec<Warning>,
    pub stats: Vec<ChannelStats>,
}

/// The kept samples of a channel (dropped NaN samples removed, copied only if there are any).
fn kept(ch: &RawChannel) -> (Cow<'_, [f64]>, Cow<'_, [f64]>) {
    if ch.dropped == 0 {
        return (Cow::Borrowed(&ch.time_s[..]), Cow::Borrowed(&ch.values[..]));
    }
    let (t, v): (Vec<f64>, Vec<f64>) = ch
        .time_s
        .iter()
        .zip(&ch.values)
        .filter(|(_, v)| !v.is_nan())
        .map(|(t, v)| (*t, *v))
        .unzip();
    (Cow::Owned(t), Cow::Owned(v))
}

/// Identity of a time vector (same allocation and length): channels read from one CSV share it.
#[derive(Clone, Copy, PartialEq, Eq)]
struct TimeKey(*const f64, usize);

impl TimeKey {
    fn of(t: &[f64]) -> Self {
        TimeKey(t.as_ptr(), t.len())
    }
}

/// Smallest and largest value, in parallel.
fn min_max(v: &[f64]) -> (f64, f64) {
    v.par_chunks(CHUNK)
        .map(|c| {
            c.iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(*x), b.max(*x))
                })
        })
        .reduce(
            || (f64::INFINITY, f64::NEG_INFINITY),
            |(a, b), (c, d)| (a.min(c), b.max(d)),
        )
}

/// Grid points per parallel work item.
const CHUNK: usize = 1 << 16;

/// Interpolates every member series (sharing sample times `t`) onto `grid`; grid times strictly
/// inside a hole longer than `max_gap` get NaN and clear `valid`. Returns the outputs and the
/// number of grid samples inside such holes.
fn interpolate_group(
    t: &[f64],
    values: &[&[f64]],
    grid: &[f64],
    max_gap: f64,
    valid: &mut [bool],
) -> (Vec<Vec<f64>>, usize) {
    let n = grid.len();
    let mut outs: Vec<Vec<f64>> = values.iter().map(|_| vec![0.0; n]).collect();
    let chunks = n.div_ceil(CHUNK);
    // Per grid chunk: its first index, each member's output slice, its slice of `valid`.
    type Work<'a> = (usize, Vec<&'a mut [f64]>, &'a mut [bool]);
    let mut work: Vec<Work> = Vec::with_capacity(chunks);
    let mut valid_chunks = valid.chunks_mut(CHUNK);
    for c in 0..chunks {
        work.push((
            c * CHUNK,
            Vec::with_capacity(values.len()),
            valid_chunks.next().expect("same length as the grid"),
        ));
    }
    for out in outs.iter_mut() {
        for (c, sl) in out.chunks_mut(CHUNK).enumerate() {
            work[c].1.push(sl);
        }
    }
    let invalid: usize = work
        .into_par_iter()
        .map(|(start, mut slices, valid)| {
            let g0 = grid[start];
            // First k with t[k+1] >= g0, kept within [0, len-2].
            let mut k = t
                .partition_point(|&x| x < g0)
                .saturating_sub(1)
                .min(t.len() - 2);
            let mut invalid = 0;
            for (j, &g) in grid[start..start + valid.len()].iter().enumerate() {
                while k + 2 < t.len() && t[k + 1] < g {
                    k += 1;
                }
                let (t0, t1) = (t[k], t[k + 1]);
                if g <= t0 || g >= t1 {
                    let kk = if g <= t0 { k } else { k + 1 };
                    for (out, v) in slices.iter_mut().zip(values) {
                        out[j] = v[kk];
                    }
                } else if t1 - t0 > max_gap {
                    for out in slices.iter_mut() {
                        out[j] = f64::NAN;
                    }
                    valid[j] = false;
                    invalid += 1;
                } else {
                    let f = (g - t0) / (t1 - t0);
                    for (out, v) in slices.iter_mut().zip(values) {
                        out[j] = v[k] + (v[k + 1] - v[k]) * f;
                    }
                }
            }
            invalid
        })
        .sum();
    (outs, invalid)
}

/// Holes longer than `max_gap` overlapping [t_start, t_end] (last sample before, first after),
/// the median step and the longest step of a channel's sample times, s.
fn step_summary(t: &[f64], max_gap: f64, t_start: f64, t_end: f64) -> (Vec<(f64, f64)>, f64, f64) {
    let mut gaps = Vec::new();
    let mut max_step: f64 = 0.0;
    for w in t.windows(2) {
        let d = w[1] - w[0];
        max_step = max_step.max(d);
        if d > max_gap && w[1] > t_start && w[0] < t_end {
            gaps.push((w[0], w[1]));
        }
    }
    (gaps, median_step(t), max_step)
}

/// Median sample step, s: exact up to 200 000 steps, beyond that the median of 200 000 steps
/// taken at an even stride (the rate found is a summary figure, not used in computation).
fn median_step(t: &[f64]) -> f64 {
    const MAX: usize = 200_000;
    let steps = t.len().saturating_sub(1);
    let stride = steps.div_ceil(MAX).max(1);
    let mut d: Vec<f64> = (0..steps)
        .step_by(stride)
        .map(|i| t[i + 1] - t[i])
        .collect();
    if d.is_empty() {
        return f64::NAN;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// A channel's kept (time, value) samples.
type Kept<'a> = (Cow<'a, [f64]>, Cow<'a, [f64]>);

/// Most samples of a resampled run (2·10⁷: 1.6 GB of grid for its ten columns).
pub const MAX_SAMPLES: f64 = 2e7;

/// The channels' common span [t_start, t_end] (s) must be finite, at most
/// `ingest.max_duration_s` and at most [`MAX_SAMPLES`] at the sample rate, checked before the
/// grid is allocated. The hint reads the rows' median spacing: a span far beyond it means a
/// stray time stamp; rows a thousand times further apart than a logger's usually are mean a
/// time column in ms or µs declared as s.
fn check_span(
    path: &Path,
    kept: &[Kept<'_>],
    t_start: f64,
    t_end: f64,
    cfg: &IngestConfig,
) -> Result<(), IngestError> {
    let fs = cfg.sample_rate_hz;
    let span = t_end - t_start;
    let samples = span * fs;
    if span.is_finite() && span <= cfg.max_duration_s && samples <= MAX_SAMPLES {
        return Ok(());
    }
    // The densest channel's rows: their median spacing (s; robust to a stray row) and count.
    let (step, rows) = kept
        .iter()
        .map(|(t, _)| t)
        .max_by_key(|t| t.len())
        .map(|t| {
            let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
            d.sort_by(f64::total_cmp);
            (d.get(d.len() / 2).copied().unwrap_or(f64::NAN), t.len())
        })
        .unwrap_or((f64::NAN, 0));
    let hint = if !span.is_finite() || span > 10.0 * step * rows as f64 {
        format!(
            "a time stamp far from the others: the rows lie {step:.3e} s apart (median) yet span {span:.3e} s — a corrupt row or message? Check the first and last time stamps of each channel"
        )
    } else if (0.05..50.0).contains(&step) {
        format!(
            "the rows lie {step:.4} s apart (median) — about 1000 times a logger's usual spacing: is the time column in milliseconds? Declare its unit (ingest.csv.time = {{ unit = \"ms\" }})"
        )
    } else if (50.0..5e4).contains(&step) {
        format!(
            "the rows lie {step:.1} s apart (median): is the time column in microseconds? Declare its unit (unit = \"us\")"
        )
    } else {
        "raise ingest.max_duration_s if the run really lasts this long, or split the log"
            .to_string()
    };
    Err(IngestError::TooLong {
        path: path.to_path_buf(),
        span_s: span,
        t_start,
        samples,
        rate_hz: fs,
        limit_s: cfg.max_duration_s,
        hint,
    })
}

pub(super) fn resample(
    path: &Path,
    channels: &[RawChannel],
    cfg: &IngestConfig,
) -> Result<Resampled, IngestError> {
    let fs = cfg.sample_rate_hz;
    let max_gap = cfg.max_gap_s;
    let kept: Vec<_> = channels.iter().map(kept).collect();
    for (ch, (t, _)) in channels.iter().zip(&kept) {
        if t.len() < 2 {
            return Err(IngestError::NoOverlap {
                path: path.to_path_buf(),
                what: format!("{} has {} usable sample(s)", ch.signal, t.len()),
            });
        }
    }
    let firsts: Vec<f64> = kept.iter().map(|(t, _)| t[0]).collect();
    let lasts: Vec<f64> = kept.iter().map(|(t, _)| t[t.len() - 1]).collect();
    let (i_start, &t_start) = firsts
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .expect("nine channels");
    let (i_end, &t_end) = lasts
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .expect("nine channels");
    if t_end - t_start < 1.0 / fs {
        return Err(IngestError::NoOverlap {
            path: path.to_path_buf(),
            what: format!(
                "{} starts at {t_start:.3} s but {} ends at {t_end:.3} s",
                channels[i_start].signal, channels[i_end].signal
            ),
        });
    }
    check_span(path, &kept, t_start, t_end, cfg)?;
    let n = ((t_end - t_start) * fs + 1e-9).floor() as usize + 1;
    let time_s: Vec<f64> = (0..n)
        .map(|j| (t_start + j as f64 / fs).min(t_end))
        .collect();

    let mut warnings = Vec::new();
    let earliest = firsts.iter().copied().fold(f64::INFINITY, f64::min);
    let latest = lasts.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if t_start - earliest > max_gap {
        warnings.push(Warning {
            kind: WarningKind::Trimmed,
            message: format!(
                "trimmed {:.3} s at the start: {} has no data before t = {t_start:.3} s",
                t_start - earliest,
                channels[i_start].signal
            ),
        });
    }
    if latest - t_end > max_gap {
        warnings.push(Warning {
            kind: WarningKind::Trimmed,
            message: format!(
                "trimmed {:.3} s at the end: {} has no data after t = {t_end:.3} s",
                latest - t_end,
                channels[i_end].signal
            ),
        });
    }

    // Channels sharing a time base (all of a CSV, the fields of one MCAP topic) are
    // interpolated together: one walk over the grid per group, in parallel over grid chunks,
    // writing every member's output and the validity mask. Nothing per sample is stored twice.
    let mut groups: Vec<(TimeKey, Vec<usize>)> = Vec::new();
    for (i, (t, _)) in kept.iter().enumerate() {
        let key = TimeKey::of(t);
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(i),
            None => groups.push((key, vec![i])),
        }
    }
    let mut valid = vec![true; n];
    let mut outputs: Vec<Vec<f64>> = (0..channels.len()).map(|_| Vec::new()).collect();
    let mut stats: Vec<Option<ChannelStats>> = (0..channels.len()).map(|_| None).collect();
    let mut gaps = Vec::new();
    for (_, members) in &groups {
        let t = &kept[members[0]].0[..];
        let values: Vec<&[f64]> = members.iter().map(|&i| &kept[i].1[..]).collect();
        let (outs, invalid) = interpolate_group(t, &values, &time_s, max_gap, &mut valid);
        let (group_gaps, median, max_step) = step_summary(t, max_gap, t_start, t_end);
        for (&i, out) in members.iter().zip(outs) {
            let ch = &channels[i];
            if !group_gaps.is_empty() {
                let longest = group_gaps
                    .iter()
                    .max_by(|a, b| (a.1 - a.0).total_cmp(&(b.1 - b.0)))
                    .expect("non-empty");
                warnings.push(Warning {
                    kind: WarningKind::Gap,
                    message: format!(
                        "{}: {} gap(s) longer than {} ms not interpolated ({invalid} samples marked invalid); longest {:.3} s from t = {:.3} s to {:.3} s",
                        ch.signal,
                        group_gaps.len(),
                        max_gap * 1e3,
                        longest.1 - longest.0,
                        longest.0,
                        longest.1
                    ),
                });
                gaps.extend(group_gaps.iter().map(|&(from_s, to_s)| Gap {
                    signal: ch.signal,
                    from_s,
                    to_s,
                }));
            }
            let (min, max) = min_max(&kept[i].1);
            stats[i] = Some(ChannelStats {
                rate_hz: 1.0 / median,
                max_step_s: max_step,
                min,
                max,
            });
            outputs[i] = out;
        }
    }
    gaps.sort_by_key(|g| g.signal);
    let per_channel: Vec<(Vec<f64>, ChannelStats)> = outputs
        .into_iter()
        .zip(stats)
        .map(|(o, s)| (o, s.expect("every channel is in one group")))
        .collect();
    let (columns, stats) = per_channel.into_iter().unzip();
    Ok(Resampled {
        time_s,
        columns,
        valid,
        gaps,
        warnings,
        stats,
    })
}
