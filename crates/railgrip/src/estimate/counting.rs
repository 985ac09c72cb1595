//! The tachometers' counting window, read from their quantisation.
//!
//! A tachometer that counts pulses over the last W samples reports
//!
//!   ω̂_k = Δθ (⌊θ_k / Δθ⌋ − ⌊θ_{k−W} / Δθ⌋) / (W h)
//!
//! (Δθ the angle per pulse, rad; h the sample period, s): the mean of ω over the window,
//! which lags ω by W h / 2, plus the quantisation error e_k = Δθ (u_{k−W} − u_k) / (W h) with
//! u_k = frac(θ_k / Δθ) ∈ [0, 1) — the ±1-count error of frequency (pulse-counting) speed
//! measurement (Petrella, Tursini, Peretti, Zigliotto, "Speed measurement algorithms for
//! low-resolution incremental encoder equipped drives: a comparative analysis", ACEMP 2007).
//! Where several pulses pass per sample and the speed changes, the u_k are close to
//! independent and uniform, so e_k is a difference of two of them W samples apart: its
//! autocorrelation is −1/2 at lag W and about 0 at every other lag ≥ 1. With 1000 pulses per
//! revolution the trough is −0.48 … −0.53 whatever the speed; with 100–200 it stays −0.44 …
//! −0.53 but the other lags reach ±0.25 (the fractions rotate regularly within a second of
//! slow deceleration), and with 60 it can be as shallow as −0.33. The wheel's own motion is
//! smooth at the sample rate, and what of it reaches the residual about a low-pass at a
//! twentieth of the sample rate (the filter's ringing after a wheel slide's kinks) has a
//! smooth autocorrelation: +0.3 … +0.9 at lag 1 and a broad trough around lag 8 (−0.70 on a
//! simulated 200 km/h run without the counting, against −0.52 with it and |ρ| ≤ 0.11 at the
//! other lags). Depth alone does not tell the two apart; a trough counts as a window only
//! where it also stands alone, every shorter lag and the next one within ±[`FLANK`]. The window,
//! and with it the delay W h / 2, can be read off the raw tachometer channel instead of being
//! fitted from the deceleration balance, where it trades off against the radar's latency
//! (docs/calibration.md, "The delays").
//!
//! Not every tachometer counts over a window: one that times the interval between pulses
//! leaves no trough. Windows of 1–13 samples are tested; the lags searched end at
//! [`MAX_LAG`], and a long window loses part of its error below the residual's cut-off. The
//! held delay assumes the tachometer chain adds no other latency (a filter, a logger's time
//! stamps). Campaigns whose tachometers show no window keep the balance's fit.

use crate::signal::filter::{LowPass4, MIN_LEN};

/// The residual's low-pass cut-off as a fraction of the sample rate.
const CUTOFF_FRACTION: f64 = 1.0 / 20.0;
/// Longest window looked for, samples.
pub const MAX_LAG: usize = 32;
/// Shortest stretch of finite samples used, s (a stretch is filtered on its own).
const MIN_STRETCH_S: f64 = 2.0;
/// An axle shows a counting window where its residual's autocorrelation falls to this or
/// below at the lag (the ideal counter gives −0.5). Depth alone is not enough: the filter's
/// ringing on runs without a window reaches −0.70; [`FLANK`] tells them apart.
pub const TROUGH: f64 = -0.35;

/// At most this |autocorrelation| at every lag shorter than the trough's and the next one:
/// the trough stands alone (a counter with 100–200 pulses per revolution reaches ±0.25 there,
/// the ringing without a window +0.3 … +0.9 at lag 1).
pub const FLANK: f64 = 0.3;

/// One axle's evidence: the lag (samples) where the residual's autocorrelation is lowest,
/// that autocorrelation, and the largest |autocorrelation| at the other lags from 1 to one
/// beyond the trough's (its flank).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trough {
    pub lag: usize,
    pub acf: f64,
    pub flank: f64,
}

impl Trough {
    /// Deep ([`TROUGH`]) and alone ([`FLANK`]): a counting window of `lag` samples.
    pub fn is_window(&self) -> bool {
        self.acf <= TROUGH && self.flank <= FLANK
    }
}

