//! `railgrip score`: a model file against the truth of simulated scenes, on the cells the
//! scenes' data support (railgrip::score): per scene, then the curve view per initial speed and
//! the replay view per speed band.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::Context as _;
use railgrip::model::Model;
use railgrip::score::{
    pooled_hysteresis_ratio, replay, score, Band, CurveSupport, Grid, Sample, Score, Stats,
    SPEED_BANDS_KMH,
};
use railgrip::sim::{self, Scene, TrueLaw};

use super::{EXIT_LOSSY, EXIT_OK};

#[derive(clap::Args)]
pub struct Args {
    /// A model file (railgrip train or run: mlp.json, mlp.polach.json).
    #[arg(value_name = "MODEL")]
    model: PathBuf,
    /// Scene files (TOML) whose truth scores the model, e.g. pipelines/scenes/foreign/*.toml.
    #[arg(value_name = "SCENE", required = true)]
    scenes: Vec<PathBuf>,
    /// Campaign noise seeds, as `simulate --seed` takes them: each scene is simulated once per
    /// seed (default: once, with its own noise).
    #[arg(long, value_delimiter = ',')]
    seeds: Vec<u64>,
    /// Samples of one axle a cell needs to count as supported.
    #[arg(long, default_value_t = 20)]
    min_samples: usize,
    /// Print the scores as JSON.
    #[arg(long)]
    json: bool,
}

/// True loss − recovery differences below this give no hysteresis ratio.
const MIN_HYSTERESIS: f64 = 0.002;

/// A curve's mean true and predicted loss − recovery differences and their pairs
/// ([`railgrip::score::CurveScore::hysteresis_with_pairs`]).
type Hysteresis = Option<(f64, f64, usize)>;

/// A curve table's hysteresis columns: each line's own ratio, and its differences and pairs.
type HysteresisOf = (fn(&Line) -> Option<f64>, fn(&Line) -> Hysteresis);

#[derive(serde::Serialize)]
struct Line {
    scene: String,
    initial_speed_kmh: f64,
    ambient_temperature_c: f64,
    cells: usize,
    rmse: f64,
    max_error: f64,
    negative_cells: usize,
    hysteresis_true: Option<f64>,
    hysteresis_predicted: Option<f64>,
    /// The curve view at the run's initial speed and temperature (laws in closed form only).
    curve: Option<Stats>,
    curve_hysteresis_ratio: Option<f64>,
    /// The curve's mean true and predicted loss − recovery differences and their pairs (a
    /// band pools its runs by them).
    curve_hysteresis: Hysteresis,
    /// The curve view with each cell at its samples' mean slip and slip rate (the run's
    /// states) instead of its nominal centre, and its hysteresis ratio.
    curve_at_states: Option<Stats>,
    curve_at_states_hysteresis_ratio: Option<f64>,
    curve_at_states_hysteresis: Hysteresis,
    /// The scene's rail condition (`adhesion.level_scale`); absent for laws without one.
    level_scale: Option<f64>,
    /// The curve view against the law at the scored runs' mean condition (the run's law
    /// × s̄/s): the model's error with the run's own condition taken out.
    curve_mean_condition: Option<Stats>,
    /// The law at the mean condition against the run's own law on the same cells: what a
    /// campaign model that knew the law exactly, but not the run's condition, would score.
    curve_condition_floor: Option<Stats>,
    /// The replay view per speed band.
    replay: Vec<Band>,
    /// The replay view of the true law itself at the run's condition (each sample's slip,
    /// slip rate and speed; the truth blends its branches by a lagged slip rate and loads
    /// each wheel dynamically, which no μ(Δv, dΔv/dt, v) has): a reference, not a bound — a
    /// fitted model may absorb part of those effects on average.
    replay_law: Vec<Band>,
    /// The same with the law at the scored runs' mean condition (the run's law × s̄/s): the
    /// reference for a campaign model, which cannot know the run's own condition.
    replay_condition_floor: Vec<Band>,
}

