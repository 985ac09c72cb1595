//! What a learned model file says about its own data — the data-support grid and its
//! blend (format version 2), ensembles and Bayesian regularisation through the pipeline, the
//! plausibility audit, and version-1 files still loading.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use railgrip::identify::export::mlp_file;
use railgrip::identify::support::audit;
use railgrip::identify::{creep_spec, median_speed, train_mlp};
use railgrip::model::{Model, ModelFile, Provenance};
use railgrip::score::Sample;
use railgrip::Pipeline;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn golden(name: &str) -> Model {
    Model::load(&root().join("models/golden").join(name)).unwrap()
}

fn provenance() -> Provenance {
    Provenance {
        inputs: vec![],
        pipeline: "uic_z1".into(),
        pipeline_sha256: String::new(),
        seed: 1,
        crate_version: String::new(),
        created: String::new(),
        generation: None,
        calibration: None,
    }
}

#[test]
fn version_1_files_still_load_and_agree_where_the_data_are() {
    let v1 = golden("v1/synthetic_mlp.json");
    let v2 = golden("synthetic_mlp.json");
    assert_eq!(v1.file.version, 1);
    assert_eq!(v2.file.version, 2);
    assert!(v1.file.support.is_none() && v1.support_weight(1.0, 0.0, f64::NAN).is_none());
    let p1 = golden("v1/synthetic_polach.json");
    assert!(p1.mu_v(1.0, 0.0, 30.0).is_finite());
    // Same network in both (trained the same way): equal wherever the support is whole.
    let (mut inside, mut outside) = (0, 0);
    for i in 0..=120 {
        for j in 0..=24 {
            let (dv, ddv) = (0.25 + 0.03 * i as f64, -3.0 + 0.25 * j as f64);
            let w = v2.support_weight(dv, ddv, f64::NAN).unwrap();
            assert!((0.0..=1.0).contains(&w), "{w}");
            if w == 1.0 {
                inside += 1;
                let (a, b) = (v1.mu(dv, ddv), v2.mu(dv, ddv));
                assert!((a - b).abs() < 1e-9, "({dv}, {ddv}): {a} vs {b}");
            } else {
                outside += 1;
            }
        }
    }
    assert!(inside > 500 && outside > 100, "{inside} {outside}");
}

#[test]
fn a_version_2_file_with_a_grid_that_does_not_fit_is_refused_by_name() {
    let text = std::fs::read_to_string(root().join("models/golden/synthetic_mlp.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["support"]["cells"] = serde_json::json!([24, 24, 8]);
    let e = ModelFile::from_json(&v.to_string(), "bad.json")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad.json") && e.contains("support: 3 grid dimensions for 2 inputs"),
        "{e}"
    );
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["support"]["counts"].as_array_mut().unwrap().pop();
    let e = ModelFile::from_json(&v.to_string(), "short.json")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("short.json") && e.contains("one per cell"),
        "{e}"
    );
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["support"]["cells"] = serde_json::json!([1024, 4096]);
    let e = ModelFile::from_json(&v.to_string(), "huge.json")
        .unwrap_err()
        .to_string();
    assert!(e.contains("huge.json") && e.contains("(2..=1024)"), "{e}");
    // Version 1 has no grid.
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["version"] = 1.into();
    let e = ModelFile::from_json(&v.to_string(), "old.json")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("old.json") && e.contains("version 1 has no"),
        "{e}"
    );
}

