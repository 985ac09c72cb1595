//! Resampling onto one uniform time base by linear interpolation.
//!
//! Grid: from the latest channel start to the earliest channel end, `t_j = t_start + j / fs`
//! (computed from `j`, never accumulated, so a 1-hour run has no drift).
//!
//! Gap rules. A hole between two kept samples up to `ingest.max_gap_ms` is interpolated
//! linearly like any other step. A hole longer than that and at most `ingest.bridge_gap_ms`
//! (default 0.5 s) is **bridged** ([`bridge`]): cubic Hermite interpolation between the samples
//! on both sides, with end slopes from a least-squares line through each side's samples of
//! the last/first [`SLOPE_WINDOW_S`]; the grid samples inside stay valid, so the filters run
//! through, and the hole is listed as a bridged [`Gap`] — conditioning masks the bridged
//! samples and the filters' support around them (`signal::condition`). Splitting the
//! filters at a 0.2 s logger gap and masking the settling at both new ends cost ~640 samples
//! per axle. A longer hole gets NaN in that channel and `valid = false`; the filters split
//! there. Masking over splitting the run: the time base stays one uniform grid, later stages
//! work on [`RunLog::valid_segments`](super::RunLog), and the samples on both sides of a gap
//! keep their place in time.

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
    // A CSV channel's cells without a value are left out when it is read.
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

/// Span of samples on each side of a bridged hole that sets the end slope, s.
pub const SLOPE_WINDOW_S: f64 = 0.1;

/// Slope at `t_end` of the least-squares parabola v ≈ a + b x + c x², x = t − t_end, through
/// the samples `idx` (unit/s): b. A straight line's slope would estimate the derivative at
/// the window's middle, half a window from the gap (a bias of |v''|·W/2). `None` with fewer
/// than four samples or a singular fit.
fn end_slope(
    t: &[f64],
    v: &[f64],
    idx: std::ops::RangeInclusive<usize>,
    t_end: f64,
) -> Option<f64> {
    if idx.clone().count() < 4 {
        return None;
    }
    // Normal equations in x scaled by the window (for conditioning): u = x / w.
    let w = idx
        .clone()
        .map(|i| (t[i] - t_end).abs())
        .fold(0.0, f64::max);
    if w <= 0.0 {
        return None;
    }
    let mut s = [0.0f64; 5];
    let mut r = [0.0f64; 3];
    for i in idx {
        let u = (t[i] - t_end) / w;
        let mut p = 1.0;
        for (k, sk) in s.iter_mut().enumerate() {
            *sk += p;
            if k < 3 {
                r[k] += p * v[i];
            }
            p *= u;
        }
    }
    // [s0 s1 s2; s1 s2 s3; s2 s3 s4] [a b c]ᵀ = r; b by Cramer's rule.
    let det3 = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let m = [[s[0], s[1], s[2]], [s[1], s[2], s[3]], [s[2], s[3], s[4]]];
    let d = det3(m);
    if d.is_nan() || d.abs() <= 1e-12 * s[0].powi(3) {
        return None;
    }
    let mb = [[s[0], r[0], s[2]], [s[1], r[1], s[3]], [s[2], r[2], s[4]]];
    Some(det3(mb) / d / w)
}

