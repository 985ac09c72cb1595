//! railgrip learns wheel–rail adhesion curves from railway braking-test logs.
//!
//! Data flows one way (see ARCHITECTURE.md): [`ingest`] reads a log (CSV or MCAP, any column
//! names and units) into a [`ingest::RunLog`] on a uniform time base in canonical units.
//! [`format`] owns every channel name, column, topic and unit of the log format; [`config`]
//! holds the validated pipeline file. [`signal`] filters and differentiates the signals,
//! [`estimate`] turns them into slip, loads, forces and μ per axle and sample (and calibrates
//! the brake coefficient); [`vehicle`] is the load-transfer model they share with [`sim`].
//!
//! The library never prints, exits or reads the terminal; the `railgrip` binary does.

pub mod archive;
pub mod campaign;
pub mod config;
pub mod estimate;
pub mod format;
pub mod fuzzing;
pub mod hash;
pub mod identify;
pub mod ingest;
pub mod linalg;
pub mod outdir;
pub mod progress;
pub mod replay;
pub mod report;
pub mod rng;
pub mod score;
pub mod signal;
pub mod sim;
pub mod study;
pub mod table;
pub mod units;
pub mod vehicle;

pub use railgrip_contact as contact;
pub(crate) use railgrip_io::{atomic, input};
pub use railgrip_model as model;
pub(crate) use railgrip_simd as simd;

pub use config::Pipeline;
pub use ingest::{ingest_file, RunLog};

/// The root of the source tree this library was built from, where `fixtures/` and
/// `pipelines/` live (the bundled archive and the study's scenes).
pub(crate) fn source_tree() -> &'static std::path::Path {
    let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest.ancestors().nth(2).unwrap_or(manifest)
}
