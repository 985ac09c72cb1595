//! Training the seed 002 network: dataset → mapminmax → Nguyen–Widrow → trainlm (the
//! least-squares problem in [`super::problem`]), or Adam/AdamW through burn ([`super::adam`]);
//! several starts kept best or averaged into an ensemble.

use rayon::prelude::*;

use super::adam::{self, AdamData, AdamSettings};
use super::dataset::{Dataset, MapMinMax, RunTable};
use super::lm::{self, Epoch, LeastSquares, LevenbergMarquardt, LmSettings, StopReason};
use super::mlp::{self, Shape};
use super::support::{occupancy, Occupancy};
use super::IdentifyError;
use super::InputSet;
use crate::config::{
    default_support_cells, TrainConfig, Trainer, DEFAULT_AUDIT_MU_MAX, DEFAULT_SUPPORT_MIN_SAMPLES,
};
use crate::score::Sample;

use super::problem::MlpProblem;

/// A trained network with everything the model file needs.
#[derive(Debug, Clone)]
pub struct TrainedMlp {
    pub inputs: InputSet,
    /// The network's widths (θ in [`mlp::Arch`]'s order).
    pub arch: mlp::Arch,
    pub theta: Vec<f64>,
    pub x_norm: MapMinMax,
    pub y_norm: MapMinMax,
    pub history: Vec<Epoch>,
    pub stop: StopReason,
    pub n_train: usize,
    pub n_val: usize,
    /// Training and validation MSE of the returned weights, μ².
    pub train_mse: f64,
    pub val_mse: f64,
    /// Input ranges seen in training and validation data: (min, max) per input.
    pub domain: Vec<(f64, f64)>,
    /// Median vehicle speed of the training samples, m/s.
    pub reference_speed_mps: f64,
    /// Median ambient temperature of the training samples, °C (networks with that input).
    pub reference_temperature_c: Option<f64>,
    /// The seed of the kept start.
    pub seed: u64,
    /// Validation MSE (μ²) of every start, seeds in order (one entry for a single start).
    pub start_val_mse: Vec<f64>,
    /// Training and validation samples per cell of the model file's support grid.
    pub occupancy: Occupancy,
    /// The training and validation samples (physical units, pooled as axle 1) the audit
    /// compares the model's loss/recovery order with.
    pub data: Vec<Sample>,
    /// The audit's ceiling μ_max.
    pub audit_mu_max: f64,
    /// An ensemble's members (θ of one network of `hidden` neurons each, best first; `theta`
    /// is their mean as one wide network); empty for a single network.
    pub members: Vec<Vec<f64>>,
    pub settings: LmSettings,
}

impl TrainedMlp {
    /// μ for physical inputs `x` (network only: no creep region, no clamping).
    pub fn eval_raw(&self, x: &[f64]) -> f64 {
        let xn: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(c, v)| {
                let (g, o) = self.x_norm.gain_offset(c);
                g * v + o
            })
            .collect();
        self.y_norm
            .reverse(0, mlp::forward_layers(&self.arch, &self.theta, &xn))
    }
}

/// The audit's samples of `tables`: the split and decimation of `cfg`, with the speed (and, for
/// networks with the temperature input, the run's ambient temperature) of every sample, pooled
/// as axle 1.
pub fn audit_samples(tables: &[RunTable], cfg: &TrainConfig) -> Result<Vec<Sample>, IdentifyError> {
    let full = if cfg.inputs.has_temperature() {
        InputSet::DvDdvVT
    } else {
        InputSet::DvDdvV
    };
    let k = full.count();
    let with_v = Dataset::build(tables, full, &cfg.split, cfg.decimate)?;
    Ok(with_v
        .train_x
        .chunks_exact(k)
        .zip(&with_v.train_y)
        .chain(with_v.val_x.chunks_exact(k).zip(&with_v.val_y))
        .map(|(x, mu)| Sample {
            axle: 1,
            dv_mps: x[0],
            ddv_mps2: x[1],
            v_mps: x[2],
            t_c: x.get(3).copied().unwrap_or(f64::NAN),
            mu: *mu,
        })
        .collect())
}

/// LM settings of a pipeline's `[train]` section.
pub fn lm_settings(cfg: &TrainConfig) -> LmSettings {
    LmSettings {
        epochs: cfg.epochs,
        goal: cfg.goal,
        min_grad: cfg.min_grad,
        mu: cfg.mu,
        mu_dec: cfg.mu_dec,
        mu_inc: cfg.mu_inc,
        mu_max: cfg.mu_max,
        max_fail: cfg.max_fail,
        bayesian: cfg.bayesian,
        // trainlm and trainbr have no such tests.
        ftol: 0.0,
        xtol: 0.0,
        gain_ratio: false,
    }
}

