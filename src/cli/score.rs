//! `railgrip score`: a model file against the truth of simulated scenes, on the cells the
//! scenes' data support (railgrip::score).

use std::path::PathBuf;

use anyhow::Context as _;
use railgrip::model::Model;
use railgrip::score::{score, Grid, Sample, Score};
use railgrip::sim::{self, Scene};

use super::{EXIT_LOSSY, EXIT_OK};

#[derive(clap::Args)]
pub struct Args {
    /// A model file (railgrip train or run: mlp.json, mlp.polach.json).
    #[arg(value_name = "MODEL")]
    model: PathBuf,
    /// Scene files (TOML) whose truth scores the model, e.g. pipelines/scenes/foreign/*.toml.
    #[arg(value_name = "SCENE", required = true)]
    scenes: Vec<PathBuf>,
    /// Seeds of the sensor noise: each scene is simulated once per seed (default: its own).
    #[arg(long, value_delimiter = ',')]
    seeds: Vec<u64>,
    /// Samples of one axle a cell needs to count as supported.
    #[arg(long, default_value_t = 20)]
    min_samples: usize,
    /// Print the scores as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(serde::Serialize)]
struct Line {
    scene: String,
    cells: usize,
    rmse: f64,
    max_error: f64,
    negative_cells: usize,
    hysteresis_true: Option<f64>,
    hysteresis_predicted: Option<f64>,
}

impl Line {
    fn new(scene: &str, s: &Score) -> Line {
        Line {
            scene: scene.to_string(),
            cells: s.cells.len(),
            rmse: s.rmse,
            max_error: s.max_error,
            negative_cells: s.negative_cells,
            hysteresis_true: s.hysteresis.map(|h| h.0),
            hysteresis_predicted: s.hysteresis.map(|h| h.1),
        }
    }
}

pub fn run(args: Args) -> anyhow::Result<u8> {
    let model = Model::load(&args.model)?;
    let grid = Grid {
        min_samples: args.min_samples.max(1),
        ..Grid::default()
    };
    let mut lines = Vec::new();
    let mut pooled: Vec<Sample> = Vec::new();
    let mut runs = 0usize;
    for path in &args.scenes {
        let scene = Scene::load(path)?;
        let seeds = if args.seeds.is_empty() {
            vec![scene.seed]
        } else {
            args.seeds.clone()
        };
        for seed in seeds {
            let out = sim::simulate(&scene, Some(seed))?;
            let t_c = scene.run.ambient_temperature_c;
            let samples = out.truth.samples(t_c);
            let name = format!("{} (seed {seed})", scene.name);
            let s = score(&samples, &grid, |dv, q, v, t| model.mu_vt(dv, q, v, t))
                .with_context(|| format!("{}: scoring {}", path.display(), args.model.display()))?;
            lines.push(Line::new(&name, &s));
            // Pooled: the axles of each simulated run numbered apart (while they fit a u8),
            // so that a cell's support counts one run's samples.
            let offset = if runs < 63 { 4 * runs as u8 } else { 0 };
            pooled.extend(samples.into_iter().map(|x| Sample {
                axle: x.axle + offset,
                ..x
            }));
            runs += 1;
        }
    }
    // All scenes together, each sample at its own scene's ambient temperature.
    let all = score(&pooled, &grid, |dv, q, v, t| model.mu_vt(dv, q, v, t))?;
    lines.push(Line::new("all", &all));
    let negative = lines.iter().any(|l| l.negative_cells > 0);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&lines)?);
    } else {
        println!(
            "{:<40} {:>6} {:>8} {:>8} {:>9} {:>12}",
            "scene", "cells", "RMSE μ", "max |e|", "μ̂ < 0", "hysteresis"
        );
        for l in &lines {
            println!(
                "{:<40} {:>6} {:>8.4} {:>8.4} {:>9} {:>12}",
                l.scene,
                l.cells,
                l.rmse,
                l.max_error,
                l.negative_cells,
                match (l.hysteresis_true, l.hysteresis_predicted) {
                    (Some(t), Some(p)) => format!("{p:+.4}/{t:+.4}"),
                    _ => "–".into(),
                }
            );
        }
        println!("\nCells: Δv every 0.1 m/s (±0.1), dΔv/dt ±{{0.25 … 8}} m/s² (×0.5–1.5), v every 10 km/h (±15), ≥ {} truth samples of one axle. Hysteresis: mean μ(Δv,+q) − μ(Δv,−q) over 0.5–3 m/s, predicted/true.", grid.min_samples);
        if negative {
            println!("The model predicts μ < 0 on supported cells. Exit code 3.");
        }
    }
    Ok(if negative { EXIT_LOSSY } else { EXIT_OK })
}
