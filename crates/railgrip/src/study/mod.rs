//! `railgrip study`: what accuracy costs in time, measured on the user's own
//! campaign. A plan ([`plan`], bundled `pipelines/study.toml`) declares grids of cells — model
//! family and size, training settings, conditioning — each a complete pipeline. For every cell
//! the campaign's runs are estimated with the cell's conditioning (shared between cells that
//! differ only in `[train]`, and reused across invocations like `railgrip run`'s), the model is
//! trained on the runs of one rail condition except the held-out ones, and measured:
//!
//! - training wall time, s (cells train side by side on `--jobs` threads; with 1 job alone);
//! - evaluation time per μ, ns: the Rust evaluator's single call and batch
//!   ([`crate::model::Model`]), and for networks a plain loop over the file's layers with the
//!   C library's tanh against the same loop with the evaluators' fast tanh, with the largest
//!   difference in μ between the two (what "exact vs fast tanh" costs and buys). Timed after
//!   all training, one cell at a time, best of 5 repetitions of ≥ 20 ms;
//! - model file size, bytes;
//! - RMSE against the held-out runs' own estimates (μ; [`crate::identify::held_out_score`]);
//! - when the held-out runs carry truth (`<stem>.truth.parquet` beside a log in a folder, as
//!   `railgrip simulate` writes it), the supported-cell error against the true law
//!   ([`crate::score`]: RMSE over the cells with ≥ 20 truth samples of one axle).
//!
//! Cells are keyed by a SHA-256 of everything that decides their result (railgrip version,
//! family, the cell's pipeline text, the runs' input hashes, the held-out runs, the number of
//! timing points); a finished cell's result is a file `cells/<key>.json` and is reused, so an
//! interrupted study resumes. Results but the times are deterministic for the same inputs.

mod cells;
pub mod html;
pub mod ladder;
pub mod plan;
mod runs;
mod timing;

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub use plan::{CellSpec, Plan, DEFAULT_PLAN_NAME, DEFAULT_PLAN_TOML};

use crate::campaign::{sources_all, CampaignError};
pub use crate::outdir::StudyPaths;
use crate::table::{Cell, CsvText};

/// Why a study could not run.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    #[error("{file}: {what}. Hint: {hint}")]
    Plan {
        file: String,
        what: String,
        hint: String,
    },
    #[error("{what}. Hint: {hint}")]
    Refused { what: String, hint: String },
    #[error("{what}. Hint: {hint}")]
    Data { what: String, hint: String },
    #[error(transparent)]
    Campaign(#[from] CampaignError),
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// How [`study`] goes about it.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Cells trained side by side (None: one per core).
    pub jobs: Option<usize>,
    /// Run a plan over its cell or time limit.
    pub force: bool,
    /// The recommendation's budgets: evaluation ns per μ (single call) and training s.
    pub budget_ns: Option<f64>,
    pub budget_train_s: Option<f64>,
}

/// What a study reports while it works (cells finish on worker threads).
pub enum Event<'a> {
    /// Runs are being estimated for `conditionings` settings.
    Estimating { conditionings: usize, runs: usize },
    /// The cells: how many, how many reused, the estimated training time of the rest, s.
    Planned {
        cells: usize,
        reused: usize,
        estimated_s: f64,
    },
    /// A cell was trained (or failed).
    Trained(&'a CellResult),
    /// A cell's evaluators were timed.
    Timed(&'a CellResult),
}

pub use crate::progress::{Progress, Quiet};

/// What receives a study's [`Event`]s: any [`Progress`] of them.
pub type StudyProgress<'p> = &'p dyn for<'a> Progress<Event<'a>>;

/// Evaluation times of one model file, ns per μ.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EvalTiming {
    /// `Model::mu_vt`, one call per μ.
    pub single_ns: f64,
    /// `Model::mu_batch_t` over all timing points.
    pub batch_ns: f64,
    /// Networks: the network alone in a plain scalar loop over the file's layers (no
    /// allocation, no creep region or support blend) with the C library's tanh (`f64::tanh`)
    /// — what a hand-written evaluator of the JSON file costs …
    pub plain_libm_ns: Option<f64>,
    /// … and the largest |Δμ| of that loop between the C library's tanh and the evaluators'
    /// fast one (`model::tanh_fast`) over the timing points: what the fast tanh costs in
    /// accuracy.
    pub libm_max_diff: Option<f64>,
}

