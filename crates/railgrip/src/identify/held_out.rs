//! How a model generalises across runs: a model scored on a run it was not trained on, and
//! leave-one-run-out validation (one fit per run on all the others; per fold of runs beyond
//! `train.folds` runs).

use rayon::prelude::*;

use super::dataset::RunTable;
use super::family::{FitData, ModelFamily};
use super::IdentifyError;
use crate::config::Pipeline;
use crate::model::{Model, Provenance};

/// A model of one leave-one-run-out fold scored on its held-out run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeldOut {
    pub run: String,
    /// Valid samples of the held-out run scored (every `decimate`-th of each axle).
    pub samples: usize,
    /// RMSE of the exported model (creep region, clamping and support included) against the
    /// run's own estimates, μ.
    pub rmse_mu: f64,
}

/// Leave-one-run-out validation: for every run, `family` fitted as the pipeline says — a
/// network from one start, without an ensemble — on the other runs, and its model scored
/// against the held-out run's estimates (all axles, every `train.decimate`-th sample): how the
/// model generalises across runs, which the axle split cannot show. Beyond `train.folds` runs,
/// K = `train.folds` folds of runs instead (run i in fold i mod K, [`super::choice::fold_of`]):
/// each fold's model is fitted on the runs of the other folds and scores the runs of its own,
/// so the cost grows with the runs like one fit, not like their square. Folds run in parallel;
/// results in run order. Fewer than two runs: none.
pub fn leave_one_run_out(
    family: &dyn ModelFamily,
    tables: &[RunTable],
    pipeline: &Pipeline,
) -> Result<Vec<HeldOut>, IdentifyError> {
    if tables.len() < 2 {
        return Ok(Vec::new());
    }
    let mut fold = pipeline.clone();
    fold.train.starts = 1;
    fold.train.ensemble = 1;
    let provenance = Provenance {
        inputs: vec![],
        pipeline: pipeline.source.clone(),
        pipeline_sha256: String::new(),
        seed: fold.train.seed,
        crate_version: env!("CARGO_PKG_VERSION").into(),
        created: String::new(),
        generation: None,
        calibration: None,
    };
    let n = tables.len();
    let folds = n.min(pipeline.train.folds.max(2));
    let fold_of = |i: usize| super::choice::fold_of(i, n, folds);
    let scored: Vec<Vec<(usize, HeldOut)>> = (0..folds)
        .into_par_iter()
        .map(|f| {
            let others: Vec<RunTable> = (0..n)
                .filter(|&k| fold_of(k) != f)
                .map(|k| tables[k].clone())
                .collect();
            let held: Vec<usize> = (0..n).filter(|&k| fold_of(k) == f).collect();
            let names = held
                .iter()
                .map(|&k| tables[k].name.as_str())
                .collect::<Vec<_>>()
                .join(", ");
            let fitted = family.fit(&FitData {
                tables: &others,
                pipeline: &fold,
                provenance: provenance.clone(),
                fallback: None,
                epochs: None,
                audit: false,
            })?;
            let bug = |what: String| IdentifyError::Data {
                what: format!("leave-one-run-out fold without {names}: {what}"),
                hint: "report this as a bug".into(),
            };
            let file = fitted.model.map_err(|e| bug(e.to_string()))?;
            let model =
                Model::named(file, "leave-one-run-out model").map_err(|e| bug(e.to_string()))?;
            Ok(held
                .iter()
                .map(|&k| (k, held_out_score(&model, &tables[k], fold.train.decimate)))
                .collect())
        })
        .collect::<Result<_, IdentifyError>>()?;
    let mut all: Vec<(usize, HeldOut)> = scored.into_iter().flatten().collect();
    all.sort_by_key(|(k, _)| *k);
    Ok(all.into_iter().map(|(_, h)| h).collect())
}

/// A model scored on a run it was not trained on: RMSE of the model (creep region, clamping and
/// support included) against the run's own estimates, every `decimate`-th valid sample of all
/// axles, at the run's ambient temperature.
pub fn held_out_score(model: &Model, held: &RunTable, decimate: usize) -> HeldOut {
    let s = super::choice::errors(model, held, decimate);
    HeldOut {
        run: held.name.clone(),
        samples: s.n,
        rmse_mu: s.rmse(),
    }
}

/// `<name>.leave-one-run-out.json`: the network's held-out scores and the generation that
/// wrote them.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct HeldOutFile {
    #[serde(default)]
    pub generation: Option<String>,
    pub runs: Vec<HeldOut>,
}
