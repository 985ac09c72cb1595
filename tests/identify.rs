//! Identification and model files: the LM solver's hard cases by name, the analytic Jacobian
//! against finite differences, determinism, the model file's round trip, golden file and
//! schema, the C header against the Rust evaluator, and seed 002's figures on simulated runs.

mod common;

use std::path::PathBuf;

use proptest::prelude::*;
use railgrip::config::SplitConfig;
use railgrip::identify::dataset::{Dataset, RunTable};
use railgrip::identify::lm::{self, LeastSquares, LevenbergMarquardt, LmSettings};
use railgrip::identify::mlp::{self, Shape};
use railgrip::identify::InputSet;
use railgrip::identify::TrainedMlp;
use railgrip::identify::{creep_spec, train_on, MlpProblem};
use railgrip::model::{c_header, InputFile, Model, ModelFile, Provenance};
use railgrip::Pipeline;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A smooth synthetic law with a loss/recovery difference: μ(Δv, dΔv/dt).
fn law(dv: f64, ddv: f64) -> f64 {
    let base = 0.09 * (1.0 - (-8.0 * dv).exp()) * (0.45 + 0.55 * (-0.5 * dv).exp());
    base * (1.0 + 0.15 * (ddv / 2.0).tanh())
}

/// Samples of `law` on a deterministic scatter, as one run with axles 2 (train) and 3 (val).
fn synthetic_table(n: usize) -> RunTable {
    let mut rng = railgrip::sim::Rng::new(11);
    let mut t = RunTable {
        name: "synthetic".into(),
        source: "synthetic".into(),
        sha256: "0".repeat(64),
        ..RunTable::default()
    };
    for axle in [2u8, 3] {
        for i in 0..n {
            let dv = 4.0 * rng.uniform();
            let ddv = 6.0 * rng.uniform() - 3.0;
            t.axle.push(axle);
            t.time_s.push(i as f64 / 100.0);
            t.v_mps.push(20.0 + 10.0 * rng.uniform());
            t.dv_mps.push(dv);
            t.ddv_mps2.push(ddv);
            t.mu.push(law(dv, ddv));
        }
    }
    t
}

fn axles_2_3() -> SplitConfig {
    SplitConfig::Axles {
        train: vec![2],
        val: vec![3],
    }
}

fn assert_finite_model(t: &TrainedMlp) {
    assert!(t.theta.iter().all(|v| v.is_finite()), "{:?}", t.theta);
    assert!(t.train_mse.is_finite());
    for e in &t.history {
        assert!(e.train_mse.is_finite() && e.mu.is_finite() && e.grad_norm.is_finite());
    }
    for dv in [-1.0, 0.0, 0.1, 1.0, 5.0] {
        for ddv in [-5.0, 0.0, 5.0] {
            assert!(t.eval_raw(&[dv, ddv, 20.0][..t.arch.inputs]).is_finite());
        }
    }
}

fn quick() -> LmSettings {
    LmSettings {
        epochs: 60,
        ..LmSettings::default()
    }
}

// ------------------------------------------------------------------ the solver's hard cases

#[test]
fn learns_a_smooth_law() {
    let d = Dataset::build(&[synthetic_table(3000)], InputSet::DvDdv, &axles_2_3(), 1).unwrap();
    let t = train_on(&d, 10, 1, LmSettings::default(), None).unwrap();
    assert_finite_model(&t);
    eprintln!(
        "{} epochs ({}), RMSE train {:.2e} val {:.2e}",
        t.history.len(),
        t.stop.text(),
        t.train_mse.sqrt(),
        t.val_mse.sqrt()
    );
    assert!(t.val_mse.sqrt() < 1e-3, "{}", t.val_mse.sqrt());
    // trainlm never accepts a step that raises the training error.
    assert!(t
        .history
        .windows(2)
        .all(|w| w[1].train_mse <= w[0].train_mse));
}

#[test]
fn rank_deficient_jacobian() {
    // Speed as a third input, equal to Δv: two identical input columns make J rank-deficient.
    let mut tab = synthetic_table(500);
    tab.v_mps = tab.dv_mps.clone();
    let d = Dataset::build(&[tab], InputSet::DvDdvV, &axles_2_3(), 1).unwrap();
    let t = train_on(&d, 10, 3, quick(), None).unwrap();
    assert_finite_model(&t);
    assert!(t.train_mse.sqrt() < 0.01);
}

#[test]
fn duplicated_samples() {
    let mut tab = synthetic_table(1);
    for _ in 0..9 {
        let one = synthetic_table(1);
        for k in 0..one.len() {
            tab.push_row(&one, k);
        }
    }
    let d = Dataset::build(&[tab], InputSet::DvDdv, &axles_2_3(), 1).unwrap();
    assert_eq!(d.n_train(), 10);
    let t = train_on(&d, 10, 1, quick(), None).unwrap();
    assert_finite_model(&t);
}

#[test]
fn saturated_neurons() {
    // Start from weights 1000× Nguyen–Widrow: every tanh saturated, their derivatives ~0.
    let d = Dataset::build(&[synthetic_table(500)], InputSet::DvDdv, &axles_2_3(), 1).unwrap();
    let shape = Shape::one(2, 10);
    let mut x = d.train_x.clone();
    let xn = railgrip::identify::MapMinMax::fit(&x, 2);
    xn.apply(&mut x);
    let y = d.train_y.clone();
    let problem = MlpProblem::new(shape, x, y, Vec::new(), Vec::new(), 1.0);
    let theta0: Vec<f64> = mlp::nguyen_widrow(shape, 1)
        .iter()
        .map(|v| v * 1000.0)
        .collect();
    let e0 = problem.sse(&theta0);
    let (solver, problem) = lm::run(problem, LevenbergMarquardt::new(quick()), theta0).unwrap();
    let best = solver.best().unwrap();
    assert!(best.iter().all(|v| v.is_finite()));
    let e1 = problem.sse(best);
    assert!(e1.is_finite() && e1 <= e0, "{e0} → {e1}");
}

#[test]
fn constant_target() {
    let mut tab = synthetic_table(300);
    tab.mu.iter_mut().for_each(|m| *m = 0.05);
    let d = Dataset::build(&[tab], InputSet::DvDdv, &axles_2_3(), 1).unwrap();
    let t = train_on(&d, 10, 1, quick(), None).unwrap();
    assert_finite_model(&t);
    // A constant target passes mapminmax unchanged and is learned.
    assert!(
        (t.eval_raw(&[1.0, 0.0]) - 0.05).abs() < 1e-6,
        "{}",
        t.eval_raw(&[1.0, 0.0])
    );
}

#[test]
fn one_sample() {
    let tab = synthetic_table(1);
    let d = Dataset::build(&[tab], InputSet::DvDdv, &axles_2_3(), 1).unwrap();
    assert_eq!((d.n_train(), d.n_val()), (1, 1));
    let t = train_on(&d, 10, 1, quick(), None).unwrap();
    assert_finite_model(&t);
    // The weights returned are those of the best validation epoch.
    let best = t
        .history
        .iter()
        .map(|e| e.val_mse)
        .fold(f64::INFINITY, f64::min);
    assert!(t.val_mse <= best * (1.0 + 1e-12), "{} vs {best}", t.val_mse);
}

#[test]
fn no_training_samples_is_a_clear_error() {
    let tab = synthetic_table(10);
    let e = Dataset::build(
        &[tab],
        InputSet::DvDdv,
        &SplitConfig::Axles {
            train: vec![4],
            val: vec![3],
        },
        1,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("no valid samples for training") && e.contains("Hint"),
        "{e}"
    );
}

#[test]
fn deterministic_and_independent_of_the_thread_count() {
    let d = Dataset::build(&[synthetic_table(5000)], InputSet::DvDdv, &axles_2_3(), 1).unwrap();
    let a = train_on(&d, 10, 7, quick(), None).unwrap();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = one.install(|| train_on(&d, 10, 7, quick(), None).unwrap());
    assert_eq!(a.theta, b.theta);
    assert_eq!(a.history.len(), b.history.len());
}

/// `[train] starts`: K Nguyen–Widrow starts in parallel, the lowest validation error kept —
/// the same network as training that seed alone, whatever the thread count.
#[test]
fn multi_start_keeps_the_best_start_on_any_thread_count() {
    let table = synthetic_table(3000);
    let mut cfg = Pipeline::default_uic_z1().train.clone();
    cfg.split = axles_2_3();
    cfg.epochs = 40;
    cfg.decimate = 1;
    cfg.seed = 5;
    cfg.starts = 4;
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    let tables = [table];
    let multi = pool(2).install(|| railgrip::identify::train_mlp(&tables, &cfg, None).unwrap());
    let again = pool(1).install(|| railgrip::identify::train_mlp(&tables, &cfg, None).unwrap());
    assert_eq!(multi.theta, again.theta);
    assert_eq!(multi.start_val_mse.len(), 4);
    let singles: Vec<TrainedMlp> = (5..9)
        .map(|seed| {
            let mut c = cfg.clone();
            c.seed = seed;
            c.starts = 1;
            railgrip::identify::train_mlp(&tables, &c, None).unwrap()
        })
        .collect();
    let best = singles
        .iter()
        .min_by(|a, b| a.val_mse.total_cmp(&b.val_mse))
        .unwrap();
    assert_eq!(multi.seed, best.seed);
    assert_eq!(multi.theta, best.theta);
    let vals: Vec<f64> = singles.iter().map(|t| t.val_mse).collect();
    assert_eq!(multi.start_val_mse, vals);
}

/// The same solver trains larger nets: 3 inputs and two hidden layers (P = 455, past
/// `linalg::BLOCKED_FROM`, so the damped solve is faer's blocked Cholesky), bit-identical for
/// one and two threads, and it learns.
#[test]
fn two_hidden_layers_train_deterministically_on_any_thread_count() {
    let shape = Shape {
        inputs: 3,
        hidden: 20,
        hidden2: 17,
    };
    assert_eq!(shape.n_params(), 455);
    let mut rng = railgrip::sim::Rng::new(4);
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for _ in 0..5000 {
        let s = [
            2.0 * rng.uniform() - 1.0,
            2.0 * rng.uniform() - 1.0,
            2.0 * rng.uniform() - 1.0,
        ];
        y.push((2.0 * s[0]).sin() * (1.0 - 0.5 * s[1] * s[1]) + 0.3 * s[2].powi(3));
        x.extend(s);
    }
    let (vx, vy) = (x[..3 * 1000].to_vec(), y[..1000].to_vec());
    let problem = MlpProblem::new(shape, x, y, vx, vy, 1.0);
    let settings = LmSettings {
        epochs: 8,
        ..quick()
    };
    let train = || {
        let (s, _) = lm::run(
            &problem,
            LevenbergMarquardt::new(settings),
            mlp::nguyen_widrow(shape, 2),
        )
        .unwrap();
        let mse: Vec<u64> = s.history().iter().map(|e| e.train_mse.to_bits()).collect();
        (s.best().unwrap().to_vec(), mse)
    };
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    let (a, b) = (pool(1).install(train), pool(2).install(train));
    assert_eq!(a, b);
    let first = f64::from_bits(a.1[0]);
    let last = f64::from_bits(*a.1.last().unwrap());
    assert!(a.1.len() == 8 && last < 0.2 * first, "{first} -> {last}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn analytic_jacobian_matches_finite_differences(
        seed in 0u64..1000,
        hidden in 1usize..13,
        three in proptest::bool::ANY,
        x in proptest::collection::vec(-1.0f64..1.0, 3),
        scale in 0.1f64..3.0,
    ) {
        let shape = Shape::one(if three { 3 } else { 2 }, hidden);
        let theta: Vec<f64> = mlp::nguyen_widrow(shape, seed).iter().map(|v| v * scale).collect();
        let x = &x[..shape.inputs];
        let mut g = vec![0.0; shape.n_params()];
        let y = mlp::forward_grad(shape, &theta, x, &mut g);
        prop_assert!((y - mlp::forward(shape, &theta, x)).abs() < 1e-14);
        for p in 0..shape.n_params() {
            let h = 1e-6 * (1.0 + theta[p].abs());
            let mut tp = theta.clone();
            tp[p] += h;
            let mut tm = theta.clone();
            tm[p] -= h;
            let fd = (mlp::forward(shape, &tp, x) - mlp::forward(shape, &tm, x)) / (2.0 * h);
            prop_assert!((fd - g[p]).abs() < 1e-7 * (1.0 + g[p].abs()), "param {}: {} vs {}", p, fd, g[p]);
        }
    }
}

// ------------------------------------------------------------------ model files

fn synthetic_model() -> ModelFile {
    let d = Dataset::build(&[synthetic_table(800)], InputSet::DvDdv, &axles_2_3(), 1).unwrap();
    let mut t = train_on(&d, 10, 1, quick(), None).unwrap();
    t.reference_speed_mps = 25.0;
    // 1 600 samples over 24 × 24 cells: with 2 samples a cell, about three in four are
    // supported — support and blends both in the file.
    t.occupancy.min_samples = 2;
    // Timings would make the file differ from run to run.
    for e in &mut t.history {
        e.elapsed_s = 0.0;
    }
    let p = Pipeline::default_uic_z1();
    let creep = creep_spec(&p, t.reference_speed_mps).unwrap();
    railgrip::identify::export::mlp_file(
        &t,
        creep,
        Provenance {
            inputs: vec![InputFile {
                path: "synthetic".into(),
                sha256: "0".repeat(64),
            }],
            pipeline: p.source.clone(),
            pipeline_sha256: common::sha256_hex(p.text.as_bytes()),
            seed: 1,
            crate_version: "golden".into(),
            created: "2026-01-01T00:00:00Z".into(),
            generation: None,
            calibration: None,
        },
        None,
    )
    .unwrap()
}

/// Compares `text` with the committed golden file `models/golden/<name>` (numbers to 1e-7
/// relative), rewriting it first when UPDATE_GOLDEN=1.
fn golden_check(name: &str, text: &str) {
    let golden = root().join("models/golden").join(name);
    if std::env::var("UPDATE_GOLDEN").as_deref() == Ok("1") {
        std::fs::create_dir_all(golden.parent().unwrap()).unwrap();
        std::fs::write(&golden, text).unwrap();
    }
    let committed = std::fs::read_to_string(&golden).unwrap_or_else(|_| {
        panic!("models/golden/{name} (refresh with UPDATE_GOLDEN=1 cargo test --test identify)")
    });
    // Trained weights: the last bits follow the CPU's matrix kernels (ARCHITECTURE.md).
    common::assert_same_up_to_rounding(name, text, &committed, 1e-7);
}

#[test]
fn model_file_round_trips_exactly_and_matches_the_golden_file() {
    let m = synthetic_model();
    let text = m.to_json();
    let back = ModelFile::from_json(&text, "mem").unwrap();
    assert_eq!(back, m, "reading back changed a value");
    assert_eq!(back.to_json(), text);
    golden_check("synthetic_mlp.json", &text);
}

