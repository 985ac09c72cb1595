//! Training the seed 002 network: dataset → mapminmax → Nguyen–Widrow → trainlm.
//!
//! The least-squares problem ([`MlpProblem`]) works on blocks of [`mlp::BLOCK`] samples, the
//! data stored by input column so that SIMD lanes run across samples ([`mlp::block`], AVX-512,
//! AVX2 or plain f64, chosen at run time and bit-identical). Per block the Jacobian J (P × B)
//! and the residuals r are built with the residuals as one more row, A = [J; rᵀ]; then the
//! lower triangle of A Aᵀ (a symmetric rank-k update, faer's triangular matrix product) holds
//! JᵀJ and Jᵀr at once.
//! Blocks are grouped into fixed chunks of [`CHUNK`] samples, chunks run in parallel and are
//! summed in order, so the result does not depend on the number of threads; memory is
//! O(chunk × P) per thread, never O(N × P).

use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;

use super::adam::{self, AdamData, AdamSettings};
use super::dataset::{Dataset, MapMinMax, RunTable};
use super::lm::{
    self, Epoch, LeastSquares, LevenbergMarquardt, LmSettings, NormalEquations, StopReason,
};
use super::mlp::{self, Scratch, Shape, BLOCK};
use super::support::{occupancy, Occupancy};
use super::IdentifyError;
use super::InputSet;
use crate::config::{
    default_support_cells, TrainConfig, Trainer, DEFAULT_AUDIT_MU_MAX, DEFAULT_SUPPORT_MIN_SAMPLES,
};
use crate::score::Sample;
#[cfg(target_arch = "x86_64")]
use crate::simd::{Avx2, Avx512, F64x4, F64x8};
use crate::simd::{Isa, Portable};

/// Samples per chunk: fixed, so the sums (chunk results added in order) do not depend on the
/// number of threads.
pub const CHUNK: usize = 8 * BLOCK;

/// [`mlp::block`] on the widest lanes of this CPU (same bits on every path).
#[allow(clippy::too_many_arguments)]
pub(super) fn block_dispatch(
    isa: Isa,
    shape: Shape,
    theta: &[f64],
    x: &[&[f64]],
    y: &[f64],
    n: usize,
    r: &mut [f64],
    jac: Option<&mut [f64]>,
    scratch: &mut Scratch,
) {
    match isa {
        // SAFETY: the token proves AVX-512F on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512(t) => unsafe { block_avx512(t, shape, theta, x, y, n, r, jac, scratch) },
        // SAFETY: the token proves AVX2 and FMA on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2(t) => unsafe { block_avx2(t, shape, theta, x, y, n, r, jac, scratch) },
        _ => mlp::block::<f64>(Portable, shape, theta, x, y, n, r, jac, scratch),
    }
}

/// [`mlp::block`] on AVX-512 registers (eight samples per vector).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[allow(clippy::too_many_arguments)]
fn block_avx512(
    isa: Avx512,
    shape: Shape,
    theta: &[f64],
    x: &[&[f64]],
    y: &[f64],
    n: usize,
    r: &mut [f64],
    jac: Option<&mut [f64]>,
    scratch: &mut Scratch,
) {
    mlp::block::<F64x8>(isa, shape, theta, x, y, n, r, jac, scratch)
}

/// [`mlp::block`] on AVX2 registers (four samples per vector).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn block_avx2(
    isa: Avx2,
    shape: Shape,
    theta: &[f64],
    x: &[&[f64]],
    y: &[f64],
    n: usize,
    r: &mut [f64],
    jac: Option<&mut [f64]>,
    scratch: &mut Scratch,
) {
    mlp::block::<F64x4>(isa, shape, theta, x, y, n, r, jac, scratch)
}

/// Samples stored by input column, padded to whole blocks (padding: inputs and target 0,
/// masked out of every sum).
#[derive(Clone)]
struct Columns {
    x: Vec<Vec<f64>>,
    y: Vec<f64>,
    /// Real samples.
    n: usize,
}

