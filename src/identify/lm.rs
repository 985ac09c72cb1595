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

use crate::linalg::{cho_solve, cholesky};

/// JᵀJ (row-major, p×p), Jᵀr and Σr² at one parameter vector.
#[derive(Debug, Clone, PartialEq)]
pub struct NormalEquations {
    pub jtj: Vec<f64>,
    pub jtr: Vec<f64>,
    pub sse: f64,
}

/// A nonlinear least-squares problem for [`LevenbergMarquardt`].
pub trait LeastSquares {
    /// Number of parameters p.
    fn n_params(&self) -> usize;
    /// Number of training residuals (for mean squared errors).
    fn n_train(&self) -> usize;
    /// Σ r² over the training residuals.
    fn sse(&self, theta: &[f64]) -> f64;
    /// JᵀJ, Jᵀr and Σ r² over the training residuals.
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations;
    /// Mean squared validation error, `None` without a validation set.
    fn validation_mse(&self, theta: &[f64]) -> Option<f64>;
    /// Factor turning a mean squared error of the residuals into the reported unit (e.g. the
    /// square of the mapminmax scale of the target). 1 by default.
    fn mse_scale(&self) -> f64 {
        1.0
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
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        (**self).normal_equations(theta)
    }
    fn validation_mse(&self, theta: &[f64]) -> Option<f64> {
        (**self).validation_mse(theta)
    }
    fn mse_scale(&self) -> f64 {
        (**self).mse_scale()
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
    /// validation error.
    pub max_fail: u32,
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
        }
    }
}

pub use crate::model::Epoch;

/// Called after every epoch (the CLI prints progress with it).
pub type Progress = Box<dyn FnMut(&Epoch) + Send>;

/// Why training stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    Epochs,
    Goal,
    MinGrad,
    MuMax,
    ValidationStop,
}

impl StopReason {
    pub fn text(self) -> &'static str {
        match self {
            StopReason::Epochs => "maximum epochs reached",
            StopReason::Goal => "performance goal met",
            StopReason::MinGrad => "minimum gradient reached",
            StopReason::MuMax => "mu reached its maximum",
            StopReason::ValidationStop => "validation stop (max_fail)",
        }
    }
}

/// The solver. After a run, [`LevenbergMarquardt::best`] holds the weights to use (the best
/// validation epoch when there is validation data, else the last accepted ones) and
/// [`LevenbergMarquardt::history`] the epochs.
pub struct LevenbergMarquardt {
    pub settings: LmSettings,
    mu: f64,
    fails: u32,
    best_val: f64,
    best: Option<Vec<f64>>,
    stop: Option<StopReason>,
    history: Vec<Epoch>,
    start: Instant,
    progress: Option<Progress>,
}

impl LevenbergMarquardt {
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
        }
    }

    /// Calls `f` after every epoch (the CLI prints progress with it).
    pub fn with_progress(mut self, f: impl FnMut(&Epoch) + Send + 'static) -> Self {
        self.progress = Some(Box::new(f));
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

impl<O: LeastSquares> Solver<O, LmState> for LevenbergMarquardt {
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
        let (sse, n, scale) = problem.problem("cost_count", |o| {
            Ok((o.sse(&theta), o.n_train().max(1) as f64, o.mse_scale()))
        })?;
        let val = problem.problem("validation_count", |o| Ok(o.validation_mse(&theta)))?;
        if let Some(v) = val {
            self.best_val = v;
        }
        self.best = Some(theta);
        Ok((state.cost(sse / n * scale), None))
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LmState,
    ) -> Result<(LmState, Option<KV>), Error> {
        let s = self.settings;
        let theta = state.take_param().expect("set in init").to_vec();
        let (ne, n, scale, p) = problem.problem("jacobian_count", |o| {
            Ok((
                o.normal_equations(&theta),
                o.n_train().max(1) as f64,
                o.mse_scale(),
                o.n_params(),
            ))
        })?;
        let grad_norm = 2.0 * ne.jtr.iter().map(|g| g * g).sum::<f64>().sqrt();
        let mse = ne.sse / n * scale;
        if mse <= s.goal {
            self.stop = Some(StopReason::Goal);
        } else if grad_norm < s.min_grad {
            self.stop = Some(StopReason::MinGrad);
        }
        let mut next = theta.clone();
        let mut next_sse = ne.sse;
        if self.stop.is_none() {
            let mut a = ne.jtj.clone();
            loop {
                for d in 0..p {
                    a[d * p + d] = ne.jtj[d * p + d] + self.mu;
                }
                let trial = cholesky(&a, p).map(|l| {
                    let step = cho_solve(&l, p, &ne.jtr);
                    theta
                        .iter()
                        .zip(&step)
                        .map(|(t, d)| t - d)
                        .collect::<Vec<f64>>()
                });
                let accepted = match trial {
                    Some(t) if t.iter().all(|v| v.is_finite()) => {
                        let e = problem.problem("cost_count", |o| Ok(o.sse(&t)))?;
                        if e.is_finite() && e < ne.sse {
                            next = t;
                            next_sse = e;
                            true
                        } else {
                            false
                        }
                    }
                    _ => false,
                };
                if accepted {
                    self.mu *= s.mu_dec;
                    break;
                }
                self.mu *= s.mu_inc;
                if self.mu > s.mu_max {
                    self.stop = Some(StopReason::MuMax);
                    break;
                }
            }
        }
        let val = problem.problem("validation_count", |o| Ok(o.validation_mse(&next)))?;
        match val {
            Some(v) if v < self.best_val => {
                self.best_val = v;
                self.best = Some(next.clone());
                self.fails = 0;
            }
            Some(_) => {
                self.fails += 1;
                if self.fails >= s.max_fail && self.stop.is_none() {
                    self.stop = Some(StopReason::ValidationStop);
                }
            }
            None => self.best = Some(next.clone()),
        }
        let epoch = Epoch {
            epoch: state.get_iter() + 1,
            train_mse: next_sse / n * scale,
            val_mse: val.unwrap_or(f64::NAN),
            mu: self.mu,
            grad_norm,
            elapsed_s: self.start.elapsed().as_secs_f64(),
        };
        self.history.push(epoch);
        if let Some(f) = self.progress.as_mut() {
            f(&epoch);
        }
        if state.get_iter() + 1 >= s.epochs && self.stop.is_none() {
            self.stop = Some(StopReason::Epochs);
        }
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

/// Runs the solver from `theta0` and returns it (weights in [`LevenbergMarquardt::best`]).
pub fn run<O: LeastSquares>(
    problem: O,
    solver: LevenbergMarquardt,
    theta0: Vec<f64>,
) -> Result<(LevenbergMarquardt, O), Error> {
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
}