fn schema_check(json: &str, what: &str) {
    let schema: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root().join("models/schema/adhesion-model.schema.json")).unwrap(),
    )
    .unwrap();
    let v: serde_json::Value = serde_json::from_str(json).unwrap();
    let validator = jsonschema::validator_for(&schema).unwrap();
    let errors: Vec<String> = validator
        .iter_errors(&v)
        .map(|e| format!("{e} at {}", e.instance_path()))
        .collect();
    assert!(errors.is_empty(), "{what}: {errors:#?}");
}

#[test]
fn model_files_follow_the_schema() {
    schema_check(&synthetic_model().to_json(), "synthetic model");
    let golden = std::fs::read_to_string(root().join("models/golden/synthetic_mlp.json")).unwrap();
    schema_check(&golden, "golden file");
    // And the schema rejects what the reader rejects.
    let mut v: serde_json::Value = serde_json::from_str(&golden).unwrap();
    v["version"] = 4.into();
    let schema: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root().join("models/schema/adhesion-model.schema.json")).unwrap(),
    )
    .unwrap();
    assert!(!jsonschema::is_valid(&schema, &v));
    let e = ModelFile::from_json(&v.to_string(), "v4.json")
        .unwrap_err()
        .to_string();
    assert!(e.contains("v4.json") && e.contains("version 4"), "{e}");
    // A deeper network is version 3: valid as such, refused by both as version 2.
    let deep = deep_model(&synthetic_model(), &[6, 5], 1.0, 1);
    let mut v: serde_json::Value = serde_json::from_str(&deep.to_json()).unwrap();
    assert!(jsonschema::is_valid(&schema, &v));
    v["version"] = 2.into();
    assert!(!jsonschema::is_valid(&schema, &v));
    assert!(ModelFile::from_json(&v.to_string(), "v2.json").is_err());
}

#[test]
fn evaluator_is_continuous_odd_and_clamped() {
    let model = Model::new(synthetic_model()).unwrap();
    let blend = model.file.creep.as_ref().unwrap().blend_mps;
    for ddv in [-2.0, 0.0, 2.0] {
        // Continuous across the blend point and at zero.
        let below = model.mu(blend * (1.0 - 1e-9), ddv);
        let above = model.mu(blend * (1.0 + 1e-9), ddv);
        assert!((below - above).abs() < 1e-8, "{below} {above}");
        assert_eq!(model.mu(0.0, ddv), 0.0);
        assert!(model.mu(1e-9, ddv).abs() < 1e-6);
        // Odd in (Δv, dΔv/dt).
        for dv in [0.05, 0.5, 2.0] {
            assert_eq!(model.mu(-dv, -ddv), -model.mu(dv, ddv));
        }
        // Clamped outside the domain: constant beyond the largest Δv seen.
        let hi = model.file.inputs[0].domain_max;
        assert_eq!(model.mu(hi + 1.0, ddv), model.mu(hi + 50.0, ddv));
        assert!(!model.in_domain(hi + 1.0, ddv, f64::NAN));
        assert!(model.in_domain(1.0, ddv, f64::NAN) && model.in_domain(-1.0, -ddv, f64::NAN));
        assert!(!model.in_domain(1.0, 100.0, f64::NAN));
    }
    // Batch = single.
    let dv = [0.01, 0.3, 1.0, 3.0];
    let ddv = [0.0, 1.0, -1.0, 0.5];
    let mut out = [0.0; 4];
    model.mu_batch(&dv, &ddv, &[], &mut out);
    for i in 0..4 {
        assert_eq!(out[i], model.mu(dv[i], ddv[i]));
    }
    // A long batch takes the vectorised path (AVX-512/AVX2 where the CPU has it): identical
    // to single calls, bit for bit, including mirrored, creep-region, clamped and NaN inputs.
    batch_matches_single_calls(&model, 1003, 17, 9);
    // The network learned the law where there was data.
    assert!((model.mu(1.5, 0.0) - law(1.5, 0.0)).abs() < 2e-3);
}

/// `n` random slips (Δv ∈ [−3, 9] m/s, NaN at `nan_at`) and slip rates (± 8 m/s²): the long
/// batch (vectorised where the CPU can) equals single calls bit for bit — mirrored,
/// creep-region, clamped and NaN inputs included. Returns the inputs.
fn batch_matches_single_calls(
    model: &Model,
    n: usize,
    nan_at: usize,
    seed: u64,
) -> (Vec<f64>, Vec<f64>) {
    let mut rng = railgrip::sim::Rng::new(seed);
    let dv: Vec<f64> = (0..n)
        .map(|i| {
            if i == nan_at {
                f64::NAN
            } else {
                12.0 * rng.uniform() - 3.0
            }
        })
        .collect();
    let ddv: Vec<f64> = (0..n).map(|_| 16.0 * rng.uniform() - 8.0).collect();
    let mut out = vec![0.0; n];
    model.mu_batch(&dv, &ddv, &[], &mut out);
    for i in 0..n {
        let single = model.mu(dv[i], ddv[i]);
        assert!(
            out[i].to_bits() == single.to_bits() || (out[i].is_nan() && single.is_nan()),
            "{i}: {} vs {single}",
            out[i]
        );
    }
    (dv, ddv)
}

/// A C literal for a double (NaN as NAN, ±∞ as ±INFINITY).
fn c_lit(x: f64) -> String {
    if x.is_nan() {
        "NAN".into()
    } else if x.is_infinite() {
        if x > 0.0 { "INFINITY" } else { "-INFINITY" }.into()
    } else {
        format!("{x:?}")
    }
}

/// Compiles `model`'s C header with the system cc (`-std=c99 -O2` and `flags`), evaluates
/// `rg_mu_vt` at every point (Δv, dΔv/dt, v, T), `rg_mu_batch` over the same points (without
/// T) and `rg_mu_batch_t` (with T), and returns the largest difference to the Rust evaluator and the number of
/// values that differ in any bit (NaN = NaN); None when there is no C compiler.
fn c_header_error(model: &Model, points: &[[f64; 4]], flags: &[&str]) -> Option<(f64, usize)> {
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    if std::process::Command::new(&cc)
        .arg("--version")
        .output()
        .is_err()
    {
        // CI installs a C compiler (.ci/run): there a missing one is a failure, not a skip.
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "CI=true but no C compiler ({cc}): .ci/run should have installed gcc"
        );
        eprintln!("SKIPPED: no C compiler ({cc}) found; install gcc or set CC");
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let header = c_header::c_header(&model.file, "rg", "test");
    std::fs::write(dir.path().join("model.h"), header).unwrap();
    let mut c = String::from("#include <stdio.h>\n#include \"model.h\"\nint main(void) {\n");
    for p in points {
        c.push_str(&format!(
            "  printf(\"%.17g\\n\", rg_mu_vt({}, {}, {}, {}));\n",
            c_lit(p[0]),
            c_lit(p[1]),
            c_lit(p[2]),
            c_lit(p[3])
        ));
    }
    let list = |k: usize| {
        points
            .iter()
            .map(|p| c_lit(p[k]))
            .collect::<Vec<_>>()
            .join(", ")
    };
    c.push_str(&format!(
        "  {{ static const double dv[] = {{{}}}; static const double ddv[] = {{{}}}; static const double v[] = {{{}}}; static const double t[] = {{{}}}; static double out[{n}]; int i;\n    rg_mu_batch(dv, ddv, v, out, {n});\n    for (i = 0; i < {n}; ++i) printf(\"%.17g\\n\", out[i]);\n    rg_mu_batch_t(dv, ddv, v, t, out, {n});\n    for (i = 0; i < {n}; ++i) printf(\"%.17g\\n\", out[i]); }}\n",
        list(0),
        list(1),
        list(2),
        list(3),
        n = points.len()
    ));
    c.push_str("  return 0;\n}\n");
    std::fs::write(dir.path().join("main.c"), c).unwrap();
    let exe = dir.path().join("eval");
    let out = std::process::Command::new(&cc)
        .args(["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror"])
        .args(flags)
        .arg("-o")
        .arg(&exe)
        .arg(dir.path().join("main.c"))
        .arg("-lm")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let run = std::process::Command::new(&exe).output().unwrap();
    let text = String::from_utf8(run.stdout).unwrap();
    let values: Vec<f64> = text.lines().map(|l| l.parse().unwrap()).collect();
    assert_eq!(values.len(), 3 * points.len());
    let mut rust: Vec<f64> = points
        .iter()
        .map(|p| model.mu_vt(p[0], p[1], p[2], p[3]))
        .collect();
    rust.extend(points.iter().map(|p| model.mu_v(p[0], p[1], p[2])));
    rust.extend(points.iter().map(|p| model.mu_vt(p[0], p[1], p[2], p[3])));
    let mut worst: f64 = 0.0;
    let mut differ = 0;
    for (r, c) in rust.iter().zip(&values) {
        worst = worst.max((r - c).abs());
        if r.to_bits() != c.to_bits() && !(r.is_nan() && c.is_nan()) {
            differ += 1;
        }
    }
    Some((worst, differ))
}

/// No C-header injection: `railgrip export` copied the model's path into the header
/// comment, so a path holding `*/ int injected_symbol = 1; /*` compiled into the header. Now
/// the comment text is made safe: the header compiles and defines no such symbol.
#[test]
fn a_hostile_model_path_cannot_inject_code_into_the_c_header() {
    let hostile = "models/x*/ int injected_symbol = 1; /*y\\\nz.json";
    for (file, prefix) in [(synthetic_model(), "rg"), (polach_model(true), "rgp")] {
        let header = c_header::c_header(&file, prefix, hostile);
        assert!(!header.contains("*/ int injected_symbol"), "{header}");
        assert!(
            header.contains("int injected_symbol = 1;"),
            "the path stays readable"
        );
        let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
        if std::process::Command::new(&cc)
            .arg("--version")
            .output()
            .is_err()
        {
            assert!(
                std::env::var("CI").as_deref() != Ok("true"),
                "CI=true but no C compiler"
            );
            eprintln!("SKIPPED compiling: no C compiler ({cc})");
            continue;
        }
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("model.h"), &header).unwrap();
        std::fs::write(
            dir.path().join("use.c"),
            format!("#include \"model.h\"\ndouble f(double x) {{ return {prefix}_mu(x, 0.0); }}\n"),
        )
        .unwrap();
        let obj = dir.path().join("use.o");
        let out = std::process::Command::new(&cc)
            .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-c", "-o"])
            .arg(&obj)
            .arg(dir.path().join("use.c"))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        if let Ok(nm) = std::process::Command::new("nm").arg(&obj).output() {
            let syms = String::from_utf8_lossy(&nm.stdout);
            assert!(!syms.contains("injected_symbol"), "{syms}");
        }
    }
}

#[test]
fn c_header_agrees_with_the_rust_evaluator() {
    let model = Model::new(synthetic_model()).unwrap();
    let grid: Vec<[f64; 4]> = (0..=60)
        .flat_map(|i| {
            (0..=10).map(move |j| [-1.0 + i as f64 * 0.1, -5.0 + j as f64, f64::NAN, f64::NAN])
        })
        .collect();
    // The grid crosses the data support: points inside (w = 1), in blends and outside (w = 0).
    let w: Vec<f64> = grid
        .iter()
        .map(|p| model.support_weight(p[0], p[1], p[2]).unwrap())
        .collect();
    assert!(w.contains(&1.0), "inside");
    assert!(w.iter().any(|w| *w > 0.0 && *w < 1.0), "blends");
    assert!(w.contains(&0.0), "outside");
    // As shipped (fma() only where the target has a fast one), and with fma() forced and no
    // other contraction: then the header claims bit-identical results.
    for flags in [&[][..], &["-DRG_EXACT_FMA", "-ffp-contract=off"][..]] {
        if let Some((worst, differ)) = c_header_error(&model, &grid, flags) {
            eprintln!(
                "C header {flags:?} vs Rust: max |Δμ| = {worst:.1e}, {differ} of {} values differ in a bit",
                3 * grid.len()
            );
            assert!(worst <= 1e-12, "{worst}");
            if !flags.is_empty() {
                assert_eq!(differ, 0, "bit-identical with exact fma");
            }
        }
    }
}

// ------------------------------------------------------------------ four inputs: ambient temperature

/// The synthetic law at four ambient temperatures (the level × (1 + 0.006 (20 − T))), one
/// run each with that temperature in its metadata.
fn tables_at_temperatures() -> Vec<RunTable> {
    [-10.0, 0.0, 10.0, 20.0]
        .iter()
        .enumerate()
        .map(|(k, &t_c)| {
            let mut t = synthetic_table(600);
            t.name = format!("synthetic_{k}");
            t.metadata.ambient_temperature_c = Some(t_c);
            for m in &mut t.mu {
                *m *= 1.0 + 0.006 * (20.0 - t_c);
            }
            t
        })
        .collect()
}

/// A four-input network (Δv, dΔv/dt, v, T) with a support grid, trained by `train_mlp`.
fn four_input_model() -> ModelFile {
    let p = Pipeline::default_uic_z1();
    let mut cfg = p.train.clone();
    cfg.inputs = InputSet::DvDdvVT;
    // Four temperature cells: one run each (a temperature between two runs interpolates the
    // support of both).
    cfg.support_cells = vec![4, 4, 2, 4];
    cfg.support_min_samples = 2;
    cfg.epochs = 200;
    let tables = tables_at_temperatures();
    let mut t = railgrip::identify::train_mlp(&tables, &cfg, None).unwrap();
    t.reference_speed_mps = 25.0;
    let creep = creep_spec(&p, t.reference_speed_mps).unwrap();
    let provenance = Provenance {
        inputs: vec![],
        pipeline: p.source.clone(),
        pipeline_sha256: common::sha256_hex(p.text.as_bytes()),
        seed: 1,
        crate_version: "test".into(),
        created: "2026-01-01T00:00:00Z".into(),
        generation: None,
        calibration: None,
    };
    railgrip::identify::export::mlp_file(&t, creep, provenance, None).unwrap()
}

