//! Foreign-law truth: the scenes of `pipelines/scenes/foreign/` brake on adhesion
//! laws outside the families railgrip fits; `railgrip::score` judges a learned curve against
//! their truth on data-supported cells.
//!
//! `measure_networks_on_foreign_laws` (ignored: a measurement, about a minute) prints the
//! supported-cell scores of the networks `railgrip train` makes from these runs:
//!     cargo test --test foreign -- --ignored --nocapture

mod common;

use std::path::{Path, PathBuf};

use railgrip::config::TrainConfig;
use railgrip::identify::dataset::RunTable;
use railgrip::identify::export::mlp_file;
use railgrip::identify::TrainedMlp;
use railgrip::identify::{creep_spec, median_speed, train_mlp};
use railgrip::model::{InputSet, Model, ModelFile, Provenance};
use railgrip::score::{score, Grid, Sample, Score};
use railgrip::sim::{self, AdhesionLaw, OutputFormat, Scene};
use railgrip::Pipeline;

fn scenes() -> Vec<PathBuf> {
    scene_files("pipelines/scenes/foreign")
}

/// The scene files (`*.toml`) of a folder of the repository, sorted.
fn scene_files(folder: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(folder);
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

/// The top-speed scenes: every run follows its law, whose level falls by more than 10 % from
/// 120 to 160 km/h and faster above (the quadratic form; flat forms such as the `ratio` one
/// of the scenes above lose ~4 %), and the three runs at one speed differ in rail condition.
#[test]
fn top_speed_scenes_follow_a_level_that_falls_steeper_at_the_top() {
    let paths = scene_files("pipelines/scenes/top_speed");
    assert_eq!(paths.len(), 12, "{paths:?}");
    let mut scales = std::collections::BTreeSet::new();
    for path in paths {
        let sc = Scene::load(&path).unwrap();
        let AdhesionLaw::LossRecovery(l) = &sc.adhesion.law else {
            panic!("{}: not loss_recovery", sc.name)
        };
        assert_eq!(l.speed_form, railgrip::sim::foreign::SpeedForm::Quadratic);
        scales.insert((l.level_scale * 100.0).round() as i64);
        let law = railgrip::sim::TrueLaw::of(&sc).unwrap().unwrap();
        let level = |kmh: f64| law.mu(0.8, 1.0, kmh / 3.6);
        let (l80, l120, l160, l200) = (level(80.0), level(120.0), level(160.0), level(200.0));
        assert!(
            l160 / l120 < 0.9 && l200 / l160 < l160 / l120 && l120 < l80,
            "{}",
            sc.name
        );
        let out = sim::simulate(&sc, None).unwrap();
        let samples = out.truth.samples(sc.run.ambient_temperature_c);
        let s = score(&samples, &Grid::default(), |dv, q, v, _| law.mu(dv, q, v)).unwrap();
        // The simulator lags the slip rate by 20 ms; the law here does not (measured: RMSE
        // 0.0008–0.0036 over the 12 runs).
        eprintln!(
            "{}: truth against its law RMSE {:.4}, {} cells",
            sc.name,
            s.rmse,
            s.cells.len()
        );
        assert!(
            s.rmse < 4e-3 && s.cells.len() > 100,
            "{}: {} {}",
            sc.name,
            s.rmse,
            s.cells.len()
        );
    }
    assert_eq!(scales.into_iter().collect::<Vec<_>>(), [95, 100, 105]);
}

/// The scene's true law at the sample's inputs (the slip rate unlagged: the simulator lags it
/// by 20 ms, which is part of what a learned curve cannot see).
fn true_law(sc: &Scene) -> impl Fn(f64, f64, f64, f64) -> f64 + '_ {
    let lr = match &sc.adhesion.law {
        AdhesionLaw::LossRecovery(l) => Some(l.prepare(Some(sc.run.ambient_temperature_c))),
        _ => None,
    };
    move |dv, q, v, _t| match (&sc.adhesion.law, &lr) {
        (AdhesionLaw::LossRecovery(_), Some(p)) => p.mu(dv, q, v),
        (AdhesionLaw::Table(t), _) => t.mu(dv, v),
        other => panic!("not a foreign law: {other:?}"),
    }
}

#[test]
fn foreign_scenes_cover_the_plane_and_their_truth_follows_their_law() {
    let all = scenes();
    assert_eq!(all.len(), 14, "{all:?}");
    for path in all {
        let sc = Scene::load(&path).unwrap();
        let out = sim::simulate(&sc, None).unwrap();
        let samples = out.truth.samples(sc.run.ambient_temperature_c);
        let s = score(&samples, &Grid::default(), true_law(&sc)).unwrap();
        let name = &sc.name;
        eprintln!(
            "{name}: {} supported cells, truth against its law RMSE {:.1e}, max {:.1e}, hysteresis {:?}",
            s.cells.len(),
            s.rmse,
            s.max_error,
            s.hysteresis
        );
        // WSP cycles spread the data over slip and both signs of slip rate.
        assert!(s.cells.len() > 150, "{name}: {} cells", s.cells.len());
        // What is left is the simulator's 20 ms lag of the slip rate at WSP transitions.
        assert!(
            s.rmse < 3e-3 && s.max_error < 2.5e-2,
            "{name}: RMSE {} max {}",
            s.rmse,
            s.max_error
        );
        let (t, _) = s.hysteresis.expect("pairs of rising and falling slip");
        match sc.adhesion.law {
            // The loss branch above the recovery branch around the peak.
            AdhesionLaw::LossRecovery(_) => assert!(t > 0.005, "{name}: {t}"),
            // No branches: the difference is what the cells' slip spread leaves.
            _ => assert!(t.abs() < 0.003, "{name}: {t}"),
        }
    }
}

/// The estimates of `scenes` (written as CSV, ingested and estimated as `run` does) and their
/// truth samples, the axles of each run numbered apart (as `railgrip score` pools scenes: a
/// cell's support counts one run's axle).
fn campaign(scenes: &[Scene], dir: &Path) -> (Vec<RunTable>, Vec<Sample>) {
    campaign_with(scenes, dir, &Pipeline::default_uic_z1())
}

/// [`campaign`] with the estimates of pipeline `p`.
fn campaign_with(scenes: &[Scene], dir: &Path, p: &Pipeline) -> (Vec<RunTable>, Vec<Sample>) {
    let (mut tables, mut truth) = (Vec::new(), Vec::new());
    for (r, sc) in scenes.iter().enumerate() {
        let out = sim::simulate(sc, None).unwrap();
        out.write(dir, &sc.name, OutputFormat::Csv).unwrap();
        let offset = 4 * r as u8;
        truth.extend(
            out.truth
                .samples(sc.run.ambient_temperature_c)
                .into_iter()
                .map(|x| Sample {
                    axle: x.axle + offset,
                    ..x
                }),
        );
        let path = dir.join(format!("{}.csv", sc.name));
        let log = railgrip::ingest_file(&path, p).unwrap();
        let e = railgrip::estimate::estimate(&log, p).unwrap();
        tables.push(RunTable::from_estimates(&sc.name, &sc.name, "", &e));
    }
    (tables, truth)
}

