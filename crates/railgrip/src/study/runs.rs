//! The study's runs: every conditioning's estimates (reused across studies like `railgrip
//! run`'s), the rail condition, the runs the cells train on and the held-out runs, and the
//! held-out runs' truth.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::{Plan, StudyError};
use crate::campaign::{process_run, OutDir, RunRecord};
use crate::config::Pipeline;
use crate::identify::dataset::RunTable;
use crate::identify::family::TemperatureNeed;
use crate::identify::select_condition;
use crate::ingest::LogSource;
use crate::outdir::StudyPaths;
use crate::score::Sample;

/// The plan's conditionings: the distinct non-`[train]` settings of its cells, each estimated
/// once (cells that differ in training only share their estimates).
pub(super) struct Conditionings {
    /// (key: the first 16 hex digits of the SHA-256 of the pipeline text, the pipeline).
    pub(super) pipelines: Vec<(String, Pipeline)>,
    /// The conditioning of each cell, by index into `pipelines`.
    pub(super) of_cell: Vec<usize>,
}

impl Conditionings {
    pub(super) fn of(plan: &Plan) -> Conditionings {
        let mut keys: BTreeMap<String, usize> = BTreeMap::new();
        let (mut pipelines, mut of_cell) = (Vec::new(), Vec::new());
        for c in &plan.cells {
            let key = crate::hash::sha256_bytes(c.conditioning.text.as_bytes())[..16].to_string();
            let next = keys.len();
            let i = *keys.entry(key.clone()).or_insert_with(|| {
                pipelines.push((key, c.conditioning.clone()));
                next
            });
            of_cell.push(i);
        }
        Conditionings { pipelines, of_cell }
    }
}

/// The estimated runs of one conditioning.
pub(super) struct Estimated {
    pub(super) records: Vec<RunRecord>,
    pub(super) tables: Vec<RunTable>,
}

/// [`Estimated`] split into the runs the cells train on and the held-out runs.
pub(super) struct Split {
    pub(super) records: Vec<RunRecord>,
    pub(super) train: Vec<RunTable>,
    pub(super) held: Vec<RunTable>,
}