/// One cell's result (`cells/<key>.json`, a row of `study.csv`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CellResult {
    pub key: String,
    pub name: String,
    pub group: String,
    /// The model the cell fits: its grid's `train.model`, the
    /// [`crate::identify::ModelFamily::name`] of its family (`model` in the files; cells of
    /// earlier releases said `family`).
    #[serde(rename = "model", alias = "family")]
    pub family: String,
    /// Pipeline keys the cell sets, as TOML values.
    pub settings: Vec<(String, String)>,
    /// `2-10-1` for a network, `polach` / `polach+k(T)`.
    pub architecture: String,
    pub parameters: usize,
    /// Samples the training saw (networks: training + validation; Polach: the pooled fit's).
    pub train_samples: usize,
    pub epochs: usize,
    /// None when the cell failed.
    pub train_s: Option<f64>,
    /// The plan's estimate of `train_s` before it ran.
    pub estimated_train_s: f64,
    pub file_bytes: u64,
    pub held_out_rmse: Option<f64>,
    pub held_out_samples: usize,
    pub truth_rmse: Option<f64>,
    pub truth_cells: Option<usize>,
    /// Supported truth cells where the model predicts μ < 0.
    pub truth_negative_cells: Option<usize>,
    pub eval: Option<EvalTiming>,
    /// Why the cell has no model.
    pub error: Option<String>,
}

impl CellResult {
    pub fn ok(&self) -> bool {
        self.error.is_none()
    }
    /// The error the study ranks by: against the truth where every cell has it, else held-out.
    pub fn accuracy(&self, by_truth: bool) -> f64 {
        let e = if by_truth {
            self.truth_rmse
        } else {
            self.held_out_rmse
        };
        e.unwrap_or(f64::INFINITY)
    }
}

/// What [`study`] did (`study.json`).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Outcome {
    pub archive: String,
    pub plan: String,
    pub pipeline: String,
    pub condition: String,
    pub train_runs: Vec<String>,
    pub held_out: Vec<String>,
    /// Whether accuracy is the truth error (every held-out run has truth) or the held-out RMSE.
    pub by_truth: bool,
    pub jobs: usize,
    pub budget_ns: Option<f64>,
    pub budget_train_s: Option<f64>,
    pub cells: Vec<CellResult>,
    /// `[[simulator]]` and `[[contact]]` rows.
    pub simulator: Vec<ladder::SimRow>,
    pub contact: Vec<ladder::ContactRow>,
    /// Keys of the cells on the Pareto fronts (accuracy vs training time, vs single-call ns).
    pub pareto_train: Vec<String>,
    pub pareto_eval: Vec<String>,
    /// The most accurate cell within the budgets.
    pub recommended: Option<String>,
    pub notes: Vec<String>,
    /// Wall time of this invocation, s (the only field that differs between identical runs
    /// besides the cells' times).
    pub wall_s: f64,
}

fn write_text(path: &Path, text: &str) -> Result<(), StudyError> {
    crate::atomic::write_atomically(path, |w| w.write_all(text.as_bytes())).map_err(|source| {
        StudyError::Write {
            path: path.to_path_buf(),
            source,
        }
    })
}

