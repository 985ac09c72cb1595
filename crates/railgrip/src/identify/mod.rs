//! Identification (seed 002 002_8d8769283f5e9cb6.txt, "Neural network" and Fig. 9–11): the
//! adhesion curve μ(Δv, dΔv/dt) learned by a tanh MLP trained with Levenberg–Marquardt.
//!
//! [`dataset`] turns estimates into training/validation sets, [`mlp`] is the network and its
//! analytic Jacobian, [`lm`] the trainlm-style solver (an argmin `Solver`), and [`train`] ties
//! them together. [`adam`] trains networks of any depth by mini-batch Adam/AdamW through burn.

pub mod adam;
pub mod campaign;
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
    creep_spec, median_speed, pipeline_patch, run_condition, select_condition, ConditionChoice,
};
pub use dataset::{Dataset, MapMinMax, RunTable};
pub use family::{FitData, Fitted, ModelFamily, FAMILIES};
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
    /// A fit produced parameters outside the model file's valid domain.
    #[error("{group}: {defect}. Hint: the Polach fit left its valid domain; check the estimates it was fitted to")]
    InvalidModel {
        group: String,
        #[source]
        defect: crate::model::Defect,
    },
}
