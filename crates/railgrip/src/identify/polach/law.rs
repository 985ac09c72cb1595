//! Polach's law in the fit's coordinates: the samples, the parameters' bounds and logistic
//! reparametrisation, and μ with its analytic gradient (seed 004 eq. 1–2).

use serde::{Deserialize, Serialize};

use crate::contact::polach::{ContactPatch, PolachParams};
use crate::simd::{atan_parts, exp_lanes, Select};

/// One sample for the fit.
#[derive(Debug, Clone, Copy)]
pub(super) struct Sample {
    pub(super) q_n: f64,
    pub(super) v: f64,
    pub(super) dv: f64,
    pub(super) mu: f64,
    /// c (w/v_s)/Q with c = π G a b c11/4 of the patch: the gradient ε times μ_w (set by
    /// [`with_patch`]).
    pub(super) cs: f64,
}

/// The samples with their patch term `cs` set: the creepage w/v_s taken at the sample's speed
/// (`creepage_speed` `None`: Polach's, seed 004 eq. 2) or at a fixed speed (m/s; the
/// slip-velocity form, the model file's `creepage_speed_mps`).
pub(super) fn with_patch(
    mut s: Vec<Sample>,
    patch: &ContactPatch,
    creepage_speed: Option<f64>,
) -> Vec<Sample> {
    let c = std::f64::consts::PI * patch.g_pa * patch.a_m * patch.b_m * patch.c11 / 4.0;
    for x in &mut s {
        x.cs = c * (x.dv / creepage_speed.unwrap_or(x.v)) / x.q_n;
    }
    s
}

pub(super) fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// The fitted parameters in the solver's order: μ0, A, B (s/m), k_A and ρ = k_S/k_A (so that
/// every parameter has its own bounds and k_S ≤ k_A holds by construction).
pub const PARAMETERS: [&str; 5] = ["mu0", "a_ratio", "b_s_per_m", "k_a", "k_s"];
/// Lower and upper bounds of μ0, A, B (s/m), k_A and ρ. B's are railgrip's: below 1e-3 s/m
/// friction does not fall within the slips braking reaches, above 100 s/m it falls within
/// 1 cm/s; the others are the law's own (seed 004 eq. 1–2: 0 < A < 1, 0 < k_S ≤ k_A ≤ 1).
pub(super) const LOWER: [f64; 5] = [0.0, 0.0, 1e-3, 0.0, 0.0];
pub(super) const UPPER: [f64; 5] = [1.5, 1.0, 100.0, 1.0, 1.0];
/// A parameter whose logistic coordinate is within this of 0 or 1 sits at its bound.
pub(super) const AT_BOUND: f64 = 1e-4;

/// Whether a logistic coordinate σ is within [`AT_BOUND`] of 0 or 1: the one test of "at its
/// bound", for LM's stop ([`super::problem::PolachProblem`]) and for holding the parameter
/// there ([`super::fit`]).
pub(super) fn is_at_bound(sigma: f64) -> bool {
    !(AT_BOUND..=1.0 - AT_BOUND).contains(&sigma)
}
/// A parameter is identified when its 95 % Wald interval (±1.96 se, se corrected for the
/// residuals' autocorrelation) excludes zero: se ≤ x / 1.96.
pub(super) const IDENTIFIED_Z: f64 = 1.96;

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
pub(super) fn to_natural(i: usize, p: f64) -> (f64, f64) {
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
pub(super) fn to_unconstrained(i: usize, x: f64) -> f64 {
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
pub(super) fn solver_order(q: &PolachParams) -> [f64; 5] {
    [q.mu0, q.a_ratio, q.b_s_per_m, q.k_a, q.k_s / q.k_a]
}

pub(super) fn law_params(x: &[f64; 5]) -> PolachParams {
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
/// The value is the contact library's `polach(…).fx_n / Q` (tested to 1e-14). The fits
/// evaluate it a block at a time ([`law_lanes`] through `LawBlock`); this one-sample form is
/// the tests'.
#[cfg(test)]
pub(super) fn mu_and_gradient(x: &[f64; 5], s: &Sample) -> (f64, [f64; 5]) {
    let [mu0, a, b, k_a, rho] = *x;
    law_lanes::<f64, true>(mu0, [a, b, k_a, rho], s.dv, s.cs)
}

/// The value of [`mu_and_gradient`] alone (the same operations, as the trial steps take it).
#[cfg(test)]
pub(super) fn mu_only(x: &[f64; 5], s: &Sample) -> f64 {
    let [mu0, a, b, k_a, rho] = *x;
    law_lanes::<f64, false>(mu0, [a, b, k_a, rho], s.dv, s.cs).0
}

/// atan's argument is held below this: atan(10¹⁸) = π/2 in f64, and [`atan_parts`] keeps its
/// homogeneous polynomial finite (its denominator grows as the 13th power of the argument).
const ATAN_ARGUMENT_MAX: f64 = 1e18;

/// Polach's μ and its gradient (the formulas of `mu_and_gradient` above) on every lane (with
/// `GRAD` false the gradient is left zero): μ0 per
/// lane (a speed law makes it vary by sample), (A, B, k_A, ρ) shared, slip `dv` (m/s) and
/// the patch term `cs` per lane. e^(−Bw) is [`exp_lanes`] and atan y is [`atan_parts`]:
/// every lane performs the same IEEE operations, so the plain f64 path and the vector paths
/// give the same bits (tested).
#[inline(always)]
pub(super) fn law_lanes<V: Select, const GRAD: bool>(
    mu0: V,
    [a, b, k_a, rho]: [f64; 4],
    dv: V,
    cs: V,
) -> (V, [V; 5]) {
    let isa = mu0.isa();
    // A macro, not a closure: closures do not inherit the caller's target features.
    macro_rules! c {
        ($x:expr) => {
            V::splat(isa, $x)
        };
    }
    let one = c!(1.0);
    let e = exp_lanes(c!(-b).mul(dv));
    let g = c!(1.0 - a).fma(e, c!(a));
    let mu_w = mu0.mul(g);
    let eps = cs.div(mu_w);
    let xa = c!(k_a).mul(eps);
    let ys = c!(k_a * rho).mul(eps);
    let inv_dxa = one.div(xa.fma(xa, one));
    let (off, num, den) = atan_parts(ys.min(c!(ATAN_ARGUMENT_MAX)), one);
    let bracket = xa.fma(inv_dxa, off.add(num.div(den)));
    let two_pi = c!(2.0 / std::f64::consts::PI);
    let f = two_pi.mul(mu_w).mul(bracket);
    if !GRAD {
        return (f, [c!(0.0); 5]);
    }
    let h1 = xa.fnma(xa, one).mul(inv_dxa.mul(inv_dxa));
    let inv_dys = one.div(ys.fma(ys, one));
    let df_dmuw = two_pi.mul(ys.fnma(inv_dys, xa.fnma(h1, bracket)));
    let scale = two_pi.mul(mu_w).mul(eps);
    (
        f,
        [
            df_dmuw.mul(g),
            df_dmuw.mul(mu0).mul(one.sub(e)),
            df_dmuw.mul(mu0).mul(c!(a - 1.0)).mul(dv).mul(e),
            scale.mul(c!(rho).fma(inv_dys, h1)),
            scale.mul(c!(k_a)).mul(inv_dys),
        ],
    )
}
