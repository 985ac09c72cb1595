//! Polach creep-force fits (seed 004 004_7d175079b70fb95b.txt eq. 1–3; Polach 2005) to the
//! estimated μ, and the temperature dependence k_A(T), k_S(T) across runs.
//!
//! Per sample, one wheel carries Q = N_i / 2 and the estimate μ_i = T_i / N_i is the wheel's
//! F/Q, so the model is μ̂ = polach(patch, params, Q, v, Δv, 0).f_x / Q (contact library,
//! creepage Δv/v, falling friction μ = μ0[(1 − A)e^(−BΔv) + A]). The patch (Hertz + Kalker at
//! the static wheel load, pipeline `[contact]`) is held fixed.
//!
//! Parameters are fitted by the same Levenberg–Marquardt solver as the network, on
//! unconstrained p with bounds by reparametrisation: μ0 = 1.5 σ(p0) ∈ (0, 1.5),
//! A = σ(p1) ∈ (0, 1), B = e^(p2) > 0, k_A = σ(p3) ∈ (0, 1), k_S = k_A σ(p4) ∈ (0, k_A)
//! (σ the logistic function). The Jacobian is by central differences in p (five parameters).
//! Standard errors: σ² (JᵀJ)⁻¹ at the optimum, inflated for the residuals' autocorrelation
//! (n_eff, [`crate::linalg::effective_samples`]) and carried to the natural parameters by the
//! derivative of the transform (delta method).
//!
//! k(T): per ambient temperature (run metadata `ambient_temperature_c`), one Polach fit of the
//! pooled runs; then k_A(T) and k_S(T) as least-squares polynomials of degree
//! min(`train.temperature_degree`, temperatures − 1), in the contact library's
//! [`TemperatureLaw`], with their residuals.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::dataset::RunTable;
use super::lm::{self, LeastSquares, LevenbergMarquardt, LmSettings, NormalEquations};
use super::IdentifyError;
use crate::contact::polach::{horner, ContactPatch, PolachParams, TemperatureLaw};
use crate::linalg::{cho_solve, cholesky, effective_samples, inverse_diagonal};

/// One sample for the fit.
#[derive(Debug, Clone, Copy)]
struct Sample {
    q_n: f64,
    v: f64,
    dv: f64,
    mu: f64,
    /// c (w/v)/Q with c = π G a b c11/4 of the patch: the gradient ε times μ_w (set by
    /// [`with_patch`]).
    cs: f64,
}

/// The samples with their patch term `cs` set.
fn with_patch(mut s: Vec<Sample>, patch: &ContactPatch) -> Vec<Sample> {
    let c = std::f64::consts::PI * patch.g_pa * patch.a_m * patch.b_m * patch.c11 / 4.0;
    for x in &mut s {
        x.cs = c * (x.dv / x.v) / x.q_n;
    }
    s
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// The fitted parameters in the solver's order: μ0, A, B (s/m), k_A and ρ = k_S/k_A (so that
/// every parameter has its own bounds and k_S ≤ k_A holds by construction).
pub const PARAMETERS: [&str; 5] = ["mu0", "a_ratio", "b_s_per_m", "k_a", "k_s"];
/// Lower and upper bounds of μ0, A, B (s/m), k_A and ρ. B's are railgrip's: below 1e-3 s/m
/// friction does not fall within the slips braking reaches, above 100 s/m it falls within
/// 1 cm/s; the others are the law's own (seed 004 eq. 1–2: 0 < A < 1, 0 < k_S ≤ k_A ≤ 1).
const LOWER: [f64; 5] = [0.0, 0.0, 1e-3, 0.0, 0.0];
const UPPER: [f64; 5] = [1.5, 1.0, 100.0, 1.0, 1.0];
/// A parameter whose logistic coordinate is within this of 0 or 1 sits at its bound.
const AT_BOUND: f64 = 1e-4;
/// A parameter is identified when its 95 % Wald interval (±1.96 se, se corrected for the
/// residuals' autocorrelation) excludes zero: se ≤ x / 1.96.
const IDENTIFIED_Z: f64 = 1.96;

/// The start of every campaign fit (the benchmarks and tests start there too).
pub const DEFAULT_START: PolachParams = PolachParams {
    mu0: 0.1,
    a_ratio: 0.4,
    b_s_per_m: 0.3,
    k_a: 0.3,
    k_s: 0.1,
};

/// What a fit could say about one parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamStatus {
    /// Estimated from the data (with its standard error).
    Estimated,
    /// The fit ran into a bound; held there and the rest refitted.
    AtBound,
    /// The data do not determine it (Wald interval includes zero, or the Fisher matrix is
    /// singular in it); held at its least-squares value and the rest refitted.
    NotIdentifiable,
}

