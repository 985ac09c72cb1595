//! `railgrip run`: the whole job over a campaign folder, and `railgrip report`.

use std::io::IsTerminal as _;
use std::path::PathBuf;
use std::sync::Mutex;

use anyhow::bail;
use indicatif::{ProgressBar, ProgressStyle};
use railgrip::campaign::{self, Event, OutDir, RunRecord, Stage};
use serde::Serialize;

use super::{PipelineArg, EXIT_ERROR, EXIT_LOSSY, EXIT_OK};

#[derive(clap::Args)]
pub struct Args {
    /// Campaign folder (searched recursively for .csv + .meta.toml and .mcap logs) or archive
    /// (.zip, .tar, .tar.gz, .tar.zst; read in place); default: the bundled archive
    /// (fixtures/archive of this source tree).
    #[arg(value_name = "ARCHIVE")]
    archive: Option<PathBuf>,
    #[command(flatten)]
    pipeline: PipelineArg,
    /// Output folder.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Runs processed in parallel (default: one per core).
    #[arg(long, value_name = "N")]
    jobs: Option<usize>,
    /// Recompute every run even when its inputs and the pipeline are unchanged.
    #[arg(long)]
    force: bool,
    /// Print a machine-readable summary (JSON) on stdout instead of the table.
    #[arg(long)]
    json: bool,
    /// Also write runs/<run>/<run>.railgrip.mcap per run: slip, slip rate, N, T, μ, valid and
    /// the trained network's μ on the run, as JSON topics /railgrip/axle<i>/… at the input's
    /// log times, to open beside the original log in Foxglove.
    #[arg(long)]
    mcap: bool,
}

/// Progress on stderr: a bar per stage on a terminal, plain lines otherwise.
struct Bars {
    terminal: bool,
    estimate: Mutex<Option<ProgressBar>>,
    train: Mutex<Option<ProgressBar>>,
}

impl Bars {
    fn new() -> Bars {
        Bars {
            terminal: std::io::stderr().is_terminal(),
            estimate: Mutex::new(None),
            train: Mutex::new(None),
        }
    }
}

fn run_line(r: &RunRecord) -> String {
    match (r.ok(), r.reused) {
        (true, true) => format!("run        {}: unchanged, reused", r.run),
        (true, false) => format!("run        {}: ok ({:.2} s)", r.run, r.duration_s),
        _ => format!(
            "run        {}: FAILED: {}",
            r.run,
            r.error.as_deref().unwrap_or("")
        ),
    }
}

impl<'a> campaign::Progress<Event<'a>> for Bars {
    fn event(&self, e: Event<'a>) {
        match e {
            Event::EstimateStarts {
                runs,
                source,
                threads,
            } => {
                if self.terminal {
                    let bar = ProgressBar::new(runs as u64);
                    bar.set_style(
                        ProgressStyle::with_template(
                            "{prefix:>10} [{bar:30}] {pos}/{len} {elapsed_precise} {wide_msg}",
                        )
                        .expect("valid template")
                        .progress_chars("=> "),
                    );
                    bar.set_prefix("estimate");
                    *self.estimate.lock().expect("not poisoned") = Some(bar);
                } else {
                    eprintln!(
                        "estimate   {runs} run(s) from {} on {threads} thread(s)",
                        source.display()
                    );
                }
            }
            Event::RunDone(r) => {
                let line = run_line(r);
                match &*self.estimate.lock().expect("not poisoned") {
                    Some(b) => {
                        if !r.ok() {
                            b.println(line.clone());
                        }
                        b.set_message(line);
                        b.inc(1);
                    }
                    None => eprintln!("{line}"),
                }
            }
            Event::TrainStarts => {
                if self.terminal {
                    let b = ProgressBar::new_spinner();
                    b.set_style(
                        ProgressStyle::with_template(
                            "{prefix:>10} {spinner} {elapsed_precise} {wide_msg}",
                        )
                        .expect("valid template"),
                    );
                    b.set_prefix("train");
                    b.enable_steady_tick(std::time::Duration::from_millis(120));
                    *self.train.lock().expect("not poisoned") = Some(b);
                } else {
                    eprintln!("train      network and Polach fits on the pooled estimates");
                }
            }
            Event::Epoch(e) => {
                if let Some(b) = &*self.train.lock().expect("not poisoned") {
                    b.set_message(format!(
                        "epoch {}  train MSE {:.3e}  val MSE {:.3e}",
                        e.epoch, e.train_mse, e.val_mse
                    ));
                }
            }
            Event::StageDone(stage) => {
                let slot = match stage {
                    Stage::Estimate => &self.estimate,
                    Stage::Train => &self.train,
                    Stage::Report => return,
                };
                if let Some(b) = slot.lock().expect("not poisoned").take() {
                    b.finish_and_clear();
                }
            }
        }
    }
}

