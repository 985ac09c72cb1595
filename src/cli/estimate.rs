//! `railgrip estimate` and `railgrip calibrate`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use railgrip::estimate::calibrate::{calibrate, AlphaFit, Resistance};
use railgrip::estimate::{estimate, Estimates};

use super::{PipelineArg, EXIT_LOSSY, EXIT_OK};

#[derive(clap::Args)]
pub struct Args {
    /// The log to estimate: .csv (with optional <stem>.meta.toml sidecar) or .mcap; a path,
    /// file://PATH or s3://BUCKET/KEY (AWS_* environment variables: docs/cluster.md).
    #[arg(value_name = "RUN")]
    run: String,
    #[command(flatten)]
    pipeline: PipelineArg,
    /// Directory for <stem>.estimates.parquet (created if missing): a path, file://PATH or
    /// s3://BUCKET/PREFIX (each file written by one PUT).
    #[arg(long, value_name = "DIR")]
    out: String,
    /// Also write <stem>.estimates.csv.
    #[arg(long)]
    csv: bool,
    /// Also write <stem>.railgrip.mcap: per axle Δv, dΔv/dt, N, T, μ, valid as JSON topics
    /// /railgrip/axle<i>/… (and /railgrip/v_mps) at the input's log times, for Foxglove.
    #[arg(long)]
    mcap: bool,
    /// A model file whose μ is replayed on the run into the MCAP (/railgrip/axle<i>/mu_model).
    #[arg(long, value_name = "MODEL", requires = "mcap")]
    model: Option<PathBuf>,
    /// A campaign's calibration (calibration.json of `railgrip calibrate --campaign` or
    /// `railgrip run`) to estimate the run with: per-axle α, the pad friction's speed law, the
    /// radar's scale and latency, the tachometers' delay.
    #[arg(long, value_name = "FILE")]
    calibration: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<u8> {
    let mut pipeline = args.pipeline.load()?;
    match &args.calibration {
        Some(f) => {
            let given = railgrip::campaign::calibration::read_calibration(f)?;
            railgrip::campaign::calibration::check_for_run(
                &given,
                &pipeline,
                std::path::Path::new(&args.run),
            )?;
            if given.source == railgrip::campaign::calibration::NONE_SOURCE {
                eprintln!(
                    "note: estimated with [vehicle]'s α and the radar as logged: {} records that the campaign fitted no calibration (estimate.calibration = \"auto\")",
                    f.display()
                );
            } else {
                pipeline.calibrated = Some(given);
            }
        }
        // A run alone cannot calibrate itself: "auto" estimates it with the pipeline's values.
        None if pipeline.estimate.calibration == railgrip::config::CalibrationSource::Auto => {
            eprintln!(
                "note: estimated with [vehicle]'s α and the radar as logged (estimate.calibration = \"auto\": a run alone cannot calibrate itself; give a campaign's calibration with --calibration FILE, which `railgrip calibrate --campaign ARCHIVE --out DIR` writes)"
            );
        }
        None if pipeline.estimate.calibration != railgrip::config::CalibrationSource::Pipeline => {
            anyhow::bail!(
                "{}: estimate.calibration = \"{}\" needs the campaign's calibration. Hint: give it with --calibration FILE (railgrip calibrate --campaign ARCHIVE --out DIR writes DIR/calibration.json)",
                pipeline.source,
                pipeline.estimate.calibration.name()
            )
        }
        None => {}
    }
    let folder = railgrip::store::OutFolder::at(&args.out)?;
    // A model that does not load is found before the run is estimated.
    let model = match &args.model {
        Some(p) => Some(railgrip::model::Model::load(p)?),
        None => None,
    };
    let log =
        railgrip::ingest::ingest_source(&railgrip::ingest::LogSource::at(&args.run)?, &pipeline)?;
    let est = estimate(&log, &pipeline)?;
    let stem = super::ingest::stem(std::path::Path::new(&args.run));
    // Errors name the output's URI, not a staging folder.
    let staged = |e: anyhow::Error| anyhow::anyhow!(folder.explain(&format!("{e:#}")));
    let mut written = est
        .write(folder.dir(), &stem, args.csv)
        .map_err(|e| staged(e.into()))?;
    if args.mcap {
        let path = folder.dir().join(format!("{stem}.railgrip.mcap"));
        railgrip::replay::write_replay(
            &path,
            &railgrip::replay::ReplayRun::from_estimates(&est),
            model.as_ref(),
            log.start_log_time_ns.unwrap_or(0),
        )
        .map_err(|e| staged(e.into()))?;
        written.push(path);
    }
    print!("{}", summary(&est));
    for w in &log.warnings {
        println!("warning    {}", w.message);
    }
    folder.finish(&written)?;
    for p in written {
        let size = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
        println!(
            "wrote      {} ({:.1} MB)",
            folder.name_of(&p),
            size as f64 / 1e6
        );
    }
    Ok(if log.lost_data() { EXIT_LOSSY } else { EXIT_OK })
}

/// The human summary printed by `railgrip estimate`.
pub fn summary(e: &Estimates) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "file       {}", e.source.display());
    let gd = e.group_delay_s;
    let _ = writeln!(
        s,
        "filters    {} · group delay radar {:.3} s, tachometers {:.3} s, pressures {:.3} s{}",
        match e.mode {
            railgrip::config::FilterMode::ZeroPhase => "zero-phase (forward-backward)",
            railgrip::config::FilterMode::Causal => "causal (one pass, as in seed 002)",
        },
        gd.radar_s,
        gd.tacho_s,
        gd.pressure_s,
        if gd.radar_s != gd.tacho_s {
            format!(" — slip is skewed by {:.3} s", gd.radar_s - gd.tacho_s)
        } else {
            String::new()
        }
    );
    let _ = writeln!(
        s,
        "despiking  {} radar sample(s) replaced{}",
        e.despiked,
        if e.despiked > 0 { " (warning)" } else { "" }
    );
    let _ = writeln!(
        s,
        "\n{:<5} {:>8} {:>8} {:>11} {:>10} {:>12}  masked",
        "axle", "valid", "peak μ", "max Δv m/s", "sliding s", "utilisation"
    );
    for (a, sm) in e.summary().iter().enumerate() {
        let m = &e.axles[a].masked;
        let reasons: Vec<String> = m
            .pairs()
            .iter()
            .filter(|(_, k)| *k > 0)
            .map(|(r, k)| format!("{k} {r}"))
            .collect();
        let _ = writeln!(
            s,
            "{:<5} {:>8} {:>8.4} {:>11.3} {:>10.2} {:>12.2}  {}",
            sm.axle,
            sm.valid_samples,
            sm.peak_mu,
            sm.max_dv_mps,
            sm.sliding_s,
            sm.utilisation,
            if reasons.is_empty() {
                "none".to_string()
            } else {
                reasons.join(", ")
            }
        );
    }
    s
}

