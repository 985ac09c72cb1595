//! Levenberg–Marquardt with MATLAB `trainlm` semantics, written as an argmin [`Solver`]
//! (argmin ships no LM). Reference: MathWorks trainlm documentation as summarised in
//! ../shared/design/reference-values.md ("Levenberg–Marquardt as MATLAB trainlm does it"):
//! mu 1e-3, mu_dec 0.1, mu_inc 10, mu_max 1e10, epochs 1000, goal 0, min_grad 1e-7,
//! max_fail 6; stop on epochs, goal, gradient below min_grad, mu above mu_max, or the
//! validation error rising max_fail times in a row (weights restored to the best validation
//! epoch).
//!
//! One iteration is one epoch: with the residuals r(θ) = ŷ(θ) − y and J = ∂r/∂θ at the current
//! θ, try θ' = θ − (JᵀJ + μ I)⁻¹ Jᵀr; accept if the sum of squared errors falls (μ ← μ·mu_dec),
//! otherwise μ ← μ·mu_inc and try again, until μ > mu_max. The problem hands over JᵀJ, Jᵀr and
//! the SSE ([`NormalEquations`]), so J itself never has to be stored: the MLP problem
//! accumulates them over fixed chunks of samples in parallel and sums the chunks in order, so
//! the result does not depend on the number of threads.
//!
//! Two additions, off by default (trainlm has neither), on in the Polach fits: MINPACK's
//! convergence tests ([`LmSettings::ftol`], [`LmSettings::xtol`]) and damping that heeds the gain
//! ratio ([`LmSettings::gain_ratio`]: an accepted step that delivered less than a quarter of
//! its predicted reduction doubles μ instead of lowering it). A problem may also end the fit
//! itself after an accepted step ([`LeastSquares::stop_at`], [`StopReason::AtBound`]).
//!
//! Bayesian regularisation ([`LmSettings::bayesian`]), as MATLAB `trainbr` does it (MacKay 1992;
//! Foresee & Hagan 1997; reference-values.md, tag trainbr): LM on F = β E_D + α E_W with
//! E_D = Σ r² and E_W = Σ θ², step θ' = θ − (β JᵀJ + (μ + α) I)⁻¹ (β Jᵀr + α θ), accepted when F
//! falls; after each accepted epoch, with JᵀJ of the epoch's start, the effective number of
//! parameters γ = P − α tr((β JᵀJ + α I)⁻¹) and α = γ / (2 E_W), β = (N − γ) / (2 E_D)
//! (start: γ = P). Validation data are watched but neither stop training nor choose the
//! weights (trainbr's max_fail = 0): the last epoch's weights are kept.
//!
//! Damped system: Cholesky of JᵀJ + μ I. Fallback: when the factorisation fails (not positive
//! definite in floating point, e.g. a tiny μ on a rank-deficient J) or the step is not finite,
//! the step counts as rejected and μ grows — the same path a worse error takes — so the solver
//! never produces NaN. Parameters and errors stay finite by construction; a problem that
//! returns a non-finite SSE gets that step rejected too.

use std::time::Instant;

use argmin::core::{
    Error, IterState, Problem, Solver, State, TerminationReason, TerminationStatus, KV,
};
use ndarray::Array1;

use crate::linalg::{cho_solve, cholesky, inverse_trace};

/// JᵀJ (row-major, p×p), Jᵀr and Σr² at one parameter vector.
#[derive(Debug, Clone, PartialEq)]
pub struct NormalEquations {
    pub jtj: Vec<f64>,
    pub jtr: Vec<f64>,
    pub sse: f64,
}

impl NormalEquations {
    /// Every value's bits, JᵀJ then Jᵀr then the SSE (tests compare them bit for bit).
    #[cfg(test)]
    pub(crate) fn bits(&self) -> Vec<u64> {
        self.jtj
            .iter()
            .chain(&self.jtr)
            .chain([&self.sse])
            .map(|v| v.to_bits())
            .collect()
    }
}

/// True when parameter vectors `a` and `b` are the same bits: whether what a problem kept at
/// one θ ([`LeastSquares::sse`]'s pass, its normal equations) is for another.
pub(crate) fn same_theta(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// A nonlinear least-squares problem for [`LevenbergMarquardt`].
pub trait LeastSquares {
    /// Number of parameters p.
    fn n_params(&self) -> usize;
    /// Number of training residuals (for mean squared errors).
    fn n_train(&self) -> usize;
    /// Σ r² over the training residuals.
    fn sse(&self, theta: &[f64]) -> f64;
    /// [`LeastSquares::sse`], or a partial sum of its terms (in the order `sse` adds them) as
    /// soon as that makes `reject` true. `reject` must hold for every sum at or above one it
    /// holds for; the terms being squares, a partial sum that rejects then proves the whole
    /// sum would, and the caller's decision is the same (a trial step whose error only has to
    /// be found too large). By default the whole sum.
    fn sse_unless(&self, theta: &[f64], reject: &(dyn Fn(f64) -> bool + Sync)) -> f64 {
        let _ = reject;
        self.sse(theta)
    }
    /// JᵀJ, Jᵀr and Σ r² over the training residuals.
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations;
    /// Mean squared validation error, `None` without a validation set.
    fn validation_mse(&self, theta: &[f64]) -> Option<f64>;
    /// Factor turning a mean squared error of the residuals into the reported unit (e.g. the
    /// square of the mapminmax scale of the target). 1 by default.
    fn mse_scale(&self) -> f64 {
        1.0
    }
    /// True when the problem ends the fit at θ, an accepted step's parameters
    /// ([`StopReason::AtBound`]): a parameter that reached its bound, which the caller then
    /// holds there. Never by default.
    fn stop_at(&self, _theta: &[f64]) -> bool {
        false
    }
}

/// A borrowed problem is a problem (the solver takes its problem by value).
impl<T: LeastSquares + ?Sized> LeastSquares for &T {
    fn n_params(&self) -> usize {
        (**self).n_params()
    }
    fn n_train(&self) -> usize {
        (**self).n_train()
    }
    fn sse(&self, theta: &[f64]) -> f64 {
        (**self).sse(theta)
    }
    fn sse_unless(&self, theta: &[f64], reject: &(dyn Fn(f64) -> bool + Sync)) -> f64 {
        (**self).sse_unless(theta, reject)
    }
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        (**self).normal_equations(theta)
    }
    fn validation_mse(&self, theta: &[f64]) -> Option<f64> {
        (**self).validation_mse(theta)
    }
    fn mse_scale(&self) -> f64 {
        (**self).mse_scale()
    }
    fn stop_at(&self, theta: &[f64]) -> bool {
        (**self).stop_at(theta)
    }
}