impl ParamStatus {
    pub fn text(self) -> &'static str {
        match self {
            ParamStatus::Estimated => "estimated",
            ParamStatus::AtBound => "at bound",
            ParamStatus::NotIdentifiable => "not identifiable",
        }
    }
}

/// Natural parameter i from its unconstrained coordinate: x = lo + (hi − lo) σ(p), B on a log
/// scale (ln B = ln lo + (ln hi − ln lo) σ(p)); and dx/dp.
fn to_natural(i: usize, p: f64) -> (f64, f64) {
    let s = sigmoid(p);
    let ds = s * (1.0 - s);
    if i == 2 {
        let (l, h) = (LOWER[2].ln(), UPPER[2].ln());
        // Clamped: exp(ln 100) rounds to 100.00000000000004.
        let x = (l + (h - l) * s).exp().clamp(LOWER[2], UPPER[2]);
        (x, x * (h - l) * ds)
    } else {
        let (l, h) = (LOWER[i], UPPER[i]);
        (l + (h - l) * s, (h - l) * ds)
    }
}

/// The unconstrained coordinate of natural parameter i (inside its open bounds).
fn to_unconstrained(i: usize, x: f64) -> f64 {
    let u = if i == 2 {
        let (l, h) = (LOWER[2].ln(), UPPER[2].ln());
        (x.ln() - l) / (h - l)
    } else {
        (x - LOWER[i]) / (UPPER[i] - LOWER[i])
    };
    let u = u.clamp(1e-9, 1.0 - 1e-9);
    (u / (1.0 - u)).ln()
}

/// (μ0, A, B, k_A, ρ) from the law's parameters.
fn solver_order(q: &PolachParams) -> [f64; 5] {
    [q.mu0, q.a_ratio, q.b_s_per_m, q.k_a, q.k_s / q.k_a]
}

fn law_params(x: &[f64; 5]) -> PolachParams {
    PolachParams {
        mu0: x[0],
        a_ratio: x[1],
        b_s_per_m: x[2],
        k_a: x[3],
        k_s: x[3] * x[4],
    }
}

/// Polach's μ = F/Q of one sample and its derivatives in (μ0, A, B, k_A, ρ) — seed 004
/// 004_7d175079b70fb95b.txt eq. 1–2, Polach 2005 — for slip w = Δv > 0 (m/s), speed v > 0
/// (m/s): with the falling friction μ_w = μ0 g, g = (1 − A)e^(−Bw) + A, the gradient
/// ε = c/μ_w, c = π G a b c11 (w/v)/(4Q), x = k_A ε, y = k_S ε:
///   f = (2μ_w/π) [x/(1 + x²) + atan y],
///   ∂f/∂μ_w = (2/π) [x/(1 + x²) + atan y − x(1 − x²)/(1 + x²)² − y/(1 + y²)]
///   (ε falls as μ_w rises), ∂μ_w/∂μ0 = g, ∂μ_w/∂A = μ0 (1 − e^(−Bw)),
///   ∂μ_w/∂B = −μ0 (1 − A) w e^(−Bw);
///   ∂f/∂k_A = (2μ_w/π) ε [(1 − x²)/(1 + x²)² + ρ/(1 + y²)], ∂f/∂ρ = (2μ_w/π) ε k_A/(1 + y²).
/// The value is the contact library's `polach(…).fx_n / Q` (tested to 1e-14).
#[inline]
fn mu_and_gradient(x: &[f64; 5], s: &Sample) -> (f64, [f64; 5]) {
    let [mu0, a, b, k_a, rho] = *x;
    let k_s = k_a * rho;
    let e = (-b * s.dv).exp();
    let g = (1.0 - a) * e + a;
    let mu_w = mu0 * g;
    let eps = s.cs / mu_w;
    let (xa, ys) = (k_a * eps, k_s * eps);
    let (dxa, dys) = (1.0 + xa * xa, 1.0 + ys * ys);
    let bracket = xa / dxa + ys.atan();
    let two_pi = 2.0 / std::f64::consts::PI;
    let f = two_pi * mu_w * bracket;
    let h1 = (1.0 - xa * xa) / (dxa * dxa);
    let df_dmuw = two_pi * (bracket - xa * h1 - ys / dys);
    let scale = two_pi * mu_w * eps;
    (
        f,
        [
            df_dmuw * g,
            df_dmuw * mu0 * (1.0 - e),
            -df_dmuw * mu0 * (1.0 - a) * s.dv * e,
            scale * (h1 + rho / dys),
            scale * k_a / dys,
        ],
    )
}

