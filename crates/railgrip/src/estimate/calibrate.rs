//! Brake-coefficient calibration from a full-adhesion (dry) run.
//!
//! Seed 002 (002_8d8769283f5e9cb6.txt, after eq. 10): "The brake pad friction factor can be
//! easily verified or extrapolated from the braking test with full adhesion conditions
//! exploiting the proportionality between vehicle deceleration and applied braking forces."
//!
//! The vehicle's longitudinal balance with the wheel torque balance (eq. 9–10) substituted
//! for the contact forces, M v̇ = −Σ_i T_i − R(v), T_i = (J ω̇_i + α_i p_i)/r, gives the linear
//! model
//!
//! y = −(M v̇ + (J/r) Σ_i ω̇_i) = Σ_i α_i (p_i / r) + c0 + c2 v²        [N]
//!
//! with M the translating mass (kg), v̇ (m/s²) and ω̇_i (rad/s²) the derivatives of the
//! filtered signals, p_i (bar), r (m), J (kg·m²), and the nuisance terms c0 (N: constant
//! running resistance and gradient) and c2 (N·s²/m²: aerodynamic drag). α is common to the
//! axles (one regressor Σ p_i / r) or per axle (four regressors, identifiable only when the
//! pressures differ between axles). Ordinary least squares on standardised columns by
//! Cholesky; the standard errors come from σ²(XᵀX)⁻¹ inflated for the residuals'
//! autocorrelation (filtered signals at 417 Hz are far from independent): n_eff =
//! n / (1 + 2 Σ ρ_k) from the residuals' autocorrelations ρ_k, and se × √(n / n_eff).
//!
//! With the resistance fitted, α rests on how the pressure varies against the constant term
//! (mostly the brake application); a known Davis resistance A + B v + C v² (`--davis`) is
//! subtracted instead and only α is fitted, which is far better determined.
//!
//! Samples used: conditioned and settled (away from segment ends), speed ≥ `estimate.min_speed_mps`, every wheel rolling and none
//! sliding (Δv_i below `estimate.sliding_threshold_mps`) — full adhesion is the premise.

// `!(x >= lo)` is deliberate: a NaN fails the check instead of passing it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::config::Pipeline;
use crate::format::AXLES;
use crate::ingest::RunLog;
use crate::linalg::{cho_solve, cholesky, effective_samples};
use crate::signal;
use crate::vehicle::total_mass_kg;

use super::EstimateError;

/// Common α for all axles, or one per axle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlphaFit {
    Common,
    PerAxle,
}

/// How the running resistance (and gradient) enters the balance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Resistance {
    /// Fit c0 + c2 v² alongside α.
    Fit,
    /// Known Davis resistance A + B v + C v² (N, N·s/m, N·s²/m²), subtracted before fitting α.
    Davis {
        a_n: f64,
        b_n_s_per_m: f64,
        c_n_s2_per_m2: f64,
    },
}

/// Result of a calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// α_i, N·m/bar (4 values; equal for a common fit).
    pub alpha_nm_per_bar: [f64; AXLES],
    /// One standard error of each α_i, N·m/bar.
    pub alpha_se: [f64; AXLES],
    pub fit: AlphaFit,
    /// Constant resistance c0 (running resistance + gradient), N; NaN when not fitted.
    pub c0_n: f64,
    /// Quadratic resistance c2, N·s²/m²; NaN when not fitted.
    pub c2_n_s2_per_m2: f64,
    /// Samples used.
    pub samples: usize,
    /// Effective independent samples after the autocorrelation correction.
    pub effective_samples: f64,
    /// RMS of the residual force, N.
    pub rms_residual_n: f64,
}

impl Calibration {
    /// The line to put into `[vehicle]` of the pipeline file.
    pub fn toml_line(&self) -> String {
        let vals: Vec<String> = self
            .alpha_nm_per_bar
            .iter()
            .map(|a| format!("{a:.1}"))
            .collect();
        format!("brake_torque_nm_per_bar = [{}]", vals.join(", "))
    }
}

