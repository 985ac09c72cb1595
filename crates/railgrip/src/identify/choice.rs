//! Model choice by held-out runs (`train.model = "auto"`): every candidate — the network of
//! `[train]` (seed 002), networks over the other input sets (speed, speed and ambient
//! temperature), the residual network over the Polach law ([`Residual`]) and Polach's law with
//! the temperature and speed laws BIC chose ([`PolachWithLaws`]) — is fitted as the campaign
//! fits it on all runs but the held-out ones and scored on those, fold by fold; the candidate
//! with the lowest pooled held-out RMSE becomes the campaign's model.
//!
//! Folds: with at most `train.folds` runs, one run out at a time; beyond, `train.folds` folds of
//! runs, run i (in the campaign's run order) in fold i mod K. Each fold does what the campaign
//! does: its Polach law first (a candidate, the networks' support fallback and the residual
//! network's base), then the networks, one start each. Folds and their candidates run in
//! parallel; the results do not depend on the order (the same bytes on any number of threads).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::dataset::RunTable;
use super::family::{FitData, ModelFamily, Network, PolachWithLaws, Residual};
use super::polach::FormChoice;
use super::IdentifyError;
use crate::config::{default_support_cells, ModelChoice, Pipeline};
use crate::model::{InputSet, Model, ModelFile, Provenance};

/// What a candidate is fitted as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CandidateKind {
    Network,
    Residual,
    Polach,
}

/// One candidate of the campaign's model: its name (tables, reports, and the tag of its
/// files), what it is, and the pipeline it is fitted with (`[train]` with its inputs).
#[derive(Debug, Clone)]
pub struct Candidate {
    /// `mlp` (the network of `[train]`), `mlp_2in` / `mlp_3in` / `mlp_4in` (a network over
    /// another input set), `residual`, `polach`.
    pub name: String,
    pub kind: CandidateKind,
    pub pipeline: Pipeline,
}

impl Candidate {
    /// The family that fits it; a Polach candidate refits `pinned` when given.
    pub fn family(&self, pinned: Option<FormChoice>) -> Box<dyn ModelFamily> {
        match self.kind {
            CandidateKind::Network => Box::new(Network),
            CandidateKind::Residual => Box::new(Residual),
            CandidateKind::Polach => Box::new(PolachWithLaws {
                intervals: false,
                law_required: false,
                pinned,
            }),
        }
    }
}

/// `pipeline` with the network inputs `inputs` (the support grid's default for their count
/// unless `[train]` gave one for that count).
fn with_inputs(pipeline: &Pipeline, inputs: InputSet) -> Pipeline {
    let mut p = pipeline.clone();
    if inputs != p.train.inputs {
        if p.train.support_cells.len() != inputs.count() {
            p.train.support_cells = default_support_cells(inputs.count());
        }
        p.train.inputs = inputs;
    }
    p
}

fn input_tag(inputs: InputSet) -> &'static str {
    match inputs.count() {
        4 => "mlp_4in",
        3 => "mlp_3in",
        _ => "mlp_2in",
    }
}

/// True when every run carries an ambient temperature and there are two or more distinct ones
/// (a network with the temperature input, or a law in T, can learn something from them).
pub fn temperatures_vary(tables: &[RunTable]) -> bool {
    let mut t: Vec<f64> = Vec::new();
    for r in tables {
        match r.metadata.ambient_temperature_c {
            Some(x) if x.is_finite() => t.push(x),
            _ => return false,
        }
    }
    t.sort_by(f64::total_cmp);
    t.dedup();
    t.len() >= 2
}

/// The candidates of `train.model` for these runs, the Polach law first (the others stand on
/// it), then the network of `[train]`: `auto` all of them (a 4-input network only when
/// [`temperatures_vary`]); a named model the Polach law, the network of `[train]` (the
/// campaign's history and audit come from it) and, for `residual`, the residual network.
/// The residual network takes the inputs of `[train]` when they include the speed, else Δv,
/// dΔv/dt and v (the law carries the temperature).
pub fn candidates(pipeline: &Pipeline, tables: &[RunTable]) -> Vec<Candidate> {
    let train = &pipeline.train;
    let mut c = vec![
        Candidate {
            name: "polach".into(),
            kind: CandidateKind::Polach,
            pipeline: pipeline.clone(),
        },
        Candidate {
            name: "mlp".into(),
            kind: CandidateKind::Network,
            pipeline: pipeline.clone(),
        },
    ];
    if train.model == ModelChoice::Auto {
        let mut sets = vec![InputSet::DvDdv, InputSet::DvDdvV];
        if temperatures_vary(tables) {
            sets.push(InputSet::DvDdvVT);
        }
        for s in sets.into_iter().filter(|&s| s != train.inputs) {
            c.push(Candidate {
                name: input_tag(s).into(),
                kind: CandidateKind::Network,
                pipeline: with_inputs(pipeline, s),
            });
        }
    }
    if matches!(train.model, ModelChoice::Auto | ModelChoice::Residual) {
        let inputs = if train.inputs.has_speed() {
            train.inputs
        } else {
            InputSet::DvDdvV
        };
        c.push(Candidate {
            name: "residual".into(),
            kind: CandidateKind::Residual,
            pipeline: with_inputs(pipeline, inputs),
        });
    }
    c
}