/// One run table per scene from the campaign's truth (`campaign`'s axle numbering, four per
/// scene): true Δv, dΔv/dt, v and μ of every sample with |Δv| ≥ 0.01 m/s, the scene's ambient
/// temperature — what a network trained on the truth instead of the estimates sees.
fn truth_tables(scenes: &[Scene], truth: &[Sample]) -> Vec<RunTable> {
    scenes
        .iter()
        .enumerate()
        .map(|(r, sc)| {
            let mut t = RunTable {
                name: sc.name.clone(),
                source: sc.name.clone(),
                ..RunTable::default()
            };
            t.metadata.ambient_temperature_c = Some(sc.run.ambient_temperature_c);
            for x in truth.iter().filter(|x| (x.axle as usize - 1) / 4 == r) {
                if x.dv_mps.abs() < 0.01 {
                    continue;
                }
                t.axle.push((x.axle - 1) % 4 + 1);
                t.time_s.push(0.0);
                t.v_mps.push(x.v_mps);
                t.dv_mps.push(x.dv_mps);
                t.ddv_mps2.push(x.ddv_mps2);
                t.mu.push(x.mu);
            }
            t
        })
        .collect()
}

/// `[train] starts` on a law the network does not contain, from several seeds: the kept start
/// is the best by validation error, stays positive on every supported cell, gets the loss /
/// recovery order right and fits within the single-start figures measured (docs/simulator.md).
#[test]
fn multi_start_on_a_foreign_law() {
    let dir = tempfile::tempdir().unwrap();
    let p = Pipeline::default_uic_z1();
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/scenes/foreign/lr_120kmh_p10.toml");
    let sc = Scene::load(&path).unwrap();
    let (tables, truth) = campaign(std::slice::from_ref(&sc), dir.path());
    for seed in [1, 11, 21] {
        let mut cfg = p.train.clone();
        cfg.seed = seed;
        cfg.starts = 3;
        let Scored { net, score: s, .. } = train_and_score(&tables, &truth, &cfg);
        let best = net
            .start_val_mse
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        assert_eq!(net.val_mse, best, "seed {seed}");
        let (t, pr) = s.hysteresis.unwrap();
        eprintln!(
            "seed {seed}: RMSE {:.4} max {:.3} hysteresis {t:+.4} / {pr:+.4}",
            s.rmse, s.max_error
        );
        assert_eq!(s.negative_cells, 0, "seed {seed}");
        assert!(
            s.rmse < 0.006 && s.max_error < 0.03,
            "seed {seed}: {} {}",
            s.rmse,
            s.max_error
        );
        assert!(t > 0.0 && pr > 0.5 * t, "seed {seed}: {t} {pr}");
    }
}

/// The identification targets on truth railgrip did not fit, for every one of 8 seeds: the default
/// network (one start) trained on one run of each foreign law stays positive on every
/// supported cell, gets the loss/recovery order of the loss_recovery law right, passes its
/// plausibility audit, and scores within 0.010 RMSE (the one-band target).
#[test]
fn every_seed_holds_on_both_foreign_laws() {
    let dir = tempfile::tempdir().unwrap();
    let p = Pipeline::default_uic_z1();
    for law in ["lr", "table"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("pipelines/scenes/foreign/{law}_120kmh_p10.toml"));
        let sc = Scene::load(&path).unwrap();
        let (tables, truth) = campaign(std::slice::from_ref(&sc), dir.path());
        let mut worst = 0.0f64;
        for seed in 1..=8 {
            let mut cfg = p.train.clone();
            cfg.seed = seed;
            let Scored { file, score: s, .. } = train_and_score(&tables, &truth, &cfg);
            let audit = file.audit.clone().unwrap();
            assert!(audit.passed, "{law} seed {seed}: {:?}", audit.failures);
            assert_eq!(s.negative_cells, 0, "{law} seed {seed}");
            assert!(s.rmse <= 0.010, "{law} seed {seed}: RMSE {}", s.rmse);
            let (t, pr) = s.hysteresis.unwrap();
            if law == "lr" {
                assert!(t > 0.0 && pr > 0.5 * t, "{law} seed {seed}: {t} {pr}");
            }
            worst = worst.max(s.rmse);
        }
        eprintln!("{law}: worst supported-cell RMSE over 8 seeds {worst:.4}");
    }
}

/// The all-speeds target (RMSE ≤ 0.004 on supported cells) on the foreign laws, from
/// several seeds: these runs span 80–200 km/h and −20 … +30 °C, and the loss_recovery law's
/// level moves with temperature, so the network takes the runs' ambient temperature as a
/// fourth input. It also stays positive, passes its audit and gets the loss/recovery order
/// right.
#[test]
fn four_input_networks_hold_over_all_speeds_and_temperatures() {
    let dir = tempfile::tempdir().unwrap();
    let p = Pipeline::default_uic_z1();
    // The targets: 0.004 for the loss/recovery law, and for the table law what its estimates allow: its sharp peak is
    // smeared by the conditioning (the same network trained on the true samples scores 0.0022,
    // `measure_networks_trained_on_the_truth`; on the estimates 0.0049).
    for (law, target) in [("lr", 0.004), ("table", 0.0055)] {
        let set = measurement_scenes(law, None);
        assert_eq!(set.len(), 7, "{law}");
        let (tables, truth) = campaign(&set, dir.path());
        for seed in [1, 2, 3] {
            let mut cfg = p.train.clone();
            cfg.seed = seed;
            cfg.inputs = InputSet::DvDdvVT;
            cfg.support_cells = railgrip::config::default_support_cells(4);
            let Scored { file, score: s, .. } = train_and_score(&tables, &truth, &cfg);
            let audit = file.audit.clone().unwrap();
            assert!(audit.passed, "{law} seed {seed}: {:?}", audit.failures);
            eprintln!(
                "{law} 4 inputs seed {seed}: RMSE {:.4} max {:.3} over {} cells",
                s.rmse,
                s.max_error,
                s.cells.len()
            );
            assert_eq!(s.negative_cells, 0, "{law} seed {seed}");
            assert!(s.rmse <= target, "{law} seed {seed}: RMSE {}", s.rmse);
            let (t, pr) = s.hysteresis.unwrap();
            if law == "lr" {
                assert!(t > 0.0 && pr > 0.5 * t, "{law} seed {seed}: {t} {pr}");
            }
        }
    }
}

/// A network trained by `train_mlp` with `cfg`, exported as `railgrip train` exports it (the
/// default pipeline's creep region, no Polach fallback), and scored on `truth`.
struct Scored {
    net: TrainedMlp,
    file: ModelFile,
    /// Wall time of `train_mlp`, s.
    secs: f64,
    score: Score,
}

fn train_and_score(tables: &[RunTable], truth: &[Sample], cfg: &TrainConfig) -> Scored {
    let p = Pipeline::default_uic_z1();
    let t0 = std::time::Instant::now();
    let mut net = train_mlp(tables, cfg, None).unwrap();
    let secs = t0.elapsed().as_secs_f64();
    net.reference_speed_mps = median_speed(tables);
    let creep = creep_spec(&p, net.reference_speed_mps).unwrap();
    let file = mlp_file(&net, creep, provenance(cfg.seed), None).unwrap();
    let model = Model::new(file.clone()).unwrap();
    let score = score(truth, &Grid::default(), |dv, q, v, t| {
        model.mu_vt(dv, q, v, t)
    })
    .unwrap();
    Scored {
        net,
        file,
        secs,
        score,
    }
}

