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
    if ch.values.iter().all(|v| !v.is_nan()) {
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

fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return f64::NAN;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    *m
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

    let mut valid = vec![true; n];
    let mut columns = Vec::with_capacity(channels.len());
    let mut gaps = Vec::new();
    let mut stats = Vec::with_capacity(channels.len());
    let mut median_cache: Vec<(*const f64, usize, f64)> = Vec::new();
    for (ch, (t, v)) in channels.iter().zip(&kept) {
        let (t, v) = (&t[..], &v[..]);
        let mut out = vec![0.0; n];
        let mut k = 0usize;
        let mut invalid = 0usize;
        for (j, &g) in time_s.iter().enumerate() {
            while k + 2 < t.len() && t[k + 1] < g {
                k += 1;
            }
            // Now t[k] <= g and (g <= t[k+1] or k+1 is the last sample).
            let (t0, t1, v0, v1) = (t[k], t[k + 1], v[k], v[k + 1]);
            out[j] = if g <= t0 {
                v0
            } else if g >= t1 {
                v1
            } else if t1 - t0 > max_gap {
                valid[j] = false;
                invalid += 1;
                f64::NAN
            } else {
                v0 + (v1 - v0) * ((g - t0) / (t1 - t0))
            };
        }
        let mut ch_gaps = Vec::new();
        let mut max_step: f64 = 0.0;
        for w in t.windows(2) {
            let d = w[1] - w[0];
            max_step = max_step.max(d);
            if d > max_gap && w[1] > t_start && w[0] < t_end {
                ch_gaps.push(Gap {
                    signal: ch.signal,
                    from_s: w[0],
                    to_s: w[1],
                });
            }
        }
        if !ch_gaps.is_empty() {
            let longest = ch_gaps
                .iter()
                .max_by(|a, b| (a.to_s - a.from_s).total_cmp(&(b.to_s - b.from_s)))
                .expect("non-empty");
            warnings.push(Warning {
                kind: WarningKind::Gap,
                message: format!(
                    "{}: {} gap(s) longer than {} ms not interpolated ({invalid} samples marked invalid); longest {:.3} s from t = {:.3} s to {:.3} s",
                    ch.signal,
                    ch_gaps.len(),
                    max_gap * 1e3,
                    longest.to_s - longest.from_s,
                    longest.from_s,
                    longest.to_s
                ),
            });
        }
        gaps.extend(ch_gaps);
        let key = (t.as_ptr(), t.len());
        let step = match median_cache.iter().find(|c| (c.0, c.1) == key) {
            Some(c) => c.2,
            None => {
                let m = median_step(t);
                median_cache.push((key.0, key.1, m));
                m
            }
        };
        let (min, max) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                (a.min(*x), b.max(*x))
            });
        stats.push(ChannelStats {
            rate_hz: 1.0 / step,
            max_step_s: max_step,
            min,
            max,
        });
        columns.push(out);
    }
    Ok(Resampled {
        time_s,
        columns,
        valid,
        gaps,
        warnings,
        stats,
    })
}
