//! The least-squares problem of one Polach fit: parameters held or free, constant or as node
//! values over temperature (Lagrange basis per temperature group), optionally μ0 × g(v) with a
//! speed law linear in its coefficients (`railgrip_model::polach::SpeedSpec`), with the
//! analytic Jacobian.

use super::block::{Gram, LawBlock, BLOCK};
use super::law::{is_at_bound, sigmoid, to_natural, to_unconstrained, Sample, LOWER, UPPER};
use crate::identify::lm::{self, LeastSquares, LevenbergMarquardt, LmSettings, NormalEquations};
use crate::identify::IdentifyError;
use crate::linalg::{cho_solve, cholesky, effective_samples};
use crate::simd::Isa;

/// Most coefficients per parameter of a temperature law (degree ≤ 5, the bound of
/// `train.temperature_degree`).
pub(super) const MAX_NODES: usize = 6;
/// Most free coordinates of a problem (five parameters, each with up to [`MAX_NODES`], and
/// the speed law's coefficients).
pub(super) const MAX_COORDS: usize = 6 * MAX_NODES;
/// The row of [`Nodes`] (and [`Coord::param`]) holding the speed law's coefficients.
pub(super) const SPEED: usize = 5;
/// The speed factor g(v) is held at this floor where the coefficients would take it below
/// (the model file's check refuses such a law; the fit must not divide by it on the way).
const MIN_SPEED_FACTOR: f64 = 0.05;

/// μ0's speed law in a fit: g(v) = 1 + Σ_j c_j φ_j(v), φ_j = u^j with u = v/v_ref − 1
/// (polynomial of `terms` terms), or φ = (v_ref + v_c)/(v + v_c) − 1 (Curtius–Kniffler's
/// shape, one term); v clamped to the samples' speed range as the model file clamps it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SpeedBasis {
    pub(super) curtius_kniffler: bool,
    pub(super) terms: usize,
    pub(super) v_ref: f64,
    pub(super) range: (f64, f64),
}

impl SpeedBasis {
    /// φ_j(v) for j < terms.
    #[inline]
    pub(super) fn phi(&self, v: f64) -> [f64; 3] {
        let v = v.clamp(self.range.0, self.range.1);
        let mut out = [0.0; 3];
        if self.curtius_kniffler {
            let vc = crate::model::polach::CURTIUS_KNIFFLER_SPEED_MPS;
            out[0] = (self.v_ref + vc) / (v + vc) - 1.0;
        } else {
            let u = v / self.v_ref - 1.0;
            let mut p = u;
            for o in out.iter_mut().take(self.terms) {
                *o = p;
                p *= u;
            }
        }
        out
    }

    /// The form's name in the model file.
    pub(super) fn form(&self) -> &'static str {
        if self.curtius_kniffler {
            "curtius_kniffler"
        } else {
            "polynomial"
        }
    }
}

/// The samples at one ambient temperature (a contiguous range of the problem's samples) and,
/// per parameter, its Lagrange basis at that temperature: x_i = Σ_j basis[i][j] · node_ij.
/// A fit without temperature law is one group with basis [1, 0, …] for every parameter.
#[derive(Debug, Clone)]
pub(super) struct Group {
    pub(super) range: std::ops::Range<usize>,
    pub(super) basis: [[f64; MAX_NODES]; 5],
}

/// One free coordinate: parameter `param`'s value at temperature node `node` (degree 0: its
/// constant value), solved for in its unconstrained logistic coordinate.
#[derive(Debug, Clone, Copy)]
pub(super) struct Coord {
    pub(super) param: usize,
    pub(super) node: usize,
}

/// The least-squares problem of one fit: parameters held at `fixed`, the others' node values
/// free; `ks_fixed` holds k_S itself (profile likelihood of k_S), ρ = k_S/k_A then follows k_A.
pub(super) struct PolachProblem<'a> {
    pub(super) samples: &'a [Sample],
    pub(super) groups: Vec<Group>,
    pub(super) fixed: [Option<f64>; 5],
    pub(super) ks_fixed: Option<f64>,
    pub(super) free: Vec<Coord>,
    pub(super) speed: Option<SpeedBasis>,
    /// Speed-law coefficients held at a value (profile likelihood of a coefficient).
    pub(super) speed_held: [Option<f64>; 3],
    /// Per parameter: end the fit when its logistic coordinate comes within [`AT_BOUND`](super::law::AT_BOUND) of
    /// 0 or 1 ([`LeastSquares::stop_at`]; the plain fit then holds it there).
    pub(super) stop_at_bound: [bool; 5],
    /// The lanes the law is evaluated on ([`LawBlock::eval`]).
    isa: Isa,
    /// The normal equations at the θ of the last [`LeastSquares::sse`], which computes them
    /// whole: LM asks for the normal equations next at the step it accepted, almost always the
    /// θ of the last SSE (rejections are rare with the gain-ratio rule), and the SSE alone
    /// would evaluate the law there once more. The same bits as computing them again.
    last: std::sync::Mutex<Option<(Vec<f64>, NormalEquations)>>,
}