#[test]
fn a_four_input_network_takes_the_ambient_temperature() {
    let file = four_input_model();
    schema_check(&file.to_json(), "four-input model");
    // Also the golden file the evaluator's every-instruction-set test reads (crates/railgrip-model/src/net.rs).
    let mut golden = file.clone();
    for e in &mut golden.history {
        e.elapsed_s = 0.0;
    }
    golden_check("synthetic_mlp_4inputs.json", &golden.to_json());
    assert_eq!(file.input_set(), InputSet::DvDdvVT);
    let creep = file.creep.clone().unwrap();
    // The median training temperature (the runs' samples are equally many: the upper one).
    assert_eq!(creep.reference_temperature_c, Some(10.0));
    let t = &file.inputs[3];
    assert_eq!(
        (t.name.as_str(), t.domain_min, t.domain_max),
        ("ambient_temperature_c", -10.0, 20.0)
    );
    let model = Model::new(file.clone()).unwrap();
    // It learned the level's trend: colder is higher, by about the law's factor.
    let (cold, warm) = (
        model.mu_vt(1.5, 0.5, 25.0, -10.0),
        model.mu_vt(1.5, 0.5, 25.0, 20.0),
    );
    let truth = 1.0 + 0.006 * 30.0;
    assert!(
        (cold / warm - truth).abs() < 0.03,
        "{cold} / {warm} vs {truth}"
    );
    // No temperature: the reference; supported at every run's
    // temperature (the edges included) and between.
    assert_eq!(
        model.mu_v(1.5, 0.5, 25.0),
        model.mu_vt(1.5, 0.5, 25.0, 10.0)
    );
    // Far beyond the coldest run: the fallback (the nearest supported cell's network value).
    let (far, edge) = (
        model.mu_vt(1.5, 0.5, 25.0, -40.0),
        model.mu_vt(1.5, 0.5, 25.0, -10.0),
    );
    assert_eq!(model.support_weight_t(1.5, 0.5, 25.0, -40.0), Some(0.0));
    assert!((far - edge).abs() < 0.05 * edge, "{far} {edge}");
    assert!(!model.in_domain_t(1.5, 0.5, 25.0, -40.0) && model.in_domain_t(1.5, 0.5, 25.0, 0.0));
    for t_c in [-10.0, -5.0, 0.0, 10.0, 15.0, 20.0] {
        let w = model.support_weight_t(1.5, 0.5, 25.0, t_c).unwrap();
        assert!(w > 1.0 - 1e-12, "{t_c}: {w}");
    }
    // Far outside the temperatures seen the support has faded: the fallback alone.
    assert_eq!(model.support_weight_t(1.5, 0.5, 25.0, 60.0), Some(0.0));
    // Batch with temperatures = single calls, bit for bit (vectorised blocks and the tail).
    let mut rng = railgrip::sim::Rng::new(4);
    let n = 203;
    let cols: Vec<Vec<f64>> = [(8.0, -2.0), (12.0, -6.0), (30.0, 5.0), (70.0, -35.0)]
        .iter()
        .map(|&(w, o)| (0..n).map(|_| w * rng.uniform() + o).collect())
        .collect();
    let mut t_col = cols[3].clone();
    t_col[5] = f64::NAN;
    let mut out = vec![0.0; n];
    model.mu_batch_t(&cols[0], &cols[1], &cols[2], &t_col, &mut out);
    for i in 0..n {
        let single = model.mu_vt(cols[0][i], cols[1][i], cols[2][i], t_col[i]);
        assert_eq!(out[i].to_bits(), single.to_bits(), "{i}");
    }
    // The C header, bit for bit with exact fma, across temperatures inside, between, at and
    // beyond the runs', and without one.
    let mut pts = Vec::new();
    for i in 0..=40 {
        for ddv in [-3.0, -0.5, 0.5, 2.5] {
            for t_c in [f64::NAN, -40.0, -10.0, -2.5, 5.0, 12.0, 20.0, 45.0] {
                pts.push([-1.0 + 0.125 * i as f64, ddv, 25.0, t_c]);
            }
        }
    }
    for flags in [&[][..], &["-DRG_EXACT_FMA", "-ffp-contract=off"][..]] {
        if let Some((worst, differ)) = c_header_error(&model, &pts, flags) {
            assert!(worst <= 1e-12, "{worst}");
            if !flags.is_empty() {
                assert_eq!(differ, 0, "bit-identical with exact fma");
            }
        }
    }
}

#[test]
fn four_input_files_and_data_are_checked() {
    // A run without an ambient temperature: the error names it and says what to do.
    let mut tables = tables_at_temperatures();
    tables[1].source = "runs/cold_run.csv".into();
    tables[1].metadata.ambient_temperature_c = None;
    let e = Dataset::build(&tables, InputSet::DvDdvVT, &axles_2_3(), 1)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("runs/cold_run.csv") && e.contains("ambient_temperature_c"),
        "{e}"
    );
    // A file without its reference temperature, or with one it does not use, or a version-1
    // file with four inputs.
    let good = four_input_model();
    let mut bad = good.clone();
    bad.creep.as_mut().unwrap().reference_temperature_c = None;
    let e = Model::new(bad).unwrap_err().to_string();
    assert!(e.contains("reference_temperature_c"), "{e}");
    let mut two = synthetic_model();
    two.creep.as_mut().unwrap().reference_temperature_c = Some(5.0);
    let e = Model::new(two).unwrap_err().to_string();
    assert!(e.contains("reference_temperature_c"), "{e}");
    let mut v1 = good.clone();
    v1.version = 1;
    v1.support = None;
    v1.audit = None;
    let e = Model::new(v1).unwrap_err().to_string();
    assert!(e.contains("version 1"), "{e}");
    // Inputs in another order are not a known set.
    let mut swapped = good;
    swapped.inputs.swap(2, 3);
    let e = Model::new(swapped).unwrap_err().to_string();
    assert!(e.contains("ambient_temperature_c"), "{e}");
}

// ------------------------------------------------------------------ Polach model files

/// The provenance of the synthetic Polach model files (fixed, so their bytes are).
fn polach_provenance() -> railgrip::model::Provenance {
    railgrip::model::Provenance {
        inputs: vec![],
        pipeline: "uic_z1.toml".into(),
        pipeline_sha256: "0".repeat(64),
        seed: 0,
        crate_version: "0.1.0".into(),
        created: "2026-01-01T00:00:00Z".into(),
        generation: None,
        calibration: None,
    }
}

/// A Polach model file with a temperature law over −20 … +20 °C.
fn polach_model(with_temperature: bool) -> ModelFile {
    use railgrip::identify::polach::{PolachFit, TemperatureFit};
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    let fit = PolachFit {
        group: "all runs".into(),
        mu0: 0.12,
        a_ratio: 0.35,
        b_s_per_m: 0.5,
        k_a: 0.15,
        k_s: 0.05,
        se: [0.001, 0.01, f64::INFINITY, 0.003, 0.001],
        status: [railgrip::identify::polach::ParamStatus::Estimated; 5],
        notes: vec![],
        profiles: vec![],
        samples: 4000,
        effective_samples: 400.0,
        rmse: 0.002,
        ambient_temperature_c: None,
        iterations: 12,
        stop_reason: "minimum gradient reached".into(),
    };
    // μ0(T) linear, k(T) quadratic; the reference temperature 0 °C gives the base values
    // (0.12, 0.15, 0.05) of `fit`.
    let t = TemperatureFit {
        mu0_degree: 1,
        k_degree: 2,
        speed: None,
        mu0: vec![0.12, -0.0005],
        k_a: vec![0.15, -0.002, 1e-5],
        k_s: vec![0.05, -0.0005, 0.0],
        a_ratio: 0.35,
        b_s_per_m: 0.5,
        se: [f64::NAN, 0.01, f64::INFINITY, f64::NAN, f64::NAN],
        fitted_range_c: (-20.0, 20.0),
        reference_temperature_c: 0.0,
        samples: 4000,
        effective_samples: 400.0,
        criterion: "BIC".into(),
        candidates: vec![],
        residuals: vec![],
        excluded: vec![],
        notes: vec![],
        creepage_speed_mps: None,
    };
    railgrip::identify::export::polach_file(
        &fit,
        &patch,
        q,
        with_temperature.then_some(&t),
        (0.01, 4.5),
        (3.0, 44.0),
        25.0,
        None,
        polach_provenance(),
    )
    .unwrap()
}

