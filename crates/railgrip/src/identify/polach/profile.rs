//! Profile-likelihood intervals of a fit's estimated parameters (Venzon & Moolgavkar 1988).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::law::{law_params, ParamStatus, Sample, LOWER, PARAMETERS, UPPER};
use super::problem::{constant_nodes, profile_settings, solve};
use super::problem::{Covariance, PolachProblem};

/// The profile likelihood of one parameter: at each value the others refitted, the statistic
/// Δ(x) = (SSE(x) − SSE_min) / (σ² n/n_eff) (the likelihood-ratio statistic of Gaussian
/// residuals, with σ² = SSE_min/(n − k) and the autocorrelation correction n/n_eff of the
/// standard errors); the 95 % interval is where Δ ≤ χ²₁(0.95) = 3.841 (Venzon & Moolgavkar,
/// Appl. Statist. 37 (1988) 87–94). Unlike the Wald interval (±1.96 se) it follows the
/// law's curvature, so it may be asymmetric.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    /// `mu0`, `a_ratio`, `b_s_per_m`, `k_a` or `k_s`; `speed_c1`, … for a speed law's
    /// coefficients.
    pub parameter: String,
    pub estimate: f64,
    /// The interval's limits, interpolated linearly in √Δ between the profile points around
    /// 3.841; null where the profile stays below it up to the parameter's bound (or 32
    /// standard errors): not bounded by these data on that side.
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    /// (value, Δ), ascending in value, the estimate (Δ = 0) included.
    pub points: Vec<(f64, f64)>,
}

/// χ²₁(0.95): the profile statistic at a 95 % interval's limits.
pub const PROFILE_LIMIT: f64 = 3.841_458_820_694_124;
/// Profile points, in Wald standard errors from the estimate, tried outward on each side until
/// the statistic passes [`PROFILE_LIMIT`].
pub(super) const PROFILE_STEPS: [f64; 11] =
    [1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 32.0];

/// One side of a profile: its points (outward) and the interval's limit, if reached.
pub(super) type Side = (Vec<(f64, f64)>, Option<f64>);

/// The profile likelihood of every estimated parameter of a fit at `x` (natural, ρ for k_S)
/// with `fixed` held: both sides of each in parallel, each side warm-started from its previous
/// point. A side whose refit fails ends there, unbounded.
pub(super) fn profiles(
    group: &str,
    s: &[Sample],
    fixed: [Option<f64>; 5],
    x: &[f64; 5],
    se: &[f64; 5],
    status: &[ParamStatus; 5],
    cov: &Covariance,
) -> Vec<Profile> {
    let est = law_params(x);
    let value = [est.mu0, est.a_ratio, est.b_s_per_m, est.k_a, est.k_s];
    let params: Vec<usize> = (0..5)
        .filter(|&i| status[i] == ParamStatus::Estimated && se[i].is_finite() && se[i] > 0.0)
        .collect();
    let sides: Vec<(usize, f64)> = params.iter().flat_map(|&i| [(i, -1.0), (i, 1.0)]).collect();
    // The free parameters of the fit (natural order) and, per profiled parameter, how the
    // others move with it at the optimum to first order: cov(x_j, x_i)/var(x_i) — the warm
    // start of each refit is the previous point's optimum moved along it.
    let free: Vec<usize> = (0..5).filter(|&i| fixed[i].is_none()).collect();
    let k = free.len();
    let slope = |i: usize| -> [f64; 5] {
        let mut out = [0.0; 5];
        if let (Some(m), Some(ci)) = (&cov.cov, free.iter().position(|&f| f == i)) {
            if i != 4 {
                for (cj, &j) in free.iter().enumerate() {
                    out[j] = m[cj * k + ci] / m[ci * k + ci];
                }
            }
        }
        out
    };
    let walked: Vec<Side> = sides
        .par_iter()
        .map(|&(i, dir)| {
            // k_S lies in (0, 1) (k_S ≤ k_A ≤ 1); the others in their fit bounds.
            let (lo, hi) = if i == 4 {
                (0.0, 1.0)
            } else {
                (LOWER[i], UPPER[i])
            };
            let mut warm = *x;
            let along = slope(i);
            let mut pts = Vec::new();
            let mut prev: (f64, f64) = (value[i], 0.0);
            for z in PROFILE_STEPS {
                let at = value[i] + dir * z * se[i];
                if !(at > lo && at < hi) {
                    return (pts, None);
                }
                for j in 0..5 {
                    if j != i && fixed[j].is_none() {
                        let moved = warm[j] + along[j] * (at - prev.0);
                        warm[j] = moved.clamp(
                            LOWER[j] + 1e-6 * (UPPER[j] - LOWER[j]),
                            UPPER[j] - 1e-6 * (UPPER[j] - LOWER[j]),
                        );
                    }
                }
                let mut f = fixed;
                let ks = if i == 4 {
                    Some(at)
                } else {
                    f[i] = Some(at);
                    None
                };
                let problem = PolachProblem::plain(s, f, ks);
                let Ok((problem, theta, _, _)) =
                    solve(group, problem, &constant_nodes(&warm), profile_settings())
                else {
                    return (pts, None);
                };
                let nodes = problem.nodes(&theta).0;
                warm = problem.at_group(&problem.groups[0], &nodes).0;
                let stat = ((problem.sse_nodes(&nodes) - cov.sse) / cov.scale).max(0.0);
                pts.push((at, stat));
                if stat > PROFILE_LIMIT {
                    // Linear in √Δ between the last two points (√Δ is linear in the value
                    // where the law is).
                    let (z0, z1) = (prev.1.sqrt(), stat.sqrt());
                    let lim = PROFILE_LIMIT.sqrt();
                    let t = ((lim - z0) / (z1 - z0)).clamp(0.0, 1.0);
                    return (pts, Some(prev.0 + t * (at - prev.0)));
                }
                prev = (at, stat);
            }
            (pts, None)
        })
        .collect();
    params
        .iter()
        .enumerate()
        .map(|(k, &i)| {
            let (lo_pts, lower) = &walked[2 * k];
            let (hi_pts, upper) = &walked[2 * k + 1];
            let mut points: Vec<(f64, f64)> = lo_pts.iter().rev().copied().collect();
            points.push((value[i], 0.0));
            points.extend(hi_pts.iter().copied());
            Profile {
                parameter: PARAMETERS[i].to_string(),
                estimate: value[i],
                lower: *lower,
                upper: *upper,
                points,
            }
        })
        .collect()
}

/// A parameter's name for notes (k_S stands for ρ = k_S/k_A).
pub(super) fn label(i: usize) -> &'static str {
    ["μ0", "A", "B", "k_A", "k_S/k_A"][i]
}
