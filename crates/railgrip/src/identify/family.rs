//! One seam for model families: every way railgrip identifies μ from estimates — the network
//! (seed 002; Levenberg–Marquardt, or Adam/AdamW through burn for deeper ones), Polach's law
//! (seed 004 eq. 1–2), Polach's law with its temperature and speed laws (seed 004 eq. 3, Fig. 2)
//! and the residual network over that law — is a
//! [`ModelFamily`]: fitted on run tables of one rail condition with a pipeline, it gives a model
//! file, its shape and the fit's report. `railgrip run`, `railgrip train`, leave-one-run-out
//! validation and `railgrip study` call families through this trait only; [`FAMILIES`] is the
//! one list of the models a study grid's `train.model` may name.

use rayon::prelude::*;

use super::campaign::{creep_spec, median_speed, pipeline_patch};
use super::choice::{self, Choice};
use super::dataset::RunTable;
use super::export;
use super::held_out::{leave_one_run_out, HeldOut};
use super::lm::Epoch;
use super::polach::{fit_campaign, fit_campaign_form, FormChoice, PolachReport, PARAMETERS};
use super::support::projected_onto_slip;
use super::train::{audit_samples, train_mlp, TrainedMlp};
use super::IdentifyError;
use crate::config::Pipeline;
use crate::config::{ModelChoice, TrainConfig, Trainer};
use crate::model::{Model, ModelFile, Provenance};
use crate::progress::Progress;

/// What a family is fitted from.
pub struct FitData<'a> {
    /// The runs (their valid estimates), all of one rail condition.
    pub tables: &'a [RunTable],
    /// The pipeline: `[train]` sets the fit, `[vehicle]` and `[contact]` the contact patch and
    /// the creep region.
    pub pipeline: &'a Pipeline,
    /// Written into the model file.
    pub provenance: Provenance,
    /// A model the fitted one blends to outside its data support (a network's fallback: the
    /// campaign's Polach model); `None`: no fallback.
    pub fallback: Option<&'a Model>,
    /// Sees every epoch of an iterative training.
    pub epochs: Option<&'a dyn for<'e> Progress<&'e Epoch>>,
    /// Run the network's plausibility audit into its file (docs/model-files.md); off for
    /// fits that are only scored on held-out runs and then dropped (the model choice's
    /// folds, leave-one-run-out), where it would cost about a tenth of the training.
    pub audit: bool,
}

/// What a fitted model looks like, for tables and reports.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Shape {
    /// `2-10-1` for a network; `polach`, `polach+k(T)`.
    pub architecture: String,
    pub parameters: usize,
    /// Samples the fit saw (networks: training + validation; Polach: the pooled fit's).
    pub train_samples: usize,
    /// Epochs (networks) or LM iterations (Polach).
    pub epochs: usize,
}

/// A family's own account of its fit.
#[derive(Debug)]
pub enum Report {
    Network(Box<TrainedMlp>),
    Polach(Box<PolachReport>),
}

impl Report {
    /// The network's training, when this is a network's report.
    pub fn into_network(self) -> Option<TrainedMlp> {
        match self {
            Report::Network(t) => Some(*t),
            Report::Polach(_) => None,
        }
    }

    /// The Polach fits, when this is a Polach family's report.
    pub fn into_polach(self) -> Option<PolachReport> {
        match self {
            Report::Polach(r) => Some(*r),
            Report::Network(_) => None,
        }
    }
}

/// A fitted family.
#[derive(Debug)]
pub struct Fitted {
    /// The model file, or why the fit gave none (the report is kept either way: the Polach
    /// fits of a campaign are written even when the pooled one failed).
    pub model: Result<ModelFile, IdentifyError>,
    pub shape: Shape,
    pub report: Report,
    /// What the fit left out and why (runs not fitted, a temperature law dropped).
    pub notes: Vec<String>,
}

/// What a family needs of the runs' ambient temperatures (run metadata
/// `ambient_temperature_c`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TemperatureNeed {
    /// Nothing.
    None,
    /// Every run must carry one (networks with the temperature input).
    EveryRun,
    /// Every run must carry one and there must be two or more distinct ones (a law in T).
    TwoOrMore,
}