fn provenance(seed: u64) -> Provenance {
    Provenance {
        inputs: vec![],
        pipeline: "uic_z1".into(),
        pipeline_sha256: String::new(),
        seed,
        crate_version: String::new(),
        created: String::new(),
        generation: None,
        calibration: None,
    }
}

/// One training method of the measurement.
struct Method {
    name: &'static str,
    starts: usize,
    ensemble: usize,
    bayesian: bool,
}

const METHODS: &[Method] = &[
    Method {
        name: "none",
        starts: 1,
        ensemble: 1,
        bayesian: false,
    },
    Method {
        name: "multi-start 8",
        starts: 8,
        ensemble: 1,
        bayesian: false,
    },
    Method {
        name: "ensemble 4 of 8",
        starts: 8,
        ensemble: 4,
        bayesian: false,
    },
    Method {
        name: "bayesian",
        starts: 1,
        ensemble: 1,
        bayesian: true,
    },
];

/// Scenes of a measurement set: the bundled soap scenes or one foreign law, one speed band
/// (2-input nets) or all speeds (3-input nets).
fn measurement_scenes(law: &str, band: Option<&str>) -> Vec<Scene> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/scenes");
    let paths: Vec<PathBuf> = if law == "bundled" {
        let mut v: Vec<PathBuf> = std::fs::read_dir(&root)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| {
                let n = p.file_name().unwrap().to_string_lossy();
                n.starts_with("soap_") && !n.contains("multirate")
            })
            .collect();
        v.sort();
        v
    } else {
        scenes()
    };
    paths
        .iter()
        .filter(|p| {
            let n = p.file_stem().unwrap().to_string_lossy().to_string();
            let law_ok = law == "bundled" || n.starts_with(&format!("{law}_"));
            law_ok && band.is_none_or(|b| n.contains(b))
        })
        .map(|p| Scene::load(p).unwrap())
        .collect()
}

#[test]
#[ignore = "a measurement, not a check (the targets are checked by the tests above)"]
fn measure_networks_on_foreign_laws() {
    let dir = tempfile::tempdir().unwrap();
    let p = Pipeline::default_uic_z1();
    let seeds: u64 = std::env::var("MEASURE_SEEDS").map_or(8, |v| v.parse().unwrap());
    let only = std::env::var("MEASURE_ONLY").unwrap_or_default();
    println!("| data | inputs | method | RMSE median (worst) | worst max error | seeds with μ < 0 | hysteresis sign right | predicted / true (median) | train s (median) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for law in ["bundled", "lr", "table"] {
        for inputs in InputSet::ALL {
            let band = (!inputs.has_speed()).then_some("_120kmh");
            let set = measurement_scenes(law, band);
            let (tables, truth) = campaign(&set, dir.path());
            for m in METHODS {
                let label = format!("{law} {}", inputs.count());
                if !only.is_empty() && !label.contains(&only) && !m.name.contains(&only) {
                    continue;
                }
                let mut rows = Vec::new();
                for seed in 1..=seeds {
                    let mut cfg = p.train.clone();
                    cfg.seed = seed;
                    cfg.inputs = inputs;
                    cfg.support_cells = railgrip::config::default_support_cells(inputs.count());
                    cfg.starts = m.starts;
                    cfg.ensemble = m.ensemble;
                    cfg.bayesian = m.bayesian;
                    if m.bayesian {
                        cfg.mu = railgrip::identify::lm::LmSettings::trainbr().mu;
                    }
                    let Scored {
                        net,
                        secs,
                        score: s,
                        ..
                    } = train_and_score(&tables, &truth, &cfg);
                    let (t, pr) = s.hysteresis.unwrap_or((f64::NAN, f64::NAN));
                    eprintln!(
                        "{label} {} seed {seed}: RMSE {:.4} max {:.3} negative {} hysteresis {t:+.4}/{pr:+.4} {secs:.1} s {} epochs{}",
                        m.name, s.rmse, s.max_error, s.negative_cells, net.history.len(),
                        net.history.last().and_then(|e| e.gamma).map_or(String::new(), |g| format!(" γ {g:.1}"))
                    );
                    rows.push((s.rmse, s.max_error, s.negative_cells, t, pr, secs));
                }
                let median = |mut v: Vec<f64>| {
                    v.sort_by(f64::total_cmp);
                    let n = v.len();
                    if n % 2 == 1 {
                        v[n / 2]
                    } else {
                        0.5 * (v[n / 2 - 1] + v[n / 2])
                    }
                };
                let rmse: Vec<f64> = rows.iter().map(|r| r.0).collect();
                let worst = rmse.iter().copied().fold(0.0, f64::max);
                let maxe = rows.iter().map(|r| r.1).fold(0.0, f64::max);
                let neg = rows.iter().filter(|r| r.2 > 0).count();
                let sign = rows
                    .iter()
                    .filter(|r| r.3.signum() == r.4.signum() || r.3.abs() < 0.003)
                    .count();
                let ratio = median(rows.iter().map(|r| r.4 / r.3).collect());
                let secs = median(rows.iter().map(|r| r.5).collect());
                println!(
                    "| {law}{} | {} | {} | {:.4} ({worst:.4}) | {maxe:.3} | {neg} of {seeds} | {sign} of {seeds} | {ratio:.2} | {secs:.1} |",
                    band.unwrap_or(" all speeds"),
                    inputs.count(),
                    m.name,
                    median(rmse.clone()),
                );
            }
        }
    }
}

/// The same four-input network trained on the truth itself (true Δv, dΔv/dt, v, T → true μ)
/// instead of the estimates: what the network family can reach when the conditioning and
/// estimation add nothing (`MEASURE_HIDDEN` sets the hidden neurons, default 10):
///     cargo test --release --test foreign truth -- --ignored --nocapture
#[test]
#[ignore = "a measurement"]
fn measure_networks_trained_on_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let p = Pipeline::default_uic_z1();
    let hidden: usize = std::env::var("MEASURE_HIDDEN").map_or(10, |v| v.parse().unwrap());
    for law in ["table", "lr", "bundled"] {
        let set = measurement_scenes(law, None);
        let (_, truth) = campaign(&set, dir.path());
        let tables = truth_tables(&set, &truth);
        let mut cfg = p.train.clone();
        cfg.inputs = InputSet::DvDdvVT;
        cfg.hidden = hidden;
        cfg.support_cells = railgrip::config::default_support_cells(4);
        let Scored {
            net,
            secs,
            score: s,
            ..
        } = train_and_score(&tables, &truth, &cfg);
        eprintln!(
            "{law}: {hidden} neurons trained on the truth: RMSE {:.4} max {:.3} ({secs:.1} s, {} epochs, {:?})",
            s.rmse, s.max_error, net.history.len(), net.stop
        );
    }
}

