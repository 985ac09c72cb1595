//! The radar's scale from a run's own data: the first step of a campaign's self-calibration
//! (the radar against the wheels, the wheel radius of the pipeline taken as known).
//!
//! A Doppler radar whose mounting angle is off reads a scaled speed: v_radar = s v. In the
//! coast before the first brake application (every cylinder below
//! `estimate.min_pressure_bar`) the wheels roll without creep, so v = r ω̄ (ω̄ the mean of the
//! four axles' filtered speeds, r the pipeline's wheel radius): s is the least-squares slope of
//! v_radar on r ω̄ through the origin, s = Σ v_radar r ω̄ / Σ (r ω̄)². Its standard error
//! combines the residuals' (inflated for their autocorrelation: n_eff, as
//! [`super::calibrate`] does) with what an unknown radar delay of up to [`MAX_LATENCY_S`] makes
//! of the coast's slow deceleration a (running resistance): a delay τ reads as a scale
//! 1 − τ a / v, 2 × 10⁻⁴ for 30 ms at 0.3 m/s² and 44 m/s. (Fitting v_radar = s r ω̄ + b a to
//! take the delay out was tried: over a coast of a second the two are too alike, and the
//! errors grew to 5 × 10⁻⁴.) What is fitted is s r_true / r_pipeline: a worn wheel reads like
//! a radar scale. s is dimensionless.
//!
//! The radar's latency is not fitted here. Matching the radar's deceleration with the wheels'
//! over the phases without sliding finds a delay that is not there: while the brake force
//! changes, the creep changes with it, so the wheels decelerate faster than the vehicle
//! exactly where the deceleration changes, and that looks like a delay. Measured on simulated
//! runs: 157 ms for a true 30 ms on soap, and ~200 ms (at the edge of the search) on dry rail
//! with an exact radar, where the wheels decelerated ~0.08 m/s² faster than the vehicle
//! throughout a 1.5 s brake ramp. A latency fit has to model the creep (it grows with each
//! axle's force, which α_i p_i gives) or use phases where the force is constant.

// `!(x >= lo)` is deliberate: a NaN fails the check instead of passing it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::config::Pipeline;
use crate::format::AXLES;
use crate::ingest::RunLog;
use crate::linalg::effective_samples;
use crate::signal;

use super::EstimateError;

/// The radar's calibration from one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RadarCalibration {
    /// Radar reading / true speed (–).
    pub scale: f64,
    /// One standard error of the scale (–).
    pub scale_se: f64,
    /// Samples of the coast before the first brake application the scale rests on.
    pub scale_samples: usize,
}

/// The radar delays the scale's standard error allows for, s (not fitted; see the module's
/// documentation).
pub const MAX_LATENCY_S: f64 = 0.05;

/// Calibrates the radar's scale on `log` (see the module's documentation).
/// Errors name the file and say what the run lacks.
pub fn calibrate_radar(
    log: &RunLog,
    pipeline: &Pipeline,
) -> Result<RadarCalibration, EstimateError> {
    let fail = |what: String, hint: &str| EstimateError::Calibration {
        file: log.source.clone(),
        what,
        hint: hint.to_string(),
    };
    let filter_err = |source| EstimateError::Filter {
        file: log.source.clone(),
        source,
    };
    let c = signal::condition(log, &pipeline.filters).map_err(filter_err)?;
    let r = pipeline.vehicle.wheel_radius_m;
    let est = &pipeline.estimate;
    let n = c.v_mps.len();
    let omega_mean = |k: usize| (0..AXLES).map(|a| c.omega_radps[a][k]).sum::<f64>() / AXLES as f64;

    // The coast before the first brake application: every cylinder below the threshold,
    // rolling, settled (a release later in the run, by the WSP or the driver, may come with
    // wheels still recovering from a slide).
    let first_brake = (0..n)
        .find(|&k| (0..AXLES).any(|a| c.p_bar[a][k] >= est.min_pressure_bar))
        .unwrap_or(n);
    let (mut sxy, mut sxx, mut sum_a, mut sum_w) = (0.0, 0.0, 0.0, 0.0);
    let mut pairs = Vec::new();
    for k in 0..first_brake {
        let v = c.v_mps[k];
        let w = r * omega_mean(k);
        let a = c.accel_mps2[k];
        if c.settled[k] && v >= est.min_speed_mps && w >= est.min_speed_mps && a.is_finite() {
            sxy += v * w;
            sxx += w * w;
            sum_a += a;
            sum_w += w;
            pairs.push((w, v));
        }
    }
    let m = pairs.len();
    let too_few = |what: String| {
        fail(
            what,
            "calibrate on runs that coast for a second or more before the brake is applied",
        )
    };
    if m < 100 {
        return Err(too_few(format!(
            "only {m} samples with every brake released above {} m/s before the first application: too few for the radar's scale",
            est.min_speed_mps
        )));
    }
    let scale = sxy / sxx;
    let resid: Vec<f64> = pairs.iter().map(|(w, v)| v - scale * w).collect();
    let s2 = resid.iter().map(|e| e * e).sum::<f64>() / (m as f64 - 1.0);
    let n_eff = effective_samples(&resid);
    if n_eff < 3.0 {
        return Err(too_few(format!(
            "the {m} samples of the coast are worth {n_eff:.1} independent ones: too few for the radar's scale"
        )));
    }
    let noise_se = (s2 / sxx).sqrt() * (m as f64 / n_eff).sqrt();
    // A radar delay τ reads as s (1 − τ a / v) while the coast decelerates: its share, for
    // delays up to MAX_LATENCY_S, joins the noise's in the standard error.
    let latency_se = MAX_LATENCY_S * (sum_a / m as f64).abs() / (sum_w / m as f64);
    let scale_se = noise_se.hypot(latency_se);
    Ok(RadarCalibration {
        scale,
        scale_se,
        scale_samples: m,
    })
}
