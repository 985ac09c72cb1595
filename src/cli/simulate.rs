//! `railgrip simulate`: run a scene, write the log(s) and the truth table.

use std::path::PathBuf;

use railgrip::sim::{self, OutputFormat, Scene};

use super::EXIT_OK;

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum Format {
    Csv,
    Mcap,
    Both,
}

#[derive(clap::Args)]
pub struct Args {
    /// The scene file (TOML), e.g. pipelines/scenes/soap_120kmh_p20.toml.
    #[arg(value_name = "SCENE")]
    scene: PathBuf,
    /// Directory for <name>.csv + .meta.toml, <name>.mcap and <name>.truth.parquet.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// A campaign's noise seed: the scene's noise comes from it and the scene's own `seed`
    /// (the scenes of a folder simulated with one --seed draw independent noise; the seed
    /// used is printed and in the log's metadata).
    #[arg(long)]
    seed: Option<u64>,
    /// Log format to write.
    #[arg(long, value_enum, default_value = "both")]
    format: Format,
}

pub fn run(args: Args) -> anyhow::Result<u8> {
    let scene = Scene::load(&args.scene)?;
    let started = std::time::Instant::now();
    let out = sim::simulate(&scene, args.seed)?;
    let elapsed = started.elapsed().as_secs_f64();
    let fmt = match args.format {
        Format::Csv => OutputFormat::Csv,
        Format::Mcap => OutputFormat::Mcap,
        Format::Both if scene.single_rate() => OutputFormat::Both,
        Format::Both => OutputFormat::Mcap,
    };
    let written = out.write(&args.out, &scene.name, fmt)?;
    println!(
        "scene      {} (noise seed {}): {:.2} s simulated in {} steps of {} ms, {:.3} s wall ({:.0}x real time)",
        scene.name,
        sim::run_seed(&scene, args.seed),
        out.duration_s,
        out.steps,
        scene.run.step_s * 1e3,
        elapsed,
        out.duration_s / elapsed
    );
    println!(
        "effects    {}",
        if scene.effects.names().is_empty() {
            "none".to_string()
        } else {
            scene.effects.names().join(", ")
        }
    );
    for p in written {
        println!("wrote      {}", p.display());
    }
    Ok(EXIT_OK)
}