#[test]
fn polach_model_files_evaluate_the_contact_librarys_law_and_round_trip() {
    use railgrip::contact::polach::{polach, PolachParams};
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    golden_check("synthetic_polach.json", &polach_model(true).to_json());
    // The speed law's section is in the schema too.
    schema_check(
        &with_speed_law(polach_model(true), "polynomial", &[-0.3, -0.1]).to_json(),
        "Polach model file with a speed law",
    );
    for with_t in [false, true] {
        let file = polach_model(with_t);
        schema_check(&file.to_json(), "Polach model file");
        let back = ModelFile::from_json(&file.to_json(), "p.json").unwrap();
        assert_eq!(back, file);
        assert_eq!(back.to_json(), file.to_json());
        let model = Model::new(file).unwrap();
        let base = PolachParams {
            mu0: 0.12,
            a_ratio: 0.35,
            b_s_per_m: 0.5,
            k_a: 0.15,
            k_s: 0.05,
        };
        let mut worst: f64 = 0.0;
        for i in 0..200 {
            let dv = -5.0 + 0.05 * i as f64 + 0.001;
            for v in [0.5, 3.0, 20.0, 44.0, 60.0] {
                let want = polach(&patch, &base, q, v, dv, 0.0).unwrap().fx_n / q;
                let got = model.mu_v(dv, 0.7, v);
                worst = worst.max(((got - want) / want).abs());
                // dΔv/dt is not an input of this law.
                assert_eq!(got, model.mu_v(dv, -3.0, v));
            }
        }
        assert!(
            worst < 1e-13,
            "relative difference to contact::polach {worst:e}"
        );
        // Zero slip, NaN speed (→ reference speed), standstill (→ the speed floor).
        assert_eq!(model.mu_v(0.0, 0.0, 30.0), 0.0);
        assert_eq!(model.mu(1.0, 0.0), model.mu_v(1.0, 0.0, 25.0));
        assert!(model.mu_v(1.0, 0.0, 0.0).is_finite());
        assert_eq!(model.mu_v(1.0, 0.0, 0.0), model.mu_v(1.0, 0.0, 0.1));
        assert!(model.mu_v(f64::NAN, 0.0, 30.0).is_nan());
        assert!(model.in_domain(1.0, 0.0, 30.0) && !model.in_domain(1.0, 0.0, 50.0));
        if with_t {
            // μ0(T), k(T) replace μ0, k_A, k_S; T is clamped to the fitted range; NaN → the base
            // values (the law at its reference temperature).
            let at = |t: f64| {
                let (ka, ks) = (0.15 - 0.002 * t + 1e-5 * t * t, 0.05 - 0.0005 * t);
                polach(
                    &patch,
                    &PolachParams {
                        mu0: 0.12 - 0.0005 * t,
                        k_a: ka,
                        k_s: ks,
                        ..base
                    },
                    q,
                    30.0,
                    1.5,
                    0.0,
                )
                .unwrap()
                .fx_n
                    / q
            };
            for t in [-20.0, -5.0, 0.0, 13.0, 20.0] {
                let got = model.mu_vt(1.5, 0.0, 30.0, t);
                assert!(((got - at(t)) / at(t)).abs() < 1e-13, "{t}");
                let fixed = model.at_temperature(t).unwrap();
                assert!(((fixed.mu_v(1.5, 0.0, 30.0) - got) / got).abs() < 1e-15);
            }
            assert_eq!(
                model.mu_vt(1.5, 0.0, 30.0, -40.0),
                model.mu_vt(1.5, 0.0, 30.0, -20.0)
            );
            assert_eq!(
                model.mu_vt(1.5, 0.0, 30.0, f64::NAN),
                model.mu_v(1.5, 0.0, 30.0)
            );
            let e = model.at_temperature(35.0).unwrap_err().to_string();
            assert!(e.contains("outside the range") && e.contains("20"), "{e}");
            assert!(model.mu_vt(1.5, 0.0, 30.0, -20.0) > model.mu_vt(1.5, 0.0, 30.0, 20.0));
        } else {
            let e = model.at_temperature(0.0).unwrap_err().to_string();
            assert!(e.contains("no temperature law"), "{e}");
        }
    }
    // A network has no temperature law either.
    let e = Model::new(synthetic_model())
        .unwrap()
        .at_temperature(0.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no temperature law"), "{e}");
}

/// `good` (a model file's JSON) edited by `edit` is refused at load by an error naming `file`
/// and containing `needle`.
fn assert_refused(good: &str, file: &str, edit: &dyn Fn(&mut serde_json::Value), needle: &str) {
    let mut v: serde_json::Value = serde_json::from_str(good).unwrap();
    edit(&mut v);
    let e = ModelFile::from_json(&v.to_string(), file)
        .unwrap_err()
        .to_string();
    assert!(e.contains(file) && e.contains(needle), "{needle}: {e}");
}

#[test]
fn polach_model_files_reject_what_they_cannot_evaluate() {
    let good = polach_model(true).to_json();
    let bad = |edit: &dyn Fn(&mut serde_json::Value), needle: &str| {
        assert_refused(&good, "bad.polach.json", edit, needle)
    };
    // k_A(T) leaves (0, 1] inside the fitted range.
    bad(
        &|v| v["polach"]["temperature"]["k_a"] = serde_json::json!([0.15, 0.0, 0.01]),
        "k_A",
    );
    bad(&|v| v["polach"]["k_s"] = 0.5.into(), "k_S");
    // A residual network's law section belongs to networks.
    bad(&|v| v["base"] = v["polach"].clone(), "\"base\" section");
    bad(&|v| v["polach"]["patch"]["c11"] = (-1.0).into(), "c11");
    bad(
        &|v| {
            v["polach"].as_object_mut().unwrap().remove("temperature");
        },
        "temperature input goes with a temperature law",
    );
    bad(&|v| v["outside_domain"] = "clamp".into(), "\"law\"");
    // Free text in a unit once reached the C header unescaped; units are the
    // inputs' own.
    bad(
        &|v| v["inputs"][0]["unit"] = "m/s */ int injected_symbol = 1; /*".into(),
        "the unit of dv_mps is \"m/s\"",
    );
    bad(&|v| v["output"]["unit"] = "N".into(), "\"mu\" in \"1\"");
    // No model file that evaluates to NaN/±∞ loads: a wheel load of 5e-324
    // (finite, valid on its own) makes μ NaN; 10⁶ k(T) coefficients took seconds to check.
    bad(
        &|v| v["polach"]["wheel_load_n"] = 5e-324.into(),
        "a model must be finite there",
    );
    bad(
        &|v| v["polach"]["temperature"]["k_a"] = serde_json::json!(vec![0.0; 1_000_000]),
        "at most 11",
    );
    bad(
        &|v| {
            v.as_object_mut().unwrap().remove("polach");
        },
        "needs a \"polach\" section",
    );
}

/// No model file that evaluates to NaN/±∞ loads: networks whose constants are
/// finite but extreme (weights 1e308, an output range of ±1e308) or whose output range is
/// reversed are refused at load, naming the file and what is wrong.
#[test]
fn network_files_that_would_evaluate_to_nan_are_refused() {
    let good = synthetic_model().to_json();
    let bad = |edit: &dyn Fn(&mut serde_json::Value), needle: &str| {
        assert_refused(&good, "hostile.json", edit, needle)
    };
    bad(
        &|v| {
            v["output"]["norm_min"] = (-1e308).into();
            v["output"]["norm_max"] = 1e308.into();
        },
        "output.norm_min = -1e308 is beyond ±1e3",
    );
    bad(
        &|v| {
            fn huge(x: &mut serde_json::Value) {
                match x {
                    serde_json::Value::Number(_) => *x = 1e308.into(),
                    serde_json::Value::Array(a) => a.iter_mut().for_each(huge),
                    _ => {}
                }
            }
            for l in v["layers"].as_array_mut().unwrap() {
                huge(&mut l["weights"]);
            }
        },
        "layers[0].weights[0][0] = 1e308 is beyond ±1e8",
    );
    bad(
        &|v| v["creep"]["wheel_load_n"] = 5e-324.into(),
        "creep.wheel_load_n = 5e-324 N: a wheel load below 1 N",
    );
    bad(
        &|v| {
            v["inputs"][0]["norm_min"] = 0.0.into();
            v["inputs"][0]["norm_max"] = 1e-310.into();
        },
        "normalisation range is so narrow that its gain overflows",
    );
    // Within the limits, a weight of output magnitude that saturates every neuron still gives
    // finite μ on the whole domain and loads; its header compiles and agrees with Rust.
    let mut v: serde_json::Value = serde_json::from_str(&good).unwrap();
    v["layers"][0]["weights"][0][0] = 9.9e7.into();
    v["layers"][0]["biases"][1] = 5e-324.into();
    let edge = ModelFile::from_json(&v.to_string(), "edge.json").unwrap();
    let model = Model::new(edge).unwrap();
    let pts: Vec<[f64; 4]> = (0..50)
        .map(|i| [-3.0 + 0.12 * i as f64, 0.5, 0.0, 0.0])
        .collect();
    if let Some((worst, _)) = c_header_error(&model, &pts, &[]) {
        assert!(worst <= 1e-12, "{worst}");
    }
    bad(
        &|v| {
            v["output"]["norm_min"] = 0.5.into();
            v["output"]["norm_max"] = 0.1.into();
        },
        "must be below output.norm_max",
    );
    // The good file still loads.
    assert!(ModelFile::from_json(&good, "good.json").is_ok());
}

/// `polach_model` with μ0's speed law `form` and coefficients over its fitted speeds.
fn with_speed_law(mut file: ModelFile, form: &str, coefficients: &[f64]) -> ModelFile {
    let v = &file.inputs[1];
    let range = [v.domain_min, v.domain_max];
    file.polach.as_mut().unwrap().speed = Some(railgrip::model::polach::SpeedSpec {
        form: form.into(),
        coefficients: coefficients.to_vec(),
        fitted_range_mps: range,
    });
    file
}

#[test]
fn polach_speed_laws_scale_mu0_and_are_checked() {
    use railgrip::model::polach::CURTIUS_KNIFFLER_SPEED_MPS as VC;
    let base = Model::new(polach_model(true)).unwrap();
    let poly = Model::new(with_speed_law(
        polach_model(true),
        "polynomial",
        &[-0.3, -0.1],
    ))
    .unwrap();
    let ck = Model::new(with_speed_law(
        polach_model(false),
        "curtius_kniffler",
        &[0.6],
    ))
    .unwrap();
    let plain = Model::new(polach_model(false)).unwrap();
    // At the reference speed (25 m/s) g = 1: the same μ as without the law.
    for dv in [0.2, 1.0, 3.0] {
        for t in [f64::NAN, -10.0, 15.0] {
            assert_eq!(poly.mu_vt(dv, 0.0, 25.0, t), base.mu_vt(dv, 0.0, 25.0, t));
        }
    }
    // Elsewhere μ0 × g(v): at large slip μ ≈ μ_w ∝ μ0 (the creep term saturates), so the
    // ratio of μ with and without the law tends to g(v).
    let g_poly = |v: f64| {
        let u = v / 25.0 - 1.0;
        1.0 + u * (-0.3 + u * -0.1)
    };
    let g_ck = |v: f64| 1.0 + 0.6 * ((25.0 + VC) / (v + VC) - 1.0);
    for v in [5.0, 15.0, 40.0] {
        let r = poly.mu_vt(4.0, 0.0, v, 0.0) / base.mu_vt(4.0, 0.0, v, 0.0);
        assert!(
            (r / g_poly(v) - 1.0).abs() < 0.02,
            "{v}: {r} vs {}",
            g_poly(v)
        );
        let r = ck.mu_vt(4.0, 0.0, v, f64::NAN) / plain.mu_vt(4.0, 0.0, v, f64::NAN);
        assert!((r / g_ck(v) - 1.0).abs() < 0.02, "{v}: {r} vs {}", g_ck(v));
    }
    // The level falls with speed for these coefficients; clamped beyond the fitted speeds.
    assert!(poly.mu_vt(4.0, 0.0, 40.0, 0.0) < poly.mu_vt(4.0, 0.0, 10.0, 0.0));
    let at = |m: &Model, v: f64| m.mu_vt(4.0, 0.0, v, 0.0) / base.mu_vt(4.0, 0.0, v, 0.0);
    assert!((at(&poly, 60.0) - at(&poly, 44.0)).abs() < 0.01);
    // Checks: unknown form, wrong count, a factor leaving its bounds, range ≠ the v domain.
    let good = with_speed_law(polach_model(true), "polynomial", &[-0.3]).to_json();
    let bad = |edit: &dyn Fn(&mut serde_json::Value), needle: &str| {
        assert_refused(&good, "bad.polach.json", edit, needle)
    };
    bad(
        &|v| v["polach"]["speed"]["form"] = "cubic".into(),
        "curtius_kniffler",
    );
    bad(
        &|v| v["polach"]["speed"]["coefficients"] = serde_json::json!([0.1, 0.1, 0.1, 0.1]),
        "coefficients",
    );
    bad(
        &|v| {
            v["polach"]["speed"]["form"] = "curtius_kniffler".into();
            v["polach"]["speed"]["coefficients"] = serde_json::json!([0.1, 0.1]);
        },
        "curtius_kniffler 1",
    );
    bad(
        &|v| v["polach"]["speed"]["coefficients"] = serde_json::json!([-20.0]),
        "speed factor",
    );
    bad(
        &|v| v["polach"]["speed"]["fitted_range_mps"] = serde_json::json!([1.0, 44.0]),
        "fitted_range_mps",
    );
}

#[test]
fn polach_c_header_agrees_with_the_rust_evaluator() {
    let files = [
        ("plain", polach_model(false)),
        ("k(T)", polach_model(true)),
        (
            "k(T), μ0(v) polynomial",
            with_speed_law(polach_model(true), "polynomial", &[-0.3, -0.1, 0.02]),
        ),
        (
            "μ0(v) Curtius–Kniffler",
            with_speed_law(polach_model(false), "curtius_kniffler", &[0.6]),
        ),
        ("k(T), μ0(v), creepage at a fixed speed", {
            let mut f = with_speed_law(polach_model(true), "polynomial", &[-0.3, -0.1]);
            f.polach.as_mut().unwrap().creepage_speed_mps = Some(17.5);
            f
        }),
    ];
    for (with_t, file) in files {
        let model = Model::new(file).unwrap();
        let mut pts = Vec::new();
        for i in 0..=80 {
            let dv = -4.0 + 0.1 * i as f64;
            for v in [f64::NAN, 0.0, 0.05, 2.0, 30.0, 80.0] {
                for t in [f64::NAN, -30.0, -20.0, 0.0, 7.5, 20.0, 40.0] {
                    pts.push([dv, 0.3, v, t]);
                }
            }
        }
        pts.push([f64::NAN, 0.0, 30.0, 0.0]);
        pts.push([1.0, f64::INFINITY, 30.0, 0.0]);
        if let Some((worst, _)) = c_header_error(&model, &pts, &[]) {
            eprintln!(
                "Polach C header ({with_t}) vs Rust: max |Δμ| = {worst:.1e} over {} points",
                pts.len()
            );
            assert!(worst <= 1e-12, "{worst}");
        }
    }
}

/// The slip-velocity form: the creepage taken at the file's `creepage_speed_mps` rather than at
/// the rolling speed. Without a speed law μ(w) is then the same at every speed, and it is the
/// rolling form's μ at that speed; a non-positive speed is refused.
#[test]
fn polach_creepage_at_a_fixed_speed_gives_the_same_curve_at_every_speed() {
    let rolling = polach_model(false);
    let mut fixed = rolling.clone();
    fixed.polach.as_mut().unwrap().creepage_speed_mps = Some(20.0);
    schema_check(
        &fixed.to_json(),
        "Polach model file with a fixed creepage speed",
    );
    let back = ModelFile::from_json(&fixed.to_json(), "f.json").unwrap();
    assert_eq!(back, fixed);
    // A file without the field is unchanged by it (older files and rolling fits).
    assert!(!rolling.to_json().contains("creepage_speed_mps"));
    let (r, f) = (
        Model::new(rolling).unwrap(),
        Model::new(fixed.clone()).unwrap(),
    );
    for dv in [0.05, 0.3, 1.0, 4.0, -0.7] {
        let at_vs = r.mu_vt(dv, 0.0, 20.0, f64::NAN);
        for v in [3.0, 20.0, 44.0, 80.0] {
            assert_eq!(f.mu_vt(dv, 0.0, v, f64::NAN), at_vs, "dv {dv}, v {v}");
        }
    }
    // The rolling form's creep slope falls with speed; the fixed one's does not.
    assert!(r.mu_vt(0.1, 0.0, 40.0, f64::NAN) < 0.6 * r.mu_vt(0.1, 0.0, 10.0, f64::NAN));
    let good = fixed.to_json();
    for x in [0.0, -5.0] {
        assert_refused(
            &good,
            "bad.polach.json",
            &|v| v["polach"]["creepage_speed_mps"] = x.into(),
            "creepage_speed_mps",
        );
    }
}

// ------------------------------------------------------------------ residual (grey-box) networks

/// The synthetic network as a residual over a Polach law with k(T) and a Curtius–Kniffler speed
/// law (the law Polach files are tested with), falling back to the law outside its support.
fn residual_model() -> (ModelFile, ModelFile) {
    let mut law = with_speed_law(polach_model(true), "curtius_kniffler", &[0.6]);
    // The law's k_A at 0 °C away from the file's base k_A: a call without a temperature must
    // take the base values in Rust and in C alike (not the law at 0 °C).
    let spec = law.polach.as_mut().unwrap();
    spec.temperature.as_mut().unwrap().k_a[0] += 0.004;
    let base_ka = spec.k_a;
    let t = spec.temperature.as_ref().unwrap();
    assert!(
        (t.k_a[0] - base_ka).abs() > 1e-3,
        "the law at 0 °C differs from its base"
    );
    let mut f = synthetic_model();
    f.base = law.polach.clone();
    let s = f.support.as_mut().unwrap();
    s.fallback = "law".into();
    s.fallback_mu = vec![0.0; s.fallback_mu.len()];
    (f, law)
}

/// Points over the slip plane (both signs, the creep region, inside, across and outside the
/// support) at several speeds and temperatures (NaN: the references).
fn residual_points() -> Vec<[f64; 4]> {
    let mut pts = Vec::new();
    for i in 0..=40 {
        let dv = -4.0 + 0.2 * i as f64;
        for ddv in [-6.0, -1.0, 0.0, 0.7, 5.0] {
            for (v, t) in [
                (f64::NAN, f64::NAN),
                (12.0, -10.0),
                (30.0, 7.5),
                (55.0, 20.0),
            ] {
                pts.push([dv, ddv, v, t]);
            }
        }
    }
    pts.push([f64::NAN, 0.0, 30.0, 0.0]);
    pts
}

/// A residual network is its law plus the network before the creep region (seed 002 eq. 6–8
/// apply to the sum), odd in the slip like every model, where the support is 0 the law alone
/// (`fallback = "law"`) or the law plus the held residual (`"law_held"`), and law + network
/// where it is 1; the batch path and the C header give the same bits.
#[test]
fn residual_networks_add_their_law_and_fall_back_to_it() {
    let (file, law_file) = residual_model();
    check_residual(&file, &law_file, Some(0.0));
    // A held residual, the same everywhere: outside the data the law plus it.
    let mut held = file.clone();
    let s = held.support.as_mut().unwrap();
    s.fallback = "law_held".into();
    s.fallback_mu.fill(0.003);
    check_residual(&held, &law_file, Some(0.003));
    // A held residual that varies from cell to cell and changes sign: Rust's batch path and
    // the C header interpolate it as the single calls do.
    let s = held.support.as_mut().unwrap();
    for (j, f) in s.fallback_mu.iter_mut().enumerate() {
        *f = 0.002 * ((j % 7) as f64 - 3.0);
    }
    check_residual(&held, &law_file, None);
}

/// [`residual_networks_add_their_law_and_fall_back_to_it`] for one file: where the support
/// is 0, μ is the law plus `held` (when given, a residual the same in every cell).
fn check_residual(file: &ModelFile, law_file: &ModelFile, held: Option<f64>) {
    file.check().unwrap();
    let text = file.to_json();
    schema_check(&text, "residual network");
    let back = ModelFile::from_json(&text, "residual").unwrap();
    assert_eq!(&back, file, "JSON round trip");
    let model = Model::new(back).unwrap();
    let law = Model::new(law_file.clone()).unwrap();
    let plain = Model::new(synthetic_model()).unwrap();
    let blend = file.creep.as_ref().unwrap().blend_mps;
    let pts = residual_points();
    let (mut outside, mut inside) = (0, 0);
    for p in &pts {
        let [dv, ddv, v, t] = *p;
        let mu = model.mu_vt(dv, ddv, v, t);
        if !dv.is_finite() {
            assert!(mu.is_nan());
            continue;
        }
        assert!(mu.is_finite(), "{p:?}");
        assert_eq!(model.mu_vt(-dv, -ddv, v, t), -mu, "odd at {p:?}");
        if dv.abs() < blend || !v.is_finite() {
            continue;
        }
        match model.support_weight_t(dv, ddv, v, t) {
            Some(0.0) => {
                outside += 1;
                let b = law.mu_vt(dv, ddv, v, t);
                match held {
                    Some(0.0) => assert_eq!(mu, b, "the law alone at {p:?}"),
                    Some(h) => assert!(
                        (mu - (b + h.copysign(dv))).abs() <= 1e-15,
                        "the law plus the held residual at {p:?}: {mu} vs {}",
                        b + h.copysign(dv)
                    ),
                    None => {}
                }
            }
            Some(1.0) => {
                inside += 1;
                let n = plain.mu_vt(dv, ddv, v, t);
                let b = law.mu_vt(dv, ddv, v, t);
                assert!(
                    (mu - (n + b)).abs() <= 1e-15,
                    "law + network at {p:?}: {mu} vs {}",
                    n + b
                );
            }
            _ => {}
        }
    }
    assert!(
        outside > 10 && inside > 10,
        "{outside} outside, {inside} inside"
    );
    // The batch path with speeds and temperatures, lane by lane the single call's bits.
    let col = |k: usize| pts.iter().map(|p| p[k]).collect::<Vec<f64>>();
    let mut out = vec![0.0; pts.len()];
    model.mu_batch_t(&col(0), &col(1), &col(2), &col(3), &mut out);
    for (p, o) in pts.iter().zip(&out) {
        let single = model.mu_vt(p[0], p[1], p[2], p[3]);
        assert!(
            o.to_bits() == single.to_bits() || (o.is_nan() && single.is_nan()),
            "{p:?}"
        );
    }
    batch_matches_single_calls(&model, 301, 7, 11);
    for flags in [&[][..], &["-DRG_EXACT_FMA", "-ffp-contract=off"][..]] {
        if let Some((worst, differ)) = c_header_error(&model, &pts, flags) {
            eprintln!(
                "residual C header {flags:?} vs Rust: max |Δμ| = {worst:.1e}, {differ} differ"
            );
            assert!(worst <= 1e-12, "{worst}");
            if !flags.is_empty() {
                assert_eq!(differ, 0, "bit-identical with exact fma");
            }
        }
    }
}

/// What a residual network file cannot be: a law fallback without a law (held or not), a
/// `law` fallback with a non-zero residual, a law outside Polach's domain.
#[test]
fn residual_network_files_reject_what_they_cannot_evaluate() {
    let good = residual_model().0.to_json();
    let bad = |edit: &dyn Fn(&mut serde_json::Value), needle: &str| {
        assert_refused(&good, "bad.residual.json", edit, needle)
    };
    bad(
        &|v| {
            v.as_object_mut().unwrap().remove("base");
        },
        "goes with a \"base\"",
    );
    bad(
        &|v| v["support"]["fallback"] = "polach".into(),
        "goes with a \"base\"",
    );
    bad(
        &|v| v["support"]["fallback_mu"][0] = 0.1.into(),
        "needs every fallback_mu 0",
    );
    // A held residual needs a law to be held on, and a plain network has none.
    bad(
        &|v| {
            v["support"]["fallback"] = "law_held".into();
            v.as_object_mut().unwrap().remove("base");
        },
        "goes with a \"base\"",
    );
    bad(&|v| v["base"]["mu0"] = 2.0.into(), "base:");
    bad(
        &|v| v["base"]["speed"]["coefficients"] = serde_json::json!([40.0]),
        "base: polach.speed",
    );
}

// ------------------------------------------------------------------ seed 002 on simulated runs

fn archive_tables(p: &Pipeline) -> Vec<RunTable> {
    let runs = [
        "soap_120kmh_p20.csv",
        "soap_120kmh_0c.csv",
        "soap_120kmh_m20.csv",
        "soap_160kmh_p20.csv",
        "soap_160kmh_0c.mcap",
        "soap_160kmh_m20.mcap",
    ];
    runs.iter()
        .map(|r| {
            let path = root().join("fixtures/archive").join(r);
            let log = railgrip::ingest_file(&path, p).unwrap();
            let e = railgrip::estimate::estimate(&log, p).unwrap();
            RunTable::from_estimates(r, &path.display().to_string(), "", &e)
        })
        .collect()
}

/// Truth μ at the estimate's samples of one axle of one run (aligned by time).
fn truth_mu(run: &str, axle: u8, times: &[f64]) -> Vec<f64> {
    let path = root().join(format!("fixtures/archive/{run}.truth.parquet"));
    let c = common::parquet_columns(&path, &["time_s", "axle", "mu"]);
    let (t, a, mu) = (&c[0], &c[1], &c[2]);
    let t0 = t[0];
    let per: Vec<f64> = (0..t.len())
        .filter(|&i| a[i] == axle as f64)
        .map(|i| mu[i])
        .collect();
    times
        .iter()
        .map(|x| per[(((x - t0) * 417.0).round() as usize).min(per.len() - 1)])
        .collect()
}

#[test]
fn seed002_figures_on_simulated_runs() {
    let p = Pipeline::default_uic_z1();
    let tables = archive_tables(&p);
    let trained = railgrip::identify::train_mlp(&tables, &p.train, None).unwrap();
    let h = &trained.history;
    eprintln!(
        "{} epochs ({}), RMSE train {:.5} val {:.5}",
        h.len(),
        trained.stop.text(),
        trained.train_mse.sqrt(),
        trained.val_mse.sqrt()
    );
    // Fig. 9: the validation error falls with the training error and stays close to it.
    assert!(h.len() >= 5);
    assert!(h.last().unwrap().train_mse < 0.5 * h[0].train_mse);
    assert!(trained.val_mse < 0.5 * h[0].val_mse);
    assert!(
        trained.val_mse < 2.0 * trained.train_mse,
        "{} vs {}",
        trained.val_mse,
        trained.train_mse
    );
    // Fig. 10: on validation data (axle 3) the network follows the estimated μ.
    let mut model_t = trained.clone();
    model_t.reference_speed_mps = railgrip::identify::median_speed(&tables);
    let creep = creep_spec(&p, model_t.reference_speed_mps).unwrap();
    let file = railgrip::identify::export::mlp_file(
        &model_t,
        creep,
        Provenance {
            inputs: vec![],
            pipeline: p.source.clone(),
            pipeline_sha256: "0".repeat(64),
            seed: 1,
            crate_version: "test".into(),
            created: "2026-01-01T00:00:00Z".into(),
            generation: None,
            calibration: None,
        },
        None,
    )
    .unwrap();
    let model = Model::new(file).unwrap();
    let (mut se_est, mut se_truth, mut var, mut n) = (0.0, 0.0, 0.0, 0usize);
    for t in &tables {
        let idx: Vec<usize> = (0..t.len())
            .filter(|&i| t.axle[i] == 3 && t.dv_mps[i] > 0.2)
            .collect();
        let times: Vec<f64> = idx.iter().map(|&i| t.time_s[i]).collect();
        let stem = t.name.rsplit_once('.').unwrap().0;
        let truth = truth_mu(stem, 3, &times);
        let mean: f64 = idx.iter().map(|&i| t.mu[i]).sum::<f64>() / idx.len() as f64;
        for (k, &i) in idx.iter().enumerate() {
            let m = model.mu(t.dv_mps[i], t.ddv_mps2[i]);
            se_est += (m - t.mu[i]).powi(2);
            se_truth += (m - truth[k]).powi(2);
            var += (t.mu[i] - mean).powi(2);
            n += 1;
        }
    }
    let (rmse_est, rmse_truth) = ((se_est / n as f64).sqrt(), (se_truth / n as f64).sqrt());
    let r2 = 1.0 - se_est / var;
    eprintln!("validation (axle 3, Δv > 0.2 m/s, {n} samples): RMSE vs estimated μ {rmse_est:.5}, vs the simulator's truth {rmse_truth:.5}, R² {r2:.3}");
    assert!(rmse_est < 0.01 && r2 > 0.5, "{rmse_est} {r2}");
    // Against the simulator's truth law (stated in docs/simulator.md): the learned curve is as close to the
    // truth as to the estimates it was trained on.
    assert!(rmse_truth < 0.01, "{rmse_truth}");
    // Fig. 11: a ramp 0 → 9 m/s → 0 at ±2 m/s² traces a loop: the loss branch (slip growing)
    // lies above the recovery branch.
    let (mut up, mut down) = (0.0, 0.0);
    for k in 1..=40 {
        let dv = 0.1 * k as f64;
        up += model.mu(dv, 2.0);
        down += model.mu(dv, -2.0);
    }
    eprintln!(
        "ramp: mean μ loss branch {:.4}, recovery branch {:.4}",
        up / 40.0,
        down / 40.0
    );
    assert!(up > down * 1.05, "{up} {down}");
}

// ------------------------------------------------------------------ Polach and k(T)

/// Polach samples with known parameters, slips from `dv_min` m/s and speeds from `v_min`
/// m/s, noise of standard deviation `sigma` as an AR(1) process with coefficient `phi` (0:
/// white).
fn polach_table(dv_min: f64, v_min: f64, sigma: f64, phi: f64) -> (RunTable, [f64; 5]) {
    let truth = railgrip::contact::polach::PolachParams {
        mu0: 0.12,
        a_ratio: 0.35,
        b_s_per_m: 0.5,
        k_a: 0.15,
        k_s: 0.05,
    };
    let t = polach_rows(&truth, 5, 4000, dv_min, v_min, sigma, phi);
    let want = [
        truth.mu0,
        truth.a_ratio,
        truth.b_s_per_m,
        truth.k_a,
        truth.k_s,
    ];
    (t, want)
}

/// `n` samples of Polach's law with parameters `truth` (pipeline patch and wheel load), random
/// generator seed `seed`; the rest as [`polach_table`].
fn polach_rows(
    truth: &railgrip::contact::polach::PolachParams,
    seed: u64,
    n: usize,
    dv_min: f64,
    v_min: f64,
    sigma: f64,
    phi: f64,
) -> RunTable {
    polach_rows_level(truth, &|_| 1.0, seed, n, (dv_min, v_min), sigma, phi)
}

/// [`polach_rows`] with μ0 × `level(v)` (v in m/s).
fn polach_rows_level(
    truth: &railgrip::contact::polach::PolachParams,
    level: &dyn Fn(f64) -> f64,
    seed: u64,
    n: usize,
    (dv_min, v_min): (f64, f64),
    sigma: f64,
    phi: f64,
) -> RunTable {
    polach_rows_creepage(truth, level, None, seed, n, (dv_min, v_min), sigma, phi)
}

/// [`polach_rows_level`] with the creepage taken at `creepage_speed` (m/s) instead of each
/// sample's speed when given: the contact library's law evaluated at that speed.
#[allow(clippy::too_many_arguments)]
fn polach_rows_creepage(
    truth: &railgrip::contact::polach::PolachParams,
    level: &dyn Fn(f64) -> f64,
    creepage_speed: Option<f64>,
    seed: u64,
    n: usize,
    (dv_min, v_min): (f64, f64),
    sigma: f64,
    phi: f64,
) -> RunTable {
    use railgrip::contact::polach::polach;
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    let mut rng = railgrip::sim::Rng::new(seed);
    let mut t = RunTable::default();
    let mut i = 0;
    let mut noise = 0.0;
    while t.len() < n {
        let v = v_min + (35.0 - v_min) * rng.uniform();
        let dv = 0.01 + 4.0 * rng.uniform() * rng.uniform();
        noise = phi * noise + (1.0 - phi * phi).sqrt() * sigma * rng.normal();
        if dv < dv_min {
            continue;
        }
        let at_v = railgrip::contact::polach::PolachParams {
            mu0: truth.mu0 * level(v),
            ..*truth
        };
        let v_s = creepage_speed.unwrap_or(v);
        let mu = polach(&patch, &at_v, q, v_s, dv, 0.0).unwrap().fx_n / q + noise;
        t.axle.push(2);
        t.time_s.push(i as f64 * 0.01);
        t.v_mps.push(v);
        t.dv_mps.push(dv);
        t.ddv_mps2.push(0.0);
        t.mu.push(mu);
        i += 1;
    }
    t
}

fn fit_of(t: &RunTable) -> railgrip::identify::polach::PolachFit {
    use railgrip::identify::polach::{fit_polach, DEFAULT_START};
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    fit_polach("synthetic", &[t], patch, q, 1, DEFAULT_START, true, None).unwrap()
}

/// A campaign's fits take the creepage its data follow: Polach's w/v on data from Polach's
/// law, w over one fixed speed on data whose creep slope per m/s of slip is the same at every
/// speed; either way by a clear BIC margin, and the chosen fit's residual is the noise.
#[test]
fn polach_campaigns_choose_the_creepage_their_data_follow() {
    use railgrip::identify::polach::fit_campaign;
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    let (_, want) = polach_table(0.0, 5.0, 0.002, 0.0);
    let truth = railgrip::contact::polach::PolachParams {
        mu0: want[0],
        a_ratio: want[1],
        b_s_per_m: want[2],
        k_a: want[3],
        k_s: want[4],
    };
    use railgrip::identify::polach::Creepage;
    let cases = [
        (None, Creepage::RollingSpeed),
        (Some(20.0), Creepage::FixedSpeed),
    ];
    for (creepage, chosen) in cases {
        let tables: Vec<RunTable> = (1..=3)
            .map(|seed| {
                let rows = (0.0, 5.0);
                polach_rows_creepage(&truth, &|_| 1.0, creepage, seed, 3000, rows, 0.002, 0.0)
            })
            .collect();
        let (r, _) = fit_campaign(&tables, patch, q, 1, 0, false);
        let c = r.creepage.as_ref().expect("both pooled fits");
        let (bic, rmse) = (c.bic.unwrap(), c.rmse.unwrap());
        eprintln!("{creepage:?}: {c:?}");
        assert_eq!(c.chosen, chosen);
        let (won, lost) = if creepage.is_some() { (1, 0) } else { (0, 1) };
        assert!(bic[lost] - bic[won] > 50.0, "{bic:?}");
        assert!((rmse[won] / 0.002 - 1.0).abs() < 0.1, "{rmse:?}");
        assert!(rmse[lost] > 1.2 * rmse[won], "{rmse:?}");
        // The fixed speed is the runs' median (speeds uniform over 5–35 m/s).
        assert!((c.fixed_speed_mps - 20.0).abs() < 1.0, "{c:?}");
        if creepage.is_some() {
            // With intervals, the pooled fit the choice made gets its profiles and is what a
            // pooled fit at that speed from the start, profiles and all, gives (every field).
            let (ri, _) = fit_campaign(&tables, patch, q, 1, 0, true);
            let refs: Vec<&RunTable> = tables.iter().collect();
            let fresh = railgrip::identify::polach::fit_polach(
                "all runs",
                &refs,
                patch,
                q,
                1,
                railgrip::identify::polach::DEFAULT_START,
                true,
                Some(c.fixed_speed_mps),
            )
            .unwrap();
            let b = ri.pooled.as_ref().unwrap();
            assert_eq!(
                serde_json::to_string(b).unwrap(),
                serde_json::to_string(&fresh).unwrap()
            );
            assert!(r.pooled.as_ref().unwrap().profiles.is_empty());
            assert_eq!(b.profiles.len(), 5, "{:?}", b.status);
        }
    }
}

#[test]
fn polach_fit_recovers_known_parameters() {
    use railgrip::identify::polach::ParamStatus;
    let (t, want) = polach_table(0.0, 5.0, 0.002, 0.0);
    let f = fit_of(&t);
    eprintln!("{f:?}");
    let got = [f.mu0, f.a_ratio, f.b_s_per_m, f.k_a, f.k_s];
    for k in 0..5 {
        assert_eq!(f.status[k], ParamStatus::Estimated, "param {k}");
        assert!(f.se[k] > 0.0 && f.se[k].is_finite());
        assert!(
            (got[k] - want[k]).abs() < 2.0 * f.se[k],
            "param {k}: {} ± {} vs {}",
            got[k],
            f.se[k],
            want[k]
        );
    }
    assert!((f.rmse - 0.002).abs() < 3e-4, "{}", f.rmse);
    // Profile likelihood: an interval per parameter around its estimate, holding the truth;
    // on this well-determined fit close to the Wald interval ±1.96 se; the statistic 0 at the
    // estimate and rising outward, past χ²₁(0.95) at each end.
    assert_eq!(f.profiles.len(), 5);
    for (k, pr) in f.profiles.iter().enumerate() {
        let (lo, hi) = (pr.lower.unwrap(), pr.upper.unwrap());
        eprintln!(
            "{}: {:.5} [{lo:.5}, {hi:.5}] Wald ±{:.5} truth {}",
            pr.parameter,
            pr.estimate,
            1.96 * f.se[k],
            want[k]
        );
        assert_eq!(pr.parameter, railgrip::identify::polach::PARAMETERS[k]);
        assert!(lo < pr.estimate && pr.estimate < hi);
        assert!(
            lo <= want[k] && want[k] <= hi,
            "{}: truth outside",
            pr.parameter
        );
        for half in [pr.estimate - lo, hi - pr.estimate] {
            let ratio = half / (1.96 * f.se[k]);
            assert!((0.8..1.25).contains(&ratio), "{}: {ratio}", pr.parameter);
        }
        let i0 = pr.points.iter().position(|p| p.0 == pr.estimate).unwrap();
        assert_eq!(pr.points[i0].1, 0.0);
        assert!(pr.points.windows(2).all(|w| w[0].0 < w[1].0));
        assert!(pr.points[..i0].windows(2).all(|w| w[0].1 >= w[1].1));
        assert!(pr.points[i0..].windows(2).all(|w| w[0].1 <= w[1].1));
        let limit = railgrip::identify::polach::PROFILE_LIMIT;
        assert!(pr.points[0].1 > limit && pr.points.last().unwrap().1 > limit);
    }
    // MINPACK's test ends it, in a few iterations (the analytic Jacobian).
    assert!(f.stop_reason.starts_with("converged"), "{}", f.stop_reason);
    assert!(f.iterations < 30, "{}", f.iterations);
}

/// With the scatter of real estimates (RMSE of μ 0.01 and residuals correlated so that
/// n_eff/n ≈ 1/30, as the fits on the bundled archive measure) and braking speeds (20–35 m/s),
/// every parameter is identified — and without the small slips (Δv > 0.2 m/s, where soap-rail
/// braking data mostly lie) the creep slope k_A is not: the fit says so, holds it and still
/// recovers the falling friction μ0, A, B within 2 se.
#[test]
fn polach_fit_says_what_data_without_small_slip_cannot_identify() {
    use railgrip::identify::polach::ParamStatus;
    let phi = 29.0 / 31.0;
    let (t, _) = polach_table(0.0, 20.0, 0.01, phi);
    let f = fit_of(&t);
    eprintln!("{f:?}");
    assert!(
        f.effective_samples < 0.05 * f.samples as f64,
        "{}",
        f.effective_samples
    );
    assert!(
        f.status.iter().all(|s| *s == ParamStatus::Estimated),
        "{f:?}"
    );
    let (t, want) = polach_table(0.2, 20.0, 0.01, phi);
    let f = fit_of(&t);
    eprintln!("{f:?}");
    assert_eq!(f.status[3], ParamStatus::NotIdentifiable, "{f:?}");
    assert!(f.se[3].is_nan());
    assert!(
        f.notes.iter().any(|n| n.contains("k_A not identifiable")),
        "{:?}",
        f.notes
    );
    let got = [f.mu0, f.a_ratio, f.b_s_per_m];
    for k in 0..3 {
        assert_eq!(f.status[k], ParamStatus::Estimated, "param {k}");
        assert!(
            (got[k] - want[k]).abs() < 2.0 * f.se[k],
            "param {k}: {} ± {} vs {}",
            got[k],
            f.se[k],
            want[k]
        );
    }
    assert!(f.stop_reason.starts_with("converged"), "{}", f.stop_reason);
}

/// Data the law cannot be fully identified from, said clearly (bad input): slips
/// only in the creep region (Δv < 0.05 m/s: no falling friction to see), and a single run at
/// one temperature (no k(T), with the reason).
#[test]
fn polach_fits_of_thin_data_say_why() {
    use railgrip::identify::polach::{fit_campaign, ParamStatus};
    let (mut t, _) = polach_table(0.0, 20.0, 0.002, 0.0);
    t = t.subset(|i| t.dv_mps[i] < 0.05);
    assert!(t.len() > 150, "{}", t.len());
    let f = fit_of(&t);
    eprintln!("{f:?}");
    assert!(f.stop_reason.starts_with("converged"), "{}", f.stop_reason);
    // The falling friction's decay B is not seen below 5 cm/s; every held parameter says why.
    assert_ne!(f.status[2], ParamStatus::Estimated, "{f:?}");
    let held = f
        .status
        .iter()
        .filter(|s| **s != ParamStatus::Estimated)
        .count();
    assert!(
        f.notes.len() + 1 >= held && !f.notes.is_empty(),
        "{:?}",
        f.notes
    );
    // One run at one temperature: fits, and k(T) absent with its reason.
    t.metadata.ambient_temperature_c = Some(10.0);
    t.name = "only".into();
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    let (r, notes) = fit_campaign(&[t.clone()], patch, q, 1, 2, true);
    assert!(notes.is_empty(), "{notes:?}");
    // The fits file reads back (held parameters' standard errors are null, read as NaN).
    let json = serde_json::to_string(&r).unwrap();
    assert!(json.contains("null"), "{json}");
    let back: railgrip::identify::polach::PolachReport = serde_json::from_str(&json).unwrap();
    assert_eq!(serde_json::to_string(&back).unwrap(), json);
    assert!(r.pooled.is_some() && r.per_run.len() == 1 && r.per_temperature.len() == 1);
    // Its speeds (20–35 m/s) are wide enough for speed forms, which the data do not choose.
    assert!(r.temperature.as_ref().is_some_and(|t| !t.has_law()));
    let why = r.temperature_note.unwrap();
    assert!(
        why.contains("one ambient temperature: no temperature forms"),
        "{why}"
    );
    // Narrower speeds: no law at all, and why (here: this creep-only fit holds μ0).
    let narrow = t.subset(|i| t.v_mps[i] < 28.0);
    let (r, _) = fit_campaign(&[narrow], patch, q, 1, 2, false);
    assert!(r.temperature.is_none());
    let why = r.temperature_note.unwrap();
    assert!(
        why.contains("two or more ambient temperatures; found 1")
            && why.contains("μ0(v) forms not offered"),
        "{why}"
    );
}

/// μ0's speed law follows the data over three seeds: a level falling with speed (linearly,
/// and steeper at the top) → a speed law chosen by BIC, its factor within 2 % of the truth
/// over the fitted speeds, the model file and its evaluator following it.
#[test]
fn the_speed_law_follows_a_level_that_falls_with_speed() {
    use railgrip::contact::polach::PolachParams;
    use railgrip::identify::polach::fit_campaign;
    let base = PolachParams {
        mu0: 0.12,
        a_ratio: 0.35,
        b_s_per_m: 0.5,
        k_a: 0.15,
        k_s: 0.05,
    };
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    let cases: [(&str, &dyn Fn(f64) -> f64); 2] = [
        ("linear", &|v: f64| 1.0 + 0.3 * (1.0 - v / 25.0)),
        ("quadratic", &|v: f64| {
            1.0 + 0.2 * (1.0 - (v / 25.0).powi(2))
        }),
    ];
    for (what, level) in cases {
        for seed in 1..=3 {
            let tables: Vec<RunTable> = [0.0, 20.0]
                .iter()
                .enumerate()
                .map(|(k, &temp)| {
                    let mut t = polach_rows_level(
                        &base,
                        level,
                        seed * 10 + k as u64,
                        6000,
                        (0.0, 5.0),
                        0.005,
                        29.0 / 31.0,
                    );
                    t.name = format!("run_{temp}");
                    t.metadata.ambient_temperature_c = Some(temp);
                    t
                })
                .collect();
            let (r, _) = fit_campaign(&tables, patch, q, 1, 2, false);
            let t = r.temperature.as_ref().expect("a law");
            let s = t
                .speed
                .as_ref()
                .unwrap_or_else(|| panic!("{what} {seed}: {}", t.form()));
            let v_ref = railgrip::identify::median_speed(&tables);
            assert_eq!(s.reference_speed_mps, v_ref);
            eprintln!(
                "{what} seed {seed}: {} c = {:?} ± {:?}",
                t.form(),
                s.coefficients,
                s.standard_errors
            );
            for v in [6.0, 15.0, 25.0, 34.0] {
                let want = level(v) / level(v_ref);
                let got = s.factor(v);
                assert!(
                    (got / want - 1.0).abs() < 0.02,
                    "{what} seed {seed} g({v}) = {got}, truth {want}"
                );
            }
            // The model file carries the law; its evaluator scales μ0 by it.
            let file = railgrip::identify::export::polach_file(
                r.pooled.as_ref().unwrap(),
                &patch,
                q,
                Some(t),
                r.dv_range_mps,
                r.v_range_mps,
                v_ref,
                r.creepage.as_ref().and_then(|c| c.speed()),
                polach_provenance(),
            )
            .unwrap();
            let model = Model::new(file).unwrap();
            let (m, ka, ks) = t.at(0.0);
            for v in [8.0, 30.0] {
                let want = railgrip::contact::polach::polach(
                    &patch,
                    &PolachParams {
                        mu0: m * s.factor(v),
                        a_ratio: t.a_ratio,
                        b_s_per_m: t.b_s_per_m,
                        k_a: ka,
                        k_s: ks,
                    },
                    q,
                    v,
                    1.5,
                    0.0,
                )
                .unwrap()
                .fx_n
                    / q;
                let got = model.mu_vt(1.5, 0.0, v, 0.0);
                assert!((got / want - 1.0).abs() < 1e-9, "{what}: {got} vs {want}");
            }
        }
    }
}

/// At one ambient temperature the speed forms are fitted alone, and with intervals each
/// coefficient gets its profile-likelihood interval.
#[test]
fn speed_forms_alone_at_one_temperature_with_intervals() {
    use railgrip::contact::polach::PolachParams;
    use railgrip::identify::polach::fit_campaign;
    let base = PolachParams {
        mu0: 0.12,
        a_ratio: 0.35,
        b_s_per_m: 0.5,
        k_a: 0.15,
        k_s: 0.05,
    };
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    let linear = |v: f64| 1.0 + 0.3 * (1.0 - v / 25.0);
    // One ambient temperature: the speed forms alone (5 candidates: none, linear,
    // Curtius–Kniffler, quadratic, cubic).
    let mut one = polach_rows_level(&base, &linear, 7, 6000, (0.0, 5.0), 0.005, 29.0 / 31.0);
    one.metadata.ambient_temperature_c = Some(10.0);
    let (r, _) = fit_campaign(&[one], patch, q, 1, 2, true);
    let t = r.temperature.as_ref().expect("a speed law");
    assert_eq!(t.candidates.len(), 5);
    assert!(
        t.speed.is_some() && !t.has_temperature_law(),
        "{}",
        t.form()
    );
    // With intervals: each coefficient's profile-likelihood interval holds its estimate and
    // is about ±1.96 standard errors wide (the law is nearly linear in its coefficients).
    let s = t.speed.as_ref().unwrap();
    assert_eq!(s.profiles.len(), s.coefficients.len(), "{s:?}");
    for (p, se) in s.profiles.iter().zip(&s.standard_errors) {
        let (lo, hi) = (p.lower.unwrap(), p.upper.unwrap());
        assert!(lo < p.estimate && p.estimate < hi, "{p:?}");
        let half = 0.5 * (hi - lo) / se;
        assert!((1.5..2.5).contains(&half), "{p:?}: ±{half} se");
    }
}

/// Campaign tables at −20, 0 and +20 °C from Polach's law with `at(T)` giving its
/// parameters, realistic scatter (σ 0.01, AR(1) φ = 29/31: n_eff/n ≈ 1/30 as measured on the
/// bundled fits), 6 000 samples per temperature, generator seed `seed`.
fn tables_over_temperature(
    at: &dyn Fn(f64) -> railgrip::contact::polach::PolachParams,
    seed: u64,
) -> Vec<RunTable> {
    [-20.0, 0.0, 20.0]
        .iter()
        .enumerate()
        .map(|(k, &temp)| {
            let mut t = polach_rows(
                &at(temp),
                seed * 10 + k as u64,
                6000,
                0.0,
                15.0,
                0.01,
                29.0 / 31.0,
            );
            t.name = format!("run_{temp}");
            t.metadata.ambient_temperature_c = Some(temp);
            t
        })
        .collect()
}

/// The temperature law's form follows what varies with temperature, over three
/// seeds: only μ0 (the adhesion level of seed 004 Fig. 2) → μ0(T) and constant k; only k_S →
/// k(T) and constant μ0; nothing → the constant form, no law written, and a note saying so.
#[allow(clippy::too_many_lines)] // a test or benchmark: one scenario end to end
#[test]
fn the_temperature_form_follows_what_varies() {
    use railgrip::contact::polach::PolachParams;
    use railgrip::identify::polach::fit_campaign;
    let base = PolachParams {
        mu0: 0.12,
        a_ratio: 0.35,
        b_s_per_m: 0.5,
        k_a: 0.15,
        k_s: 0.05,
    };
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    let cases: [(&str, &dyn Fn(f64) -> PolachParams); 3] = [
        ("μ0", &|t: f64| PolachParams {
            mu0: 0.12 * (1.0 + 0.005 * (20.0 - t)),
            ..base
        }),
        ("k_S", &|t: f64| PolachParams {
            k_s: 0.05 * (1.0 + 0.02 * (20.0 - t)),
            k_a: 0.15,
            ..base
        }),
        ("nothing", &|_| base),
    ];
    for (what, at) in cases {
        for seed in 1..=3 {
            let tables = tables_over_temperature(at, seed);
            // Without intervals (`train.polach_intervals = false`): no profiles anywhere.
            let (r, notes) = fit_campaign(&tables, patch, q, 1, 2, false);
            assert!(r
                .pooled
                .iter()
                .chain(&r.per_temperature)
                .all(|f| f.profiles.is_empty()));
            let t = r.temperature.as_ref().expect("a temperature fit");
            let table: Vec<String> = t
                .candidates
                .iter()
                .map(|c| format!("{} BIC {:.1}", c.form(), c.bic))
                .collect();
            eprintln!(
                "{what} seed {seed}: chose {}; {table:?}; {notes:?}; creepage {:?}",
                t.form(),
                r.creepage
            );
            // 3 × 3 temperature forms; four speed laws (15–35 m/s) on the best three.
            assert_eq!(t.candidates.len(), 21, "{what}");
            // The level does not depend on speed: no speed law (BIC).
            assert!(t.speed.is_none(), "{what} seed {seed}: {}", t.form());
            match what {
                "μ0" => assert!(
                    t.mu0_degree >= 1 && t.k_degree == 0,
                    "{what} seed {seed}: {}",
                    t.form()
                ),
                "k_S" => assert!(
                    t.mu0_degree == 0 && t.k_degree >= 1,
                    "{what} seed {seed}: {}",
                    t.form()
                ),
                _ => {
                    assert!(!t.has_law(), "{what} seed {seed}: {}", t.form());
                    let note = r.temperature_note.as_deref().unwrap();
                    assert!(
                        note.contains("prefer no temperature or speed dependence"),
                        "{note}"
                    );
                }
            }
            // The law recovers what varies: within 3 % of the truth over the range.
            for temp in [-20.0, 0.0, 20.0] {
                let (m, _, ks) = t.at(temp);
                let want = at(temp);
                assert!(
                    (m / want.mu0 - 1.0).abs() < 0.03,
                    "{what} seed {seed} μ0 at {temp}: {m}"
                );
                if what == "k_S" {
                    assert!(
                        (ks / want.k_s - 1.0).abs() < 0.1,
                        "{what} seed {seed} k_S at {temp}: {ks}"
                    );
                }
            }
            // The model file follows the chosen form.
            let fit = r.pooled.as_ref().unwrap();
            let file = railgrip::identify::export::polach_file(
                fit,
                &patch,
                q,
                Some(t),
                r.dv_range_mps,
                r.v_range_mps,
                25.0,
                r.creepage.as_ref().and_then(|c| c.speed()),
                polach_provenance(),
            )
            .unwrap();
            let law = file.polach.as_ref().unwrap().temperature.as_ref();
            assert_eq!(law.is_some(), t.has_law(), "{what}");
            if let Some(l) = law {
                assert_eq!(l.mu0.is_empty(), t.mu0_degree == 0, "{what}");
                let model = Model::new(file.clone()).unwrap();
                let (m, ka, ks) = t.at(-10.0);
                let want = railgrip::contact::polach::polach(
                    &patch,
                    &PolachParams {
                        mu0: m,
                        a_ratio: t.a_ratio,
                        b_s_per_m: t.b_s_per_m,
                        k_a: ka,
                        k_s: ks,
                    },
                    q,
                    30.0,
                    1.0,
                    0.0,
                )
                .unwrap()
                .fx_n
                    / q;
                let got = model.mu_vt(1.0, 0.0, 30.0, -10.0);
                assert!(
                    ((got - want) / want).abs() < 1e-12,
                    "{what}: {got} vs {want}"
                );
            }
        }
    }
}

/// k(T) forms are offered only when two or more temperatures' own fits identified k_A and
/// k_S; the others are named with the reason. On the bundled archive (soap at +20, 0, −20 °C,
/// k_A higher in the cold as in seed 004) the law chosen has k(T).
#[test]
fn k_forms_need_temperatures_that_identify_k_and_the_archive_chooses_one() {
    use railgrip::identify::polach::{fit_campaign, k_identified, ParamStatus, PolachFit};
    let fit = |t: f64| PolachFit {
        group: format!("T = {t}"),
        mu0: 0.1,
        a_ratio: 0.4,
        b_s_per_m: 0.3,
        k_a: 0.1,
        k_s: 0.05,
        se: [0.0; 5],
        status: [ParamStatus::Estimated; 5],
        notes: vec![],
        profiles: vec![],
        samples: 100,
        effective_samples: 10.0,
        rmse: 0.0,
        ambient_temperature_c: Some(t),
        iterations: 10,
        stop_reason: "minimum gradient reached".into(),
    };
    let mut fits: Vec<PolachFit> = [-40.0, -20.0, 0.0, 20.0].iter().map(|t| fit(*t)).collect();
    assert_eq!(k_identified(&fits).0.len(), 4);
    fits[1].status[3] = ParamStatus::NotIdentifiable;
    fits[0].status[4] = ParamStatus::NotIdentifiable;
    fits[2].status[3] = ParamStatus::AtBound;
    // k_S/k_A at its bound leaves k_S as determined as k_A: kept.
    fits[3].status[4] = ParamStatus::AtBound;
    let (kept, excluded) = k_identified(&fits);
    assert_eq!(kept, vec![20.0]);
    assert_eq!(
        excluded,
        vec![
            "T = -40 °C (k_S not identifiable)".to_string(),
            "T = -20 °C (k_A not identifiable)".to_string(),
            "T = 0 °C (k_A at bound)".to_string(),
        ]
    );

    let p = Pipeline::default_uic_z1();
    let tables = archive_tables(&p);
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    let (report, notes) = fit_campaign(&tables, patch, q, 8, 2, true);
    assert!(notes.is_empty(), "{notes:?}");
    let ka = |t: f64| {
        report
            .per_temperature
            .iter()
            .find(|f| f.ambient_temperature_c == Some(t))
            .unwrap()
            .k_a
    };
    eprintln!(
        "k_A at +20/0/−20 °C: {:.4} {:.4} {:.4}",
        ka(20.0),
        ka(0.0),
        ka(-20.0)
    );
    assert!(ka(0.0) > 1.1 * ka(20.0) && ka(-20.0) > 1.1 * ka(20.0));
    let json = serde_json::to_string(&report).unwrap();
    let back: railgrip::identify::polach::PolachReport = serde_json::from_str(&json).unwrap();
    assert_eq!(serde_json::to_string(&back).unwrap(), json);
    let law = report.temperature.unwrap();
    eprintln!("archive: {}", law.form());
    assert!(law.k_degree >= 1, "{}", law.form());
    assert_eq!(law.fitted_range_c, (-20.0, 20.0));
    let (_, ka_cold, _) = law.at(-20.0);
    let (_, ka_warm, _) = law.at(20.0);
    assert!(ka_cold > 1.1 * ka_warm);
    // The pooled and per-temperature fits carry profile intervals; per-run fits do not.
    assert_eq!(report.pooled.as_ref().unwrap().profiles.len(), 5);
    assert!(report
        .per_temperature
        .iter()
        .all(|f| !f.profiles.is_empty()));
    assert!(report.per_run.iter().all(|f| f.profiles.is_empty()));
}

#[test]
fn one_rail_condition_trains_a_campaign() {
    use railgrip::identify::select_condition;
    let run = |name: &str, condition: Option<&str>| {
        let mut t = synthetic_table(10);
        t.name = name.into();
        t.metadata.condition = condition.map(String::from);
        t
    };
    let tables = || {
        vec![
            run("dry1", Some("dry")),
            run("soap1", Some("soap")),
            run("x", None),
            run("soap2", Some("soap")),
        ]
    };
    let c = select_condition(tables(), None).unwrap();
    assert_eq!(c.condition, "soap");
    let names: Vec<&str> = c.used.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["soap1", "soap2"]);
    assert_eq!(
        c.skipped,
        [
            ("dry1".to_string(), "dry".to_string()),
            ("x".to_string(), "unknown".to_string())
        ]
    );
    let c = select_condition(tables(), Some("dry")).unwrap();
    assert_eq!(c.used.len(), 1);
    // A tie goes to the alphabetically first condition.
    let c = select_condition(vec![run("w", Some("wet")), run("d", Some("dry"))], None).unwrap();
    assert_eq!(c.condition, "dry");
    let e = select_condition(tables(), Some("wet"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("train.condition = \"wet\"") && e.contains("soap"),
        "{e}"
    );
}

// ------------------------------------------------------------------ deeper networks (format v3)

/// `base` with its network replaced by random hidden layers of `widths` (weights ~ U(−w, w)),
/// as a version-3 file.
fn deep_model(base: &ModelFile, widths: &[usize], w: f64, seed: u64) -> ModelFile {
    let mut rng = railgrip::sim::Rng::new(seed);
    let mut m = base.clone();
    let mut layers = Vec::new();
    let mut n_in = m.inputs.len();
    for (l, &n) in widths.iter().chain([&1]).enumerate() {
        let last = l == widths.len();
        layers.push(railgrip::model::Layer {
            shape: [n, n_in],
            weights: (0..n)
                .map(|_| (0..n_in).map(|_| w * (2.0 * rng.uniform() - 1.0)).collect())
                .collect(),
            biases: (0..n).map(|_| 0.5 * (2.0 * rng.uniform() - 1.0)).collect(),
            activation: if last { "linear" } else { "tanh" }.into(),
        });
        n_in = n;
    }
    m.layers = layers;
    m.version = railgrip::model::DEEP_VERSION;
    m
}

/// The model file holds networks of any depth (version 3), and the Rust single call,
/// the Rust batch and the C header evaluate them with the same bits — widths that fill whole
/// SIMD chunks and ragged ones, mirrored, creep-region, clamped and NaN inputs, with the
/// support grid of the base file.
#[test]
fn deep_networks_evaluate_bit_identically_in_rust_single_batch_and_c() {
    let base = synthetic_model();
    for (widths, seed) in [
        (&[32usize, 32][..], 1u64),
        (&[7, 13, 5][..], 2),
        (&[1, 3][..], 3),
        (&[20, 9, 16, 6, 3][..], 4),
    ] {
        let file = deep_model(&base, widths, 1.5, seed);
        file.check().unwrap();
        let text = file.to_json();
        schema_check(&text, "deep network");
        let back = ModelFile::from_json(&text, "deep").unwrap();
        assert_eq!(back, file, "{widths:?}: JSON round trip");
        let model = Model::new(back).unwrap();
        let n = 307;
        let (dv, ddv) = batch_matches_single_calls(&model, n, 5, seed + 10);
        let mut distinct = std::collections::BTreeSet::new();
        for i in 0..n {
            let single = model.mu(dv[i], ddv[i]);
            assert!(single.is_finite() || i == 5);
            distinct.insert(single.to_bits());
        }
        // A network that really depends on its inputs (not a constant through saturation).
        assert!(
            distinct.len() > n / 2,
            "{widths:?}: {} distinct",
            distinct.len()
        );
        let pts: Vec<[f64; 4]> = dv
            .iter()
            .zip(&ddv)
            .map(|(a, b)| [*a, *b, f64::NAN, f64::NAN])
            .collect();
        if let Some((worst, differ)) =
            c_header_error(&model, &pts, &["-DRG_EXACT_FMA", "-ffp-contract=off"])
        {
            assert_eq!(differ, 0, "{widths:?}: C differs, worst {worst:e}");
        }
    }
}

/// Deeper networks need version 3, and every layer's shape must follow from the one before.
#[test]
fn deep_network_files_with_bad_shapes_or_versions_are_refused() {
    let base = synthetic_model();
    let good = deep_model(&base, &[8, 6], 1.0, 1);
    let mut old = good.clone();
    old.version = 2;
    let e = old.check().unwrap_err().to_string();
    assert!(e.contains("version 3"), "{e}");
    let mut bad = good.clone();
    bad.layers[1].shape = [6, 7];
    let e = bad.check().unwrap_err().to_string();
    assert!(
        e.contains("layers[1]") && e.contains("8 inputs to the layer"),
        "{e}"
    );
    let mut bad = good.clone();
    bad.layers[1].activation = "relu".into();
    assert!(bad.check().unwrap_err().to_string().contains("tanh"));
    let too_deep = deep_model(&base, &[2; 9], 1.0, 1);
    let e = too_deep.check().unwrap_err().to_string();
    assert!(e.contains("1 to 8 hidden"), "{e}");
    let too_wide = deep_model(&base, &[4, 257], 1.0, 1);
    assert!(too_wide.check().is_err());
}

// ------------------------------------------------------------------ burn: Adam/AdamW, autodiff

/// Burn's reverse-mode autodiff and the analytic Jacobian the LM trainer builds
/// (`mlp::forward_grad`) agree on every parameter, for one and two hidden layers, at random
/// weights (including saturated neurons) and inputs.
#[test]
fn burn_autodiff_agrees_with_the_analytic_lm_jacobian() {
    use railgrip::identify::adam::gradient_by_autodiff;
    let mut rng = railgrip::sim::Rng::new(4);
    for (shape, scale) in [
        (Shape::one(3, 10), 1.0),
        (Shape::one(2, 1), 3.0),
        (
            Shape {
                inputs: 2,
                hidden: 6,
                hidden2: 4,
            },
            1.0,
        ),
        (
            Shape {
                inputs: 4,
                hidden: 9,
                hidden2: 7,
            },
            4.0,
        ),
    ] {
        let arch = mlp::Arch::from(shape);
        for seed in 0..5 {
            let theta: Vec<f64> = mlp::nguyen_widrow(shape, seed)
                .iter()
                .map(|v| v * scale)
                .collect();
            let x: Vec<f64> = (0..shape.inputs)
                .map(|_| 2.0 * rng.uniform() - 1.0)
                .collect();
            let mut analytic = vec![0.0; shape.n_params()];
            mlp::forward_grad(shape, &theta, &x, &mut analytic);
            let auto = gradient_by_autodiff(&arch, &theta, &x).unwrap();
            assert_eq!(auto.len(), analytic.len());
            for (p, (a, b)) in auto.iter().zip(&analytic).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                    "{arch} seed {seed} θ[{p}]: autodiff {a} vs analytic {b}"
                );
            }
        }
    }
}