/// trainlm's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmSettings {
    pub epochs: u64,
    /// Stop when the training MSE (reported unit) is at or below this.
    pub goal: f64,
    /// Stop when ‖2 Jᵀr‖ (the gradient of the SSE) falls below this.
    pub min_grad: f64,
    pub mu: f64,
    pub mu_dec: f64,
    pub mu_inc: f64,
    pub mu_max: f64,
    /// Validation checks: stop after this many epochs in a row without a new best
    /// validation error (ignored with [`LmSettings::bayesian`]).
    pub max_fail: u32,
    /// Bayesian regularisation (MATLAB trainbr) instead of plain trainlm.
    pub bayesian: bool,
    /// MINPACK's convergence tests (`lmder`'s ftol and xtol; 0 turns them off, as trainlm has
    /// neither): stop when an accepted step reduced the objective by a relative amount of at
    /// most `ftol`, or moved the parameters by at most `xtol` (‖Δθ‖ ≤ xtol (‖θ‖ + xtol)).
    pub ftol: f64,
    pub xtol: f64,
    /// Damping that heeds the gain ratio ρ = actual / predicted reduction of the SSE (the
    /// test of Fletcher 1971 and Madsen, Nielsen & Tingleff 2004, §3.2; trainlm has none): an
    /// accepted step with ρ < 1/4 doubles μ instead of lowering it by mu_dec. Without it μ falls
    /// after every accepted step, however little of the predicted reduction it delivered, down
    /// to pure Gauss–Newton steps (μ = 1e-180 was seen) that zigzag across a curved valley,
    /// each lowering the SSE a little, until the epoch limit. Steps with ρ ≥ 1/4 keep trainlm's
    /// rule, so a fit that never takes a poor step follows the same path as without it.
    /// Plain least squares only (ignored with [`LmSettings::bayesian`]).
    pub gain_ratio: bool,
}

impl Default for LmSettings {
    fn default() -> Self {
        LmSettings {
            epochs: 1000,
            goal: 0.0,
            min_grad: 1e-7,
            mu: 1e-3,
            mu_dec: 0.1,
            mu_inc: 10.0,
            mu_max: 1e10,
            max_fail: 6,
            bayesian: false,
            ftol: 0.0,
            xtol: 0.0,
            gain_ratio: false,
        }
    }
}

impl LmSettings {
    /// MATLAB trainbr's defaults (reference-values.md, tag trainbr): μ 0.005, validation stop
    /// off, the rest as trainlm.
    pub fn trainbr() -> LmSettings {
        LmSettings {
            mu: crate::config::TRAINBR_MU,
            max_fail: 0,
            bayesian: true,
            ..LmSettings::default()
        }
    }
}

/// trainbr's hyperparameters (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bayes {
    /// Weight of E_W = Σ θ².
    pub alpha: f64,
    /// Weight of E_D = Σ r².
    pub beta: f64,
    /// Effective number of parameters, 0..P.
    pub gamma: f64,
}

impl Bayes {
    /// trainbr's start: γ = P, α = γ / (2 E_W) (1 for zero weights), β = (N − γ) / (2 E_D)
    /// (1 for a zero error).
    fn start(p: usize, n: f64, e_d: f64, e_w: f64) -> Bayes {
        let gamma = p as f64;
        Bayes::update(gamma, n, e_d, e_w, 1.0)
    }

    fn update(gamma: f64, n: f64, e_d: f64, e_w: f64, beta_before: f64) -> Bayes {
        Bayes {
            alpha: if e_w > 0.0 { gamma / (2.0 * e_w) } else { 1.0 },
            beta: if e_d > 0.0 {
                (n - gamma) / (2.0 * e_d)
            } else {
                beta_before
            },
            gamma,
        }
    }

    /// F = β E_D + α E_W.
    fn objective(&self, e_d: f64, e_w: f64) -> f64 {
        self.beta * e_d + self.alpha * e_w
    }
}

fn sum_sq(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum()
}

pub use crate::model::Epoch;

/// Receives every epoch of a training (the CLI prints progress with it).
pub type EpochProgress<'a> = &'a dyn for<'e> crate::progress::Progress<&'e Epoch>;

