//! Self-calibration from a run's own data, against the truth of the simulator's mismatch
//! effects (which the estimator never sees: they are in the truth table, not the log).
//!
//! The radar's scale: a radar reading 0.3 % high (and 30 ms late) is found within 0.05 %, on
//! soap runs from 120 and 160 km/h with wheel-slide protection at work, three seeds each; a
//! radar without error is found at 1.

use std::path::Path;

use railgrip::estimate::radar::calibrate_radar;
use railgrip::ingest::ingest_file;
use railgrip::sim::{self, OutputFormat, Scene};
use railgrip::Pipeline;

/// A soap run from `kmh` with three seconds of coasting before the brake, the effects of the
/// bundled scenes' sensors, and `extra` effects.
fn braking_run(kmh: f64, seed: u64, extra: &str, dir: &Path) -> railgrip::ingest::RunLog {
    let text = format!(
        "name = \"cal\"\nseed = {seed}\neffects = [\"load_transfer\", \"wsp\", \"hysteresis\", \"falling_friction\", \"temperature\", \"cleaning\", \"running_resistance\", \"radar_noise\", \"radar_spikes\", \"tacho_quantization\", \"pressure_noise\"{extra}]\n[run]\ninitial_speed_kmh = {kmh}\nmax_duration_s = 60.0\ncondition = \"soap\"\n[brake]\ndemand_bar = [[0.0, 0.0], [3.0, 0.0], [4.5, 3.8]]\n"
    );
    let sc = Scene::from_toml(&text, "cal.toml", None).unwrap_or_else(|e| panic!("{e}"));
    let out = sim::simulate(&sc, None).unwrap();
    let stem = format!("cal_{kmh}_{seed}");
    out.write(dir, &stem, OutputFormat::Csv).unwrap();
    ingest_file(
        &dir.join(format!("{stem}.csv")),
        &Pipeline::default_uic_z1(),
    )
    .unwrap()
}

#[test]
fn the_radars_scale_comes_out_of_braking_runs() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = Pipeline::default_uic_z1();
    for (extra, scale) in [(", \"radar_error\"", 1.003), ("", 1.0)] {
        for kmh in [120.0, 160.0] {
            for seed in [1, 2, 3] {
                let log = braking_run(kmh, seed, extra, dir.path());
                let c = calibrate_radar(&log, &pipeline).unwrap();
                eprintln!(
                    "{kmh} km/h, seed {seed}, radar scale {scale}: found {:.5} ± {:.5} ({} samples)",
                    c.scale, c.scale_se, c.scale_samples
                );
                assert!(
                    (c.scale / scale - 1.0).abs() <= 5e-4,
                    "{kmh} km/h seed {seed}: scale {} against {scale}",
                    c.scale
                );
                // The standard error is honest: the error within three of them.
                assert!(c.scale_se > 0.0 && c.scale_se < 5e-4, "{}", c.scale_se);
                assert!(
                    (c.scale - scale).abs() <= 3.0 * c.scale_se,
                    "{kmh} km/h seed {seed}: error {} against se {}",
                    c.scale - scale,
                    c.scale_se
                );
            }
        }
    }
}

#[test]
fn a_run_that_never_coasts_is_refused_with_what_it_lacks() {
    let dir = tempfile::tempdir().unwrap();
    let text = "name = \"b\"\nseed = 1\neffects = [\"radar_error\"]\n[run]\ninitial_speed_kmh = 100.0\nmax_duration_s = 10.0\n[brake]\ndemand_bar = [[0.0, 3.0]]\n";
    let sc = Scene::from_toml(text, "b.toml", None).unwrap();
    let out = sim::simulate(&sc, None).unwrap();
    out.write(dir.path(), "b", OutputFormat::Csv).unwrap();
    let log = ingest_file(&dir.path().join("b.csv"), &Pipeline::default_uic_z1()).unwrap();
    let e = calibrate_radar(&log, &Pipeline::default_uic_z1())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.csv") && e.contains("every brake released") && e.contains("Hint: "),
        "{e}"
    );
}

