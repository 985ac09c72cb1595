//! The study's cells: each keyed by a SHA-256 of everything that decides its result, reused
//! when a finished result is on disk, the rest trained side by side (each saved as it
//! finishes) through its model family and scored on the held-out runs and their truth.

use std::time::Instant;

use rayon::prelude::*;

use super::runs::{Conditionings, Runs, Split};
use super::{write_text, CellResult, CellSpec, Event, Plan, StudyError, StudyProgress};
use crate::identify::dataset::RunTable;
use crate::identify::family::FitData;
use crate::identify::held_out_score;
use crate::model::{Model, ModelFile, Provenance};
use crate::outdir::StudyPaths;
use crate::score::{score, Grid, Sample};

/// A cell of the plan with its key.
pub(super) struct Keyed<'a> {
    /// Index into the plan's cells.
    pub(super) index: usize,
    pub(super) spec: &'a CellSpec,
    pub(super) key: String,
}

/// Every cell's key: railgrip's version, the family, the cell's pipeline text, the runs' input
/// hashes, the held-out runs, the rail condition and the number of timing points.
pub(super) fn keyed<'a>(
    plan: &'a Plan,
    conditionings: &Conditionings,
    splits: &[Split],
    runs: &Runs,
) -> Vec<Keyed<'a>> {
    let run_hashes = |e: &Split| -> String {
        e.records
            .iter()
            .map(|r| format!("{} {}\n", r.run, r.input_sha256))
            .collect()
    };
    plan.cells
        .iter()
        .enumerate()
        .map(|(index, spec)| {
            let text = format!(
                "railgrip {}\nmodel {}\n{}\nruns\n{}held out {:?}\ncondition {}\ntiming points {}\n",
                env!("CARGO_PKG_VERSION"),
                spec.family.name(),
                spec.pipeline.text,
                run_hashes(&splits[conditionings.of_cell[index]]),
                runs.held_out,
                runs.condition,
                plan.eval_points
            );
            let key = crate::hash::sha256_bytes(text.as_bytes())[..16].to_string();
            Keyed { index, spec, key }
        })
        .collect()
}

/// The cells' results: reused from disk, or trained now — side by side on `pool`, each saved
/// as it finishes (without timings: a study killed before them retimes only). Refuses work
/// estimated over the plan's time budget unless `force`.
#[allow(clippy::too_many_arguments)]
pub(super) fn train(
    plan: &Plan,
    cells: &[Keyed<'_>],
    conditionings: &Conditionings,
    splits: &[Split],
    runs: &Runs,
    paths: &StudyPaths,
    pool: &rayon::ThreadPool,
    force: bool,
    progress: StudyProgress<'_>,
) -> Result<Vec<CellResult>, StudyError> {
    let jobs = pool.current_num_threads();
    let mut results: Vec<Option<CellResult>> =
        cells.iter().map(|c| read_result(paths, &c.key)).collect();
    let split_of = |c: &Keyed<'_>| &splits[conditionings.of_cell[c.index]];
    let estimates: Vec<f64> = cells
        .iter()
        .map(|c| {
            let samples = split_of(c).train.iter().map(|t| t.len()).sum();
            c.spec
                .family
                .estimated_seconds(&c.spec.pipeline.train, samples)
        })
        .collect();
    let pending_s: f64 = results
        .iter()
        .zip(&estimates)
        .filter(|(r, _)| r.is_none())
        .map(|(_, e)| *e)
        .sum::<f64>()
        / jobs as f64;
    let reused = results.iter().filter(|r| r.is_some()).count();
    progress.event(Event::Planned {
        cells: cells.len(),
        reused,
        estimated_s: pending_s,
    });
    if pending_s > plan.max_minutes * 60.0 && !force {
        return Err(StudyError::Refused {
            what: format!(
                "{}: the {} cells to train are estimated at {:.1} min on {jobs} thread(s), more than study.max_minutes = {}",
                plan.source,
                cells.len() - reused,
                pending_s / 60.0,
                plan.max_minutes
            ),
            hint: "narrow the grids, raise study.max_minutes, or pass --force (finished cells are kept and reused)".into(),
        });
    }
    let fresh: Vec<(usize, CellResult)> = pool.install(|| {
        cells
            .par_iter()
            .enumerate()
            .filter(|(i, _)| results[*i].is_none())
            .map(|(i, c)| {
                let e = split_of(c);
                let mut r = train_cell(c, &e.train, &e.held, paths, runs);
                r.estimated_train_s = estimates[i];
                let _ = write_text(&paths.cell(&c.key), &to_json(&r));
                progress.event(Event::Trained(&r));
                (i, r)
            })
            .collect()
    });
    for (i, r) in fresh {
        results[i] = Some(r);
    }
    Ok(results
        .into_iter()
        .map(|r| r.expect("every cell trained or reused"))
        .collect())
}

pub(super) fn to_json(r: &CellResult) -> String {
    serde_json::to_string_pretty(r).expect("cell serialises") + "\n"
}

/// A saved result: failed, or trained with its model file beside it (timed or not yet).
fn read_result(paths: &StudyPaths, key: &str) -> Option<CellResult> {
    let text = std::fs::read_to_string(paths.cell(key)).ok()?;
    let r: CellResult = serde_json::from_str(&text).ok()?;
    (r.key == key && (!r.ok() || paths.cell_model(key).is_file())).then_some(r)
}

/// Trains and scores one cell; a failure is the result's `error`, not an abort.
fn train_cell(
    cell: &Keyed<'_>,
    train: &[RunTable],
    held: &[RunTable],
    paths: &StudyPaths,
    runs: &Runs,
) -> CellResult {
    let spec = cell.spec;
    let mut r = CellResult {
        key: cell.key.clone(),
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
    if let Err(e) = write_text(&paths.cell_model(&cell.key), &text) {
        r.error = Some(e.to_string());
        return r;
    }
    match Model::named(file, &r.name) {
        Ok(model) => score_cell(&model, spec, held, runs, &mut r),
        Err(e) => r.error = Some(e.to_string()),
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
        calibration: None,
    };
    let fitted = spec
        .family
        .fit(&FitData {
            tables: train,
            pipeline,
            provenance,
            fallback: None,
            epochs: None,
            audit: true,
        })
        .map_err(|e| e.to_string())?;
    let file = fitted.model.map_err(|e| e.to_string())?;
    let s = fitted.shape;
    (r.architecture, r.parameters, r.train_samples, r.epochs) =
        (s.architecture, s.parameters, s.train_samples, s.epochs);
    Ok(file)
}

/// The held-out RMSE of `model` (every `train.decimate`-th sample of the held-out runs) and,
/// when every held-out run has truth, its supported-cell error against the truth.
fn score_cell(model: &Model, spec: &CellSpec, held: &[RunTable], runs: &Runs, r: &mut CellResult) {
    let decimate = spec.pipeline.train.decimate;
    let (mut sq, mut n) = (0.0, 0usize);
    for t in held {
        let h = held_out_score(model, t, decimate);
        sq += h.rmse_mu * h.rmse_mu * h.samples as f64;
        n += h.samples;
    }
    if n == 0 {
        r.error = Some(
            "no held-out samples: the held-out runs have no valid estimates with this cell's conditioning"
                .into(),
        );
        return;
    }
    r.held_out_samples = n;
    r.held_out_rmse = Some((sq / n as f64).sqrt());
    let truth: &[Sample] = &runs.truth;
    if !truth.is_empty() && runs.by_truth {
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
}