/// Why training stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    Epochs,
    Goal,
    MinGrad,
    MuMax,
    ValidationStop,
    /// MINPACK's ftol test.
    CostConverged,
    /// MINPACK's xtol test.
    StepConverged,
    /// With MINPACK's tests on: no step reduces the cost at any damping up to `mu_max` — the
    /// minimum at the arithmetic's precision (MINPACK's info 6/7), not a failure.
    NoFurtherReduction,
    /// The problem's own stop ([`LeastSquares::stop_at`]): a parameter reached its bound.
    AtBound,
}

impl StopReason {
    pub fn text(self) -> &'static str {
        match self {
            StopReason::Epochs => "maximum epochs reached",
            StopReason::Goal => "performance goal met",
            StopReason::MinGrad => "minimum gradient reached",
            StopReason::MuMax => "mu reached its maximum",
            StopReason::ValidationStop => "validation stop (max_fail)",
            StopReason::CostConverged => "converged: relative cost reduction at most ftol",
            StopReason::StepConverged => "converged: relative step at most xtol",
            StopReason::NoFurtherReduction => {
                "converged: no step reduces the cost any further (MINPACK info 6)"
            }
            StopReason::AtBound => "a parameter reached its bound",
        }
    }
}

/// The solver. After a run, [`LevenbergMarquardt::best`] holds the weights to use (the best
/// validation epoch when there is validation data, else the last accepted ones) and
/// [`LevenbergMarquardt::history`] the epochs.
pub struct LevenbergMarquardt<'a> {
    pub settings: LmSettings,
    mu: f64,
    fails: u32,
    best_val: f64,
    best: Option<Vec<f64>>,
    stop: Option<StopReason>,
    history: Vec<Epoch>,
    start: Instant,
    progress: Option<EpochProgress<'a>>,
    /// trainbr's α, β, γ (with [`LmSettings::bayesian`]).
    bayes: Option<Bayes>,
}

impl<'a> LevenbergMarquardt<'a> {
    pub fn new(settings: LmSettings) -> Self {
        LevenbergMarquardt {
            settings,
            mu: settings.mu,
            fails: 0,
            best_val: f64::INFINITY,
            best: None,
            stop: None,
            history: Vec::new(),
            start: Instant::now(),
            progress: None,
            bayes: None,
        }
    }

    /// trainbr's α, β and γ after the last epoch (`None` without Bayesian regularisation).
    pub fn bayes(&self) -> Option<Bayes> {
        self.bayes
    }

    /// Reports every epoch to `progress` (the CLI prints progress with it).
    pub fn with_progress(mut self, progress: EpochProgress<'a>) -> Self {
        self.progress = Some(progress);
        self
    }

    pub fn history(&self) -> &[Epoch] {
        &self.history
    }
    pub fn best(&self) -> Option<&[f64]> {
        self.best.as_deref()
    }
    pub fn stop_reason(&self) -> Option<StopReason> {
        self.stop
    }
}

type LmState = IterState<Array1<f64>, (), (), (), (), f64>;

impl<O: LeastSquares> Solver<O, LmState> for LevenbergMarquardt<'_> {
    fn name(&self) -> &str {
        "Levenberg-Marquardt (trainlm)"
    }

    fn init(
        &mut self,
        problem: &mut Problem<O>,
        state: LmState,
    ) -> Result<(LmState, Option<KV>), Error> {
        self.start = Instant::now();
        let theta = state
            .get_param()
            .ok_or_else(|| Error::msg("initial parameters are required"))?
            .to_vec();
        let (sse, n, scale, p) = problem.problem("cost_count", |o| {
            Ok((
                o.sse(&theta),
                o.n_train().max(1) as f64,
                o.mse_scale(),
                o.n_params(),
            ))
        })?;
        if self.settings.bayesian {
            if n <= p as f64 {
                return Err(Error::msg(format!(
                    "Bayesian regularisation needs more training residuals than parameters ({n} residuals, {p} parameters)"
                )));
            }
            self.bayes = Some(Bayes::start(p, n, sse, sum_sq(&theta)));
        }
        let val = problem.problem("validation_count", |o| Ok(o.validation_mse(&theta)))?;
        if let Some(v) = val {
            self.best_val = v;
        }
        self.best = Some(theta);
        Ok((state.cost(sse / n * scale), None))
    }

    /// One epoch (see the module documentation): the normal equations at θ, the stop tests
    /// of the epoch's start, the μ loop and trainbr's update, the validation watch, and the
    /// epoch's record.
    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LmState,
    ) -> Result<(LmState, Option<KV>), Error> {
        let theta = state.take_param().expect("set in init").to_vec();
        let (ne, n, scale, p) = problem.problem("jacobian_count", |o| {
            Ok((
                o.normal_equations(&theta),
                o.n_train().max(1) as f64,
                o.mse_scale(),
                o.n_params(),
            ))
        })?;
        let rhs = self.gradient(&ne, &theta);
        let grad_norm = 2.0 * sum_sq(&rhs).sqrt();
        self.check_goal_and_gradient(ne.sse / n * scale, grad_norm);
        let mut next = theta.clone();
        let mut next_sse = ne.sse;
        if self.stop.is_none() {
            let mut system = DampedSystem::new(&ne.jtj, p, self.bayes);
            if let Some((t, e)) = self.damped_step(problem, &mut system, &theta, &rhs, ne.sse)? {
                next = t;
                next_sse = e;
                if self.stop.is_none() && problem.problem("stop_count", |o| Ok(o.stop_at(&next)))? {
                    self.stop = Some(StopReason::AtBound);
                }
            }
            self.update_bayes(&mut system, n, next_sse, &next);
        }
        let val = problem.problem("validation_count", |o| Ok(o.validation_mse(&next)))?;
        self.watch_validation(val, &next);
        let epoch = self.record_epoch(state.get_iter() + 1, next_sse / n * scale, val, grad_norm);
        let kv =
            argmin::kv!("mu" => self.mu; "grad_norm" => grad_norm; "val_mse" => epoch.val_mse;);
        Ok((
            state.param(Array1::from(next)).cost(epoch.train_mse),
            Some(kv),
        ))
    }

    fn terminate(&mut self, _state: &LmState) -> TerminationStatus {
        match self.stop {
            None => TerminationStatus::NotTerminated,
            Some(StopReason::Epochs) => {
                TerminationStatus::Terminated(TerminationReason::MaxItersReached)
            }
            Some(StopReason::Goal) => {
                TerminationStatus::Terminated(TerminationReason::TargetCostReached)
            }
            Some(r) => {
                TerminationStatus::Terminated(TerminationReason::SolverExit(r.text().into()))
            }
        }
    }
}