#[test]
fn the_blend_is_continuous_and_the_network_alone_at_supported_centres() {
    let m = golden("synthetic_mlp.json");
    let sup = m.file.support.clone().unwrap();
    let mut bare = m.file.clone();
    bare.support = None;
    bare.audit = None;
    let bare = Model::new(bare).unwrap();
    // Along lines through the plane, μ never jumps: neighbouring points 1e-4 m/s apart differ
    // by little more than the network's own slope allows.
    for ddv in [-2.6, -0.3, 0.0, 1.1, 2.9] {
        let mut prev = m.mu(0.3, ddv);
        for k in 1..=40_000 {
            let dv = 0.3 + 1e-4 * k as f64;
            let mu = m.mu(dv, ddv);
            assert!(
                (mu - prev).abs() < 5e-4,
                "jump at ({dv}, {ddv}): {prev} → {mu}"
            );
            prev = mu;
        }
    }
    // At the centre of a supported cell the support is 1 and the result the bare network's
    // (up to the rounding of the centre's coordinates).
    let centres = railgrip::identify::support::cell_centres(&m.file, &sup.cells);
    let mut checked = 0;
    for (j, x) in centres.iter().enumerate() {
        if sup.supported(j) && x[0] > 0.2 {
            let w = m.support_weight(x[0], x[1], x[2]).unwrap();
            assert!((w - 1.0).abs() < 1e-12, "{w}");
            assert!((m.mu(x[0], x[1]) - bare.mu(x[0], x[1])).abs() < 1e-12);
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked}");
    // Beyond the domain (inputs the network only sees clamped) the file is its fallback.
    let hi = m.file.inputs[0].domain_max;
    for ddv in [-2.0, 0.5, 2.0] {
        assert_eq!(m.support_weight(2.0 * hi, ddv, f64::NAN), Some(0.0));
        assert_eq!(m.mu(2.0 * hi, ddv), m.mu(3.0 * hi, ddv));
    }
    // μ(0) = 0 and odd, whatever the support.
    for ddv in [-3.0, 0.0, 3.0] {
        assert_eq!(m.mu(0.0, ddv), 0.0);
        assert_eq!(m.mu(-1.3, -ddv), -m.mu(1.3, ddv));
    }
}

/// Samples of a law whose loss branch (rising slip, q > 0) lies above its recovery branch.
fn hysteretic_samples() -> Vec<Sample> {
    let mut rng = railgrip::sim::Rng::new(5);
    (0..40_000)
        .map(|_| {
            let dv = 0.2 + 3.5 * rng.uniform();
            let q = if rng.uniform() < 0.5 { 2.0 } else { -2.0 } * (0.6 + 0.8 * rng.uniform());
            let mu = 0.08 * (1.0 - (-4.0 * dv).exp()) * (1.0 + 0.1 * (q / 2.0).tanh());
            Sample {
                axle: 1,
                dv_mps: dv,
                ddv_mps2: q,
                v_mps: 30.0,
                t_c: f64::NAN,
                mu,
            }
        })
        .collect()
}

#[test]
fn the_audit_fails_a_deliberately_bad_net_and_names_its_cells() {
    let good = golden("synthetic_mlp.json");
    let data = hysteretic_samples();
    let a = audit(&good, &data, 0.6);
    assert!(a.passed, "{:?}", a.failures);
    let (d, m) = (a.hysteresis_data.unwrap(), a.hysteresis_model.unwrap());
    assert!(d > 0.0 && m > 0.0, "{d} {m}");
    // Negative adhesion: the output layer negated.
    let mut bad = good.file.clone();
    for w in bad.layers[1].weights[0].iter_mut() {
        *w = -*w;
    }
    bad.layers[1].biases[0] = -bad.layers[1].biases[0] - 2.0;
    let a = audit(&Model::new(bad).unwrap(), &data, 0.6);
    assert!(!a.passed && a.failing_cells > 10, "{a:?}");
    assert!(
        a.failures
            .iter()
            .any(|f| f.starts_with("cell Δv ") && f.contains("outside [0, 0.6]")),
        "{:?}",
        a.failures
    );
    assert!(a.failures.len() <= railgrip::identify::support::LISTED_FAILURES);
    // Inverted hysteresis: the slip rate's weights negated, so the recovery branch lies above.
    let mut swapped = good.file.clone();
    for row in swapped.layers[0].weights.iter_mut() {
        row[1] = -row[1];
    }
    let s = Model::new(swapped.clone()).unwrap();
    assert!(s.mu(1.5, -2.0) > s.mu(1.5, 2.0));
    let a = audit(&s, &data, 0.6);
    assert!(!a.passed, "{a:?}");
    assert!(
        a.failures.iter().any(|f| f.starts_with("hysteresis:")),
        "{:?}",
        a.failures
    );
    // A ceiling below the network's values fails every supported cell it exceeds.
    let a = audit(&good, &data, 0.01);
    assert!(!a.passed && a.failing_cells > 10);
}

/// The bundled 120 km/h soap runs' estimates.
fn soap_120() -> Vec<railgrip::identify::RunTable> {
    common::bundled_tables(|n| n.starts_with("soap_120kmh") && !n.contains("multirate"))
}

#[test]
fn an_ensemble_is_the_mean_of_its_members_with_their_spread_in_the_file() {
    let tables = soap_120();
    let p = Pipeline::default_uic_z1();
    let mut cfg = p.train.clone();
    cfg.starts = 3;
    cfg.ensemble = 2;
    cfg.epochs = 40;
    let mut t = train_mlp(&tables, &cfg, None).unwrap();
    t.reference_speed_mps = median_speed(&tables);
    assert_eq!(t.members.len(), 2);
    assert_eq!(t.arch.hidden, [2 * cfg.hidden]);
    let creep = creep_spec(&p, t.reference_speed_mps).unwrap();
    let file = mlp_file(&t, creep.clone(), provenance(), None).unwrap();
    let ens = Model::new(file.clone()).unwrap();
    // Each member as its own network (the same file with its layers).
    let member = |i: usize| {
        let mut one = t.clone();
        one.arch.hidden = vec![cfg.hidden];
        one.theta = t.members[i].clone();
        one.members.clear();
        let mut f = mlp_file(&one, creep.clone(), provenance(), None).unwrap();
        f.support = None;
        f.audit = None;
        Model::new(f).unwrap()
    };
    let (a, b) = (member(0), member(1));
    let mut bare = file.clone();
    bare.support = None;
    bare.audit = None;
    let bare = Model::new(bare).unwrap();
    for (dv, ddv) in [(0.8, 1.0), (2.0, -1.5), (3.0, 0.2)] {
        let mean = 0.5 * (a.mu(dv, ddv) + b.mu(dv, ddv));
        assert!((bare.mu(dv, ddv) - mean).abs() < 1e-12, "{dv} {ddv}");
    }
    let sup = file.support.as_ref().unwrap();
    assert_eq!(sup.spread.len(), sup.len());
    assert!(sup.spread.iter().any(|s| *s > 0.0));
    assert!(ens.spread(2.0, 1.0, f64::NAN).unwrap() >= 0.0);
    // The campaign's Polach model as the fallback.
    assert_eq!(sup.fallback, "nearest");
    let polach = golden("synthetic_polach.json");
    let f2 = mlp_file(&t, creep, provenance(), Some(&polach)).unwrap();
    let s2 = f2.support.as_ref().unwrap();
    assert_eq!(s2.fallback, "polach");
    let c = railgrip::identify::support::cell_centres(&f2, &s2.cells);
    let j = (0..s2.len()).find(|&j| !s2.supported(j)).unwrap();
    let want = polach.mu_v(c[j][0], c[j][1], t.reference_speed_mps).abs();
    assert_eq!(s2.fallback_mu[j], want);
}

#[test]
fn bayesian_regularisation_through_the_pipeline_reports_gamma_per_epoch() {
    let tables = soap_120();
    let text = railgrip::config::DEFAULT_PIPELINE_TOML
        .replace("regularisation = \"none\"", "regularisation = \"bayesian\"")
        .replace("epochs = 1000", "epochs = 60");
    let p = Pipeline::from_toml(&text, "bayes.toml").unwrap();
    assert!(p.train.bayesian);
    let t = train_mlp(&tables, &p.train, None).unwrap();
    let n_params = t.theta.len() as f64;
    assert!(t.history.iter().all(|e| e.gamma.is_some()));
    let g = t.history.last().unwrap().gamma.unwrap();
    assert!(g > 1.0 && g < n_params, "γ = {g} of {n_params}");
    // Validation never stops trainbr: it runs its epochs or stops on μ or the gradient.
    assert_ne!(t.stop, railgrip::identify::lm::StopReason::ValidationStop);
    let csv = railgrip::campaign::train::history_csv(&t.history);
    assert!(csv.starts_with("epoch,train_mse,val_mse,mu,grad_norm,gamma\n"));
}

fn railgrip(args: &[&str], cwd: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap()
}

#[test]
fn train_exits_3_and_marks_the_file_when_the_audit_fails() {
    let dir = tempfile::tempdir().unwrap();
    let text = railgrip::config::DEFAULT_PIPELINE_TOML
        .replace("audit_mu_max = 0.6", "audit_mu_max = 0.02")
        .replace("epochs = 1000", "epochs = 30");
    std::fs::write(dir.path().join("strict.toml"), text).unwrap();
    let log = root().join("fixtures/archive/soap_120kmh_p20.csv");
    let o = railgrip(
        &[
            "train",
            log.to_str().unwrap(),
            "--pipeline",
            "strict.toml",
            "--out",
            "m",
            "--quiet",
        ],
        dir.path(),
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(
        o.status.code(),
        Some(3),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        out.contains("AUDIT FAILED") && out.contains("outside [0, 0.02]"),
        "{out}"
    );
    let m = ModelFile::read(&dir.path().join("m/mlp.json")).unwrap();
    assert!(m.audit_failed());
    // The marked file still loads and evaluates.
    assert!(Model::new(m).unwrap().mu(1.0, 0.0).is_finite());
}

/// Scenes on rails of different condition (`level_scale` 0.95 and 1.05): `score` adds the
/// curve view against the law at their mean condition and the condition floor, the exact law
/// at the mean condition against each run's own — high on the slippery run, low on the other,
/// by the condition's share of μ, in the curve view and in replay — and neither where the
/// conditions are equal. The true law's own replay, at each run's condition, is near 0 on both.
/// Each initial speed's hysteresis ratio pools its runs' pairs: between the runs' own.
#[test]
fn score_separates_the_runs_rail_condition_from_the_models_error() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |name: &str| {
        root()
            .join(format!("pipelines/scenes/top_speed/{name}.toml"))
            .to_string_lossy()
            .into_owned()
    };
    let (slippery, good) = (scene("lrq_80kmh_p1"), scene("lrq_80kmh_p23"));
    let model = root().join("models/golden/synthetic_mlp.json");
    let model = model.to_str().unwrap();
    let o = railgrip(&["score", model, &slippery, &good, "--json"], dir.path());
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        (v["mean_level_scale"].as_f64().unwrap() - 1.0).abs() < 1e-12,
        "{v}"
    );
    let runs = v["scenes"].as_array().unwrap();
    let floor =
        |run: &serde_json::Value, k: &str| run["curve_condition_floor"][k].as_f64().unwrap();
    assert_eq!(runs[0]["level_scale"], 0.95);
    // The law at condition 1 is 1/0.95 of the slippery run's and 1/1.05 of the other's.
    assert!(
        floor(&runs[0], "bias") > 0.0 && floor(&runs[1], "bias") < 0.0,
        "{v}"
    );
    for run in runs {
        // |bias| ≤ RMSE ≤ max, and the floor's error is the condition's share of μ (< 6 %
        // of the largest μ of these laws, ~0.13).
        let (b, r, m) = (
            floor(run, "bias"),
            floor(run, "rmse"),
            floor(run, "max_error"),
        );
        assert!(b.abs() <= r && r <= m && m < 0.06 * 0.13 && r > 0.0, "{v}");
        let at_mean = &run["curve_mean_condition"];
        assert!(at_mean["n"] == run["curve"]["n"], "the same cells: {v}");
        // In replay, per band: the same sign as in the curve view, the same samples as the
        // model's replay; the law at the run's own condition an order smaller.
        let bands = |k: &str| run[k].as_array().unwrap().clone();
        let (model, own, floor) = (
            bands("replay"),
            bands("replay_law"),
            bands("replay_condition_floor"),
        );
        assert!(!floor.is_empty() && floor.len() == model.len() && own.len() == model.len());
        let sign = floor_sign(run);
        for ((m, o), f) in model.iter().zip(&own).zip(&floor) {
            assert_eq!(m["stats"]["n"], f["stats"]["n"], "{v}");
            let (o, f) = (
                o["stats"]["bias"].as_f64().unwrap(),
                f["stats"]["bias"].as_f64().unwrap(),
            );
            assert!(f * sign > 0.0015 && o.abs() < 0.3 * f.abs(), "{o} {f}: {v}");
        }
    }
    // The initial speed's hysteresis ratio: the runs' (true, predicted, pairs) pooled, and the
    // mean of their own ratios.
    let row = &v["curve_by_initial_speed"][0];
    let h: Vec<[f64; 3]> = runs
        .iter()
        .map(|r| std::array::from_fn(|i| r["curve_hysteresis"][i].as_f64().unwrap()))
        .collect();
    assert!(h.iter().all(|[t, _, n]| *t >= 0.002 && *n >= 1.0), "{v}");
    let pooled =
        h.iter().map(|[_, p, n]| p * n).sum::<f64>() / h.iter().map(|[t, _, n]| t * n).sum::<f64>();
    let mean = h.iter().map(|[t, p, _]| p / t).sum::<f64>() / h.len() as f64;
    let near = |k: &str, x: f64| (row[k].as_f64().unwrap() - x).abs() < 1e-12;
    assert!(
        near("hysteresis_ratio_pooled", pooled) && near("hysteresis_ratio_run_mean", mean),
        "{row}"
    );
    assert!(
        row["hysteresis_ratio"][0].as_f64().unwrap() < row["hysteresis_ratio"][1].as_f64().unwrap(),
        "{row}"
    );
    for key in [
        "replay_law_by_speed_band",
        "replay_condition_floor_by_speed_band",
    ] {
        assert_eq!(
            v[key].as_array().unwrap().len(),
            2,
            "0–40 and 40–80 km/h: {v}"
        );
    }
    for key in ["curve_at_mean_condition", "curve_condition_floor"] {
        assert_eq!(
            v[key].as_array().unwrap().len(),
            1,
            "one initial speed: {v}"
        );
    }
    let text = railgrip(&["score", model, &slippery, &good], dir.path());
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains("mean rail condition")
            && text.contains("Condition floor")
            && text.contains("Replay of the true law itself")
            && text.contains("Replay of the true law at the runs' mean condition"),
        "{text}"
    );
    // Equal conditions: no such tables.
    let o = railgrip(&["score", model, &good, "--json"], dir.path());
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["mean_level_scale"].is_null(), "{v}");
    assert!(
        v["curve_condition_floor"].as_array().unwrap().is_empty(),
        "{v}"
    );
    assert!(
        v["replay_condition_floor_by_speed_band"]
            .as_array()
            .unwrap()
            .is_empty()
            && !v["replay_law_by_speed_band"].as_array().unwrap().is_empty(),
        "{v}"
    );
}