/// The value at `g` inside the hole between samples `k` and `k + 1` of (`t`, `v`): cubic
/// Hermite interpolation (e.g. de Boor, *A Practical Guide to Splines*, ch. IV)
/// p(s) = h00 v0 + h10 H m0 + h01 v1 + h11 H m1, s = (g − t0)/H, H = t1 − t0, with
/// h00 = 2s³ − 3s² + 1, h10 = s³ − 2s² + s, h01 = −2s³ + 3s², h11 = s³ − s², and end slopes
/// m0, m1 the slopes at t0 and t1 of least-squares parabolas through the samples within
/// [`SLOPE_WINDOW_S`] before t0 and after t1 (the secant (v1 − v0)/H where a side has fewer
/// than four samples). Continuous in
/// value and slope at both ends, so the derivative the estimator takes has no step; exact
/// for cubic signals sampled densely. Units of `v`.
pub fn bridge(t: &[f64], v: &[f64], k: usize, g: f64) -> f64 {
    let (t0, t1, v0, v1) = (t[k], t[k + 1], v[k], v[k + 1]);
    let h = t1 - t0;
    let secant = (v1 - v0) / h;
    let lo = t[..=k].partition_point(|&x| x < t0 - SLOPE_WINDOW_S);
    let hi = k + 1 + t[k + 1..].partition_point(|&x| x <= t1 + SLOPE_WINDOW_S) - 1;
    let m0 = end_slope(t, v, lo..=k, t0).unwrap_or(secant);
    let m1 = end_slope(t, v, k + 1..=hi, t1).unwrap_or(secant);
    let s = (g - t0) / h;
    let (s2, s3) = (s * s, s * s * s);
    (2.0 * s3 - 3.0 * s2 + 1.0) * v0
        + (s3 - 2.0 * s2 + s) * h * m0
        + (-2.0 * s3 + 3.0 * s2) * v1
        + (s3 - s2) * h * m1
}