impl Columns {
    /// From row-major inputs (`k` per sample) and targets.
    fn new(x: &[f64], y: &[f64], k: usize) -> Columns {
        let n = y.len();
        let padded = n.div_ceil(BLOCK) * BLOCK;
        let mut cols = vec![vec![0.0; padded]; k];
        for (s, row) in x.chunks_exact(k).enumerate() {
            for (c, v) in row.iter().enumerate() {
                cols[c][s] = *v;
            }
        }
        let mut yy = y.to_vec();
        yy.resize(padded, 0.0);
        Columns { x: cols, y: yy, n }
    }

    /// Index ranges of the chunks.
    fn chunks(&self) -> Vec<std::ops::Range<usize>> {
        (0..self.n)
            .step_by(CHUNK)
            .map(|a| a..(a + CHUNK).min(self.n))
            .collect()
    }
}

/// The MLP's least-squares problem on normalised data.
pub struct MlpProblem {
    pub shape: Shape,
    train: Columns,
    val: Columns,
    /// (max − min)² / 4 of the target: normalised MSE → μ² units.
    scale: f64,
    isa: Isa,
}

impl MlpProblem {
    /// From normalised row-major inputs and targets.
    pub fn new(
        shape: Shape,
        x: Vec<f64>,
        y: Vec<f64>,
        vx: Vec<f64>,
        vy: Vec<f64>,
        scale: f64,
    ) -> Self {
        let k = shape.inputs;
        MlpProblem {
            shape,
            train: Columns::new(&x, &y, k),
            val: Columns::new(&vx, &vy, k),
            scale,
            isa: Isa::detect(),
        }
    }

    /// The same data for a network of another shape (same inputs).
    pub fn with_shape(&self, shape: Shape) -> MlpProblem {
        assert_eq!(shape.inputs, self.shape.inputs);
        MlpProblem {
            shape,
            train: self.train.clone(),
            val: self.val.clone(),
            scale: self.scale,
            isa: self.isa,
        }
    }

    /// Σ r² over `cols` (blocks in order, samples in order within a block).
    fn sse_of(&self, theta: &[f64], cols: &Columns) -> f64 {
        let parts: Vec<f64> = cols
            .chunks()
            .into_par_iter()
            .map(|range| {
                let mut scratch = Scratch::new(self.shape);
                let mut r = vec![0.0; BLOCK];
                let mut sse = 0.0;
                for a in range.clone().step_by(BLOCK) {
                    let n = BLOCK.min(range.end - a);
                    let xs: Vec<&[f64]> = cols.x.iter().map(|c| &c[a..a + BLOCK]).collect();
                    block_dispatch(
                        self.isa,
                        self.shape,
                        theta,
                        &xs,
                        &cols.y[a..a + BLOCK],
                        BLOCK,
                        &mut r,
                        None,
                        &mut scratch,
                    );
                    sse += r[..n].iter().map(|e| e * e).sum::<f64>();
                }
                sse
            })
            .collect();
        parts.iter().sum()
    }

    /// A Aᵀ, A = [J; rᵀ] ((P + 1) × (P + 1), row-major) over the samples of `range` (one
    /// chunk), and Σ r² summed in sample order (as [`MlpProblem::sse_of`] sums it, so that the
    /// current and a trial error compare like for like). A holds the whole chunk, so one matrix
    /// product serves it.
    fn gram_of_chunk(&self, theta: &[f64], range: std::ops::Range<usize>) -> (Vec<f64>, f64) {
        let p = self.shape.n_params();
        let cols = &self.train;
        let width = range.len().div_ceil(BLOCK) * BLOCK;
        let mut scratch = Scratch::new(self.shape);
        let mut a_mat = vec![0.0; (p + 1) * width];
        let (mut jac, mut r) = (vec![0.0; p * BLOCK], vec![0.0; BLOCK]);
        let mut sse = 0.0;
        for (b, a) in range.clone().step_by(BLOCK).enumerate() {
            let n = BLOCK.min(range.end - a);
            let xs: Vec<&[f64]> = cols.x.iter().map(|c| &c[a..a + BLOCK]).collect();
            block_dispatch(
                self.isa,
                self.shape,
                theta,
                &xs,
                &cols.y[a..a + BLOCK],
                BLOCK,
                &mut r,
                Some(&mut jac),
                &mut scratch,
            );
            sse += r[..n].iter().map(|e| e * e).sum::<f64>();
            // Padding samples stay zero in A: they contribute nothing.
            for q in 0..p {
                a_mat[q * width + b * BLOCK..q * width + b * BLOCK + n]
                    .copy_from_slice(&jac[q * BLOCK..q * BLOCK + n]);
            }
            a_mat[p * width + b * BLOCK..p * width + b * BLOCK + n].copy_from_slice(&r[..n]);
        }
        // The lower triangle of A Aᵀ: a symmetric rank-k update (faer, sequential).
        let mut gram = vec![0.0; (p + 1) * (p + 1)];
        let am = MatRef::from_row_major_slice(&a_mat, p + 1, width);
        matmul(
            MatMut::from_row_major_slice_mut(&mut gram, p + 1, p + 1),
            BlockStructure::TriangularLower,
            Accum::Replace,
            am,
            BlockStructure::Rectangular,
            am.transpose(),
            BlockStructure::Rectangular,
            1.0,
            Par::Seq,
        );
        (gram, sse)
    }
}

