//! `railgrip run`: the whole job over a campaign folder, and `railgrip report`.

use std::io::IsTerminal as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use railgrip::campaign::{self, RunRecord};
use railgrip::identify::campaign::train_models;
use railgrip::ingest::LogSource;
use rayon::prelude::*;
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
}

/// The bundled archive of this source tree.
fn bundled_archive() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/archive")
}

/// Progress: a bar on a terminal, plain lines otherwise.
struct Progress {
    bar: Option<ProgressBar>,
}

impl Progress {
    fn new(len: u64, what: &str) -> Progress {
        if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new(len);
            bar.set_style(
                ProgressStyle::with_template(
                    "{prefix:>10} [{bar:30}] {pos}/{len} {elapsed_precise} {wide_msg}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            bar.set_prefix(what.to_string());
            Progress { bar: Some(bar) }
        } else {
            Progress { bar: None }
        }
    }
    fn line(&self, text: String) {
        match &self.bar {
            Some(b) => {
                b.set_message(text);
                b.inc(1);
            }
            None => eprintln!("{text}"),
        }
    }
    fn println(&self, text: String) {
        match &self.bar {
            Some(b) => b.println(text),
            None => eprintln!("{text}"),
        }
    }
    fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
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
    condition: Option<String>,
    models: Vec<String>,
    model_error: Option<String>,
    notes: Vec<String>,
    report: Option<String>,
    /// Wall time per stage, s.
    stages: Vec<(String, f64)>,
    exit_code: u8,
}

pub fn run(args: Args) -> anyhow::Result<u8> {
    let t_all = Instant::now();
    let pipeline = args.pipeline.load()?;
    let root = match &args.archive {
        Some(a) => a.clone(),
        None => {
            let b = bundled_archive();
            if !b.is_dir() {
                bail!(
                    "{}: the bundled archive is not there (this binary was built from another source tree). Hint: give a campaign folder: railgrip run <FOLDER>",
                    b.display()
                );
            }
            b
        }
    };
    // A folder, searched on disk, or an archive file, read in place.
    let logs: Vec<(String, LogSource)> = if root.is_file() {
        railgrip::archive::read_archive(&root, railgrip::archive::Limits::default())?
            .into_iter()
            .map(|s| (campaign::run_name(&root, s.name()), s))
            .collect()
    } else {
        campaign::discover(&root, Some(&args.out))?
            .into_iter()
            .map(|p| (campaign::run_name(&root, &p), LogSource::File(p)))
            .collect()
    };
    if logs.is_empty() {
        bail!(
            "{}: no .csv or .mcap logs found (searched recursively). Hint: give the folder that holds the campaign's logs",
            root.display()
        );
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create the output folder", args.out.display()))?;
    let runs_dir = args.out.join("runs");
    let mut stages = Vec::new();

    // Stage 1: every run, in parallel, each on its own.
    let t = Instant::now();
    let jobs = args.jobs.unwrap_or(0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .context("cannot start the worker threads")?;
    let progress = Progress::new(logs.len() as u64, "estimate");
    if progress.bar.is_none() {
        eprintln!(
            "estimate   {} run(s) from {} on {} thread(s)",
            logs.len(),
            root.display(),
            pool.current_num_threads()
        );
    }
    let results: Vec<(RunRecord, Option<railgrip::identify::RunTable>)> = pool.install(|| {
        logs.par_iter()
            .map(|(name, src)| {
                let name = name.clone();
                let (rec, table) =
                    campaign::process_run(src, &name, &runs_dir, &pipeline, args.force);
                let line = match (&rec.status[..], rec.reused) {
                    ("ok", true) => format!("run        {name}: unchanged, reused"),
                    ("ok", false) => format!("run        {name}: ok ({:.2} s)", rec.duration_s),
                    _ => format!(
                        "run        {name}: FAILED: {}",
                        rec.error.as_deref().unwrap_or("")
                    ),
                };
                if rec.status != "ok" && progress.bar.is_some() {
                    progress.println(line.clone());
                }
                progress.line(line);
                (rec, table)
            })
            .collect()
    });
    progress.finish();
    stages.push(("estimate".to_string(), t.elapsed().as_secs_f64()));
    let (records, tables): (Vec<RunRecord>, Vec<_>) = results.into_iter().unzip();
    let tables: Vec<_> = tables.into_iter().flatten().collect();
    let failed = records.iter().filter(|r| r.status != "ok").count();
    let reused = records.iter().filter(|r| r.reused).count();

    // Stage 2: the campaign's models.
    let t = Instant::now();
    let mut models_written = Vec::new();
    let mut model_error = None;
    let mut notes = Vec::new();
    let mut condition = None;
    if tables.is_empty() {
        model_error = Some("no run could be estimated, so no model was trained".to_string());
    } else {
        let bar = std::io::stderr().is_terminal().then(|| {
            let b = ProgressBar::new_spinner();
            b.set_style(
                ProgressStyle::with_template("{prefix:>10} {spinner} {elapsed_precise} {wide_msg}")
                    .expect("valid template"),
            );
            b.set_prefix("train");
            b.enable_steady_tick(std::time::Duration::from_millis(120));
            b
        });
        if bar.is_none() {
            eprintln!("train      network and Polach fits on the pooled estimates");
        }
        let b2 = bar.clone();
        let progress: railgrip::identify::lm::Progress = Box::new(move |e| {
            if let Some(b) = &b2 {
                b.set_message(format!(
                    "epoch {}  train MSE {:.3e}  val MSE {:.3e}",
                    e.epoch, e.train_mse, e.val_mse
                ));
            }
        });
        match train_models(tables, &pipeline, Some(progress)) {
            Ok(m) => {
                if let Some(b) = &bar {
                    b.set_message("Polach fits written");
                }
                condition = Some(m.condition.clone());
                notes.extend(m.notes.iter().cloned());
                for (run, c) in &m.skipped {
                    notes.push(format!(
                        "{run}: not used for the models (condition {c}; they train on {})",
                        m.condition
                    ));
                }
                models_written = m
                    .write(&args.out.join("models"), "mlp", true)
                    .with_context(|| format!("{}: cannot write the models", args.out.display()))?;
            }
            Err(e) => model_error = Some(e.to_string()),
        }
        if let Some(b) = bar {
            b.finish_and_clear();
        }
    }
    stages.push(("train".to_string(), t.elapsed().as_secs_f64()));

    // Stage 3: summary and report.
    let t = Instant::now();
    campaign::write_summary(&args.out, &records)?;
    campaign::CampaignRecord {
        archive: root.display().to_string(),
        runs: records.clone(),
        condition: condition.clone(),
        model_error: model_error.clone(),
        notes: notes.clone(),
        pipeline: pipeline.source.clone(),
        validation_axles: match &pipeline.train.split {
            railgrip::config::SplitConfig::Axles { val, .. } => val.clone(),
            _ => vec![],
        },
    }
    .write(&args.out)?;
    let report = match railgrip::report::write_report(&args.out) {
        Ok(p) => Some(p),
        Err(e) => {
            notes.push(format!("report: {e}"));
            None
        }
    };
    stages.push(("report".to_string(), t.elapsed().as_secs_f64()));
    stages.push(("total".to_string(), t_all.elapsed().as_secs_f64()));

    let code = if model_error.is_some() && failed == 0 {
        EXIT_ERROR
    } else if failed > 0 {
        EXIT_LOSSY
    } else {
        EXIT_OK
    };
    if args.json {
        let s = JsonSummary {
            archive: root.display().to_string(),
            out: args.out.display().to_string(),
            runs: &records,
            failed,
            reused,
            condition,
            models: models_written
                .iter()
                .map(|p| p.display().to_string())
                .collect(),
            model_error,
            notes,
            report: report.as_ref().map(|p| p.display().to_string()),
            stages,
            exit_code: code,
        };
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(code);
    }
    println!(
        "\nrun                              status   peak μ (axles 1–4)          max Δv m/s (axles 1–4)"
    );
    let f = |v: &[Option<f64>; 4], d: usize| -> String {
        v.iter()
            .map(|x| x.map_or("–".to_string(), |x| format!("{x:.d$}")))
            .collect::<Vec<_>>()
            .join(" ")
    };
    for r in &records {
        println!(
            "{:<32} {:<8} {:<27} {}",
            r.run,
            if r.status == "ok" {
                if r.reused {
                    "reused"
                } else {
                    "ok"
                }
            } else {
                "FAILED"
            },
            f(&r.peak_mu, 3),
            f(&r.max_dv_mps, 2)
        );
    }
    for r in records.iter().filter(|r| r.status != "ok") {
        println!("failed     {}: {}", r.run, r.error.as_deref().unwrap_or(""));
    }
    if let Some(c) = &condition {
        println!("\nmodels     trained on {c} rail");
    }
    if let Some(e) = &model_error {
        println!("\nmodels     none: {e}");
    }
    for n in &notes {
        println!("note       {n}");
    }
    for p in &models_written {
        println!("wrote      {}", p.display());
    }
    println!("wrote      {}", args.out.join("summary.csv").display());
    println!("wrote      {}", args.out.join("summary.parquet").display());
    if let Some(r) = &report {
        println!("report     {}", r.display());
    }
    let st: Vec<String> = stages
        .iter()
        .map(|(s, t)| format!("{s} {t:.2} s"))
        .collect();
    println!("time       {}", st.join(", "));
    if failed > 0 {
        println!(
            "\n{failed} of {} run(s) failed (listed above and in summary.csv); the rest completed. Exit code 3.",
            records.len()
        );
    }
    Ok(code)
}

#[derive(clap::Args)]
pub struct ReportArgs {
    /// An output folder of `railgrip run`.
    #[arg(value_name = "OUT_DIR")]
    out: PathBuf,
}

pub fn report(args: ReportArgs) -> anyhow::Result<u8> {
    let p = railgrip::report::write_report(&args.out)?;
    println!("report     {}", p.display());
    Ok(EXIT_OK)
}