/// Node values of the five parameters, and in row [`SPEED`] the speed law's coefficients.
pub(super) type Nodes = [[f64; MAX_NODES]; 6];

impl<'a> PolachProblem<'a> {
    /// Constant parameters over all samples, `fixed` held.
    pub(super) fn plain(
        samples: &'a [Sample],
        fixed: [Option<f64>; 5],
        ks_fixed: Option<f64>,
    ) -> Self {
        let group = Group {
            range: 0..samples.len(),
            basis: basis_at([0; 5], 0.0, 0.0, 0.0),
        };
        Self::new(samples, vec![group], [0; 5], fixed, ks_fixed)
    }

    pub(super) fn new(
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
            speed: None,
            speed_held: [None; 3],
            stop_at_bound: [false; 5],
            isa: Isa::detect(),
            last: std::sync::Mutex::new(None),
        }
    }

    /// This problem with μ0 × g(v) of `basis`, its coefficients free (from the start's values)
    /// except those `held` at a value.
    pub(super) fn with_speed(mut self, basis: SpeedBasis, held: [Option<f64>; 3]) -> Self {
        self.free.extend(
            (0..basis.terms)
                .filter(|j| held[*j].is_none())
                .map(|node| Coord { param: SPEED, node }),
        );
        self.speed = Some(basis);
        self.speed_held = held;
        // Normal equations kept before would be another problem's.
        self.last = std::sync::Mutex::new(None);
        self
    }

    /// g(v) of sample `s` under coefficients `v[SPEED]`, its basis φ, and whether g was held
    /// at its floor (then it does not move with the coefficients). 1 without a speed law.
    #[inline]
    fn speed_factor(&self, v: &Nodes, s: &Sample) -> (f64, [f64; 3], bool) {
        match &self.speed {
            None => (1.0, [0.0; 3], true),
            Some(b) => {
                let phi = b.phi(s.v);
                let g = 1.0 + (0..b.terms).map(|j| v[SPEED][j] * phi[j]).sum::<f64>();
                if g < MIN_SPEED_FACTOR {
                    (MIN_SPEED_FACTOR, phi, true)
                } else {
                    (g, phi, false)
                }
            }
        }
    }

    /// Node values from θ, and each free coordinate's d(node)/dθ.
    pub(super) fn nodes(&self, theta: &[f64]) -> (Nodes, Vec<f64>) {
        let mut v = [[0.0; MAX_NODES]; 6];
        for (j, h) in self.speed_held.iter().enumerate() {
            if let Some(c) = h {
                v[SPEED][j] = *c;
            }
        }
        let mut d = vec![0.0; self.free.len()];
        for (k, c) in self.free.iter().enumerate() {
            (v[c.param][c.node], d[k]) = if c.param == SPEED {
                (theta[k], 1.0)
            } else {
                to_natural(c.param, theta[k])
            };
        }
        (v, d)
    }

    /// θ of node values `v` (inside their bounds).
    pub(super) fn theta(&self, v: &Nodes) -> Vec<f64> {
        self.free
            .iter()
            .map(|c| {
                if c.param == SPEED {
                    v[c.param][c.node]
                } else {
                    to_unconstrained(c.param, v[c.param][c.node])
                }
            })
            .collect()
    }

    /// The natural parameters (μ0, A, B, k_A, ρ) at a group, and which were clamped into their
    /// bounds (a temperature law's interpolation may leave them between nodes; a clamped
    /// parameter does not move with its nodes).
    #[inline]
    pub(super) fn at_group(&self, g: &Group, v: &Nodes) -> ([f64; 5], [bool; 5]) {
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

    /// The SSE at node values `v`.
    pub(super) fn sse_nodes(&self, v: &Nodes) -> f64 {
        let mut sse = 0.0;
        let mut blk = LawBlock::new();
        for g in &self.groups {
            let (x, _) = self.at_group(g, v);
            for chunk in self.samples[g.range.clone()].chunks(BLOCK) {
                blk.load(chunk, x[0], |s| self.speed_factor(v, s));
                blk.eval(self.isa, [x[1], x[2], x[3], x[4]], false);
                for (s, f) in chunk.iter().zip(&blk.f) {
                    let r = f - s.mu;
                    sse += r * r;
                }
            }
        }
        sse
    }

    /// JᵀJ, Jᵀr and the SSE in θ (`natural = false`, for the solver) or in the node values
    /// themselves (`natural = true`, for standard errors), one pass over the samples; the
    /// residuals into `residuals` when given.
    pub(super) fn accumulate(
        &self,
        theta: &[f64],
        natural: bool,
        mut residuals: Option<&mut Vec<f64>>,
    ) -> NormalEquations {
        let (v, d) = self.nodes(theta);
        let k = self.free.len();
        let mut gram = Gram::new(k, self.samples.len(), self.isa);
        let mut sse = 0.0;
        // Per coordinate: d(parameter)/d(coordinate) at the group.
        let mut m = [0.0; MAX_COORDS];
        let mut blk = LawBlock::new();
        for g in &self.groups {
            let (x, clamped) = self.at_group(g, &v);
            for (c, co) in self.free.iter().enumerate() {
                let dd = if natural { 1.0 } else { d[c] };
                m[c] = if co.param == SPEED {
                    1.0
                } else if clamped[co.param] {
                    0.0
                } else {
                    g.basis[co.param][co.node] * dd
                };
            }
            // With k_S held, k_A also moves ρ = k_S/k_A: dρ/dk_A = −k_S/k_A².
            let drho = self.ks_fixed.map(|ks| -ks / (x[3] * x[3]));
            for chunk in self.samples[g.range.clone()].chunks(BLOCK) {
                blk.load(chunk, x[0], |s| self.speed_factor(&v, s));
                blk.eval(self.isa, [x[1], x[2], x[3], x[4]], true);
                let n = chunk.len();
                if let Some(dr) = drho {
                    let [.., g3, g4] = &mut blk.grad;
                    for (a, b) in g3[..n].iter_mut().zip(&g4[..n]) {
                        *a += b * dr;
                    }
                }
                // The residuals replace μ in the block; the SSE sums them in sample order.
                for (f, s) in blk.f[..n].iter_mut().zip(chunk) {
                    let r = *f - s.mu;
                    *f = r;
                    sse += r * r;
                }
                if let Some(out) = residuals.as_deref_mut() {
                    out.extend_from_slice(&blk.f[..n]);
                }
                // The Jacobian's columns of this chunk, coordinate by coordinate, straight into
                // the Gram panel (split where a panel fills up).
                let mut done = 0;
                while done < n {
                    let take = (n - done).min(gram.room());
                    let at = done..done + take;
                    for (c, co) in self.free.iter().enumerate() {
                        self.column(&blk, co, m[c], x[0], at.clone(), gram.slots(c, take));
                    }
                    gram.slots(k, take).copy_from_slice(&blk.f[at]);
                    gram.advance(take);
                    done += take;
                }
            }
        }
        let (jtj, jtr) = gram.finish();
        NormalEquations { jtj, jtr, sse }
    }

    /// One coordinate's Jacobian column over samples `at` of an evaluated block (its gradient
    /// with ρ's share already in k_A's), into `out`: with a speed law μ0_eff = μ0 g(v), so
    /// dμ/dμ0 = g ∂μ/∂μ0_eff and dμ/dc_j = μ0 φ_j ∂μ/∂μ0_eff (0 where g sits at its floor);
    /// `m` is d(parameter)/d(coordinate) at the group, `mu0` the group's μ0.
    #[inline]
    fn column(
        &self,
        blk: &LawBlock,
        co: &Coord,
        m: f64,
        mu0: f64,
        at: std::ops::Range<usize>,
        out: &mut [f64],
    ) {
        let grad = &blk.grad;
        match co.param {
            SPEED => {
                for (o, i) in out.iter_mut().zip(at) {
                    *o = if blk.held[i] {
                        0.0
                    } else {
                        grad[0][i] * mu0 * blk.phi[i][co.node]
                    };
                }
            }
            0 if self.speed.is_some() => {
                for (o, i) in out.iter_mut().zip(at) {
                    *o = grad[0][i] * blk.gv[i] * m;
                }
            }
            p => {
                for (o, g) in out.iter_mut().zip(&grad[p][at]) {
                    *o = g * m;
                }
            }
        }
    }

    /// The covariance of the free node values at θ: σ² (JᵀJ)⁻¹ inflated by n/n_eff for the
    /// residuals' autocorrelation ([`effective_samples`]); `None` where JᵀJ is singular.
    pub(super) fn covariance(&self, theta: &[f64]) -> Covariance {
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
pub(super) struct Covariance {
    /// k × k over the free coordinates (row-major), natural units.
    pub(super) cov: Option<Vec<f64>>,
    pub(super) sse: f64,
    pub(super) n_eff: f64,
    /// σ² n/n_eff: the variance of one residual, inflated for autocorrelation.
    pub(super) scale: f64,
    pub(super) residuals: Vec<f64>,
}

impl LeastSquares for PolachProblem<'_> {
    fn n_params(&self) -> usize {
        self.free.len()
    }
    fn n_train(&self) -> usize {
        self.samples.len()
    }
    /// The SSE as [`PolachProblem::sse_nodes`] sums it (the same samples in the same order),
    /// with JᵀJ and Jᵀr at θ beside it, kept for [`LeastSquares::normal_equations`].
    fn sse(&self, theta: &[f64]) -> f64 {
        let ne = self.accumulate(theta, false, None);
        let sse = ne.sse;
        if let Ok(mut last) = self.last.lock() {
            *last = Some((theta.to_vec(), ne));
        }
        sse
    }
    fn stop_at(&self, theta: &[f64]) -> bool {
        self.free
            .iter()
            .zip(theta)
            .any(|(c, t)| c.param < 5 && self.stop_at_bound[c.param] && is_at_bound(sigmoid(*t)))
    }
    /// One pass over the samples: JᵀJ and Jᵀr in the unconstrained coordinates (the
    /// analytic Jacobian in the natural parameters times the chain of node → parameter and
    /// θ → node, column by column).
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        let kept = self.last.lock().ok().and_then(|mut last| last.take());
        match kept {
            Some((at, ne)) if lm::same_theta(&at, theta) => ne,
            _ => self.accumulate(theta, false, None),
        }
    }
    fn validation_mse(&self, _: &[f64]) -> Option<f64> {
        None
    }
}