impl LeastSquares for MlpProblem {
    fn n_params(&self) -> usize {
        self.shape.n_params()
    }
    fn n_train(&self) -> usize {
        self.train.n
    }
    fn sse(&self, theta: &[f64]) -> f64 {
        self.sse_of(theta, &self.train)
    }
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        let p = self.shape.n_params();
        let grams: Vec<(Vec<f64>, f64)> = self
            .train
            .chunks()
            .into_par_iter()
            .map(|range| self.gram_of_chunk(theta, range))
            .collect();
        let mut total = vec![0.0; (p + 1) * (p + 1)];
        let mut sse = 0.0;
        for (g, s) in &grams {
            for (t, v) in total.iter_mut().zip(g) {
                *t += v;
            }
            sse += s;
        }
        // JᵀJ from the lower triangle (mirrored), Jᵀr from the last row.
        let q = p + 1;
        let jtj = (0..p * p)
            .map(|i| {
                let (a, b) = (i / p, i % p);
                total[a.max(b) * q + a.min(b)]
            })
            .collect();
        NormalEquations {
            jtj,
            jtr: (0..p).map(|a| total[p * q + a]).collect(),
            sse,
        }
    }
    fn validation_mse(&self, theta: &[f64]) -> Option<f64> {
        if self.val.n == 0 {
            return None;
        }
        Some(self.sse_of(theta, &self.val) / self.val.n as f64 * self.scale)
    }
    fn mse_scale(&self) -> f64 {
        self.scale
    }
}

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
    }
}