/// Trains the network on the valid estimates of `tables` with the pipeline's `[train]`
/// settings. `progress` is called after every epoch.
pub fn train_mlp(
    tables: &[RunTable],
    cfg: &TrainConfig,
    progress: Option<lm::EpochProgress<'_>>,
) -> Result<TrainedMlp, IdentifyError> {
    let inputs = cfg.inputs;
    if cfg.support_cells.len() != inputs.count() {
        return Err(IdentifyError::Data {
            what: format!(
                "train.support_cells gives {} counts for {} inputs",
                cfg.support_cells.len(),
                inputs.count()
            ),
            hint: format!(
                "give one count per input, e.g. {:?}",
                default_support_cells(inputs.count())
            ),
        });
    }
    let data = Dataset::build(tables, inputs, &cfg.split, cfg.decimate)?;
    let mut trained = if cfg.starts <= 1 {
        fit_one(&data, cfg, cfg.seed, progress)?
    } else {
        train_starts(&data, cfg, progress)?
    };
    trained.occupancy = occupancy_of(&data, &trained, &cfg.support_cells, cfg.support_min_samples);
    if inputs.has_temperature() {
        let mut t: Vec<f64> = data.train_x.iter().skip(3).step_by(4).copied().collect();
        t.sort_by(f64::total_cmp);
        trained.reference_temperature_c = Some(t[t.len() / 2]);
    }
    trained.data = audit_samples(tables, cfg)?;
    trained.audit_mu_max = cfg.audit_mu_max;
    Ok(trained)
}

/// The training and validation samples of `data` per support cell of the network `t`.
fn occupancy_of(data: &Dataset, t: &TrainedMlp, cells: &[usize], min_samples: u64) -> Occupancy {
    let k = data.inputs.count();
    let x: Vec<f64> = data.train_x.iter().chain(&data.val_x).copied().collect();
    let norm: Vec<(f64, f64)> = (0..k).map(|c| (t.x_norm.min[c], t.x_norm.max[c])).collect();
    occupancy(&x, k, &norm, &t.domain, cells, min_samples)
}

/// `cfg.starts` trainings from the seeds `cfg.seed`, `cfg.seed + 1`, … in parallel; keeps the
/// one with the lowest validation error (training error without validation data), the
/// earliest seed on a tie, so the choice does not depend on the thread count — or, with
/// `cfg.ensemble` = M > 1, the best M averaged into one network ([`mlp::average`]). `progress` sees
/// the epochs of the first start only (the others run beside it).
fn train_starts(
    data: &Dataset,
    cfg: &TrainConfig,
    progress: Option<lm::EpochProgress<'_>>,
) -> Result<TrainedMlp, IdentifyError> {
    let settings = lm_settings(cfg);
    // LM: one problem (data scaled and laid out by column) for every start.
    let prepared = match cfg.trainer {
        Trainer::Lm => Some(Prepared::new(data, lm_shape(cfg))?),
        Trainer::Burn(_) => None,
    };
    let runs: Vec<Result<TrainedMlp, IdentifyError>> = (0..cfg.starts as u64)
        .into_par_iter()
        .map(|k| {
            let p = if k == 0 { progress } else { None };
            let seed = cfg.seed.wrapping_add(k);
            match &prepared {
                Some(prepared) => prepared.fit(data, seed, settings, p),
                None => fit_one(data, cfg, seed, p),
            }
        })
        .collect();
    let runs: Vec<TrainedMlp> = runs.into_iter().collect::<Result<_, _>>()?;
    let key = |t: &TrainedMlp| {
        if t.val_mse.is_finite() {
            t.val_mse
        } else if t.train_mse.is_finite() {
            t.train_mse
        } else {
            f64::INFINITY
        }
    };
    let all: Vec<f64> = runs.iter().map(|t| t.val_mse).collect();
    // Best first; a stable sort keeps the earlier seed first on a tie.
    let mut order: Vec<usize> = (0..runs.len()).collect();
    order.sort_by(|&a, &b| key(&runs[a]).total_cmp(&key(&runs[b])));
    let mut runs: Vec<Option<TrainedMlp>> = runs.into_iter().map(Some).collect();
    let mut best = runs[order[0]].take().expect("each start once");
    best.start_val_mse = all;
    if cfg.ensemble > 1 {
        let members: Vec<Vec<f64>> = std::iter::once(best.theta.clone())
            .chain(
                order[1..cfg.ensemble.min(order.len())]
                    .iter()
                    .map(|&i| runs[i].take().expect("each start once").theta),
            )
            .collect();
        let refs: Vec<&[f64]> = members.iter().map(Vec::as_slice).collect();
        let shape = best
            .arch
            .lm_shape()
            .expect("LM trains one hidden layer here");
        let (wide, theta) = mlp::average(shape, &refs);
        let prepared = prepared
            .as_ref()
            .expect("checked: an ensemble is trained by LM");
        let problem = prepared.problem.with_shape(wide);
        best.train_mse = problem.sse(&theta) / problem.n_train() as f64 * problem.mse_scale();
        best.val_mse = problem.validation_mse(&theta).unwrap_or(f64::NAN);
        best.arch = wide.into();
        best.theta = theta;
        best.members = members;
    }
    Ok(best)
}