/// A candidate's held-out errors on one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunError {
    pub run: String,
    /// Samples scored (every `train.decimate`-th valid sample of every axle).
    pub samples: usize,
    /// RMSE and mean of model − estimate, μ.
    pub rmse_mu: f64,
    pub bias_mu: f64,
}

/// A candidate's row of the model choice.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CandidateScore {
    pub name: String,
    /// `2-10-1`, `polach`, `polach+3-10-1`.
    pub architecture: String,
    pub parameters: usize,
    /// Pooled over every held-out sample of every fold (`null` when a fold could not fit it).
    pub rmse_mu: Option<f64>,
    pub bias_mu: Option<f64>,
    /// The worst run's held-out RMSE.
    pub worst_run_rmse_mu: Option<f64>,
    pub runs: Vec<RunError>,
    /// Why a fold could not fit it (the first such fold).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The model choice: the folds, every candidate's scores, and the chosen one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Choice {
    /// `auto`, or the named model.
    pub setting: String,
    pub folds: usize,
    pub candidates: Vec<CandidateScore>,
    /// The chosen candidate's name.
    pub chosen: String,
    /// Why it was chosen.
    pub reason: String,
    /// The campaign generation that wrote the file, when a campaign did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generation: Option<String>,
}

impl Choice {
    /// Which candidate was chosen and why, in one line (`residual: lowest held-out …`).
    pub fn why(&self) -> String {
        format!("{}: {}", self.chosen, self.reason)
    }
}

/// The fold of run `i` of `n` runs with `folds` folds.
pub fn fold_of(i: usize, n: usize, folds: usize) -> usize {
    if n <= folds {
        i
    } else {
        i % folds
    }
}

/// Sums of one run's errors.
#[derive(Debug, Clone, Default)]
pub(super) struct Sums {
    pub(super) n: usize,
    sum: f64,
    sq: f64,
}

impl Sums {
    fn add(&mut self, o: &Sums) {
        self.n += o.n;
        self.sum += o.sum;
        self.sq += o.sq;
    }
    pub(super) fn rmse(&self) -> f64 {
        (self.sq / self.n.max(1) as f64).sqrt()
    }
    fn bias(&self) -> f64 {
        self.sum / self.n.max(1) as f64
    }
}

/// `model` on every `decimate`-th valid sample of `run` at the run's ambient temperature.
pub(super) fn errors(model: &Model, run: &RunTable, decimate: usize) -> Sums {
    let t_c = run.metadata.ambient_temperature_c.unwrap_or(f64::NAN);
    let mut s = Sums::default();
    for k in (0..run.len()).step_by(decimate.max(1)) {
        let e = model.mu_vt(run.dv_mps[k], run.ddv_mps2[k], run.v_mps[k], t_c) - run.mu[k];
        s.n += 1;
        s.sum += e;
        s.sq += e * e;
    }
    s
}

/// A fold's pipeline: one start, no ensemble (as leave-one-run-out trains).
fn fold_pipeline(p: &Pipeline) -> Pipeline {
    let mut f = p.clone();
    f.train.starts = 1;
    f.train.ensemble = 1;
    f
}

/// Per candidate of a fold: its sums per held-out run, or why it could not be fitted.
type FoldScores = Vec<Result<Vec<Sums>, String>>;