/// Trains the network on the valid estimates of `tables` with the pipeline's `[train]`
/// settings. `progress` is called after every epoch.
pub fn train_mlp(
    tables: &[RunTable],
    cfg: &TrainConfig,
    progress: Option<lm::Progress>,
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
    // The audit's samples: the same split with the speed (and temperature) of every sample.
    let full = if inputs.has_temperature() {
        InputSet::DvDdvVT
    } else {
        InputSet::DvDdvV
    };
    let k = full.count();
    let with_v = Dataset::build(tables, full, &cfg.split, cfg.decimate)?;
    trained.data = with_v
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
        .collect();
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
    progress: Option<lm::Progress>,
) -> Result<TrainedMlp, IdentifyError> {
    let settings = lm_settings(cfg);
    // LM: one problem (data scaled and laid out by column) for every start.
    let prepared = match cfg.trainer {
        Trainer::Lm => Some(Prepared::new(data, lm_shape(cfg))?),
        Trainer::Burn(_) => None,
    };
    let progress = std::sync::Mutex::new(progress);
    let runs: Vec<Result<TrainedMlp, IdentifyError>> = (0..cfg.starts as u64)
        .into_par_iter()
        .map(|k| {
            let p = if k == 0 {
                progress.lock().map(|mut p| p.take()).unwrap_or(None)
            } else {
                None
            };
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
    progress: Option<lm::Progress>,
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
        progress: Option<lm::Progress>,
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
    progress: Option<lm::Progress>,
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
    mut progress: Option<lm::Progress>,
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
        progress
            .as_mut()
            .map(|p| p.as_mut() as &mut dyn FnMut(&Epoch)),
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

/// The network of one leave-one-run-out fold scored on its held-out run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeldOut {
    pub run: String,
    /// Valid samples of the held-out run scored (every `decimate`-th of each axle).
    pub samples: usize,
    /// RMSE of the exported model (creep region, clamping and support included) against the
    /// run's own estimates, μ.
    pub rmse_mu: f64,
}

/// Leave-one-run-out validation (issue 15, point 4): for every run, the network trained as
/// `cfg` says — but from one start, without an ensemble — on the other runs, exported with the
/// pipeline's creep region, and scored against the held-out run's estimates (all axles,
/// every `cfg.decimate`-th sample). Folds run in parallel; results in run order. Fewer than
/// two runs: none.
pub fn leave_one_run_out(
    tables: &[RunTable],
    pipeline: &crate::Pipeline,
) -> Result<Vec<HeldOut>, IdentifyError> {
    if tables.len() < 2 {
        return Ok(Vec::new());
    }
    let mut cfg = pipeline.train.clone();
    cfg.starts = 1;
    cfg.ensemble = 1;
    (0..tables.len())
        .into_par_iter()
        .map(|i| {
            let others: Vec<RunTable> = tables
                .iter()
                .enumerate()
                .filter(|(k, _)| *k != i)
                .map(|(_, t)| t.clone())
                .collect();
            let mut t = train_mlp(&others, &cfg, None)?;
            t.reference_speed_mps = median_speed(&others);
            let creep = creep_spec(pipeline, t.reference_speed_mps)?;
            let provenance = crate::model::Provenance {
                inputs: vec![],
                pipeline: pipeline.source.clone(),
                pipeline_sha256: String::new(),
                seed: cfg.seed,
                crate_version: env!("CARGO_PKG_VERSION").into(),
                created: String::new(),
                generation: None,
            };
            let file = super::export::mlp_file(&t, creep, provenance, None)?;
            let model =
                crate::model::Model::named(file, "leave-one-run-out network").map_err(|e| {
                    IdentifyError::Data {
                        what: e.to_string(),
                        hint: "report this as a bug".into(),
                    }
                })?;
            Ok(held_out_score(&model, &tables[i], cfg.decimate))
        })
        .collect()
}

/// A model scored on a run it was not trained on: RMSE of the model (creep region, clamping and
/// support included) against the run's own estimates, every `decimate`-th valid sample of all
/// axles, at the run's ambient temperature.
pub fn held_out_score(model: &crate::model::Model, held: &RunTable, decimate: usize) -> HeldOut {
    let t_c = held.metadata.ambient_temperature_c.unwrap_or(f64::NAN);
    let (mut sq, mut n) = (0.0, 0usize);
    for k in (0..held.len()).step_by(decimate.max(1)) {
        let e = model.mu_vt(held.dv_mps[k], held.ddv_mps2[k], held.v_mps[k], t_c) - held.mu[k];
        sq += e * e;
        n += 1;
    }
    HeldOut {
        run: held.name.clone(),
        samples: n,
        rmse_mu: (sq / n.max(1) as f64).sqrt(),
    }
}

/// The contact patch of one wheel at the static wheel load for a pipeline (Hertz, seed 001
/// eq. 1–5; Kalker's c11, c22) and that load Q, N.
pub fn pipeline_patch(
    pipeline: &crate::Pipeline,
) -> Result<(crate::contact::polach::ContactPatch, f64), IdentifyError> {
    crate::vehicle::wheel_patch(&pipeline.vehicle, &pipeline.contact).map_err(|e| {
        IdentifyError::Data {
            what: format!("contact patch of the pipeline's [contact] section: {e}"),
            hint: "check [contact] and vehicle.wheel_radius_m in the pipeline file".into(),
        }
    })
}

/// The creep region of a model for a pipeline: Kalker's creep stiffness C = G a b c11 of one
/// wheel's Hertz patch (seed 001 eq. 1–5, 10–11) at the static wheel load Q.
pub fn creep_spec(
    pipeline: &crate::Pipeline,
    reference_speed_mps: f64,
) -> Result<crate::model::CreepSpec, IdentifyError> {
    let (patch, q) = pipeline_patch(pipeline)?;
    Ok(crate::model::CreepSpec {
        blend_mps: pipeline.train.creep_blend_mps,
        creep_stiffness_n: patch.g_pa * patch.a_m * patch.b_m * patch.c11,
        wheel_load_n: q,
        reference_speed_mps,
        reference_temperature_c: None,
    })
}

/// The runs that train a campaign's models: one rail condition (run metadata `condition`;
/// runs without it count as `unknown`). Adhesion on dry rail and on soap are different
/// curves, and a dry calibration run in a soap campaign would bend both the network and the
/// Polach fits.
#[derive(Debug)]
pub struct ConditionChoice {
    pub condition: String,
    pub used: Vec<RunTable>,
    /// (run, its condition) of the runs left out.
    pub skipped: Vec<(String, String)>,
}

/// The rail condition of a run, `unknown` without metadata.
pub fn run_condition(t: &RunTable) -> String {
    t.metadata
        .condition
        .clone()
        .unwrap_or_else(|| "unknown".into())
}

/// Keeps the runs of condition `wanted`, or without it of the most common condition (most
/// runs; a tie goes to the alphabetically first).
pub fn select_condition(
    tables: Vec<RunTable>,
    wanted: Option<&str>,
) -> Result<ConditionChoice, IdentifyError> {
    let mut counts: std::collections::BTreeMap<String, usize> = Default::default();
    for t in &tables {
        *counts.entry(run_condition(t)).or_default() += 1;
    }
    let condition = match wanted {
        Some(w) => {
            if !counts.contains_key(w) {
                return Err(IdentifyError::Data {
                    what: format!(
                        "train.condition = \"{w}\": no run has that condition (found {:?})",
                        counts.keys().collect::<Vec<_>>()
                    ),
                    hint: "set train.condition to one of the conditions found, or leave it out"
                        .into(),
                });
            }
            w.to_string()
        }
        None => counts
            .iter()
            .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(a.0)))
            .map(|(c, _)| c.clone())
            .ok_or_else(|| IdentifyError::Data {
                what: "no runs to train on".into(),
                hint: "give estimates tables or run logs".into(),
            })?,
    };
    let (used, other): (Vec<RunTable>, Vec<RunTable>) = tables
        .into_iter()
        .partition(|t| run_condition(t) == condition);
    Ok(ConditionChoice {
        condition,
        used,
        skipped: other
            .iter()
            .map(|t| (t.name.clone(), run_condition(t)))
            .collect(),
    })
}

