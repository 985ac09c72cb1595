//! `railgrip train`, `railgrip export`, `railgrip eval`.

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context};
use railgrip::campaign::{train_pooled, CampaignModels, ModelPaths};
use railgrip::identify::polach::PolachReport;
use railgrip::model::{c_header, Model, ModelFile};

use super::{PipelineArg, EXIT_LOSSY, EXIT_OK};

#[derive(clap::Args)]
pub struct TrainArgs {
    /// Estimates tables (<stem>.estimates.parquet from `railgrip estimate`), run logs
    /// (.csv/.mcap, estimated on the fly), campaign folders (searched recursively for logs) or
    /// archives (.zip, .tar, .tar.gz) — the sources `railgrip run` takes, any mix.
    #[arg(value_name = "INPUT", required = true)]
    inputs: Vec<PathBuf>,
    #[command(flatten)]
    pipeline: PipelineArg,
    /// Output directory for <name>.json, .history.csv, .polach.json and .polach-fits.json: a
    /// path, file://PATH or s3://BUCKET/PREFIX (each file written by one PUT).
    #[arg(long, value_name = "DIR")]
    out: String,
    /// Model name (file stem).
    #[arg(long, default_value = "mlp")]
    name: String,
    /// Only print the final summary, not every epoch.
    #[arg(long)]
    quiet: bool,
}

pub fn train(args: TrainArgs) -> anyhow::Result<u8> {
    if !c_header::valid_prefix(&args.name) {
        bail!(
            "--name {:?}: use letters, digits and '_' (it names files and C symbols)",
            args.name
        );
    }
    let pipeline = args.pipeline.load()?;
    let folder = railgrip::store::OutFolder::at(&args.out)?;
    let tables = railgrip::campaign::load_pooled(&args.inputs, &pipeline)?;
    let quiet = args.quiet;
    let progress = |e: &railgrip::model::Epoch| {
        if !quiet {
            eprintln!(
                "epoch {:>4}  train MSE {:.4e}  val MSE {:.4e}  mu {:.1e}  |grad| {:.2e}  {:.2} s",
                e.epoch, e.train_mse, e.val_mse, e.mu, e.grad_norm, e.elapsed_s
            );
        }
    };
    let models = train_pooled(tables, &pipeline, Some(&progress))?;
    eprintln!(
        "data       {} run(s) on {} rail, {} valid samples; [train] split {:?}, decimate {}",
        models.runs,
        models.condition,
        models.samples,
        pipeline.train.split,
        pipeline.train.decimate
    );
    for (run, condition) in &models.skipped {
        eprintln!(
            "skipped    {run}: condition {condition} (train.condition selects one rail condition)"
        );
    }
    let written = models
        .write(&ModelPaths::new(folder.dir(), &args.name), false)
        .map_err(|e| anyhow::anyhow!(folder.explain(&e.to_string())))?;
    folder.finish(&written)?;
    print_network(&models);
    print_polach(&models.polach_fits);
    print_temperature_law(&models.polach_fits);
    print_choice(&models.choice);
    let notes = &models.notes;
    for n in notes {
        println!("warning    {n}");
    }
    for p in written {
        println!("wrote      {}", folder.name_of(&p));
    }
    Ok(match &models.mlp.audit {
        Some(a) => {
            print_audit(a);
            if a.passed {
                EXIT_OK
            } else {
                EXIT_LOSSY
            }
        }
        None => EXIT_OK,
    })
}

/// The model choice: every candidate's held-out scores and the chosen one.
fn print_choice(c: &railgrip::identify::choice::Choice) {
    print_candidates(c);
    println!("chosen     {} ({})", c.chosen, c.reason);
}