/// The sign of a run's condition floor: + where the mean condition is better than the run's.
fn floor_sign(run: &serde_json::Value) -> f64 {
    if run["level_scale"].as_f64().unwrap() < 1.0 {
        1.0
    } else {
        -1.0
    }
}

#[test]
fn score_prints_supported_cell_scores_and_exits_3_on_negative_adhesion() {
    let dir = tempfile::tempdir().unwrap();
    let scene = root().join("pipelines/scenes/foreign/table_120kmh_p10.toml");
    let good = root().join("models/golden/synthetic_mlp.json");
    let o = railgrip(
        &[
            "score",
            good.to_str().unwrap(),
            scene.to_str().unwrap(),
            "--json",
        ],
        dir.path(),
    );
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rows = v["scenes"].as_array().unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(v["all"]["scene"], "all");
    assert!(rows[0]["cells"].as_u64().unwrap() > 100 && rows[0]["rmse"].as_f64().unwrap() > 0.0);
    // The curve view at the run's initial speed against the table law, and the replay view
    // per speed band: a run braking from 120 km/h fills the bands below 120 km/h.
    let curve = &rows[0]["curve"];
    assert!(curve["n"].as_u64().unwrap() > 20 && curve["rmse"].as_f64().unwrap() > 0.0);
    assert!(curve["rmse"].as_f64().unwrap() >= curve["bias"].as_f64().unwrap().abs());
    let by_speed = v["curve_by_initial_speed"].as_array().unwrap();
    assert_eq!(by_speed.len(), 1);
    assert_eq!(by_speed[0]["lo_kmh"], 120.0);
    // The same cells at the run's states: as many cells, scored elsewhere.
    let states = v["curve_at_runs_states"].as_array().unwrap();
    assert_eq!(states.len(), 1);
    assert_eq!(states[0]["pooled"]["n"], by_speed[0]["pooled"]["n"]);
    assert_ne!(states[0]["pooled"]["rmse"], by_speed[0]["pooled"]["rmse"]);
    assert_eq!(
        rows[0]["curve_at_states"]["n"].as_u64(),
        curve["n"].as_u64()
    );
    let bands: Vec<f64> = v["replay_by_speed_band"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["lo_kmh"].as_f64().unwrap())
        .collect();
    assert_eq!(bands, [0.0, 40.0, 80.0], "{v}");
    // A network that predicts negative adhesion: exit code 3 and the line that says so.
    let mut bad = ModelFile::read(&good).unwrap();
    for w in bad.layers[1].weights[0].iter_mut() {
        *w = -*w;
    }
    bad.layers[1].biases[0] = -bad.layers[1].biases[0] - 2.0;
    bad.write(&dir.path().join("bad.json")).unwrap();
    let o = railgrip(&["score", "bad.json", scene.to_str().unwrap()], dir.path());
    assert_eq!(o.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&o.stdout).contains("predicts μ < 0"));
    // A missing scene: an error naming it.
    let o = railgrip(&["score", "bad.json", "nowhere.toml"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("nowhere.toml"));
}