/// The value of [`mu_and_gradient`] alone (the same operations; for trial steps).
#[inline]
fn mu_only(x: &[f64; 5], s: &Sample) -> f64 {
    let [mu0, a, b, k_a, rho] = *x;
    let e = (-b * s.dv).exp();
    let mu_w = mu0 * ((1.0 - a) * e + a);
    let eps = s.cs / mu_w;
    let (xa, ys) = (k_a * eps, k_a * rho * eps);
    2.0 / std::f64::consts::PI * mu_w * (xa / (1.0 + xa * xa) + ys.atan())
}

/// The least-squares problem of one fit: the free parameters' unconstrained coordinates, the
/// others held at `fixed`.
struct PolachProblem<'a> {
    samples: &'a [Sample],
    fixed: [Option<f64>; 5],
    free: Vec<usize>,
}

impl PolachProblem<'_> {
    fn natural(&self, theta: &[f64]) -> ([f64; 5], [f64; 5]) {
        let mut x = self.fixed.map(|v| v.unwrap_or(0.0));
        let mut dx = [0.0; 5];
        for (k, &i) in self.free.iter().enumerate() {
            (x[i], dx[i]) = to_natural(i, theta[k]);
        }
        (x, dx)
    }
    fn sse_natural(&self, x: &[f64; 5]) -> f64 {
        self.samples
            .iter()
            .map(|s| {
                let r = mu_only(x, s) - s.mu;
                r * r
            })
            .sum()
    }
    /// Residuals and the Jacobian in the natural parameters (n × 5, row-major).
    fn residuals_and_jacobian(&self, x: &[f64; 5]) -> (Vec<f64>, Vec<f64>) {
        let mut r = Vec::with_capacity(self.samples.len());
        let mut j = Vec::with_capacity(5 * self.samples.len());
        for s in self.samples {
            let (f, g) = mu_and_gradient(x, s);
            r.push(f - s.mu);
            j.extend_from_slice(&g);
        }
        (r, j)
    }
}

impl LeastSquares for PolachProblem<'_> {
    fn n_params(&self) -> usize {
        self.free.len()
    }
    fn n_train(&self) -> usize {
        self.samples.len()
    }
    fn sse(&self, theta: &[f64]) -> f64 {
        self.sse_natural(&self.natural(theta).0)
    }
    /// One pass over the samples: JᵀJ and Jᵀr in the unconstrained coordinates (the natural
    /// Jacobian times dx/dp, column by column).
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        let (x, dx) = self.natural(theta);
        let k = self.free.len();
        let mut jtj = vec![0.0; k * k];
        let mut jtr = vec![0.0; k];
        let mut sse = 0.0;
        let mut row = vec![0.0; k];
        for s in self.samples {
            let (f, g) = mu_and_gradient(&x, s);
            let r = f - s.mu;
            sse += r * r;
            for (c, &i) in self.free.iter().enumerate() {
                row[c] = g[i] * dx[i];
            }
            for a in 0..k {
                jtr[a] += row[a] * r;
                for b in 0..=a {
                    jtj[a * k + b] += row[a] * row[b];
                }
            }
        }
        for a in 0..k {
            for b in 0..a {
                jtj[b * k + a] = jtj[a * k + b];
            }
        }
        NormalEquations { jtj, jtr, sse }
    }
    fn validation_mse(&self, _: &[f64]) -> Option<f64> {
        None
    }
}

/// A fitted parameter set with one standard error per parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PolachFit {
    /// What was fitted: a run name, or `T = x °C`.
    pub group: String,
    pub mu0: f64,
    pub a_ratio: f64,
    pub b_s_per_m: f64,
    pub k_a: f64,
    pub k_s: f64,
    /// Standard errors in the same order (μ0, A, B, k_A, k_S); NaN (`null`) for a parameter
    /// held at a bound or prior.
    pub se: [f64; 5],
    /// What the data said about each parameter (same order; k_S's is that of k_S/k_A, the
    /// parameter the fit solves for).
    #[serde(default = "all_estimated")]
    pub status: [ParamStatus; 5],
    /// Why parameters were held (one line each), in the order it happened.
    #[serde(default)]
    pub notes: Vec<String>,
    pub samples: usize,
    pub effective_samples: f64,
    /// RMS residual of μ.
    pub rmse: f64,
    /// Ambient temperature of the group, °C (when known).
    pub ambient_temperature_c: Option<f64>,
    /// Levenberg–Marquardt iterations and why it stopped.
    pub iterations: usize,
    pub stop_reason: String,
}

