//! Polach creep-force fits (seed 004 004_7d175079b70fb95b.txt eq. 1–3; Polach 2005) to the
//! estimated μ, and the temperature dependence k_A(T), k_S(T) across runs.
//!
//! Per sample, one wheel carries Q = N_i / 2 and the estimate μ_i = T_i / N_i is the wheel's
//! F/Q, so the model is μ̂ = polach(patch, params, Q, v, Δv, 0).f_x / Q (contact library,
//! creepage Δv/v, falling friction μ = μ0[(1 − A)e^(−BΔv) + A]). The patch (Hertz + Kalker at
//! the static wheel load, pipeline `[contact]`) is held fixed.
//!
//! Parameters are fitted by the same Levenberg–Marquardt solver as the network, on
//! unconstrained coordinates with bounds by reparametrisation (logistic, see [`LOWER`],
//! [`UPPER`]), with the analytic Jacobian ([`mu_and_gradient`]). What the data cannot identify
//! is held and named ([`fit_polach`]); the estimated parameters get Wald standard errors
//! corrected for the residuals' autocorrelation (n_eff, [`crate::linalg::effective_samples`])
//! and profile-likelihood intervals ([`Profile`]).
//!
//! Temperature: per ambient temperature (run metadata `ambient_temperature_c`), one Polach fit
//! of the pooled runs; then the temperature law — μ0(T) (seed 004 Fig. 2: the adhesion level
//! moves with temperature), k_A(T), k_S(T) (seed 004 eq. 3), or both, of degrees up to
//! `train.temperature_degree` — fitted jointly over all samples and chosen by BIC
//! ([`fit_temperature_forms`]).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::dataset::RunTable;
use super::lm::{self, LeastSquares, LevenbergMarquardt, LmSettings, NormalEquations};
use super::IdentifyError;
use crate::contact::polach::{horner, ContactPatch, PolachParams};
use crate::linalg::{cho_solve, cholesky, effective_samples};

/// Standard errors in files: NaN (held, not identifiable or not applicable) written as `null`
/// and read back as NaN (JSON has no NaN).
mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(x: &[f64; 5], s: S) -> Result<S::Ok, S::Error> {
        x.map(|v| v.is_finite().then_some(v)).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 5], D::Error> {
        let v = <[Option<f64>; 5]>::deserialize(d)?;
        Ok(v.map(|x| x.unwrap_or(f64::NAN)))
    }
}

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
    let inv_dxa = 1.0 / dxa;
    let bracket = xa * inv_dxa + ys.atan();
    let two_pi = 2.0 / std::f64::consts::PI;
    let f = two_pi * mu_w * bracket;
    let h1 = (1.0 - xa * xa) * (inv_dxa * inv_dxa);
    let inv_dys = 1.0 / dys;
    let df_dmuw = two_pi * (bracket - xa * h1 - ys * inv_dys);
    let scale = two_pi * mu_w * eps;
    (
        f,
        [
            df_dmuw * g,
            df_dmuw * mu0 * (1.0 - e),
            -df_dmuw * mu0 * (1.0 - a) * s.dv * e,
            scale * (h1 + rho * inv_dys),
            scale * k_a * inv_dys,
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
    2.0 / std::f64::consts::PI * mu_w * (xa * (1.0 / (1.0 + xa * xa)) + ys.atan())
}

/// Most coefficients per parameter of a temperature law (degree ≤ 5, the bound of
/// `train.temperature_degree`).
const MAX_NODES: usize = 6;
/// Most free coordinates of a problem (five parameters, each with up to [`MAX_NODES`]).
const MAX_COORDS: usize = 5 * MAX_NODES;

/// The samples at one ambient temperature (a contiguous range of the problem's samples) and,
/// per parameter, its Lagrange basis at that temperature: x_i = Σ_j basis[i][j] · node_ij.
/// A fit without temperature law is one group with basis [1, 0, …] for every parameter.
#[derive(Debug, Clone)]
struct Group {
    range: std::ops::Range<usize>,
    basis: [[f64; MAX_NODES]; 5],
}

/// One free coordinate: parameter `param`'s value at temperature node `node` (degree 0: its
/// constant value), solved for in its unconstrained logistic coordinate.
#[derive(Debug, Clone, Copy)]
struct Coord {
    param: usize,
    node: usize,
}

/// The least-squares problem of one fit: parameters held at `fixed`, the others' node values
/// free; `ks_fixed` holds k_S itself (profile likelihood of k_S), ρ = k_S/k_A then follows k_A.
struct PolachProblem<'a> {
    samples: &'a [Sample],
    groups: Vec<Group>,
    fixed: [Option<f64>; 5],
    ks_fixed: Option<f64>,
    free: Vec<Coord>,
}

/// Node values of the five parameters.
type Nodes = [[f64; MAX_NODES]; 5];

impl<'a> PolachProblem<'a> {
    /// Constant parameters over all samples, `fixed` held.
    fn plain(samples: &'a [Sample], fixed: [Option<f64>; 5], ks_fixed: Option<f64>) -> Self {
        let group = Group {
            range: 0..samples.len(),
            basis: basis_at([0; 5], 0.0, 0.0, 0.0),
        };
        Self::new(samples, vec![group], [0; 5], fixed, ks_fixed)
    }

    fn new(
        samples: &'a [Sample],
        groups: Vec<Group>,
        degrees: [usize; 5],
        fixed: [Option<f64>; 5],
        ks_fixed: Option<f64>,
    ) -> Self {
        let free = (0..5)
            .filter(|&i| fixed[i].is_none() && !(i == 4 && ks_fixed.is_some()))
            .flat_map(|param| (0..=degrees[param]).map(move |node| Coord { param, node }))
            .collect();
        PolachProblem {
            samples,
            groups,
            fixed,
            ks_fixed,
            free,
        }
    }

