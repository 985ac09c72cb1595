//! One Polach fit of a group of runs: Levenberg–Marquardt with MINPACK's tests, then what the
//! data cannot identify held and named, Wald standard errors corrected for autocorrelation.

use serde::{Deserialize, Serialize};

use super::law::{
    is_at_bound, law_params, sigmoid, solver_order, with_patch, ParamStatus, Sample, AT_BOUND,
    IDENTIFIED_Z, LOWER, UPPER,
};
use super::problem::{constant_nodes, fit_settings, solve, Covariance, PolachProblem};
use super::profile::{label, profiles, Profile};
use crate::contact::polach::{ContactPatch, PolachParams};
use crate::identify::dataset::RunTable;
use crate::identify::lm::LeastSquares;

use crate::identify::IdentifyError;

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
    #[serde(with = "super::nan_as_null")]
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

pub(super) fn all_estimated() -> [ParamStatus; 5] {
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
pub(super) fn samples(tables: &[&RunTable], q_n: f64, decimate: usize) -> Vec<Sample> {
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

/// Fits Polach's parameters to the valid estimates of `tables` (pooled) with a fixed patch
/// and static wheel load `q_n`, saying what the data identify:
/// 1. LM on all five parameters (unconstrained logistic coordinates, analytic Jacobian,
///    MINPACK's ftol/xtol convergence);
/// 2. a parameter within [`AT_BOUND`] of a bound (in its logistic coordinate) is held at the
///    bound (`at bound`; a lower bound of 0, which no Polach law may take, where it was
///    detected: A = 1e-4) and the rest refitted. LM stops as soon as a parameter gets there
///    ([`PolachProblem::stop_at_bound`]): in logistic coordinates its Jacobian column fades as
///    it nears the bound, and LM would spend tens of epochs creeping the last 1e-4 of the way.
///    A parameter held at a bound whose gradient, once the rest is refitted, points back inside
///    (the stop came on the way to an interior optimum) is released, refitted from `start`
///    and not stopped at a bound again — an active-set method's test of the bound (Nocedal &
///    Wright 2006, §16.5);
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
/// The fit ends with every parameter classified; it fails only without data. The creepage is
/// taken at `creepage_speed` (m/s; `None`: at each sample's speed, Polach's; see
/// [`super::law::with_patch`]).
#[allow(clippy::too_many_arguments)]
pub fn fit_polach(
    group: &str,
    tables: &[&RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    start: PolachParams,
    profile: bool,
    creepage_speed: Option<f64>,
) -> Result<PolachFit, IdentifyError> {
    let s = fit_samples(group, tables, patch, q_n, decimate, creepage_speed)?;
    Ok(fit_unprofiled(group, &s, start)?.finish(profile, &s))
}

/// The samples of a fit of `tables` with their patch term (see [`fit_polach`]); an error
/// with fewer than 20.
pub(super) fn fit_samples(
    group: &str,
    tables: &[&RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    creepage_speed: Option<f64>,
) -> Result<Vec<Sample>, IdentifyError> {
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
    Ok(with_patch(s, &patch, creepage_speed))
}

/// A fit before its profile likelihoods, with what they need: the held values and the
/// covariance at the optimum (its residuals dropped).
pub(super) struct Unprofiled {
    pub(super) fit: PolachFit,
    fixed: [Option<f64>; 5],
    x: [f64; 5],
    cov: Covariance,
}

impl Unprofiled {
    /// The fit, with the profile likelihood of every estimated parameter when `profile`
    /// (`s`: the samples it was fitted to).
    pub(super) fn finish(&self, profile: bool, s: &[Sample]) -> PolachFit {
        let mut fit = self.fit.clone();
        if profile {
            fit.profiles = profiles(
                &fit.group,
                s,
                self.fixed,
                &self.x,
                &fit.se,
                &fit.status,
                &self.cov,
            );
        }
        fit
    }
}

/// Steps 1–3 of [`fit_polach`] on samples `s` (with their patch term).
pub(super) fn fit_unprofiled(
    group: &str,
    s: &[Sample],
    start: PolachParams,
) -> Result<Unprofiled, IdentifyError> {
    let mut held = Held {
        fixed: [None; 5],
        status: all_estimated(),
        notes: Vec::new(),
    };
    let mut current = solver_order(&start);
    let mut iterations = 0;
    let mut released = [false; 5];
    let (x, var, cov, stop) = loop {
        let mut problem = PolachProblem::plain(s, held.fixed, None);
        problem.stop_at_bound = released.map(|r| !r);
        let (problem, theta, its, stop) =
            solve(group, problem, &constant_nodes(&current), fit_settings())?;
        iterations += its;
        let x = problem
            .at_group(&problem.groups[0], &problem.nodes(&theta).0)
            .0;
        current = x;
        // 2. Bounds, tested on the logistic coordinates themselves (the test of LM's stop).
        let sg: [f64; 5] = std::array::from_fn(|i| {
            problem
                .free
                .iter()
                .position(|c| c.param == i)
                .map_or(f64::NAN, |c| sigmoid(theta[c]))
        });
        if held.at_bounds(&sg, &mut current) {
            continue;
        }
        if held.release_inside(s, &x, &solver_order(&start), &mut current, &mut released) {
            continue;
        }
        // 3. Identifiability of the free parameters.
        let cov = problem.covariance(&theta);
        let mut var = [f64::NAN; 5];
        let k = problem.free.len();
        for (c, co) in problem.free.iter().enumerate() {
            var[co.param] = cov.cov.as_ref().map_or(f64::INFINITY, |m| m[c * k + c]);
        }
        if held.worst_determined(&problem, &var, &x) {
            continue;
        }
        var[4] = ks_variance(&problem, &cov, &x, &held.fixed, &var);
        break (x, var, cov, stop);
    };
    let Held {
        fixed,
        status,
        notes,
    } = held;
    // k_S = k_A ρ carries the status of ρ: held at a bound, k_S/k_A is fixed (k_S = k_A, or
    // 0), and k_S has no standard error of its own.
    let p = law_params(&x);
    let se: [f64; 5] = std::array::from_fn(|i| match status[i] {
        ParamStatus::Estimated => var[i].sqrt(),
        _ => f64::NAN,
    });
    let fit = PolachFit {
        group: group.to_string(),
        mu0: p.mu0,
        a_ratio: p.a_ratio,
        b_s_per_m: p.b_s_per_m,
        k_a: p.k_a,
        k_s: p.k_s,
        se,
        status,
        notes,
        profiles: Vec::new(),
        samples: s.len(),
        effective_samples: cov.n_eff,
        rmse: (cov.sse / s.len() as f64).sqrt(),
        ambient_temperature_c: None,
        iterations,
        stop_reason: stop.text().to_string(),
    };
    Ok(Unprofiled {
        fit,
        fixed,
        x,
        cov: Covariance {
            residuals: Vec::new(),
            ..cov
        },
    })
}

/// What a fit holds and why: the held parameters' values, every parameter's status, notes.
struct Held {
    fixed: [Option<f64>; 5],
    status: [ParamStatus; 5],
    notes: Vec<String>,
}

impl Held {
    /// Holds every free parameter that ran into its bound, `sg` the logistic coordinates σ of
    /// the fit's parameters (also in `current`, the next start); true when one did and the
    /// rest must be refitted.
    fn at_bounds(&mut self, sg: &[f64; 5], current: &mut [f64; 5]) -> bool {
        let mut held = false;
        let free_now: Vec<usize> = (0..5).filter(|i| self.fixed[*i].is_none()).collect();
        for i in free_now {
            let sg = sg[i];
            if is_at_bound(sg) {
                // A lower bound of 0 (μ0, A, k_A, ρ) is not a valid Polach law (the model
                // file needs them > 0): held where the bound was detected, σ = AT_BOUND —
                // A = 1e-4 rather than 0. Other bounds are valid values, held exactly.
                let bound = if sg >= AT_BOUND {
                    UPPER[i]
                } else if LOWER[i] == 0.0 {
                    super::law::to_natural(i, (AT_BOUND / (1.0 - AT_BOUND)).ln()).0
                } else {
                    LOWER[i]
                };
                self.fixed[i] = Some(bound);
                current[i] = bound;
                self.status[i] = ParamStatus::AtBound;
                self.notes.push(format!(
                    "{} ran into its bound {bound}; held there and the rest refitted",
                    label(i)
                ));
                held = true;
            }
        }
        held
    }

    /// Releases every parameter held at a bound whose gradient at the edge of the bound's band,
    /// the others at `x` (refitted), points back inside: the SSE falls as it leaves the bound, so the bound is not where the
    /// fit belongs. A released parameter restarts from `start` (its coordinate barely moves
    /// at the bound) and is marked in `released`; true when one was.
    fn release_inside(
        &mut self,
        s: &[Sample],
        x: &[f64; 5],
        start: &[f64; 5],
        current: &mut [f64; 5],
        released: &mut [bool; 5],
    ) -> bool {
        let mut any = false;
        for i in 0..5 {
            if self.status[i] != ParamStatus::AtBound || released[i] {
                continue;
            }
            let mut fixed = self.fixed;
            fixed[i] = None;
            let problem = PolachProblem::plain(s, fixed, None);
            let mut theta = problem.theta(&constant_nodes(x));
            let Some(c) = problem.free.iter().position(|co| co.param == i) else {
                continue;
            };
            // At the edge of the band in which a parameter counts as at its bound (σ = AT_BOUND
            // or 1 − AT_BOUND), where LM stopped: an optimum inside the band is the bound's.
            let upper = sigmoid(theta[c]) > 0.5;
            let edge = ((1.0 - AT_BOUND) / AT_BOUND).ln();
            theta[c] = if upper { edge } else { -edge };
            // Jᵀr is half the gradient of the SSE in the logistic coordinates, in which the
            // upper bound is +∞ and the lower −∞.
            let g = problem.normal_equations(&theta).jtr[c];
            if (upper && g > 0.0) || (!upper && g < 0.0) {
                self.fixed[i] = None;
                self.status[i] = ParamStatus::Estimated;
                let name = label(i);
                self.notes
                    .retain(|n| !(n.starts_with(name) && n.contains("ran into its bound")));
                current[i] = start[i];
                released[i] = true;
                any = true;
            }
        }
        any
    }

    /// Holds the worst-determined free parameter at its value `x` if any fails the Wald test
    /// (its 95 % interval, ±1.96 se from the variances `var`, includes 0); true when one did.
    fn worst_determined(&mut self, problem: &PolachProblem, var: &[f64; 5], x: &[f64; 5]) -> bool {
        let worst = problem
            .free
            .iter()
            .map(|co| (co.param, var[co.param].sqrt() / x[co.param].abs()))
            // NaN (a zero estimate) and ∞ (singular) fail too.
            .filter(|(_, rel)| rel.is_nan() || *rel > 1.0 / IDENTIFIED_Z)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, rel)) = worst else {
            return false;
        };
        self.fixed[i] = Some(x[i]);
        self.status[i] = ParamStatus::NotIdentifiable;
        self.notes.push(format!(
            "{} not identifiable from these data ({:.4}, se/value = {}: its 95 % interval includes 0); held at that value and the rest refitted",
            label(i),
            x[i],
            if rel.is_finite() { format!("{rel:.2}") } else { "∞ (singular)".into() },
        ));
        true
    }
}

/// The variance of k_S = k_A ρ by the delta method (it needs cov(k_A, ρ)); NaN when both are
/// held.
fn ks_variance(
    problem: &PolachProblem,
    cov: &Covariance,
    x: &[f64; 5],
    fixed: &[Option<f64>; 5],
    var: &[f64; 5],
) -> f64 {
    let k = problem.free.len();
    let pos = |p: usize| problem.free.iter().position(|c| c.param == p);
    let cov_ka_rho = match (pos(3), pos(4), &cov.cov) {
        (Some(a), Some(b), Some(m)) => m[a * k + b],
        _ => 0.0,
    };
    let v0 = |v: f64| if v.is_finite() { v } else { 0.0 };
    match (fixed[3].is_none(), fixed[4].is_none()) {
        (false, false) => f64::NAN,
        _ => x[4] * x[4] * v0(var[3]) + x[3] * x[3] * v0(var[4]) + 2.0 * x[3] * x[4] * cov_ka_rho,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::polach::law::mu_only;

    /// Samples of Polach's law at `x` (natural, solver order), the patch term scaled by
    /// `stiffer` (2: a creep slope twice what the fit's patch gives, so that k_A would have to
    /// be twice its true value), with a little noise.
    fn law_samples(x: &[f64; 5], stiffer: f64) -> Vec<Sample> {
        let patch = crate::identify::polach::tests::patch();
        let mut rng = crate::rng::Rng::new(7);
        let s: Vec<Sample> = (0..600)
            .map(|_| Sample {
                q_n: 80_000.0,
                v: 10.0 + 30.0 * rng.uniform(),
                dv: 0.005 + 3.0 * rng.uniform(),
                mu: 0.0,
                cs: f64::NAN,
            })
            .collect();
        with_patch(s, &patch, None)
            .into_iter()
            .map(|mut p| {
                let mut truth = p;
                truth.cs *= stiffer;
                p.mu = mu_only(x, &truth) + 0.002 * rng.normal();
                p
            })
            .collect()
    }

    /// A parameter held at its bound after an early stop: released where the data pull it back
    /// inside (the SSE falls as it leaves the bound), kept where they push it out — k_A at its
    /// upper bound 1 (the data's k_A 0.4, or a creep slope that would need k_A = 2), A at its
    /// lower bound, held at σ = 1e-4 (the data's A 0.3, or a falling friction that would need
    /// A = −0.1).
    #[test]
    fn a_bound_the_data_pull_away_from_is_released() {
        let a_low =
            crate::identify::polach::law::to_natural(1, (AT_BOUND / (1.0 - AT_BOUND)).ln()).0;
        for (i, held_at, truth_value, stiffer, released) in [
            (3, 1.0, 0.4, 1.0, true),
            (3, 1.0, 1.0, 2.0, false),
            (1, a_low, 0.3, 1.0, true),
            (1, a_low, -0.1, 1.0, false),
        ] {
            let mut truth = [0.2, 0.3, 0.5, 0.4, 0.2];
            truth[i] = truth_value;
            let s = law_samples(&truth, stiffer);
            let mut held = Held {
                fixed: [None; 5],
                status: all_estimated(),
                notes: vec![format!(
                    "{} ran into its bound {held_at}; held there and the rest refitted",
                    label(i)
                )],
            };
            held.fixed[i] = Some(held_at);
            held.status[i] = ParamStatus::AtBound;
            let mut at = truth;
            at[i] = held_at;
            let start = solver_order(&crate::identify::polach::DEFAULT_START);
            let mut current = at;
            let mut marks = [false; 5];
            let got = held.release_inside(&s, &at, &start, &mut current, &mut marks);
            let case = format!("{} held at {held_at}, data {truth_value}", label(i));
            assert_eq!(got, released, "{case}");
            assert_eq!(marks[i], released, "{case}");
            if released {
                assert_eq!(held.fixed[i], None, "{case}");
                assert_eq!(held.status[i], ParamStatus::Estimated, "{case}");
                assert!(held.notes.is_empty(), "{case}: {:?}", held.notes);
                assert_eq!(current[i], start[i], "{case}");
            } else {
                assert_eq!(held.fixed[i], Some(held_at), "{case}");
                assert_eq!(held.notes.len(), 1, "{case}");
            }
        }
    }
}