/// A way of identifying μ from estimates.
pub trait ModelFamily: Send + Sync + std::fmt::Debug {
    /// The family's name in plans (a grid's `train.model`), tables and reports (`mlp`,
    /// `residual`, `polach`, `polach_pooled`, `polach_kt`).
    fn name(&self) -> &'static str;
    /// What the fit needs of the runs' ambient temperatures with these `[train]` settings.
    fn temperatures(&self, train: &TrainConfig) -> TemperatureNeed;
    /// Rough wall time of a fit to `samples` valid samples, s (release build, 2 cores;
    /// calibrated on the bundled archive; docs/study.md compares it with measured times).
    /// Plans refuse work over their time budget with it.
    fn estimated_seconds(&self, train: &TrainConfig, samples: usize) -> f64;
    /// Fits the family. An error means no fit at all (bad settings, no data); a fit that gives
    /// a report but no model file says why in [`Fitted::model`].
    fn fit(&self, data: &FitData<'_>) -> Result<Fitted, IdentifyError>;
}

/// The seed 002 network of `[train]`: `layers`, `inputs`, trained by Levenberg–Marquardt
/// (trainlm or trainbr) or by Adam/AdamW through burn, with the pipeline's creep region and,
/// when given, the fallback outside its data support.
#[derive(Debug, Clone, Copy, Default)]
pub struct Network;

impl ModelFamily for Network {
    fn name(&self) -> &'static str {
        "mlp"
    }

    fn temperatures(&self, train: &TrainConfig) -> TemperatureNeed {
        if train.inputs.has_temperature() {
            TemperatureNeed::EveryRun
        } else {
            TemperatureNeed::None
        }
    }

    fn estimated_seconds(&self, cfg: &TrainConfig, samples: usize) -> f64 {
        let n = (samples / cfg.decimate.max(1)) as f64;
        let arch = super::mlp::Arch {
            inputs: cfg.inputs.count(),
            hidden: cfg.layers.clone(),
        };
        let p = arch.n_params() as f64;
        let starts = cfg.starts.max(1) as f64;
        match cfg.trainer {
            Trainer::Lm => {
                // trainbr has no validation stop: it runs longer.
                let cap = if cfg.bayesian { 400.0 } else { 150.0 };
                let epochs = (cfg.epochs as f64).min(cap);
                starts * epochs * n * (8e-10 * p + 8e-12 * p * p)
            }
            Trainer::Burn(_) => {
                let epochs = (cfg.epochs as f64).min(80.0);
                epochs * n * 3e-9 * p
            }
        }
    }

    fn fit(&self, d: &FitData<'_>) -> Result<Fitted, IdentifyError> {
        let mut t = train_mlp(d.tables, &d.pipeline.train, d.epochs)?;
        t.reference_speed_mps = median_speed(d.tables);
        let creep = creep_spec(d.pipeline, t.reference_speed_mps)?;
        let file =
            export::network_file(&t, creep, d.provenance.clone(), d.fallback, None, d.audit)?;
        Ok(Fitted {
            model: Ok(file),
            shape: Shape {
                architecture: t.arch.to_string(),
                parameters: t.arch.n_params(),
                train_samples: t.n_train + t.n_val,
                epochs: t.history.len(),
            },
            report: Report::Network(Box::new(t)),
            notes: Vec::new(),
        })
    }
}

/// Polach's law with constant parameters: the pooled fit of all runs (per-run and
/// per-temperature fits in the report).
#[derive(Debug, Clone, Copy, Default)]
pub struct Polach {
    /// Profile-likelihood intervals of the pooled and per-temperature fits (about 30 refits
    /// per fit).
    pub intervals: bool,
}

/// Polach's law with its temperature law μ0(T), k_A(T), k_S(T) as the data choose it (BIC).
#[derive(Debug, Clone, Copy, Default)]
pub struct PolachWithLaws {
    /// As [`Polach::intervals`].
    pub intervals: bool,
    /// Without a temperature law the fit gives no model (a study's `polach_kt` cell); otherwise
    /// the model is written without the law, and a law the model file refuses is dropped with a
    /// note (a campaign's Polach model).
    pub law_required: bool,
    /// Refit this form only (no BIC search, no per-run or per-temperature fits): the model
    /// choice's folds refit the form the campaign chose.
    pub pinned: Option<FormChoice>,
}

const POOLED_FAILED: &str = "the pooled Polach fit failed (see `railgrip train` for why)";