/// Polach fits on data from laws outside the Polach family: every fit of the
/// campaign — pooled, per run, per temperature — ends converged (not at μ's maximum), with
/// every parameter classified and a reason for each one held, and k(T) is fitted or its
/// absence explained.
#[test]
fn polach_fits_on_foreign_laws_converge_and_classify_every_parameter() {
    use railgrip::identify::polach::{fit_campaign, ParamStatus};
    let dir = tempfile::tempdir().unwrap();
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    for law in ["lr", "table"] {
        let set = measurement_scenes(law, Some("_120kmh"));
        let (tables, _) = campaign(&set, dir.path());
        let (report, notes) = fit_campaign(&tables, patch, q, p.train.decimate, 2, true);
        // Every fit succeeds; the only notes say why a temperature's k cannot enter k(T)
        // (the table law's sharp peak, with the creepage at a fixed speed, holds k_A at 1).
        assert!(
            notes.is_empty()
                || (law == "table"
                    && notes
                        .iter()
                        .all(|n| n.starts_with("k(T) not identified at T = "))),
            "{law}: {notes:?}"
        );
        let fits: Vec<_> = report
            .pooled
            .iter()
            .chain(&report.per_run)
            .chain(&report.per_temperature)
            .collect();
        assert_eq!(fits.len(), 1 + 4 + 4, "{law}");
        for f in fits {
            eprintln!(
                "{law} {}: μ0 {:.4} A {:.3} B {:.3} k_A {:.4} k_S {:.4} {:?} {} it, {}; {:?}",
                f.group,
                f.mu0,
                f.a_ratio,
                f.b_s_per_m,
                f.k_a,
                f.k_s,
                f.status,
                f.iterations,
                f.stop_reason,
                f.notes
            );
            assert!(
                f.stop_reason.starts_with("converged")
                    || f.stop_reason.starts_with("minimum gradient"),
                "{law} {}: {}",
                f.group,
                f.stop_reason
            );
            let held = f
                .status
                .iter()
                .filter(|s| **s != ParamStatus::Estimated)
                .count();
            // k_S follows ρ = k_S/k_A: one note per held solver parameter.
            assert!(
                f.notes.len() >= held.saturating_sub(1),
                "{law} {}: {:?}",
                f.group,
                f.notes
            );
            for (k, s) in f.status.iter().enumerate() {
                assert_eq!(
                    *s == ParamStatus::Estimated,
                    f.se[k].is_finite(),
                    "{law} {} param {k}",
                    f.group
                );
            }
        }
        let t = report.temperature.as_ref().expect("four temperatures");
        let forms: Vec<String> = t
            .candidates
            .iter()
            .map(|c| format!("{} ΔBIC {:.1}", c.form(), c.bic - t.candidates[0].bic))
            .collect();
        eprintln!("{law}: {} over {:?}; {forms:?}", t.form(), t.fitted_range_c);
        // Every pooled and per-temperature fit has a profile interval per estimated parameter.
        for f in report.pooled.iter().chain(&report.per_temperature) {
            let estimated = f
                .status
                .iter()
                .filter(|s| **s == ParamStatus::Estimated)
                .count();
            assert_eq!(f.profiles.len(), estimated, "{law} {}", f.group);
        }
    }
}

/// The temperature law on truth railgrip does not fit, over three seeds: the
/// loss_recovery law's adhesion level moves 0.6 %/K (its peaks scale by 1 + τ(20 °C − T)),
/// so the form chosen has μ0(T), μ0 falling from the coldest run to the warmest as the truth's
/// peaks do, and closer to the truth than the constant law. The table law has no temperature
/// dependence — but on these runs the slip the wheels reach falls as the temperature rises
/// (median 1.35 → 0.53 m/s), and Polach's misfit over different slip ranges looks like a
/// temperature trend that no criterion can tell apart: the fit must say so (the coverage
/// note), and whatever form it chooses must be no farther from the truth on these runs than
/// the constant law.
#[test]
fn temperature_laws_on_foreign_laws_follow_the_level() {
    use railgrip::contact::polach::{polach, PolachParams};
    use railgrip::identify::polach::fit_campaign;
    let dir = tempfile::tempdir().unwrap();
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    for law in ["lr", "table"] {
        for seed in 1..=3 {
            let mut set = measurement_scenes(law, Some("_120kmh"));
            for sc in &mut set {
                sc.seed += 100 * seed;
            }
            let (tables, truth) = campaign(&set, dir.path());
            let (report, _) = fit_campaign(&tables, patch, q, p.train.decimate, 2, true);
            let t = report.temperature.as_ref().expect("four temperatures");
            let (lo, hi) = t.fitted_range_c;
            let change = t.at(lo).0 / t.at(hi).0 - 1.0;
            // RMSE against the truth over the slipping samples of every run: the chosen law
            // (at each run's temperature) and the constant one (the pooled fit).
            let pooled = report.pooled.as_ref().unwrap().params();
            // The creepage at the speed the fits took it (the sample's, or a fixed one).
            let creepage = report.creepage.as_ref().and_then(|c| c.speed());
            let rmse = |at: &dyn Fn(f64) -> PolachParams| {
                let (mut sse, mut n) = (0.0, 0);
                for x in truth.iter().filter(|x| x.dv_mps > 0.01) {
                    let v_s = creepage.unwrap_or(x.v_mps);
                    let mu = polach(&patch, &at(x.t_c), q, v_s, x.dv_mps, 0.0)
                        .unwrap()
                        .fx_n
                        / q;
                    sse += (mu - x.mu).powi(2);
                    n += 1;
                }
                (sse / n as f64).sqrt()
            };
            let chosen = rmse(&|tc: f64| {
                let (m, ka, ks) = t.at(tc.clamp(lo, hi));
                PolachParams {
                    mu0: m,
                    a_ratio: t.a_ratio,
                    b_s_per_m: t.b_s_per_m,
                    k_a: ka,
                    k_s: ks,
                }
            });
            let constant = rmse(&|_| pooled);
            eprintln!(
                "{law} seed {seed}: {} (μ0 {:+.1} % from {lo} to {hi} °C); RMSE against the truth {chosen:.4} vs constant {constant:.4}; notes {:?}",
                t.form(),
                100.0 * change,
                t.notes
            );
            assert!(
                chosen <= constant * 1.02,
                "{law} seed {seed}: {chosen} vs {constant}"
            );
            // Both sets brake harder in the cold: the coverage note names it.
            // The table runs' median slip falls from 1.35 to 0.53 m/s as the temperature rises:
            // named. The loss_recovery runs' stays near 0.9 m/s: its trend is the temperature's.
            let coverage = t
                .notes
                .iter()
                .any(|n| n.contains("slip coverage changes with temperature"));
            assert_eq!(coverage, law == "table", "{law} seed {seed}: {:?}", t.notes);
            if law == "lr" {
                assert!(t.mu0_degree >= 1, "{law} seed {seed}: {}", t.form());
                // The truth's peaks: (1 + 0.006·40)/(1 − 0.006·10) − 1 = +32 %.
                assert!(change > 0.15, "{law} seed {seed}: {change}");
                assert!(
                    chosen < 0.9 * constant,
                    "{law} seed {seed}: {chosen} vs {constant}"
                );
            }
        }
    }
}

