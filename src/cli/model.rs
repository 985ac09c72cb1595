//! `railgrip train`, `railgrip export`, `railgrip eval`.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use railgrip::identify::dataset::sha256_file;
use railgrip::identify::train::{creep_spec, median_speed, train_mlp, utc_now_rfc3339};
use railgrip::identify::RunTable;
use railgrip::model::{c_header, InputFile, Model, ModelFile, Provenance};
use rayon::prelude::*;

use super::{PipelineArg, EXIT_OK};

#[derive(clap::Args)]
pub struct TrainArgs {
    /// Estimates tables (<stem>.estimates.parquet from `railgrip estimate`) or run logs
    /// (.csv/.mcap, estimated on the fly), any mix.
    #[arg(value_name = "INPUT", required = true)]
    inputs: Vec<PathBuf>,
    #[command(flatten)]
    pipeline: PipelineArg,
    /// Output directory for <name>.json and <name>.history.csv.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Model name (file stem).
    #[arg(long, default_value = "mlp")]
    name: String,
    /// Only print the final summary, not every epoch.
    #[arg(long)]
    quiet: bool,
}

/// Reads the inputs as run tables, in parallel, in the order given.
pub fn load_tables(
    inputs: &[PathBuf],
    pipeline: &railgrip::Pipeline,
) -> anyhow::Result<Vec<RunTable>> {
    inputs
        .par_iter()
        .map(|p| -> anyhow::Result<RunTable> {
            let name = p.display().to_string();
            if name.ends_with(".parquet") {
                return Ok(RunTable::read_parquet(p)?);
            }
            let log = railgrip::ingest_file(p, pipeline)?;
            let e = railgrip::estimate::estimate(&log, pipeline)?;
            let sha = sha256_file(p).with_context(|| format!("{name}: cannot read"))?;
            Ok(RunTable::from_estimates(
                &super::ingest::stem(p),
                &name,
                &sha,
                &e,
            ))
        })
        .collect()
}