/// Every candidate's held-out scores, a line each (`train` and `run` print them).
pub(super) fn print_candidates(c: &railgrip::identify::choice::Choice) {
    for k in &c.candidates {
        let score = match (k.rmse_mu, k.bias_mu) {
            (Some(r), Some(b)) => format!(
                "held-out RMSE {r:.5}, bias {b:+.5}, worst run {:.5}",
                k.worst_run_rmse_mu.unwrap_or(f64::NAN)
            ),
            _ => format!("not scored: {}", k.error.as_deref().unwrap_or("–")),
        };
        println!("candidate  {:<9} {:<16} {score}", k.name, k.architecture);
    }
}

/// What `train` prints about the network: shape, samples, epochs, starts, errors, support.
fn print_network(models: &CampaignModels) {
    let trained = &models.trained;
    println!(
        "model      network {} ({} inputs, tanh hidden layers, {} parameters)",
        trained.arch,
        trained.arch.inputs,
        trained.arch.n_params()
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
    if trained.start_val_mse.len() > 1 {
        let rmse: Vec<String> = trained
            .start_val_mse
            .iter()
            .map(|m| format!("{:.5}", m.sqrt()))
            .collect();
        println!(
            "starts     {} (validation RMSE {}), kept seed {}",
            rmse.len(),
            rmse.join(" "),
            trained.seed
        );
    }
    if !trained.members.is_empty() {
        println!(
            "ensemble   the best {} starts averaged into one network of {} neurons",
            trained.members.len(),
            trained.arch.hidden[0]
        );
    }
    if let Some(g) = trained.history.last().and_then(|e| e.gamma) {
        println!(
            "bayesian   γ = {g:.1} effective parameters of {}",
            trained.theta.len()
        );
    }
    println!(
        "error      RMSE of μ: training {:.5}, validation {:.5}",
        trained.train_mse.sqrt(),
        trained.val_mse.sqrt()
    );
    if let Some(s) = &models.mlp.support {
        let supported = (0..s.len()).filter(|&j| s.supported(j)).count();
        println!(
            "support    {supported} of {} cells hold ≥ {} samples; elsewhere the model blends to the {} fallback",
            s.len(),
            s.min_samples,
            s.fallback
        );
    }
}

/// Every Polach fit with its standard errors, what was held, and the pooled fit's intervals.
fn print_polach(report: &PolachReport) {
    println!("\nPolach     μ0 ± se       A ± se        B s/m ± se    k_A ± se      k_S ± se      RMSE    group");
    let mut held = Vec::new();
    for f in report
        .pooled
        .iter()
        .chain(&report.per_run)
        .chain(&report.per_temperature)
    {
        // "x±se", or "x (bound)" / "x (prior)" for a parameter the fit held.
        let cell = |k: usize, x: f64| {
            use railgrip::identify::polach::ParamStatus;
            match f.status[k] {
                ParamStatus::Estimated => format!("{x:.4}±{:.4}", f.se[k]),
                ParamStatus::AtBound => format!("{x:.4} (bound)"),
                ParamStatus::NotIdentifiable => format!("{x:.4} (held)"),
            }
        };
        println!(
            "           {:<13} {:<13} {:<13} {:<13} {:<13} {:.4}  {}",
            cell(0, f.mu0),
            cell(1, f.a_ratio),
            cell(2, f.b_s_per_m),
            cell(3, f.k_a),
            cell(4, f.k_s),
            f.rmse,
            f.group
        );
        held.extend(f.notes.iter().map(|n| format!("{}: {n}", f.group)));
    }
    for n in held {
        println!("held       {n}");
    }
    // Profile-likelihood 95 % intervals of the pooled fit.
    if let Some(p) = report.pooled.as_ref().filter(|p| !p.profiles.is_empty()) {
        let side = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.4}"));
        let cells: Vec<String> = p
            .profiles
            .iter()
            .map(|q| format!("{} [{}, {}]", q.parameter, side(q.lower), side(q.upper)))
            .collect();
        println!(
            "95 %       {} (profile likelihood, {})",
            cells.join(", "),
            p.group
        );
    }
}