    /// Node values from θ, and each free coordinate's d(node)/dθ.
    fn nodes(&self, theta: &[f64]) -> (Nodes, Vec<f64>) {
        let mut v = [[0.0; MAX_NODES]; 5];
        let mut d = vec![0.0; self.free.len()];
        for (k, c) in self.free.iter().enumerate() {
            (v[c.param][c.node], d[k]) = to_natural(c.param, theta[k]);
        }
        (v, d)
    }

    /// θ of node values `v` (inside their bounds).
    fn theta(&self, v: &Nodes) -> Vec<f64> {
        self.free
            .iter()
            .map(|c| to_unconstrained(c.param, v[c.param][c.node]))
            .collect()
    }

    /// The natural parameters (μ0, A, B, k_A, ρ) at a group, and which were clamped into their
    /// bounds (a temperature law's interpolation may leave them between nodes; a clamped
    /// parameter does not move with its nodes).
    #[inline]
    fn at_group(&self, g: &Group, v: &Nodes) -> ([f64; 5], [bool; 5]) {
        let mut x = [0.0; 5];
        let mut clamped = [false; 5];
        for i in 0..5 {
            x[i] = match self.fixed[i] {
                Some(f) => f,
                None => {
                    let raw: f64 = (0..MAX_NODES).map(|j| g.basis[i][j] * v[i][j]).sum();
                    let c = raw.clamp(LOWER[i], UPPER[i]);
                    clamped[i] = c != raw;
                    c
                }
            };
        }
        if let Some(ks) = self.ks_fixed {
            x[4] = ks / x[3];
        }
        (x, clamped)
    }

    fn sse_nodes(&self, v: &Nodes) -> f64 {
        let mut sse = 0.0;
        for g in &self.groups {
            let (x, _) = self.at_group(g, v);
            for s in &self.samples[g.range.clone()] {
                let r = mu_only(&x, s) - s.mu;
                sse += r * r;
            }
        }
        sse
    }

