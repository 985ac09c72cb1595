//! Self-calibration from a run's own data, against the truth of the simulator's mismatch
//! effects (which the estimator never sees: they are in the truth table, not the log).
//!
//! The radar's scale: a radar reading 0.3 % high (and 30 ms late) is found within 0.05 %, on
//! soap runs from 120 and 160 km/h with wheel-slide protection at work, three seeds each; a
//! radar without error is found at 1.

use std::path::Path;

use railgrip::estimate::radar::calibrate_radar;
use railgrip::estimate::selfcal::{CampaignCalibration, CampaignCalibrator, PadForm};
use railgrip::estimate::{estimate, estimate_corrected, Estimates};
use railgrip::ingest::ingest_file;
use railgrip::sim::{self, OutputFormat, Scene};
use railgrip::sim::{Effect, Effects};
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

/// The mismatch campaign (pipelines/scenes/mismatch, 12 scenes), each scene changed by
/// `edit`, simulated with noise seed `seed`: each run's log and simulator output.
fn mismatch_campaign(
    seed: u64,
    dir: &Path,
    edit: impl Fn(&mut Scene),
) -> Vec<(railgrip::ingest::RunLog, sim::SimOutput)> {
    campaign("pipelines/scenes/mismatch", Some(seed), dir, edit)
}

/// The scenes (`*.toml`) of the folder `scenes`, each changed by `edit` and simulated with
/// noise seed `seed` (None: the scene's own), written as CSV (MCAP where the sensors run at
/// different rates) and read back: each run's log and simulator output.
fn campaign(
    scenes: &str,
    seed: Option<u64>,
    dir: &Path,
    edit: impl Fn(&mut Scene),
) -> Vec<(railgrip::ingest::RunLog, sim::SimOutput)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths: Vec<_> = std::fs::read_dir(root.join(scenes))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    paths.sort();
    paths
        .iter()
        .map(|path| {
            let mut sc = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
            edit(&mut sc);
            let out = sim::simulate(&sc, seed).unwrap();
            let stem = format!("{}_{}", sc.name, seed.unwrap_or(sc.seed));
            let file = if out.write(dir, &stem, OutputFormat::Csv).is_ok() {
                format!("{stem}.csv")
            } else {
                out.write(dir, &stem, OutputFormat::Mcap).unwrap();
                format!("{stem}.mcap")
            };
            let log = ingest_file(&dir.join(file), &Pipeline::default_uic_z1()).unwrap();
            (log, out)
        })
        .collect()
}

