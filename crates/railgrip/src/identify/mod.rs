//! Identification: the adhesion curve μ(Δv, dΔv/dt[, v, T]) learned from the estimates by the
//! model families — the seed 002 network (002_8d8769283f5e9cb6.txt, "Neural network" and
//! Fig. 9–11), Polach's law (seed 004 eq. 1–2) and Polach's law with its temperature law
//! (seed 004 eq. 3, Fig. 2).
//!
//! [`family`] is the one seam: every family is a [`ModelFamily`], fitted on run tables with a
//! pipeline into a model file, its shape and its report; [`campaign_models`] is what a campaign
//! trains. Below it: [`dataset`] turns estimates into training/validation sets, [`mlp`] is the
//! network and its analytic Jacobian, [`problem`] its least-squares problem, [`lm`] the
//! trainlm-style solver (an argmin `Solver`), [`train`] multi-start training and ensembles,
//! [`adam`] networks of any depth by mini-batch Adam/AdamW through burn; [`polach`] the Polach
//! fits, profiles and temperature law; [`held_out`] held-out scores and leave-one-run-out;
//! [`campaign`] the rail condition, median speed, patch and creep region a campaign's fits
//! share; [`support`] the data support and the audit; [`export`] the model files; [`choice`]
//! the campaign's model chosen among the candidates by held-out runs.

pub mod adam;
pub mod campaign;
pub mod choice;
pub mod dataset;
pub mod export;
pub mod family;
pub mod held_out;
pub mod lm;
pub mod mlp;
pub mod polach;
pub mod problem;
pub mod support;
pub mod train;

pub use crate::model::InputSet;
pub use campaign::{
    creep_spec, median_speed, pipeline_patch, pooled_thinning, run_condition, select_condition,
    CampaignRun, ConditionChoice,
};
pub use dataset::{Dataset, EstimateColumns, MapMinMax, RunTable};
pub use family::{campaign_models, CampaignFit, FitData, Fitted, ModelFamily, FAMILIES};
pub use held_out::{held_out_score, leave_one_run_out, HeldOut, HeldOutFile};
pub use problem::MlpProblem;
pub use train::{train_mlp, train_on, TrainedMlp};

/// Why identification failed.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    #[error("{file}: {message}. Hint: {hint}")]
    Input {
        file: String,
        message: String,
        hint: String,
    },
    /// A table the table reader refuses.
    #[error("{file}: {source}. Hint: {hint}")]
    Table {
        file: String,
        #[source]
        source: polars::error::PolarsError,
        hint: String,
    },
    #[error("{file}: cannot read: {source}")]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{what}. Hint: {hint}")]
    Data { what: String, hint: String },
    /// The solver stopped with an error (not a convergence failure: LM reports those as stop
    /// reasons).
    #[error("{fit}: the solver failed: {source}")]
    Solver {
        fit: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A family fitted its report but could not give a model file from it (the pooled fit
    /// failed, no temperature law was chosen where one is required).
    #[error("{why}")]
    NotFitted { why: &'static str },
    /// A fit produced parameters outside the model file's valid domain.
    #[error("{group}: {defect}. Hint: the Polach fit left its valid domain; check the estimates it was fitted to")]
    InvalidModel {
        group: String,
        #[source]
        defect: crate::model::Defect,
    },
}