    /// JᵀJ, Jᵀr and the SSE in θ (`natural = false`, for the solver) or in the node values
    /// themselves (`natural = true`, for standard errors), one pass over the samples; the
    /// residuals into `residuals` when given.
    fn accumulate(
        &self,
        theta: &[f64],
        natural: bool,
        mut residuals: Option<&mut Vec<f64>>,
    ) -> NormalEquations {
        let (v, d) = self.nodes(theta);
        let k = self.free.len();
        let mut jtj = vec![0.0; k * k];
        let mut jtr = vec![0.0; k];
        let mut sse = 0.0;
        // Per coordinate: its parameter and d(parameter)/d(coordinate) at the group.
        let mut row = [0.0; MAX_COORDS];
        let mut m = [0.0; MAX_COORDS];
        let mut ps = [0usize; MAX_COORDS];
        for (c, co) in self.free.iter().enumerate() {
            ps[c] = co.param;
        }
        for g in &self.groups {
            let (x, clamped) = self.at_group(g, &v);
            for (c, co) in self.free.iter().enumerate() {
                let dd = if natural { 1.0 } else { d[c] };
                m[c] = if clamped[co.param] {
                    0.0
                } else {
                    g.basis[co.param][co.node] * dd
                };
            }
            // With k_S held, k_A also moves ρ = k_S/k_A: dρ/dk_A = −k_S/k_A².
            let drho = self.ks_fixed.map(|ks| -ks / (x[3] * x[3]));
            for s in &self.samples[g.range.clone()] {
                let (f, mut grad) = mu_and_gradient(&x, s);
                if let Some(dr) = drho {
                    grad[3] += grad[4] * dr;
                }
                let r = f - s.mu;
                sse += r * r;
                if let Some(out) = residuals.as_deref_mut() {
                    out.push(r);
                }
                for c in 0..k {
                    row[c] = grad[ps[c]] * m[c];
                }
                for a in 0..k {
                    jtr[a] += row[a] * r;
                    for b in 0..=a {
                        jtj[a * k + b] += row[a] * row[b];
                    }
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

    /// The covariance of the free node values at θ: σ² (JᵀJ)⁻¹ inflated by n/n_eff for the
    /// residuals' autocorrelation ([`effective_samples`]); `None` where JᵀJ is singular.
    fn covariance(&self, theta: &[f64]) -> Covariance {
        let n = self.samples.len();
        let mut r = Vec::with_capacity(n);
        let ne = self.accumulate(theta, true, Some(&mut r));
        let n_eff = effective_samples(&r);
        let k = self.free.len();
        let sigma2 = ne.sse / (n as f64 - k as f64).max(1.0);
        let scale = sigma2 * n as f64 / n_eff.max(1.0);
        let cov = cholesky(&ne.jtj, k).map(|l| {
            let mut out = vec![0.0; k * k];
            for col in 0..k {
                let mut unit = vec![0.0; k];
                unit[col] = 1.0;
                for (row, x) in cho_solve(&l, k, &unit).into_iter().enumerate() {
                    out[row * k + col] = x * scale;
                }
            }
            out
        });
        Covariance {
            cov,
            sse: ne.sse,
            n_eff,
            scale,
            residuals: r,
        }
    }
}

/// [`PolachProblem::covariance`]'s result.
struct Covariance {
    /// k × k over the free coordinates (row-major), natural units.
    cov: Option<Vec<f64>>,
    sse: f64,
    n_eff: f64,
    /// σ² n/n_eff: the variance of one residual, inflated for autocorrelation.
    scale: f64,
    residuals: Vec<f64>,
}

impl LeastSquares for PolachProblem<'_> {
    fn n_params(&self) -> usize {
        self.free.len()
    }
    fn n_train(&self) -> usize {
        self.samples.len()
    }
    fn sse(&self, theta: &[f64]) -> f64 {
        self.sse_nodes(&self.nodes(theta).0)
    }
    /// One pass over the samples: JᵀJ and Jᵀr in the unconstrained coordinates (the
    /// analytic Jacobian in the natural parameters times the chain of node → parameter and
    /// θ → node, column by column).
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        self.accumulate(theta, false, None)
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
    /// Standard errors in the same order (μ0, A, B, k_A, k_S), corrected for the residuals'
    /// autocorrelation; NaN (`null`) for a parameter held at a bound or where the data did
    /// not identify it.
    #[serde(with = "nan_as_null")]
    pub se: [f64; 5],
    /// What the data said about each parameter (same order; k_S's is that of k_S/k_A, the
    /// parameter the fit solves for).
    #[serde(default = "all_estimated")]
    pub status: [ParamStatus; 5],
    /// Why parameters were held (one line each), in the order it happened.
    #[serde(default)]
    pub notes: Vec<String>,
    /// Profile likelihood of each estimated parameter, with its 95 % interval (the pooled and
    /// per-temperature fits; empty for per-run fits).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub profiles: Vec<Profile>,
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

/// The profile likelihood of one parameter: at each value the others refitted, the statistic
/// Δ(x) = (SSE(x) − SSE_min) / (σ² n/n_eff) (the likelihood-ratio statistic of Gaussian
/// residuals, with σ² = SSE_min/(n − k) and the autocorrelation correction n/n_eff of the
/// standard errors); the 95 % interval is where Δ ≤ χ²₁(0.95) = 3.841 (Venzon & Moolgavkar,
/// Appl. Statist. 37 (1988) 87–94). Unlike the Wald interval (±1.96 se) it follows the
/// law's curvature, so it may be asymmetric.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    /// `mu0`, `a_ratio`, `b_s_per_m`, `k_a` or `k_s`.
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
const PROFILE_STEPS: [f64; 11] = [1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 32.0];

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

/// The refits of a profile, warm-started next to their optimum: ftol = xtol = 1e-8 (an SSE
/// within 1e-8 of its minimum moves the profile statistic by about 1e-8 n_eff, 5e-5 for the
/// bundled archive's pooled fit).
fn profile_settings() -> LmSettings {
    LmSettings {
        ftol: 1e-7,
        xtol: 1e-7,
        ..fit_settings()
    }
}

/// Solves `problem` from node values `start`: the problem back, its optimal θ, iterations and
/// why it stopped.
fn solve<'a>(
    group: &str,
    problem: PolachProblem<'a>,
    start: &Nodes,
    settings: LmSettings,
) -> Result<(PolachProblem<'a>, Vec<f64>, usize, lm::StopReason), IdentifyError> {
    let theta0 = problem.theta(start);
    if theta0.is_empty() {
        return Ok((problem, theta0, 0, lm::StopReason::MinGrad));
    }
    let (solver, problem) =
        lm::run(problem, LevenbergMarquardt::new(settings), theta0).map_err(|e| {
            IdentifyError::Solver {
                fit: format!("Polach fit {group}"),
                source: e.into(),
            }
        })?;
    let theta = solver.best().expect("solver ran").to_vec();
    let stop = solver.stop_reason().unwrap_or(lm::StopReason::Epochs);
    Ok((problem, theta, solver.history().len(), stop))
}

/// Constant node values of natural parameters `x`.
fn constant_nodes(x: &[f64; 5]) -> Nodes {
    let mut v = [[0.0; MAX_NODES]; 5];
    for i in 0..5 {
        v[i] = [x[i]; MAX_NODES];
    }
    v
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
///    with it (tested);
/// 4. with `profile`, the profile likelihood of every estimated parameter ([`Profile`]).
///
/// The fit ends with every parameter classified; it fails only without data.
pub fn fit_polach(
    group: &str,
    tables: &[&RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    start: PolachParams,
    profile: bool,
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
    let (x, var, cov, stop) = loop {
        let problem = PolachProblem::plain(&s, fixed, None);
        let (problem, theta, its, stop) =
            solve(group, problem, &constant_nodes(&current), fit_settings())?;
        iterations += its;
        let x = problem
            .at_group(&problem.groups[0], &problem.nodes(&theta).0)
            .0;
        current = x;
        // 2. Bounds.
        let mut held = false;
        let free_now: Vec<usize> = (0..5).filter(|i| fixed[*i].is_none()).collect();
        for i in free_now {
            let sg = sigmoid(to_unconstrained(i, x[i]));
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
        let cov = problem.covariance(&theta);
        let mut var = [f64::NAN; 5];
        let k = problem.free.len();
        for (c, co) in problem.free.iter().enumerate() {
            var[co.param] = cov.cov.as_ref().map_or(f64::INFINITY, |m| m[c * k + c]);
        }
        // The worst-determined free parameter, if any fails the Wald test.
        let worst = problem
            .free
            .iter()
            .map(|co| (co.param, var[co.param].sqrt() / x[co.param].abs()))
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
        let pos = |p: usize| problem.free.iter().position(|c| c.param == p);
        let cov_ka_rho = match (pos(3), pos(4), &cov.cov) {
            (Some(a), Some(b), Some(m)) => m[a * k + b],
            _ => 0.0,
        };
        let v0 = |v: f64| if v.is_finite() { v } else { 0.0 };
        var[4] = match (fixed[3].is_none(), fixed[4].is_none()) {
            (false, false) => f64::NAN,
            _ => {
                x[4] * x[4] * v0(var[3]) + x[3] * x[3] * v0(var[4]) + 2.0 * x[3] * x[4] * cov_ka_rho
            }
        };
        break (x, var, cov, stop);
    };
    // k_S = k_A ρ carries the status of ρ: held at a bound, k_S/k_A is fixed (k_S = k_A, or
    // 0), and k_S has no standard error of its own.
    let p = law_params(&x);
    let se: [f64; 5] = std::array::from_fn(|i| match status[i] {
        ParamStatus::Estimated => var[i].sqrt(),
        _ => f64::NAN,
    });
    let profiles = if profile {
        profiles(group, &s, fixed, &x, &se, &status, &cov)
    } else {
        Vec::new()
    };
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
        profiles,
        samples: s.len(),
        effective_samples: cov.n_eff,
        rmse: (cov.sse / s.len() as f64).sqrt(),
        ambient_temperature_c: None,
        iterations,
        stop_reason: stop.text().to_string(),
    })
}

/// One side of a profile: its points (outward) and the interval's limit, if reached.
type Side = (Vec<(f64, f64)>, Option<f64>);

/// The profile likelihood of every estimated parameter of a fit at `x` (natural, ρ for k_S)
/// with `fixed` held: both sides of each in parallel, each side warm-started from its previous
/// point. A side whose refit fails ends there, unbounded.
fn profiles(
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
fn label(i: usize) -> &'static str {
    ["μ0", "A", "B", "k_A", "k_S/k_A"][i]
}

/// One temperature form the campaign fit tried, and how it fitted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TemperatureCandidate {
    /// Degrees of μ0(T) and of k_A(T), k_S(T)/k_A(T) (0: constant).
    pub mu0_degree: usize,
    pub k_degree: usize,
    /// Free parameters (those the pooled fit held are not counted).
    pub parameters: usize,
    pub sse: f64,
    pub rmse: f64,
    /// AIC = n_eff ln(SSE/n) + 2p and BIC = n_eff ln(SSE/n) + p ln n_eff: the Gaussian
    /// log-likelihood of n residuals carries the information of n_eff independent ones
    /// (n_eff of the most flexible form's residuals, the same for every candidate).
    pub aic: f64,
    pub bic: f64,
    pub iterations: usize,
    pub stop_reason: String,
    /// Why the form cannot be used (its law leaves the valid domain), if so.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rejected: Option<String>,
}

impl TemperatureCandidate {
    /// "μ0(T) degree 1, k(T) constant" and the like.
    pub fn form(&self) -> String {
        form_name(self.mu0_degree, self.k_degree)
    }
}

fn form_name(mu0_degree: usize, k_degree: usize) -> String {
    let part = |name: &str, d: usize| match d {
        0 => format!("{name} constant"),
        d => format!("{name} degree {d}"),
    };
    format!("{}, {}", part("μ0(T)", mu0_degree), part("k(T)", k_degree))
}

/// The temperature law of a campaign: the form chosen by BIC among μ0(T) and k_A(T), k_S(T)
/// of degrees 0 … `train.temperature_degree`, fitted jointly to every sample of the runs with
/// an ambient temperature (A and B shared), and the candidates it was chosen from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TemperatureFit {
    /// The chosen degrees (both 0: the data prefer no temperature dependence; no law is written).
    pub mu0_degree: usize,
    pub k_degree: usize,
    /// The chosen form's polynomials, ascending powers of T (°C).
    pub mu0: Vec<f64>,
    pub k_a: Vec<f64>,
    pub k_s: Vec<f64>,
    pub a_ratio: f64,
    pub b_s_per_m: f64,
    /// Standard errors of the parameters that do not depend on T (μ0, A, B, k_A, k_S order;
    /// null for those that do, or that the pooled fit held).
    #[serde(with = "nan_as_null")]
    pub se: [f64; 5],
    pub fitted_range_c: (f64, f64),
    /// Median temperature of the samples (°C): the model file's μ0, k_A, k_S are the law's
    /// values there (used when a caller gives no temperature).
    pub reference_temperature_c: f64,
    pub samples: usize,
    pub effective_samples: f64,
    /// `BIC`.
    pub criterion: String,
    pub candidates: Vec<TemperatureCandidate>,
    /// Per temperature: (T, μ0, k_A, k_S) of that temperature's own fit minus the law.
    pub residuals: Vec<(f64, f64, f64, f64)>,
    /// Temperatures whose own fit did not identify k_A and k_S (k(T) forms are offered only
    /// when two or more do), with why.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub excluded: Vec<String>,
    /// Forms not offered, and why.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

impl TemperatureFit {
    /// Whether anything depends on temperature.
    pub fn has_law(&self) -> bool {
        self.mu0_degree > 0 || self.k_degree > 0
    }
    pub fn form(&self) -> String {
        form_name(self.mu0_degree, self.k_degree)
    }
    /// (μ0, k_A, k_S) at T (°C, not clamped).
    pub fn at(&self, t_c: f64) -> (f64, f64, f64) {
        (
            horner(&self.mu0, t_c),
            horner(&self.k_a, t_c),
            horner(&self.k_s, t_c),
        )
    }
    /// As a model file's temperature section (μ0 coefficients only when μ0 depends on T).
    pub fn spec(&self) -> crate::model::polach::TemperatureSpec {
        crate::model::polach::TemperatureSpec {
            mu0: if self.mu0_degree > 0 {
                self.mu0.clone()
            } else {
                Vec::new()
            },
            k_a: self.k_a.clone(),
            k_s: self.k_s.clone(),
            fitted_range_c: [self.fitted_range_c.0, self.fitted_range_c.1],
        }
    }
}

/// The temperatures whose own Polach fit identified k_A and k_S, and those left out with why
/// (a value held because the data did not determine it says nothing about how k changes with
/// temperature; k_S/k_A at its bound leaves k_S = k_A or 0, as determined as k_A).
pub fn k_identified(fits: &[PolachFit]) -> (Vec<f64>, Vec<String>) {
    let mut kept = Vec::new();
    let mut excluded = Vec::new();
    for f in fits {
        let Some(t) = f.ambient_temperature_c else {
            continue;
        };
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
            kept.push(t);
        } else {
            excluded.push(format!("T = {t} °C ({})", held.join(", ")));
        }
    }
    (kept, excluded)
}

/// Evenly spaced temperature nodes of a degree-d law over [lo, hi].
fn temperature_nodes(d: usize, lo: f64, hi: f64) -> Vec<f64> {
    if d == 0 {
        return vec![0.5 * (lo + hi)];
    }
    (0..=d)
        .map(|j| lo + (hi - lo) * j as f64 / d as f64)
        .collect()
}

/// Per parameter, the basis at temperature t (°C) of a law of `degrees` over [lo, hi]: the
/// Lagrange basis of its nodes, or [1, 0, …] for a constant.
fn basis_at(degrees: [usize; 5], lo: f64, hi: f64, t: f64) -> [[f64; MAX_NODES]; 5] {
    std::array::from_fn(|i| {
        if degrees[i] == 0 {
            let mut b = [0.0; MAX_NODES];
            b[0] = 1.0;
            b
        } else {
            lagrange(&temperature_nodes(degrees[i], lo, hi), t)
        }
    })
}

/// The Lagrange basis of `nodes` at t.
fn lagrange(nodes: &[f64], t: f64) -> [f64; MAX_NODES] {
    let mut out = [0.0; MAX_NODES];
    for (j, tj) in nodes.iter().enumerate() {
        out[j] = nodes
            .iter()
            .enumerate()
            .filter(|(m, _)| *m != j)
            .map(|(_, tm)| (t - tm) / (tj - tm))
            .product();
    }
    out
}

/// The polynomial (ascending powers) through (nodes[j], values[j]): Σ_j values[j] L_j(t),
/// each L_j expanded as Π_{m≠j} (t − t_m)/(t_j − t_m).
fn monomials(nodes: &[f64], values: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; nodes.len()];
    for (j, tj) in nodes.iter().enumerate() {
        let mut poly = vec![values[j]];
        for (m, tm) in nodes.iter().enumerate().filter(|(m, _)| *m != j) {
            let _ = m;
            let scale = 1.0 / (tj - tm);
            let mut next = vec![0.0; poly.len() + 1];
            for (p, c) in poly.iter().enumerate() {
                next[p + 1] += c * scale;
                next[p] -= c * tm * scale;
            }
            poly = next;
        }
        for (o, c) in out.iter_mut().zip(&poly) {
            *o += c;
        }
    }
    out
}

/// Product of two polynomials (ascending powers).
fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// A note when the samples' slip coverage changes monotonically with temperature: the median
/// slip of each temperature group, ordered by temperature, strictly rising or falling over three
/// or more temperatures by more than 20 %. A law family that does not fit the data exactly then
/// fits different slip ranges with different parameters, and a temperature law can stand for
/// the coverage (e.g. a campaign that brakes harder in the cold) — the data cannot tell them
/// apart (measured on the foreign `table` law, README "Temperature law").
fn coverage_note(s: &[Sample], ranges: &[(f64, std::ops::Range<usize>)]) -> Option<String> {
    if ranges.len() < 3 {
        return None;
    }
    let medians: Vec<f64> = ranges
        .iter()
        .map(|(_, r)| {
            let mut dv: Vec<f64> = s[r.clone()].iter().map(|x| x.dv).collect();
            dv.sort_by(f64::total_cmp);
            dv.get(dv.len() / 2).copied().unwrap_or(f64::NAN)
        })
        .collect();
    let rising = medians.windows(2).all(|w| w[1] > w[0]);
    let falling = medians.windows(2).all(|w| w[1] < w[0]);
    let (first, last) = (medians[0], medians[medians.len() - 1]);
    if !(rising || falling) || (first.max(last) / first.min(last)) < 1.2 {
        return None;
    }
    Some(format!(
        "the runs' slip coverage changes with temperature (median Δv {:.2} m/s at {} °C to {:.2} m/s at {} °C): a temperature law here may stand for the slip range each temperature's runs cover rather than for the temperature; brake at equal demand across temperatures (or add runs) to tell them apart",
        first,
        ranges[0].0,
        last,
        ranges[ranges.len() - 1].0
    ))
}

/// One candidate's fit: its record, the law's polynomials (μ0, k_A, k_S), A, B, and the
/// standard errors of its constant parameters.
struct FormFit {
    record: TemperatureCandidate,
    mu0: Vec<f64>,
    k_a: Vec<f64>,
    k_s: Vec<f64>,
    a_ratio: f64,
    b_s_per_m: f64,
    se: [f64; 5],
    residuals: Vec<f64>,
}

/// Fits the temperature law of a campaign (issue 16): the candidate forms μ0(T) of degree
/// d_μ and k_A(T), ρ(T) = k_S/k_A of degree d_k (d ≤ min(`degree`, temperatures − 1); A and B
/// constant), each jointly over all samples of the runs with `ambient_temperature_c`, each
/// parameter's law as its values at evenly spaced nodes over the range (Lagrange basis;
/// logistic bounds at the nodes, clamped between them), from the pooled fit's values, with the
/// parameters the pooled fit held still held. The form with the least BIC (n_eff-corrected, see
/// [`TemperatureCandidate`]) whose law stays in the valid domain over the range
/// (0 < μ0 ≤ 1.5, 0 < k_S ≤ k_A ≤ 1) is chosen. k forms are offered only when two or more
/// temperatures' own fits identified k_A and k_S ([`k_identified`]), μ0 forms only when the
/// pooled fit identified μ0.
#[allow(clippy::too_many_arguments)]
pub fn fit_temperature_forms(
    tables: &[&RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    degree: usize,
    pooled: &PolachFit,
    per_temperature: &[PolachFit],
) -> Result<TemperatureFit, IdentifyError> {
    let mut temps: Vec<f64> = tables
        .iter()
        .filter_map(|t| t.metadata.ambient_temperature_c)
        .collect();
    temps.sort_by(f64::total_cmp);
    temps.dedup();
    if temps.len() < 2 {
        return Err(IdentifyError::Data {
            what: format!(
                "a temperature law needs runs at two or more ambient temperatures; found {}",
                temps.len()
            ),
            hint: "give runs at several ambient temperatures with ambient_temperature_c in their metadata".into(),
        });
    }
    let (lo, hi) = (temps[0], temps[temps.len() - 1]);
    // Samples grouped by temperature.
    let mut s = Vec::new();
    let mut ranges = Vec::new();
    for t in &temps {
        let at: Vec<&RunTable> = tables
            .iter()
            .copied()
            .filter(|r| r.metadata.ambient_temperature_c == Some(*t))
            .collect();
        let from = s.len();
        s.extend(samples(&at, q_n, decimate));
        ranges.push((*t, from..s.len()));
    }
    if s.len() < 20 {
        return Err(IdentifyError::Data {
            what: format!("only {} samples with slip for the temperature law", s.len()),
            hint: "fit on braking runs with wheel slip".into(),
        });
    }
    let s = with_patch(s, &patch);
    // The samples' median temperature (groups are in ascending temperature).
    let mut seen = 0;
    let reference = ranges
        .iter()
        .find(|(_, r)| {
            seen += r.len();
            2 * seen > s.len()
        })
        .map_or(lo, |(t, _)| *t);

    let mut notes = Vec::new();
    let held = |i: usize| pooled.status[i] != ParamStatus::Estimated;
    let top = degree.min(temps.len() - 1).min(MAX_NODES - 1);
    let (k_temps, excluded) = k_identified(per_temperature);
    let k_top = if held(3) || held(4) {
        notes.push(format!(
            "k(T) forms not offered: the pooled fit holds {}",
            if held(3) { "k_A" } else { "k_S/k_A" }
        ));
        0
    } else if k_temps.len() < 2 {
        notes.push(format!(
            "k(T) forms not offered: k_A and k_S are identified at {} of the temperatures (two or more needed); left out: {}",
            k_temps.len(),
            excluded.join("; ")
        ));
        0
    } else {
        top.min(k_temps.len() - 1)
    };
    let mu_top = if held(0) {
        notes.push("μ0(T) forms not offered: the pooled fit holds μ0".into());
        0
    } else {
        top
    };
    if top == 0 {
        notes.push("train.temperature_degree = 0: only the constant form".into());
    }
    if let Some(n) = coverage_note(&s, &ranges) {
        notes.push(n);
    }
    let x0 = solver_order(&pooled.params());
    let fixed: [Option<f64>; 5] = std::array::from_fn(|i| held(i).then_some(x0[i]));
    let forms: Vec<(usize, usize)> = (0..=mu_top)
        .flat_map(|dm| (0..=k_top).map(move |dk| (dm, dk)))
        .collect();
    let fits: Vec<Result<FormFit, IdentifyError>> = forms
        .par_iter()
        .map(|&(dm, dk)| {
            let degrees = [dm, 0, 0, dk, dk];
            let nodes: Vec<Vec<f64>> = degrees
                .iter()
                .map(|&d| temperature_nodes(d, lo, hi))
                .collect();
            let groups = ranges
                .iter()
                .map(|(t, r)| Group {
                    range: r.clone(),
                    basis: basis_at(degrees, lo, hi, *t),
                })
                .collect();
            let degrees_free: [usize; 5] =
                std::array::from_fn(|i| if fixed[i].is_some() { 0 } else { degrees[i] });
            let problem = PolachProblem::new(&s, groups, degrees_free, fixed, None);
            let (problem, theta, its, stop) = solve(
                &form_name(dm, dk),
                problem,
                &constant_nodes(&x0),
                fit_settings(),
            )?;
            let (v, _) = problem.nodes(&theta);
            let cov = problem.covariance(&theta);
            let value = |i: usize| -> Vec<f64> {
                match fixed[i] {
                    Some(f) => vec![f],
                    None => monomials(&nodes[i], &v[i][..=degrees[i]]),
                }
            };
            let k = problem.free.len();
            let mut se = [f64::NAN; 5];
            for (c, co) in problem.free.iter().enumerate() {
                if degrees[co.param] == 0 {
                    se[co.param] = cov.cov.as_ref().map_or(f64::NAN, |m| m[c * k + c].sqrt());
                }
            }
            let (ka, rho) = (value(3), value(4));
            if degrees[3] == 0 && fixed[3].is_none() && fixed[4].is_none() {
                let pos = |p: usize| problem.free.iter().position(|c| c.param == p);
                if let (Some(a), Some(b), Some(m)) = (pos(3), pos(4), &cov.cov) {
                    se[4] = (rho[0] * rho[0] * m[a * k + a]
                        + ka[0] * ka[0] * m[b * k + b]
                        + 2.0 * ka[0] * rho[0] * m[a * k + b])
                        .sqrt();
                }
            } else {
                se[4] = f64::NAN;
            }
            Ok(FormFit {
                record: TemperatureCandidate {
                    mu0_degree: dm,
                    k_degree: dk,
                    parameters: k,
                    sse: cov.sse,
                    rmse: (cov.sse / s.len() as f64).sqrt(),
                    aic: f64::NAN,
                    bic: f64::NAN,
                    iterations: its,
                    stop_reason: stop.text().into(),
                    rejected: None,
                },
                mu0: value(0),
                k_s: poly_mul(&ka, &rho),
                k_a: ka,
                a_ratio: value(1)[0],
                b_s_per_m: value(2)[0],
                se,
                residuals: cov.residuals,
            })
        })
        .collect();
    let mut fits: Vec<FormFit> = fits.into_iter().collect::<Result<_, _>>()?;
    // n_eff of the most flexible form's residuals (the last; closest to the noise alone — a
    // form that misses a temperature trend leaves residuals correlated over whole runs, whose
    // n_eff would hide the very trend), for every candidate.
    let n = s.len() as f64;
    let n_eff = effective_samples(&fits[fits.len() - 1].residuals).max(1.0);
    for f in &mut fits {
        let c = &mut f.record;
        let fit_term = n_eff * (c.sse / n).ln();
        c.aic = fit_term + 2.0 * c.parameters as f64;
        c.bic = fit_term + c.parameters as f64 * n_eff.ln();
        let spec = crate::model::polach::TemperatureSpec {
            mu0: f.mu0.clone(),
            k_a: f.k_a.clone(),
            k_s: f.k_s.clone(),
            fitted_range_c: [lo, hi],
        };
        if let Err(e) = crate::model::polach::check_law(&spec, f.mu0[0]) {
            c.rejected = Some(e.to_string());
        }
        f.residuals = Vec::new();
    }
    let best = fits
        .iter()
        .enumerate()
        .filter(|(_, f)| f.record.rejected.is_none())
        .min_by(|a, b| a.1.record.bic.total_cmp(&b.1.record.bic))
        .map(|(i, _)| i)
        .ok_or_else(|| IdentifyError::Data {
            what: "every temperature form leaves the valid domain of Polach's law".into(),
            hint: "lower train.temperature_degree".into(),
        })?;
    let chosen = &fits[best];
    let mut law = TemperatureFit {
        mu0_degree: chosen.record.mu0_degree,
        k_degree: chosen.record.k_degree,
        mu0: chosen.mu0.clone(),
        k_a: chosen.k_a.clone(),
        k_s: chosen.k_s.clone(),
        a_ratio: chosen.a_ratio,
        b_s_per_m: chosen.b_s_per_m,
        se: chosen.se,
        fitted_range_c: (lo, hi),
        reference_temperature_c: reference,
        samples: s.len(),
        effective_samples: n_eff,
        criterion: "BIC".into(),
        candidates: fits.into_iter().map(|f| f.record).collect(),
        residuals: Vec::new(),
        excluded,
        notes,
    };
    law.residuals = per_temperature
        .iter()
        .filter_map(|f| {
            let t = f.ambient_temperature_c?;
            let (m, a, k) = law.at(t);
            Some((t, f.mu0 - m, f.k_a - a, f.k_s - k))
        })
        .collect();
    Ok(law)
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
                // Truncation O(h²) relative, plus the rounding of the difference quotient,
                // a few ulps of f over h.
                let tol = 1e-6 * (g[i].abs() + fd.abs()) + 16.0 * f64::EPSILON * f.abs() / h;
                proptest::prop_assert!((g[i] - fd).abs() <= tol, "param {}: {} vs {}", i, g[i], fd);
            }
        }
    }

    /// Samples over three temperature groups for the problem tests.
    fn grouped_samples() -> (Vec<Sample>, Vec<(f64, std::ops::Range<usize>)>) {
        let mut rng = crate::rng::Rng::new(3);
        let mut s = Vec::new();
        let mut ranges = Vec::new();
        for (g, t) in [-20.0, 5.0, 30.0].iter().enumerate() {
            let from = s.len();
            for _ in 0..200 {
                let dv = 0.01 + 3.0 * rng.uniform();
                s.push(Sample {
                    q_n: 80_000.0,
                    v: 5.0 + 30.0 * rng.uniform(),
                    dv,
                    mu: 0.08 + 0.01 * g as f64 + 0.005 * rng.normal(),
                    cs: f64::NAN,
                });
            }
            ranges.push((*t, from..s.len()));
        }
        (with_patch(s, &patch()), ranges)
    }

    fn groups_for(degrees: [usize; 5], ranges: &[(f64, std::ops::Range<usize>)]) -> Vec<Group> {
        ranges
            .iter()
            .map(|(t, r)| Group {
                range: r.clone(),
                basis: basis_at(degrees, -20.0, 30.0, *t),
            })
            .collect()
    }

    /// Jᵀr of the temperature-law problem (Lagrange nodes, the logistic chain, k_S held for
    /// a profile) is the gradient of SSE/2 in θ, by central differences; and with every degree
    /// 0 the grouped problem is the plain one.
    #[test]
    fn grouped_problems_have_the_gradient_of_their_cost() {
        let (s, ranges) = grouped_samples();
        let x = [0.1, 0.4, 0.5, 0.2, 0.4];
        for (degrees, fixed, ks) in [
            ([1, 0, 0, 2, 1], [None; 5], None),
            ([2, 0, 0, 0, 0], [None, None, Some(0.5), None, None], None),
            ([0; 5], [None; 5], Some(0.07)),
        ] {
            let problem = PolachProblem::new(&s, groups_for(degrees, &ranges), degrees, fixed, ks);
            let mut nodes = constant_nodes(&x);
            // Distinct node values, so that the law does vary with temperature.
            nodes[0][1] = 0.12;
            nodes[3][2] = 0.25;
            let theta = problem.theta(&nodes);
            let ne = problem.normal_equations(&theta);
            assert!((ne.sse - problem.sse(&theta)).abs() < 1e-12 * ne.sse);
            for k in 0..theta.len() {
                let h = 1e-6;
                let (mut up, mut dn) = (theta.clone(), theta.clone());
                up[k] += h;
                dn[k] -= h;
                let fd = (problem.sse(&up) - problem.sse(&dn)) / (4.0 * h);
                assert!(
                    (ne.jtr[k] - fd).abs() <= 1e-6 * fd.abs().max(1e-6),
                    "{degrees:?} coordinate {k}: {} vs {fd}",
                    ne.jtr[k]
                );
            }
        }
        let plain = PolachProblem::plain(&s, [None; 5], None);
        let grouped = PolachProblem::new(&s, groups_for([0; 5], &ranges), [0; 5], [None; 5], None);
        let theta = plain.theta(&constant_nodes(&x));
        assert_eq!(
            plain.normal_equations(&theta).jtr,
            grouped.normal_equations(&theta).jtr
        );
    }

    #[test]
    fn lagrange_nodes_expand_to_the_polynomial_through_them() {
        let c = [0.1, 0.002, -1e-5, 3e-8];
        for d in 1..=3 {
            // A polynomial of degree d, which d + 1 nodes determine.
            let f = |t: f64| horner(&c[..=d], t);
            let nodes = temperature_nodes(d, -20.0, 35.0);
            let values: Vec<f64> = nodes.iter().map(|t| f(*t)).collect();
            let c = monomials(&nodes, &values);
            for t in [-20.0, -3.0, 0.0, 12.5, 35.0] {
                assert!((horner(&c, t) - f(t)).abs() < 1e-14, "degree {d} at {t}");
                let b = lagrange(&nodes, t);
                let v: f64 = values.iter().zip(b).map(|(v, b)| v * b).sum();
                assert!((v - f(t)).abs() < 1e-14, "basis, degree {d} at {t}");
            }
        }
        assert_eq!(poly_mul(&[1.0, 2.0], &[3.0, 0.5]), vec![3.0, 6.5, 1.0]);
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
    /// The temperature law and the forms it was chosen from; absent with fewer than two
    /// temperatures (`temperature_note` says why).
    pub temperature: Option<TemperatureFit>,
    /// Why there is no temperature law: `temperature` absent, or its chosen form constant.
    pub temperature_note: Option<String>,
    /// The campaign generation that wrote the file (`campaign.json`'s), when a campaign did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generation: Option<String>,
}