/// The top-speed campaign (12 runs at 80–200 km/h whose level falls steeper at the top), one
/// per noise seed, through `railgrip run` with its defaults (`train.model = "auto"`), every
/// model scored against the truth it does not contain, per speed band:
/// - the Polach fits take the creepage at one fixed speed (the truth's creep slope per m/s of
///   slip does not fall with speed as Polach's w/v makes it; BIC prefers the fixed speed by
///   ~600 on every seed, measured) and carry a quadratic speed law of μ0; the Polach model's
///   replay bias, pooled per speed band, stays within ±0.002 in every band (−0.0009 … +0.0003
///   measured; with Polach's creepage it needed the cubic law and reached −0.0025 at
///   145–210 km/h);
/// - the model the campaign chose by held-out runs (the residual network on every seed
///   measured) has a pooled replay bias within ±0.0015 in every band (+0.0012 at most,
///   measured), and in the curve view (the model at each run's initial speed and temperature)
///   a bias within ±0.0025 at every initial speed (−0.0009 … +0.0013 measured, by `railgrip
///   score`; +0.0023 with Polach's creepage) — at 200 km/h less than half the 2-input
///   network's — and a loss/recovery difference of 0.8–1.2 times the truth's at every initial
///   speed, its runs' pairs pooled as the band's bias pools their cells (0.89 … 1.13
///   measured), and 0.65–1.3 times in every run where the truth's is at least 0.002 (0.79 …
///   1.14 measured; 0.58 … 0.99 with Polach's creepage);
/// - the 2-input network is printed beside them (replay +0.0055 at 145–170 km/h and +0.0105 at
///   170–210 km/h, measured).
///
/// Its curve RMSE is within 0.005 at every initial speed, at the cells' nominal centres
/// against each run's own law (0.0029–0.0044 measured, since the residual network holds its
/// residual along the slip rate beyond the data; 0.0038–0.0059 when it fell back to the law
/// alone there), and at the runs' states (each curve cell at its samples' mean slip and slip
/// rate) with its bias within ±0.002 (0.0029–0.0043 and −0.0007 … +0.0015 measured).
///
/// Per run and band, a replay bias within ±0.0015 is out of reach of a model trained on the
/// pooled runs: each run's rail condition is ±5 % of the mean, which no model input carries,
/// and two runs at the same ambient temperature on different rails share speed bands where
/// the same inputs met μ differing by more than 0.003 (the exact law at the runs' mean
/// condition is biased by up to ±0.0050 per run and band, seeds 1–3). Net of that — the
/// chosen model's bias less the exact law's at the mean condition, per run and band — it is
/// within ±0.005 (0.0037 measured, seeds 1–3): itself more than the ±0.0015 asked, so the
/// condition explains part of the per-run bias, not all of it. Not asserted because not met
/// (docs/training.md#top-speeds-the-models-per-speed-band): a hysteresis ratio of 0.8–1.2 in
/// every run (0.79–1.14 at the centres, one run of 36 at 0.795; 0.78–1.17 at the runs'
/// states); per initial speed, pooled over its runs' pairs or as the mean of their ratios,
/// it is within 0.8–1.2 (asserted).
#[test]
fn the_chosen_model_and_polach_hold_the_top_speed_bands() {
    for seed in [1, 2, 3] {
        let c = run_and_score("pipelines/scenes/top_speed/", seed);
        // The creep slope of the truth does not fall with speed: BIC takes the creepage at a
        // fixed speed, and the level's quadratic speed law.
        assert_eq!(
            c.polach_creepage,
            Some(c.polach_reference_speed),
            "seed {seed}: the fixed speed is the runs' median (Polach's creepage if None)"
        );
        assert_eq!(c.polach_speed, ("polynomial".to_string(), 2), "seed {seed}");
        let polach = &c.models["polach"];
        eprintln!("seed {seed}: polach replay {:?}", polach.replay);
        assert!(
            polach.replay.iter().all(|b| b.abs() <= 0.002),
            "seed {seed}: {:?}",
            polach.replay
        );
        let chosen = &c.models["chosen"];
        assert!(
            chosen.replay.iter().all(|b| b.abs() <= 0.0015),
            "seed {seed}: {} replay {:?}",
            c.chosen,
            chosen.replay
        );
        assert!(
            chosen.curve.iter().all(|(_, b)| b.abs() <= 0.0025),
            "seed {seed}: {} curve {:?}",
            c.chosen,
            chosen.curve
        );
        // The loss/recovery difference holds up to the top speed (a residual whose support
        // was counted per speed cell kept 0.1 of it at 200 km/h).
        assert!(
            chosen.hysteresis.len() >= 9
                && chosen
                    .hysteresis
                    .iter()
                    .all(|(_, r)| (0.65..=1.3).contains(r)),
            "seed {seed}: {} hysteresis ratios {:?}",
            c.chosen,
            chosen.hysteresis
        );
        // Per initial speed, the runs' pairs pooled, and the mean of the runs' own ratios:
        // within 0.8–1.2 of the truth's.
        for (how, ratios) in [
            ("pooled", &chosen.hysteresis_pooled),
            ("run mean", &chosen.hysteresis_run_mean),
        ] {
            assert!(
                ratios.len() == 4 && ratios.iter().all(|(_, r)| (0.8..=1.2).contains(r)),
                "seed {seed}: {} hysteresis ratios, {how}: {ratios:?}",
                c.chosen
            );
        }
        // Per run and band, what the runs' own conditions leave to any campaign model, and
        // the chosen model's bias net of it.
        let floor = c
            .replay_condition_floor
            .as_ref()
            .expect("the top-speed runs' conditions differ");
        let worst = floor
            .iter()
            .flatten()
            .filter(|b| b.is_finite())
            .fold(0.0f64, |m, b| m.max(b.abs()));
        assert!(
            worst > 0.003,
            "seed {seed}: the exact law's worst run bias {worst}"
        );
        // Two runs at the same ambient temperature on different rails, in the same speed band,
        // whose true μ differs by more than 0.003 where one model of (Δv, dΔv/dt, v, T) sees
        // the same inputs: no campaign model holds both within ±0.0015.
        let mut spread = 0.0f64;
        for (i, (ti, si)) in c.conditions.iter().enumerate() {
            for (j, (tj, sj)) in c.conditions.iter().enumerate() {
                if ti == tj && si < sj {
                    for (a, b) in floor[i].iter().zip(&floor[j]) {
                        if a.is_finite() && b.is_finite() {
                            spread = spread.max(a - b);
                        }
                    }
                }
            }
        }
        assert!(
            spread > 0.003,
            "seed {seed}: the runs' condition spread {spread}"
        );
        // The model's bias against the law at the mean condition — the most a campaign model
        // can aim at — per run and band. (Both replays score the same samples: the support
        // does not depend on the model.)
        for (run, (m, f)) in chosen.replay_per_run.iter().zip(floor).enumerate() {
            for (band, (a, b)) in m.iter().zip(f).enumerate() {
                assert_eq!(
                    a.is_finite(),
                    b.is_finite(),
                    "seed {seed}: run {run} band {band}"
                );
                assert!(
                    !a.is_finite() || (a - b).abs() <= 0.005,
                    "seed {seed}: run {run} band {band}: {} bias {a} against the exact law's {b}",
                    c.chosen
                );
            }
        }
        // At the cells' nominal centres, against each run's own law: RMSE within 0.005 at
        // every initial speed (0.0051–0.0059 at 80–160 km/h while the residual fell back to
        // the law alone beyond the data's slip rates).
        assert!(
            chosen.curve_rmse.iter().all(|(_, r)| *r <= 0.005),
            "seed {seed}: {} curve RMSE {:?}",
            c.chosen,
            chosen.curve_rmse
        );
        // At the runs' states (each curve cell at its samples' mean slip and slip rate):
        // RMSE within 0.005 and bias within ±0.002 at every initial speed.
        assert!(
            chosen
                .at_states
                .iter()
                .all(|(_, (rmse, bias))| *rmse <= 0.005 && bias.abs() <= 0.002),
            "seed {seed}: {} curve at the runs' states {:?}",
            c.chosen,
            chosen.at_states
        );
        c.assert_top_speed_under_half_the_network(seed);
    }
}