/// Calibrates α from a conditioned full-adhesion run.
pub fn calibrate(
    log: &RunLog,
    pipeline: &Pipeline,
    fit: AlphaFit,
    resistance: Resistance,
) -> Result<Calibration, EstimateError> {
    let fail = |what: String, hint: &str| EstimateError::Calibration {
        file: log.source.clone(),
        what,
        hint: hint.to_string(),
    };
    let c = signal::condition(log, &pipeline.filters).map_err(|source| EstimateError::Filter {
        file: log.source.clone(),
        source,
    })?;
    let k_alpha = match fit {
        AlphaFit::Common => 1,
        AlphaFit::PerAxle => AXLES,
    };
    let k = match resistance {
        Resistance::Fit => k_alpha + 2,
        Resistance::Davis { .. } => k_alpha,
    };
    let rows = balance_rows(&c, pipeline, fit, resistance, k_alpha);
    let n = rows.len();
    if n < 10 * k {
        return Err(fail(
            format!("only {n} samples at full adhesion with the brake data needed"),
            "calibrate on a dry run where the wheels do not slide (e.g. fixtures/archive/dry_120kmh_p20.csv)",
        ));
    }
    let not_apart =
        "the axles' pressures move together, so their α cannot be told apart: use the common fit";
    let ls = least_squares(&rows, k).map_err(|cond| match cond {
        None => fail(
            "the regressors are linearly dependent".into(),
            "the pressures do not vary enough against the speed; use a run with a brake application from coasting",
        ),
        Some(cond) => fail(
            format!("the least-squares problem is ill-conditioned (condition number {cond:.1e})"),
            match fit {
                AlphaFit::PerAxle => not_apart,
                AlphaFit::Common => "the pressure barely varies against the speed; use a run with a brake application from coasting",
            },
        ),
    })?;
    let (alpha, alpha_se) = match fit {
        AlphaFit::Common => ([ls.beta[0]; AXLES], [ls.se[0]; AXLES]),
        AlphaFit::PerAxle => (
            std::array::from_fn(|a| ls.beta[a]),
            std::array::from_fn(|a| ls.se[a]),
        ),
    };
    let worst = alpha
        .iter()
        .zip(&alpha_se)
        .map(|(a, e)| e / a.abs())
        .fold(
            0.0f64,
            |m, r| if r.is_nan() { f64::INFINITY } else { m.max(r) },
        );
    if worst > 0.2 {
        return Err(fail(
            format!(
                "α is not identifiable from this run: α = {:?} N·m/bar with standard errors up to {:.0} %",
                alpha.map(|a| (a * 10.0).round() / 10.0),
                worst * 100.0
            ),
            match fit {
                AlphaFit::PerAxle => not_apart,
                AlphaFit::Common => "the pressure barely varies against the speed; give the running resistance with --davis or use a run with a brake application from coasting",
            },
        ));
    }
    if alpha.iter().any(|a| !(*a > 0.0)) {
        return Err(fail(
            format!("the fit gives a non-positive brake coefficient {alpha:?}"),
            "check that the run is a braking run at full adhesion and that the pressures are mapped to the right axles",
        ));
    }
    Ok(Calibration {
        alpha_nm_per_bar: alpha,
        alpha_se,
        fit,
        c0_n: ls.beta.get(k_alpha).copied().unwrap_or(f64::NAN),
        c2_n_s2_per_m2: ls.beta.get(k_alpha + 1).copied().unwrap_or(f64::NAN),
        samples: n,
        effective_samples: ls.n_eff,
        rms_residual_n: (ls.rss / n as f64).sqrt(),
    })
}