/// One fold: the candidates fitted on `train` and scored on `held` — the Polach law first,
/// the others with it as their fallback or base. Per candidate: per held-out run sums, or why
/// it could not be fitted.
fn fold(
    cands: &[Candidate],
    train: &[RunTable],
    held: &[&RunTable],
    decimate: usize,
    form: FormChoice,
) -> FoldScores {
    let provenance = Provenance {
        inputs: vec![],
        pipeline: String::new(),
        pipeline_sha256: String::new(),
        seed: 0,
        crate_version: env!("CARGO_PKG_VERSION").into(),
        created: String::new(),
        generation: None,
        calibration: None,
    };
    let fit = |c: &Candidate, fallback: Option<&Model>| -> Result<Model, String> {
        let p = fold_pipeline(&c.pipeline);
        let fitted = c
            .family(Some(form))
            .fit(&FitData {
                tables: train,
                pipeline: &p,
                provenance: provenance.clone(),
                fallback,
                epochs: None,
                audit: false,
            })
            .map_err(|e| e.to_string())?;
        let file: ModelFile = fitted.model.map_err(|e| e.to_string())?;
        Model::named(file, &c.name).map_err(|e| e.to_string())
    };
    let score = |m: &Model| held.iter().map(|r| errors(m, r, decimate)).collect();
    let polach_at = cands.iter().position(|c| c.kind == CandidateKind::Polach);
    let law = polach_at.map(|i| fit(&cands[i], None));
    let base = law.as_ref().and_then(|l| l.as_ref().ok());
    cands
        .par_iter()
        .enumerate()
        .map(|(i, c)| {
            if Some(i) == polach_at {
                return match &law {
                    Some(Ok(m)) => Ok(score(m)),
                    Some(Err(e)) => Err(e.clone()),
                    None => Err("no Polach law".into()),
                };
            }
            fit(c, base).map(|m| score(&m))
        })
        .collect()
}

/// Every candidate's held-out scores over the folds of `tables` (see the module text), in the
/// order of `cands` (the architecture and parameter count are left for the caller, who has
/// the fits on all runs), `form` the temperature and speed form the campaign's Polach fit chose
/// (the folds refit it; the search itself is not repeated per fold).
pub fn score_candidates(
    cands: &[Candidate],
    tables: &[RunTable],
    folds: usize,
    decimate: usize,
    form: FormChoice,
) -> Vec<CandidateScore> {
    let n = tables.len();
    let k = n.min(folds);
    let per_fold: Vec<(Vec<usize>, FoldScores)> = (0..k)
        .into_par_iter()
        .map(|f| {
            let held_idx: Vec<usize> = (0..n).filter(|&i| fold_of(i, n, folds) == f).collect();
            let train: Vec<RunTable> = (0..n)
                .filter(|&i| fold_of(i, n, folds) != f)
                .map(|i| tables[i].clone())
                .collect();
            let held: Vec<&RunTable> = held_idx.iter().map(|&i| &tables[i]).collect();
            (held_idx, fold(cands, &train, &held, decimate, form))
        })
        .collect();
    cands
        .iter()
        .enumerate()
        .map(|(c, cand)| {
            let mut runs: Vec<Option<Sums>> = vec![None; n];
            let mut error = None;
            for (held_idx, results) in &per_fold {
                match &results[c] {
                    Ok(sums) => {
                        for (&i, s) in held_idx.iter().zip(sums) {
                            runs[i] = Some(s.clone());
                        }
                    }
                    Err(e) => {
                        error.get_or_insert_with(|| e.clone());
                    }
                }
            }
            let complete = error.is_none() && k >= 2;
            let mut pooled = Sums::default();
            let mut worst: f64 = 0.0;
            let mut rows = Vec::new();
            for (i, s) in runs.iter().enumerate() {
                if let Some(s) = s {
                    pooled.add(s);
                    worst = worst.max(s.rmse());
                    rows.push(RunError {
                        run: tables[i].name.clone(),
                        samples: s.n,
                        rmse_mu: s.rmse(),
                        bias_mu: s.bias(),
                    });
                }
            }
            CandidateScore {
                name: cand.name.clone(),
                architecture: String::new(),
                parameters: 0,
                rmse_mu: complete.then(|| pooled.rmse()),
                bias_mu: complete.then(|| pooled.bias()),
                worst_run_rmse_mu: complete.then_some(worst),
                runs: rows,
                error: if k < 2 {
                    Some("fewer than two runs: nothing to hold out".into())
                } else {
                    error
                },
            }
        })
        .collect()
}