/// A scene edit that drops every mismatch effect ([`sim::MISMATCH_EFFECTS`]: the scene as
/// the pipeline describes it) and the effects named in `also`.
fn clean<'a>(also: &'a [&'a str]) -> impl Fn(&mut Scene) + 'a {
    move |sc| {
        let keep = Effect::ALL.iter().filter(|e| {
            sc.effects.has(**e) && !sim::MISMATCH_EFFECTS.contains(e) && !also.contains(&e.name())
        });
        sc.effects = keep.fold(Effects::none(), |m, e| m.with(*e));
    }
}

/// Per axle (RMSE, bias) of μ, and the RMSE over all axles.
type MuError = ([(f64, f64); 4], f64);

/// (RMSE, bias) of μ against the truth per axle, and the RMSE over all axles, over valid
/// samples with true Δv > 0.2 m/s (the estimator's measure).
fn mu_error(e: &Estimates, tr: &sim::Truth) -> MuError {
    let fs = 1.0 / (tr.time_s[1] - tr.time_s[0]);
    let (mut all_sq, mut all_k) = (0.0, 0usize);
    let per = std::array::from_fn(|a| {
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
        all_sq += sq;
        all_k += k;
        let k = k.max(1) as f64;
        ((sq / k).sqrt(), sum / k)
    });
    (per, (all_sq / all_k.max(1) as f64).sqrt())
}

/// The campaign's calibration of `runs`.
fn calibrate(
    runs: &[(railgrip::ingest::RunLog, sim::SimOutput)],
    dir: &Path,
) -> CampaignCalibration {
    let pipeline = Pipeline::default_uic_z1();
    let mut cal = CampaignCalibrator::new(&pipeline);
    for (log, _) in runs {
        cal.add(log).unwrap();
    }
    cal.finish(dir).unwrap_or_else(|e| panic!("{e}"))
}

/// Per run: the estimates' μ error without and with the calibration.
fn before_after(
    runs: &[(railgrip::ingest::RunLog, sim::SimOutput)],
    c: &CampaignCalibration,
) -> Vec<(String, MuError, MuError)> {
    // The vehicle as its owner describes it: with the pivot force's share of the load
    // transfer when the simulated vehicle has it (a known geometry, not a calibration).
    let pivot = runs[0].1.mismatch.as_ref().is_some_and(|m| m.pivot_force);
    let pipeline = if pivot {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/uic_z1.toml"),
        )
        .unwrap()
        .replacen(
            "[vehicle]\n",
            "[vehicle]\npivot_force_load_transfer = true\n",
            1,
        );
        Pipeline::from_toml(&text, "uic_z1_pivot.toml").unwrap()
    } else {
        Pipeline::default_uic_z1()
    };
    let corr = c.corrections();
    runs.iter()
        .map(|(log, out)| {
            let before = mu_error(&estimate(log, &pipeline).unwrap(), &out.truth);
            let after = mu_error(
                &estimate_corrected(log, &pipeline, &corr).unwrap(),
                &out.truth,
            );
            let name = log
                .source
                .file_stem()
                .unwrap()
                .to_string_lossy()
                .to_string();
            let f = |x: &MuError| {
                x.0.iter()
                    .map(|(r, b)| format!("{r:.4}/{b:+.4}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            eprintln!(
                "{name}: RMSE/bias before {} | after {}",
                f(&before),
                f(&after)
            );
            (name, before, after)
        })
        .collect()
}

/// Per run, asserts the calibrated μ RMSE at most 0.6 of the uncalibrated (printed with
/// `label`); returns each run's name and calibrated per-axle (RMSE, bias).
fn assert_rmse_ratio(
    runs: &[(railgrip::ingest::RunLog, sim::SimOutput)],
    c: &CampaignCalibration,
    label: &str,
) -> Vec<(String, [(f64, f64); 4])> {
    before_after(runs, c)
        .into_iter()
        .map(|(name, before, after)| {
            eprintln!("{name}: RMSE ratio {:.3} ({label})", after.1 / before.1);
            assert!(
                after.1 <= 0.6 * before.1,
                "{name}: RMSE {} against {}",
                after.1,
                before.1
            );
            (name, after.0)
        })
        .collect()
}

/// Asserts the calibration's running-resistance speed terms within 3 of their standard errors
/// of the scenes' (the simulator's default Davis b = 30 N·s/m and c = 6 N·s²/m²).
fn assert_davis_resistance(c: &CampaignCalibration) {
    for (name, got, se, truth) in [
        ("c1", c.resistance_c1_n_s_per_m, c.resistance_c1_se, 30.0),
        ("c2", c.resistance_c2_n_s2_per_m2, c.resistance_c2_se, 6.0),
    ] {
        eprintln!("  {name} {got:.3} ± {se:.3} (truth {truth})");
        assert!(
            (got - truth).abs() <= 3.0 * se,
            "{name} {got} ± {se} against {truth}"
        );
    }
}

/// Asserts the calibration's radar targets against the truth `m`: the scale within 0.05 %, the
/// latency within 5 ms (`label` names the case).
fn assert_radar_targets(c: &CampaignCalibration, m: &sim::Mismatch, label: &str) {
    assert!(
        (c.radar_scale / m.radar_scale - 1.0).abs() <= 5e-4,
        "{label}: scale {}",
        c.radar_scale
    );
    assert!(
        (c.radar_latency_s - m.radar_latency_s).abs() <= 0.005,
        "{label}: latency {}",
        c.radar_latency_s
    );
}

/// Asserts that one of `notes` contains every one of `parts`.
fn assert_note(notes: &[String], parts: &[&str]) {
    assert!(
        notes.iter().any(|n| parts.iter().all(|p| n.contains(p))),
        "no note with {parts:?}: {notes:?}"
    );
}

/// Asserts that the calibration leaves no run's per-sample μ RMSE worse by more than 2 %.
fn assert_no_run_worse(
    runs: &[(railgrip::ingest::RunLog, sim::SimOutput)],
    c: &CampaignCalibration,
) {
    for (name, before, after) in before_after(runs, c) {
        eprintln!("{name}: RMSE ratio {:.3}", after.1 / before.1);
        assert!(
            after.1 <= 1.02 * before.1,
            "{name}: RMSE {} against {}",
            after.1,
            before.1
        );
    }
}

/// Per axle, the calibrated α_i(v)'s largest relative error against the truth over 5–55 m/s
/// (printed with α at the top speed); asserts it within 1 % and, with `within_3_se`, α at the
/// top within 3 standard errors.
fn alpha_errors(c: &CampaignCalibration, m: &sim::Mismatch, within_3_se: bool) -> [f64; 4] {
    std::array::from_fn(|a| {
        let mut worst = 0.0f64;
        for v in [5.0, 15.0, 25.0, 35.0, 45.0, c.pad.v_ref_mps] {
            let tr = m.brake_torque_nm_per_bar[a] * m.pad_factor(v);
            worst = worst.max((c.alpha_nm_per_bar[a] * c.pad.factor(v) / tr - 1.0).abs());
        }
        let at_top = m.brake_torque_nm_per_bar[a] * m.pad_factor(c.pad.v_ref_mps);
        eprintln!(
            "  axle {}: α(v) within {:.2} %; α at the top {:+.2} % (se {:.2} %)",
            a + 1,
            worst * 100.0,
            (c.alpha_nm_per_bar[a] / at_top - 1.0) * 100.0,
            c.alpha_se[a] / at_top * 100.0
        );
        assert!(worst <= 0.01, "axle {}: {worst}", a + 1);
        assert!(
            !within_3_se || (c.alpha_nm_per_bar[a] - at_top).abs() <= 3.0 * c.alpha_se[a],
            "axle {}: α {} against {at_top} (se {})",
            a + 1,
            c.alpha_nm_per_bar[a],
            c.alpha_se[a]
        );
        worst
    })
}

/// The mismatch scenes at the specified sizes (α scatter 2 %, pad friction +5 % from 200 km/h,
/// radar +0.3 % and 30 ms late, tachometers counting over 20 ms, so 10 ms late, wheel loads
/// fluctuating 1.5 % rms at 2–10 Hz, the pivot force's share of the load transfer — which the
/// pipeline describes, `vehicle.pivot_force_load_transfer`), three noise seeds, each a
/// campaign of 12 runs over 80–200 km/h and three temperatures. Asserted (docs/calibration.md
/// has the figures): the radar's scale within 0.05 %, its latency and the tachometers' delay
/// within 5 ms, the linear pad law with its rise within 3 standard errors, per-run μ RMSE at
/// most 0.6 × the uncalibrated one, α_i(v) within 1 % and 3 standard errors — not the 0.5 %
/// aimed for (measured: 0.08–0.59 %, 9 of 12 axles within 0.5 %; with the force balance's
/// coefficients 0.30–1.48 %, 5 of 12, before the load fluctuation's band): the per-axle α rest
/// on the wheel-slide protection's pressure differences against the radar's noise, ~0.45 % one
/// standard error over 12 runs from the balance integrated over time (~0.8 % from the force
/// balance). That error is the radar's noise: the balance's residual is within 10 % of what
/// the radar's white noise (read from its samples, 0.05 m/s) leaves through the same low-pass
/// (measured 0.99–1.02). Each axle's bias is within ±0.001 on every run (measured: up to 0.00064; up to
/// 0.0014 with the force balance's). The three campaigns pooled (one vehicle, 36 runs) bring α
/// to −0.44 … +0.37 % with one standard error of 0.24–0.29 %.
#[test]
fn the_campaign_calibrates_itself_on_mismatch_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let mut all = Vec::new();
    for seed in [1, 2, 3] {
        let runs = mismatch_campaign(seed, dir.path(), |_| {});
        all.extend(
            runs.iter()
                .map(|(log, out)| (log.clone(), out.mismatch.clone())),
        );
        let c = calibrate(&runs, dir.path());
        let m = runs[0].1.mismatch.clone().unwrap();
        eprintln!(
            "seed {seed}: α {:?} ± {:?}, pad {:?}, radar {:.5} ± {:.5}, latency {:.1} ± {:.1} ms, tachos {:.1} ± {:.1} ms",
            c.alpha_nm_per_bar, c.alpha_se, c.pad, c.radar_scale, c.radar_scale_se,
            c.radar_latency_s * 1e3, c.radar_latency_se * 1e3, c.tacho_delay_s * 1e3, c.tacho_delay_se * 1e3
        );
        assert!(c.shared.is_empty(), "{:?}", c.shared);
        assert_radar_targets(&c, &m, &format!("seed {seed}"));
        // The radar's noise, read from its samples, is all the balance leaves: its residual
        // is within 10 % of what that noise leaves through the same low-pass (measured
        // 0.99–1.02 on seeds 1–3).
        let b = &c.integrated;
        eprintln!(
            "seed {seed}: radar noise {:?} m/s, residual {:?}× what it leaves",
            b.radar_noise_mps, b.residual_over_radar_noise
        );
        assert_eq!(b.radar_noise_runs, runs.len());
        let noise = b.radar_noise_mps.unwrap();
        assert!((noise / 0.05 - 1.0).abs() <= 0.03, "radar noise {noise}");
        let ratio = b.residual_over_radar_noise.unwrap();
        assert!(
            (0.9..=1.1).contains(&ratio),
            "residual over the radar's noise {ratio}"
        );
        assert!(
            (c.tacho_delay_s - 0.010).abs() <= 0.005,
            "{}",
            c.tacho_delay_s
        );
        assert_eq!(c.pad.form, PadForm::Linear, "{:?}", c.pad_candidates);
        // The running resistance's speed terms (measured: within 1.5 standard errors).
        assert_davis_resistance(&c);
        let rise = c.pad.rise_to_standstill();
        let true_rise = m.pad_friction_rise * (c.pad.v_ref_mps / m.pad_friction_v0_mps);
        assert!(
            (rise - true_rise).abs() <= 3.0 * c.pad.gamma_se + 0.005,
            "rise {rise} against {true_rise} (se {})",
            c.pad.gamma_se
        );
        let alpha_within = alpha_errors(&c, &m, true);
        for (name, after) in assert_rmse_ratio(&runs, &c, "mismatch") {
            for (a, (_, bias)) in after.iter().enumerate() {
                eprintln!("{name} axle {}: bias {bias:+.5}", a + 1);
                assert!(
                    bias.abs() <= 0.001,
                    "{name} axle {}: bias {bias} (α(v) within {})",
                    a + 1,
                    alpha_within[a]
                );
            }
        }
    }
    // The three campaigns are one vehicle (its brake scatter has its own seed): as one
    // campaign of 36 runs the α_i rest on three times the data.
    let pipeline = Pipeline::default_uic_z1();
    let mut cal = CampaignCalibrator::new(&pipeline);
    for (log, _) in &all {
        cal.add(log).unwrap();
    }
    let c = cal.finish(dir.path()).unwrap();
    let m = all[0].1.clone().unwrap();
    for a in 0..4 {
        let at_top = m.brake_torque_nm_per_bar[a]
            * (1.0
                + m.pad_friction_rise * (1.0 - c.pad.v_ref_mps / m.pad_friction_v0_mps).max(0.0));
        eprintln!(
            "36 runs, axle {}: α at the top {:+.2} % (se {:.2} %)",
            a + 1,
            (c.alpha_nm_per_bar[a] / at_top - 1.0) * 100.0,
            c.alpha_se[a] / at_top * 100.0
        );
        assert!(
            c.alpha_se[a] / at_top < 0.006,
            "axle {}: se {}",
            a + 1,
            c.alpha_se[a]
        );
        assert!(
            (c.alpha_nm_per_bar[a] - at_top).abs() <= 3.0 * c.alpha_se[a],
            "axle {}: α {} against {at_top} (se {})",
            a + 1,
            c.alpha_nm_per_bar[a],
            c.alpha_se[a]
        );
    }
}

/// What limits the per-axle α is the radar's noise: the mismatch scenes without it (and its
/// spikes), every other mismatch and sensor effect kept (the wheel loads' fluctuation too),
/// noise seed 1, on three vehicles (brake scatter seeds 11 — the scenes' own — 13 and 14):
/// every α_i(v) within 0.25 % over 5–55 m/s (measured: within 0.12 %). Their standard errors
/// are not asserted: at ~0.05 % they leave out what remains of the model's error (up to 2.8 of
/// them here). With the radar's noise the same vehicles come out up to 1.2 % off, about as far
/// as their standard errors (~0.45 %) say (docs/calibration.md, `scripts/alpha-floor.sh`).
#[test]
fn without_the_radars_noise_every_alpha_is_within_a_quarter_percent() {
    let dir = tempfile::tempdir().unwrap();
    for vehicle in [11, 13, 14] {
        let runs = mismatch_campaign(1, dir.path(), |sc| {
            sc.brake.scatter_seed = vehicle;
            let keep = Effect::ALL.iter().filter(|e| {
                sc.effects.has(**e) && !matches!(e, Effect::RadarNoise | Effect::RadarSpikes)
            });
            sc.effects = keep.fold(Effects::none(), |m, e| m.with(*e));
        });
        let c = calibrate(&runs, dir.path());
        let m = runs[0].1.mismatch.clone().unwrap();
        eprintln!(
            "vehicle {vehicle}: α {:?} against {:?}, residual {:?}× what the radar's noise leaves",
            c.alpha_nm_per_bar, m.brake_torque_nm_per_bar, c.integrated.residual_over_radar_noise
        );
        // Without its noise the radar (rounded to 1 mm/s) no longer accounts for the residual:
        // the rest of the model's error does (measured 13.5× on vehicle 11).
        let ratio = c.integrated.residual_over_radar_noise.unwrap();
        assert!(
            ratio >= 3.0,
            "vehicle {vehicle}: residual over the radar's noise {ratio}"
        );
        for (a, worst) in alpha_errors(&c, &m, false).iter().enumerate() {
            assert!(
                *worst <= 0.0025,
                "vehicle {vehicle}, axle {}: α(v) within {worst}",
                a + 1
            );
        }
    }
}

/// The pad friction's shape: the mismatch scenes (noise seed 1) with a pad law whose rise
/// gathers towards standstill, α_i (1 + 0.05 (1 − v/v0)^n) (n = 1, the scenes' own, is the
/// mismatch test's). Each n gets a form near it: linear or the linear–quadratic mixture at 1.5,
/// quadratic at 2, the quadratic–cubic mixture at 2.5 (between two powers, which no form
/// contains), cubic at 3.
///
/// What a form's misfit does to the estimates is seen without the radar's noise, which alone
/// moves each axle's α by ~0.45 % (one standard error; `scripts/alpha-floor.sh`) and so its μ
/// by ~0.0004, in a draw that changes with every change of the trajectories: there every
/// axle's μ bias is within ±0.0005 on every run (at n = 2.5 the fixed forms left 0.0019, the
/// misfit leaking into the per-axle α, over 4 vehicles × 3 seeds). With the radar's noise, at
/// n = 2.5, the mixture is still chosen and the bias within ±0.0015 (the target's ±0.001 is
/// asserted on the scenes' own law by the mismatch test; over 4 vehicles × 3 seeds at n = 1.5,
/// 44 of 48 axles are within it, all within 0.0013). Measured: 0.00019, 0.00013, 0.00014 and
/// 0.00019 without the noise, 0.00059 with it. The runs' μ RMSE stays at most 0.6 of the
/// uncalibrated (measured 0.28–0.47).
#[test]
fn pad_laws_of_other_shapes_are_calibrated_by_a_form_near_them() {
    let dir = tempfile::tempdir().unwrap();
    let (linear, quadratic, mixed, cubic) = (
        &[PadForm::Linear, PadForm::LinearQuadratic][..],
        &[PadForm::Quadratic][..],
        &[PadForm::QuadraticCubic][..],
        &[PadForm::Cubic, PadForm::QuadraticCubic][..],
    );
    for (n, forms, radar_noise, bound) in [
        (1.5, linear, false, 0.0005),
        (2.0, quadratic, false, 0.0005),
        (2.5, mixed, false, 0.0005),
        (3.0, cubic, false, 0.0005),
        (2.5, mixed, true, 0.0015),
    ] {
        let runs = mismatch_campaign(1, dir.path(), |sc| {
            sc.brake.pad_friction_exponent = n;
            if !radar_noise {
                let keep = Effect::ALL.iter().filter(|e| {
                    sc.effects.has(**e) && !matches!(e, Effect::RadarNoise | Effect::RadarSpikes)
                });
                sc.effects = keep.fold(Effects::none(), |m, e| m.with(*e));
            }
        });
        let label = format!("pad law n = {n}, radar noise {radar_noise}");
        let c = calibrate(&runs, dir.path());
        let m = runs[0].1.mismatch.clone().unwrap();
        assert_eq!(m.pad_friction_exponent, n);
        eprintln!(
            "{label}: pad {:?}, α {:?} against {:?}",
            c.pad, c.alpha_nm_per_bar, m.brake_torque_nm_per_bar
        );
        assert!(
            forms.contains(&c.pad.form),
            "{label}: {:?}",
            c.pad_candidates
        );
        if c.pad.form.mixes() {
            // The weight written is the chosen candidate's, and inside its range.
            let chosen = c
                .pad_candidates
                .iter()
                .find(|k| k.form == c.pad.form && k.per_run_constants == c.per_run_constants)
                .unwrap();
            assert_eq!(chosen.mix, c.pad.mix);
            assert!(
                (0.15..=0.85).contains(&c.pad.mix),
                "{label}: w {}",
                c.pad.mix
            );
            // γ's error with w profiled out: finite and positive (measured: 0.0003 without the
            // radar's noise, 0.0013 with it, about the fixed forms' 0.0012–0.0013).
            assert!(
                c.pad.gamma_se > 0.0 && c.pad.gamma_se < 0.005,
                "{label}: γ se {}",
                c.pad.gamma_se
            );
        }
        let after = assert_rmse_ratio(&runs, &c, &label);
        let largest = after
            .iter()
            .flat_map(|(_, axles)| axles.iter().map(|(_, bias)| bias.abs()))
            .fold(0.0, f64::max);
        eprintln!("{label}: largest per-axle μ bias {largest:.5}");
        for (name, axles) in after {
            for (a, (_, bias)) in axles.iter().enumerate() {
                assert!(
                    bias.abs() <= bound,
                    "{label}, {name} axle {}: bias {bias}",
                    a + 1
                );
            }
        }
    }
}

/// Each run's constant of the balance is its running resistance's constant and its gradient
/// force: the mismatch scenes (seed 1), each on its own gradient (−5 … +6 ‰ in steps of 1 ‰),
/// Davis a = 1200 N. Every run's constant within 3 of its standard errors of
/// a + M g sin(atan i) (M the simulator's translating mass), and the standard errors small
/// enough to tell the gradients apart (below 1 ‰'s force).
#[test]
fn each_runs_constant_is_its_resistance_and_gradient() {
    let dir = tempfile::tempdir().unwrap();
    let next = std::cell::Cell::new(0usize);
    let grades = std::cell::RefCell::new(Vec::new());
    let runs = mismatch_campaign(1, dir.path(), |sc| {
        let i = next.get();
        next.set(i + 1);
        sc.effects = sc.effects.with(Effect::Gradient);
        sc.run.gradient_permille = -5.0 + i as f64;
        let mass = sc.vehicle.body_mass_kg + 2.0 * sc.vehicle.bogie_mass_kg;
        let force = mass * 9.80665 * (sc.run.gradient_permille / 1000.0).atan().sin();
        grades
            .borrow_mut()
            .push((sc.resistance.davis_a_n + force, mass * 9.80665 / 1000.0));
    });
    let c = calibrate(&runs, dir.path());
    assert!(c.per_run_constants, "{:?}", c.pad_candidates);
    assert_eq!(c.resistance_constants.len(), runs.len());
    for ((log, _), (rc, (truth, permille))) in runs
        .iter()
        .zip(c.resistance_constants.iter().zip(grades.borrow().iter()))
    {
        let name = log.source.file_name().unwrap().to_string_lossy();
        eprintln!(
            "{}: {:.0} ± {:.0} N, truth {truth:.0} N",
            rc.run, rc.constant_n, rc.se_n
        );
        assert_eq!(rc.run, name);
        assert!(
            rc.se_n > 0.0 && rc.se_n < *permille,
            "{}: se {}",
            rc.run,
            rc.se_n
        );
        assert!(
            (rc.constant_n - truth).abs() <= 3.0 * rc.se_n,
            "{}: {} ± {} against {truth}",
            rc.run,
            rc.constant_n,
            rc.se_n
        );
    }
}

/// Without a mismatch (the same scenes, the brake rig and the radar as the pipeline says),
/// the calibration finds the identity within its errors and keeps the pipeline's α (one ratio
/// to it for all axles, within its errors of 1: a change the data do not call for would only
/// add the fit's noise); the per-sample μ RMSE is never worse by more than 2 % on any run
/// (measured: ratios 0.71–0.996 over 24 runs; the gain is the tachometers' counting delay,
/// which the simulated sensors have and the uncalibrated estimate ignores).
#[test]
fn calibration_changes_little_on_clean_data() {
    let dir = tempfile::tempdir().unwrap();
    for seed in [1, 2] {
        let runs = mismatch_campaign(seed, dir.path(), clean(&[]));
        let c = calibrate(&runs, dir.path());
        eprintln!(
            "seed {seed}: α {:?} ± {:?}, pad {:?}, radar {:.5} ± {:.5}, latency {:.1} ms, tachos {:.1} ms",
            c.alpha_nm_per_bar, c.alpha_se, c.pad, c.radar_scale, c.radar_scale_se,
            c.radar_latency_s * 1e3, c.tacho_delay_s * 1e3
        );
        assert!((c.radar_scale - 1.0).abs() <= 5e-4, "{}", c.radar_scale);
        assert!(c.radar_latency_s.abs() <= 0.006, "{}", c.radar_latency_s);
        // No false pad law: without noise the balance integrated over time may call for a speed
        // term, but not for one that matters (measured: linear, γ = 9e-5).
        let rise = c.pad.gamma * c.pad.phi(0.0);
        assert!(rise.abs() <= 1e-3, "{:?} {:?}", c.pad, c.pad_candidates);
        for a in 0..4 {
            assert!(
                (c.alpha_fitted[a] / 1600.0 - 1.0).abs() <= 0.02,
                "{:?}",
                c.alpha_fitted
            );
        }
        assert_eq!(c.alpha_nm_per_bar, [1600.0; 4]);
        assert_note(&c.notes, &["the pipeline's α kept"]);
        // With the pipeline's α kept, the resistance is the balance's at them.
        assert_davis_resistance(&c);
        assert_no_run_worse(&runs, &c);
    }
}

/// The bundled archive's scenes (Polach's law with its effects, no mismatch, one run logged
/// with the radar at 100 Hz and the pressures at 200 Hz): the calibration keeps the pipeline's
/// α and improves every soap run (measured: 0.73–0.78×, the tachometers' counting delay). Each
/// run is weighted by its residual variance: unweighted, the 100 Hz radar's larger noise read
/// as a 1.8 % scatter between the axles and made every run 3–8 % worse.
#[test]
fn the_bundled_scenes_keep_the_pipelines_alpha() {
    let dir = tempfile::tempdir().unwrap();
    let runs = campaign("pipelines/scenes", None, dir.path(), |_| {});
    assert_eq!(runs.len(), 8);
    let c = calibrate(&runs, dir.path());
    eprintln!("fitted α {:?} ± {:?}", c.alpha_fitted, c.alpha_fitted_se);
    assert_eq!(c.alpha_nm_per_bar, [1600.0; 4]);
    assert_no_run_worse(&runs, &c);
    // The tachometers' delay is half their counting window, read from their quantisation; the
    // radar's latency, tested alone, is not told from 0 (truth 0) and taken as 0. Fitted from
    // the balance instead, the two came out at latency 8.0 ± 7.1 ms and tachometers 3.2 ± 3.4
    // ms (correlated −0.96, kept together), which took only 14–16 % off the soap runs' μ error.
    assert_eq!(c.radar_latency_s, 0.0, "{:?}", c.notes);
    assert!(
        (c.tacho_delay_s - 4.0 / 417.0).abs() <= 1e-12,
        "{:?}",
        c.notes
    );
    for (name, before, after) in before_after(&runs, &c) {
        if name.starts_with("soap") {
            assert!(
                after.1 <= 0.8 * before.1,
                "{name}: {} against {}",
                after.1,
                before.1
            );
        }
    }
}

/// Hard case: a campaign without the wheel-slide protection and without sensor noise (the
/// mismatch scenes with every mismatch and the protection taken out). The pressures change
/// only when the brake is applied, so the balance's residual has no minimum in either delay:
/// both are taken as 0, said so; wheels lock, and those samples are left out; the α stay
/// within 0.1 % of the truth and no run's estimate is worse by more than 2 % (before the locks
/// were left out, the fit chose a false pad law, −3.9 % by Karwatzki's factor, and made runs up
/// to 8× worse).
#[test]
fn a_campaign_without_pressure_changes_takes_its_delays_as_0() {
    let dir = tempfile::tempdir().unwrap();
    let runs = mismatch_campaign(
        1,
        dir.path(),
        clean(&[
            "tacho_quantization",
            "radar_noise",
            "radar_spikes",
            "pressure_noise",
            "wsp",
        ]),
    );
    let c = calibrate(&runs, dir.path());
    eprintln!("{:?}", c.notes);
    for name in ["radar's latency", "tachometers' delay"] {
        assert_note(&c.notes, &[name, "has no minimum", "taken as 0"]);
    }
    assert_eq!((c.radar_latency_s, c.tacho_delay_s), (0.0, 0.0));
    assert_note(&c.notes, &["have a wheel locked"]);
    // No false pad law: without noise the balance integrated over time may call for a speed
    // term, but not for one that matters (measured: linear, γ = 9e-5).
    let rise = c.pad.gamma * c.pad.phi(0.0);
    assert!(rise.abs() <= 1e-3, "{:?} {:?}", c.pad, c.pad_candidates);
    // Without noise, even 0.01 % is significant: the α stay within 0.1 % of the truth.
    for a in c.alpha_nm_per_bar {
        assert!((a / 1600.0 - 1.0).abs() <= 1e-3, "{:?}", c.alpha_nm_per_bar);
    }
    assert_no_run_worse(&runs, &c);
}

/// Hard case: no run coasts before its brake (the brake applied from the first sample), so
/// nothing gives the radar's scale. The calibration says so, takes the radar as it reads
/// (scale 1) and still fits the brake coefficients: the radar's unknown 0.3 % scales the
/// deceleration, and with a pressure that barely changes within a run the pad friction's speed
/// law and the resistance's speed term are harder to tell apart (measured: the axles' mean α
/// 0.41 % high; 3.0 % from the force balance). Still better than the pipeline's α (1.7 % low):
/// every run's μ RMSE at most 0.6 of the uncalibrated (measured 0.27–0.39).
#[test]
fn a_campaign_that_never_coasts_keeps_the_radar_as_it_reads() {
    let dir = tempfile::tempdir().unwrap();
    let runs = mismatch_campaign(1, dir.path(), |sc| {
        for d in sc.brake.demand_bar.iter_mut() {
            let p = d.last().unwrap().1;
            *d = vec![(0.0, p)];
        }
    });
    let c = calibrate(&runs, dir.path());
    let m = runs[0].1.mismatch.clone().unwrap();
    assert_eq!(c.radar_scale, 1.0);
    assert_eq!(c.radar_scale_runs, 0);
    assert_note(&c.notes, &["no run coasts", "taken as 1"]);
    let mean = |x: &[f64; 4]| x.iter().sum::<f64>() / 4.0;
    let at_top = m.brake_torque_nm_per_bar.map(|a| {
        a * (1.0 + m.pad_friction_rise * (1.0 - c.pad.v_ref_mps / m.pad_friction_v0_mps).max(0.0))
    });
    let rel = mean(&c.alpha_nm_per_bar) / mean(&at_top) - 1.0;
    eprintln!(
        "α {:?} against {at_top:?}: mean off by {:.2} %",
        c.alpha_nm_per_bar,
        rel * 100.0
    );
    assert!(rel.abs() <= 0.01, "{rel}");
    assert_rmse_ratio(&runs, &c, "never coasts");
}

/// A dry campaign without wheel-slide protection whose axles 1 and 2 always get the same
/// pressure (axles 3 and 4 their own profiles), per-axle α off by 2 %.
fn pair_campaign(dir: &Path) -> Vec<railgrip::ingest::RunLog> {
    let mut logs = Vec::new();
    for (i, kmh) in [80.0, 120.0, 160.0, 200.0].iter().enumerate() {
        for seed in [1u64, 2] {
            let p = 3.0 + 0.3 * i as f64;
            let text = format!(
                "name = \"pair\"\nseed = {seed}\neffects = [\"load_transfer\", \"running_resistance\", \"radar_noise\", \"tacho_quantization\", \"pressure_noise\", \"brake_scatter\"]\n[run]\ninitial_speed_kmh = {kmh}\ncondition = \"dry\"\n[brake]\nscatter_seed = 5\ndemand_bar_per_axle = [[[0.0, 0.0], [3.0, 0.0], [4.5, {p}]], [[0.0, 0.0], [3.0, 0.0], [4.5, {p}]], [[0.0, 0.0], [3.0, 0.0], [6.0, {a}], [12.0, {p}]], [[0.0, 0.0], [3.5, 0.0], [5.0, {b}], [14.0, {c}]]]\n",
                a = 0.7 * p,
                b = 1.1 * p,
                c = 0.6 * p
            );
            let sc = Scene::from_toml(&text, "pair.toml", None).unwrap_or_else(|e| panic!("{e}"));
            let out = sim::simulate(&sc, None).unwrap();
            let stem = format!("pair_{kmh}_{seed}");
            out.write(dir, &stem, OutputFormat::Csv).unwrap();
            logs.push(
                ingest_file(
                    &dir.join(format!("{stem}.csv")),
                    &Pipeline::default_uic_z1(),
                )
                .unwrap(),
            );
        }
    }
    logs
}

/// Hard cases: two axles whose pressures never differ cannot have their α told apart (the
/// calibration says so by name, fits the pair with one α, and the others on their own); the
/// tachometers' delay, which these smooth runs could not tell from the balance, comes from
/// their counting window; a delay whose interval reaches its range's end is taken as 0;
/// locked wheels are left out.
#[test]
fn axles_with_the_same_pressure_share_one_alpha() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = Pipeline::default_uic_z1();
    let mut cal = CampaignCalibrator::new(&pipeline);
    for log in pair_campaign(dir.path()) {
        cal.add(&log).unwrap();
    }
    let c = cal.finish(dir.path()).unwrap();
    eprintln!(
        "{:?} ± {:?}, shared {:?}, latency {:.1} ± {:.1} ms, notes {:?}",
        c.alpha_nm_per_bar,
        c.alpha_se,
        c.shared,
        c.radar_latency_s * 1e3,
        c.radar_latency_se * 1e3,
        c.notes
    );
    assert_eq!(c.shared, vec![vec![0, 1]]);
    // Without the wheel-slide protection the dry runs lock wheels: a locked wheel's brake
    // holds it with less than α p, so those samples (and the filters' settling around them)
    // are left out, one note saying in how many runs and how long.
    assert_note(
        &c.notes,
        &[
            "8 of 8 runs have a wheel locked",
            "the longest in pair_200_",
        ],
    );
    // Smooth runs without the wheel-slide protection barely tell the tachometers' delay from
    // the balance (it came out at the end of its range and was taken as 0 before the
    // counting window was read): it is half the 20 ms window's 8 samples, held, its standard
    // error not a number — which the calibration's JSON carries as null and reads back.
    let window = c.tacho_window_s.expect("the counting window is read");
    assert!((window - 8.0 / 417.0).abs() <= 1e-12, "{window}");
    assert!(
        (c.tacho_delay_s - 4.0 / 417.0).abs() <= 1e-12,
        "{}",
        c.tacho_delay_s
    );
    assert!(c.tacho_delay_se.is_nan());
    assert_note(
        &c.notes,
        &["count pulses over 19.2 ms", "not fitted from the balance"],
    );
    // With the tachometers held, the radar's latency alone comes out at −43 ± 6 ms, its 95 %
    // interval reaching the searched range's end (−50 ms, where both ran when fitted
    // together): no fit, taken as 0 — kept, it put the α 7–13 % off (1481, 1800, 1781).
    assert_eq!(c.radar_latency_s, 0.0);
    assert_note(
        &c.notes,
        &[
            "radar's latency",
            "reaching the lower end of the searched range",
            "taken as 0",
        ],
    );
    let json = serde_json::to_string(&c).unwrap();
    let back: CampaignCalibration = serde_json::from_str(&json).unwrap();
    assert!(back.tacho_delay_se.is_nan() && back.alpha_nm_per_bar == c.alpha_nm_per_bar);
    assert_eq!(back.tacho_window_s, c.tacho_window_s);
    // A file written before the window was read lacks the key: it reads back as none read.
    let mut old: serde_json::Value = serde_json::from_str(&json).unwrap();
    old.as_object_mut().unwrap().remove("tacho_window_s");
    let old: CampaignCalibration = serde_json::from_value(old).unwrap();
    assert_eq!(old.tacho_window_s, None);
    assert_eq!(c.alpha_nm_per_bar[0], c.alpha_nm_per_bar[1]);
    assert_note(&c.notes, &["axles 1 and 2", "one α"]);
}