fn all_estimated() -> [ParamStatus; 5] {
    [ParamStatus::Estimated; 5]
}

impl PolachFit {
    pub fn params(&self) -> PolachParams {
        PolachParams {
            mu0: self.mu0,
            a_ratio: self.a_ratio,
            b_s_per_m: self.b_s_per_m,
            k_a: self.k_a,
            k_s: self.k_s,
        }
    }
}

/// Samples with slip, every `decimate`-th. The tables hold no loads, so every sample gets the
/// static wheel load `q_n`: load transfer moves it by a few per cent, far below the scatter of μ.
fn samples(tables: &[&RunTable], q_n: f64, decimate: usize) -> Vec<Sample> {
    let mut out = Vec::new();
    for t in tables {
        for i in (0..t.len()).step_by(decimate.max(1)) {
            if t.dv_mps[i] > 0.0 && t.v_mps[i] > 0.0 {
                out.push(Sample {
                    q_n,
                    v: t.v_mps[i],
                    dv: t.dv_mps[i],
                    mu: t.mu[i],
                    cs: f64::NAN,
                });
            }
        }
    }
    out
}

/// LM settings of the Polach fits: MINPACK's convergence tests (ftol = xtol = 1e-10), so that
/// a fit whose cost stopped falling ends as converged rather than running μ to its maximum.
fn fit_settings() -> LmSettings {
    LmSettings {
        epochs: 300,
        min_grad: 1e-12,
        ftol: 1e-10,
        xtol: 1e-10,
        ..LmSettings::default()
    }
}

/// One solve with the parameters of `fixed` held: the free parameters from `start`.
fn solve(
    group: &str,
    s: &[Sample],
    fixed: [Option<f64>; 5],
    start: &[f64; 5],
) -> Result<([f64; 5], [f64; 5], usize, lm::StopReason), IdentifyError> {
    let free: Vec<usize> = (0..5).filter(|i| fixed[*i].is_none()).collect();
    let problem = PolachProblem {
        samples: s,
        fixed,
        free: free.clone(),
    };
    let theta0: Vec<f64> = free
        .iter()
        .map(|&i| to_unconstrained(i, start[i]))
        .collect();
    if free.is_empty() {
        let (x, dx) = problem.natural(&[]);
        return Ok((x, dx, 0, lm::StopReason::MinGrad));
    }
    let (solver, problem) = lm::run(problem, LevenbergMarquardt::new(fit_settings()), theta0)
        .map_err(|e| IdentifyError::Solver {
            fit: format!("Polach fit {group}"),
            source: e.into(),
        })?;
    let theta = solver.best().expect("solver ran").to_vec();
    let (x, dx) = problem.natural(&theta);
    Ok((
        x,
        dx,
        solver.history().len(),
        solver.stop_reason().unwrap_or(lm::StopReason::Epochs),
    ))
}