/// The model choice and the residual network on the other foreign law: the seven `table`
/// scenes of pipelines/scenes/foreign (μ tabulated per speed with a sharp peak and a plateau,
/// 80–200 km/h, −20 … +30 °C; a law no candidate contains), two noise seeds, through `railgrip
/// run` with its defaults and scored per speed band against the truth:
/// - the chosen model (the residual network on both seeds, held-out RMSE 0.00382 / 0.00387
///   against the 3-input network's 0.00414 / 0.00408, measured 2026-12-07) has a pooled replay
///   bias within ±0.003 in every band (+0.0017 at most) and a curve bias within ±0.004 at
///   every initial speed (+0.0021 at most), at 200 km/h under half the 2-input network's
///   (+0.0020 / +0.0021 against +0.0133 / +0.0134);
/// - the residual network (here the chosen one; the bounds hold whichever is chosen) has a
///   curve bias within ±0.003 at every initial speed and a replay bias within ±0.003 in every
///   band.
#[test]
fn the_model_choice_and_the_residual_network_hold_on_the_table_law() {
    for seed in [1, 2] {
        let c = run_and_score("pipelines/scenes/foreign/table_", seed);
        for (name, curve_max, replay_max) in [("chosen", 0.004, 0.003), ("residual", 0.003, 0.003)]
        {
            let m = &c.models[name];
            assert!(
                m.curve.iter().all(|(_, b)| b.abs() <= curve_max),
                "seed {seed}: {name} ({}) curve {:?}",
                c.chosen,
                m.curve
            );
            assert!(
                m.replay.iter().all(|b| b.abs() <= replay_max),
                "seed {seed}: {name} ({}) replay {:?}",
                c.chosen,
                m.replay
            );
        }
        c.assert_top_speed_under_half_the_network(seed);
    }
}

/// What [`run_and_score`] found for one model.
struct BandScores {
    /// Replay bias per band of [`railgrip::score::SPEED_BANDS_KMH`], pooled over the runs
    /// (sample-weighted; every band holds samples).
    replay: Vec<f64>,
    /// Replay bias per run and band (NaN where the run has no sample in the band).
    replay_per_run: Vec<Vec<f64>>,
    /// Curve bias per initial speed (km/h), pooled over that speed's runs (cell-weighted).
    curve: Vec<(i64, f64)>,
    /// Curve RMSE per initial speed (km/h), pooled over that speed's runs (cell-weighted).
    curve_rmse: Vec<(i64, f64)>,
    /// Per run: (initial speed, the curve's hysteresis ratio) where the truth's loss − recovery
    /// difference is at least 0.002.
    hysteresis: Vec<(i64, f64)>,
    /// Per initial speed: the hysteresis ratio of its runs pooled (their pairs; runs whose
    /// true difference is under 0.002 left out), as `railgrip score` prints it per band …
    hysteresis_pooled: Vec<(i64, f64)>,
    /// … and the mean of its runs' own ratios (one weight per run).
    hysteresis_run_mean: Vec<(i64, f64)>,
    /// The curve at the runs' states (each cell at its samples' mean slip and slip rate): per
    /// initial speed, pooled over its runs (cell-weighted), (RMSE, bias).
    at_states: Vec<(i64, (f64, f64))>,
}

/// A campaign and its models' scores per speed band ([`run_and_score`]).
struct CampaignScores {
    /// `campaign.json`'s `chosen_model`.
    chosen: String,
    /// By name: `polach` (mlp.polach.json), `network` (mlp.json, the 2-input network),
    /// `residual` (mlp.residual.json) and `chosen`.
    models: std::collections::BTreeMap<&'static str, BandScores>,
    /// The Polach model's speed law: its form and number of coefficients.
    polach_speed: (String, usize),
    /// The Polach model's fixed creepage speed (m/s), if it has one, and its reference speed.
    polach_creepage: Option<f64>,
    polach_reference_speed: f64,
    /// Where the runs' rail conditions differ (`loss_recovery`'s `level_scale`): per run and
    /// band, the replay bias of the true law at the runs' mean condition — what a campaign
    /// model with the exact law, which cannot know a run's own condition, would show (NaN
    /// where the run has no sample in the band).
    replay_condition_floor: Option<Vec<Vec<f64>>>,
    /// Per run: its ambient temperature (°C) and rail condition (`level_scale`, if its law
    /// has one).
    conditions: Vec<(f64, Option<f64>)>,
}

impl CampaignScores {
    /// At the top initial speed, the chosen model's curve bias is under half the 2-input
    /// network's.
    fn assert_top_speed_under_half_the_network(&self, seed: u64) {
        let top = |m: &str| self.models[m].curve.last().unwrap().1;
        assert!(
            top("chosen").abs() < 0.5 * top("network").abs(),
            "seed {seed}: curve bias at the top speed: chosen {} network {}",
            top("chosen"),
            top("network")
        );
    }
}

/// Simulates the scenes whose paths start with `prefix` (a folder and a file-name prefix:
/// `folder/` for all of the folder, `folder/table_` for some) at noise `seed`, runs `railgrip
/// run` with its defaults on them, and scores the campaign's models against each scene's true
/// law in the replay and curve views. Every speed band must hold samples of every model.
fn run_and_score(prefix: &str, seed: u64) -> CampaignScores {
    let (folder, start) = prefix.rsplit_once('/').unwrap();
    let paths: Vec<PathBuf> = scene_files(folder)
        .into_iter()
        .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with(start))
        .collect();
    assert!(paths.len() >= 4, "{prefix}: {paths:?}");
    let scenes: Vec<Scene> = paths.iter().map(|p| Scene::load(p).unwrap()).collect();
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    let mut truths = Vec::new();
    for sc in &scenes {
        let out = sim::simulate(sc, Some(seed)).unwrap();
        out.write(&archive, &sc.name, OutputFormat::Csv).unwrap();
        truths.push(out.truth.samples(sc.run.ambient_temperature_c));
    }
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(["run", archive.to_str().unwrap(), "--out", "out"])
        .current_dir(tmp.path())
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let out = tmp.path().join("out");
    let models = out.join("models");
    let polach = ModelFile::read(&models.join("mlp.polach.json")).unwrap();
    let polach_creepage = polach.polach.as_ref().unwrap().creepage_speed_mps;
    let polach_reference_speed = polach.polach.as_ref().unwrap().reference_speed_mps;
    let polach_speed = polach
        .polach
        .as_ref()
        .unwrap()
        .speed
        .as_ref()
        .map(|s| (s.form.clone(), s.coefficients.len()))
        .unwrap_or_else(|| panic!("{prefix} seed {seed}: no speed law"));
    let camp: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("campaign.json")).unwrap()).unwrap();
    let chosen = camp["chosen_model"].as_str().unwrap().to_string();
    let mut scores = std::collections::BTreeMap::new();
    for (name, file) in [
        ("polach", polach),
        (
            "network",
            ModelFile::read(&models.join("mlp.json")).unwrap(),
        ),
        (
            "residual",
            ModelFile::read(&models.join("mlp.residual.json")).unwrap(),
        ),
        ("chosen", ModelFile::read(&out.join(&chosen)).unwrap()),
    ] {
        let what = format!("{prefix} seed {seed} {name} ({chosen})");
        scores.insert(name, band_scores(file, &truths, &scenes, &what));
    }
    CampaignScores {
        chosen,
        models: scores,
        polach_speed,
        polach_creepage,
        polach_reference_speed,
        replay_condition_floor: replay_condition_floor(&truths, &scenes),
        conditions: scenes
            .iter()
            .map(|sc| (sc.run.ambient_temperature_c, sc.adhesion.law.level_scale()))
            .collect(),
    }
}

