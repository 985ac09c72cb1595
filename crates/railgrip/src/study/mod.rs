//! `railgrip study` (issue 20): what accuracy costs in time, measured on the user's own
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

pub mod html;
pub mod ladder;
pub mod plan;

use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

pub use plan::{CellSpec, Plan, DEFAULT_PLAN_NAME, DEFAULT_PLAN_TOML};

use crate::campaign::{process_run, sources_all, CampaignError, OutDir, RunRecord};
use crate::identify::dataset::RunTable;
use crate::identify::family::{FitData, TemperatureNeed};
use crate::identify::{held_out_score, select_condition};
use crate::ingest::LogSource;
use crate::model::{Model, ModelFile, Provenance};
pub use crate::outdir::StudyPaths;
use crate::score::{score, Grid, Sample};

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
    /// The [`crate::identify::ModelFamily::name`] of the cell's family.
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

/// The estimated runs of one conditioning.
struct Estimated {
    records: Vec<RunRecord>,
    tables: Vec<RunTable>,
}

/// [`Estimated`] split into the runs the cells train on and the held-out runs.
struct Split {
    records: Vec<RunRecord>,
    train: Vec<RunTable>,
    held: Vec<RunTable>,
}

/// Runs the study of `plan` over the campaign at `archive` into `out`.
pub fn run(
    archive: &Path,
    plan: &Plan,
    out: &Path,
    options: Options,
    progress: StudyProgress<'_>,
) -> Result<Outcome, StudyError> {
    let t_all = Instant::now();
    if plan.cells.len() > plan.max_cells && !options.force {
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
    // One rail condition for every cell: the held-out runs are the same for all.
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
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.jobs.unwrap_or(0))
        .build()
        .map_err(CampaignError::from)?;
    let jobs = pool.current_num_threads();

    // 1. Every conditioning's estimates (reused from earlier studies when unchanged).
    let mut conds: BTreeMap<String, usize> = BTreeMap::new();
    let mut cond_of = Vec::new();
    let mut cond_pipes = Vec::new();
    for c in &plan.cells {
        let key = crate::hash::sha256_bytes(c.conditioning.text.as_bytes())[..16].to_string();
        let next = conds.len();
        let i = *conds.entry(key.clone()).or_insert_with(|| {
            cond_pipes.push((key, c.conditioning.clone()));
            next
        });
        cond_of.push(i);
    }
    progress.event(Event::Estimating {
        conditionings: cond_pipes.len(),
        runs: logs.len(),
    });
    let mut estimated = Vec::new();
    for (key, pipe) in &cond_pipes {
        let od = OutDir::new(paths.conditioning(key));
        std::fs::create_dir_all(od.runs()).map_err(|source| StudyError::Write {
            path: od.runs(),
            source,
        })?;
        let results: Vec<(RunRecord, Option<RunTable>)> = pool.install(|| {
            logs.par_iter()
                .map(|(name, src)| process_run(src, name, &od, pipe, false))
                .collect()
        });
        let (records, tables): (Vec<_>, Vec<_>) = results.into_iter().unzip();
        for r in records.iter().filter(|r| !r.ok()) {
            let note = format!(
                "{}: not estimated ({})",
                r.run,
                r.error.as_deref().unwrap_or("failed")
            );
            if !notes.contains(&note) {
                notes.push(note);
            }
        }
        estimated.push(Estimated {
            records,
            tables: tables.into_iter().flatten().collect(),
        });
    }

    // 2. The rail condition, the training and the held-out runs (from the first
    // conditioning; every conditioning estimates the same logs).
    let first = &estimated[0];
    let choice = select_condition(
        first.tables.clone(),
        plan.cells[0].pipeline.train.condition.as_deref(),
    )
    .map_err(|e| StudyError::Data {
        what: e.to_string(),
        hint: "give a campaign with estimable runs".into(),
    })?;
    let condition = choice.condition.clone();
    let mut names: Vec<String> = choice.used.iter().map(|t| t.name.clone()).collect();
    names.sort();
    // Inputs the families need.
    let temps: Vec<(String, Option<f64>)> = choice
        .used
        .iter()
        .map(|t| (t.name.clone(), t.metadata.ambient_temperature_c))
        .collect();
    let missing: Vec<&str> = temps
        .iter()
        .filter(|(_, t)| t.is_none())
        .map(|(n, _)| n.as_str())
        .collect();
    let mut distinct: Vec<f64> = temps.iter().filter_map(|(_, t)| *t).collect();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    for c in &plan.cells {
        let need = c.family.temperatures(&c.pipeline.train);
        if need != TemperatureNeed::None && !missing.is_empty() {
            return Err(StudyError::Plan {
                file: plan.source.clone(),
                what: format!(
                    "cell \"{}\" needs the runs' ambient temperature, which {} lack(s)",
                    c.name(),
                    missing.join(", ")
                ),
                hint: "add ambient_temperature_c to those runs' metadata, or drop the 4-input and polach_kt cells from the plan".into(),
            });
        }
        if need == TemperatureNeed::TwoOrMore && distinct.len() < 2 {
            return Err(StudyError::Plan {
                file: plan.source.clone(),
                what: format!(
                    "cell \"{}\" fits k(T), but the runs of condition {condition} were all at one ambient temperature",
                    c.name()
                ),
                hint: "give runs at two or more temperatures, or drop the polach_kt cells".into(),
            });
        }
    }
    let held_out: Vec<String> = match &plan.held_out {
        Some(h) => {
            for n in h {
                if !names.contains(n) {
                    return Err(StudyError::Plan {
                        file: plan.source.clone(),
                        what: format!("study.held_out names {n}, which is not an estimated run of condition {condition}"),
                        hint: format!("the runs are {}", names.join(", ")),
                    });
                }
            }
            h.clone()
        }
        None => {
            let every_third: Vec<String> = names.iter().skip(2).step_by(3).cloned().collect();
            match (every_third.is_empty(), names.last()) {
                (true, Some(last)) if names.len() >= 2 => vec![last.clone()],
                _ => every_third,
            }
        }
    };
    let train_runs: Vec<String> = names
        .iter()
        .filter(|n| !held_out.contains(n))
        .cloned()
        .collect();
    if held_out.is_empty() || train_runs.is_empty() {
        return Err(StudyError::Data {
            what: format!(
                "condition {condition} has {} estimated run(s) ({}): a study needs at least one to train on and one held out",
                names.len(),
                names.join(", ")
            ),
            hint: "give a campaign with three or more runs of one rail condition, or set study.held_out".into(),
        });
    }
    // Truth of the held-out runs (folders only).
    let mut truth: Vec<Sample> = Vec::new();
    let mut truth_runs = 0usize;
    for (k, run) in held_out.iter().enumerate() {
        let src = logs.iter().find(|(n, _)| n == run).map(|(_, s)| s);
        let t_c = temps
            .iter()
            .find(|(n, _)| n == run)
            .and_then(|(_, t)| *t)
            .unwrap_or(f64::NAN);
        if let Some(LogSource::File(p)) = src {
            let tp = truth_path(p);
            if tp.is_file() {
                let samples =
                    crate::sim::read_truth_samples(&tp, t_c).map_err(|e| StudyError::Data {
                        what: e.to_string(),
                        hint:
                            "remove the broken truth table or write it again with railgrip simulate"
                                .into(),
                    })?;
                // Each run's axles numbered apart, so a cell never averages two runs.
                let offset = (4 * k).min(250) as u8;
                truth.extend(samples.into_iter().map(|s| Sample {
                    axle: s.axle + offset,
                    ..s
                }));
                truth_runs += 1;
            }
        }
    }
    let by_truth = truth_runs == held_out.len();
    if truth_runs > 0 && !by_truth {
        notes.push(format!(
            "{truth_runs} of {} held-out runs carry truth: cells are ranked by the held-out RMSE",
            held_out.len()
        ));
    }

    // Each conditioning's tables split once into training and held-out runs (the others,
    // of other rail conditions, dropped).
    let splits: Vec<Split> = estimated
        .into_iter()
        .map(|e| {
            let (mut train, mut held) = (Vec::new(), Vec::new());
            for t in e.tables {
                if train_runs.contains(&t.name) {
                    train.push(t);
                } else if held_out.contains(&t.name) {
                    held.push(t);
                }
            }
            Split {
                records: e.records,
                train,
                held,
            }
        })
        .collect();
    let points = timing_points(&splits[0].held, plan.eval_points);
    if points.dv.is_empty() {
        return Err(StudyError::Data {
            what: format!(
                "the held-out runs {} have no valid samples to time the evaluators on",
                held_out.join(", ")
            ),
            hint: "hold out runs with valid estimates (study.held_out)".into(),
        });
    }
    // 3. Keys, reuse, estimate.
    let run_hashes = |e: &Split| -> String {
        e.records
            .iter()
            .map(|r| format!("{} {}\n", r.run, r.input_sha256))
            .collect()
    };
    let specs: Vec<(usize, &CellSpec, String)> = plan
        .cells
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let text = format!(
                "railgrip {}\nfamily {}\n{}\nruns\n{}held out {:?}\ncondition {condition}\ntiming points {}\n",
                env!("CARGO_PKG_VERSION"),
                c.family.name(),
                c.pipeline.text,
                run_hashes(&splits[cond_of[i]]),
                held_out,
                plan.eval_points
            );
            (i, c, crate::hash::sha256_bytes(text.as_bytes())[..16].to_string())
        })
        .collect();
    let mut results: Vec<Option<CellResult>> = specs
        .iter()
        .map(|(_, _, key)| read_result(&paths, key))
        .collect();
    let samples_of = |i: usize| -> usize { splits[cond_of[i]].train.iter().map(|t| t.len()).sum() };
    let estimates: Vec<f64> = specs
        .iter()
        .map(|(i, c, _)| {
            c.family
                .estimated_seconds(&c.pipeline.train, samples_of(*i))
        })
        .collect();
    let pending_s: f64 = specs
        .iter()
        .zip(&results)
        .zip(&estimates)
        .filter(|((_, r), _)| r.is_none())
        .map(|(_, e)| *e)
        .sum::<f64>()
        / jobs as f64;
    let reused = results.iter().filter(|r| r.is_some()).count();
    progress.event(Event::Planned {
        cells: specs.len(),
        reused,
        estimated_s: pending_s,
    });
    if pending_s > plan.max_minutes * 60.0 && !options.force {
        return Err(StudyError::Refused {
            what: format!(
                "{}: the {} cells to train are estimated at {:.1} min on {jobs} thread(s), more than study.max_minutes = {}",
                plan.source,
                specs.len() - reused,
                pending_s / 60.0,
                plan.max_minutes
            ),
            hint: "narrow the grids, raise study.max_minutes, or pass --force (finished cells are kept and reused)".into(),
        });
    }

    // 4. Train the missing cells side by side; each result is saved as it finishes.
    let fresh: Vec<(usize, CellResult)> = pool.install(|| {
        specs
            .par_iter()
            .filter(|(i, _, _)| results[*i].is_none())
            .map(|(i, c, key)| {
                let e = &splits[cond_of[*i]];
                let mut r = train_cell(c, key, &e.train, &e.held, &paths, &truth, by_truth);
                r.estimated_train_s = estimates[*i];
                // Saved without timings: a study killed before them retimes only.
                let _ = write_text(&paths.cell(key), &to_json(&r));
                progress.event(Event::Trained(&r));
                (*i, r)
            })
            .collect()
    });
    for (i, r) in fresh {
        results[i] = Some(r);
    }

    // 5. Time the evaluators one cell at a time (nothing else running).
    let mut cells: Vec<CellResult> = Vec::new();
    for ((_, _, key), r) in specs.iter().zip(results) {
        let mut r = r.expect("every cell trained or reused");
        if r.ok() && r.eval.is_none() {
            match Model::load(&paths.cell_model(key)) {
                Ok(m) => {
                    r.eval = Some(time_model(&m, &points));
                    write_text(&paths.cell(key), &to_json(&r))?;
                }
                Err(e) => r.error = Some(format!("model file: {e}")),
            }
            progress.event(Event::Timed(&r));
        }
        cells.push(r);
    }

    // 6. The simulator and contact rows (timed, so alone too).
    let simulator = ladder::sim_rows(&plan.simulator)?;
    let contact = ladder::contact_rows(&plan.contact, &plan.base_pipeline)?;

    // 7. Fronts, recommendation, outputs.
    let pareto_train = pareto(&cells, by_truth, |c| c.train_s);
    let pareto_eval = pareto(&cells, by_truth, |c| c.eval.as_ref().map(|e| e.single_ns));
    let recommended = cells
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
        .map(|c| c.key.clone());
    if recommended.is_none() {
        notes.push("no cell meets the budgets: none recommended".into());
    }
    let outcome = Outcome {
        archive: archive.display().to_string(),
        plan: plan.source.clone(),
        pipeline: plan.base.clone(),
        condition,
        train_runs,
        held_out,
        by_truth,
        jobs,
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

fn to_json(r: &CellResult) -> String {
    serde_json::to_string_pretty(r).expect("cell serialises") + "\n"
}

/// A saved result: failed, or trained with its model file beside it (timed or not yet).
fn read_result(paths: &StudyPaths, key: &str) -> Option<CellResult> {
    let text = std::fs::read_to_string(paths.cell(key)).ok()?;
    let r: CellResult = serde_json::from_str(&text).ok()?;
    (r.key == key && (!r.ok() || paths.cell_model(key).is_file())).then_some(r)
}

/// `<dir>/<stem>.truth.parquet` beside a log.
fn truth_path(log: &Path) -> PathBuf {
    let stem = log
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    log.with_file_name(format!("{stem}{}", crate::format::TRUTH_SUFFIX))
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

/// Trains and scores one cell; a failure is the result's `error`, not an abort.
fn train_cell(
    spec: &CellSpec,
    key: &str,
    train: &[RunTable],
    held: &[RunTable],
    paths: &StudyPaths,
    truth: &[Sample],
    by_truth: bool,
) -> CellResult {
    let mut r = CellResult {
        key: key.to_string(),
        name: spec.name(),
        group: spec.group.clone(),
        family: spec.family.name().to_string(),
        settings: spec.settings.clone(),
        architecture: String::new(),
        parameters: 0,
        train_samples: 0,
        epochs: 0,
        train_s: None,
        estimated_train_s: f64::NAN,
        file_bytes: 0,
        held_out_rmse: None,
        held_out_samples: 0,
        truth_rmse: None,
        truth_cells: None,
        truth_negative_cells: None,
        eval: None,
        error: None,
    };
    let t0 = Instant::now();
    let file = match fit(spec, train, &mut r) {
        Ok(f) => f,
        Err(e) => {
            r.error = Some(e);
            return r;
        }
    };
    r.train_s = Some(t0.elapsed().as_secs_f64());
    let text = file.to_json();
    r.file_bytes = text.len() as u64;
    if let Err(e) = write_text(&paths.cell_model(key), &text) {
        r.error = Some(e.to_string());
        return r;
    }
    let model = match Model::named(file, &r.name) {
        Ok(m) => m,
        Err(e) => {
            r.error = Some(e.to_string());
            return r;
        }
    };
    let decimate = spec.pipeline.train.decimate;
    let (mut sq, mut n) = (0.0, 0usize);
    for t in held {
        let h = held_out_score(&model, t, decimate);
        sq += h.rmse_mu * h.rmse_mu * h.samples as f64;
        n += h.samples;
    }
    if n == 0 {
        r.error = Some(
            "no held-out samples: the held-out runs have no valid estimates with this cell's conditioning"
                .into(),
        );
        return r;
    }
    r.held_out_samples = n;
    r.held_out_rmse = Some((sq / n as f64).sqrt());
    if !truth.is_empty() && by_truth {
        match score(truth, &Grid::default(), |dv, q, v, t| {
            model.mu_vt(dv, q, v, t)
        }) {
            Ok(s) => {
                r.truth_rmse = Some(s.rmse);
                r.truth_cells = Some(s.cells.len());
                r.truth_negative_cells = Some(s.negative_cells);
            }
            Err(e) => r.error = Some(format!("scoring against the truth: {e}")),
        }
    }
    r
}

/// The cell's model file, with its shape in `r`.
fn fit(spec: &CellSpec, train: &[RunTable], r: &mut CellResult) -> Result<ModelFile, String> {
    let pipeline = &spec.pipeline;
    let provenance = Provenance {
        inputs: vec![],
        pipeline: format!("study cell {}", r.key),
        pipeline_sha256: crate::hash::sha256_bytes(pipeline.text.as_bytes()),
        seed: pipeline.train.seed,
        crate_version: env!("CARGO_PKG_VERSION").into(),
        created: String::new(),
        generation: None,
    };
    let fitted = spec
        .family
        .fit(&FitData {
            tables: train,
            pipeline,
            provenance,
            fallback: None,
            epochs: None,
        })
        .map_err(|e| e.to_string())?;
    let file = fitted.model?;
    let s = fitted.shape;
    (r.architecture, r.parameters, r.train_samples, r.epochs) =
        (s.architecture, s.parameters, s.train_samples, s.epochs);
    Ok(file)
}

/// Inputs (Δv, dΔv/dt, v, T) of the held-out runs, every k-th sample so that about `n` remain.
struct Points {
    dv: Vec<f64>,
    ddv: Vec<f64>,
    v: Vec<f64>,
    t: Vec<f64>,
}

fn timing_points(tables: &[RunTable], n: usize) -> Points {
    let total: usize = tables.iter().map(|t| t.len()).sum();
    let step = (total / n.max(1)).max(1);
    let mut p = Points {
        dv: vec![],
        ddv: vec![],
        v: vec![],
        t: vec![],
    };
    for t in tables {
        let t_c = t.metadata.ambient_temperature_c.unwrap_or(f64::NAN);
        for k in (0..t.len()).step_by(step) {
            p.dv.push(t.dv_mps[k]);
            p.ddv.push(t.ddv_mps2[k]);
            p.v.push(t.v_mps[k]);
            p.t.push(t_c);
        }
    }
    p
}

/// ns per point of `f` (which evaluates every point once): best of 5 repetitions of ≥ 20 ms.
pub(crate) fn ns_per_point(points: usize, mut f: impl FnMut() -> f64) -> f64 {
    std::hint::black_box(f());
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t0 = Instant::now();
        let mut loops = 0usize;
        while t0.elapsed().as_secs_f64() < 0.02 {
            std::hint::black_box(f());
            loops += 1;
        }
        let ns = t0.elapsed().as_secs_f64() * 1e9 / (loops * points.max(1)) as f64;
        best = best.min(ns);
    }
    best
}

fn time_model(m: &Model, p: &Points) -> EvalTiming {
    let n = p.dv.len();
    let single_ns = ns_per_point(n, || {
        let mut s = 0.0;
        for i in 0..n {
            s += m.mu_vt(std::hint::black_box(p.dv[i]), p.ddv[i], p.v[i], p.t[i]);
        }
        s
    });
    let mut out = vec![0.0; n];
    let batch_ns = ns_per_point(n, || {
        m.mu_batch_t(&p.dv, &p.ddv, &p.v, &p.t, &mut out);
        out[n / 2]
    });
    let (mut plain_libm_ns, mut libm_max_diff) = (None, None);
    if let Some(net) = PlainNet::of(&m.file) {
        plain_libm_ns = Some(ns_per_point(n, || {
            let mut s = 0.0;
            for i in 0..n {
                s += net.mu(
                    [std::hint::black_box(p.dv[i]), p.ddv[i], p.v[i], p.t[i]],
                    f64::tanh,
                );
            }
            s
        }));
        libm_max_diff = Some((0..n).fold(0.0f64, |d, i| {
            let x = [p.dv[i], p.ddv[i], p.v[i], p.t[i]];
            d.max((net.mu(x, crate::model::tanh_fast) - net.mu(x, f64::tanh)).abs())
        }));
    }
    EvalTiming {
        single_ns,
        batch_ns,
        plain_libm_ns,
        libm_max_diff,
    }
}

/// A network as a user would evaluate the model file in a plain scalar loop: inputs clamped to
/// the domain and normalised (mapminmax), layers z = b + W t (row-major, in order) with tanh on
/// the hidden ones, output reversed; two stack buffers, no allocation — and no creep region or
/// support blend (docs/model-files.md).
struct PlainNet {
    k: usize,
    lo: [f64; 4],
    hi: [f64; 4],
    gx: [f64; 4],
    ox: [f64; 4],
    gy: f64,
    oy: f64,
    /// (inputs, outputs, weights row-major, biases) per layer.
    layers: Vec<(usize, usize, Vec<f64>, Vec<f64>)>,
}

impl PlainNet {
    fn of(f: &ModelFile) -> Option<PlainNet> {
        if f.layers.is_empty()
            || f.layers
                .iter()
                .any(|l| l.biases.len() > crate::model::MAX_HIDDEN)
        {
            return None;
        }
        let mut n = PlainNet {
            k: f.inputs.len().min(4),
            lo: [0.0; 4],
            hi: [0.0; 4],
            gx: [1.0; 4],
            ox: [0.0; 4],
            gy: 1.0,
            oy: 0.0,
            layers: f
                .layers
                .iter()
                .map(|l| {
                    let cols = l.weights.first().map_or(0, Vec::len);
                    (cols, l.biases.len(), l.weights.concat(), l.biases.clone())
                })
                .collect(),
        };
        for (c, i) in f.inputs.iter().take(4).enumerate() {
            n.lo[c] = i.domain_min;
            n.hi[c] = i.domain_max;
            (n.gx[c], n.ox[c]) = crate::model::gain_offset(i.norm_min, i.norm_max);
        }
        (n.gy, n.oy) = crate::model::gain_offset(f.output.norm_min, f.output.norm_max);
        Some(n)
    }

    /// μ at `x`, with buffers as wide as the widest layer needs (a hand-written evaluator
    /// sizes its arrays to its network).
    fn mu(&self, x: [f64; 4], tanh: fn(f64) -> f64) -> f64 {
        match self
            .layers
            .iter()
            .map(|l| l.1)
            .max()
            .unwrap_or(1)
            .max(self.k)
        {
            0..=16 => self.mu_in::<16>(x, tanh),
            17..=64 => self.mu_in::<64>(x, tanh),
            _ => self.mu_in::<{ crate::model::MAX_HIDDEN }>(x, tanh),
        }
    }

    fn mu_in<const W: usize>(&self, x: [f64; 4], tanh: fn(f64) -> f64) -> f64 {
        let (mut a, mut b) = ([0.0f64; W], [0.0f64; W]);
        for c in 0..self.k {
            a[c] = self.gx[c] * x[c].clamp(self.lo[c], self.hi[c]) + self.ox[c];
        }
        let last = self.layers.len() - 1;
        for (l, (cols, rows, w, bias)) in self.layers.iter().enumerate() {
            for j in 0..*rows {
                let row = &w[j * cols..(j + 1) * cols];
                let mut z = bias[j];
                for (w, t) in row.iter().zip(&a[..*cols]) {
                    z += w * t;
                }
                b[j] = if l < last { tanh(z) } else { z };
            }
            std::mem::swap(&mut a, &mut b);
        }
        (a[0] - self.oy) / self.gy
    }
}

/// `study.csv`: one row per cell.
pub fn csv(o: &Outcome) -> String {
    let mut s = String::from("key,group,family,name,architecture,parameters,train_samples,epochs,train_s,estimated_train_s,single_ns,batch_ns,plain_libm_ns,libm_max_diff,file_bytes,held_out_rmse,held_out_samples,truth_rmse,truth_cells,truth_negative_cells,pareto_train,pareto_eval,recommended,error\n");
    let f = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:?}"));
    let q = |t: &str| format!("\"{}\"", t.replace('"', "\"\""));
    for c in &o.cells {
        let e = c.eval.as_ref();
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            c.key,
            q(&c.group),
            c.family,
            q(&c.name),
            c.architecture,
            c.parameters,
            c.train_samples,
            c.epochs,
            f(c.train_s),
            f(Some(c.estimated_train_s)),
            f(e.map(|e| e.single_ns)),
            f(e.map(|e| e.batch_ns)),
            f(e.and_then(|e| e.plain_libm_ns)),
            f(e.and_then(|e| e.libm_max_diff)),
            c.file_bytes,
            f(c.held_out_rmse),
            c.held_out_samples,
            f(c.truth_rmse),
            c.truth_cells.map_or(String::new(), |n| n.to_string()),
            c.truth_negative_cells
                .map_or(String::new(), |n| n.to_string()),
            o.pareto_train.contains(&c.key),
            o.pareto_eval.contains(&c.key),
            o.recommended.as_deref() == Some(c.key.as_str()),
            q(c.error.as_deref().unwrap_or("")),
        ));
    }
    s
}