/// Solves `problem` from node values `start`: the problem back, its optimal θ, iterations and
/// why it stopped.
pub(super) fn solve<'a>(
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

/// Constant node values of natural parameters `x` (no speed dependence).
pub(super) fn constant_nodes(x: &[f64; 5]) -> Nodes {
    let mut v = [[0.0; MAX_NODES]; 6];
    for i in 0..5 {
        v[i] = [x[i]; MAX_NODES];
    }
    v
}

/// LM settings of the Polach fits: MINPACK's convergence tests (ftol = xtol = 1e-10), so that
/// a fit whose cost stopped falling ends as converged rather than running μ to its maximum.
pub(super) fn fit_settings() -> LmSettings {
    LmSettings {
        epochs: 300,
        min_grad: 1e-12,
        ftol: 1e-10,
        xtol: 1e-10,
        gain_ratio: true,
        ..LmSettings::default()
    }
}

/// The refits of a profile, warm-started next to their optimum: ftol = xtol = 1e-8 (an SSE
/// within 1e-8 of its minimum moves the profile statistic by about 1e-8 n_eff, 5e-5 for the
/// bundled archive's pooled fit).
pub(super) fn profile_settings() -> LmSettings {
    LmSettings {
        ftol: 1e-7,
        xtol: 1e-7,
        ..fit_settings()
    }
}

/// Evenly spaced temperature nodes of a degree-d law over [lo, hi].
pub(super) fn temperature_nodes(d: usize, lo: f64, hi: f64) -> Vec<f64> {
    if d == 0 {
        return vec![0.5 * (lo + hi)];
    }
    (0..=d)
        .map(|j| lo + (hi - lo) * j as f64 / d as f64)
        .collect()
}

/// Per parameter, the basis at temperature t (°C) of a law of `degrees` over [lo, hi]: the
/// Lagrange basis of its nodes, or [1, 0, …] for a constant.
pub(super) fn basis_at(degrees: [usize; 5], lo: f64, hi: f64, t: f64) -> [[f64; MAX_NODES]; 5] {
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
pub(super) fn lagrange(nodes: &[f64], t: f64) -> [f64; MAX_NODES] {
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