/// A law from a family the network does not contain (Burckhardt's tyre law with a slip-rate
/// term, not Polach): μ(Δv, dΔv/dt) = c1 (1 − e^(−c2 Δv)) − c3 Δv + c4 dΔv/dt, on normalised
/// inputs x ∈ [−1, 1]² (Δv = 2.5 (x0 + 1) m/s, dΔv/dt = 4 x1 m/s²).
fn burckhardt(x: &[f64], c: [f64; 4]) -> f64 {
    let dv = 2.5 * (x[0] + 1.0);
    let ddv = 4.0 * x[1];
    c[0] * (1.0 - (-c[1] * dv).exp()) - c[2] * dv + c[3] * ddv
}

/// A two-hidden-layer network trained by Adam and by AdamW through burn learns a
/// foreign law from noisy samples over several seeds (RMSE against the truth on a fresh grid
/// within twice the noise), the same data and seed give the same weights bit for bit,
/// early stopping keeps the best validation epoch, and bad settings are refused.
#[allow(clippy::too_many_lines)] // a test or benchmark: one scenario end to end
#[test]
fn adam_through_burn_learns_a_foreign_law_deterministically() {
    use railgrip::identify::adam::{train, AdamData, AdamSettings, Optimizer};
    let arch = mlp::Arch {
        inputs: 2,
        hidden: vec![12, 12],
    };
    for (seed, c, optimizer) in [
        (1u64, [0.30, 2.0, 0.020, 0.004], Optimizer::Adam),
        (2, [0.18, 6.0, 0.010, -0.003], Optimizer::AdamW),
        (3, [0.40, 1.2, 0.045, 0.006], Optimizer::Adam),
    ] {
        let mut rng = railgrip::sim::Rng::new(seed);
        let noise = 0.005;
        let mut sample = |n: usize| {
            let x: Vec<f64> = (0..2 * n).map(|_| 2.0 * rng.uniform() - 1.0).collect();
            let y: Vec<f64> = x
                .chunks(2)
                .map(|p| burckhardt(p, c) + noise * (2.0 * rng.uniform() - 1.0) * 3f64.sqrt())
                .collect();
            (x, y)
        };
        let (x, y) = sample(2000);
        let (vx, vy) = sample(500);
        // mapminmax of μ onto [−1, 1], as the pipeline trains.
        let (lo, hi) = y
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let g = 2.0 / (hi - lo);
        let norm = |v: &[f64]| v.iter().map(|y| g * (y - lo) - 1.0).collect::<Vec<f64>>();
        let (yn, vyn) = (norm(&y), norm(&vy));
        let data = AdamData {
            x: &x,
            y: &yn,
            vx: &vx,
            vy: &vyn,
            scale: 1.0 / (g * g),
        };
        let settings = AdamSettings {
            optimizer,
            learning_rate: 5e-3,
            weight_decay: if optimizer == Optimizer::AdamW {
                1e-4
            } else {
                0.0
            },
            batch: 64,
            max_epochs: 300,
            patience: 30,
        };
        let theta0 = mlp::nguyen_widrow_layers(&arch, seed);
        let a = train(&arch, &data, theta0.clone(), &settings, seed, None).unwrap();
        let b = train(&arch, &data, theta0, &settings, seed, None).unwrap();
        let bits = |t: &[f64]| t.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a.theta), bits(&b.theta), "seed {seed}: deterministic");
        // Early stopping kept the best validation epoch.
        let best = a.history[a.best_epoch - 1].val_mse;
        assert!(a.history.iter().all(|e| e.val_mse >= best), "seed {seed}");
        // Against the truth on a grid the training never saw.
        let mut sq = 0.0;
        let mut n = 0;
        for i in 0..=40 {
            for j in 0..=40 {
                let p = [-1.0 + i as f64 / 20.0, -1.0 + j as f64 / 20.0];
                let mu = (mlp::forward_layers(&arch, &a.theta, &p) + 1.0) / g + lo;
                let e = mu - burckhardt(&p, c);
                sq += e * e;
                n += 1;
            }
        }
        let rmse = (sq / n as f64).sqrt();
        eprintln!(
            "{optimizer:?} seed {seed}: RMSE vs truth {rmse:.2e} (noise {noise}), {} epochs, best {}, {:?}",
            a.history.len(),
            a.best_epoch,
            a.stop
        );
        assert!(rmse < 2.0 * noise, "seed {seed}: RMSE {rmse}");
    }
    // Bad settings: refused before any work, naming the setting.
    let data = AdamData {
        x: &[0.0, 0.0],
        y: &[0.0],
        vx: &[],
        vy: &[],
        scale: 1.0,
    };
    let theta0 = mlp::nguyen_widrow_layers(&arch, 1);
    for (bad, name) in [
        (
            AdamSettings {
                learning_rate: 0.0,
                ..AdamSettings::default()
            },
            "learning_rate",
        ),
        (
            AdamSettings {
                learning_rate: f64::NAN,
                ..AdamSettings::default()
            },
            "learning_rate",
        ),
        (
            AdamSettings {
                weight_decay: -1.0,
                ..AdamSettings::default()
            },
            "weight_decay",
        ),
        (
            AdamSettings {
                batch: 0,
                ..AdamSettings::default()
            },
            "batch",
        ),
    ] {
        let e = train(&arch, &data, theta0.clone(), &bad, 1, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name), "{e}");
    }
}