#[derive(clap::Args)]
pub struct CalibrateArgs {
    /// A full-adhesion (dry) braking run: .csv or .mcap.
    #[arg(
        value_name = "RUN",
        required_unless_present = "campaign",
        conflicts_with = "campaign"
    )]
    run: Option<PathBuf>,
    /// Calibrate from a whole campaign instead (a folder, an archive, file:// or s3://): per-axle
    /// α, the pad friction's speed law, the running resistance, the radar's scale and latency
    /// and the tachometers' delay, pooled over its runs (docs/calibration.md).
    #[arg(long, value_name = "ARCHIVE")]
    campaign: Option<String>,
    /// With --campaign: write DIR/calibration.json (what `railgrip run --calibration` and a
    /// pipeline with estimate.calibration = "campaign" take).
    #[arg(long, value_name = "DIR", requires = "campaign")]
    out: Option<PathBuf>,
    /// With --campaign: runs conditioned in parallel (default: one per core).
    #[arg(long, value_name = "N", requires = "campaign")]
    jobs: Option<usize>,
    #[command(flatten)]
    pipeline: PipelineArg,
    /// Fit one α per axle instead of a common one (needs pressures that differ between axles).
    #[arg(long)]
    per_axle: bool,
    /// Known running resistance A,B,C of A + B v + C v² (N, N·s/m, N·s²/m²), e.g.
    /// `--davis 1200,30,6`: subtracted instead of fitted, which pins α down much better.
    #[arg(
        long,
        value_name = "A,B,C",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    davis: Option<Vec<f64>>,
}