pub fn train(args: TrainArgs) -> anyhow::Result<u8> {
    if !c_header::valid_prefix(&args.name) {
        bail!(
            "--name {:?}: use letters, digits and '_' (it names files and C symbols)",
            args.name
        );
    }
    let pipeline = args.pipeline.load()?;
    let choice = railgrip::identify::train::select_condition(
        load_tables(&args.inputs, &pipeline)?,
        pipeline.train.condition.as_deref(),
    )?;
    let tables = choice.used;
    let samples: usize = tables.iter().map(|t| t.len()).sum();
    eprintln!(
        "data       {} run(s) on {} rail, {} valid samples; [train] split {:?}, decimate {}",
        tables.len(),
        choice.condition,
        samples,
        pipeline.train.split,
        pipeline.train.decimate
    );
    for (run, condition) in &choice.skipped {
        eprintln!(
            "skipped    {run}: condition {condition} (train.condition selects one rail condition)"
        );
    }
    let quiet = args.quiet;
    let progress: Box<dyn FnMut(&railgrip::identify::lm::Epoch) + Send> = Box::new(move |e| {
        if !quiet {
            eprintln!(
                "epoch {:>4}  train MSE {:.4e}  val MSE {:.4e}  mu {:.1e}  |grad| {:.2e}  {:.2} s",
                e.epoch, e.train_mse, e.val_mse, e.mu, e.grad_norm, e.elapsed_s
            );
        }
    });
    let trained = train_mlp(&tables, &pipeline.train, Some(progress))?;
    let mut trained = trained;
    trained.reference_speed_mps = median_speed(&tables);
    let creep = creep_spec(&pipeline, trained.reference_speed_mps)?;
    let provenance = Provenance {
        inputs: tables
            .iter()
            .map(|t| InputFile {
                path: t.source.clone(),
                sha256: t.sha256.clone(),
            })
            .collect(),
        pipeline: pipeline.source.clone(),
        pipeline_sha256: railgrip::identify::dataset::sha256_bytes(pipeline.text.as_bytes()),
        seed: pipeline.train.seed,
        crate_version: env!("CARGO_PKG_VERSION").into(),
        created: utc_now_rfc3339(),
    };
    let file = ModelFile::from_trained(&trained, creep, provenance.clone());
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create the output directory", args.out.display()))?;
    let path = args.out.join(format!("{}.json", args.name));
    file.write(&path)?;
    let hist = args.out.join(format!("{}.history.csv", args.name));
    write_history(&hist, &trained.history)?;
    // Polach fits per run and temperature, and k(T).
    let (patch, q) = railgrip::identify::train::pipeline_patch(&pipeline)?;
    let (report, notes) = railgrip::identify::polach_fit::fit_campaign(
        &tables,
        patch,
        q,
        pipeline.train.decimate,
        pipeline.train.temperature_degree,
    );
    let mut notes = notes;
    let fits_path = args.out.join(format!("{}.polach-fits.json", args.name));
    let text = serde_json::to_string_pretty(&report)? + "\n";
    railgrip::atomic::write_atomically(&fits_path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("{}: cannot write", fits_path.display()))?;
    // The campaign's Polach model file: the pooled fit with k(T) when there is one.
    let polach_path = args.out.join(format!("{}.polach.json", args.name));
    let polach_model = report.pooled.as_ref().map(|pooled| {
        let make = |t| {
            ModelFile::from_polach(
                pooled,
                &patch,
                q,
                t,
                report.dv_range_mps,
                report.v_range_mps,
                trained.reference_speed_mps,
                provenance.clone(),
            )
        };
        make(report.temperature.as_ref()).or_else(|e| {
            notes.push(format!("Polach model written without k(T): {e}"));
            make(None)
        })
    });
    let polach_written = match polach_model {
        Some(Ok(m)) => {
            m.write(&polach_path)?;
            true
        }
        Some(Err(e)) => {
            notes.push(format!("no Polach model file: {e}"));
            false
        }
        None => false,
    };
    println!(
        "model      {} inputs, {} hidden tanh neurons, {} parameters",
        trained.shape.inputs,
        trained.shape.hidden,
        trained.shape.n_params()
    );
    println!(
        "data       {} training, {} validation samples",
        trained.n_train, trained.n_val
    );
    println!(
        "trained    {} epochs ({}), {:.2} s",
        trained.history.len(),
        trained.stop.text(),
        trained.history.last().map(|e| e.elapsed_s).unwrap_or(0.0)
    );
    println!(
        "error      RMSE of μ: training {:.5}, validation {:.5}",
        trained.train_mse.sqrt(),
        trained.val_mse.sqrt()
    );
    println!("\nPolach     μ0 ± se      A ± se      B s/m ± se   k_A ± se     k_S ± se     RMSE    group");
    for f in report
        .pooled
        .iter()
        .chain(&report.per_run)
        .chain(&report.per_temperature)
    {
        println!(
            "           {:.4}±{:.4} {:.3}±{:.3} {:.3}±{:.3} {:.4}±{:.4} {:.4}±{:.4} {:.4}  {}",
            f.mu0,
            f.se[0],
            f.a_ratio,
            f.se[1],
            f.b_s_per_m,
            f.se[2],
            f.k_a,
            f.se[3],
            f.k_s,
            f.se[4],
            f.rmse,
            f.group
        );
    }
    match &report.temperature {
        Some(t) => println!(
            "k(T)       k_A = {:?}, k_S = {:?} (ascending powers of T in °C, degree {}, fitted over {} … {} °C)",
            t.k_a, t.k_s, t.degree, t.fitted_range_c.0, t.fitted_range_c.1
        ),
        None => println!("k(T)       not fitted: {}", report.temperature_note.clone().unwrap_or_default()),
    }
    for n in &notes {
        println!("warning    {n}");
    }
    println!("wrote      {}", path.display());
    println!("wrote      {}", hist.display());
    if polach_written {
        println!("wrote      {}", polach_path.display());
    }
    println!("wrote      {}", fits_path.display());
    Ok(EXIT_OK)
}

fn write_history(path: &Path, h: &[railgrip::identify::lm::Epoch]) -> anyhow::Result<()> {
    let mut text = String::from("epoch,train_mse,val_mse,mu,grad_norm,elapsed_s\n");
    for e in h {
        text.push_str(&format!(
            "{},{:?},{:?},{:?},{:?},{:?}\n",
            e.epoch, e.train_mse, e.val_mse, e.mu, e.grad_norm, e.elapsed_s
        ));
    }
    railgrip::atomic::write_atomically(path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("{}: cannot write", path.display()))
}

#[derive(clap::Args)]
pub struct ExportArgs {
    /// A model file written by `railgrip train`.
    #[arg(value_name = "MODEL")]
    model: PathBuf,
    /// Write a header-only C99 evaluator here.
    #[arg(long, value_name = "FILE")]
    c_header: PathBuf,
    /// Prefix of the C symbols (`<prefix>_mu`, `<prefix>_mu_v`).
    #[arg(long, default_value = "railgrip")]
    prefix: String,
}