/// Fits Polach's parameters to the valid estimates of `tables` (pooled) with a fixed patch
/// and static wheel load `q_n`, saying what the data identify (issue 16):
/// 1. LM on all five parameters (unconstrained logistic coordinates, analytic Jacobian,
///    MINPACK's ftol/xtol convergence);
/// 2. a parameter within [`AT_BOUND`] of a bound (in its logistic coordinate) is held at the
///    bound (`at bound`) and the rest refitted;
/// 3. standard errors σ² (JᵀJ)⁻¹ in the natural parameters, inflated by n/n_eff for the
///    residuals' autocorrelation ([`effective_samples`]); the free parameter with the largest
///    se/x above 1/1.96 (Wald interval including zero; a singular JᵀJ counts as infinite) is held
///    at its least-squares value (`not identifiable`) and the rest refitted; repeated until every
///    free parameter is identified. Held at its own best value rather than at a published
///    prior: any value in its wide interval fits about as well, and a prior far from the data
///    (the published wet-rail k_A is twice a soap rail's) would drag the identified parameters
///    with it (tested).
///
/// The fit ends with every parameter classified; it fails only without data.
pub fn fit_polach(
    group: &str,
    tables: &[&RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    start: PolachParams,
) -> Result<PolachFit, IdentifyError> {
    let s = samples(tables, q_n, decimate);
    if s.len() < 20 {
        return Err(IdentifyError::Data {
            what: format!(
                "{group}: only {} samples with slip for the Polach fit",
                s.len()
            ),
            hint: "fit Polach on braking runs with wheel slip".into(),
        });
    }
    let s = with_patch(s, &patch);
    let mut fixed: [Option<f64>; 5] = [None; 5];
    let mut status = all_estimated();
    let mut notes = Vec::new();
    let mut current = solver_order(&start);
    let mut iterations = 0;
    let (x, var, n_eff, stop) = loop {
        let (x, _dx, its, stop) = solve(group, &s, fixed, &current)?;
        iterations += its;
        current = x;
        // 2. Bounds.
        let mut held = false;
        let free_now: Vec<usize> = (0..5).filter(|i| fixed[*i].is_none()).collect();
        for i in free_now {
            let u = to_unconstrained(i, x[i]);
            let sg = sigmoid(u);
            if !(AT_BOUND..=1.0 - AT_BOUND).contains(&sg) {
                let bound = if sg < AT_BOUND { LOWER[i] } else { UPPER[i] };
                fixed[i] = Some(bound);
                current[i] = bound;
                status[i] = ParamStatus::AtBound;
                notes.push(format!(
                    "{} ran into its bound {bound}; held there and the rest refitted",
                    label(i)
                ));
                held = true;
            }
        }
        if held {
            continue;
        }
        // 3. Identifiability of the free parameters.
        let problem = PolachProblem {
            samples: &s,
            fixed,
            free: vec![],
        };
        let (r, j) = problem.residuals_and_jacobian(&x);
        let n = r.len();
        let n_eff = effective_samples(&r);
        let free: Vec<usize> = (0..5).filter(|i| fixed[*i].is_none()).collect();
        let k = free.len();
        let mut jtj = vec![0.0; k * k];
        for row in j.chunks_exact(5) {
            for (a, &ia) in free.iter().enumerate() {
                for (b, &ib) in free.iter().enumerate() {
                    jtj[a * k + b] += row[ia] * row[ib];
                }
            }
        }
        let sse: f64 = r.iter().map(|v| v * v).sum();
        let sigma2 = sse / (n as f64 - k as f64).max(1.0);
        let inflate = n as f64 / n_eff.max(1.0);
        let mut var = [f64::NAN; 5];
        match cholesky(&jtj, k) {
            Some(l) => {
                for (c, d) in inverse_diagonal(&l, k).into_iter().enumerate() {
                    var[free[c]] = d * sigma2 * inflate;
                }
            }
            None => {
                for &i in &free {
                    var[i] = f64::INFINITY;
                }
            }
        }
        // The worst-determined free parameter, if any fails the Wald test.
        let worst = free
            .iter()
            .map(|&i| (i, var[i].sqrt() / x[i].abs()))
            // NaN (a zero estimate) and ∞ (singular) fail too.
            .filter(|(_, rel)| rel.is_nan() || *rel > 1.0 / IDENTIFIED_Z)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((i, rel)) = worst {
            fixed[i] = Some(x[i]);
            status[i] = ParamStatus::NotIdentifiable;
            notes.push(format!(
                "{} not identifiable from these data ({:.4}, se/value = {}: its 95 % interval includes 0); held at that value and the rest refitted",
                label(i),
                x[i],
                if rel.is_finite() { format!("{rel:.2}") } else { "∞ (singular)".into() },
            ));
            continue;
        }
        // k_S = k_A ρ: its variance by the delta method needs cov(k_A, ρ).
        let mut cov_ka_rho = 0.0;
        if let (Some(a), Some(b)) = (
            free.iter().position(|&i| i == 3),
            free.iter().position(|&i| i == 4),
        ) {
            if let Some(l) = cholesky(&jtj, k) {
                let mut e = vec![0.0; k];
                e[b] = 1.0;
                cov_ka_rho = cho_solve(&l, k, &e)[a] * sigma2 * inflate;
            }
        }
        let v4 = |v: f64| if v.is_finite() { v } else { 0.0 };
        let var_ks = match (fixed[3].is_none(), fixed[4].is_none()) {
            (false, false) => f64::NAN,
            _ => {
                x[4] * x[4] * v4(var[3]) + x[3] * x[3] * v4(var[4]) + 2.0 * x[3] * x[4] * cov_ka_rho
            }
        };
        var[4] = var_ks;
        break (x, var, n_eff, stop);
    };
    // k_S = k_A ρ carries the status of ρ: held at a bound, k_S/k_A is fixed (k_S = k_A, or
    // 0), and k_S has no standard error of its own.
    let p = law_params(&x);
    let sse = problem_sse(&s, &x);
    let se = var.map(|v| if v.is_nan() { f64::NAN } else { v.sqrt() });
    let se = [
        if status[0] == ParamStatus::Estimated {
            se[0]
        } else {
            f64::NAN
        },
        if status[1] == ParamStatus::Estimated {
            se[1]
        } else {
            f64::NAN
        },
        if status[2] == ParamStatus::Estimated {
            se[2]
        } else {
            f64::NAN
        },
        if status[3] == ParamStatus::Estimated {
            se[3]
        } else {
            f64::NAN
        },
        if status[4] == ParamStatus::Estimated {
            se[4]
        } else {
            f64::NAN
        },
    ];
    Ok(PolachFit {
        group: group.to_string(),
        mu0: p.mu0,
        a_ratio: p.a_ratio,
        b_s_per_m: p.b_s_per_m,
        k_a: p.k_a,
        k_s: p.k_s,
        se,
        status,
        notes,
        samples: s.len(),
        effective_samples: n_eff,
        rmse: (sse / s.len() as f64).sqrt(),
        ambient_temperature_c: None,
        iterations,
        stop_reason: stop.text().to_string(),
    })
}

/// The SSE of the natural parameters `x`.
fn problem_sse(s: &[Sample], x: &[f64; 5]) -> f64 {
    PolachProblem {
        samples: s,
        fixed: [None; 5],
        free: vec![],
    }
    .sse_natural(x)
}

/// A parameter's name for notes (k_S stands for ρ = k_S/k_A).
fn label(i: usize) -> &'static str {
    ["μ0", "A", "B", "k_A", "k_S/k_A"][i]
}