/// Hard case: a dropout, 6–8 s of the first run (braking), three ways: a CSV logger that
/// drops whole rows (the tachometers and pressures go with the radar), a CSV whose radar cells
/// are empty (the radar alone), and an MCAP log without the radar's messages. The run's
/// samples there and the filters' settling around them are left out of the calibration, with
/// a note naming the file and the channel; the campaign's radar scale and latency stay within
/// their targets, and the run itself is estimated outside the dropout, calibrated as well as
/// the others (μ RMSE ≤ 0.6 of the uncalibrated).
#[test]
fn a_radar_dropout_leaves_its_samples_out() {
    let dir = tempfile::tempdir().unwrap();
    let mut runs = mismatch_campaign(1, dir.path(), |_| {});
    let csv = runs[0].0.source.clone();
    let text = std::fs::read_to_string(&csv).unwrap();
    let in_dropout = |t: f64| (6.0..8.0).contains(&t);
    // Whole rows dropped.
    let rows = text
        .lines()
        .enumerate()
        .filter(|(i, l)| *i == 0 || !in_dropout(l.split(',').next().unwrap().parse().unwrap()))
        .map(|(_, l)| format!("{l}\n"))
        .collect::<String>();
    // The radar's cells emptied.
    let cells = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let f: Vec<&str> = l.split(',').collect();
            if i > 0 && in_dropout(f[0].parse().unwrap()) {
                format!("{},,{}\n", f[0], f[2..].join(","))
            } else {
                format!("{l}\n")
            }
        })
        .collect::<String>();
    // The radar's messages left out of an MCAP log of the same run.
    let stem = csv.file_stem().unwrap().to_string_lossy().to_string();
    let mcap = dir.path().join(format!("{stem}_radar_dropout.mcap"));
    runs[0]
        .1
        .write(dir.path(), &format!("{stem}_full"), OutputFormat::Mcap)
        .unwrap();
    let full = std::fs::read(dir.path().join(format!("{stem}_full.mcap"))).unwrap();
    let mut cut = std::io::Cursor::new(Vec::new());
    {
        let mut w = mcap::Writer::new(&mut cut).unwrap();
        let mut t0 = None;
        for m in mcap::MessageStream::new(&full).unwrap() {
            let m = m.unwrap();
            let t = (m.log_time - *t0.get_or_insert(m.log_time)) as f64 * 1e-9;
            if !(m.channel.topic == "/radar/speed" && in_dropout(t)) {
                w.write(&m).unwrap();
            }
        }
        w.finish().unwrap();
    }
    std::fs::write(&mcap, cut.into_inner()).unwrap();
    let pipeline = Pipeline::default_uic_z1();
    for (what, path, channel) in [
        ("rows", csv.clone(), "every channel"),
        ("radar cells", csv.clone(), "v_radar"),
        ("radar messages", mcap.clone(), "v_radar"),
    ] {
        match what {
            "rows" => std::fs::write(&csv, &rows).unwrap(),
            "radar cells" => std::fs::write(&csv, &cells).unwrap(),
            _ => std::fs::write(&csv, &text).unwrap(),
        }
        let gapped = ingest_file(&path, &pipeline).unwrap_or_else(|e| panic!("{what}: {e}"));
        let lost = gapped.invalid_samples() as f64 / gapped.sample_rate_hz;
        assert!((1.9..2.1).contains(&lost), "{what}: {lost} s invalid");
        runs[0].0 = gapped;
        let c = calibrate(&runs, dir.path());
        let m = runs[0].1.mismatch.clone().unwrap();
        let file = path.file_name().unwrap().to_string_lossy().to_string();
        eprintln!(
            "{what}: scale {:.5}, latency {:.1} ms",
            c.radar_scale,
            1e3 * c.radar_latency_s
        );
        assert_note(
            &c.notes,
            &[&file, &format!("without data on {channel}"), "dropout"],
        );
        assert_radar_targets(&c, &m, what);
        assert_eq!(c.runs, 12);
        // The run's estimates outside the dropout.
        assert_rmse_ratio(&runs[..1], &c, what);
    }
}