/// Per run and band of [`railgrip::score::SPEED_BANDS_KMH`], the replay bias of each run's true
/// law scaled to the runs' mean rail condition (`loss_recovery`'s `level_scale`; μ is
/// proportional to it), as `railgrip score` prints it; `None` where the conditions do not
/// differ or a law has none.
fn replay_condition_floor(truths: &[Vec<Sample>], scenes: &[Scene]) -> Option<Vec<Vec<f64>>> {
    use railgrip::score::{replay, SPEED_BANDS_KMH};
    let scales: Vec<f64> = scenes
        .iter()
        .map(|sc| sc.adhesion.law.level_scale())
        .collect::<Option<_>>()?;
    if scales.iter().all(|s| *s == scales[0]) {
        return None;
    }
    let mean = scales.iter().sum::<f64>() / scales.len() as f64;
    let runs = truths
        .iter()
        .zip(scenes)
        .zip(&scales)
        .map(|((t, sc), own)| {
            let law = railgrip::sim::TrueLaw::of(sc).unwrap().unwrap();
            let at_mean = |dv, q, v, _| law.mu(dv, q, v) * mean / own;
            let mut run = vec![f64::NAN; SPEED_BANDS_KMH.len() - 1];
            for b in replay(t, &Grid::default(), &SPEED_BANDS_KMH, at_mean).unwrap() {
                run[SPEED_BANDS_KMH.iter().position(|e| *e == b.lo_kmh).unwrap()] = b.stats.bias;
            }
            run
        });
    Some(runs.collect())
}

/// One model's scores on the campaign's runs (`truths` the runs' true samples, `scenes` their
/// scenes, `what` names the model in messages): replay bias per band, curve bias per initial
/// speed, hysteresis ratios, and the curve at the runs' states.
fn band_scores(
    file: ModelFile,
    truths: &[Vec<Sample>],
    scenes: &[Scene],
    what: &str,
) -> BandScores {
    use railgrip::score::{curve, pooled_hysteresis_ratio, replay, SPEED_BANDS_KMH};
    let model = Model::new(file).unwrap();
    let predict = |dv, q, v, tc| model.mu_vt(dv, q, v, tc);
    let mut sums = vec![(0.0, 0usize); SPEED_BANDS_KMH.len() - 1];
    let mut per_run = Vec::new();
    let mut curves: std::collections::BTreeMap<i64, (f64, f64, usize)> = Default::default();
    let mut hysteresis = Vec::new();
    // Per initial speed, each run's (true, predicted, pairs) loss − recovery difference.
    type Hysteresis = Option<(f64, f64, usize)>;
    let mut pairs: std::collections::BTreeMap<i64, Vec<Hysteresis>> = Default::default();
    let mut states: std::collections::BTreeMap<i64, (f64, f64, usize)> = Default::default();
    for (t, sc) in truths.iter().zip(scenes) {
        let mut run = vec![f64::NAN; sums.len()];
        for b in replay(t, &Grid::default(), &SPEED_BANDS_KMH, predict).unwrap() {
            let i = SPEED_BANDS_KMH.iter().position(|e| *e == b.lo_kmh).unwrap();
            sums[i].0 += b.stats.bias * b.stats.n as f64;
            sums[i].1 += b.stats.n;
            run[i] = b.stats.bias;
        }
        per_run.push(run);
        let law = railgrip::sim::TrueLaw::of(sc).unwrap().unwrap();
        let (v0, t_c) = (sc.run.initial_speed_kmh, sc.run.ambient_temperature_c);
        let c = curve(
            t,
            &Grid::default(),
            v0 / 3.6,
            t_c,
            predict,
            |dv, q, v, _| law.mu(dv, q, v),
        )
        .unwrap();
        if let Some(r) = c.hysteresis_ratio(0.002) {
            hysteresis.push((v0.round() as i64, r));
        }
        pairs
            .entry(v0.round() as i64)
            .or_default()
            .push(c.hysteresis_with_pairs());
        let e = curves.entry(v0.round() as i64).or_default();
        e.0 += c.stats.bias * c.stats.n as f64;
        e.1 += c.stats.rmse * c.stats.rmse * c.stats.n as f64;
        e.2 += c.stats.n;
        let at_means = Grid {
            at_sample_means: true,
            ..Grid::default()
        };
        let c = curve(t, &at_means, v0 / 3.6, t_c, predict, |dv, q, v, _| {
            law.mu(dv, q, v)
        })
        .unwrap();
        let e = states.entry(v0.round() as i64).or_default();
        e.0 += c.stats.rmse * c.stats.rmse * c.stats.n as f64;
        e.1 += c.stats.bias * c.stats.n as f64;
        e.2 += c.stats.n;
    }
    assert!(
        sums.iter().all(|(_, n)| *n > 0),
        "{what}: a speed band without scored samples {sums:?}"
    );
    let s = BandScores {
        replay: sums.iter().map(|(s, n)| s / *n as f64).collect(),
        replay_per_run: per_run,
        curve: curves
            .iter()
            .map(|(k, (s, _, n))| (*k, s / (*n).max(1) as f64))
            .collect(),
        curve_rmse: curves
            .iter()
            .map(|(k, (_, sq, n))| (*k, (sq / (*n).max(1) as f64).sqrt()))
            .collect(),
        hysteresis_run_mean: {
            let mut by: std::collections::BTreeMap<i64, Vec<f64>> = Default::default();
            for (k, r) in &hysteresis {
                by.entry(*k).or_default().push(*r);
            }
            by.into_iter()
                .map(|(k, r)| (k, r.iter().sum::<f64>() / r.len() as f64))
                .collect()
        },
        hysteresis,
        hysteresis_pooled: pairs
            .into_iter()
            .filter_map(|(k, runs)| Some((k, pooled_hysteresis_ratio(runs, 0.002)?)))
            .collect(),
        at_states: states
            .iter()
            .map(|(k, (sq, b, n))| {
                let n = (*n).max(1) as f64;
                (*k, ((sq / n).sqrt(), b / n))
            })
            .collect(),
    };
    eprintln!(
        "{what}: replay bias per band {:.4?}; curve bias per initial speed {:.4?}, RMSE {:.4?}; hysteresis ratio per run {:.2?}, per initial speed {:.2?}; curve at the runs' states (RMSE, bias) {:.4?}",
        s.replay, s.curve, s.curve_rmse, s.hysteresis, s.hysteresis_pooled, s.at_states
    );
    s
}

