//! How a model generalises across runs: a model scored on a run it was not trained on, and
//! leave-one-run-out validation (one fit per run on all the others).

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
/// model generalises across runs, which the axle split cannot show. Folds run in parallel;
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
    };
    (0..tables.len())
        .into_par_iter()
        .map(|i| {
            let others: Vec<RunTable> = tables
                .iter()
                .enumerate()
                .filter(|(k, _)| *k != i)
                .map(|(_, t)| t.clone())
                .collect();
            let fitted = family.fit(&FitData {
                tables: &others,
                pipeline: &fold,
                provenance: provenance.clone(),
                fallback: None,
                epochs: None,
            })?;
            let bug = |what: String| IdentifyError::Data {
                what: format!("leave-one-run-out fold without {}: {what}", tables[i].name),
                hint: "report this as a bug".into(),
            };
            let file = fitted.model.map_err(|e| bug(e.to_string()))?;
            let model =
                Model::named(file, "leave-one-run-out model").map_err(|e| bug(e.to_string()))?;
            Ok(held_out_score(&model, &tables[i], fold.train.decimate))
        })
        .collect()
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