/// Trains on a prepared dataset.
pub fn train_on(
    data: &Dataset,
    hidden: usize,
    seed: u64,
    settings: LmSettings,
    progress: Option<lm::EpochProgress<'_>>,
) -> Result<TrainedMlp, IdentifyError> {
    Prepared::new(data, Shape::one(data.inputs.count(), hidden))?
        .fit(data, seed, settings, progress)
}

/// The LM shape of `cfg.layers` (one or two hidden layers; the config refuses more for LM).
fn lm_shape(cfg: &TrainConfig) -> Shape {
    mlp::Arch {
        inputs: cfg.inputs.count(),
        hidden: cfg.layers.clone(),
    }
    .lm_shape()
    .expect("checked: LM trains one or two hidden layers")
}

/// The Adam/AdamW settings of a pipeline's `[train]` section (`epochs` and `max_fail` are
/// the epochs and the patience).
pub fn adam_settings(cfg: &TrainConfig, optimizer: crate::config::Optimizer) -> AdamSettings {
    AdamSettings {
        optimizer,
        learning_rate: cfg.learning_rate,
        weight_decay: cfg.weight_decay,
        batch: cfg.batch,
        max_epochs: cfg.epochs as usize,
        patience: cfg.max_fail.max(1) as usize,
    }
}

/// A dataset checked, scaled and laid out as the least-squares problem of one network shape:
/// what every start of a training shares.
struct Prepared {
    problem: MlpProblem,
    x_norm: MapMinMax,
    y_norm: MapMinMax,
    /// Input ranges seen in training and validation data: (min, max) per input.
    domain: Vec<(f64, f64)>,
}

impl Prepared {
    fn new(data: &Dataset, shape: Shape) -> Result<Prepared, IdentifyError> {
        check_finite(data)?;
        let n = data.normalised();
        let domain = domain_of(data);
        Ok(Prepared {
            problem: MlpProblem::new(shape, n.x, n.y, n.vx, n.vy, n.scale),
            x_norm: n.x_norm,
            y_norm: n.y_norm,
            domain,
        })
    }

    /// One LM training from the Nguyen–Widrow start of `seed`.
    fn fit(
        &self,
        data: &Dataset,
        seed: u64,
        settings: LmSettings,
        progress: Option<lm::EpochProgress<'_>>,
    ) -> Result<TrainedMlp, IdentifyError> {
        let problem = &self.problem;
        let shape = problem.shape;
        let mut solver = LevenbergMarquardt::new(settings);
        if let Some(p) = progress {
            solver = solver.with_progress(p);
        }
        let (solver, _) =
            lm::run(problem, solver, mlp::nguyen_widrow(shape, seed)).map_err(|e| {
                IdentifyError::Solver {
                    fit: "network training".into(),
                    source: e.into(),
                }
            })?;
        let theta = solver.best().expect("set from the first epoch").to_vec();
        let train_mse = problem.sse(&theta) / problem.n_train() as f64 * problem.mse_scale();
        let val_mse = problem.validation_mse(&theta).unwrap_or(f64::NAN);
        Ok(assemble(
            data,
            Fitted {
                arch: shape.into(),
                theta,
                x_norm: self.x_norm.clone(),
                y_norm: self.y_norm.clone(),
                history: solver.history().to_vec(),
                stop: solver.stop_reason().unwrap_or(StopReason::Epochs),
                train_mse,
                val_mse,
                domain: self.domain.clone(),
                seed,
                settings,
            },
        ))
    }
}