/// `family` fitted on `tables` as `p` says, without a fallback, audited.
fn fit_family(
    family: &dyn railgrip::identify::family::ModelFamily,
    tables: &[RunTable],
    p: &Pipeline,
) -> railgrip::identify::family::Fitted {
    fit_family_audited(family, tables, p, true)
}

fn fit_family_audited(
    family: &dyn railgrip::identify::family::ModelFamily,
    tables: &[RunTable],
    p: &Pipeline,
    audit: bool,
) -> railgrip::identify::family::Fitted {
    family
        .fit(&railgrip::identify::family::FitData {
            tables,
            pipeline: p,
            provenance: polach_provenance(),
            fallback: None,
            epochs: None,
            audit,
        })
        .unwrap()
}

/// A fit that is only scored on held-out runs skips the plausibility audit and nothing else:
/// its file is the audited fit's without the audit (network and residual network).
#[test]
fn a_fit_without_the_audit_differs_only_by_the_audit() {
    use railgrip::identify::family::{ModelFamily, Network, Residual};
    let tables = common::bundled_tables(|n| n.starts_with("soap_"));
    let mut p = Pipeline::default_uic_z1();
    p.train.epochs = 10;
    let families: [&dyn ModelFamily; 2] = [&Network, &Residual];
    for family in families {
        let audited = fit_family_audited(family, &tables, &p, true).model.unwrap();
        let mut lean = fit_family_audited(family, &tables, &p, false)
            .model
            .unwrap();
        assert!(audited.audit.is_some(), "{}", family.name());
        assert!(lean.audit.is_none(), "{}", family.name());
        lean.audit.clone_from(&audited.audit);
        assert_eq!(
            serde_json::to_string(&lean).unwrap(),
            serde_json::to_string(&audited).unwrap(),
            "{}",
            family.name()
        );
    }
}

