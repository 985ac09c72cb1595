//! `railgrip report`, and the table `railgrip run` prints of a campaign's outcome.

use std::path::PathBuf;

use railgrip::campaign::{self, OutDir};

use super::EXIT_OK;

/// The table of runs, failures, notes, files written and stage times.
pub(super) fn print_outcome(o: &campaign::Outcome, out: &OutDir) {
    print_runs(o);
    if let Some(c) = &o.condition {
        println!("\nmodels     trained on {c} rail");
    }
    if let Some(c) = &o.choice {
        super::model::print_candidates(c);
    }
    if let Some((path, c)) = o.chosen.as_ref().zip(o.choice.as_ref()) {
        println!("chosen     {} ({})", path.display(), c.why());
    }
    if let Some(e) = &o.model_error {
        println!("\nmodels     none: {e}");
    }
    for n in &o.notes {
        println!("note       {n}");
    }
    for p in &o.models {
        println!("wrote      {}", p.display());
    }
    println!("wrote      {}", out.summary_csv().display());
    println!("wrote      {}", out.summary_parquet().display());
    if let Some(r) = &o.report {
        println!("report     {}", r.display());
    }
    print_stages(o);
    let failed = o.failed();
    if let Some(a) = &o.audit {
        super::model::print_audit(a);
    }
    if o.model_error.is_some() {
        println!("\nNo models were trained (why: above). Exit code 1.");
    } else if failed > 0 {
        println!(
            "\n{failed} of {} run(s) failed (listed above and in summary.csv); the rest completed. Exit code 3.",
            o.records.len()
        );
    }
}

/// The runs' table, their failures and the campaign's files that are not logs.
fn print_runs(o: &campaign::Outcome) {
    println!(
        "\nrun                              status   peak μ (axles 1–4)          max Δv m/s (axles 1–4)"
    );
    let f = |v: &[Option<f64>; 4], d: usize| -> String {
        v.iter()
            .map(|x| x.map_or("–".to_string(), |x| format!("{x:.d$}")))
            .collect::<Vec<_>>()
            .join(" ")
    };
    for r in &o.records {
        let status = match (r.ok(), r.reused) {
            (true, true) => "reused",
            (true, false) => "ok",
            _ => "FAILED",
        };
        println!(
            "{:<32} {:<8} {:<27} {}",
            r.run,
            status,
            f(&r.peak_mu, 3),
            f(&r.max_dv_mps, 2)
        );
    }
    for r in o.records.iter().filter(|r| !r.ok()) {
        println!("failed     {}: {}", r.run, r.error.as_deref().unwrap_or(""));
    }
    for s in &o.skipped {
        println!("skipped    {}: {}", s.path.display(), s.reason);
    }
}

/// The wall time of each stage.
fn print_stages(o: &campaign::Outcome) {
    let st: Vec<String> = o
        .stages
        .iter()
        .map(|(s, t)| format!("{s} {t:.2} s"))
        .collect();
    println!("time       {}", st.join(", "));
}

/// What an estimate shard did: its runs, notes and time.
pub(super) fn print_shard(o: &campaign::Outcome) {
    if !o.records.is_empty() {
        print_runs(o);
    }
    for n in &o.notes {
        println!("note       {n}");
    }
    print_stages(o);
    let failed = o.failed();
    if failed > 0 {
        println!(
            "\n{failed} of {} run(s) failed (listed above); the rest completed. Exit code 3.",
            o.records.len()
        );
    }
}

#[derive(clap::Args)]
pub struct ReportArgs {
    /// An output folder of `railgrip run`.
    #[arg(value_name = "OUT_DIR")]
    out: PathBuf,
    /// Where each run's speeds, pressures and μ against Δv go: in index.html, on a page of
    /// their own per run (report/runs/<run>.html, linked from index.html), or inline up to 32
    /// estimated runs and on pages beyond (auto, what `railgrip run` writes).
    #[arg(long, value_enum, default_value_t = RunSectionsArg::Auto)]
    run_sections: RunSectionsArg,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum RunSectionsArg {
    Auto,
    Inline,
    Pages,
}

pub fn report(args: ReportArgs) -> anyhow::Result<u8> {
    use railgrip::report::RunSections;
    let sections = match args.run_sections {
        RunSectionsArg::Auto => RunSections::Auto,
        RunSectionsArg::Inline => RunSections::Inline,
        RunSectionsArg::Pages => RunSections::Pages,
    };
    let p = railgrip::report::write_report_as(&OutDir::new(&args.out), sections)?;
    println!("report     {}", p.display());
    Ok(EXIT_OK)
}
