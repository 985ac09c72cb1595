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
use crate::contact::polach::{horner, polach, ContactPatch, PolachParams, TemperatureLaw};
use crate::linalg::{cho_solve, cholesky, effective_samples, inverse_diagonal};

/// One sample for the fit.
#[derive(Debug, Clone, Copy)]
struct Sample {
    q_n: f64,
    v: f64,
    dv: f64,
    mu: f64,
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// Natural parameters from unconstrained ones.
fn natural(p: &[f64]) -> PolachParams {
    let k_a = sigmoid(p[3]);
    PolachParams {
        mu0: 1.5 * sigmoid(p[0]),
        a_ratio: sigmoid(p[1]),
        b_s_per_m: p[2].exp(),
        k_a,
        k_s: k_a * sigmoid(p[4]),
    }
}

/// Unconstrained parameters of natural ones (inside their open bounds).
fn unconstrained(q: &PolachParams) -> [f64; 5] {
    let logit = |x: f64| (x / (1.0 - x)).ln();
    [
        logit(q.mu0 / 1.5),
        logit(q.a_ratio),
        q.b_s_per_m.ln(),
        logit(q.k_a),
        logit(q.k_s / q.k_a),
    ]
}

struct PolachProblem<'a> {
    patch: ContactPatch,
    samples: &'a [Sample],
}

impl PolachProblem<'_> {
    fn predict(&self, p: &PolachParams, s: &Sample) -> f64 {
        match polach(&self.patch, p, s.q_n, s.v, s.dv, 0.0) {
            Ok(f) => f.fx_n / s.q_n,
            Err(_) => f64::NAN,
        }
    }
    fn residuals(&self, theta: &[f64]) -> Vec<f64> {
        let p = natural(theta);
        self.samples
            .iter()
            .map(|s| self.predict(&p, s) - s.mu)
            .collect()
    }
    /// Central-difference Jacobian rows (n × 5, row-major) and residuals.
    fn jacobian(&self, theta: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let r = self.residuals(theta);
        let n = r.len();
        let mut j = vec![0.0; n * 5];
        for k in 0..5 {
            let h = 1e-6 * (1.0 + theta[k].abs());
            let mut tp = theta.to_vec();
            tp[k] += h;
            let mut tm = theta.to_vec();
            tm[k] -= h;
            let (rp, rm) = (self.residuals(&tp), self.residuals(&tm));
            for i in 0..n {
                j[i * 5 + k] = (rp[i] - rm[i]) / (2.0 * h);
            }
        }
        (j, r)
    }
}

impl LeastSquares for PolachProblem<'_> {
    fn n_params(&self) -> usize {
        5
    }
    fn n_train(&self) -> usize {
        self.samples.len()
    }
    fn sse(&self, theta: &[f64]) -> f64 {
        self.residuals(theta).iter().map(|r| r * r).sum()
    }
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        let (j, r) = self.jacobian(theta);
        let mut jtj = vec![0.0; 25];
        let mut jtr = vec![0.0; 5];
        for (row, ri) in j.chunks_exact(5).zip(&r) {
            for a in 0..5 {
                jtr[a] += row[a] * ri;
                for b in 0..5 {
                    jtj[a * 5 + b] += row[a] * row[b];
                }
            }
        }
        NormalEquations {
            jtj,
            jtr,
            sse: r.iter().map(|x| x * x).sum(),
        }
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
    /// Standard errors in the same order (μ0, A, B, k_A, k_S).
    pub se: [f64; 5],
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
                });
            }
        }
    }
    out
}