/// Runs the study of `plan` over the campaign at `archive` into `out`: every conditioning's
/// estimates, the training and held-out runs, the cells trained side by side and timed one at a
/// time, the simulator and contact rows, the Pareto fronts and the recommendation, written as
/// `study.json`, `study.csv` and `study.html`.
pub fn run(
    archive: &Path,
    plan: &Plan,
    out: &Path,
    options: Options,
    progress: StudyProgress<'_>,
) -> Result<Outcome, StudyError> {
    let t_all = Instant::now();
    check_plan(plan, options.force)?;
    let paths = StudyPaths {
        root: out.to_path_buf(),
    };
    for d in [paths.root.clone(), paths.cells()] {
        std::fs::create_dir_all(&d).map_err(|source| StudyError::Write { path: d, source })?;
    }
    let (logs, skipped) = sources_all(archive, Some(out))?;
    let mut notes: Vec<String> = skipped
        .iter()
        .map(|s| format!("{}: skipped ({})", s.path.display(), s.reason))
        .collect();
    let pool = crate::parallel::pool(options.jobs).map_err(CampaignError::from)?;

    // 1. Every conditioning's estimates (reused from earlier studies when unchanged).
    let conditionings = runs::Conditionings::of(plan);
    progress.event(Event::Estimating {
        conditionings: conditionings.pipelines.len(),
        runs: logs.len(),
    });
    let estimated = runs::estimate(&conditionings, &logs, &paths, &pool, &mut notes)?;
    // 2. The rail condition, the training and held-out runs, their truth.
    let chosen = runs::choose(plan, &estimated[0], &logs, &mut notes)?;
    let splits = runs::split(estimated, &chosen);
    let points = timing::timing_points(&splits[0].held, plan.eval_points);
    if points.dv.is_empty() {
        return Err(StudyError::Data {
            what: format!(
                "the held-out runs {} have no valid samples to time the evaluators on",
                chosen.held_out.join(", ")
            ),
            hint: "hold out runs with valid estimates (study.held_out)".into(),
        });
    }
    // 3. The cells: keyed, reused or trained side by side.
    let keyed = cells::keyed(plan, &conditionings, &splits, &chosen);
    let results = cells::train(
        plan,
        &keyed,
        &conditionings,
        &splits,
        &chosen,
        &paths,
        &pool,
        options.force,
        progress,
    )?;
    // 4. The evaluators timed one cell at a time (nothing else running).
    let cells = timing::time_cells(&keyed, results, &paths, &points, progress)?;
    // 5. The simulator and contact rows (timed, so alone too).
    let simulator = ladder::sim_rows(&plan.simulator)?;
    let contact = ladder::contact_rows(&plan.contact, &plan.base_pipeline)?;
    // 6. Fronts, recommendation, outputs.
    let by_truth = chosen.by_truth;
    let pareto_train = pareto(&cells, by_truth, |c| c.train_s);
    let pareto_eval = pareto(&cells, by_truth, |c| c.eval.as_ref().map(|e| e.single_ns));
    let recommended = recommend(&cells, by_truth, &options);
    if recommended.is_none() {
        notes.push("no cell meets the budgets: none recommended".into());
    }
    let outcome = Outcome {
        archive: archive.display().to_string(),
        plan: plan.source.clone(),
        pipeline: plan.base.clone(),
        condition: chosen.condition,
        train_runs: chosen.train,
        held_out: chosen.held_out,
        by_truth,
        jobs: pool.current_num_threads(),
        budget_ns: options.budget_ns,
        budget_train_s: options.budget_train_s,
        cells,
        simulator,
        contact,
        pareto_train,
        pareto_eval,
        recommended,
        notes,
        wall_s: t_all.elapsed().as_secs_f64(),
    };
    write_text(
        &paths.json(),
        &(serde_json::to_string_pretty(&outcome).expect("outcome serialises") + "\n"),
    )?;
    write_text(&paths.csv(), &csv(&outcome))?;
    write_text(&paths.html(), &html::render(&outcome))?;
    Ok(outcome)
}

/// Refuses a plan over its cell limit (unless `force`) and one whose cells train on different
/// rail conditions (a study compares cells on one condition, so the held-out runs are the same
/// for all).
fn check_plan(plan: &Plan, force: bool) -> Result<(), StudyError> {
    if plan.cells.len() > plan.max_cells && !force {
        return Err(StudyError::Refused {
            what: format!(
                "{}: the plan has {} cells, more than study.max_cells = {}",
                plan.source,
                plan.cells.len(),
                plan.max_cells
            ),
            hint: "narrow the grids, raise study.max_cells, or pass --force".into(),
        });
    }
    let wanted = &plan.cells[0].pipeline.train.condition;
    if let Some(c) = plan
        .cells
        .iter()
        .find(|c| &c.pipeline.train.condition != wanted)
    {
        return Err(StudyError::Plan {
            file: plan.source.clone(),
            what: format!(
                "cell \"{}\" trains on condition {:?}, cell \"{}\" on {:?}: a study compares cells on one rail condition",
                plan.cells[0].name(),
                wanted,
                c.name(),
                c.pipeline.train.condition
            ),
            hint: "vary train.condition in separate studies (one --out each)".into(),
        });
    }
    Ok(())
}