/// The temperature law chosen, or why there is none; and the creepage the fits took.
fn print_temperature_law(report: &PolachReport) {
    if let Some(c) = &report.creepage {
        let why = c.bic.map_or(String::new(), |b| {
            format!(
                " (BIC w/v {:.1}, fixed speed {:.1}; the fixed speed needs ΔBIC > 10)",
                b[0], b[1]
            )
        });
        match c.speed() {
            Some(v) => println!(
                "creepage   w over a fixed {:.1} km/h (the slip-velocity form){why}",
                v * 3.6
            ),
            None => println!("creepage   Polach's w/v{why}"),
        }
    }
    match &report.temperature {
        Some(t) => {
            // ΔBIC of the runner-up among the valid forms.
            let mut bics: Vec<f64> = t
                .candidates
                .iter()
                .filter(|c| c.rejected.is_none())
                .map(|c| c.bic)
                .collect();
            bics.sort_by(f64::total_cmp);
            let next = bics.get(1).map_or(f64::NAN, |b| b - bics[0]);
            println!(
                "law        {} chosen by {} among {} forms (next best ΔBIC {:.1}); fitted over {} … {} °C",
                t.form(),
                t.criterion,
                t.candidates.len(),
                next,
                t.fitted_range_c.0,
                t.fitted_range_c.1
            );
            if t.has_temperature_law() {
                println!(
                    "           μ0 = {:?}, k_A = {:?}, k_S = {:?} (ascending powers of T in °C)",
                    t.mu0, t.k_a, t.k_s
                );
            }
            if let Some(s) = &t.speed {
                let coefficients: Vec<String> = s
                    .coefficients
                    .iter()
                    .zip(&s.standard_errors)
                    .map(|(c, e)| format!("{c:.4} ± {e:.4}"))
                    .collect();
                println!(
                    "           μ0 × g(v), {}: c = [{}], g(v_ref = {:.1} m/s) = 1, g = {:.3} … {:.3} over {:.1} … {:.1} m/s",
                    s.form,
                    coefficients.join(", "),
                    s.reference_speed_mps,
                    s.factor(s.fitted_range_mps.1),
                    s.factor(s.fitted_range_mps.0),
                    s.fitted_range_mps.0,
                    s.fitted_range_mps.1
                );
                let limits = |x: Option<f64>| x.map_or("–".to_string(), |v| format!("{v:.4}"));
                let intervals: Vec<String> = s
                    .profiles
                    .iter()
                    .map(|p| format!("{} [{}, {}]", p.parameter, limits(p.lower), limits(p.upper)))
                    .collect();
                if !intervals.is_empty() {
                    println!(
                        "           95 % {} (profile likelihood)",
                        intervals.join(", ")
                    );
                }
            }
            for n in &t.notes {
                println!("           {n}");
            }
        }
        None => println!(
            "law        none: {}",
            report.temperature_note.clone().unwrap_or_default()
        ),
    }
}

/// The network's plausibility audit: one line when it passed, the failures when not.
pub(super) fn print_audit(a: &railgrip::model::AuditSpec) {
    if a.passed {
        println!(
            "audit      passed: 0 ≤ μ ≤ {} on every supported cell{}",
            a.mu_max,
            match (a.hysteresis_data, a.hysteresis_model) {
                (Some(d), Some(m)) => format!("; loss − recovery {m:+.4} (data {d:+.4})"),
                _ => String::new(),
            }
        );
        return;
    }
    println!(
        "\nAUDIT FAILED: {} problem(s); the model is written but marked (audit.passed = false). Exit code 3.",
        a.failing_cells
    );
    for f in &a.failures {
        println!("  {f}");
    }
    if a.failing_cells > a.failures.len() {
        println!("  … and {} more", a.failing_cells - a.failures.len());
    }
    println!("  Hint: train more starts ([train] starts, ensemble), try regularisation = \"bayesian\", or use the Polach model where the network fails.");
}