/// Fits Polach's parameters to the valid estimates of `tables` (pooled) with a fixed patch
/// and static wheel load `q_n`.
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
    let problem = PolachProblem { patch, samples: &s };
    let settings = LmSettings {
        epochs: 300,
        min_grad: 1e-12,
        ..LmSettings::default()
    };
    let theta0 = unconstrained(&start).to_vec();
    let (solver, problem) =
        lm::run(problem, LevenbergMarquardt::new(settings), theta0).map_err(|e| {
            IdentifyError::Solver {
                fit: format!("Polach fit {group}"),
                source: e.into(),
            }
        })?;
    let theta = solver.best().expect("solver ran").to_vec();
    let iterations = solver.history().len();
    let stop_reason = solver
        .stop_reason()
        .map(|r| r.text().to_string())
        .unwrap_or_else(|| "iteration limit".into());
    let (j, r) = problem.jacobian(&theta);
    let n = r.len();
    let sse: f64 = r.iter().map(|x| x * x).sum();
    let n_eff = effective_samples(&r);
    let mut jtj = vec![0.0; 25];
    for row in j.chunks_exact(5) {
        for a in 0..5 {
            for b in 0..5 {
                jtj[a * 5 + b] += row[a] * row[b];
            }
        }
    }
    let sigma2 = sse / (n as f64 - 5.0).max(1.0);
    let inflate = n as f64 / n_eff;
    let var_p: Vec<f64> = match cholesky(&jtj, 5) {
        Some(l) => inverse_diagonal(&l, 5)
            .iter()
            .map(|d| d * sigma2 * inflate)
            .collect(),
        None => vec![f64::INFINITY; 5],
    };
    let p = natural(&theta);
    // Delta method: derivatives of the natural parameters with respect to p (diagonal except
    // k_S, which depends on p3 and p4).
    let sg = |x: f64| sigmoid(x) * (1.0 - sigmoid(x));
    let d_mu0 = 1.5 * sg(theta[0]);
    let d_a = sg(theta[1]);
    let d_b = theta[2].exp();
    let d_ka = sg(theta[3]);
    let se_ks = ((sigmoid(theta[4]) * d_ka).powi(2) * var_p[3]
        + (p.k_a * sg(theta[4])).powi(2) * var_p[4])
        .sqrt();
    Ok(PolachFit {
        group: group.to_string(),
        mu0: p.mu0,
        a_ratio: p.a_ratio,
        b_s_per_m: p.b_s_per_m,
        k_a: p.k_a,
        k_s: p.k_s,
        se: [
            d_mu0 * var_p[0].sqrt(),
            d_a * var_p[1].sqrt(),
            d_b * var_p[2].sqrt(),
            d_ka * var_p[3].sqrt(),
            se_ks,
        ],
        samples: n,
        effective_samples: n_eff,
        rmse: (sse / n as f64).sqrt(),
        ambient_temperature_c: None,
        iterations,
        stop_reason,
    })
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
    let pts: Vec<(f64, f64, f64)> = fits
        .iter()
        .filter_map(|f| f.ambient_temperature_c.map(|t| (t, f.k_a, f.k_s)))
        .collect();
    if pts.len() < 2 {
        return Err(IdentifyError::Data {
            what: format!("k(T) needs runs at two or more ambient temperatures; found {}", pts.len()),
            hint: "give runs at several ambient temperatures with ambient_temperature_c in their metadata".into(),
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
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reparametrisation_round_trips_and_respects_bounds() {
        let p = PolachParams {
            mu0: 0.3,
            a_ratio: 0.4,
            b_s_per_m: 0.2,
            k_a: 0.3,
            k_s: 0.1,
        };
        let q = natural(&unconstrained(&p));
        assert!((q.mu0 - 0.3).abs() < 1e-12 && (q.k_s - 0.1).abs() < 1e-12);
        let extreme = natural(&[50.0, -50.0, 10.0, 50.0, 50.0]);
        assert!(extreme.mu0 <= 1.5 && extreme.a_ratio >= 0.0 && extreme.k_s <= extreme.k_a);
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
    let start = PolachParams {
        mu0: 0.1,
        a_ratio: 0.4,
        b_s_per_m: 0.3,
        k_a: 0.3,
        k_s: 0.1,
    };
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
        Ok(t) => (Some(t), None),
        Err(e) => (None, Some(e.to_string())),
    };
    (
        PolachReport {
            format: "railgrip-polach-fit".into(),
            version: 1,
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