/// The mismatch campaign (pipelines/scenes/mismatch, 12 scenes) simulated with noise seed
/// `seed`: each run's log, its truth and the mismatch behind it.
fn mismatch_campaign(
    seed: u64,
    dir: &Path,
) -> Vec<(railgrip::ingest::RunLog, sim::SimOutput, f64)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut scenes: Vec<_> = std::fs::read_dir(root.join("pipelines/scenes/mismatch"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    scenes.sort();
    scenes
        .iter()
        .map(|path| {
            let mut sc = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
            if let Ok(x) = std::env::var("RG_NOQUIET") {
                for name in x.split(',') {
                    let e = railgrip::sim::Effect::ALL
                        .iter()
                        .find(|e| e.name() == name)
                        .unwrap();
                    let keep = railgrip::sim::Effect::ALL
                        .iter()
                        .filter(|f| sc.effects.has(**f) && *f != e);
                    sc.effects = keep.fold(railgrip::sim::Effects::none(), |m, f| m.with(*f));
                }
            }
            let out = sim::simulate(&sc, Some(seed)).unwrap();
            let stem = format!("{}_{seed}", sc.name);
            out.write(dir, &stem, OutputFormat::Csv).unwrap();
            let log = ingest_file(
                &dir.join(format!("{stem}.csv")),
                &Pipeline::default_uic_z1(),
            )
            .unwrap();
            (log, out, sc.run.ambient_temperature_c)
        })
        .collect()
}

/// Per-axle (RMSE, bias) of μ against the truth over valid samples with true Δv > 0.2 m/s.
fn mu_error(e: &railgrip::estimate::Estimates, tr: &sim::Truth) -> [(f64, f64); 4] {
    let fs = 1.0 / (tr.time_s[1] - tr.time_s[0]);
    std::array::from_fn(|a| {
        let (mut sum, mut sq, mut k) = (0.0, 0.0, 0usize);
        for (i, &t) in e.time_s.iter().enumerate() {
            let j = ((t - tr.time_s[0]) * fs).round();
            if j < 0.0 || j as usize >= tr.mu[a].len() {
                continue;
            }
            let j = j as usize;
            if e.axles[a].valid[i] && tr.dv_mps[a][j] > 0.2 {
                let d = e.axles[a].mu[i] - tr.mu[a][j];
                sum += d;
                sq += d * d;
                k += 1;
            }
        }
        let k = k.max(1) as f64;
        ((sq / k).sqrt(), sum / k)
    })
}

#[test]
fn the_campaign_calibrates_itself_on_mismatch_scenes() {
    use railgrip::estimate::selfcal::CampaignCalibrator;
    use railgrip::estimate::{estimate, estimate_corrected};
    let dir = tempfile::tempdir().unwrap();
    let pipeline = Pipeline::default_uic_z1();
    for seed in [1, 2, 3] {
        let runs = mismatch_campaign(seed, dir.path());
        let mut cal = CampaignCalibrator::new(&pipeline);
        for (log, ..) in &runs {
            cal.add(log).unwrap();
        }
        let t = std::time::Instant::now();
        let c = cal.finish(dir.path()).unwrap();
        eprintln!("seed {seed}: fit in {:?}\n{c:#?}", t.elapsed());
        let m = runs[0].1.mismatch.clone().unwrap();
        eprintln!("truth {m:?}");
        for a in 0..4 {
            // α_i(v) truth against the fit over the speed range.
            let mut worst = 0.0f64;
            for v in [5.0, 10.0, 20.0, 30.0, 40.0, 50.0, c.pad.v_ref_mps] {
                let tr = m.brake_torque_nm_per_bar[a]
                    * (1.0 + m.pad_friction_rise * (1.0 - v / m.pad_friction_v0_mps).max(0.0));
                let fit = c.alpha_nm_per_bar[a] * c.pad.factor(v);
                worst = worst.max((fit / tr - 1.0).abs());
            }
            eprintln!("axle {}: worst α(v) error {:.4} %", a + 1, worst * 100.0);
        }
        let corr = c.corrections();
        for (log, out, _) in &runs {
            let before = mu_error(&estimate(log, &pipeline).unwrap(), &out.truth);
            let after = mu_error(
                &estimate_corrected(log, &pipeline, &corr).unwrap(),
                &out.truth,
            );
            let f = |x: [(f64, f64); 4]| {
                x.iter()
                    .map(|(r, b)| format!("{r:.4}/{b:+.4}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            eprintln!(
                "{}: before {} | after {}",
                log.source.file_name().unwrap().to_string_lossy(),
                f(before),
                f(after)
            );
        }
    }
}