pub fn calibrate_run(args: CalibrateArgs) -> anyhow::Result<u8> {
    let pipeline = args.pipeline.load()?;
    if let Some(archive) = &args.campaign {
        if args.per_axle || args.davis.is_some() {
            anyhow::bail!("--per-axle and --davis go with one dry RUN; --campaign fits per-axle α and the resistance itself");
        }
        return calibrate_campaign(archive, args.out.as_deref(), args.jobs, pipeline);
    }
    let run = args.run.expect("clap requires RUN without --campaign");
    let log = railgrip::ingest_file(&run, &pipeline)?;
    let fit = if args.per_axle {
        AlphaFit::PerAxle
    } else {
        AlphaFit::Common
    };
    let resistance = match args.davis.as_deref() {
        None => Resistance::Fit,
        Some(&[a, b, c]) if [a, b, c].iter().all(|x| x.is_finite() && *x >= 0.0) => {
            Resistance::Davis {
                a_n: a,
                b_n_s_per_m: b,
                c_n_s2_per_m2: c,
            }
        }
        Some(v) => anyhow::bail!(
            "--davis {v:?}: give three finite non-negative numbers A,B,C (N, N·s/m, N·s²/m²), e.g. --davis 1200,30,6"
        ),
    };
    let c = calibrate(&log, &pipeline, fit, resistance)?;
    println!("file       {}", log.source.display());
    println!(
        "samples    {} at full adhesion ({:.0} effective after autocorrelation)",
        c.samples, c.effective_samples
    );
    for (a, (al, se)) in c.alpha_nm_per_bar.iter().zip(&c.alpha_se).enumerate() {
        if fit == AlphaFit::Common && a > 0 {
            break;
        }
        let label = match fit {
            AlphaFit::Common => "α (all)".to_string(),
            AlphaFit::PerAxle => format!("α{}", a + 1),
        };
        println!("{label:<10} {al:.1} ± {se:.1} N·m/bar (1σ)");
    }
    match resistance {
        Resistance::Fit => println!(
            "resistance {:.0} N + {:.2} N·s²/m² · v² (fitted alongside; residual RMS {:.0} N)",
            c.c0_n, c.c2_n_s2_per_m2, c.rms_residual_n
        ),
        Resistance::Davis {
            a_n,
            b_n_s_per_m,
            c_n_s2_per_m2,
        } => println!(
            "resistance {a_n} N + {b_n_s_per_m} N·s/m · v + {c_n_s2_per_m2} N·s²/m² · v² (given; residual RMS {:.0} N)",
            c.rms_residual_n
        ),
    }
    // The radar against the wheels (information: the estimates take the radar as it reads).
    match railgrip::estimate::radar::calibrate_radar(&log, &pipeline) {
        Ok(r) => println!(
            "radar      reads {:.5} ± {:.5} × r ω in the coast before the brake ({} samples; r from the pipeline)",
            r.scale, r.scale_se, r.scale_samples
        ),
        Err(e) => println!("radar      scale not fitted: {e}"),
    }
    let current = pipeline.vehicle.brake_torque_nm_per_bar;
    println!("pipeline   {} has {:?}", pipeline.source, current);
    println!("\n# put this line into [vehicle] of your pipeline file:");
    println!("{}", c.toml_line());
    Ok(if log.lost_data() { EXIT_LOSSY } else { EXIT_OK })
}