/// Median vehicle speed over the valid samples of `tables`, m/s (10 m/s when there are none).
pub fn median_speed(tables: &[RunTable]) -> f64 {
    let mut v: Vec<f64> = tables
        .iter()
        .flat_map(|t| t.v_mps.iter().copied())
        .filter(|v| v.is_finite())
        .collect();
    if v.is_empty() {
        return 10.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// UTC time as RFC 3339 (`SOURCE_DATE_EPOCH` overrides the clock, for reproducible files).
pub fn utc_now_rfc3339() -> String {
    let secs = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|s| s.trim().parse::<i64>().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs() as i64)
                .unwrap_or(0)
        });
    let days = secs.div_euclid(86_400);
    let rem = secs.rem_euclid(86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// `<name>.leave-one-run-out.json`: the network's held-out scores and the generation that
/// wrote them.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct HeldOutFile {
    #[serde(default)]
    pub generation: Option<String>,
    pub runs: Vec<HeldOut>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rfc3339_dates() {
        std::env::set_var("SOURCE_DATE_EPOCH", "1763692800");
        assert_eq!(utc_now_rfc3339(), "2025-11-21T02:40:00Z");
        std::env::set_var("SOURCE_DATE_EPOCH", "951782400");
        assert_eq!(utc_now_rfc3339(), "2000-02-29T00:00:00Z");
        std::env::remove_var("SOURCE_DATE_EPOCH");
    }
}