/// The damped system of one epoch: the data-weighted JᵀJ (row-major, p×p) whose diagonal is
/// reset to its undamped values plus a shift before each factorisation — trainlm:
/// JᵀJ + μ I; trainbr: β JᵀJ + (μ + α) I.
struct DampedSystem {
    p: usize,
    a: Vec<f64>,
    /// The diagonal of the data-weighted JᵀJ.
    diagonal: Vec<f64>,
    /// What the damping adds to μ: 0 (trainlm) or α (trainbr).
    ridge: f64,
}

impl DampedSystem {
    fn new(jtj: &[f64], p: usize, bayes: Option<Bayes>) -> DampedSystem {
        let (data_weight, ridge) = match bayes {
            None => (1.0, 0.0),
            Some(b) => (b.beta, b.alpha),
        };
        let a: Vec<f64> = jtj.iter().map(|v| data_weight * v).collect();
        let diagonal: Vec<f64> = (0..p).map(|d| a[d * p + d]).collect();
        DampedSystem {
            p,
            a,
            diagonal,
            ridge,
        }
    }

    /// Sets the diagonal to the undamped one plus `shift`.
    fn shift_diagonal(&mut self, shift: f64) {
        let p = self.p;
        for d in 0..p {
            self.a[d * p + d] = self.diagonal[d] + shift;
        }
    }

    /// θ − (the system)⁻¹ `rhs`, `None` when the Cholesky factorisation fails.
    fn trial(&self, theta: &[f64], rhs: &[f64]) -> Option<Vec<f64>> {
        let p = self.p;
        cholesky(&self.a, p).map(|l| {
            let step = cho_solve(&l, p, rhs);
            theta
                .iter()
                .zip(&step)
                .map(|(t, d)| t - d)
                .collect::<Vec<f64>>()
        })
    }
}

/// The gain ratio of the accepted step from `theta` to `next` (δ = theta − next, solving
/// (JᵀJ + μ I) δ = Jᵀr = `rhs`) that took the SSE from `sse` to `next_sse`: the actual
/// reduction over the reduction the linear model ‖r − Jδ‖² predicts, which is
/// 2δᵀJᵀr − δᵀJᵀJδ = δᵀJᵀr + μ‖δ‖² (Madsen, Nielsen & Tingleff 2004, eq. 3.9).
fn gain_ratio(theta: &[f64], next: &[f64], rhs: &[f64], mu: f64, sse: f64, next_sse: f64) -> f64 {
    let (mut d_g, mut d_d) = (0.0, 0.0);
    for ((t, n), g) in theta.iter().zip(next).zip(rhs) {
        let d = t - n;
        d_g += d * g;
        d_d += d * d;
    }
    (sse - next_sse) / (d_g + mu * d_d)
}

/// The factor μ takes after an accepted step of gain ratio `rho` ([`LmSettings::gain_ratio`]):
/// 2 below 1/4 (Madsen, Nielsen & Tingleff's lower threshold), else mu_dec.
fn damping_after(rho: f64, s: LmSettings) -> f64 {
    if rho >= 0.25 {
        s.mu_dec
    } else {
        2.0
    }
}

/// The objective a step must lower: the SSE (trainlm) or F = β E_D + α E_W (trainbr).
fn objective(bayes: Option<Bayes>, sse: f64, t: &[f64]) -> f64 {
    match bayes {
        None => sse,
        Some(b) => b.objective(sse, sum_sq(t)),
    }
}

