//! The radar's white noise, read from its own samples, and what the conditioning's low-pass
//! leaves of it: the yardstick the campaign calibration's residual is held against
//! ([`super::selfcal::IntegratedBalance::residual_over_radar_noise`]).
//!
//! **The reading.** Between 10 and 40 Hz a braking vehicle's speed has no content a radar
//! could see (the body's mass smooths it; the filters' cut-offs are 1.5–4 Hz), so what the
//! radar shows there is its noise [assumed: true of the simulated radar; a real radar whose
//! beam sees the body's or bogies' vibration reads it as noise, and the residual then comes out
//! well below what that "noise" would leave, which the `calibrate` command says]. Each valid
//! stretch of the raw radar is despiked as the conditioning does
//! ([`crate::signal::despike::despike`] with the pipeline's `[filters.despike]`), band-passed
//! by the difference of two zero-phase 4th-order Butterworth low-passes (40 and 10 Hz), and its
//! robust spread 1.4826 MAD taken over the samples above the lowest speed, 0.25 s in from each
//! stretch's ends; the white noise per sample is that spread over the band's noise gain
//! √(Σ h²) (h the band-pass's impulse response, computed, not assumed). A radar resampled onto
//! the time base by linear interpolation loses at most ~5 % of its noise's variance in that
//! band (a half-sample offset: |cos(π f/f_s)|² at 40 Hz and 417 Hz is 0.91), where second
//! differences would lose five sixths of it. A radar logged at another rate than the time base
//! is not read (its samples are interpolated ones).
//!
//! **What the low-pass leaves.** White noise of σ per sample through a filter of impulse
//! response h has the variance σ² Σ h² per sample ([`lowpass_noise_gain`], in the
//! conditioning's mode: forward–backward or one pass).

use crate::config::{DespikeConfig, FilterMode};
use crate::ingest::RunLog;
use crate::signal::filter::{zero_phase_many, LowPass4, MIN_LEN};

/// The band the radar's noise is read in, Hz (a rate of at least 100 Hz: the upper edge at
/// most 0.4 × the rate).
pub const NOISE_BAND_HZ: (f64, f64) = (10.0, 40.0);

/// The fewest band-passed samples a noise is read from.
const MIN_SAMPLES: usize = 1000;

/// Samples left out at each end of a stretch, s (the band-pass's settling).
const EDGE_S: f64 = 0.25;

/// Why a run's radar noise could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unknown {
    /// The radar was logged at another rate than the time base (more than 5 % apart), or
    /// below 100 Hz (too low for the band).
    OtherRate,
    /// Fewer than [`MIN_SAMPLES`] samples above the lowest speed in stretches long enough.
    TooFew,
}

/// The radar's white noise of `log`, m/s rms per sample (see the module's documentation);
/// `min_speed` (m/s) the lowest speed whose samples count.
pub fn radar_white_noise(
    log: &RunLog,
    despike: Option<DespikeConfig>,
    min_speed: f64,
) -> Result<f64, Unknown> {
    let rate = log
        .channels
        .iter()
        .find(|c| c.signal == crate::format::Signal::VRadar)
        .map_or(f64::NAN, |c| c.rate_hz);
    if !((rate / log.sample_rate_hz - 1.0).abs() <= 0.05) {
        return Err(Unknown::OtherRate);
    }
    band_noise(
        &log.v_radar_mps,
        &crate::signal::segments(log),
        log.sample_rate_hz,
        despike,
        min_speed,
    )
}