#[derive(clap::Args)]
pub struct ExportArgs {
    /// A model file written by `railgrip train`.
    #[arg(value_name = "MODEL")]
    model: PathBuf,
    /// Write a header-only C99 evaluator here.
    #[arg(long, value_name = "FILE", required_unless_present = "fmu")]
    c_header: Option<PathBuf>,
    /// Prefix of the C header's symbols (`<prefix>_mu`, `<prefix>_mu_v`).
    #[arg(long, default_value = "railgrip")]
    prefix: String,
    /// Write an FMI 2.0 FMU here (Model Exchange and Co-Simulation; the model identifier is
    /// the file's stem): binaries for this host compiled with the system C compiler ($CC, else
    /// cc), sources for other platforms (docs/fmu.md).
    #[arg(long, value_name = "OUT.fmu")]
    fmu: Option<PathBuf>,
    /// Write a source FMU (no binaries, no compiler needed; the importing tool compiles it).
    #[arg(long, requires = "fmu")]
    fmu_sources_only: bool,
}

pub fn export(args: ExportArgs) -> anyhow::Result<u8> {
    if !c_header::valid_prefix(&args.prefix) {
        bail!(
            "--prefix {:?}: must be a C identifier (letters, digits, '_', starting with a letter)",
            args.prefix
        );
    }
    let m = ModelFile::read(&args.model)?;
    if let Some(path) = &args.c_header {
        export_c_header(&m, &args, path)?;
    }
    if let Some(out) = &args.fmu {
        let options = railgrip::fmu::FmuOptions {
            sources_only: args.fmu_sources_only,
            compiler: None,
        };
        let f = railgrip::fmu::export_fmu(&args.model, out, &options)?;
        let vars: Vec<String> = f
            .variables
            .iter()
            .map(|v| format!("{} [{}]", v.name, v.unit))
            .collect();
        println!(
            "wrote      {} (FMI 2.0 ME + CS, model identifier {}, {}; {}; {:.1} kB)",
            f.path.display(),
            f.model_identifier,
            match f.platform {
                Some(p) => format!("binaries/{p} and sources"),
                None => "sources only".into(),
            },
            vars.join(", "),
            f.size as f64 / 1e3
        );
    }
    Ok(EXIT_OK)
}

/// `railgrip export --c-header`.
fn export_c_header(m: &ModelFile, args: &ExportArgs, path: &std::path::Path) -> anyhow::Result<()> {
    let text = c_header::c_header(m, &args.prefix, &args.model.display().to_string());
    railgrip_io::atomic::write_atomically(path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("{}: cannot write", path.display()))?;
    let what = match m.kind {
        railgrip::model::ModelKind::Mlp => format!(
            "network {} ({} inputs, {} weights)",
            m.architecture(),
            m.inputs.len(),
            m.n_weights()
        ),
        railgrip::model::ModelKind::Polach => format!(
            "Polach{}",
            match m.polach.as_ref().and_then(|p| p.temperature.as_ref()) {
                Some(t) if t.mu0.is_empty() => " with k(T)",
                Some(_) => " with μ0(T), k(T)",
                None => "",
            }
        ),
    };
    let p = &args.prefix;
    println!(
        "wrote      {} ({p}_mu, {p}_mu_v, {p}_mu_vt, {p}_mu_batch, {p}_mu_batch_t; {what})",
        path.display(),
    );
    Ok(())
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
    if model.n_inputs() >= 3 && !polach && cv.is_none() {
        bail!("{file}: line 1: this model takes speed as a third input: add a column v_mps");
    }
    let ct = col(railgrip::model::polach::TEMPERATURE_INPUT);
    if model.n_inputs() == 4 && !polach && ct.is_none() {
        bail!(
            "{file}: line 1: this network takes the ambient temperature as a fourth input: add a column {} (°C)",
            railgrip::model::polach::TEMPERATURE_INPUT
        );
    }
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
    railgrip_io::atomic::write_atomically(&args.output, |w| w.write_all(out.as_bytes()))
        .with_context(|| format!("{}: cannot write", args.output.display()))?;
    println!("wrote      {}", args.output.display());
    Ok(EXIT_OK)
}
