//! Command-line interface. The only place that prints or picks exit codes.

mod contact;
mod estimate;
mod ingest;
mod model;
mod progress;
mod report;
mod run;
mod score;
mod simulate;
mod study;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Exit codes shared by every command.
pub const EXIT_OK: u8 = 0;
pub const EXIT_ERROR: u8 = 1;
pub const EXIT_USAGE: u8 = 2;
pub const EXIT_LOSSY: u8 = 3;

#[derive(Parser)]
#[command(
    name = "railgrip",
    version,
    about = "Learn wheel–rail adhesion curves from railway braking-test logs",
    long_about = "railgrip reads braking-test logs (Doppler radar speed, axle tachometers, brake-cylinder \
pressures; CSV or MCAP) and turns them into adhesion estimates and models.\n\n\
Exit codes: 0 ok, 1 error, 2 usage, 3 completed but some input was skipped or lost.",
    after_help = "Run `railgrip <COMMAND> --help` for the options of a command."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The main job: estimate every run of a campaign folder, train the models, write the report.
    #[command(
        long_about = "Run the whole pipeline over a test campaign: find the logs below ARCHIVE (recursively: .csv with their .meta.toml, .mcap), ingest, condition and estimate each run in parallel (a run that fails is reported and the rest goes on), train the candidate models (the seed 002 network, networks with speed and temperature, Polach with its temperature and speed laws, the residual network) on the pooled estimates of one rail condition, choose the campaign's model by held-out runs (train.model), export them (JSON + C headers) and write an HTML validation report.\n\nWithout ARCHIVE it runs on the bundled archive with the embedded default pipeline.\n\nWrites <OUT>/runs/<run>/estimates.parquet and run.json, <OUT>/summary.csv and .parquet (one row per run), <OUT>/models/ (mlp.json, mlp.polach.json, mlp.3in.json, mlp.4in.json, mlp.residual.json and their .h headers, mlp.choice.json, mlp.history.csv, mlp.polach-fits.json), <OUT>/campaign.json (chosen_model: the campaign's model), <OUT>/report/index.html and <OUT>/timings.json (wall times, reuse: the only file that differs between identical runs). A re-run reuses runs whose log, sidecar and pipeline are unchanged (SHA-256) unless --force. Files that are not logs are listed as skipped, with why.\n\nExit codes: 0 ok, 1 error (no models, also when every run failed), 2 usage, 3 models written but some runs failed."
    )]
    Run(run::Args),
    /// Rebuild the HTML report of an output folder of `railgrip run`.
    Report(report::ReportArgs),
    /// Read one log (CSV or MCAP), resample it onto a uniform time base and print a summary.
    #[command(
        long_about = "Read one braking-test log and print what was found: duration, rate per \
channel, gaps, min/max per signal and warnings.\n\n\
The format is recognised from the file's bytes (MCAP magic or text CSV), not its extension. \
Column names, MCAP topics/fields and units come from the pipeline's [ingest.csv] / [ingest.mcap] \
sections; the default pipeline expects the canonical names of data-contract v1 (t, v_radar, \
omega1..4, p1..4; /radar/speed, /axleN/omega, /axleN/brake_pressure).\n\n\
With --out, writes <DIR>/<stem>.runlog.parquet: time_s, v_radar_mps, omega1..4_radps, p1..4_bar, \
valid (NaN/null inside gaps longer than ingest.max_gap_ms).\n\n\
Exit codes: 0 ok, 1 error (nothing written), 2 usage, 3 read but some input was skipped or lost \
(gaps, trimmed edges, implausible samples dropped)."
    )]
    Ingest(ingest::Args),
    /// Run a braking scene and write its logs (CSV/MCAP) and truth table (Parquet).
    #[command(
        long_about = "Run a scene file (pipelines/scenes/*.toml): a 4-axle vehicle braking on the \
adhesion law the scene sets, with only the effects it lists (load_transfer, wsp, hysteresis, \
falling_friction, temperature, cleaning, running_resistance, gradient, radar_noise, radar_spikes, \
tacho_quantization, pressure_noise, thermal; and the mismatches a self-calibration is to find or live with: brake_scatter, pad_friction, radar_error, load_fluctuation, pivot_force, whose true values go into the truth table's metadata, not the log).\n\n\
Writes <DIR>/<name>.csv + <name>.meta.toml (when all sensors share one rate), <name>.mcap, and \
<name>.truth.parquet (per sample and axle: time_s, axle, v_mps, omega_radps, p_bar, normal_N, \
tangential_N, mu, dv_mps, ddv_mps2, and with the thermal effect contact_temperature_c). The same scene and seed give identical bytes."
    )]
    Simulate(simulate::Args),
    /// Condition a log and estimate slip, loads, forces and μ per axle and sample.
    #[command(
        long_about = "Read one log, condition it (radar despiking; 4th-order Butterworth low-passes, zero-phase by default, [filters] in the pipeline) and estimate per axle and sample the slip Δv = v − rω and its rate, the slip ratio, the vehicle deceleration, the normal load N_i (load transfer, seed 002 eq. 12–13), the tangential force T_i = (J ω̇_i + α_i p_i)/r (eq. 9–10) and μ_i = T_i/N_i (eq. 14), with a validity flag.\n\nWrites <DIR>/<stem>.estimates.parquet (and .csv with --csv), one row per sample and axle: time_s, axle, v_mps, omega_radps, p_bar, dv_mps, ddv_mps2, slip_ratio, decel_mps2, normal_N, tangential_N, mu, valid. Prints per axle: peak μ, max slip, time sliding, adhesion utilisation and why samples were masked.\n\nExit codes: 0 ok, 1 error (nothing written), 2 usage, 3 written but some input was lost at ingest."
    )]
    Estimate(estimate::Args),
    /// Estimate the brake-torque coefficient α from a full-adhesion (dry) run.
    #[command(
        long_about = "Fit α of C_f = α p (seed 002 eq. 10) from the vehicle's longitudinal balance on a braking run without wheel slides: M v̇ + (J/r) Σ ω̇_i = −Σ α_i p_i / r − c0 − c2 v², by least squares with the resistance terms c0, c2 fitted alongside. Prints α with its standard error (corrected for the autocorrelation of filtered signals) and the TOML line for the pipeline file."
    )]
    Calibrate(estimate::CalibrateArgs),
    /// Train the seed 002 network μ(Δv, dΔv/dt) by Levenberg–Marquardt and write a model file.
    #[command(
        long_about = "Train a tanh MLP (default 10 hidden neurons, inputs Δv and dΔv/dt; [train] in the \
pipeline) on the valid estimates of the inputs with Levenberg–Marquardt (MATLAB trainlm semantics: \
mu schedule, epochs, min_grad, goal, validation early stopping with max_fail). Default split as in \
seed 002: train on axle 2, validate on axle 3, pooled over the runs. Only runs of one rail \
condition (run metadata `condition`; train.condition, default the most common) are used. Then \
Polach fits (all runs pooled, per run, per ambient temperature; profile-likelihood intervals) and the temperature law μ0(T), k_A(T), k_S(T) chosen by BIC.\n\n\
Inputs are estimates tables (railgrip estimate) or run logs (estimated on the fly). Writes \
<DIR>/<name>.json (network model file, see models/schema/), <DIR>/<name>.history.csv, \
<DIR>/<name>.polach.json (Polach model file, with its temperature law when the data choose one) and \
<DIR>/<name>.polach-fits.json (every fit), printing one line per epoch."
    )]
    Train(model::TrainArgs),
    /// Score a model file against the true adhesion of simulated scenes, on data-supported cells.
    #[command(
        long_about = "Simulate each SCENE (once per --seeds value, default the scene's seed) and score MODEL against the scene's true adhesion on the cells its data support (railgrip::score): cells every 0.1 m/s of slip, at ±{0.25, 0.5, 1, 2, 4, 8} m/s² of slip rate and every 10 km/h, with at least --min-samples true samples of one axle. Prints per scene and for all scenes together: supported cells, RMSE and largest error of μ, cells where the model predicts μ < 0, and the loss-minus-recovery difference (mean μ(Δv,+q) − μ(Δv,−q) over 0.5–3 m/s), predicted against true.\n\nExit codes: 0 ok, 1 error, 2 usage, 3 the model predicts μ < 0 on a supported cell."
    )]
    Score(score::Args),
    /// Export a model file: a header-only C99 evaluator, an FMI 2.0 FMU, or both.
    #[command(
        long_about = "Export a model file for simulators and rigs: --c-header FILE writes a header-only C99 evaluator (<prefix>_mu, _mu_v, _mu_vt, _mu_batch, _mu_batch_t; the Rust evaluator's results, bit for bit with exact FMA); --fmu OUT.fmu writes an FMI 2.0 Functional Mock-up Unit with Model Exchange and Co-Simulation (inputs dv_mps, ddv_mps2 for networks, v_mps, ambient_temperature_c where the model has a temperature input or law; output mu), its binary compiled for this host with the system C compiler ($CC, else cc) and its sources for every other platform; --fmu-sources-only writes a source FMU without a compiler. Either or both.\n\nExit codes: 0 ok, 1 error (nothing written for the failing output), 2 usage."
    )]
    Export(model::ExportArgs),
    /// Creep curves of the contact laws (linear, saturated, Polach, FASTSIM) for one patch, and flash temperatures, as CSV.
    #[command(
        long_about = "Compute creep-force curves F_x(ξ) for ξ = 0 … --creepage-max on the Hertz patch of a wheel (--load-n, --wheel-radius-m, profile radii, E, ν) under the chosen laws side by side, so they can be compared: Kalker's linear theory, linear + Shen–Hedrick–Elkins saturation, Polach (seed 004) and FASTSIM (plain or modified after Spiryagin et al. 2013; grid --grid × --grid, elliptic or parabolic bound; also F_y, M_z and the slip-area fraction). With --temperature, the flash temperature of the first FASTSIM law's slip field by the strip model of seed 000 (peak in the contact and --after-ms behind it) and the frictional power.\n\nColumns: creepage, slip_velocity_mps, then per law fx_<law>_N, mu_<law> (F_x/N) and for FASTSIM fy_<law>_N, mz_<law>_Nm, slip_fraction_<law>; with --temperature peak_temperature_c, after_temperature_c, power_W. Writes --out atomically, else standard output; the patch is printed on standard error."
    )]
    Contact(contact::Args),
    /// What accuracy costs in time: a plan of model families, sizes, training and conditioning settings, each trained and measured on a campaign.
    #[command(
        long_about = "Train and measure every cell of a study plan on a campaign (default: the bundled plan pipelines/study.toml on the bundled archive): each cell is a complete pipeline (the base pipeline with the grid's keys set), estimated with its conditioning, trained on the runs of one rail condition except the held-out ones, and measured: training time, evaluation ns per μ (Rust single call and batch; a plain loop with the fast and with the C library's tanh), model-file size, RMSE on the held-out runs, and the supported-cell error against the true law where the held-out runs carry truth (<stem>.truth.parquet beside the log, as railgrip simulate writes it).\n\nWrites <OUT>/study.html (Pareto fronts, the recommendation for --budget-ns/--budget-train-s, every cell), <OUT>/study.csv, <OUT>/study.json, and <OUT>/cells/<key>.json + .model.json per cell: a second study reuses finished cells and estimates (SHA-256 keys), so an interrupted study resumes. A plan over study.max_cells or study.max_minutes (estimated) is refused unless --force.\n\nExit codes: 0 ok (cells that failed are listed), 1 error, 2 usage."
    )]
    Study(study::Args),
    /// Evaluate a model file on a CSV grid (dv_mps, ddv_mps2[, v_mps][, ambient_temperature_c]) and write mu.
    Eval(model::EvalArgs),
}