/// Fits every run, every temperature group (with profile-likelihood intervals for the pooled
/// and per-temperature fits when `intervals`) and the temperature law. Runs that cannot be
/// fitted are skipped with their error in `notes`.
pub fn fit_campaign(
    tables: &[RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    degree: usize,
    intervals: bool,
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
                Group::Pooled => {
                    fit_polach("all runs", &all, patch, q_n, decimate, start, intervals)
                }
                Group::Run(i) => {
                    let t = &tables[*i];
                    fit_polach(&t.name, &[t], patch, q_n, decimate, start, false).map(|mut f| {
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
                        intervals,
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
    let law = match &pooled {
        Some(p) => fit_temperature_forms(&all, patch, q_n, decimate, degree, p, &per_temperature),
        None => Err(IdentifyError::Data {
            what: "no pooled Polach fit".into(),
            hint: "see the notes above".into(),
        }),
    };
    let (temperature, temperature_note) = match law {
        Ok(t) => {
            for e in &t.excluded {
                notes.push(format!("k(T) not identified at {e}"));
            }
            let note = (!t.has_law()).then(|| {
                let best_other = t
                    .candidates
                    .iter()
                    .filter(|c| c.mu0_degree + c.k_degree > 0)
                    .map(|c| c.bic - t.candidates[0].bic)
                    .fold(f64::INFINITY, f64::min);
                format!(
                    "the data prefer no temperature dependence (BIC of the best temperature form {} above the constant's){}",
                    if best_other.is_finite() { format!("{best_other:.1}") } else { "—".into() },
                    if t.notes.is_empty() { String::new() } else { format!("; {}", t.notes.join("; ")) }
                )
            });
            (Some(t), note)
        }
        Err(e) => (None, Some(e.to_string())),
    };
    (
        PolachReport {
            format: "railgrip-polach-fit".into(),
            version: 3,
            patch: [patch.a_m, patch.b_m, patch.g_pa, patch.c11, patch.c22],
            wheel_load_n: q_n,
            pooled,
            dv_range_mps,
            v_range_mps,
            per_run,
            per_temperature,
            temperature,
            temperature_note,
            generation: None,
        },
        notes,
    )
}
