//! `railgrip study`: a plan of cells over a campaign, each trained and measured
//! (railgrip::study).

use std::path::PathBuf;

use railgrip::study::{self, CellResult, Plan};

use super::EXIT_OK;

#[derive(clap::Args)]
pub struct Args {
    /// Campaign folder or archive (as for `railgrip run`); default: the bundled archive.
    #[arg(value_name = "ARCHIVE")]
    archive: Option<PathBuf>,
    /// Study plan (TOML); default: the embedded pipelines/study.toml.
    #[arg(long, value_name = "FILE")]
    plan: Option<PathBuf>,
    /// Base pipeline for every cell, replacing the plan's `study.pipeline`.
    #[arg(long, value_name = "FILE")]
    pipeline: Option<PathBuf>,
    /// Output folder (cells are kept there and reused by a later study).
    #[arg(long, value_name = "DIR", default_value = "study")]
    out: PathBuf,
    /// Cells trained side by side (default: one per core; 1 for training times without
    /// contention).
    #[arg(long, value_name = "N")]
    jobs: Option<usize>,
    /// Run a plan over its cell or estimated-time limit (study.max_cells, study.max_minutes).
    #[arg(long)]
    force: bool,
    /// Recommend the most accurate cell whose single-call evaluation takes at most this many
    /// ns per μ.
    #[arg(long, value_name = "NS")]
    budget_ns: Option<f64>,
    /// … and whose training took at most this many seconds.
    #[arg(long, value_name = "S")]
    budget_train_s: Option<f64>,
    /// Print study.json on stdout instead of the table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<u8> {
    let plan = Plan::load(args.plan.as_deref(), args.pipeline.as_deref())?;
    let archive = args
        .archive
        .clone()
        .unwrap_or_else(railgrip::campaign::bundled_archive);
    let bar = super::progress::CellBar::new();
    let options = study::Options {
        jobs: args.jobs,
        force: args.force,
        budget_ns: args.budget_ns,
        budget_train_s: args.budget_train_s,
    };
    let o = study::run(&archive, &plan, &args.out, options, &bar)?;
    bar.finish();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&o)?);
        return Ok(EXIT_OK);
    }
    let measure = if o.by_truth {
        "truth RMSE"
    } else {
        "held-out RMSE"
    };
    println!(
        "{:<62} {:>12} {:>6} {:>9} {:>9} {:>9} {:>11}",
        "cell (sorted by accuracy)", "net", "params", "train s", "ns/μ", "ns batch", measure
    );
    let mut cells: Vec<&CellResult> = o.cells.iter().collect();
    cells.sort_by(|a, b| a.accuracy(o.by_truth).total_cmp(&b.accuracy(o.by_truth)));
    for c in cells {
        let mark = if o.recommended.as_deref() == Some(c.key.as_str()) {
            "★ "
        } else {
            "  "
        };
        match &c.error {
            Some(e) => println!("{mark}{:<60} FAILED: {e}", c.name),
            None => println!(
                "{mark}{:<60} {:>12} {:>6} {:>9.2} {:>9.1} {:>9.1} {:>11.5}",
                c.name,
                c.architecture,
                c.parameters,
                c.train_s.unwrap_or(f64::NAN),
                c.eval.as_ref().map_or(f64::NAN, |e| e.single_ns),
                c.eval.as_ref().map_or(f64::NAN, |e| e.batch_ns),
                c.accuracy(o.by_truth)
            ),
        }
    }
    if !o.simulator.is_empty() {
        println!(
            "\n{:<44} {:>8} {:>8} {:>10} {:>12} {:>12}",
            "simulator scene", "step ms", "ref ms", "× real", "RMS μ err", "max |Δv| m/s"
        );
        for r in &o.simulator {
            println!(
                "{:<44} {:>8} {:>8} {:>10.0} {:>12.5} {:>12.4}",
                r.scene,
                r.step_ms,
                r.reference_step_ms,
                r.real_time_factor,
                r.rms_mu_error,
                r.max_v_error_mps
            );
        }
    }
    if !o.contact.is_empty() {
        println!(
            "\n{:<32} {:>10} {:>12} {:>12}  reference",
            "contact law", "ns/call", "RMS err/μN", "max err/μN"
        );
        for r in &o.contact {
            println!(
                "{:<32} {:>10.1} {:>12.2e} {:>12.2e}  {}",
                r.law, r.ns_per_call, r.rms_error, r.max_error, r.reference
            );
        }
    }
    for n in &o.notes {
        println!("note: {n}");
    }
    let paths = study::StudyPaths {
        root: args.out.clone(),
    };
    println!(
        "\nTrained on {} ({}), held out {}. Wrote {}, {} and {}.",
        o.condition,
        o.train_runs.join(", "),
        o.held_out.join(", "),
        paths.html().display(),
        paths.csv().display(),
        paths.json().display()
    );
    Ok(EXIT_OK)
}