/// `railgrip calibrate --campaign`: the campaign's self-calibration, printed, and written to
/// `out/calibration.json` when asked.
fn calibrate_campaign(
    archive: &str,
    out: Option<&Path>,
    jobs: Option<usize>,
    mut pipeline: railgrip::Pipeline,
) -> anyhow::Result<u8> {
    use railgrip::campaign::calibration::{calibrate_campaign, write_calibration};
    use railgrip::config::CalibrationSource;
    // The file written is for runs whose pipeline says "campaign" (it names that file's
    // hash); printed only, the fit is shown whatever the file says.
    if pipeline.estimate.calibration.fitted() != Some(CalibrationSource::Campaign) {
        if out.is_some() {
            anyhow::bail!(
                "{}: estimate.calibration is \"{}\", so the runs would not use a campaign calibration written with --out. Hint: give the pipeline the campaign runs with (estimate.calibration = \"campaign\") with --pipeline",
                pipeline.source,
                pipeline.estimate.calibration.name()
            );
        }
        pipeline.estimate.calibration = CalibrationSource::Campaign;
    }
    let (root, (logs, _)) = railgrip::campaign::sources_at(archive, None)?;
    let options = railgrip::campaign::Options {
        jobs,
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let record = calibrate_campaign(&logs, &pipeline, options, &root)?;
    let seconds = t.elapsed().as_secs_f64();
    let f = record.campaign.as_ref().expect("a campaign fit");
    println!(
        "campaign   {} ({} runs in the balance)",
        root.display(),
        f.runs
    );
    println!(
        "samples    {} ({:.0} effective after autocorrelation), residual RMS {:.0} N (the force balance: the delays)",
        f.samples, f.effective_samples, f.rms_residual_n
    );
    println!(
        "integrated {} samples ({:.0} effective), residual RMS {:.0} N·s (the balance integrated over time: every coefficient below)",
        f.integrated.samples, f.integrated.effective_samples, f.integrated.rms_residual_n_s
    );
    println!("noise      {}", radar_noise_line(f));
    for a in 0..railgrip::format::AXLES {
        println!(
            "α{}         {:.1} ± {:.1} N·m/bar (1σ) at {:.0} km/h",
            a + 1,
            f.alpha_nm_per_bar[a],
            f.alpha_se[a],
            f.pad.v_ref_mps * 3.6
        );
    }
    for g in &f.shared {
        let names: Vec<String> = g.iter().map(|a| (a + 1).to_string()).collect();
        println!("shared     axles {} fitted with one α", names.join(", "));
    }
    print_pad(f);
    println!(
        "resistance {} + ({:.2} ± {}) N·s/m · v + ({:.3} ± {}) N·s²/m² · v²",
        if f.per_run_constants {
            "a constant per run"
        } else {
            "one constant"
        },
        f.resistance_c1_n_s_per_m,
        or_dash(f.resistance_c1_se, 2),
        f.resistance_c2_n_s2_per_m2,
        or_dash(f.resistance_c2_se, 3)
    );
    print_run_constants(&f.resistance_constants, f.per_run_constants);
    if let Some(sd) = f.alpha_between_sd {
        println!(
            "pooling    the axles' α spread {:.1} N·m/bar (1σ) beyond their errors; fitted α {:?}",
            sd,
            f.alpha_fitted.map(|a| (a * 10.0).round() / 10.0)
        );
    }
    print_sensors(f);
    for n in &record.notes {
        println!("note       {n}");
    }
    println!("time       {seconds:.2} s");
    if let Some(dir) = out {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("{}: cannot create the folder: {e}", dir.display()))?;
        let path = write_calibration(dir, &record)?;
        println!("written    {}", path.display());
    }
    Ok(EXIT_OK)
}

/// How much of the balance's residual is the radar's noise, in words: whether the residual
/// shows nothing else (the noise then sets the coefficients' statistical errors: more runs
/// narrow them) or the balance leaves more than it.
fn radar_noise_line(f: &railgrip::estimate::selfcal::CampaignCalibration) -> String {
    let b = &f.integrated;
    let over = if b.radar_noise_runs == f.runs {
        String::new()
    } else {
        format!(
            ", on the {} of {} runs whose radar shows it",
            b.radar_noise_runs, f.runs
        )
    };
    match (b.radar_noise_mps, b.residual_over_radar_noise) {
        (None, _) => "not read: no run's radar shows its noise (logged at another rate than the time base, a time base under 100 Hz, or under 1 000 samples above estimate.min_speed_mps)".into(),
        (Some(0.0), None) => format!(
            "the radar shows no noise between 10 and 40 Hz{over}: the residual is not compared"
        ),
        (Some(sd), None) => format!(
            "the radar's {sd:.4} m/s rms per sample (read between 10 and 40 Hz{over}); the balance's residual could not be compared with it"
        ),
        (Some(sd), Some(r)) if r < 0.8 => format!(
            "the radar's {sd:.4} m/s rms per sample (read between 10 and 40 Hz{over}); the balance's residual is {r:.2}× what it leaves: the radar shows more than white noise there (the vehicle's vibration, a noise rising with frequency), so its noise is not what the residual is held against"
        ),
        (Some(sd), Some(r)) if r <= 1.2 => format!(
            "the radar's {sd:.4} m/s rms per sample (read between 10 and 40 Hz{over}); the balance's residual is {r:.2}× what it leaves: the residual shows nothing but the radar's noise, which sets the coefficients' statistical errors (more runs narrow them as 1/√runs, or a quieter radar)"
        ),
        (Some(sd), Some(r)) => format!(
            "the radar's {sd:.4} m/s rms per sample (read between 10 and 40 Hz{over}); the balance's residual is {r:.2}× what it leaves: the balance leaves more than the radar's noise (the wheel loads' fluctuation, another sensor's noise, or a force its model lacks)"
        ),
    }
}