/// Leave-one-run-out holds out one run at a time up to `train.folds` runs and K folds of runs
/// beyond (run i in fold i mod K): each run's score is that of the model fitted without its
/// fold, so the trainings grow with the folds, not with the runs. Checked against fits made
/// here by hand on the bundled soap runs (7), with K = 3 and with the default 8.
#[test]
fn leave_one_run_out_holds_out_folds_of_runs_beyond_train_folds() {
    use railgrip::identify::family::Network;
    use railgrip::identify::{held_out_score, leave_one_run_out};
    let tables = common::bundled_tables(|n| n.starts_with("soap_"));
    assert_eq!(tables.len(), 7);
    let mut p = Pipeline::default_uic_z1();
    p.train.epochs = 40;
    let by_hand = |p: &Pipeline, held: &[usize]| {
        let others: Vec<RunTable> = (0..tables.len())
            .filter(|k| !held.contains(k))
            .map(|k| tables[k].clone())
            .collect();
        let fitted = fit_family(&Network, &others, p);
        Model::new(fitted.model.unwrap()).unwrap()
    };
    for (folds, check) in [
        (3usize, vec![vec![0, 3, 6], vec![2, 5]]),
        (8, vec![vec![4]]),
    ] {
        p.train.folds = folds;
        let h = leave_one_run_out(&Network, &tables, &p).unwrap();
        let names: Vec<&str> = h.iter().map(|x| x.run.as_str()).collect();
        let want: Vec<&str> = tables.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names, want, "results in run order");
        for held in check {
            let m = by_hand(&p, &held);
            for k in held {
                let s = held_out_score(&m, &tables[k], p.train.decimate);
                assert_eq!(h[k], s, "folds {folds}: run {k}");
            }
        }
    }
}