/// Every Polach fit of the runs (pooled, per run, per temperature, the temperature forms).
fn polach_fits(
    d: &FitData<'_>,
    intervals: bool,
    pinned: Option<FormChoice>,
) -> Result<(PolachReport, Vec<String>, PolachFile), IdentifyError> {
    let (patch, wheel_load_n) = pipeline_patch(d.pipeline)?;
    let cfg = &d.pipeline.train;
    let (report, notes) = match pinned {
        Some(form) => fit_campaign_form(d.tables, patch, wheel_load_n, cfg.decimate, form),
        None => fit_campaign(
            d.tables,
            patch,
            wheel_load_n,
            cfg.decimate,
            cfg.temperature_degree,
            intervals,
        ),
    };
    let file = PolachFile {
        patch,
        wheel_load_n,
        reference_speed_mps: median_speed(d.tables),
    };
    Ok((report, notes, file))
}

/// What a Polach model file needs besides the fit.
struct PolachFile {
    patch: crate::contact::polach::ContactPatch,
    wheel_load_n: f64,
    reference_speed_mps: f64,
}

impl PolachFile {
    /// The model file of the pooled fit, with `law` when given.
    fn write(
        &self,
        report: &PolachReport,
        law: Option<&super::polach::TemperatureFit>,
        provenance: &Provenance,
    ) -> Result<ModelFile, IdentifyError> {
        let pooled = report
            .pooled
            .as_ref()
            .ok_or(IdentifyError::NotFitted { why: POOLED_FAILED })?;
        export::polach_file(
            pooled,
            &self.patch,
            self.wheel_load_n,
            law,
            report.dv_range_mps,
            report.v_range_mps,
            self.reference_speed_mps,
            report.creepage.as_ref().and_then(|c| c.speed()),
            provenance.clone(),
        )
    }
}

fn polach_shape(report: &PolachReport, architecture: &str) -> Shape {
    let (train_samples, epochs) = report
        .pooled
        .as_ref()
        .map_or((0, 0), |p| (p.samples, p.iterations));
    Shape {
        architecture: architecture.into(),
        parameters: PARAMETERS.len(),
        train_samples,
        epochs,
    }
}

impl ModelFamily for Polach {
    fn name(&self) -> &'static str {
        "polach_pooled"
    }

    fn temperatures(&self, _: &TrainConfig) -> TemperatureNeed {
        TemperatureNeed::None
    }

    fn estimated_seconds(&self, cfg: &TrainConfig, samples: usize) -> f64 {
        1.0 + 1e-5 * (samples / cfg.decimate.max(1)) as f64
    }

    fn fit(&self, d: &FitData<'_>) -> Result<Fitted, IdentifyError> {
        let (report, notes, file) = polach_fits(d, self.intervals, None)?;
        Ok(Fitted {
            model: file.write(&report, None, &d.provenance),
            shape: polach_shape(&report, "polach"),
            report: Report::Polach(Box::new(report)),
            notes,
        })
    }
}

impl ModelFamily for PolachWithLaws {
    fn name(&self) -> &'static str {
        if self.law_required {
            "polach_kt"
        } else {
            "polach"
        }
    }

    fn temperatures(&self, _: &TrainConfig) -> TemperatureNeed {
        if self.law_required {
            TemperatureNeed::TwoOrMore
        } else {
            TemperatureNeed::None
        }
    }

    fn estimated_seconds(&self, cfg: &TrainConfig, samples: usize) -> f64 {
        Polach::default().estimated_seconds(cfg, samples)
    }

    fn fit(&self, d: &FitData<'_>) -> Result<Fitted, IdentifyError> {
        let (report, mut notes, file) = polach_fits(d, self.intervals, self.pinned)?;
        let law = report.temperature.as_ref();
        let model = if self.law_required {
            match (&report.pooled, law) {
                (None, _) => Err(IdentifyError::NotFitted { why: POOLED_FAILED }),
                (Some(_), None) => Err(IdentifyError::NotFitted {
                    why: "the data chose no temperature law: k(T) is not identified on these runs",
                }),
                (Some(_), Some(law)) if !law.has_temperature_law() => Err(IdentifyError::NotFitted {
                    why: "the data chose no temperature law: k(T) is not identified on these runs",
                }),
                (Some(_), Some(law)) => file.write(&report, Some(law), &d.provenance),
            }
        } else if report.pooled.is_none() {
            // fit_campaign's notes say why.
            Err(IdentifyError::NotFitted { why: POOLED_FAILED })
        } else {
            match file.write(&report, law, &d.provenance) {
                Err(e) if law.is_some() => {
                    notes.push(format!(
                        "Polach model written without its temperature and speed laws: {e}"
                    ));
                    file.write(&report, None, &d.provenance)
                }
                other => other,
            }
            .inspect_err(|e| notes.push(format!("no Polach model file: {e}")))
        };
        let architecture = if self.law_required {
            "polach+k(T)"
        } else {
            "polach"
        };
        Ok(Fitted {
            model,
            shape: polach_shape(&report, architecture),
            report: Report::Polach(Box::new(report)),
            notes,
        })
    }
}