/// The pad forms fitted, each with its BIC (a mixture's weight w in its own column), and the
/// law chosen.
fn print_pad(f: &railgrip::estimate::selfcal::CampaignCalibration) {
    // A mixture's weight w in its own column ("–" where none could be fitted).
    let w_of = |c: &railgrip::estimate::selfcal::PadCandidate| match c.form.mixes() {
        true if c.gamma.is_finite() => format!("{:>5.2}", c.mix),
        true => format!("{:>5}", "–"),
        false => " ".repeat(5),
    };
    println!("pad        form                 w constants  γ        BIC");
    for c in &f.pad_candidates {
        let chosen = c.form == f.pad.form && c.per_run_constants == f.per_run_constants;
        let mark = if chosen { "  chosen" } else { "" };
        println!(
            "           {:<16} {} {:<10} {:+.4}  {:>10.1}{mark}{}",
            c.form.name(),
            w_of(c),
            if c.per_run_constants {
                "per run"
            } else {
                "one"
            },
            c.gamma,
            c.bic,
            c.refused
                .as_deref()
                .map(|r| format!(" refused: {r}"))
                .unwrap_or_default()
        );
    }
    println!(
        "pad        {} law: α_i(v) = α_i (1 {:+.4} ± {} φ(v)){}, {:+.2} % from {:.0} km/h to standstill",
        f.pad.form.name(),
        f.pad.gamma,
        or_dash(f.pad.gamma_se, 4),
        if f.pad.form.mixes() {
            format!(", φ's mixture weight w = {:.3}", f.pad.mix)
        } else {
            String::new()
        },
        f.pad.rise_to_standstill() * 100.0,
        f.pad.v_ref_mps * 3.6
    );
}

/// The radar's and the tachometers' lines of `railgrip calibrate --campaign`.
fn print_sensors(f: &railgrip::estimate::selfcal::CampaignCalibration) {
    println!(
        "radar      scale {:.5} ± {} (coasts of {} runs), latency {:.1} ± {} ms",
        f.radar_scale,
        or_dash(f.radar_scale_se, 5),
        f.radar_scale_runs,
        f.radar_latency_s * 1e3,
        or_dash(f.radar_latency_se * 1e3, 1)
    );
    match f.tacho_window_s {
        Some(w) => println!(
            "tachos     delay {:.1} ms: half their {:.1} ms counting window, read from their quantisation",
            f.tacho_delay_s * 1e3,
            w * 1e3
        ),
        None => println!(
            "tachos     delay {:.1} ± {} ms",
            f.tacho_delay_s * 1e3,
            or_dash(f.tacho_delay_se * 1e3, 1)
        ),
    }
}

/// `x` with `digits` decimals, or "–" where it is not a number (a standard error that could
/// not be computed).
fn or_dash(x: f64, digits: usize) -> String {
    if x.is_finite() {
        format!("{x:.digits$}")
    } else {
        "–".into()
    }
}

/// The balance's constant per run (the resistance's constant and the run's gradient force):
/// every run up to a dozen, else their range (all of them are in `calibration.json`).
fn print_run_constants(constants: &[railgrip::estimate::selfcal::RunConstant], per_run: bool) {
    const LISTED: usize = 12;
    if constants.is_empty() {
        return;
    }
    if !per_run {
        let c = &constants[0];
        println!(
            "constant   {} ± {} N for every run (resistance's constant and gradient force)",
            or_dash(c.constant_n, 0),
            or_dash(c.se_n, 0)
        );
    } else if constants.len() <= LISTED {
        for c in constants {
            println!(
                "constant   {}: {} ± {} N (resistance's constant and gradient force)",
                c.run,
                or_dash(c.constant_n, 0),
                or_dash(c.se_n, 0)
            );
        }
    } else {
        let (lo, hi) = constants
            .iter()
            .map(|c| c.constant_n)
            .filter(|c| c.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                (a.min(x), b.max(x))
            });
        println!(
            "constant   {} … {} N over {} runs (resistance's constant and gradient force; each run's in calibration.json)",
            or_dash(lo, 0),
            or_dash(hi, 0),
            constants.len()
        );
    }
}