/// The defaults of seed 002's 2-input network, measured on a law it does not contain: one
/// 120 km/h run of the top-speed family (`lrq_120kmh_p12`: the level falling with speed, every
/// sensor effect), five Nguyen–Widrow seeds, scored in the curve view (the model at the run's
/// initial speed and ambient temperature against the true law, on the run's own supported
/// cells). For each `train.decimate` in 1, 2, 4 the median RMSE and training time are printed
/// (docs/training.md#defaults-chosen-by-measurement); at the default decimation numpy trainlm
/// (`benches/peers/trainlm_numpy.py`), given the same normalised samples and the same initial
/// weights, and its weights exported through the same model-file path, is no better: railgrip's
/// median ≤ numpy's × 1.02 (the trajectories agree to 1e-9 for 20 epochs,
/// `tests/lm_peer.rs`; over hundreds of epochs rounding moves where validation stops).
#[test]
fn the_default_network_holds_against_numpy_trainlm_on_the_same_samples() {
    use railgrip::identify::dataset::Dataset;
    use railgrip::identify::mlp::{self, Shape};
    use railgrip::score::curve;
    if !common::python_has("numpy", "numpy") {
        return;
    }
    let p = Pipeline::default_uic_z1();
    let scene = std::env::var("PEER_SCENE").unwrap_or("lrq_120kmh_p12".into());
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(format!("pipelines/scenes/top_speed/{scene}.toml"));
    let sc = Scene::load(&path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (tables, truth) = campaign(std::slice::from_ref(&sc), dir.path());
    let law = railgrip::sim::TrueLaw::of(&sc).unwrap().unwrap();
    let (v0, t_c) = (sc.run.initial_speed_kmh / 3.6, sc.run.ambient_temperature_c);
    let curve_rmse = |file: &ModelFile| {
        let m = Model::new(file.clone()).unwrap();
        curve(
            &truth,
            &Grid::default(),
            v0,
            t_c,
            |dv, q, v, t| m.mu_vt(dv, q, v, t),
            |dv, q, v, _| law.mu(dv, q, v),
        )
        .unwrap()
        .stats
        .rmse
    };
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let default = p.train.decimate;
    for decimate in [1, 2, 4] {
        let (mut ours, mut peer, mut secs) = (Vec::new(), Vec::new(), Vec::new());
        for seed in 1..=5 {
            let mut cfg = p.train.clone();
            cfg.seed = seed;
            cfg.decimate = decimate;
            let Scored {
                net, file, secs: s, ..
            } = train_and_score(&tables, &truth, &cfg);
            ours.push(curve_rmse(&file));
            secs.push(s);
            if decimate != default {
                continue;
            }
            // numpy trainlm on the same samples from the same start.
            let d = Dataset::build(&tables, cfg.inputs, &cfg.split, decimate).unwrap();
            let n = d.normalised();
            let problem = dir.path().join(format!("peer_{seed}.json"));
            let shape = Shape::one(2, cfg.hidden);
            common::write_trainlm_problem(
                &problem,
                2,
                cfg.hidden,
                (&n.x, &n.y, &n.vx, &n.vy),
                n.scale,
                &mlp::nguyen_widrow(shape, seed),
                &railgrip::identify::train::lm_settings(&cfg),
            );
            let theta = common::trainlm_numpy_theta(&problem).unwrap();
            assert_eq!(theta.len(), net.theta.len());
            let theirs = TrainedMlp { theta, ..net };
            let creep = creep_spec(&p, theirs.reference_speed_mps).unwrap();
            let f = mlp_file(&theirs, creep, provenance(seed), None).unwrap();
            peer.push(curve_rmse(&f));
        }
        eprintln!(
            "decimate {decimate}: railgrip curve RMSE median {:.4} (seeds {ours:.4?}), training {:.2} s median{}",
            median(ours.clone()),
            median(secs),
            if peer.is_empty() {
                String::new()
            } else {
                format!("; numpy trainlm median {:.4} ({peer:.4?})", median(peer.clone()))
            }
        );
        if decimate == default {
            assert!(
                median(ours.clone()) <= 1.02 * median(peer.clone()),
                "railgrip {ours:?} against numpy {peer:?}"
            );
        }
    }
}

/// The residual network (the top-speed campaign's chosen model) trained once on the runs'
/// estimates and once on their truth (true Δv, dΔv/dt, v → true μ, the same pipeline): its
/// curve bias per initial speed and its hysteresis ratio per run, to tell what the estimates
/// cost from what the network and its training cost:
///     cargo test --release --test foreign residual_network_on_the_truth -- --ignored --nocapture
#[test]
#[ignore = "a measurement"]
fn measure_the_residual_network_on_the_truth_at_the_top_speeds() {
    use railgrip::identify::family::{FitData, ModelFamily, Residual};
    use railgrip::score::curve;
    let dir = tempfile::tempdir().unwrap();
    let scenes: Vec<Scene> = scene_files("pipelines/scenes/top_speed")
        .iter()
        .map(|p| Scene::load(p).unwrap())
        .collect();
    // MEASURE_TACHO_HZ: the tachometers' and pressures' low-pass cut-off of the estimates.
    let mut conditioning = Pipeline::default_uic_z1();
    if let Ok(hz) = std::env::var("MEASURE_TACHO_HZ") {
        conditioning.filters.tacho_cutoff_hz = hz.parse().unwrap();
        conditioning.filters.pressure_cutoff_hz = conditioning.filters.tacho_cutoff_hz;
    }
    let (mut estimated, truth) = campaign_with(&scenes, dir.path(), &conditioning);
    for (t, sc) in estimated.iter_mut().zip(&scenes) {
        t.metadata.ambient_temperature_c = Some(sc.run.ambient_temperature_c);
    }
    let from_truth = truth_tables(&scenes, &truth);
    let mut p = Pipeline::default_uic_z1();
    p.train.inputs = InputSet::DvDdvV;
    p.train.support_cells = railgrip::config::default_support_cells(3);
    for (what, tables) in [("estimates", &estimated), ("truth", &from_truth)] {
        let fitted = Residual
            .fit(&FitData {
                tables,
                pipeline: &p,
                provenance: provenance(1),
                fallback: None,
                epochs: None,
                audit: false,
            })
            .unwrap();
        let model = Model::new(fitted.model.unwrap()).unwrap();
        let mut rows = Vec::new();
        for (r, sc) in scenes.iter().enumerate() {
            let t: Vec<Sample> = truth
                .iter()
                .filter(|x| (x.axle as usize - 1) / 4 == r)
                .map(|x| Sample {
                    axle: (x.axle - 1) % 4 + 1,
                    ..*x
                })
                .collect();
            let law = railgrip::sim::TrueLaw::of(sc).unwrap().unwrap();
            let (v0, t_c) = (sc.run.initial_speed_kmh, sc.run.ambient_temperature_c);
            let c = curve(
                &t,
                &Grid::default(),
                v0 / 3.6,
                t_c,
                |dv, q, v, tc| model.mu_vt(dv, q, v, tc),
                |dv, q, v, _| law.mu(dv, q, v),
            )
            .unwrap();
            rows.push(format!(
                "{} bias {:+.4} rmse {:.4} hysteresis {:?}",
                sc.name,
                c.stats.bias,
                c.stats.rmse,
                c.hysteresis_ratio(0.002)
                    .map(|x| (x * 100.0).round() / 100.0)
            ));
        }
        eprintln!(
            "residual trained on the {what} ({} epochs):\n  {}",
            fitted.shape.epochs,
            rows.join("\n  ")
        );
    }
}