/// The grey-box network (`train.model = "residual"`): Polach's law with its temperature and
/// speed laws ([`PolachWithLaws`]; or `FitData::fallback` when that is a Polach model — a
/// campaign passes its own), then the network of `[train]` trained on the residual
/// μ − μ_P(Δv, v, T) of every sample (T the run's ambient temperature), the law embedded in
/// the file: μ = μ_P + N (docs/model-files.md, "Residual networks"). The law carries the speed
/// and temperature structure where the data thin out — outside the data support the residual
/// fades to its mean over the supported slip rates of the same sign (the law alone where no
/// slip rate at that slip is supported) — and the network the shape and the hysteresis it
/// misses.
#[derive(Debug, Clone, Copy, Default)]
pub struct Residual;

impl ModelFamily for Residual {
    fn name(&self) -> &'static str {
        "residual"
    }

    fn temperatures(&self, train: &TrainConfig) -> TemperatureNeed {
        Network.temperatures(train)
    }

    fn estimated_seconds(&self, cfg: &TrainConfig, samples: usize) -> f64 {
        Network.estimated_seconds(cfg, samples) + Polach::default().estimated_seconds(cfg, samples)
    }

    fn fit(&self, d: &FitData<'_>) -> Result<Fitted, IdentifyError> {
        let mut notes = Vec::new();
        let base = match d.fallback {
            Some(m) if m.file.polach.is_some() => m.clone(),
            _ => {
                let law = PolachWithLaws {
                    intervals: false,
                    law_required: false,
                    pinned: None,
                }
                .fit(d)?;
                notes.extend(law.notes);
                let file = law.model.map_err(|e| IdentifyError::Data {
                    what: format!("the residual network needs a Polach law to stand on: {e}"),
                    hint: "use train.model = \"mlp\" on these runs".into(),
                })?;
                Model::named(file, "the residual network's law").map_err(|e| {
                    IdentifyError::Data {
                        what: format!("the residual network's law: {e}"),
                        hint: "report this as a bug".into(),
                    }
                })?
            }
        };
        let residual: Vec<RunTable> = d.tables.iter().map(|t| minus_law(t, &base)).collect();
        let mut t = train_mlp(&residual, &d.pipeline.train, d.epochs)?;
        t.occupancy = projected_onto_slip(&t.occupancy);
        t.reference_speed_mps = median_speed(d.tables);
        // The audit compares the whole model with μ, not with the residual.
        if d.audit {
            t.data = audit_samples(d.tables, &d.pipeline.train)?;
        }
        let creep = creep_spec(d.pipeline, t.reference_speed_mps)?;
        let spec = base
            .file
            .polach
            .clone()
            .ok_or_else(|| wrong_report("residual network's law"))?;
        let file =
            export::network_file(&t, creep, d.provenance.clone(), None, Some(spec), d.audit)?;
        Ok(Fitted {
            model: Ok(file),
            shape: Shape {
                architecture: format!("polach+{}", t.arch),
                parameters: t.arch.n_params() + PARAMETERS.len(),
                train_samples: t.n_train + t.n_val,
                epochs: t.history.len(),
            },
            report: Report::Network(Box::new(t)),
            notes,
        })
    }
}

/// `t` with μ replaced by the residual μ − μ_P(Δv, v, T) over the law `base` (T the run's
/// ambient temperature; unknown: the law's reference).
fn minus_law(t: &RunTable, base: &Model) -> RunTable {
    let t_c = t.metadata.ambient_temperature_c.unwrap_or(f64::NAN);
    // The clone shares every column; μ alone is new.
    let mut r = t.clone();
    r.mu = (0..t.len())
        .map(|k| t.mu[k] - base.mu_vt(t.dv_mps[k], t.ddv_mps2[k], t.v_mps[k], t_c))
        .collect();
    r
}