/// Hard case: delays the runs do not tell from 0. The clean mismatch scenes without the
/// tachometers' counting window have neither delay, yet the profiled balance finds a few ms
/// (seeds 1–3: latency 1.1, 1.1 and −2.8 ms, tachometers −0.9, −2.4 and 3.7 ms, one standard
/// error 2.3–3.1 ms); together they are not told from 0 (Wald 0.24–1.79 against χ²₂'s
/// 5.99), so both are taken as 0 with one note, and no run is worse by more than 2 %
/// (measured: 1.000). No counting window is read from such tachometers.
#[test]
fn delays_the_runs_do_not_tell_from_0_are_taken_as_0() {
    let dir = tempfile::tempdir().unwrap();
    for seed in [1, 2, 3] {
        let runs = mismatch_campaign(seed, dir.path(), clean(&["tacho_quantization"]));
        let c = calibrate(&runs, dir.path());
        eprintln!("seed {seed}: {:?}", c.notes);
        for name in ["radar's latency", "tachometers' delay"] {
            assert_note(&c.notes, &[name, "not told from 0 at 95 %", "taken as 0"]);
        }
        assert_eq!((c.radar_latency_s, c.tacho_delay_s), (0.0, 0.0));
        // Tachometers that read ω exactly show no counting window (the filter's ringing after
        // the slides' kinks is a broad trough, not a lone one), so the balance fits the delay.
        assert_eq!(c.tacho_window_s, None);
        assert!(
            !c.notes.iter().any(|n| n.contains("count pulses")),
            "{:?}",
            c.notes
        );
        assert_no_run_worse(&runs, &c);
    }
}