/// Every conditioning's estimates of `logs`, through the campaign's per-run stage (reused when
/// unchanged), each with the campaign's calibration that conditioning's pipeline asks for
/// (fitted over every run, the held-out ones too, as `railgrip run` fits it; written beside the
/// conditioning's runs and reused on the same inputs); runs that could not be estimated are
/// noted once.
pub(super) fn estimate(
    conditionings: &Conditionings,
    logs: &[(String, LogSource)],
    paths: &StudyPaths,
    pool: &rayon::ThreadPool,
    notes: &mut Vec<String>,
) -> Result<Vec<Estimated>, StudyError> {
    use crate::campaign::calibration::{calibrated_pipeline, write_calibration, CALIBRATION_FILE};
    let mut estimated = Vec::new();
    for (key, pipe) in &conditionings.pipelines {
        let od = OutDir::new(paths.conditioning(key));
        std::fs::create_dir_all(od.runs()).map_err(|source| StudyError::Write {
            path: od.runs(),
            source,
        })?;
        let options = crate::campaign::Options {
            jobs: Some(pool.current_num_threads()),
            ..Default::default()
        };
        let previous = od.root().join(CALIBRATION_FILE);
        let cal = calibrated_pipeline(logs, pipe, options, true, true, od.root(), Some(&previous))?;
        if let Some(r) = &cal.record {
            write_calibration(od.root(), r)?;
        }
        for n in cal.note.iter().chain(
            cal.pipeline
                .calibrated
                .as_ref()
                .map(crate::config::calibrated::Calibrated::summary)
                .as_ref(),
        ) {
            let note = format!("conditioning {key}: {n}");
            if !notes.contains(&note) {
                notes.push(note);
            }
        }
        let pipe = &cal.pipeline;
        let results: Vec<(RunRecord, Option<RunTable>)> =
            crate::parallel::each(pool, logs, |(name, src)| {
                process_run(src, name, &od, pipe, false)
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
    Ok(estimated)
}

/// The runs of a study: one rail condition, split into training and held-out runs.
pub(super) struct Runs {
    pub(super) condition: String,
    pub(super) train: Vec<String>,
    pub(super) held_out: Vec<String>,
    /// The held-out runs' true samples (each run's axles numbered apart).
    pub(super) truth: Vec<Sample>,
    /// Whether every held-out run carries truth: then cells are ranked by it.
    pub(super) by_truth: bool,
}

/// The rail condition, the training and held-out runs (from the first conditioning: every
/// conditioning estimates the same logs) and the held-out runs' truth; refuses a plan whose
/// families need temperatures the runs lack.
pub(super) fn choose(
    plan: &Plan,
    first: &Estimated,
    logs: &[(String, LogSource)],
    notes: &mut Vec<String>,
) -> Result<Runs, StudyError> {
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
    let temps: Vec<(String, Option<f64>)> = choice
        .used
        .iter()
        .map(|t| (t.name.clone(), t.metadata.ambient_temperature_c))
        .collect();
    check_temperatures(plan, &temps, &condition)?;
    let held_out = held_out_runs(plan, &names, &condition)?;
    let train: Vec<String> = names
        .iter()
        .filter(|n| !held_out.contains(n))
        .cloned()
        .collect();
    if held_out.is_empty() || train.is_empty() {
        return Err(StudyError::Data {
            what: format!(
                "condition {condition} has {} estimated run(s) ({}): a study needs at least one to train on and one held out",
                names.len(),
                names.join(", ")
            ),
            hint: "give a campaign with three or more runs of one rail condition, or set study.held_out".into(),
        });
    }
    let (truth, truth_runs) = read_truth(&held_out, logs, &temps)?;
    let by_truth = truth_runs == held_out.len();
    if truth_runs > 0 && !by_truth {
        notes.push(format!(
            "{truth_runs} of {} held-out runs carry truth: cells are ranked by the held-out RMSE",
            held_out.len()
        ));
    }
    Ok(Runs {
        condition,
        train,
        held_out,
        truth,
        by_truth,
    })
}

/// Refuses cells whose family needs ambient temperatures (`temps`: each run's) the runs of
/// `condition` do not have.
fn check_temperatures(
    plan: &Plan,
    temps: &[(String, Option<f64>)],
    condition: &str,
) -> Result<(), StudyError> {
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
    Ok(())
}

/// `study.held_out`, checked against the run `names`; without it every third run from the
/// third on (sorted by name), or the last one of two.
fn held_out_runs(
    plan: &Plan,
    names: &[String],
    condition: &str,
) -> Result<Vec<String>, StudyError> {
    if let Some(h) = &plan.held_out {
        for n in h {
            if !names.contains(n) {
                return Err(StudyError::Plan {
                    file: plan.source.clone(),
                    what: format!("study.held_out names {n}, which is not an estimated run of condition {condition}"),
                    hint: format!("the runs are {}", names.join(", ")),
                });
            }
        }
        return Ok(h.clone());
    }
    let every_third: Vec<String> = names.iter().skip(2).step_by(3).cloned().collect();
    Ok(match (every_third.is_empty(), names.last()) {
        (true, Some(last)) if names.len() >= 2 => vec![last.clone()],
        _ => every_third,
    })
}

/// The truth of the held-out runs that have it (`<stem>.truth.parquet` beside a log in a
/// folder, as `railgrip simulate` writes it), each run's axles numbered apart so that a cell
/// never averages two runs; and how many runs had it.
fn read_truth(
    held_out: &[String],
    logs: &[(String, LogSource)],
    temps: &[(String, Option<f64>)],
) -> Result<(Vec<Sample>, usize), StudyError> {
    let mut truth: Vec<Sample> = Vec::new();
    let mut runs = 0usize;
    for (k, run) in held_out.iter().enumerate() {
        let src = logs.iter().find(|(n, _)| n == run).map(|(_, s)| s);
        let t_c = temps
            .iter()
            .find(|(n, _)| n == run)
            .and_then(|(_, t)| *t)
            .unwrap_or(f64::NAN);
        let Some(LogSource::File(p)) = src else {
            continue;
        };
        let tp = truth_path(p);
        if !tp.is_file() {
            continue;
        }
        let samples = crate::sim::read_truth_samples(&tp, t_c).map_err(|e| StudyError::Data {
            what: e.to_string(),
            hint: "remove the broken truth table or write it again with railgrip simulate".into(),
        })?;
        let offset = (4 * k).min(250) as u8;
        truth.extend(samples.into_iter().map(|s| Sample {
            axle: s.axle + offset,
            ..s
        }));
        runs += 1;
    }
    Ok((truth, runs))
}

/// `<dir>/<stem>.truth.parquet` beside a log.
fn truth_path(log: &Path) -> PathBuf {
    let stem = log
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    log.with_file_name(format!("{stem}{}", crate::format::TRUTH_SUFFIX))
}

/// Each conditioning's tables split once into training and held-out runs (the others, of other
/// rail conditions, dropped).
pub(super) fn split(estimated: Vec<Estimated>, runs: &Runs) -> Vec<Split> {
    estimated
        .into_iter()
        .map(|e| {
            let (mut train, mut held) = (Vec::new(), Vec::new());
            for t in e.tables {
                if runs.train.contains(&t.name) {
                    train.push(t);
                } else if runs.held_out.contains(&t.name) {
                    held.push(t);
                }
            }
            Split {
                records: e.records,
                train,
                held,
            }
        })
        .collect()
}