/// What a campaign trains ([`campaign_models`]).
#[derive(Debug)]
pub struct CampaignFit {
    /// The network's training and its model file.
    pub trained: TrainedMlp,
    pub mlp: ModelFile,
    /// Every Polach fit, and the Polach model file when the pooled fit gave one.
    pub polach_fits: PolachReport,
    pub polach: Option<ModelFile>,
    /// The other candidates fitted on all runs (`mlp_3in`, `residual`, …), by name.
    pub others: Vec<(String, ModelFile)>,
    /// Which candidate is the campaign's model, and every candidate's held-out scores.
    pub choice: Choice,
    /// What the fits left out and why.
    pub notes: Vec<String>,
    /// The network's leave-one-run-out scores (empty when `train.leave_one_run_out` is off).
    pub held_out: Vec<HeldOut>,
}

impl CampaignFit {
    /// The chosen model's file.
    pub fn chosen(&self) -> Option<&ModelFile> {
        match self.choice.chosen.as_str() {
            "mlp" => Some(&self.mlp),
            "polach" => self.polach.as_ref(),
            name => self.others.iter().find(|(n, _)| n == name).map(|(_, f)| f),
        }
    }
}

/// The models of a campaign, as `railgrip run` and `railgrip train` train them: Polach's law
/// with its temperature and speed laws as the data choose them ([`PolachWithLaws`]; a law the
/// model file refuses is dropped with a note), the network of `[train]` ([`Network`]), which
/// blends to the Polach model outside its data support (docs/model-files.md, "Data support"),
/// the other candidates of `train.model` ([`choice::candidates`]; in parallel), with
/// `train.model = "auto"` every candidate's held-out scores and the choice
/// ([`choice::score_candidates`], [`choice::choose`]), and with `train.leave_one_run_out` the
/// network's leave-one-run-out scores. `data.fallback` is ignored: the Polach model is the
/// networks' fallback and the residual network's law.
pub fn campaign_models(data: FitData<'_>) -> Result<CampaignFit, IdentifyError> {
    let (pipeline, tables) = (data.pipeline, data.tables);
    let cands = choice::candidates(pipeline, tables);
    let polach = PolachWithLaws {
        intervals: pipeline.train.polach_intervals,
        law_required: false,
        pinned: None,
    }
    .fit(&data)?;
    let mut notes = polach.notes;
    let polach_shape = polach.shape.clone();
    let polach_fits = polach
        .report
        .into_polach()
        .ok_or_else(|| wrong_report("Polach"))?;
    let polach = polach.model.ok();
    let fallback = match &polach {
        Some(p) => {
            Some(
                Model::named(p.clone(), "Polach model").map_err(|e| IdentifyError::Data {
                    what: format!("the campaign's Polach model: {e}"),
                    hint: "report this as a bug".into(),
                })?,
            )
        }
        None => None,
    };
    // The form the Polach model file holds (a law the file refused is not refitted).
    let form = polach_fits
        .temperature
        .as_ref()
        .filter(|_| {
            polach
                .as_ref()
                .and_then(|p| p.polach.as_ref())
                .is_some_and(|s| s.temperature.is_some() || s.speed.is_some())
        })
        .map(|t| t.form_choice())
        .unwrap_or_default();
    // The folds take the creepage where the campaign did, with or without a law.
    let form = FormChoice {
        fixed_creepage_speed: polach_fits
            .creepage
            .as_ref()
            .is_some_and(|c| c.speed().is_some()),
        ..form
    };
    // The candidates on all runs beside the folds: both in parallel, so that no core idles
    // while a single-start network trains.
    let (fits, mut scores) = rayon::join(
        || fit_on_all_runs(&cands, &data, fallback.as_ref()),
        || {
            if pipeline.train.model == ModelChoice::Auto {
                let t = &pipeline.train;
                choice::score_candidates(&cands, tables, t.folds, t.decimate, form)
            } else {
                Vec::new()
            }
        },
    );
    let (network, rest) = fits?;
    notes.extend(network.notes);
    let network_shape = network.shape.clone();
    let trained = network
        .report
        .into_network()
        .ok_or_else(|| wrong_report("network"))?;
    let mlp = network.model?;
    let mut shapes = vec![
        (polach_shape.architecture.clone(), polach_shape.parameters),
        (network_shape.architecture.clone(), network_shape.parameters),
    ];
    let mut available = vec![polach.is_some(), true];
    let mut others = Vec::new();
    for (c, (shape, model, n)) in cands[2..].iter().zip(rest) {
        notes.extend(n);
        shapes.push((shape.architecture, shape.parameters));
        available.push(model.is_ok());
        match model {
            Ok(f) => others.push((c.name.clone(), f)),
            Err(e) => notes.push(format!("candidate {}: not fitted: {e}", c.name)),
        }
    }
    for (s, (architecture, parameters)) in scores.iter_mut().zip(&shapes) {
        s.architecture.clone_from(architecture);
        s.parameters = *parameters;
    }
    let names: Vec<&str> = cands.iter().map(|c| c.name.as_str()).collect();
    let (chosen, reason) = choice::choose(pipeline.train.model, &names, &scores, &available)?;
    let choice = Choice {
        setting: pipeline.train.model.name().into(),
        folds: if scores.is_empty() {
            0
        } else {
            tables.len().min(pipeline.train.folds)
        },
        candidates: scores,
        chosen: cands[chosen].name.clone(),
        reason,
        generation: None,
    };
    let held_out = network_held_out(&choice, tables, pipeline)?;
    Ok(CampaignFit {
        trained,
        mlp,
        polach_fits,
        polach,
        others,
        choice,
        notes,
        held_out,
    })
}