/// Keys of the cells no other cell beats in both cost and accuracy, cheapest first.
fn pareto(
    cells: &[CellResult],
    by_truth: bool,
    cost: impl Fn(&CellResult) -> Option<f64>,
) -> Vec<String> {
    let mut pts: Vec<(f64, f64, &str)> = cells
        .iter()
        .filter(|c| c.ok())
        .filter_map(|c| Some((cost(c)?, c.accuracy(by_truth), c.key.as_str())))
        .filter(|(x, y, _)| x.is_finite() && y.is_finite())
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut best = f64::INFINITY;
    let mut front = Vec::new();
    for (_, y, k) in pts {
        if y < best {
            best = y;
            front.push(k.to_string());
        }
    }
    front
}

/// The most accurate cell within the budgets (training s, single-call ns per μ).
fn recommend(cells: &[CellResult], by_truth: bool, options: &Options) -> Option<String> {
    cells
        .iter()
        .filter(|c| c.ok())
        .filter(|c| {
            options
                .budget_train_s
                .is_none_or(|b| c.train_s.is_some_and(|t| t <= b))
        })
        .filter(|c| {
            options
                .budget_ns
                .is_none_or(|b| c.eval.as_ref().is_some_and(|e| e.single_ns <= b))
        })
        .filter(|c| c.accuracy(by_truth).is_finite())
        .min_by(|a, b| a.accuracy(by_truth).total_cmp(&b.accuracy(by_truth)))
        .map(|c| c.key.clone())
}

/// `study.csv`: one row per cell.
pub fn csv(o: &Outcome) -> String {
    let mut t = CsvText::new(&[
        "key",
        "group",
        "model",
        "name",
        "architecture",
        "parameters",
        "train_samples",
        "epochs",
        "train_s",
        "estimated_train_s",
        "single_ns",
        "batch_ns",
        "plain_libm_ns",
        "libm_max_diff",
        "file_bytes",
        "held_out_rmse",
        "held_out_samples",
        "truth_rmse",
        "truth_cells",
        "truth_negative_cells",
        "pareto_train",
        "pareto_eval",
        "recommended",
        "error",
    ]);
    let count = |n: usize| Cell::Count(Some(n as u64));
    for c in &o.cells {
        let e = c.eval.as_ref();
        t.row(&[
            Cell::Name(&c.key),
            Cell::Text(&c.group),
            Cell::Name(&c.family),
            Cell::Text(&c.name),
            Cell::Name(&c.architecture),
            count(c.parameters),
            count(c.train_samples),
            count(c.epochs),
            Cell::Real(c.train_s),
            Cell::Real(Some(c.estimated_train_s)),
            Cell::Real(e.map(|e| e.single_ns)),
            Cell::Real(e.map(|e| e.batch_ns)),
            Cell::Real(e.and_then(|e| e.plain_libm_ns)),
            Cell::Real(e.and_then(|e| e.libm_max_diff)),
            Cell::Count(Some(c.file_bytes)),
            Cell::Real(c.held_out_rmse),
            count(c.held_out_samples),
            Cell::Real(c.truth_rmse),
            Cell::Count(c.truth_cells.map(|n| n as u64)),
            Cell::Count(c.truth_negative_cells.map(|n| n as u64)),
            Cell::Flag(o.pareto_train.contains(&c.key)),
            Cell::Flag(o.pareto_eval.contains(&c.key)),
            Cell::Flag(o.recommended.as_deref() == Some(c.key.as_str())),
            Cell::Text(c.error.as_deref().unwrap_or("")),
        ]);
    }
    t.into_text()
}