/// [`radar_white_noise`] on the samples `v` (m/s) at `fs` (Hz), over the stretches `segs`
/// (half-open index ranges of valid samples).
pub fn band_noise(
    v: &[f64],
    segs: &[(usize, usize)],
    fs: f64,
    despike: Option<DespikeConfig>,
    min_speed: f64,
) -> Result<f64, Unknown> {
    let (lo, hi) = NOISE_BAND_HZ;
    if !(hi <= 0.4 * fs) {
        return Err(Unknown::OtherRate);
    }
    let (Ok(f_lo), Ok(f_hi)) = (LowPass4::butterworth(lo, fs), LowPass4::butterworth(hi, fs))
    else {
        return Err(Unknown::OtherRate);
    };
    let edge = (EDGE_S * fs).round() as usize;
    let mut band = Vec::new();
    for &(a, b) in segs {
        let (a, b) = (a.min(v.len()), b.min(v.len()));
        if b.saturating_sub(a) < 2 * edge + MIN_LEN {
            continue;
        }
        let mut x = v[a..b].to_vec();
        if x.iter().any(|s| !s.is_finite()) {
            continue;
        }
        if let Some(d) = &despike {
            crate::signal::despike::despike(&mut x, d, fs);
        }
        let (mut h, mut l) = (vec![0.0; x.len()], vec![0.0; x.len()]);
        if zero_phase_many(&[f_hi, f_lo], [&x, &x], [&mut h, &mut l]).is_err() {
            continue;
        }
        band.extend(
            (edge..x.len() - edge)
                .filter(|&k| x[k] >= min_speed)
                .map(|k| h[k] - l[k]),
        );
    }
    if band.len() < MIN_SAMPLES {
        return Err(Unknown::TooFew);
    }
    let centre = median(&mut band);
    let mut dev: Vec<f64> = band.iter().map(|d| (d - centre).abs()).collect();
    let spread = 1.4826 * median(&mut dev);
    let gain = impulse_energy(fs, |x| {
        let (mut h, mut l) = (vec![0.0; x.len()], vec![0.0; x.len()]);
        zero_phase_many(&[f_hi, f_lo], [x, x], [&mut h, &mut l]).expect("long enough");
        h.iter().zip(&l).map(|(a, b)| a - b).collect()
    });
    Ok(spread / gain.sqrt())
}

/// Σ h² of the radar's low-pass at `cutoff_hz` and `fs` (Hz) in the conditioning's `mode`:
/// what it leaves of white noise of unit variance per sample.
pub fn lowpass_noise_gain(cutoff_hz: f64, fs: f64, mode: FilterMode) -> Option<f64> {
    let f = LowPass4::butterworth(cutoff_hz, fs).ok()?;
    Some(impulse_energy(fs, |x| match mode {
        FilterMode::ZeroPhase => f.zero_phase(x).expect("long enough"),
        FilterMode::Causal => f.causal(x),
    }))
}

/// Σ y² of `filter`'s response to a unit impulse in the middle of 10 s of zeros at `fs` (Hz):
/// long enough for the slowest filter here (1.5 Hz: its slowest poles decay by e in 0.28 s, so
/// 5 s leave e^-18 of the response).
fn impulse_energy(fs: f64, filter: impl Fn(&[f64]) -> Vec<f64>) -> f64 {
    let n = ((10.0 * fs).round() as usize).max(2 * MIN_LEN);
    let mut x = vec![0.0; n];
    x[n / 2] = 1.0;
    filter(&x).iter().map(|y| y * y).sum()
}

