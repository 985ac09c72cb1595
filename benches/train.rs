//! Levenberg–Marquardt training on 50 000 samples against scipy, and model evaluation.
//!
//!     cargo bench --bench train
//!
//! Data: the bundled soap runs (estimated here), training axle 2 / validation axle 3 as in
//! seed 002, the first 50 000 samples of each after decimation by 2; the 10-neuron network from
//! Nguyen–Widrow weights (seed 1). Criterion times one LM epoch (`train/normal_equations_50k`:
//! JᵀJ, Jᵀr over 50 000 samples) and one model evaluation (`model/mu`, `model/mu_batch_1k`).
//! Then, once each, side by side on the same problem and initial weights:
//! - railgrip: trainlm defaults with validation stop, wall time and the validation MSE of the
//!   weights it returns, and the time at which its validation MSE first reached scipy's;
//! - scipy: `benches/peers/lm_scipy.py` (`least_squares(method='lm')`, MINPACK, analytic
//!   Jacobian) — skipped with a message when python3 with numpy and scipy is missing; printed
//!   with this CPU (model, the vector path railgrip takes, logical CPUs) and scipy's and
//!   numpy's versions and BLAS;
//! - the exported C header: ns per call and per sample of the batch function, compiled with the
//!   system `cc -O2` and `cc -O3 -march=native` (skipped without cc).
//!
//! `RAILGRIP_BENCH_QUICK=1` skips the scipy run (4 minutes) and repeats training once.

use std::hint::black_box;
use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use railgrip::config::SplitConfig;
use railgrip::identify::dataset::{Dataset, Normalised};
use railgrip::identify::lm::{LeastSquares, LmSettings};
use railgrip::identify::mlp::{self, Shape};
use railgrip::identify::InputSet;
use railgrip::identify::{creep_spec, median_speed, train_on, MlpProblem};
use railgrip::model::{c_header, Model, Provenance};
use railgrip::Pipeline;

const N: usize = 50_000;

fn data() -> (Dataset, f64) {
    let tables = common::bundled_tables(|n| n.starts_with("soap_"));
    let split = SplitConfig::Axles {
        train: vec![2],
        val: vec![3],
    };
    let d = Dataset::build(&tables, InputSet::DvDdv, &split, 2).unwrap();
    assert!(
        d.n_train() >= N && d.n_val() >= N,
        "{} {}",
        d.n_train(),
        d.n_val()
    );
    (d.head(N), median_speed(&tables))
}