/// The temperature law and the fits behind it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TemperatureFit {
    /// Polynomial coefficients in ascending powers of T (°C).
    pub k_a: Vec<f64>,
    pub k_s: Vec<f64>,
    pub fitted_range_c: (f64, f64),
    pub degree: usize,
    /// (T, k_A residual, k_S residual) per temperature group.
    pub residuals: Vec<(f64, f64, f64)>,
    /// Temperatures left out because their fit held k_A or k_S, with why.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub excluded: Vec<String>,
}

impl TemperatureFit {
    /// As the contact library's type.
    pub fn law(&self) -> Result<TemperatureLaw, crate::contact::ContactError> {
        TemperatureLaw::new(self.k_a.clone(), self.k_s.clone(), self.fitted_range_c)
    }
}

/// Least-squares polynomial of `degree` through (x, y); coefficients ascending.
fn polyfit(x: &[f64], y: &[f64], degree: usize) -> Option<Vec<f64>> {
    let k = degree + 1;
    let mut a = vec![0.0; k * k];
    let mut b = vec![0.0; k];
    for (xi, yi) in x.iter().zip(y) {
        let pw: Vec<f64> = (0..k).map(|j| xi.powi(j as i32)).collect();
        for r in 0..k {
            b[r] += pw[r] * yi;
            for c in 0..k {
                a[r * k + c] += pw[r] * pw[c];
            }
        }
    }
    let l = cholesky(&a, k)?;
    Some(cho_solve(&l, k, &b))
}