/// Pipeline option shared by commands.
#[derive(clap::Args, Clone)]
pub struct PipelineArg {
    /// Pipeline file (TOML); default: the embedded pipelines/uic_z1.toml.
    #[arg(long, value_name = "FILE")]
    pub pipeline: Option<PathBuf>,
}

impl PipelineArg {
    pub fn load(&self) -> anyhow::Result<railgrip::Pipeline> {
        Ok(railgrip::Pipeline::load(self.pipeline.as_deref())?)
    }
}

pub fn main() -> ExitCode {
    // The CSV reader's worker threads (`polars-N`) can panic on malformed rows; the library
    // catches that and reports a clean error naming the file and line, so their panic
    // message would only be noise before it. Every other panic is printed as usual.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let polars = std::thread::current()
            .name()
            .is_some_and(|n| n.starts_with("polars"));
        if !polars {
            default_hook(info);
        }
    }));
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { EXIT_USAGE } else { EXIT_OK });
        }
    };
    let result = match cli.command {
        Command::Run(args) => run::run(args),
        Command::Report(args) => report::report(args),
        Command::Ingest(args) => ingest::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Estimate(args) => estimate::run(args),
        Command::Calibrate(args) => estimate::calibrate_run(args),
        Command::Train(args) => model::train(args),
        Command::Export(args) => model::export(args),
        Command::Score(args) => score::run(args),
        Command::Eval(args) => model::eval(args),
        Command::Contact(args) => contact::run(args),
        Command::Study(args) => study::run(args),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            // Library errors carry the whole story (where, what, hint) in their message; a
            // context added here (`file: cannot write`) is followed by its causes, down to the
            // operating system's (5 of 7 "cannot write" errors once omitted it).
            let mut msg = e.to_string();
            for cause in e.chain().skip(1) {
                let c = cause.to_string();
                if !msg.contains(&c) {
                    msg.push_str(": ");
                    msg.push_str(&c);
                }
            }
            eprintln!("error: {msg}");
            ExitCode::from(EXIT_ERROR)
        }
    }
}