pub fn export(args: ExportArgs) -> anyhow::Result<u8> {
    if !c_header::valid_prefix(&args.prefix) {
        bail!(
            "--prefix {:?}: must be a C identifier (letters, digits, '_', starting with a letter)",
            args.prefix
        );
    }
    let m = ModelFile::read(&args.model)?;
    let text = c_header::c_header(&m, &args.prefix, &args.model.display().to_string());
    railgrip::atomic::write_atomically(&args.c_header, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("{}: cannot write", args.c_header.display()))?;
    let what = match m.kind {
        railgrip::model::ModelKind::Mlp => format!(
            "network: {} inputs, {} hidden",
            m.inputs.len(),
            m.layers[0].shape[0]
        ),
        railgrip::model::ModelKind::Polach => format!(
            "Polach{}",
            if m.inputs.len() == 3 {
                " with k(T)"
            } else {
                ""
            }
        ),
    };
    let p = &args.prefix;
    println!(
        "wrote      {} ({p}_mu, {p}_mu_v, {p}_mu_vt, {p}_mu_batch; {what})",
        args.c_header.display(),
    );
    Ok(EXIT_OK)
}

#[derive(clap::Args)]
pub struct EvalArgs {
    /// A model file written by `railgrip train`.
    #[arg(value_name = "MODEL")]
    model: PathBuf,
    /// CSV with columns dv_mps, ddv_mps2 (v_mps for 3-input networks; optional otherwise:
    /// without it the reference speed); Polach models need only dv_mps and use
    /// ambient_temperature_c when present.
    #[arg(long, value_name = "CSV")]
    input: PathBuf,
    /// Output CSV: the input columns and mu.
    #[arg(long, value_name = "CSV")]
    output: PathBuf,
}

pub fn eval(args: EvalArgs) -> anyhow::Result<u8> {
    let model = Model::load(&args.model)?;
    let file = args.input.display().to_string();
    let text =
        std::fs::read_to_string(&args.input).with_context(|| format!("{file}: cannot read"))?;
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap_or("")
        .split(',')
        .map(|s| s.trim().trim_matches('"').to_string())
        .collect();
    let col = |name: &str| header.iter().position(|h| h == name);
    let polach = model.file.kind == railgrip::model::ModelKind::Polach;
    let Some(cdv) = col("dv_mps") else {
        bail!("{file}: line 1: the header needs a column dv_mps (found {header:?})");
    };
    let cddv = col("ddv_mps2");
    if cddv.is_none() && !polach {
        bail!("{file}: line 1: this network takes dv_mps and ddv_mps2: add a column ddv_mps2 (found {header:?})");
    }
    let cv = col("v_mps");
    if model.n_inputs() == 3 && !polach && cv.is_none() {
        bail!("{file}: line 1: this model takes speed as a third input: add a column v_mps");
    }
    let ct = col(railgrip::model::polach::TEMPERATURE_INPUT);
    // Echo the input columns used, then mu.
    let used: Vec<(usize, &str)> = [
        (Some(cdv), "dv_mps"),
        (cddv, "ddv_mps2"),
        (cv, "v_mps"),
        (ct, railgrip::model::polach::TEMPERATURE_INPUT),
    ]
    .into_iter()
    .filter_map(|(c, n)| c.map(|c| (c, n)))
    .collect();
    let mut out = used.iter().map(|u| u.1).collect::<Vec<_>>().join(",");
    out.push_str(",mu\n");
    for (n, line) in lines.enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').map(|s| s.trim()).collect();
        let num = |c: usize, name: &str| -> anyhow::Result<f64> {
            let s = cells.get(c).copied().unwrap_or("");
            let x: f64 = s.parse().map_err(|_| {
                anyhow::anyhow!(
                    "{file}: line {}, column \"{name}\": \"{s}\" is not a number",
                    n + 2
                )
            })?;
            if !x.is_finite() {
                bail!(
                    "{file}: line {}, column \"{name}\": {s} is not finite",
                    n + 2
                );
            }
            Ok(x)
        };
        let mut vals = [0.0, 0.0, f64::NAN, f64::NAN];
        for (slot, (c, name)) in [
            (Some(cdv), "dv_mps"),
            (cddv, "ddv_mps2"),
            (cv, "v_mps"),
            (ct, railgrip::model::polach::TEMPERATURE_INPUT),
        ]
        .into_iter()
        .enumerate()
        {
            if let Some(c) = c {
                vals[slot] = num(c, name)?;
            }
        }
        let [dv, ddv, v, t] = vals;
        let mu = model.mu_vt(dv, ddv, v, t);
        let row: Vec<String> = used
            .iter()
            .map(|(c, _)| cells.get(*c).copied().unwrap_or("").to_string())
            .collect();
        out.push_str(&format!("{},{mu:?}\n", row.join(",")));
    }
    railgrip::atomic::write_atomically(&args.output, |w| w.write_all(out.as_bytes()))
        .with_context(|| format!("{}: cannot write", args.output.display()))?;
    println!("wrote      {}", args.output.display());
    Ok(EXIT_OK)
}