/// The lag and depth of the deepest trough of the autocorrelation of `omega`'s residual
/// about its zero-phase low-pass at fs/20 (rad/s, sampled at `fs` Hz), over lags
/// 1..=[`MAX_LAG`], from the stretches of at least 2 s of finite samples; None where no
/// stretch is that long or the residual is 0 (a constant channel). [`Trough::is_window`]
/// says whether it is a counting window.
///
/// The autocorrelation is computed in blocks of one second (at least 4 × [`MAX_LAG`]
/// samples; at lag L the sum over the block's n − L pairs scaled by n / (n − L)) and the
/// median over blocks taken at each lag: a block holding a transient (the
/// filter's ringing after a step at a wheel lock or a stretch's end, a spike) would otherwise
/// outweigh the rest of the run, whose error is a few hundredths of a rad/s. A block whose
/// raw samples never change (a wheel standing) is left out.
pub fn deepest_trough(omega: &[f64], fs: f64) -> Option<Trough> {
    let lp = LowPass4::butterworth(fs * CUTOFF_FRACTION, fs).ok()?;
    let min_len = ((MIN_STRETCH_S * fs).ceil() as usize).max(MIN_LEN + 1);
    let block = (fs.round() as usize).max(4 * MAX_LAG);
    let mut blocks: Vec<[f64; MAX_LAG]> = Vec::new();
    let mut start = 0;
    while start < omega.len() {
        let end = omega[start..]
            .iter()
            .position(|x| !x.is_finite())
            .map_or(omega.len(), |p| start + p);
        if end - start >= min_len {
            let x = &omega[start..end];
            let Ok(smooth) = lp.zero_phase(x) else {
                start = end + 1;
                continue;
            };
            let e: Vec<f64> = x.iter().zip(&smooth).map(|(a, b)| a - b).collect();
            for (b, raw) in e.chunks_exact(block).zip(x.chunks_exact(block)) {
                // A wheel that stands (locked, or the train stopped) counts no pulses: its
                // block holds only the filter's round-off and says nothing of a window.
                let counting = raw.iter().any(|v| *v != raw[0]);
                let var: f64 = b.iter().map(|v| v * v).sum();
                if counting && var > 0.0 {
                    let n = b.len() as f64;
                    blocks.push(std::array::from_fn(|i| {
                        let pairs = n - (i + 1) as f64;
                        b.iter().zip(&b[i + 1..]).map(|(u, v)| u * v).sum::<f64>() / var * n / pairs
                    }));
                }
            }
        }
        start = end + 1;
    }
    if blocks.is_empty() {
        return None;
    }
    let rho: Vec<f64> = (0..MAX_LAG)
        .map(|i| {
            let mut col: Vec<f64> = blocks.iter().map(|b| b[i]).collect();
            col.sort_by(f64::total_cmp);
            let m = col.len() / 2;
            if col.len() % 2 == 1 {
                col[m]
            } else {
                0.5 * (col[m - 1] + col[m])
            }
        })
        .collect();
    let rho = |lag: usize| rho[lag - 1];
    let lag = (1..=MAX_LAG).min_by(|a, b| rho(*a).total_cmp(&rho(*b)))?;
    let flank = (1..=(lag + 1).min(MAX_LAG))
        .filter(|l| *l != lag)
        .map(|l| rho(l).abs())
        .fold(0.0, f64::max);
    Some(Trough {
        lag,
        acf: rho(lag),
        flank,
    })
}

/// A campaign's counting window: its length (s), the axles of the runs that show it and
/// those looked at, and the mean depth of their troughs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    pub window_s: f64,
    pub showing: usize,
    pub looked_at: usize,
    pub mean_acf: f64,
}

impl Window {
    /// The tachometers' delay, half the window, s.
    pub fn delay_s(&self) -> f64 {
        0.5 * self.window_s
    }
}

/// Share of a campaign's axles (of all runs) that must show the same window.
pub const AGREEING: f64 = 0.75;
/// Share of a campaign's axles that must show some window before too few agreeing is worth a
/// note (one noisy axle is not).
pub const SHOWING: f64 = 0.25;