/// Every training and validation value is finite (else an error naming the value).
fn check_finite(data: &Dataset) -> Result<(), IdentifyError> {
    if let Some(bad) = data
        .train_x
        .iter()
        .chain(&data.train_y)
        .chain(&data.val_x)
        .chain(&data.val_y)
        .find(|v| !v.is_finite())
    {
        return Err(IdentifyError::Data {
            what: format!("a training value is not finite ({bad})"),
            hint: "train on valid estimates only".into(),
        });
    }
    Ok(())
}

/// Input ranges seen in training and validation data: (min, max) per input.
fn domain_of(data: &Dataset) -> Vec<(f64, f64)> {
    let k = data.inputs.count();
    (0..k)
        .map(|c| {
            data.train_x
                .iter()
                .skip(c)
                .step_by(k)
                .chain(data.val_x.iter().skip(c).step_by(k))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(*v), hi.max(*v))
                })
        })
        .collect()
}

/// One training of `cfg`'s network from the start of `seed`, by its trainer.
fn fit_one(
    data: &Dataset,
    cfg: &TrainConfig,
    seed: u64,
    progress: Option<lm::EpochProgress<'_>>,
) -> Result<TrainedMlp, IdentifyError> {
    match cfg.trainer {
        Trainer::Lm => {
            Prepared::new(data, lm_shape(cfg))?.fit(data, seed, lm_settings(cfg), progress)
        }
        Trainer::Burn(o) => fit_burn(data, cfg, o, seed, progress),
    }
}

/// One Adam/AdamW training through burn ([`adam::train`]) of `cfg.layers` from the
/// Nguyen–Widrow start of `seed`, on the data normalised as for LM.
fn fit_burn(
    data: &Dataset,
    cfg: &TrainConfig,
    optimizer: crate::config::Optimizer,
    seed: u64,
    progress: Option<lm::EpochProgress<'_>>,
) -> Result<TrainedMlp, IdentifyError> {
    check_finite(data)?;
    let n = data.normalised();
    let arch = mlp::Arch {
        inputs: data.inputs.count(),
        hidden: cfg.layers.clone(),
    };
    let fit = adam::train(
        &arch,
        &AdamData {
            x: &n.x,
            y: &n.y,
            vx: &n.vx,
            vy: &n.vy,
            scale: n.scale,
        },
        mlp::nguyen_widrow_layers(&arch, seed),
        &adam_settings(cfg, optimizer),
        seed,
        progress,
    )?;
    let kept = &fit.history[fit.best_epoch - 1];
    let (train_mse, val_mse) = (kept.train_mse, kept.val_mse);
    Ok(assemble(
        data,
        Fitted {
            arch,
            theta: fit.theta,
            x_norm: n.x_norm,
            y_norm: n.y_norm,
            history: fit.history,
            stop: fit.stop,
            train_mse,
            val_mse,
            domain: domain_of(data),
            seed,
            settings: lm_settings(cfg),
        },
    ))
}

/// What one training produced, before the support occupancy is counted.
struct Fitted {
    arch: mlp::Arch,
    theta: Vec<f64>,
    x_norm: MapMinMax,
    y_norm: MapMinMax,
    history: Vec<Epoch>,
    stop: StopReason,
    train_mse: f64,
    val_mse: f64,
    domain: Vec<(f64, f64)>,
    seed: u64,
    settings: LmSettings,
}

/// The [`TrainedMlp`] of a training (default support grid; [`train_mlp`] recounts it with the
/// pipeline's).
fn assemble(data: &Dataset, f: Fitted) -> TrainedMlp {
    let mut t = TrainedMlp {
        inputs: data.inputs,
        arch: f.arch,
        theta: f.theta,
        x_norm: f.x_norm,
        y_norm: f.y_norm,
        history: f.history,
        stop: f.stop,
        n_train: data.n_train(),
        n_val: data.n_val(),
        train_mse: f.train_mse,
        val_mse: f.val_mse,
        domain: f.domain,
        reference_speed_mps: f64::NAN,
        reference_temperature_c: None,
        seed: f.seed,
        start_val_mse: vec![f.val_mse],
        members: Vec::new(),
        settings: f.settings,
        occupancy: Occupancy {
            cells: vec![],
            min_samples: 1,
            counts: vec![],
        },
        data: Vec::new(),
        audit_mu_max: DEFAULT_AUDIT_MU_MAX,
    };
    let k = data.inputs.count();
    t.occupancy = occupancy_of(
        data,
        &t,
        &default_support_cells(k),
        DEFAULT_SUPPORT_MIN_SAMPLES,
    );
    t
}
