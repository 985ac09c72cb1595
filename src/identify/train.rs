//! Training the seed 002 network: dataset → mapminmax → Nguyen–Widrow → trainlm.

use rayon::prelude::*;

use super::dataset::{Dataset, MapMinMax, RunTable};
use super::lm::{
    self, Epoch, LeastSquares, LevenbergMarquardt, LmSettings, NormalEquations, StopReason,
};
use super::mlp::{self, Shape};
use super::IdentifyError;
use super::InputSet;
use crate::config::TrainConfig;

/// Samples per chunk when accumulating JᵀJ: fixed, so the sums (chunk results added in order)
/// do not depend on the number of threads.
const CHUNK: usize = 2048;

/// The MLP's least-squares problem on normalised data.
pub struct MlpProblem {
    pub shape: Shape,
    x: Vec<f64>,
    y: Vec<f64>,
    vx: Vec<f64>,
    vy: Vec<f64>,
    /// (max − min)² / 4 of the target: normalised MSE → μ² units.
    scale: f64,
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
        MlpProblem {
            shape,
            x,
            y,
            vx,
            vy,
            scale,
        }
    }

    fn sse_of(&self, theta: &[f64], x: &[f64], y: &[f64]) -> f64 {
        let k = self.shape.inputs;
        let parts: Vec<f64> = x
            .par_chunks(CHUNK * k)
            .zip(y.par_chunks(CHUNK))
            .map(|(xc, yc)| {
                xc.chunks_exact(k)
                    .zip(yc)
                    .map(|(xi, yi)| {
                        let r = mlp::forward(self.shape, theta, xi) - yi;
                        r * r
                    })
                    .sum::<f64>()
            })
            .collect();
        parts.iter().sum()
    }
}

impl LeastSquares for MlpProblem {
    fn n_params(&self) -> usize {
        self.shape.n_params()
    }
    fn n_train(&self) -> usize {
        self.y.len()
    }
    fn sse(&self, theta: &[f64]) -> f64 {
        self.sse_of(theta, &self.x, &self.y)
    }
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        let p = self.shape.n_params();
        let k = self.shape.inputs;
        let parts: Vec<NormalEquations> = self
            .x
            .par_chunks(CHUNK * k)
            .zip(self.y.par_chunks(CHUNK))
            .map(|(xc, yc)| {
                let mut jtj = vec![0.0; p * p];
                let mut jtr = vec![0.0; p];
                let mut sse = 0.0;
                let mut g = vec![0.0; p];
                for (xi, yi) in xc.chunks_exact(k).zip(yc) {
                    let r = mlp::forward_grad(self.shape, theta, xi, &mut g) - yi;
                    sse += r * r;
                    for a in 0..p {
                        let ga = g[a];
                        jtr[a] += ga * r;
                        let row = &mut jtj[a * p..a * p + a + 1];
                        for (j, gb) in row.iter_mut().zip(&g[..=a]) {
                            *j += ga * gb;
                        }
                    }
                }
                NormalEquations { jtj, jtr, sse }
            })
            .collect();
        let mut total = NormalEquations {
            jtj: vec![0.0; p * p],
            jtr: vec![0.0; p],
            sse: 0.0,
        };
        for part in &parts {
            for (t, v) in total.jtj.iter_mut().zip(&part.jtj) {
                *t += v;
            }
            for (t, v) in total.jtr.iter_mut().zip(&part.jtr) {
                *t += v;
            }
            total.sse += part.sse;
        }
        // Mirror the lower triangle.
        for a in 0..p {
            for b in 0..a {
                total.jtj[b * p + a] = total.jtj[a * p + b];
            }
        }
        total
    }
    fn validation_mse(&self, theta: &[f64]) -> Option<f64> {
        if self.vy.is_empty() {
            return None;
        }
        Some(self.sse_of(theta, &self.vx, &self.vy) / self.vy.len() as f64 * self.scale)
    }
    fn mse_scale(&self) -> f64 {
        self.scale
    }
}

/// A trained network with everything the model file needs.
#[derive(Debug, Clone)]
pub struct TrainedMlp {
    pub inputs: InputSet,
    pub shape: Shape,
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
    pub seed: u64,
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
            .reverse(0, mlp::forward(self.shape, &self.theta, &xn))
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
    }
}

/// Trains the network on the valid estimates of `tables` with the pipeline's `[train]`
/// settings. `progress` is called after every epoch.
pub fn train_mlp(
    tables: &[RunTable],
    cfg: &TrainConfig,
    progress: Option<lm::Progress>,
) -> Result<TrainedMlp, IdentifyError> {
    let inputs = if cfg.with_speed {
        InputSet::DvDdvV
    } else {
        InputSet::DvDdv
    };
    let data = Dataset::build(tables, inputs, &cfg.split, cfg.decimate)?;
    train_on(&data, cfg.hidden, cfg.seed, lm_settings(cfg), progress)
}

/// Trains on a prepared dataset.
pub fn train_on(
    data: &Dataset,
    hidden: usize,
    seed: u64,
    settings: LmSettings,
    progress: Option<lm::Progress>,
) -> Result<TrainedMlp, IdentifyError> {
    let k = data.inputs.count();
    let shape = Shape { inputs: k, hidden };
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
    let x_norm = MapMinMax::fit(&data.train_x, k);
    let y_norm = MapMinMax::fit(&data.train_y, 1);
    let mut x = data.train_x.clone();
    x_norm.apply(&mut x);
    let mut y = data.train_y.clone();
    y_norm.apply(&mut y);
    let mut vx = data.val_x.clone();
    x_norm.apply(&mut vx);
    let mut vy = data.val_y.clone();
    y_norm.apply(&mut vy);
    let (g, _) = y_norm.gain_offset(0);
    let scale = 1.0 / (g * g);
    let problem = MlpProblem::new(shape, x, y, vx, vy, scale);
    let theta0 = mlp::nguyen_widrow(shape, seed);
    let mut solver = LevenbergMarquardt::new(settings);
    if let Some(p) = progress {
        solver = solver.with_progress(p);
    }
    let (solver, problem) =
        lm::run(problem, solver, theta0).map_err(|e| IdentifyError::Solver {
            fit: "network training".into(),
            source: e.into(),
        })?;
    let theta = solver.best().expect("set from the first epoch").to_vec();
    let train_mse = problem.sse(&theta) / problem.n_train() as f64 * scale;
    let val_mse = problem.validation_mse(&theta).unwrap_or(f64::NAN);
    let mut domain = Vec::with_capacity(k);
    for c in 0..k {
        let (lo, hi) = data
            .train_x
            .iter()
            .skip(c)
            .step_by(k)
            .chain(data.val_x.iter().skip(c).step_by(k))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            });
        domain.push((lo, hi));
    }
    Ok(TrainedMlp {
        inputs: data.inputs,
        shape,
        theta,
        x_norm,
        y_norm,
        history: solver.history().to_vec(),
        stop: solver.stop_reason().unwrap_or(StopReason::Epochs),
        n_train: data.n_train(),
        n_val: data.n_val(),
        train_mse,
        val_mse,
        domain,
        reference_speed_mps: f64::NAN,
        seed,
        settings,
    })
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