#[allow(clippy::too_many_lines)] // a test or benchmark: one scenario end to end
fn bench(c: &mut Criterion) {
    let (d, v_ref) = data();
    let shape = Shape::one(2, 10);
    let Normalised {
        x,
        y,
        vx,
        vy,
        scale,
        ..
    } = d.normalised();
    let theta0 = mlp::nguyen_widrow(shape, 1);

    // The problem as scipy will see it.
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
    std::fs::create_dir_all(&dir).unwrap();
    let problem_json = dir.join("lm_problem_50k.json");
    let json = serde_json::json!({
        "inputs": 2, "hidden": 10, "train_x": x, "train_y": y, "val_x": vx, "val_y": vy,
        "theta0": theta0, "scale": scale,
    });
    std::fs::write(&problem_json, json.to_string()).unwrap();

    let problem = MlpProblem::new(shape, x, y, vx, vy, scale);
    let mut g = c.benchmark_group("train");
    g.sample_size(20).measurement_time(Duration::from_secs(5));
    g.bench_function("normal_equations_50k", |b| {
        b.iter(|| problem.normal_equations(black_box(&theta0)).sse)
    });
    g.finish();

    // Full training, railgrip (best of 3 wall times; the result is deterministic).
    let mut best_s = f64::INFINITY;
    let mut trained = None;
    let repeats = if std::env::var("RAILGRIP_BENCH_QUICK").as_deref() == Ok("1") {
        1
    } else {
        3
    };
    for _ in 0..repeats {
        let t0 = Instant::now();
        let t = train_on(&d, 10, 1, LmSettings::default(), None).unwrap();
        best_s = best_s.min(t0.elapsed().as_secs_f64());
        trained = Some(t);
    }
    let mut trained = trained.unwrap();
    eprintln!(
        "railgrip LM: {:.3} s, {} epochs ({}), train MSE {:.4e}, val MSE {:.4e}",
        best_s,
        trained.history.len(),
        trained.stop.text(),
        trained.train_mse,
        trained.val_mse
    );

    eprintln!("train: CPU {}", common::cpu_line());
    // scipy peer (RAILGRIP_BENCH_QUICK=1 skips it while iterating on the evaluator).
    let quick = std::env::var("RAILGRIP_BENCH_QUICK").as_deref() == Ok("1");
    let peer = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("benches/peers/lm_scipy.py");
    let run = (!quick).then(|| {
        Command::new("python3")
            .arg(&peer)
            .arg(&problem_json)
            .output()
    });
    match run {
        None => eprintln!("SKIPPED scipy peer: RAILGRIP_BENCH_QUICK=1"),
        Some(Ok(o)) if o.status.success() => {
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            let (s, val) = (v["seconds"].as_f64().unwrap(), v["val_mse"].as_f64().unwrap());
            eprintln!(
                "scipy least_squares(method='lm'): {:.3} s, {} evaluations, train MSE {:.4e}, val MSE {:.4e} ({}; {})",
                s, v["nfev"], v["train_mse"].as_f64().unwrap(), val, v["message"], v["versions"].as_str().unwrap_or("versions unknown")
            );
            let reach = trained.history.iter().find(|e| e.val_mse <= val).map(|e| e.elapsed_s);
            eprintln!(
                "speed-up {:.1}x to finish; railgrip's validation MSE {} scipy's{}",
                s / best_s,
                if trained.val_mse <= val { "is at or below" } else { "is above" },
                match reach {
                    Some(r) => format!(" (first reached after {r:.3} s: {:.1}x)", s / r),
                    None => String::new(),
                }
            );
        }
        Some(Ok(o)) => eprintln!(
            "SKIPPED scipy peer: python3 {} failed: {} (needs numpy and scipy: pip install numpy scipy)",
            peer.display(),
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
        ),
        Some(Err(e)) => eprintln!("SKIPPED scipy peer: no python3 ({e})"),
    }

    // Model evaluation.
    trained.reference_speed_mps = v_ref;
    let p = Pipeline::default_uic_z1();
    let file = railgrip::identify::export::mlp_file(
        &trained,
        creep_spec(&p, v_ref).unwrap(),
        Provenance {
            inputs: vec![],
            pipeline: p.source.clone(),
            pipeline_sha256: "0".repeat(64),
            seed: 1,
            crate_version: env!("CARGO_PKG_VERSION").into(),
            created: "2026-01-01T00:00:00Z".into(),
            generation: None,
            calibration: None,
        },
        None,
    )
    .unwrap();
    let model = Model::new(file.clone()).unwrap();
    let inputs: Vec<(f64, f64)> = (0..1024)
        .map(|i| (0.004 * i as f64, ((i * 7919) % 1000) as f64 / 100.0 - 5.0))
        .collect();
    let dv: Vec<f64> = inputs.iter().map(|p| p.0).collect();
    let ddv: Vec<f64> = inputs.iter().map(|p| p.1).collect();
    let mut out = vec![0.0; 1024];
    let mut g = c.benchmark_group("model");
    g.sample_size(30).measurement_time(Duration::from_secs(4));
    g.throughput(criterion::Throughput::Elements(1024));
    g.bench_function("mu_1k", |b| {
        b.iter(|| {
            let mut s = 0.0;
            for (a, d) in &inputs {
                s += model.mu(black_box(*a), black_box(*d));
            }
            s
        })
    });
    let polach = Model::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("models/golden/synthetic_polach.json"),
    )
    .unwrap();
    g.bench_function("polach_mu_1k", |b| {
        b.iter(|| {
            let mut s = 0.0;
            for (a, d) in &inputs {
                s += polach.mu_v(black_box(*a), black_box(*d), 30.0);
            }
            s
        })
    });
    g.bench_function("mu_batch_1k", |b| {
        b.iter(|| {
            model.mu_batch(black_box(&dv), &ddv, &[], &mut out);
            out[7]
        })
    });
    // The same network without its data-support grid (as a version-1 file evaluates): what
    // the support blend costs.
    let mut bare = file.clone();
    bare.support = None;
    bare.audit = None;
    let bare = Model::new(bare).unwrap();
    let outside = inputs
        .iter()
        .filter(|(a, d)| model.support_weight(*a, *d, f64::NAN) != Some(1.0))
        .count();
    eprintln!("model: {outside} of 1024 benchmark inputs outside the full data support");
    g.bench_function("mu_1k_without_support", |b| {
        b.iter(|| {
            let mut s = 0.0;
            for (a, d) in &inputs {
                s += bare.mu(black_box(*a), black_box(*d));
            }
            s
        })
    });
    g.bench_function("mu_batch_1k_without_support", |b| {
        b.iter(|| {
            bare.mu_batch(black_box(&dv), &ddv, &[], &mut out);
            out[7]
        })
    });
    g.finish();

    // The C header, timed by a small C program.
    let header = c_header::c_header(&file, "rg", "bench");
    for r in common::time_c_header(
        &header,
        "rg_mu(dv[i], ddv[i])",
        "rg_mu_batch(dv, ddv, 0, out, 1024)",
    ) {
        match r {
            Ok((opt, ns, nb)) => eprintln!(
                "C header (cc {opt}): {ns:.1} ns per rg_mu call, {nb:.1} ns per sample in rg_mu_batch (best of 20 × 204 800)"
            ),
            Err(e) => eprintln!("SKIPPED C header timing: {e}"),
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
