//! A campaign's models from its run tables: one rail condition selected, the seed 002 network
//! trained, Polach fits (pooled, per run, per temperature) and k(T), and the model files built —
//! shared by `railgrip train` and `railgrip run`.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use super::pool::{into_tables, PooledRun};
use super::{CampaignError, ModelPaths};
use crate::config::Pipeline;
use crate::identify::choice::Choice;
use crate::identify::dataset::RunTable;
use crate::identify::family::{campaign_models, FitData};
use crate::identify::lm::EpochProgress;
use crate::identify::polach::PolachReport;
use crate::identify::{
    pooled_thinning, select_condition, CampaignRun, HeldOut, HeldOutFile, IdentifyError, TrainedMlp,
};
use crate::model::{c_header, Epoch, InputFile, ModelFile, Provenance};
use crate::table::{Cell, CsvText};

/// Everything trained from a campaign.
#[derive(Debug)]
pub struct CampaignModels {
    /// The rail condition that trained the models, and the runs left out with theirs.
    pub condition: String,
    pub skipped: Vec<(String, String)>,
    /// Runs and valid samples used.
    pub runs: usize,
    pub samples: usize,
    pub trained: TrainedMlp,
    /// Kind mlp.
    pub mlp: ModelFile,
    pub polach_fits: PolachReport,
    /// Kind polach (pooled fit, with k(T) when it passed its checks); None when the pooled fit
    /// failed.
    pub polach: Option<ModelFile>,
    /// Fits that failed, k(T) left out, and why.
    pub notes: Vec<String>,
    /// Leave-one-run-out scores (empty when switched off or with one run).
    pub held_out: Vec<HeldOut>,
    /// The other candidates of the model choice, by name.
    pub others: Vec<(String, ModelFile)>,
    /// The model choice: the candidates' held-out scores and the chosen one.
    pub choice: Choice,
}

/// Trains the campaign's models ([`campaign_models`]) from the runs of one rail condition of
/// `tables` with the pipeline's `[train]` settings. `progress` sees every epoch of the network's
/// training.
pub fn train_models(
    tables: Vec<RunTable>,
    pipeline: &Pipeline,
    progress: Option<EpochProgress<'_>>,
) -> Result<CampaignModels, IdentifyError> {
    train_pooled(
        tables.into_iter().map(PooledRun::from).collect(),
        pipeline,
        progress,
    )
}

/// [`train_models`] from runs whose tables may be parked in their estimates files
/// ([`super::pool`]): each is read back, thinned, when the condition and the thinning are
/// known. The same models as from the tables themselves.
pub fn train_pooled(
    runs: Vec<PooledRun>,
    pipeline: &Pipeline,
    progress: Option<EpochProgress<'_>>,
) -> Result<CampaignModels, IdentifyError> {
    let choice = select_condition(runs, pipeline.train.condition.as_deref())?;
    let limit = pipeline.train.max_pooled_samples;
    let thinning = pooled_thinning(&choice.used, limit);
    let pooled: usize = choice.used.iter().flat_map(|r| r.axle_counts()).sum();
    let tables = into_tables(choice.used, thinning)?;
    let samples = tables.iter().map(|t| t.len()).sum();
    let provenance = Provenance {
        inputs: tables
            .iter()
            .map(|t| InputFile {
                path: t.source.clone(),
                sha256: t.sha256.clone(),
            })
            .collect(),
        pipeline: pipeline.source.clone(),
        pipeline_sha256: crate::hash::sha256_bytes(pipeline.text.as_bytes()),
        seed: pipeline.train.seed,
        crate_version: env!("CARGO_PKG_VERSION").into(),
        created: String::new(),
        generation: None,
        calibration: pipeline.calibrated.as_ref().map(|c| c.summary()),
    };
    let fit = campaign_models(FitData {
        tables: &tables,
        pipeline,
        provenance,
        fallback: None,
        epochs: progress,
        audit: true,
    })?;
    let mut notes = fit.notes;
    if thinning > 1 {
        notes.insert(
            0,
            format!(
                "the {pooled} pooled valid samples exceed train.max_pooled_samples = {limit}: one sample in {thinning} of each run and axle was kept ({samples} samples) for every fit and held-out score{} — raise the limit where memory allows (docs/benchmarks.md#how-it-grows-with-the-campaign)",
                match pipeline.train.decimate {
                    1 => String::new(),
                    d => format!(", which take one in {d} of these (train.decimate)"),
                }
            ),
        );
    }
    Ok(CampaignModels {
        condition: choice.condition,
        skipped: choice.skipped,
        runs: tables.len(),
        samples,
        trained: fit.trained,
        mlp: fit.mlp,
        polach_fits: fit.polach_fits,
        polach: fit.polach,
        notes,
        held_out: fit.held_out,
        others: fit.others,
        choice: fit.choice,
    })
}