/// Interpolates every member series (sharing sample times `t`) onto `grid`; grid times strictly
/// inside a hole longer than `max_gap` and at most `bridge_gap` are bridged ([`bridge`]), inside
/// a longer hole get NaN and clear `valid`. Returns the outputs and the number of grid samples
/// inside unbridged holes.
fn interpolate_group(
    t: &[f64],
    values: &[&[f64]],
    grid: &[f64],
    (max_gap, bridge_gap): (f64, f64),
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
                } else if t1 - t0 > max_gap && t1 - t0 <= bridge_gap {
                    for (out, v) in slices.iter_mut().zip(values) {
                        out[j] = bridge(t, v, k, g);
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

/// Resamples the channels onto one uniform grid over their common span: trimmed edges and
/// holes are reported as warnings, holes listed as [`Gap`]s, and per channel the rate, the
/// longest step and the value range are summarised.
pub(super) fn resample(
    path: &Path,
    channels: &[RawChannel],
    cfg: &IngestConfig,
) -> Result<Resampled, IngestError> {
    let fs = cfg.sample_rate_hz;
    let kept: Vec<_> = channels.iter().map(kept).collect();
    let o = overlap(path, channels, &kept, fs)?;
    check_span(path, &kept, o.t_start, o.t_end, cfg)?;
    let n = ((o.t_end - o.t_start) * fs + 1e-9).floor() as usize + 1;
    let time_s: Vec<f64> = (0..n)
        .map(|j| (o.t_start + j as f64 / fs).min(o.t_end))
        .collect();
    let mut walk = Walk {
        channels,
        kept: &kept,
        cfg,
        span: (o.t_start, o.t_end),
        valid: vec![true; n],
        outputs: (0..channels.len()).map(|_| Vec::new()).collect(),
        stats: (0..channels.len()).map(|_| None).collect(),
        gaps: Vec::new(),
        warnings: trim_warnings(channels, &o, cfg.max_gap_s),
        time_s,
    };
    for members in time_groups(&kept) {
        walk.group(&members);
    }
    Ok(walk.finish())
}

/// The channels' common span and where it comes from.
struct Overlap {
    /// The latest channel start and the channel (index) that sets it, s.
    t_start: f64,
    i_start: usize,
    /// The earliest channel end and the channel that sets it, s.
    t_end: f64,
    i_end: usize,
    /// The earliest start and the latest end of any channel, s.
    earliest: f64,
    latest: f64,
}

/// The common span of the channels' kept samples: every channel needs two, and the span must
/// hold at least one sample period at `fs`.
fn overlap(
    path: &Path,
    channels: &[RawChannel],
    kept: &[Kept<'_>],
    fs: f64,
) -> Result<Overlap, IngestError> {
    for (ch, (t, _)) in channels.iter().zip(kept) {
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
    Ok(Overlap {
        t_start,
        i_start,
        t_end,
        i_end,
        earliest: firsts.iter().copied().fold(f64::INFINITY, f64::min),
        latest: lasts.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    })
}

/// Warnings for data cut off before the common span starts or after it ends (more than
/// `max_gap` s of it).
fn trim_warnings(channels: &[RawChannel], o: &Overlap, max_gap: f64) -> Vec<Warning> {
    let mut warnings = Vec::new();
    if o.t_start - o.earliest > max_gap {
        warnings.push(Warning {
            kind: WarningKind::Trimmed,
            message: format!(
                "trimmed {:.3} s at the start: {} has no data before t = {:.3} s",
                o.t_start - o.earliest,
                channels[o.i_start].signal,
                o.t_start
            ),
        });
    }
    if o.latest - o.t_end > max_gap {
        warnings.push(Warning {
            kind: WarningKind::Trimmed,
            message: format!(
                "trimmed {:.3} s at the end: {} has no data after t = {:.3} s",
                o.latest - o.t_end,
                channels[o.i_end].signal,
                o.t_end
            ),
        });
    }
    warnings
}

/// The channels grouped by shared time base (all of a CSV, the fields of one MCAP topic), in
/// order of first appearance, as indexes into `kept`.
fn time_groups(kept: &[Kept<'_>]) -> Vec<Vec<usize>> {
    let mut groups: Vec<(TimeKey, Vec<usize>)> = Vec::new();
    for (i, (t, _)) in kept.iter().enumerate() {
        let key = TimeKey::of(t);
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(i),
            None => groups.push((key, vec![i])),
        }
    }
    groups.into_iter().map(|(_, members)| members).collect()
}

/// A resampling in progress: the grid and validity mask, each channel's output and
/// statistics as its group is walked, and the holes and warnings in the order found.
struct Walk<'a> {
    channels: &'a [RawChannel],
    kept: &'a [Kept<'a>],
    cfg: &'a IngestConfig,
    /// The common span [t_start, t_end], s.
    span: (f64, f64),
    time_s: Vec<f64>,
    valid: Vec<bool>,
    outputs: Vec<Vec<f64>>,
    stats: Vec<Option<ChannelStats>>,
    gaps: Vec<Gap>,
    warnings: Vec<Warning>,
}

impl Walk<'_> {
    /// Interpolates one group of channels sharing a time base together: one walk over the
    /// grid, in parallel over grid chunks, writing every member's output and the validity
    /// mask (nothing per sample is stored twice); then each member's gap warnings, holes and
    /// statistics.
    fn group(&mut self, members: &[usize]) {
        let (channels, kept, cfg) = (self.channels, self.kept, self.cfg);
        let max_gap = cfg.max_gap_s;
        let t = &kept[members[0]].0[..];
        let values: Vec<&[f64]> = members.iter().map(|&i| &kept[i].1[..]).collect();
        let (outs, invalid) = interpolate_group(
            t,
            &values,
            &self.time_s,
            (max_gap, cfg.bridge_gap_s),
            &mut self.valid,
        );
        let (group_gaps, median, max_step) = step_summary(t, max_gap, self.span.0, self.span.1);
        type Holes = Vec<(f64, f64)>;
        let (bridged, open): (Holes, Holes) = group_gaps
            .iter()
            .partition(|(a, b)| b - a <= cfg.bridge_gap_s);
        for (&i, out) in members.iter().zip(outs) {
            let ch = &channels[i];
            self.gap_warnings(ch, &open, &bridged, invalid);
            self.gaps
                .extend(group_gaps.iter().map(|&(from_s, to_s)| Gap {
                    signal: ch.signal,
                    from_s,
                    to_s,
                    bridged: to_s - from_s <= cfg.bridge_gap_s,
                }));
            let (min, max) = min_max(&kept[i].1);
            self.stats[i] = Some(ChannelStats {
                rate_hz: 1.0 / median,
                max_step_s: max_step,
                min,
                max,
            });
            self.outputs[i] = out;
        }
    }

    /// The warnings of one channel about its `open` holes (`invalid` grid samples masked)
    /// and its `bridged` ones, each naming the longest.
    fn gap_warnings(
        &mut self,
        ch: &RawChannel,
        open: &[(f64, f64)],
        bridged: &[(f64, f64)],
        invalid: usize,
    ) {
        let (max_gap, bridge_gap) = (self.cfg.max_gap_s, self.cfg.bridge_gap_s);
        let longest = |g: &[(f64, f64)]| {
            *g.iter()
                .max_by(|a, b| (a.1 - a.0).total_cmp(&(b.1 - b.0)))
                .expect("non-empty")
        };
        if !open.is_empty() {
            let l = longest(open);
            self.warnings.push(Warning {
                kind: WarningKind::Gap,
                message: format!(
                    "{}: {} gap(s) longer than {} ms not interpolated ({invalid} samples marked invalid); longest {:.3} s from t = {:.3} s to {:.3} s",
                    ch.signal,
                    open.len(),
                    (max_gap.max(bridge_gap)) * 1e3,
                    l.1 - l.0,
                    l.0,
                    l.1
                ),
            });
        }
        if !bridged.is_empty() {
            let l = longest(bridged);
            self.warnings.push(Warning {
                kind: WarningKind::Gap,
                message: format!(
                    "{}: {} gap(s) longer than {} ms bridged by cubic Hermite interpolation (ingest.bridge_gap_ms = {}; the bridged samples and the filters' support around them are masked); longest {:.3} s from t = {:.3} s to {:.3} s",
                    ch.signal,
                    bridged.len(),
                    max_gap * 1e3,
                    bridge_gap * 1e3,
                    l.1 - l.0,
                    l.0,
                    l.1
                ),
            });
        }
    }

    /// The resampled run: holes sorted by signal, outputs and statistics in channel order.
    fn finish(self) -> Resampled {
        let mut gaps = self.gaps;
        gaps.sort_by_key(|g| g.signal);
        let per_channel: Vec<(Vec<f64>, ChannelStats)> = self
            .outputs
            .into_iter()
            .zip(self.stats)
            .map(|(o, s)| (o, s.expect("every channel is in one group")))
            .collect();
        let (columns, stats) = per_channel.into_iter().unzip();
        Resampled {
            time_s: self.time_s,
            columns,
            valid: self.valid,
            gaps,
            warnings: self.warnings,
            stats,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Samples of `f` every `h` s over [0, 1] s with a hole (gap_from, gap_from + gap).
    fn holed(f: &dyn Fn(f64) -> f64, h: f64, gap_from: f64, gap: f64) -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..=(1.0 / h) as usize)
            .map(|i| i as f64 * h)
            .filter(|&x| !(x > gap_from && x < gap_from + gap))
            .collect();
        let v = t.iter().map(|&x| f(x)).collect();
        (t, v)
    }

    proptest! {
        /// The bridge reproduces any quadratic exactly (the end parabolas are exact, and a
        /// cubic Hermite with exact end slopes reproduces quadratics) and stays finite.
        #[test]
        fn bridges_reproduce_quadratics(
            a in -100.0f64..100.0,
            b in -50.0f64..50.0,
            c in -20.0f64..20.0,
            gap in 0.06f64..0.5,
            from in 0.2f64..0.4,
            rate in prop::sample::select(vec![100.0, 417.0, 1000.0]),
        ) {
            let f = |x: f64| a + b * x + c * x * x;
            let (t, v) = holed(&f, 1.0 / rate, from, gap);
            let k = t.iter().position(|&x| x > from).unwrap() - 1;
            prop_assert!(t[k + 1] - t[k] >= gap);
            for s in [0.1, 0.37, 0.5, 0.9] {
                let g = t[k] + s * (t[k + 1] - t[k]);
                let y = bridge(&t, &v, k, g);
                prop_assert!((y - f(g)).abs() <= 1e-8 * (1.0 + a.abs() + b.abs() + c.abs()), "{y} vs {}", f(g));
            }
        }
    }

    #[test]
    fn a_side_with_too_few_samples_falls_back_to_the_secant() {
        // Two samples only: a straight line between them.
        let (t, v) = (vec![0.0, 1.0], vec![1.0, 3.0]);
        assert!((bridge(&t, &v, 0, 0.25) - 1.5).abs() < 1e-12);
    }
}
