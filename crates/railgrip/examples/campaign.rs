//! Run a braking campaign as a library call — what `railgrip run` does, without the CLI:
//!
//! ```sh
//! cargo run --release --example campaign [ARCHIVE] [OUT]
//! ```
//!
//! Without arguments: the bundled archive of this source tree (`fixtures/archive`) into
//! `out-example/`. Progress arrives as events (here printed as lines); the outcome lists every
//! run, the models written and the report.

use std::path::PathBuf;

use railgrip::campaign::{self, Event, Options, OutDir};
use railgrip::{run_campaign, Model, Pipeline};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args_os().skip(1).map(PathBuf::from);
    let archive = args.next().unwrap_or_else(campaign::bundled_archive);
    let out = OutDir::new(args.next().unwrap_or_else(|| "out-example".into()));
    // The embedded UIC-Z1 pipeline; Pipeline::load(Some(path)) reads yours.
    let pipeline = Pipeline::load(None)?;
    // Any closure receives the campaign's events (the CLI draws progress bars from them).
    let progress = |e: Event<'_>| match e {
        Event::RunDone(r) => println!("run   {}: {}", r.run, if r.ok() { "ok" } else { "failed" }),
        Event::StageDone(s) => println!("stage {} done", s.name()),
        _ => {}
    };
    let outcome = run_campaign(&archive, &out, &pipeline, Options::default(), &progress)?;
    println!(
        "{} runs ({} failed)",
        outcome.records.len(),
        outcome.failed()
    );
    match (&outcome.condition, &outcome.model_error) {
        (Some(c), _) => println!("models trained on {c} rail"),
        (None, Some(e)) => println!("no models: {e}"),
        (None, None) => println!("no models"),
    }
    for p in &outcome.models {
        println!("wrote {}", p.display());
    }
    // The network the campaign exported, evaluated like a simulator would.
    let model = Model::load(&out.models().mlp())?;
    println!(
        "network μ at Δv = 1 m/s, dΔv/dt = 0.5 m/s²: {:.4}",
        model.mu(1.0, 0.5)
    );
    if let Some(r) = &outcome.report {
        println!("report {}", r.display());
    }
    Ok(())
}