fn median(x: &mut [f64]) -> f64 {
    let m = x.len() / 2;
    *x.select_nth_unstable_by(m, f64::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;

    const FS: f64 = 417.0;

    /// A braking run's speed (m/s) at 417 Hz, `n` samples: a ramp with a slow wave.
    fn braking(n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let t = k as f64 / FS;
                (50.0 - t + 0.2 * (0.7 * t).sin()).max(0.0)
            })
            .collect()
    }

    fn despike() -> Option<DespikeConfig> {
        Some(DespikeConfig {
            half_window_s: 0.05,
            threshold: 3.0,
            min_deviation_mps: 0.3,
        })
    }

    /// 0.05 m/s of white noise on a braking run of 38 s, with spikes of ±3 m/s at 0.3 per
    /// second and every reading rounded to 1 mm/s: read within 5 % on each of 20 draws (the
    /// median's own scatter over ~2 300 independent band samples is ~2.4 %) and within 1 % on
    /// their mean; the same radar linearly interpolated half a sample off its own instants
    /// within 7 % each and 4 % on the mean (the interpolation takes up to ~5 % of the band's
    /// variance).
    #[test]
    fn the_radars_noise_is_read_between_10_and_40_hz() {
        let n = 16_000;
        let truth = braking(n);
        let round = |x: f64| (x * 1e3).round() / 1e3;
        let (mut grid, mut interp) = (Vec::new(), Vec::new());
        for seed in 1..=20 {
            let mut rng = crate::rng::Rng::new(seed);
            let noisy: Vec<f64> = truth
                .iter()
                .map(|v| {
                    let spike = if rng.uniform() < 0.3 / FS {
                        3.0 * (rng.uniform() - 0.5).signum()
                    } else {
                        0.0
                    };
                    v + 0.05 * rng.normal() + spike
                })
                .collect();
            let on_grid: Vec<f64> = noisy.iter().map(|v| round(*v)).collect();
            grid.push(band_noise(&on_grid, &[(0, n)], FS, despike(), 1.0).unwrap() / 0.05);
            let half: Vec<f64> = (0..n - 1)
                .map(|k| round(0.5 * (noisy[k] + noisy[k + 1])))
                .collect();
            interp.push(band_noise(&half, &[(0, n - 1)], FS, despike(), 1.0).unwrap() / 0.05);
        }
        let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
        eprintln!("on the grid {grid:?}\ninterpolated {interp:?}");
        assert!(grid.iter().all(|r| (r - 1.0).abs() <= 0.05), "{grid:?}");
        assert!((mean(&grid) - 1.0).abs() <= 0.01, "{grid:?}");
        assert!(interp.iter().all(|r| (r - 1.0).abs() <= 0.07), "{interp:?}");
        assert!((mean(&interp) - 1.0).abs() <= 0.04, "{interp:?}");
    }

    /// Without noise only the rounding's remainder is read (1 mm/s steps: ~0.3 mm/s); too few
    /// samples, samples below the lowest speed, a stretch with a gap in it, or a rate too low
    /// for the band give none.
    #[test]
    fn a_quiet_radar_and_too_little_data_are_told() {
        let n = 16_000;
        let quiet: Vec<f64> = braking(n).iter().map(|v| (v * 1e3).round() / 1e3).collect();
        let sd = band_noise(&quiet, &[(0, n)], FS, despike(), 1.0).unwrap();
        assert!(sd < 0.001, "{sd}");
        assert_eq!(
            band_noise(&quiet[..800], &[(0, 800)], FS, despike(), 1.0),
            Err(Unknown::TooFew)
        );
        assert_eq!(
            band_noise(&quiet, &[(0, n)], FS, despike(), 60.0),
            Err(Unknown::TooFew)
        );
        let mut holes = quiet.clone();
        holes[100] = f64::NAN;
        assert_eq!(
            band_noise(&holes, &[(0, n)], FS, despike(), 1.0),
            Err(Unknown::TooFew)
        );
        assert_eq!(
            band_noise(&quiet, &[(0, n)], 50.0, despike(), 1.0),
            Err(Unknown::OtherRate)
        );
    }

    /// The low-pass's noise gain: a 4th-order Butterworth's noise bandwidth is 1.026 × its
    /// cut-off, so one pass leaves 2 × 1.026 f_c / f_s of white noise's variance; forward and
    /// backward (|H|⁴) leave 2 × 0.898 f_c / f_s (
    /// ∫ dx / (1 + x⁸)² = Γ(1/8) Γ(15/8) / 8 = 0.8979).
    #[test]
    fn the_lowpass_noise_gain_is_its_noise_bandwidth() {
        let one = lowpass_noise_gain(1.5, FS, FilterMode::Causal).unwrap();
        assert!((one / (2.0 * 1.026 * 1.5 / FS) - 1.0).abs() < 0.01, "{one}");
        let two = lowpass_noise_gain(1.5, FS, FilterMode::ZeroPhase).unwrap();
        assert!(
            (two / (2.0 * 0.8979 * 1.5 / FS) - 1.0).abs() < 0.01,
            "{two}"
        );
        assert_eq!(lowpass_noise_gain(300.0, FS, FilterMode::Causal), None);
    }
}