/// One row (regressors, target) of the longitudinal balance per settled full-adhesion sample:
/// y = −(M v̇ + (J/r) Σ ω̇_i) − R_known(v), x = Σp_i/r (or p_i/r per axle) and, when the
/// resistance is fitted, 1 and v² (columns `k_alpha`, `k_alpha + 1`).
fn balance_rows(
    c: &signal::Conditioned,
    pipeline: &Pipeline,
    fit: AlphaFit,
    resistance: Resistance,
    k_alpha: usize,
) -> Vec<([f64; AXLES + 2], f64)> {
    let veh = &pipeline.vehicle;
    let cfg = &pipeline.estimate;
    let r = veh.wheel_radius_m;
    let m = total_mass_kg(veh);
    let j_r = veh.axle_inertia_kgm2 / r;
    let mut rows = Vec::new();
    for i in 0..c.v_mps.len() {
        let v = c.v_mps[i];
        if !c.settled[i] || !(v >= cfg.min_speed_mps) {
            continue;
        }
        let full_adhesion = (0..AXLES).all(|a| {
            let rw = r * c.omega_radps[a][i];
            rw >= cfg.locked_wheel_speed_mps && (v - rw).abs() < cfg.sliding_threshold_mps
        });
        if !full_adhesion {
            continue;
        }
        let known = match resistance {
            Resistance::Fit => 0.0,
            Resistance::Davis {
                a_n,
                b_n_s_per_m,
                c_n_s2_per_m2,
            } => a_n + b_n_s_per_m * v + c_n_s2_per_m2 * v * v,
        };
        let y = -(m * c.accel_mps2[i]
            + j_r * (0..AXLES).map(|a| c.omega_dot_radps2[a][i]).sum::<f64>())
            - known;
        let mut x = [0.0; AXLES + 2];
        match fit {
            AlphaFit::Common => x[0] = (0..AXLES).map(|a| c.p_bar[a][i]).sum::<f64>() / r,
            AlphaFit::PerAxle => {
                for (xa, p) in x.iter_mut().zip(&c.p_bar) {
                    *xa = p[i] / r;
                }
            }
        }
        if resistance == Resistance::Fit {
            x[k_alpha] = 1.0;
            x[k_alpha + 1] = v * v;
        }
        if y.is_finite() && x.iter().all(|v| v.is_finite()) {
            rows.push((x, y));
        }
    }
    rows
}

/// A least-squares solution with its standard errors.
struct LeastSquares {
    beta: Vec<f64>,
    /// Standard errors from σ²(XᵀX)⁻¹, inflated by √(n / n_eff) for the residuals'
    /// autocorrelation (filtered signals).
    se: Vec<f64>,
    rss: f64,
    n_eff: f64,
}

/// Ordinary least squares on the first `k` columns of `rows` by Cholesky on standardised
/// columns (the constant stays 1, so the normal matrix is well scaled). Err(None) when XᵀX is
/// not positive definite, Err(Some(κ)) when its condition number κ (estimated from the
/// Cholesky pivots) exceeds 1e10.
fn least_squares(rows: &[([f64; AXLES + 2], f64)], k: usize) -> Result<LeastSquares, Option<f64>> {
    let n = rows.len();
    let mut scale = [1.0f64; AXLES + 2];
    for (col, s) in scale.iter_mut().enumerate().take(k) {
        let rms = (rows.iter().map(|(x, _)| x[col] * x[col]).sum::<f64>() / n as f64).sqrt();
        if rms > 0.0 {
            *s = rms;
        }
    }
    let mut ata = vec![0.0; k * k];
    let mut aty = vec![0.0; k];
    for (x, y) in rows {
        for p in 0..k {
            let xp = x[p] / scale[p];
            aty[p] += xp * y;
            for q in 0..=p {
                ata[p * k + q] += xp * x[q] / scale[q];
            }
        }
    }
    for p in 0..k {
        for q in 0..p {
            ata[q * k + p] = ata[p * k + q];
        }
    }
    let l = cholesky(&ata, k).ok_or(None)?;
    // Condition number estimate from the Cholesky diagonal (ratio of extreme pivots, squared).
    let (dmin, dmax) = (0..k)
        .map(|p| l[p * k + p])
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), d| {
            (lo.min(d), hi.max(d))
        });
    let cond = (dmax / dmin).powi(2);
    if !(cond < 1e10) {
        return Err(Some(cond));
    }
    let beta_s = cho_solve(&l, k, &aty);
    let beta: Vec<f64> = (0..k).map(|p| beta_s[p] / scale[p]).collect();
    let resid: Vec<f64> = rows
        .iter()
        .map(|(x, y)| y - (0..k).map(|p| x[p] * beta[p]).sum::<f64>())
        .collect();
    let rss: f64 = resid.iter().map(|e| e * e).sum();
    let sigma2 = rss / (n - k) as f64;
    let n_eff = effective_samples(&resid);
    let inflate = (n as f64 / n_eff).sqrt();
    let se = (0..k)
        .map(|p| {
            let mut e = vec![0.0; k];
            e[p] = 1.0;
            let col = cho_solve(&l, k, &e);
            (sigma2 * col[p]).sqrt() / scale[p] * inflate
        })
        .collect();
    Ok(LeastSquares {
        beta,
        se,
        rss,
        n_eff,
    })
}
