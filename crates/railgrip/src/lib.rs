//! railgrip learns wheel–rail adhesion curves from railway braking-test logs: it reads the logs
//! of a braking campaign (CSV or MCAP, any column names and units), estimates the adhesion
//! coefficient μ per axle and sample, identifies μ(Δv, dΔv/dt[, v, T]) with a seed 002 network
//! and Polach's law, and writes model files, C headers and a validation report.
//!
//! A campaign in ten lines — what `railgrip run` does:
//!
//! ```no_run
//! use railgrip::campaign::{Options, OutDir, Quiet};
//! use railgrip::{run_campaign, Model, Pipeline};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let pipeline = Pipeline::load(None)?; // the embedded UIC-Z1 pipeline; Some(path) for yours
//! let out = OutDir::new("out");
//! let outcome = run_campaign("fixtures/archive".as_ref(), &out, &pipeline, Options::default(), &Quiet)?;
//! println!("{} runs, {} failed; models in {}", outcome.records.len(), outcome.failed(), out.models().dir.display());
//! let model = Model::load(&out.models().mlp())?;
//! println!("μ at Δv = 1 m/s, dΔv/dt = 0.5 m/s²: {:.4}", model.mu(1.0, 0.5));
//! # Ok(())
//! # }
//! ```
//!
//! The front doors: [`run_campaign`] (the main job: [`campaign`]), [`run_study`] (what accuracy
//! costs in time: [`study`]), [`Pipeline`] (the checked pipeline file: [`config`]), [`Model`]
//! (a model file ready to evaluate; the lean `railgrip-model` crate, re-exported as [`model`]),
//! [`sim::simulate`] (a braking scene: [`sim`]) and [`contact`] (the contact-mechanics library).
//! Long work reports through [`progress::Progress`].
//!
//! Data flows one way (ARCHITECTURE.md): [`ingest`] reads a log into a [`ingest::RunLog`] on a
//! uniform time base in canonical units; [`format`] owns every channel name, column, topic and
//! unit of the log format; [`signal`] filters and differentiates the signals; [`estimate`]
//! turns them into slip, loads, forces and μ per axle and sample (and calibrates the brake
//! coefficient); [`identify`] fits the model families ([`identify::ModelFamily`]); [`report`]
//! writes the HTML report; [`vehicle`] is the load-transfer model shared with [`sim`].
//!
//! The library never prints, exits or reads the terminal; the `railgrip` binary does.

pub mod archive;
pub mod campaign;
pub mod config;
pub mod estimate;
pub mod fmu;
pub mod format;
#[cfg(feature = "fuzzing")]
pub mod fuzzing;
pub(crate) mod hash;
pub mod identify;
pub mod ingest;
pub(crate) mod linalg;
pub(crate) mod outdir;
pub(crate) mod parallel;
pub mod progress;
pub mod replay;
pub mod report;
pub(crate) mod rng;
pub mod score;
pub mod signal;
pub mod sim;
pub mod store;
pub mod study;
pub(crate) mod table;
pub(crate) mod units;
pub mod vehicle;

pub use railgrip_contact as contact;
pub(crate) use railgrip_io::{atomic, input};
pub use railgrip_model as model;
pub(crate) use railgrip_simd as simd;

pub use campaign::run as run_campaign;
pub use config::Pipeline;
pub use ingest::{ingest_file, RunLog};
pub use model::Model;
pub use study::run as run_study;
