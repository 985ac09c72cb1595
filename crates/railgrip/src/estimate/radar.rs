//! The radar's scale from a run's own data: the first step of a campaign's self-calibration
//! (the radar against the wheels, the wheel radius of the pipeline taken as known).
//!
//! A Doppler radar whose mounting angle is off reads a scaled speed: v_radar = s v. While no
//! brake acts (every cylinder below `estimate.min_pressure_bar`) the wheels roll without
//! creep, so v = r ω̄ (ω̄ the mean of the four axles' filtered speeds, r the pipeline's wheel
//! radius), and the speed is nearly constant, so a radar latency does not matter: s is the
//! least-squares slope of v_radar on r ω̄ through the origin, s = Σ v_radar r ω̄ / Σ (r ω̄)²,
//! with a standard error from the residuals inflated for their autocorrelation (n_eff, as
//! [`super::calibrate`] does). Units: s (–).
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
    /// Samples with every brake released the scale rests on.
    pub scale_samples: usize,
}

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

    // Scale: brakes released, rolling, settled.
    let (mut sxy, mut sxx) = (0.0, 0.0);
    let mut pairs = Vec::new();
    for k in 0..n {
        let v = c.v_mps[k];
        let w = r * omega_mean(k);
        let released = (0..AXLES).all(|a| c.p_bar[a][k] < est.min_pressure_bar);
        if c.settled[k] && released && v >= est.min_speed_mps && w >= est.min_speed_mps {
            sxy += v * w;
            sxx += w * w;
            pairs.push((w, v));
        }
    }
    if pairs.len() < 50 {
        return Err(fail(
            format!(
                "only {} samples with every brake released above {} m/s: too few for the radar's scale",
                pairs.len(),
                est.min_speed_mps
            ),
            "calibrate on runs that coast for a second or more before the brake is applied",
        ));
    }
    let scale = sxy / sxx;
    let resid: Vec<f64> = pairs.iter().map(|(w, v)| v - scale * w).collect();
    let m = resid.len() as f64;
    let s2 = resid.iter().map(|e| e * e).sum::<f64>() / (m - 1.0);
    let n_eff = effective_samples(&resid).max(1.0);
    let scale_se = (s2 / sxx).sqrt() * (m / n_eff).sqrt();

    Ok(RadarCalibration {
        scale,
        scale_se,
        scale_samples: pairs.len(),
    })
}