/// Fits k_A(T), k_S(T) through per-temperature Polach fits.
pub fn fit_temperature(fits: &[PolachFit], degree: usize) -> Result<TemperatureFit, IdentifyError> {
    let with_t: Vec<&PolachFit> = fits
        .iter()
        .filter(|f| f.ambient_temperature_c.is_some())
        .collect();
    if with_t.len() < 2 {
        return Err(IdentifyError::Data {
            what: format!("k(T) needs runs at two or more ambient temperatures; found {}", with_t.len()),
            hint: "give runs at several ambient temperatures with ambient_temperature_c in their metadata".into(),
        });
    }
    // Only temperatures whose fit identified k_A and k_S (issue 16): a value held because the
    // data did not determine it says nothing about how k changes with temperature. (k_S/k_A
    // at its bound leaves k_S = k_A or 0: as determined as k_A.)
    let mut excluded = Vec::new();
    let mut pts: Vec<(f64, f64, f64)> = Vec::new();
    for f in with_t {
        let t = f.ambient_temperature_c.expect("filtered");
        let held: Vec<String> = [(3, "k_A"), (4, "k_S")]
            .iter()
            .filter(|(k, _)| match f.status[*k] {
                ParamStatus::Estimated => false,
                ParamStatus::AtBound => *k == 3,
                ParamStatus::NotIdentifiable => true,
            })
            .map(|(k, name)| format!("{name} {}", f.status[*k].text()))
            .collect();
        if held.is_empty() {
            pts.push((t, f.k_a, f.k_s));
        } else {
            excluded.push(format!("T = {t} °C ({})", held.join(", ")));
        }
    }
    if pts.len() < 2 {
        return Err(IdentifyError::Data {
            what: format!(
                "k(T) needs k_A and k_S identified at two or more ambient temperatures; {} of them identify both, left out: {}",
                pts.len(),
                excluded.join("; ")
            ),
            hint: "add runs with small slips (Δv below 0.2 m/s) at those temperatures, or use the pooled fit without k(T)".into(),
        });
    }
    let degree = degree.min(pts.len() - 1);
    let t: Vec<f64> = pts.iter().map(|p| p.0).collect();
    let ka: Vec<f64> = pts.iter().map(|p| p.1).collect();
    let ks: Vec<f64> = pts.iter().map(|p| p.2).collect();
    let fail = || IdentifyError::Data {
        what: "the k(T) polynomial fit is singular".into(),
        hint: "use distinct ambient temperatures or a lower train.temperature_degree".into(),
    };
    let ca = polyfit(&t, &ka, degree).ok_or_else(fail)?;
    let cs = polyfit(&t, &ks, degree).ok_or_else(fail)?;
    let residuals = pts
        .iter()
        .map(|(ti, a, s)| (*ti, a - horner(&ca, *ti), s - horner(&cs, *ti)))
        .collect();
    let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    Ok(TemperatureFit {
        k_a: ca,
        k_s: cs,
        fitted_range_c: (lo, hi),
        degree,
        residuals,
        excluded,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reparametrisation_round_trips_and_respects_bounds() {
        for (i, x) in [(0, 0.3), (1, 0.4), (2, 0.2), (3, 0.3), (4, 0.5), (2, 40.0)] {
            let (back, dx) = to_natural(i, to_unconstrained(i, x));
            assert!((back - x).abs() < 1e-12 * x.max(1.0), "{i}: {back} vs {x}");
            // dx/dp against a central difference.
            let p = to_unconstrained(i, x);
            let h = 1e-6;
            let fd = (to_natural(i, p + h).0 - to_natural(i, p - h).0) / (2.0 * h);
            assert!(
                (dx - fd).abs() < 1e-6 * fd.abs().max(1e-12),
                "{i}: {dx} vs {fd}"
            );
        }
        for (i, p) in [(0, 60.0), (1, -60.0), (2, 60.0), (3, 60.0), (4, 60.0)] {
            let x = to_natural(i, p).0;
            assert!(x >= LOWER[i] && x <= UPPER[i], "{i}: {x}");
        }
    }

    fn patch() -> ContactPatch {
        ContactPatch {
            a_m: 0.0061,
            b_m: 0.0045,
            g_pa: 8.0e10,
            c11: 4.1,
            c22: 3.6,
        }
    }

    proptest::proptest! {
        /// The analytic μ is the contact library's, and its gradient matches central
        /// differences, over the law's whole domain (issue 16).
        #[test]
        fn analytic_gradient_matches_the_law_and_finite_differences(
            mu0 in 0.02f64..1.0, a in 0.01f64..0.99, b in 0.01f64..5.0,
            k_a in 0.01f64..1.0, rho in 0.01f64..1.0,
            dv in 0.001f64..8.0, v in 1.0f64..90.0,
        ) {
            let p = patch();
            let q = 80_000.0;
            let x = [mu0, a, b, k_a, rho];
            let s = with_patch(vec![Sample { q_n: q, v, dv, mu: 0.0, cs: f64::NAN }], &p)[0];
            let (f, g) = mu_and_gradient(&x, &s);
            proptest::prop_assert_eq!(f.to_bits(), mu_only(&x, &s).to_bits());
            let law = crate::contact::polach::polach(&p, &law_params(&x), q, v, dv, 0.0).unwrap();
            proptest::prop_assert!((f - law.fx_n / q).abs() <= 1e-14 * f.abs().max(1e-3), "{} vs {}", f, law.fx_n / q);
            for i in 0..5 {
                let h = 1e-6 * x[i];
                let (mut up, mut dn) = (x, x);
                up[i] += h;
                dn[i] -= h;
                let fd = (mu_only(&up, &s) - mu_only(&dn, &s)) / (2.0 * h);
                let tol = 1e-6 * (g[i].abs() + fd.abs()) + 1e-10;
                proptest::prop_assert!((g[i] - fd).abs() <= tol, "param {}: {} vs {}", i, g[i], fd);
            }
        }
    }

    #[test]
    fn polyfit_recovers_a_quadratic() {
        let x = [-20.0, 0.0, 20.0, 35.0];
        let y: Vec<f64> = x.iter().map(|t| 0.1 + 0.002 * t - 1e-5 * t * t).collect();
        let c = polyfit(&x, &y, 2).unwrap();
        assert!(
            (c[0] - 0.1).abs() < 1e-12
                && (c[1] - 0.002).abs() < 1e-12
                && (c[2] + 1e-5).abs() < 1e-12
        );
    }
}

/// Polach fits of a campaign: per run, per ambient temperature, and k(T).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PolachReport {
    pub format: String,
    pub version: u32,
    /// The fixed contact patch: semi-axes a, b (m), shear modulus G (Pa), c11, c22, and the
    /// static wheel load Q (N) it was computed for.
    pub patch: [f64; 5],
    pub wheel_load_n: f64,
    /// All runs pooled: the parameters of the campaign's `polach` model file.
    pub pooled: Option<PolachFit>,
    /// Slip and speed ranges of the samples with slip (m/s): the model's domain.
    pub dv_range_mps: (f64, f64),
    pub v_range_mps: (f64, f64),
    pub per_run: Vec<PolachFit>,
    pub per_temperature: Vec<PolachFit>,
    /// k_A(T), k_S(T); absent with fewer than two temperatures.
    pub temperature: Option<TemperatureFit>,
    /// Why `temperature` is absent.
    pub temperature_note: Option<String>,
}

/// Fits every run, every temperature group and k(T). Runs that cannot be fitted are skipped
/// with their error in `notes`.
pub fn fit_campaign(
    tables: &[RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    degree: usize,
) -> (PolachReport, Vec<String>) {
    let start = DEFAULT_START;
    // Every group is fitted independently: in parallel, results kept in group order.
    let all: Vec<&RunTable> = tables.iter().collect();
    let mut temps: Vec<f64> = tables
        .iter()
        .filter_map(|t| t.metadata.ambient_temperature_c)
        .collect();
    temps.sort_by(f64::total_cmp);
    temps.dedup();
    enum Group {
        Pooled,
        Run(usize),
        Temperature(f64),
    }
    let mut groups = vec![Group::Pooled];
    groups.extend((0..tables.len()).map(Group::Run));
    groups.extend(temps.iter().map(|t| Group::Temperature(*t)));
    let fits: Vec<(&Group, Result<PolachFit, IdentifyError>)> = groups
        .par_iter()
        .map(|g| {
            let r = match g {
                Group::Pooled => fit_polach("all runs", &all, patch, q_n, decimate, start),
                Group::Run(i) => {
                    let t = &tables[*i];
                    fit_polach(&t.name, &[t], patch, q_n, decimate, start).map(|mut f| {
                        f.ambient_temperature_c = t.metadata.ambient_temperature_c;
                        f
                    })
                }
                Group::Temperature(temp) => {
                    let group: Vec<&RunTable> = tables
                        .iter()
                        .filter(|t| t.metadata.ambient_temperature_c == Some(*temp))
                        .collect();
                    fit_polach(
                        &format!("T = {temp} °C"),
                        &group,
                        patch,
                        q_n,
                        decimate,
                        start,
                    )
                    .map(|mut f| {
                        f.ambient_temperature_c = Some(*temp);
                        f
                    })
                }
            };
            (g, r)
        })
        .collect();
    let mut notes = Vec::new();
    let (mut pooled, mut per_run, mut per_temperature) = (None, Vec::new(), Vec::new());
    for (g, r) in fits {
        match (g, r) {
            (Group::Pooled, Ok(f)) => pooled = Some(f),
            (Group::Run(_), Ok(f)) => per_run.push(f),
            (Group::Temperature(_), Ok(f)) => per_temperature.push(f),
            (Group::Run(i), Err(e)) => notes.push(format!("{}: {e}", tables[*i].name)),
            (_, Err(e)) => notes.push(e.to_string()),
        }
    }
    let pooled_samples = samples(&all, q_n, decimate);
    let range = |f: fn(&Sample) -> f64| {
        pooled_samples
            .iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            })
    };
    let (dv_range_mps, v_range_mps) = (range(|s| s.dv), range(|s| s.v));
    let (temperature, temperature_note) = match fit_temperature(&per_temperature, degree) {
        Ok(t) => {
            for e in &t.excluded {
                notes.push(format!("k(T) fitted without {e}"));
            }
            (Some(t), None)
        }
        Err(e) => (None, Some(e.to_string())),
    };
    (
        PolachReport {
            format: "railgrip-polach-fit".into(),
            version: 2,
            patch: [patch.a_m, patch.b_m, patch.g_pa, patch.c11, patch.c22],
            wheel_load_n: q_n,
            pooled,
            dv_range_mps,
            v_range_mps,
            per_run,
            per_temperature,
            temperature,
            temperature_note,
        },
        notes,
    )
}