impl Line {
    fn new(scene: &str, v0_kmh: f64, t_c: f64, s: &Score) -> Line {
        Line {
            scene: scene.to_string(),
            initial_speed_kmh: v0_kmh,
            ambient_temperature_c: t_c,
            cells: s.cells.len(),
            rmse: s.rmse,
            max_error: s.max_error,
            negative_cells: s.negative_cells,
            hysteresis_true: s.hysteresis.map(|h| h.0),
            hysteresis_predicted: s.hysteresis.map(|h| h.1),
            curve: None,
            curve_hysteresis_ratio: None,
            curve_hysteresis: None,
            curve_at_states: None,
            curve_at_states_hysteresis_ratio: None,
            curve_at_states_hysteresis: None,
            level_scale: None,
            curve_mean_condition: None,
            curve_condition_floor: None,
            replay: Vec::new(),
            replay_law: Vec::new(),
            replay_condition_floor: Vec::new(),
        }
    }
}

/// One row of the per-band tables: pooled statistics and the range of the runs' biases.
#[derive(serde::Serialize)]
struct BandRow {
    lo_kmh: f64,
    hi_kmh: f64,
    runs: usize,
    pooled: Stats,
    /// The runs' biases averaged with one weight per run (the pooled bias weighs each run by
    /// its cells or samples: a run on a slippery rail, which slides more, counts most).
    bias_run_mean: f64,
    bias_min: f64,
    bias_max: f64,
    /// Curve view only: the range of the runs' hysteresis ratios.
    hysteresis_ratio: Option<(f64, f64)>,
    /// Curve view only: the band's own ratio, its runs' pairs pooled
    /// ([`pooled_hysteresis_ratio`]), as `pooled` pools their cells (a run on a slippery rail,
    /// which supports more cells, weighs most) …
    hysteresis_ratio_pooled: Option<f64>,
    /// … and the mean of the runs' own ratios, one weight per run (as `bias_run_mean`).
    hysteresis_ratio_run_mean: Option<f64>,
}

#[derive(serde::Serialize)]
struct Report {
    scenes: Vec<Line>,
    /// Every scene's samples pooled (the per-cell score only).
    all: Line,
    curve_by_initial_speed: Vec<BandRow>,
    /// The curve view with each cell at its samples' mean slip and slip rate.
    curve_at_runs_states: Vec<BandRow>,
    /// The scored runs' mean rail condition s̄ (one weight per scene), where their conditions
    /// differ; the two tables below only then.
    mean_level_scale: Option<f64>,
    curve_at_mean_condition: Vec<BandRow>,
    curve_condition_floor: Vec<BandRow>,
    replay_by_speed_band: Vec<BandRow>,
    /// The true law replayed at its own runs' conditions, and at their mean condition (the
    /// latter where the conditions differ).
    replay_law_by_speed_band: Vec<BandRow>,
    replay_condition_floor_by_speed_band: Vec<BandRow>,
}