impl LevenbergMarquardt<'_> {
    /// The gradient of the objective, 2 Jᵀr (trainlm) or 2 (β Jᵀr + α θ) (trainbr), over 2:
    /// the right-hand side of the damped system.
    fn gradient(&self, ne: &NormalEquations, theta: &[f64]) -> Vec<f64> {
        match self.bayes {
            None => ne.jtr.clone(),
            Some(b) => ne
                .jtr
                .iter()
                .zip(theta)
                .map(|(g, t)| b.beta * g + b.alpha * t)
                .collect(),
        }
    }

    /// Stops on the goal (training MSE `mse` at or below it) or on a gradient norm below
    /// min_grad, at the epoch's start.
    fn check_goal_and_gradient(&mut self, mse: f64, grad_norm: f64) {
        let s = self.settings;
        if mse <= s.goal {
            self.stop = Some(StopReason::Goal);
        } else if grad_norm < s.min_grad {
            self.stop = Some(StopReason::MinGrad);
        }
    }

    /// The μ loop: tries θ' = θ − (system + μ I)⁻¹ `rhs`, raising μ by mu_inc after every
    /// rejected step (factorisation failed, a non-finite step or SSE, or an objective not
    /// below `sse`'s), until a step is accepted — returned with its SSE, μ lowered by mu_dec
    /// (or, with [`LmSettings::gain_ratio`], doubled after a poor step) — or μ exceeds mu_max
    /// (stop; `None`).
    fn damped_step<O: LeastSquares>(
        &mut self,
        problem: &mut Problem<O>,
        system: &mut DampedSystem,
        theta: &[f64],
        rhs: &[f64],
        sse: f64,
    ) -> Result<Option<(Vec<f64>, f64)>, Error> {
        let s = self.settings;
        let bayes = self.bayes;
        let f0 = objective(bayes, sse, theta);
        loop {
            system.shift_diagonal(self.mu + system.ridge);
            let accepted = match system.trial(theta, rhs) {
                Some(t) if t.iter().all(|v| v.is_finite()) => {
                    // Rejected unless finite and below the objective before the step: true
                    // for every larger SSE too (β > 0), so the SSE may stop as soon as its
                    // partial sum rejects.
                    let reject = |e: f64| !(e.is_finite() && objective(bayes, e, &t) < f0);
                    let e = problem.problem("cost_count", |o| Ok(o.sse_unless(&t, &reject)))?;
                    if reject(e) {
                        None
                    } else {
                        Some((t, e))
                    }
                }
                _ => None,
            };
            if let Some((next, next_sse)) = accepted {
                self.check_convergence(f0, objective(bayes, next_sse, &next), theta, &next);
                self.mu *= if s.gain_ratio && bayes.is_none() {
                    damping_after(gain_ratio(theta, &next, rhs, self.mu, sse, next_sse), s)
                } else {
                    s.mu_dec
                };
                if self.bayes.is_some() {
                    // trainbr's floor.
                    self.mu = self.mu.max(1e-20);
                }
                return Ok(Some((next, next_sse)));
            }
            self.mu *= s.mu_inc;
            if self.mu > s.mu_max {
                self.stop = Some(if s.ftol > 0.0 {
                    StopReason::NoFurtherReduction
                } else {
                    StopReason::MuMax
                });
                return Ok(None);
            }
        }
    }

    /// MINPACK's tests on an accepted step from `theta` to `next` that took the objective
    /// from `f0` to `f1`: a relative reduction of at most ftol, or a step of at most
    /// xtol (‖θ‖ + xtol).
    fn check_convergence(&mut self, f0: f64, f1: f64, theta: &[f64], next: &[f64]) {
        let s = self.settings;
        let step = next
            .iter()
            .zip(theta)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        if s.ftol > 0.0 && f0 - f1 <= s.ftol * f0 {
            self.stop = Some(StopReason::CostConverged);
        } else if s.xtol > 0.0 && step <= s.xtol * (sum_sq(theta).sqrt() + s.xtol) {
            self.stop = Some(StopReason::StepConverged);
        }
    }

    /// trainbr's update after the epoch (unless μ reached its maximum):
    /// γ = P − α tr((β JᵀJ + α I)⁻¹) with JᵀJ of the epoch's start (as trainbr), then α and
    /// β from γ and the new weights `next` with their SSE.
    fn update_bayes(&mut self, system: &mut DampedSystem, n: f64, next_sse: f64, next: &[f64]) {
        if let (Some(b), false) = (self.bayes, self.stop == Some(StopReason::MuMax)) {
            let p = system.p;
            system.shift_diagonal(b.alpha);
            if let Some(l) = cholesky(&system.a, p) {
                let gamma = (p as f64 - b.alpha * inverse_trace(&l, p)).clamp(0.0, p as f64);
                self.bayes = Some(Bayes::update(gamma, n, next_sse, sum_sq(next), b.beta));
            }
        }
    }

    /// Keeps `next` as the best weights when its validation MSE `val` is a new best (or
    /// always, without validation data or with trainbr), else counts a validation failure
    /// and stops after max_fail of them in a row.
    fn watch_validation(&mut self, val: Option<f64>, next: &[f64]) {
        match val {
            // trainbr: validation is watched, never chooses.
            _ if self.bayes.is_some() => self.best = Some(next.to_vec()),
            Some(v) if v < self.best_val => {
                self.best_val = v;
                self.best = Some(next.to_vec());
                self.fails = 0;
            }
            Some(_) => {
                self.fails += 1;
                if self.fails >= self.settings.max_fail && self.stop.is_none() {
                    self.stop = Some(StopReason::ValidationStop);
                }
            }
            None => self.best = Some(next.to_vec()),
        }
    }

    /// Appends epoch `epoch` (1-based) to the history, reports it to the progress
    /// receiver, and stops after the last epoch allowed.
    fn record_epoch(
        &mut self,
        epoch: u64,
        train_mse: f64,
        val: Option<f64>,
        grad_norm: f64,
    ) -> Epoch {
        let record = Epoch {
            epoch,
            train_mse,
            val_mse: val.unwrap_or(f64::NAN),
            mu: self.mu,
            grad_norm,
            elapsed_s: self.start.elapsed().as_secs_f64(),
            gamma: self.bayes.map(|b| b.gamma),
        };
        self.history.push(record);
        if let Some(p) = self.progress {
            p.event(&record);
        }
        if epoch >= self.settings.epochs && self.stop.is_none() {
            self.stop = Some(StopReason::Epochs);
        }
        record
    }
}

