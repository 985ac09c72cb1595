//! Command-line interface. The only place that prints or picks exit codes.

mod ingest;
mod simulate;

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
tacho_quantization, pressure_noise).\n\n\
Writes <DIR>/<name>.csv + <name>.meta.toml (when all sensors share one rate), <name>.mcap, and \
<name>.truth.parquet (per sample and axle: time_s, axle, v_mps, omega_radps, p_bar, normal_N, \
tangential_N, mu, dv_mps, ddv_mps2). The same scene and seed give identical bytes."
    )]
    Simulate(simulate::Args),
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
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { EXIT_USAGE } else { EXIT_OK });
        }
    };
    let result = match cli.command {
        Command::Ingest(args) => ingest::run(args),
        Command::Simulate(args) => simulate::run(args),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            // Library errors carry the whole story (where, what, hint) in their message.
            eprintln!("error: {e}");
            ExitCode::from(EXIT_ERROR)
        }
    }
}