pub fn run(args: Args) -> anyhow::Result<u8> {
    let model = Model::load(&args.model)?;
    let grid = Grid {
        min_samples: args.min_samples.max(1),
        ..Grid::default()
    };
    let predict = |dv, q, v, t| model.mu_vt(dv, q, v, t);
    let mut lines = Vec::new();
    let mut pooled: Vec<Sample> = Vec::new();
    let mut runs = 0usize;
    let mut loaded = Vec::with_capacity(args.scenes.len());
    for path in &args.scenes {
        let scene = Scene::load(path)?;
        let law = TrueLaw::of(&scene)?;
        loaded.push((path, scene, law));
    }
    // The mean condition of the scenes whose law has one, where their conditions differ (the
    // two tables then cover those scenes only).
    let scales: Vec<f64> = loaded
        .iter()
        .filter(|(_, _, law)| law.is_some())
        .filter_map(|(_, scene, _)| scene.adhesion.law.level_scale())
        .collect();
    let mean_scale = (scales.iter().any(|s| *s != scales[0]))
        .then(|| scales.iter().sum::<f64>() / scales.len() as f64);
    for (path, scene, law) in loaded {
        // Without --seeds, the scene's own noise (as `simulate` without --seed).
        let seeds: Vec<Option<u64>> = if args.seeds.is_empty() {
            vec![None]
        } else {
            args.seeds.iter().copied().map(Some).collect()
        };
        for seed in seeds {
            let out = sim::simulate(&scene, seed)?;
            // The noise seed the run was simulated with (as `simulate` prints it).
            let seed = sim::run_seed(&scene, seed);
            let (v0_kmh, t_c) = (scene.run.initial_speed_kmh, scene.run.ambient_temperature_c);
            let samples = out.truth.samples(t_c);
            let name = format!("{} (noise seed {seed})", scene.name);
            let context = || format!("{}: scoring {}", path.display(), args.model.display());
            let s = score(&samples, &grid, predict).with_context(context)?;
            let mut line = Line::new(&name, v0_kmh, t_c, &s);
            if let Some(law) = &law {
                let v0 = v0_kmh / 3.6;
                let own = |dv, q, v, _| law.mu(dv, q, v);
                // The run's cells once, for every curve table below.
                let cells = CurveSupport::of(&samples, &grid).with_context(context)?;
                let c = cells
                    .curve(false, v0, t_c, predict, own)
                    .with_context(context)?;
                line.curve = Some(c.stats);
                line.curve_hysteresis_ratio = c.hysteresis_ratio(MIN_HYSTERESIS);
                line.curve_hysteresis = c.hysteresis_with_pairs();
                let c = cells
                    .curve(true, v0, t_c, predict, own)
                    .with_context(context)?;
                line.curve_at_states = Some(c.stats);
                line.curve_at_states_hysteresis_ratio = c.hysteresis_ratio(MIN_HYSTERESIS);
                line.curve_at_states_hysteresis = c.hysteresis_with_pairs();
                line.replay_law =
                    replay(&samples, &grid, &SPEED_BANDS_KMH, own).with_context(context)?;
                line.level_scale = scene.adhesion.law.level_scale();
                if let (Some(mean), Some(own_scale)) = (mean_scale, line.level_scale) {
                    // μ is proportional to the condition: the law at the mean one is × s̄/s.
                    let at_mean = |dv, q, v, _| law.mu(dv, q, v) * mean / own_scale;
                    let m = cells.curve(false, v0, t_c, predict, at_mean);
                    line.curve_mean_condition = Some(m.with_context(context)?.stats);
                    let f = cells.curve(false, v0, t_c, at_mean, own);
                    line.curve_condition_floor = Some(f.with_context(context)?.stats);
                    line.replay_condition_floor =
                        replay(&samples, &grid, &SPEED_BANDS_KMH, at_mean).with_context(context)?;
                }
            }
            line.replay =
                replay(&samples, &grid, &SPEED_BANDS_KMH, predict).with_context(context)?;
            lines.push(line);
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
    let all = score(&pooled, &grid, predict)?;
    let negative = lines.iter().any(|l| l.negative_cells > 0) || all.negative_cells > 0;
    let report = Report {
        curve_by_initial_speed: curve_rows(
            &lines,
            |l| l.curve,
            Some((|l| l.curve_hysteresis_ratio, |l| l.curve_hysteresis)),
        ),
        curve_at_runs_states: curve_rows(
            &lines,
            |l| l.curve_at_states,
            Some((
                |l| l.curve_at_states_hysteresis_ratio,
                |l| l.curve_at_states_hysteresis,
            )),
        ),
        mean_level_scale: mean_scale,
        curve_at_mean_condition: curve_rows(&lines, |l| l.curve_mean_condition, None),
        curve_condition_floor: curve_rows(&lines, |l| l.curve_condition_floor, None),
        replay_by_speed_band: replay_rows(&lines, |l| &l.replay),
        replay_law_by_speed_band: replay_rows(&lines, |l| &l.replay_law),
        replay_condition_floor_by_speed_band: replay_rows(&lines, |l| &l.replay_condition_floor),
        scenes: lines,
        all: Line::new("all", f64::NAN, f64::NAN, &all),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_report(&report, grid.min_samples);
        if negative {
            println!("The model predicts μ < 0 on supported cells. Exit code 3.");
        }
    }
    Ok(if negative { EXIT_LOSSY } else { EXIT_OK })
}

/// A curve view (`stats` of each run) grouped by the runs' initial speeds (each run's cells
/// pooled), with the runs' hysteresis ratios (`ratio`) where given.
fn curve_rows(
    lines: &[Line],
    stats: fn(&Line) -> Option<Stats>,
    hysteresis: Option<HysteresisOf>,
) -> Vec<BandRow> {
    let mut by: BTreeMap<u64, Vec<&Line>> = BTreeMap::new();
    for l in lines.iter().filter(|l| stats(l).is_some()) {
        by.entry(l.initial_speed_kmh.to_bits()).or_default().push(l);
    }
    let mut rows: Vec<BandRow> = by
        .into_values()
        .map(|ls| {
            let stats: Vec<Stats> = ls.iter().filter_map(|l| stats(l)).collect();
            let v = ls[0].initial_speed_kmh;
            let Some((ratio, pairs)) = hysteresis else {
                return row(v, v, &stats, &[]);
            };
            let ratios: Vec<f64> = ls.iter().filter_map(|l| ratio(l)).collect();
            BandRow {
                hysteresis_ratio_pooled: pooled_hysteresis_ratio(
                    ls.iter().map(|l| pairs(l)),
                    MIN_HYSTERESIS,
                ),
                ..row(v, v, &stats, &ratios)
            }
        })
        .collect();
    rows.sort_by(|a, b| a.lo_kmh.total_cmp(&b.lo_kmh));
    rows
}

/// A replay view (`bands` of a line: the model's, or a floor's) per speed band over all runs.
fn replay_rows(lines: &[Line], bands: fn(&Line) -> &Vec<Band>) -> Vec<BandRow> {
    let mut by: BTreeMap<u64, (f64, f64, Vec<Stats>)> = BTreeMap::new();
    for b in lines.iter().flat_map(bands) {
        by.entry(b.lo_kmh.to_bits())
            .or_insert((b.lo_kmh, b.hi_kmh, Vec::new()))
            .2
            .push(b.stats);
    }
    let mut rows: Vec<BandRow> = by
        .into_values()
        .map(|(lo, hi, stats)| row(lo, hi, &stats, &[]))
        .collect();
    rows.sort_by(|a, b| a.lo_kmh.total_cmp(&b.lo_kmh));
    rows
}

/// Pools per-run statistics: n-weighted bias and mean square, largest error, bias range.
fn row(lo: f64, hi: f64, stats: &[Stats], ratios: &[f64]) -> BandRow {
    let n: usize = stats.iter().map(|s| s.n).sum();
    let w = |f: &dyn Fn(&Stats) -> f64| stats.iter().map(|s| s.n as f64 * f(s)).sum::<f64>();
    let nf = n.max(1) as f64;
    BandRow {
        lo_kmh: lo,
        hi_kmh: hi,
        runs: stats.len(),
        pooled: Stats {
            n,
            rmse: (w(&|s| s.rmse * s.rmse) / nf).sqrt(),
            bias: w(&|s| s.bias) / nf,
            max_error: stats.iter().map(|s| s.max_error).fold(0.0, f64::max),
        },
        bias_run_mean: {
            // Runs with no cell or sample in the band have no bias.
            let held: Vec<f64> = stats.iter().filter(|s| s.n > 0).map(|s| s.bias).collect();
            held.iter().sum::<f64>() / held.len().max(1) as f64
        },
        bias_min: stats.iter().map(|s| s.bias).fold(f64::INFINITY, f64::min),
        bias_max: stats
            .iter()
            .map(|s| s.bias)
            .fold(f64::NEG_INFINITY, f64::max),
        hysteresis_ratio: (!ratios.is_empty()).then(|| {
            let lo = ratios.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (lo, hi)
        }),
        hysteresis_ratio_pooled: None,
        hysteresis_ratio_run_mean: (!ratios.is_empty())
            .then(|| ratios.iter().sum::<f64>() / ratios.len() as f64),
    }
}

fn print_report(r: &Report, min_samples: usize) {
    println!(
        "{:<40} {:>6} {:>8} {:>8} {:>9} {:>16} {:>9} {:>9}",
        "scene", "cells", "RMSE μ", "max |e|", "μ̂ < 0", "hysteresis", "curve", "bias"
    );
    for l in r.scenes.iter().chain(std::iter::once(&r.all)) {
        println!(
            "{:<40} {:>6} {:>8.4} {:>8.4} {:>9} {:>16} {:>9} {:>9}",
            l.scene,
            l.cells,
            l.rmse,
            l.max_error,
            l.negative_cells,
            match (l.hysteresis_true, l.hysteresis_predicted) {
                (Some(t), Some(p)) => format!("{p:+.4}/{t:+.4}"),
                _ => "–".into(),
            },
            l.curve.map_or("–".into(), |c| format!("{:.4}", c.rmse)),
            l.curve.map_or("–".into(), |c| format!("{:+.4}", c.bias)),
        );
    }
    println!("\nCells: Δv every 0.1 m/s (±0.1), dΔv/dt ±{{0.25 … 8}} m/s² (×0.5–1.5), v every 10 km/h (±15), ≥ {min_samples} truth samples of one axle. Hysteresis: mean μ(Δv,+q) − μ(Δv,−q) over 0.5–3 m/s, predicted/true.");
    let table = |title: &str, rows: &[BandRow], speed: &dyn Fn(&BandRow) -> String| {
        println!("\n{title}");
        println!(
            "{:<12} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>19} {:>27}",
            "km/h",
            "runs",
            "n",
            "RMSE μ",
            "bias",
            "run mean",
            "max |e|",
            "run biases",
            "hyst. ratio: pooled, mean (runs)"
        );
        for b in rows {
            println!(
                "{:<12} {:>5} {:>8} {:>8.4} {:>+8.4} {:>+8.4} {:>8.4} {:>19} {:>27}",
                speed(b),
                b.runs,
                b.pooled.n,
                b.pooled.rmse,
                b.pooled.bias,
                b.bias_run_mean,
                b.pooled.max_error,
                format!("{:+.4} … {:+.4}", b.bias_min, b.bias_max),
                match (
                    b.hysteresis_ratio_pooled,
                    b.hysteresis_ratio_run_mean,
                    b.hysteresis_ratio,
                ) {
                    (Some(p), Some(m), Some((lo, hi))) => {
                        format!("{p:.2}, {m:.2} ({lo:.2} … {hi:.2})")
                    }
                    _ => "–".into(),
                },
            );
        }
    };
    if !r.curve_by_initial_speed.is_empty() {
        table(
            "Curve view: the model at each run's initial speed and ambient temperature against the true law, on the run's supported (Δv, dΔv/dt) cells (n = cells)",
            &r.curve_by_initial_speed,
            &|b| format!("{:.0}", b.lo_kmh),
        );
        table(
            "Curve view at the runs' states: the same cells, each at its samples' mean Δv and dΔv/dt (the axle with the most samples there) instead of its nominal centre — a slip-rate window spans 0.5–1.5 × its centre",
            &r.curve_at_runs_states,
            &|b| format!("{:.0}", b.lo_kmh),
        );
    }
    if let Some(mean) = r.mean_level_scale {
        table(
            &format!("Curve view against the law at the runs' mean rail condition (level_scale s̄ = {mean:.4}; each run's law × s̄/s): the model's error without the run's own condition, which no campaign model can know"),
            &r.curve_at_mean_condition,
            &|b| format!("{:.0}", b.lo_kmh),
        );
        table(
            "Condition floor: the law at the mean condition against each run's own law on the same cells — what a campaign model with the exact law would score in the curve view",
            &r.curve_condition_floor,
            &|b| format!("{:.0}", b.lo_kmh),
        );
    }
    let band = |b: &BandRow| format!("{:.0}–{:.0}", b.lo_kmh, b.hi_kmh);
    table(
        "Replay view: the model at each sample's own inputs against its μ, samples in supported cells, by the sample's speed (n = samples)",
        &r.replay_by_speed_band,
        &band,
    );
    if !r.replay_law_by_speed_band.is_empty() {
        table(
            "Replay of the true law itself, at each sample's slip, slip rate and speed and its run's condition: a reference for a model of μ(Δv, dΔv/dt, v) (the truth blends its branches by a lagged slip rate and loads each wheel dynamically, which such a model can follow only on average)",
            &r.replay_law_by_speed_band,
            &band,
        );
    }
    if !r.replay_condition_floor_by_speed_band.is_empty() {
        table(
            "Replay of the true law at the runs' mean condition, as above: the reference for a campaign model — a model trained on the pooled runs sees one curve where two runs at the same speed and temperature on different rails had two, so run biases of this size remain",
            &r.replay_condition_floor_by_speed_band,
            &band,
        );
    }
}
