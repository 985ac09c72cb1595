//! `railgrip run`: the whole job over a campaign folder (its progress in `progress.rs`, the
//! table it prints in `report.rs`).

use anyhow::bail;
use railgrip::campaign::{self, OutDir, RunRecord};
use serde::Serialize;

use super::{PipelineArg, EXIT_ERROR, EXIT_LOSSY, EXIT_OK};

#[derive(clap::Args)]
pub struct Args {
    /// Campaign folder (searched recursively for .csv + .meta.toml and .mcap logs) or archive
    /// (.zip, .tar, .tar.gz, .tar.zst; read in place); default: the bundled archive
    /// (fixtures/archive of this source tree). Also file://PATH, or s3://BUCKET/PREFIX (a prefix
    /// of logs or one archive object; credentials and endpoint from the AWS_* environment
    /// variables, docs/cluster.md).
    #[arg(value_name = "ARCHIVE")]
    archive: Option<String>,
    #[command(flatten)]
    pipeline: PipelineArg,
    /// Output folder: a path, file://PATH or s3://BUCKET/PREFIX (staged locally, written back
    /// object by object with campaign.json and the report last).
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: String,
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
    /// The part of the job to do, for schedulers (a Slurm job array, docs/cluster.md): `all`;
    /// `calibrate` (the campaign's calibration into --out/calibration.json, when the pipeline
    /// asks for one; first, before the other parts); `estimate` (with --shard K/N: that shard's
    /// runs into --out, no models or report); `models` (train and report from what every shard
    /// wrote; refuses missing or stale runs by name). `calibrate`, the shards and then
    /// `models` write the same files as one `all`.
    #[arg(long, value_name = "PART", default_value = "all", value_parser = ["all", "calibrate", "estimate", "models"])]
    stage: String,
    /// With --stage estimate: shard K of N (1 ≤ K ≤ N); the runs at positions K−1, K−1+N, …
    /// of the campaign's order.
    #[arg(long, value_name = "K/N")]
    shard: Option<String>,
    /// The campaign's calibration (the calibration.json that `railgrip calibrate --campaign`
    /// or an earlier `railgrip run` wrote), for a pipeline with estimate.calibration = "auto",
    /// "campaign" or "dry-run": every part of a scheduled campaign is given the same one
    /// (refused when fitted on other runs or with another pipeline file). Without it, `all`
    /// fits it first, and the other parts take --out/calibration.json (`--stage calibrate`).
    #[arg(long, value_name = "FILE")]
    calibration: Option<std::path::PathBuf>,
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
    /// The campaign's model (`campaign.json`'s `chosen_model`) and why, and every candidate's
    /// held-out scores (`models/mlp.choice.json`).
    chosen: Option<serde_json::Value>,
    choice: &'a Option<railgrip::identify::choice::Choice>,
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
    let mut pipeline = args.pipeline.load()?;
    if let Some(f) = &args.calibration {
        pipeline.calibrated = Some(campaign::calibration::read_calibration(f)?);
    }
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
            b.display().to_string()
        }
    };
    let out = OutDir::new(&args.out);
    let part = match (args.stage.as_str(), &args.shard) {
        ("estimate", Some(s)) => campaign::Part::Estimate(
            campaign::Shard::parse(s).map_err(anyhow::Error::msg)?,
        ),
        ("estimate", None) => campaign::Part::Estimate(campaign::Shard { k: 1, n: 1 }),
        (_, Some(_)) => bail!("--shard K/N goes with --stage estimate"),
        ("models", None) if args.force => bail!(
            "--force goes with the estimate part (--stage estimate or all): --stage models uses what the shards wrote"
        ),
        ("models", None) => campaign::Part::Models,
        ("calibrate", None) if args.calibration.is_some() => bail!(
            "--calibration goes with the parts that use a calibration (estimate, models, all): --stage calibrate fits it"
        ),
        ("calibrate", None) => campaign::Part::Calibrate,
        _ => campaign::Part::All,
    };
    let options = campaign::Options {
        jobs: args.jobs,
        force: args.force,
        mcap: args.mcap,
        part,
        tables: false,
    };
    let o = campaign::run_at(
        &root,
        &args.out,
        &pipeline,
        options,
        &super::progress::Bars::new(),
    )?;
    let failed = o.failed();
    let audit_failed = o.audit.as_ref().is_some_and(|a| !a.passed);
    // No models is an error (exit 1) even when runs failed too: the help promises it, and a
    // script must not read "completed" from a campaign that produced nothing.
    let code = if o.model_error.is_some() {
        EXIT_ERROR
    } else if failed > 0 || audit_failed {
        EXIT_LOSSY
    } else {
        EXIT_OK
    };
    if args.json {
        let s = JsonSummary {
            archive: root.clone(),
            out: args.out.clone(),
            runs: &o.records,
            failed,
            reused: o.reused(),
            condition: &o.condition,
            models: o.models.iter().map(|p| p.display().to_string()).collect(),
            model_error: &o.model_error,
            chosen: o.chosen_json(),
            choice: &o.choice,
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
    if matches!(
        part,
        campaign::Part::Estimate(_) | campaign::Part::Calibrate
    ) {
        super::report::print_shard(&o);
        return Ok(if failed > 0 { EXIT_LOSSY } else { EXIT_OK });
    }
    super::report::print_outcome(&o, &out);
    Ok(code)
}