impl CampaignModels {
    /// Writes, atomically: the network, its history, the Polach model (when there is one) and
    /// every fit, and with `headers` the C headers of both models (docs/model-files.md).
    /// Returns the paths written.
    pub fn write(&self, paths: &ModelPaths, headers: bool) -> Result<Vec<PathBuf>, CampaignError> {
        std::fs::create_dir_all(&paths.dir).map_err(|source| CampaignError::Write {
            path: paths.dir.clone(),
            source,
        })?;
        let mut written = Vec::new();
        let mut put = |path: PathBuf, text: String| -> Result<(), CampaignError> {
            crate::atomic::write_atomically(&path, |w| w.write_all(text.as_bytes())).map_err(
                |source| CampaignError::Write {
                    path: path.clone(),
                    source,
                },
            )?;
            written.push(path);
            Ok(())
        };
        put(paths.mlp(), self.mlp.to_json())?;
        put(paths.history_csv(), history_csv(&self.trained.history))?;
        if let Some(p) = &self.polach {
            put(paths.polach(), p.to_json())?;
        }
        let fits = serde_json::to_string_pretty(&self.polach_fits).expect("fits serialise") + "\n";
        put(paths.polach_fits(), fits)?;
        if !self.held_out.is_empty() {
            let file = HeldOutFile {
                generation: self.mlp.provenance.generation.clone(),
                runs: self.held_out.clone(),
            };
            let text = serde_json::to_string_pretty(&file).expect("scores serialise") + "\n";
            put(paths.leave_one_run_out(), text)?;
        }
        for (name, file) in &self.others {
            put(paths.candidate(name), file.to_json())?;
        }
        let choice = serde_json::to_string_pretty(&self.choice).expect("choice serialises") + "\n";
        put(paths.choice(), choice)?;
        if headers {
            for (name, file) in self.files() {
                let source = file_name(&paths.candidate(name));
                put(
                    paths.candidate_header(name),
                    c_header::c_header(file, &paths.candidate_prefix(name), &source),
                )?;
            }
        }
        // Files an earlier generation wrote and this one does not (no Polach model, scores
        // switched off, a candidate not fitted) are removed: nothing stale beside the new
        // models.
        let mut stale = vec![paths.leave_one_run_out()];
        for name in CANDIDATE_NAMES {
            stale.push(paths.candidate(name));
            stale.push(paths.candidate_header(name));
        }
        for p in stale {
            if !written.contains(&p) {
                match std::fs::remove_file(&p) {
                    Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                        return Err(CampaignError::Write { path: p, source: e })
                    }
                    _ => {}
                }
            }
        }
        Ok(written)
    }

    /// Every model file with its candidate name: the network of `[train]`, the Polach model,
    /// the other candidates.
    pub fn files(&self) -> Vec<(&str, &ModelFile)> {
        let mut f = vec![("mlp", &self.mlp)];
        if let Some(p) = &self.polach {
            f.push(("polach", p));
        }
        f.extend(self.others.iter().map(|(n, m)| (n.as_str(), m)));
        f
    }

    /// The chosen model's file (`None` when the choice names a model that was not written).
    pub fn chosen(&self) -> Option<&ModelFile> {
        self.files()
            .into_iter()
            .find(|(n, _)| *n == self.choice.chosen)
            .map(|(_, f)| f)
    }

    /// Marks every file of these models as written by campaign generation `g`.
    pub fn set_generation(&mut self, g: &str) {
        self.mlp.provenance.generation = Some(g.to_string());
        if let Some(p) = &mut self.polach {
            p.provenance.generation = Some(g.to_string());
        }
        for (_, f) in &mut self.others {
            f.provenance.generation = Some(g.to_string());
        }
        self.choice.generation = Some(g.to_string());
        self.polach_fits.generation = Some(g.to_string());
    }
}

/// Every candidate a campaign may write (`identify::choice::candidates`).
pub const CANDIDATE_NAMES: [&str; 6] =
    ["mlp", "polach", "mlp_2in", "mlp_3in", "mlp_4in", "residual"];

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The training history as CSV: epoch, train_mse, val_mse, mu, grad_norm, and gamma (the
/// effective number of parameters) with Bayesian regularisation. No elapsed time: the file is a
/// result, the same for the same inputs.
pub fn history_csv(h: &[Epoch]) -> String {
    let bayes = h.iter().any(|e| e.gamma.is_some());
    let mut header = vec!["epoch", "train_mse", "val_mse", "mu", "grad_norm"];
    if bayes {
        header.push("gamma");
    }
    let mut t = CsvText::new(&header);
    for e in h {
        let mut row = vec![
            Cell::Count(Some(e.epoch)),
            Cell::Real(Some(e.train_mse)),
            Cell::Real(Some(e.val_mse)),
            Cell::Real(Some(e.mu)),
            Cell::Real(Some(e.grad_norm)),
        ];
        if bayes {
            row.push(Cell::Real(Some(e.gamma.unwrap_or(f64::NAN))));
        }
        t.row(&row);
    }
    t.into_text()
}