/// What [`fit_on_all_runs`] gives: the network of `[train]`, and per other candidate its shape,
/// its model file or why not, and its notes.
type AllRunFits = (Fitted, Vec<(Shape, Result<ModelFile, String>, Vec<String>)>);

/// The network of `[train]` (with `data.epochs`) and the candidates after it on all runs, in
/// parallel, each with the campaign's Polach model as fallback or base.
fn fit_on_all_runs(
    cands: &[choice::Candidate],
    data: &FitData<'_>,
    fallback: Option<&Model>,
) -> Result<AllRunFits, IdentifyError> {
    let (network, rest) = rayon::join(
        || {
            Network.fit(&FitData {
                tables: data.tables,
                pipeline: data.pipeline,
                provenance: data.provenance.clone(),
                fallback,
                epochs: data.epochs,
                audit: data.audit,
            })
        },
        || {
            cands[2..]
                .par_iter()
                .map(|c| {
                    match c.family(None).fit(&FitData {
                        tables: data.tables,
                        pipeline: &c.pipeline,
                        provenance: data.provenance.clone(),
                        fallback,
                        epochs: None,
                        audit: data.audit,
                    }) {
                        Ok(f) => (f.shape, f.model.map_err(|e| e.to_string()), f.notes),
                        Err(e) => (Shape::default(), Err(e.to_string()), vec![]),
                    }
                })
                .collect()
        },
    );
    Ok((network?, rest))
}

/// The network's leave-one-run-out scores: none when `train.leave_one_run_out` is off; the
/// model choice's folds of the network when it scored them (one run out at a time up to
/// `train.folds` runs, K folds beyond); else [`leave_one_run_out`]'s folds.
fn network_held_out(
    choice: &Choice,
    tables: &[RunTable],
    pipeline: &Pipeline,
) -> Result<Vec<HeldOut>, IdentifyError> {
    Ok(match choice.candidates.iter().find(|c| c.name == "mlp") {
        _ if !pipeline.train.leave_one_run_out => Vec::new(),
        Some(c) if c.runs.len() == tables.len() => c
            .runs
            .iter()
            .map(|r| HeldOut {
                run: r.run.clone(),
                samples: r.samples,
                rmse_mu: r.rmse_mu,
            })
            .collect(),
        _ => leave_one_run_out(&Network, tables, pipeline)?,
    })
}

/// A family's report of another kind than the family's own.
fn wrong_report(family: &str) -> IdentifyError {
    IdentifyError::Data {
        what: format!("the {family} fit returned another family's report"),
        hint: "report this as a bug".into(),
    }
}

/// The families a study grid's `train.model` may name, by [`ModelFamily::name`]: the values
/// of a pipeline's `train.model` but `auto` (`mlp`, `residual`, `polach` — Polach with the laws
/// BIC chooses, as `run` exports it) and two study-only Polach variants (`polach_pooled`
/// without laws, `polach_kt` with a temperature law required); as plans fit them (Polach
/// without profile intervals, which a study does not report).
pub const FAMILIES: [&dyn ModelFamily; 5] = [
    &Network,
    &Residual,
    &PolachWithLaws {
        intervals: false,
        law_required: false,
        pinned: None,
    },
    &Polach { intervals: false },
    &PolachWithLaws {
        intervals: false,
        law_required: true,
        pinned: None,
    },
];

/// The family of [`FAMILIES`] called `name`.
pub fn by_name(name: &str) -> Option<&'static dyn ModelFamily> {
    FAMILIES.iter().copied().find(|f| f.name() == name)
}