/// The campaign's counting window from each run's sample rate (Hz) and its axles' troughs:
/// the troughs that are windows ([`Trough::is_window`]) whose length (lag / fs) is within half a sample of
/// their median, when they are at least [`AGREEING`] of all the axles looked at (axles
/// without a trough count as looked at); the window is their mean. Windows are compared in
/// seconds: a counter set in samples at two logging rates shows two windows, too few agree,
/// and the note says so. Err with what was seen when at least [`SHOWING`] of the axles show
/// a window but too few agree (for the note); Ok(None) when fewer show one.
pub fn campaign_window(
    runs: &[(f64, Vec<Option<Trough>>)],
) -> Result<Option<Window>, (usize, usize)> {
    let looked_at: usize = runs.iter().map(|(_, t)| t.len()).sum();
    let mut shown: Vec<(f64, f64, f64)> = runs
        .iter()
        .flat_map(|(fs, troughs)| {
            troughs
                .iter()
                .flatten()
                .filter(|t| t.is_window())
                .map(move |t| (t.lag as f64 / fs, 0.5 / fs, t.acf))
        })
        .collect();
    if shown.is_empty() || (shown.len() as f64) < SHOWING * looked_at as f64 {
        return Ok(None);
    }
    shown.sort_by(|a, b| a.0.total_cmp(&b.0));
    let median = shown[shown.len() / 2].0;
    let agree: Vec<&(f64, f64, f64)> = shown
        .iter()
        .filter(|(w, half, _)| (w - median).abs() <= half * (1.0 + 1e-9))
        .collect();
    if (agree.len() as f64) < AGREEING * looked_at as f64 {
        return Err((agree.len(), looked_at));
    }
    let n = agree.len() as f64;
    Ok(Some(Window {
        window_s: agree.iter().map(|a| a.0).sum::<f64>() / n,
        showing: agree.len(),
        looked_at,
        mean_acf: agree.iter().map(|a| a.2).sum::<f64>() / n,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A counter over `window` samples of a wheel turning at a slowly varying rate.
    fn counted(window: usize, n: usize, fs: f64, pulses_per_rev: f64) -> Vec<f64> {
        let dtheta = std::f64::consts::TAU / pulses_per_rev;
        let h = 1.0 / fs;
        let mut theta = 0.0;
        let mut angles = Vec::with_capacity(n);
        for k in 0..n {
            let t = k as f64 * h;
            let omega = 100.0 - 1.5 * t + 2.0 * (2.0 * std::f64::consts::PI * 0.7 * t).sin();
            theta += omega * h;
            angles.push(theta);
        }
        (0..n)
            .map(|k| {
                let j = k.saturating_sub(window);
                let span = (k - j).max(1) as f64;
                ((angles[k] / dtheta).floor() - (angles[j] / dtheta).floor()) * dtheta / (span * h)
            })
            .collect()
    }

    #[test]
    fn the_trough_is_at_the_counting_window() {
        for window in [1, 4, 8, 13] {
            let x = counted(window, 20_000, 417.0, 1000.0);
            let t = deepest_trough(&x, 417.0).unwrap();
            assert_eq!(t.lag, window, "{t:?}");
            assert!(t.acf <= -0.4 && t.is_window(), "{t:?}");
        }
    }

    #[test]
    fn a_coarse_counter_still_shows_its_window() {
        // 100 pulses per revolution: the fractions rotate more regularly, the flank grows.
        for window in [4, 8] {
            let x = counted(window, 20_000, 417.0, 100.0);
            let t = deepest_trough(&x, 417.0).unwrap();
            assert!(t.lag == window && t.is_window(), "{t:?}");
        }
    }

    #[test]
    fn a_smooth_channel_shows_no_window() {
        let fs = 417.0;
        let x: Vec<f64> = (0..20_000)
            .map(|k| {
                let t = k as f64 / fs;
                100.0 - 1.5 * t + 2.0 * (2.0 * std::f64::consts::PI * 0.7 * t).sin()
            })
            .collect();
        // Only the filter's round-off is left: no trough anywhere near a window's.
        assert!(deepest_trough(&x, fs).is_none_or(|t| !t.is_window()));
    }

    #[test]
    fn a_kinked_channel_rings_but_shows_no_window() {
        // Exact ω whose deceleration changes in steps (a wheel-slide protection's cycles):
        // the low-pass rings after each kink, a broad trough, not a counting window.
        let fs = 417.0;
        let mut omega = 120.0;
        let x: Vec<f64> = (0..20_000)
            .map(|k| {
                let phase = (k / 300) % 2;
                omega -= if phase == 0 { 2.0 } else { 9.0 } / fs;
                omega
            })
            .collect();
        let t = deepest_trough(&x, fs).unwrap();
        assert!(!t.is_window(), "{t:?}");
        assert!(t.flank > FLANK, "{t:?}");
    }

    #[test]
    fn gaps_split_the_channel_and_short_stretches_are_skipped() {
        let mut x = counted(8, 20_000, 417.0, 1000.0);
        for v in &mut x[9_000..9_010] {
            *v = f64::NAN;
        }
        assert_eq!(deepest_trough(&x, 417.0).unwrap().lag, 8);
        assert!(deepest_trough(&x[..800], 417.0).is_none());
    }

    #[test]
    fn the_campaign_needs_three_quarters_of_its_axles_to_agree() {
        let t = |lag, acf| {
            Some(Trough {
                lag,
                acf,
                flank: 0.05,
            })
        };
        let agree = vec![(417.0, vec![t(8, -0.5), t(8, -0.52), t(8, -0.5), None])];
        let w = campaign_window(&agree).unwrap().unwrap();
        assert!((w.window_s - 8.0 / 417.0).abs() < 1e-12);
        assert!((w.delay_s() - 4.0 / 417.0).abs() < 1e-12);
        assert_eq!((w.showing, w.looked_at), (3, 4));
        let split = vec![(417.0, vec![t(8, -0.5), t(3, -0.5), t(8, -0.5), t(3, -0.5)])];
        assert_eq!(campaign_window(&split), Err((2, 4)));
        let shallow = vec![(417.0, vec![t(8, -0.1); 4])];
        assert_eq!(campaign_window(&shallow), Ok(None));
        // One axle of eight with a window is noise, not a reason for a note.
        let mut one = vec![None; 8];
        one[3] = t(8, -0.5);
        assert_eq!(campaign_window(&[(417.0, one)]), Ok(None));
    }
}