/// A fitted residual network's support is counted per (Δv, dΔv/dt) cell over all speeds: its
/// law carries the speed, so a slip and slip rate seen at any speed is supported at all of
/// them (bundled soap runs, inputs Δv, dΔv/dt, v; 16 × 16 × 8 cells).
#[test]
fn a_residual_networks_support_holds_at_every_speed_its_slips_were_seen() {
    use railgrip::identify::family::Residual;
    let tables = common::bundled_tables(|n| n.starts_with("soap_"));
    let mut p = Pipeline::default_uic_z1();
    p.train.epochs = 30;
    p.train.inputs = InputSet::DvDdvV;
    p.train.support_cells = vec![16, 16, 8];
    let fitted = fit_family(&Residual, &tables, &p);
    let file = fitted.model.unwrap();
    assert!(file.base.is_some());
    let s = file.support.as_ref().unwrap();
    assert_eq!(s.cells, vec![16, 16, 8]);
    let mut seen = 0;
    for column in s.counts.chunks(8) {
        assert!(column.iter().all(|&c| c == column[0]), "{column:?}");
        seen += usize::from(column[0] >= s.min_samples);
    }
    // The slips seen are supported at every speed, including the speed cells no run reached.
    assert!(seen > 20, "{seen} supported (Δv, dΔv/dt) cells");
    // The fallback holds the residual along the slip rate: a supported cell its network's
    // raw output N at the centre, an unsupported one the count-weighted mean of the supported
    // cells' N at the same slip and speed whose slip rate has the same sign (0 without).
    assert_eq!(s.fallback, "law_held");
    let mut plain = file.clone();
    (plain.base, plain.support, plain.audit) = (None, None, None);
    plain.creep.as_mut().unwrap().blend_mps = f64::MIN_POSITIVE;
    let n = Model::new(plain).unwrap();
    let centres = railgrip::identify::support::cell_centres(&file, &s.cells);
    let own: Vec<f64> = centres
        .iter()
        .map(|x| n.mu_vt(x[0], x[1], x[2], x[3]))
        .collect();
    let ok = |j: usize| s.counts[j] >= s.min_samples;
    let (mut held, mut law_alone) = (0, 0);
    for dv in 0..16 {
        for v in 0..8 {
            let line: Vec<usize> = (0..16).map(|q| (dv * 16 + q) * 8 + v).collect();
            for &j in &line {
                if ok(j) {
                    assert_eq!(s.fallback_mu[j], own[j], "supported cell {j}");
                    continue;
                }
                let side: Vec<usize> = line
                    .iter()
                    .copied()
                    .filter(|&m| ok(m) && (centres[m][1] >= 0.0) == (centres[j][1] >= 0.0))
                    .collect();
                let w: f64 = side.iter().map(|&m| s.counts[m] as f64).sum();
                let want = if side.is_empty() {
                    law_alone += 1;
                    0.0
                } else {
                    held += 1;
                    side.iter()
                        .map(|&m| s.counts[m] as f64 * own[m])
                        .sum::<f64>()
                        / w
                };
                assert!(
                    (s.fallback_mu[j] - want).abs() <= 1e-15,
                    "cell {j}: {} against {want}",
                    s.fallback_mu[j]
                );
            }
        }
    }
    // On these runs every slip that was seen has slip rates of both signs, so no cell is left
    // to the law alone (the unit test in identify::support covers that case).
    assert!(held > 100, "{held} held, {law_alone} law alone");
}

/// Runs' tables parked in their estimates files (a pool holds tables only while it stays
/// within `train.max_pooled_samples`) and read back thinned train the same models, to the byte,
/// as the tables held in memory; a parked file that changed before it was read back is an
/// error naming it.
#[test]
fn parked_tables_train_the_same_models_as_held_ones() {
    use railgrip::campaign::{Pool, PooledRun};
    let p0 = Pipeline::default_uic_z1();
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/archive");
    let dir = tempfile::tempdir().unwrap();
    let mut tables = Vec::new();
    let mut files = Vec::new();
    for name in ["soap_120kmh_0c", "soap_120kmh_m20", "soap_120kmh_p20"] {
        let log = railgrip::ingest_file(&src.join(format!("{name}.csv")), &p0).unwrap();
        let e = railgrip::estimate::estimate(&log, &p0).unwrap();
        let file = e.write_named(dir.path(), name, false).unwrap().remove(0);
        tables.push(railgrip::identify::RunTable::from_estimates(
            name, name, "", &e,
        ));
        files.push(file);
    }
    let pooled: usize = tables.iter().map(|t| t.len()).sum();
    let mut p = p0.clone();
    p.train.model = railgrip::config::ModelChoice::Mlp;
    p.train.leave_one_run_out = false;
    p.train.polach_intervals = false;
    p.train.max_pooled_samples = pooled / 3;
    // In turn, as `railgrip run` admits finished runs: the first fits, the others do not.
    let pool = Pool::new(p.train.max_pooled_samples);
    let runs: Vec<PooledRun> = tables
        .iter()
        .zip(&files)
        .map(|(t, f)| pool.admit(t.clone(), f))
        .collect();
    let parked = runs
        .iter()
        .filter(|r| matches!(r, PooledRun::Parked(_)))
        .count();
    assert_eq!(parked, 2, "{runs:?}");
    let held = railgrip::campaign::train_models(tables.clone(), &p, None).unwrap();
    let read_back = railgrip::campaign::train_pooled(runs.clone(), &p, None).unwrap();
    assert_eq!(read_back.samples, held.samples);
    assert_eq!(read_back.mlp.to_json(), held.mlp.to_json());
    assert_eq!(
        read_back.polach.as_ref().map(|m| m.to_json()),
        held.polach.as_ref().map(|m| m.to_json())
    );
    assert_eq!(read_back.notes, held.notes);
    // Under the limit every table is held: nothing is read back.
    let roomy = Pool::new(pooled);
    assert!(tables
        .iter()
        .zip(&files)
        .all(|(t, f)| matches!(roomy.admit(t.clone(), f), PooledRun::Held(_))));
    // A parked file overwritten with another run's estimates before it is read back.
    std::fs::copy(&files[0], &files[2]).unwrap();
    let err = railgrip::campaign::train_pooled(runs.clone(), &p, None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&files[2].display().to_string()) && err.contains("changed between"),
        "{err}"
    );
    // A parked file gone before it is read back.
    std::fs::remove_file(&files[1]).unwrap();
    let err = railgrip::campaign::train_pooled(runs, &p, None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&files[1].display().to_string()) && err.contains("does not read back"),
        "{err}"
    );
}

/// A campaign whose pooled valid samples exceed `train.max_pooled_samples` trains on every
/// m-th sample of each run and axle (m the smallest that fits) and says so in a note; under the
/// limit nothing is thinned and no note is written.
#[test]
fn a_campaign_over_the_pooled_sample_limit_is_thinned_with_a_note() {
    let tables = common::bundled_tables(|n| n.starts_with("soap_120"));
    let pooled: usize = tables.iter().map(|t| t.len()).sum();
    let mut p = Pipeline::default_uic_z1();
    p.train.model = railgrip::config::ModelChoice::Mlp;
    p.train.leave_one_run_out = false;
    p.train.polach_intervals = false;
    p.train.starts = 1;
    p.train.max_pooled_samples = pooled / 3;
    let m = railgrip::identify::pooled_thinning(&tables, p.train.max_pooled_samples);
    assert!(m >= 3, "factor {m} for {pooled} samples");
    let thinned = railgrip::campaign::train_models(tables.clone(), &p, None).unwrap();
    assert!(
        thinned.samples <= p.train.max_pooled_samples,
        "{}",
        thinned.samples
    );
    let note = thinned
        .notes
        .iter()
        .find(|n| n.contains("train.max_pooled_samples"))
        .expect("a note on the thinning");
    assert!(note.contains(&format!("one sample in {m}")), "{note}");
    p.train.max_pooled_samples = pooled;
    let whole = railgrip::campaign::train_models(tables, &p, None).unwrap();
    assert_eq!(whole.samples, pooled);
    assert!(!whole
        .notes
        .iter()
        .any(|n| n.contains("train.max_pooled_samples")));
}