/// Runs the solver from `theta0` and returns it (weights in [`LevenbergMarquardt::best`]).
pub fn run<'a, O: LeastSquares>(
    problem: O,
    solver: LevenbergMarquardt<'a>,
    theta0: Vec<f64>,
) -> Result<(LevenbergMarquardt<'a>, O), Error> {
    let epochs = solver.settings.epochs;
    let res = argmin::core::Executor::new(problem, solver)
        .configure(|s| s.param(Array1::from(theta0)).max_iters(epochs.max(1)))
        .run()?;
    let mut problem = res.problem;
    let mut solver = res.solver;
    if solver.stop.is_none() {
        solver.stop = Some(StopReason::Epochs);
    }
    let problem = problem
        .take_problem()
        .expect("the executor keeps the problem");
    Ok((solver, problem))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fit y = a exp(b x) (a classic MINPACK-style test).
    struct Exp {
        x: Vec<f64>,
        y: Vec<f64>,
    }
    impl LeastSquares for Exp {
        fn n_params(&self) -> usize {
            2
        }
        fn n_train(&self) -> usize {
            self.x.len()
        }
        fn sse(&self, t: &[f64]) -> f64 {
            self.x
                .iter()
                .zip(&self.y)
                .map(|(x, y)| (t[0] * (t[1] * x).exp() - y).powi(2))
                .sum()
        }
        fn normal_equations(&self, t: &[f64]) -> NormalEquations {
            let mut jtj = vec![0.0; 4];
            let mut jtr = vec![0.0; 2];
            let mut sse = 0.0;
            for (x, y) in self.x.iter().zip(&self.y) {
                let e = (t[1] * x).exp();
                let r = t[0] * e - y;
                let j = [e, t[0] * x * e];
                for p in 0..2 {
                    jtr[p] += j[p] * r;
                    for q in 0..2 {
                        jtj[p * 2 + q] += j[p] * j[q];
                    }
                }
                sse += r * r;
            }
            NormalEquations { jtj, jtr, sse }
        }
        fn validation_mse(&self, _: &[f64]) -> Option<f64> {
            None
        }
    }

    /// MINPACK's tests end a fit whose cost stopped falling as converged, with noisy data (a
    /// nonzero minimum), in fewer epochs than trainlm's rules; without them (trainlm) the same
    /// fit runs until μ's maximum or the gradient floor.
    #[test]
    fn minpack_tests_end_a_converged_fit() {
        let x: Vec<f64> = (0..50).map(|i| i as f64 * 0.05).collect();
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(i, x)| 2.5 * (-1.3 * x).exp() + 0.01 * ((i * 7919 % 13) as f64 - 6.0))
            .collect();
        let fit = |s: LmSettings| {
            run(
                Exp {
                    x: x.clone(),
                    y: y.clone(),
                },
                LevenbergMarquardt::new(s),
                vec![1.0, 0.0],
            )
            .unwrap()
            .0
        };
        let plain = fit(LmSettings::default());
        let minpack = fit(LmSettings {
            ftol: 1e-10,
            xtol: 1e-10,
            ..LmSettings::default()
        });
        assert!(matches!(
            minpack.stop_reason(),
            Some(
                StopReason::CostConverged
                    | StopReason::StepConverged
                    | StopReason::NoFurtherReduction
            )
        ));
        assert!(minpack
            .stop_reason()
            .unwrap()
            .text()
            .starts_with("converged"));
        assert!(matches!(
            plain.stop_reason(),
            Some(StopReason::MinGrad | StopReason::MuMax)
        ));
        assert!(minpack.history().len() <= plain.history().len());
        let (a, b) = (plain.best().unwrap(), minpack.best().unwrap());
        assert!(
            (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6,
            "{a:?} {b:?}"
        );
    }

    /// Dennis & Schnabel's large-residual example (1996, Example 10.2.4): r = (θ + 1,
    /// λθ² + θ − 1), minimum at θ = 0 with residuals (1, −1) for every λ; the Gauss–Newton
    /// step overshoots by the factor λ there (λ < 0: a zigzag), `stops` ends the fit where θ
    /// first comes within it of 0 ([`LeastSquares::stop_at`]).
    struct LargeResidual {
        lambda: f64,
        stops: Option<f64>,
    }
    impl LeastSquares for LargeResidual {
        fn n_params(&self) -> usize {
            1
        }
        fn n_train(&self) -> usize {
            2
        }
        fn sse(&self, t: &[f64]) -> f64 {
            let (a, b) = (t[0] + 1.0, self.lambda * t[0] * t[0] + t[0] - 1.0);
            a * a + b * b
        }
        fn normal_equations(&self, t: &[f64]) -> NormalEquations {
            let (a, b) = (t[0] + 1.0, self.lambda * t[0] * t[0] + t[0] - 1.0);
            let jb = 2.0 * self.lambda * t[0] + 1.0;
            NormalEquations {
                jtj: vec![1.0 + jb * jb],
                jtr: vec![a + jb * b],
                sse: a * a + b * b,
            }
        }
        fn validation_mse(&self, _: &[f64]) -> Option<f64> {
            None
        }
        fn stop_at(&self, t: &[f64]) -> bool {
            self.stops.is_some_and(|s| t[0].abs() < s)
        }
    }

    /// On the zigzag of a large-residual problem trainlm's rule lowers μ after every accepted
    /// step down to pure Gauss–Newton steps and crawls; heeding the gain ratio keeps enough
    /// damping to cross the valley and ends at the same minimum in a fraction of the epochs.
    /// On a problem whose linear model is exact (ρ = 1) both take the same path.
    #[test]
    fn the_gain_ratio_ends_a_large_residual_zigzag() {
        let fit = |gain_ratio: bool, lambda: f64| {
            run(
                LargeResidual {
                    lambda,
                    stops: None,
                },
                LevenbergMarquardt::new(LmSettings {
                    ftol: 1e-14,
                    xtol: 0.0,
                    min_grad: 0.0,
                    gain_ratio,
                    ..LmSettings::default()
                }),
                vec![1.0],
            )
            .unwrap()
            .0
        };
        let (plain, heeded) = (fit(false, -0.95), fit(true, -0.95));
        for s in [&plain, &heeded] {
            assert_eq!(s.stop_reason(), Some(StopReason::CostConverged));
            assert!(s.best().unwrap()[0].abs() < 1e-5, "{:?}", s.best());
        }
        assert!(
            2 * heeded.history().len() < plain.history().len(),
            "{} against {} epochs",
            heeded.history().len(),
            plain.history().len()
        );
        // λ = 0: the residuals are linear, every step's ρ is 1.
        let (a, b) = (fit(false, 0.0), fit(true, 0.0));
        let path = |s: &LevenbergMarquardt| -> Vec<(f64, f64)> {
            s.history().iter().map(|e| (e.train_mse, e.mu)).collect()
        };
        assert_eq!(path(&a), path(&b));
        assert_eq!(a.best(), b.best());
    }

    /// The gain ratio against the reduction computed by hand: 1 for residuals linear in θ at
    /// any damping, and below 1/4 where the SSE fell by much less than predicted.
    #[test]
    fn the_gain_ratio_is_the_actual_over_the_predicted_reduction() {
        // r = J θ − y with J = [[1, 0], [1, 2], [0, 1]], y = (1, 2, 3): SSE(θ) = ‖Jθ − y‖².
        let j = [[1.0, 0.0], [1.0, 2.0], [0.0, 1.0]];
        let y = [1.0, 2.0, 3.0];
        let sse = |t: &[f64]| -> f64 {
            j.iter()
                .zip(&y)
                .map(|(row, yi)| (row[0] * t[0] + row[1] * t[1] - yi).powi(2))
                .sum()
        };
        let theta = [0.3, -0.2];
        let mut jtj = [0.0; 4];
        let mut jtr = [0.0; 2];
        for (row, yi) in j.iter().zip(&y) {
            let r = row[0] * theta[0] + row[1] * theta[1] - yi;
            for p in 0..2 {
                jtr[p] += row[p] * r;
                for q in 0..2 {
                    jtj[p * 2 + q] += row[p] * row[q];
                }
            }
        }
        for mu in [0.0, 0.5, 3.0] {
            let a = [jtj[0] + mu, jtj[1], jtj[2], jtj[3] + mu];
            let det = a[0] * a[3] - a[1] * a[2];
            let d = [
                (a[3] * jtr[0] - a[1] * jtr[1]) / det,
                (a[0] * jtr[1] - a[2] * jtr[0]) / det,
            ];
            let next = [theta[0] - d[0], theta[1] - d[1]];
            let rho = gain_ratio(&theta, &next, &jtr, mu, sse(&theta), sse(&next));
            assert!((rho - 1.0).abs() < 1e-12, "μ {mu}: ρ {rho}");
            // The same step credited with a tenth of its reduction.
            let poor = sse(&theta) - 0.1 * (sse(&theta) - sse(&next));
            let rho = gain_ratio(&theta, &next, &jtr, mu, sse(&theta), poor);
            assert!((rho - 0.1).abs() < 1e-12, "μ {mu}: ρ {rho}");
            let s = LmSettings::default();
            assert_eq!(damping_after(rho, s), 2.0);
            assert_eq!(damping_after(0.25, s), s.mu_dec);
        }
    }

    /// A problem's own stop ends the fit at the first accepted step that meets it.
    #[test]
    fn a_problem_stops_the_fit_where_it_says() {
        let (s, _) = run(
            LargeResidual {
                lambda: -0.9,
                stops: Some(0.05),
            },
            LevenbergMarquardt::new(LmSettings {
                ftol: 1e-14,
                ..LmSettings::default()
            }),
            vec![1.0],
        )
        .unwrap();
        assert_eq!(s.stop_reason(), Some(StopReason::AtBound));
        let t = s.best().unwrap()[0];
        assert!(t.abs() < 0.05, "{t}");
        // It had not yet converged there.
        assert!(t.abs() > 1e-4, "{t}");
    }

    #[test]
    fn converges_on_an_exponential() {
        let x: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = x.iter().map(|x| 2.5 * (-1.3 * x).exp()).collect();
        let (s, _) = run(
            Exp { x, y },
            LevenbergMarquardt::new(LmSettings::default()),
            vec![1.0, 0.0],
        )
        .unwrap();
        let t = s.best().unwrap();
        assert!(
            (t[0] - 2.5).abs() < 1e-8 && (t[1] + 1.3).abs() < 1e-8,
            "{t:?}"
        );
        assert!(matches!(
            s.stop_reason(),
            Some(StopReason::MinGrad | StopReason::MuMax | StopReason::Goal)
        ));
        // The error never increased.
        let h = s.history();
        assert!(h.windows(2).all(|w| w[1].train_mse <= w[0].train_mse));
    }

    /// y = X θ with orthogonal columns (Walsh functions) of different weight and two zero
    /// columns: trainbr's fixed point is known in closed form per column.
    struct Linear {
        x: Vec<[f64; 5]>,
        y: Vec<f64>,
    }
    impl LeastSquares for Linear {
        fn n_params(&self) -> usize {
            5
        }
        fn n_train(&self) -> usize {
            self.y.len()
        }
        fn sse(&self, t: &[f64]) -> f64 {
            self.x
                .iter()
                .zip(&self.y)
                .map(|(x, y)| (x.iter().zip(t).map(|(a, b)| a * b).sum::<f64>() - y).powi(2))
                .sum()
        }
        fn normal_equations(&self, t: &[f64]) -> NormalEquations {
            let mut jtj = vec![0.0; 25];
            let mut jtr = vec![0.0; 5];
            let mut sse = 0.0;
            for (x, y) in self.x.iter().zip(&self.y) {
                let r = x.iter().zip(t).map(|(a, b)| a * b).sum::<f64>() - y;
                for p in 0..5 {
                    jtr[p] += x[p] * r;
                    for q in 0..5 {
                        jtj[p * 5 + q] += x[p] * x[q];
                    }
                }
                sse += r * r;
            }
            NormalEquations { jtj, jtr, sse }
        }
        fn validation_mse(&self, _: &[f64]) -> Option<f64> {
            None
        }
    }

    #[test]
    fn trainbr_finds_the_known_effective_parameters_of_a_linear_problem() {
        let n = 256;
        let walsh = |k: u32, i: usize| {
            if (i as u32 & k).count_ones().is_multiple_of(2) {
                1.0
            } else {
                -1.0
            }
        };
        let scale = [1.0, 1.0, 0.01, 0.0, 0.0];
        let x: Vec<[f64; 5]> = (0..n)
            .map(|i| {
                let w = [walsh(0, i), walsh(1, i), walsh(2, i), 0.0, 0.0];
                std::array::from_fn(|c| scale[c] * w[c])
            })
            .collect();
        // Truth plus a deterministic "noise" along further Walsh functions.
        let y: Vec<f64> = (0..n)
            .map(|i| {
                0.5 * walsh(0, i) - 0.3 * walsh(1, i) + 0.004 * walsh(2, i) + 0.05 * walsh(5, i)
                    - 0.04 * walsh(9, i)
                    + 0.03 * walsh(17, i)
            })
            .collect();
        // The fixed point: with D = XᵀX diagonal (d_c = n s_c²) and b = Xᵀy, the minimiser of
        // F is θ_c = β b_c / (β d_c + α), γ = Σ β d_c / (β d_c + α).
        let d: Vec<f64> = scale.iter().map(|s| n as f64 * s * s).collect();
        let b: Vec<f64> = (0..5)
            .map(|c| x.iter().zip(&y).map(|(r, y)| r[c] * y).sum())
            .collect();
        let p = Linear { x, y };
        let (mut alpha, mut beta) = (1.0, 1.0);
        let mut gamma = 0.0;
        for _ in 0..10_000 {
            let theta: Vec<f64> = (0..5)
                .map(|c| beta * b[c] / (beta * d[c] + alpha))
                .collect();
            gamma = (0..5)
                .map(|c| beta * d[c] / (beta * d[c] + alpha))
                .sum::<f64>();
            alpha = gamma / (2.0 * theta.iter().map(|t| t * t).sum::<f64>());
            beta = (n as f64 - gamma) / (2.0 * p.sse(&theta));
        }
        assert!(gamma > 2.0 && gamma < 2.99, "{gamma}");
        let (s, _) = run(
            &p,
            LevenbergMarquardt::new(LmSettings {
                epochs: 500,
                min_grad: 1e-12,
                ..LmSettings::trainbr()
            }),
            vec![0.1, 0.1, 0.1, 0.1, 0.1],
        )
        .unwrap();
        let got = s.bayes().unwrap();
        assert!(
            (got.gamma - gamma).abs() < 1e-6,
            "γ {} vs {gamma}",
            got.gamma
        );
        assert!(
            (got.alpha / alpha - 1.0).abs() < 1e-6,
            "α {} vs {alpha}",
            got.alpha
        );
        assert!(
            (got.beta / beta - 1.0).abs() < 1e-6,
            "β {} vs {beta}",
            got.beta
        );
        // The unsupported weights are pulled to zero; γ is in every epoch of the history.
        let t = s.best().unwrap();
        assert!(t[3].abs() < 1e-6 && t[4].abs() < 1e-6, "{t:?}");
        assert!(s.history().iter().all(|e| e.gamma.is_some()));
    }

    #[test]
    fn trainbr_refuses_fewer_residuals_than_parameters() {
        let p = Linear {
            x: vec![[1.0; 5]; 4],
            y: vec![1.0; 4],
        };
        let e = run(
            &p,
            LevenbergMarquardt::new(LmSettings::trainbr()),
            vec![0.0; 5],
        )
        .err()
        .unwrap()
        .to_string();
        assert!(e.contains("more training residuals than parameters"), "{e}");
    }
}