/// Without the wheel-slide protection (the clean mismatch scenes: the brake rig and the radar as
/// the pipeline says), the pressures change only when the brake is applied and the wheels lock
/// for 10–68 s of each run: the delays rest on one brake application per run. The balance alone
/// found them with the errors that allows (seeds 1–3: latency 1.0 ± 4.2, −0.4 ± 4.8 and −4.8 ±
/// 3.9 ms, tachometers −5.7 ± 4.7, 14.2 ± 10.5 and 3.7 ± 9.7 ms, where the truth is 0 and the
/// counting window's 9.6 ms), did not tell them from 0 and took both as 0. The counting window
/// does not need the pressures to change: its trough shows on the rolling wheels' blocks (46 of
/// 48 axles on seed 1), so the tachometers' delay is half of it, 9.6 ms; the radar's latency,
/// tested alone, is not told from 0 and taken as 0; the pipeline's α stay and no run is worse
/// (measured: each run's μ RMSE 0.994–0.999 of the uncalibrated, the delay taken out).
#[test]
fn without_the_wheel_slide_protection_the_counting_window_gives_the_delay() {
    let dir = tempfile::tempdir().unwrap();
    for seed in [1, 2, 3] {
        let runs = mismatch_campaign(seed, dir.path(), clean(&["wsp"]));
        let c = calibrate(&runs, dir.path());
        eprintln!("seed {seed}: {:?}", c.notes);
        assert_eq!(c.radar_latency_s, 0.0);
        assert!(
            (c.tacho_delay_s - 4.0 / 417.0).abs() <= 1e-12,
            "{}",
            c.tacho_delay_s
        );
        assert_note(
            &c.notes,
            &["count pulses over 19.2 ms", "not fitted from the balance"],
        );
        assert_note(
            &c.notes,
            &["radar's latency", "not told from 0 at 95 %", "taken as 0"],
        );
        assert_note(&c.notes, &["have a wheel locked"]);
        assert_eq!(c.alpha_nm_per_bar, [1600.0; 4]);
        assert_no_run_worse(&runs, &c);
    }
}

/// Hard case: a campaign of fewer than 3 runs. Its delays cannot be tested against the runs'
/// scatter, and a profile over one run follows that run's noise: each clean mismatch scene
/// calibrated on itself came out up to 4.3× worse than uncalibrated. The calibration is
/// refused with what to do, naming the campaign.
#[test]
fn a_campaign_of_fewer_than_3_runs_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let runs = mismatch_campaign(1, dir.path(), clean(&[]));
    let pipeline = Pipeline::default_uic_z1();
    for n in [1, 2] {
        let mut cal = CampaignCalibrator::new(&pipeline);
        for (log, _) in &runs[..n] {
            cal.add(log).unwrap();
        }
        let e = cal.finish(Path::new("two_runs")).unwrap_err().to_string();
        assert!(
            e.contains("two_runs")
                && e.contains(&format!("only {n} run"))
                && e.contains("at least 3")
                && e.contains("estimate.calibration = \"pipeline\""),
            "{e}"
        );
    }
    let mut cal = CampaignCalibrator::new(&pipeline);
    for (log, _) in &runs[..3] {
        cal.add(log).unwrap();
    }
    assert_eq!(cal.finish(dir.path()).unwrap().runs, 3);
}