/// The candidate `train.model` names, or with `auto` the lowest held-out RMSE among the
/// candidates every fold could fit (ties: the earlier candidate, the simpler one first); the
/// network of `[train]` when no candidate could be scored. `names` are the candidates' names,
/// `scores` their held-out scores in the same order (empty unless `auto`), `available` says
/// which have a model file from the fit on all runs.
pub fn choose(
    setting: ModelChoice,
    names: &[&str],
    scores: &[CandidateScore],
    available: &[bool],
) -> Result<(usize, String), IdentifyError> {
    let named = |name: &str| {
        names
            .iter()
            .position(|n| *n == name)
            .filter(|&i| available[i])
            .ok_or_else(|| IdentifyError::Data {
                what: format!("train.model = \"{name}\": that model could not be fitted on these runs (see the notes)"),
                hint: "choose another train.model, or \"auto\"".into(),
            })
    };
    match setting {
        ModelChoice::Mlp => Ok((named("mlp")?, "train.model = \"mlp\"".into())),
        ModelChoice::Polach => Ok((named("polach")?, "train.model = \"polach\"".into())),
        ModelChoice::Residual => Ok((named("residual")?, "train.model = \"residual\"".into())),
        ModelChoice::Auto => {
            let best = scores
                .iter()
                .enumerate()
                .filter(|(i, s)| available[*i] && s.rmse_mu.is_some())
                .min_by(|a, b| {
                    a.1.rmse_mu
                        .unwrap_or(f64::INFINITY)
                        .total_cmp(&b.1.rmse_mu.unwrap_or(f64::INFINITY))
                });
            match best {
                Some((i, s)) => Ok((
                    i,
                    format!(
                        "lowest held-out RMSE of μ ({:.5}) over the runs",
                        s.rmse_mu.unwrap_or(f64::NAN)
                    ),
                )),
                None => Ok((
                    named("mlp")?,
                    "no candidate could be scored on held-out runs: the network of [train]".into(),
                )),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn score(name: &str, rmse: Option<f64>) -> CandidateScore {
        CandidateScore {
            name: name.into(),
            architecture: String::new(),
            parameters: 0,
            rmse_mu: rmse,
            bias_mu: rmse.map(|_| 0.0),
            worst_run_rmse_mu: rmse,
            runs: vec![],
            error: None,
        }
    }

    #[test]
    fn folds_hold_one_run_out_up_to_the_fold_count_and_deal_runs_beyond() {
        assert_eq!(
            (0..5).map(|i| fold_of(i, 5, 8)).collect::<Vec<_>>(),
            [0, 1, 2, 3, 4]
        );
        assert_eq!(
            (0..8).map(|i| fold_of(i, 8, 8)).collect::<Vec<_>>(),
            [0, 1, 2, 3, 4, 5, 6, 7]
        );
        let twelve: Vec<usize> = (0..12).map(|i| fold_of(i, 12, 8)).collect();
        assert_eq!(twelve, [0, 1, 2, 3, 4, 5, 6, 7, 0, 1, 2, 3]);
        // Every fold holds at least one run and trains on the others.
        for f in 0..8 {
            assert!(twelve.contains(&f));
        }
    }

    #[test]
    fn auto_chooses_the_lowest_scored_available_candidate_and_names_are_obeyed() {
        let s = vec![
            score("polach", Some(0.010)),
            score("mlp", Some(0.009)),
            score("mlp_3in", Some(0.007)),
            score("residual", Some(0.007)),
            score("mlp_4in", None),
        ];
        let all = [true; 5];
        let names: Vec<&str> = s.iter().map(|c| c.name.as_str()).collect();
        // A tie goes to the earlier candidate.
        assert_eq!(choose(ModelChoice::Auto, &names, &s, &all).unwrap().0, 2);
        // A candidate without a model file on all runs is not chosen.
        let no3 = [true, true, false, true, true];
        assert_eq!(choose(ModelChoice::Auto, &names, &s, &no3).unwrap().0, 3);
        // Unscored everywhere: the network of [train].
        let none: Vec<CandidateScore> = s.iter().map(|c| score(&c.name, None)).collect();
        let (i, why) = choose(ModelChoice::Auto, &names, &none, &all).unwrap();
        assert_eq!(none[i].name, "mlp");
        assert!(why.contains("no candidate"), "{why}");
        assert_eq!(choose(ModelChoice::Polach, &names, &[], &all).unwrap().0, 0);
        assert_eq!(
            choose(ModelChoice::Residual, &names, &[], &all).unwrap().0,
            3
        );
        let e = choose(
            ModelChoice::Polach,
            &names,
            &[],
            &[false, true, true, true, true],
        )
        .unwrap_err();
        assert!(e.to_string().contains("train.model = \"polach\""), "{e}");
    }
}