#[derive(Serialize)]
struct JsonSummary<'a> {
    archive: String,
    out: String,
    runs: &'a [RunRecord],
    failed: usize,
    reused: usize,
    condition: &'a Option<String>,
    models: Vec<String>,
    model_error: &'a Option<String>,
    audit: &'a Option<railgrip::model::AuditSpec>,
    notes: &'a [String],
    /// Files of the campaign that are not logs, with why.
    skipped: &'a [campaign::Skipped],
    report: Option<String>,
    /// Wall time per stage, s.
    stages: &'a [(String, f64)],
    exit_code: u8,
}

pub fn run(args: Args) -> anyhow::Result<u8> {
    let pipeline = args.pipeline.load()?;
    let root = match &args.archive {
        Some(a) => a.clone(),
        None => {
            let b = campaign::bundled_archive();
            if !b.is_dir() {
                bail!(
                    "{}: the bundled archive is not there (this binary was built from another source tree). Hint: give a campaign folder: railgrip run <FOLDER>",
                    b.display()
                );
            }
            b
        }
    };
    let out = OutDir::new(&args.out);
    let options = campaign::Options {
        jobs: args.jobs,
        force: args.force,
        mcap: args.mcap,
    };
    let o = campaign::run(&root, &out, &pipeline, options, &Bars::new())?;
    let failed = o.failed();
    let audit_failed = o.audit.as_ref().is_some_and(|a| !a.passed);
    // No models is an error (exit 1) even when runs failed too: the help promises it, and a
    // script must not read "completed" from a campaign that produced nothing (issue 17).
    let code = if o.model_error.is_some() {
        EXIT_ERROR
    } else if failed > 0 || audit_failed {
        EXIT_LOSSY
    } else {
        EXIT_OK
    };
    if args.json {
        let s = JsonSummary {
            archive: root.display().to_string(),
            out: args.out.display().to_string(),
            runs: &o.records,
            failed,
            reused: o.reused(),
            condition: &o.condition,
            models: o.models.iter().map(|p| p.display().to_string()).collect(),
            model_error: &o.model_error,
            audit: &o.audit,
            notes: &o.notes,
            skipped: &o.skipped,
            report: o.report.as_ref().map(|p| p.display().to_string()),
            stages: &o.stages,
            exit_code: code,
        };
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(code);
    }
    print_outcome(&o, &out);
    Ok(code)
}

/// The table of runs, failures, notes, files written and stage times.
fn print_outcome(o: &campaign::Outcome, out: &OutDir) {
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
    if let Some(c) = &o.condition {
        println!("\nmodels     trained on {c} rail");
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
    let st: Vec<String> = o
        .stages
        .iter()
        .map(|(s, t)| format!("{s} {t:.2} s"))
        .collect();
    println!("time       {}", st.join(", "));
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

#[derive(clap::Args)]
pub struct ReportArgs {
    /// An output folder of `railgrip run`.
    #[arg(value_name = "OUT_DIR")]
    out: PathBuf,
}

pub fn report(args: ReportArgs) -> anyhow::Result<u8> {
    let p = railgrip::report::write_report(&OutDir::new(&args.out))?;
    println!("report     {}", p.display());
    Ok(EXIT_OK)
}
