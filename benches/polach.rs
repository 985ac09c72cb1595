//! The Polach fit on 150 000 samples of the bundled soap runs, against scipy.
//!
//!     cargo bench --bench polach
//!
//! Data: the valid estimates of the bundled soap runs (estimated here) with slip, pooled in
//! run order, the first 150 000; the pipeline's patch and static wheel load. Criterion times
//! the whole identifiability-aware fit (`polach/pooled_fit_150k`: LM with the analytic
//! Jacobian, bounds and identifiability checks; one core — the fit is sequential), the same
//! with the profile likelihood of every parameter (`polach/pooled_fit_150k_with_profiles`,
//! both sides of each parameter in parallel), and everything `railgrip train` fits with
//! Polach's law on the bundled soap runs (`polach/campaign_fits_bundled`: pooled, per-run and
//! per-temperature fits, profiles, the temperature forms; all cores). Then, once,
//! side by side on the same samples and start: scipy `least_squares(method='trf')` with the same
//! bounds, tolerances and analytic Jacobian (`benches/peers/polach_scipy.py`; skipped with a
//! message without python3, numpy and scipy, or with `RAILGRIP_BENCH_QUICK=1`), its best of 3
//! wall times and its parameters against railgrip's.

use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use railgrip::identify::polach::{fit_campaign, fit_polach, DEFAULT_START};
use railgrip::identify::RunTable;
use railgrip::Pipeline;

const N: usize = 150_000;

fn bench(c: &mut Criterion) {
    let p = Pipeline::default_uic_z1();
    let (patch, q) = railgrip::identify::pipeline_patch(&p).unwrap();
    let tables = common::bundled_tables(|n| n.starts_with("soap_"));
    let mut t = RunTable::default();
    'all: for r in &tables {
        for i in 0..r.len() {
            if r.dv_mps[i] > 0.0 && r.v_mps[i] > 0.0 {
                t.push_row(r, i);
                if t.len() == N {
                    break 'all;
                }
            }
        }
    }
    assert_eq!(t.len(), N);
    let start = DEFAULT_START;
    let fit = || fit_polach("pooled", &[&t], patch, q, 1, start, false, None).unwrap();
    let mut g = c.benchmark_group("polach");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    g.bench_function("pooled_fit_150k", |b| b.iter(fit));
    // What the intervals cost: the same fit with the profile likelihood of every parameter
    // (both sides in parallel: on all cores).
    g.bench_function("pooled_fit_150k_with_profiles", |b| {
        b.iter(|| fit_polach("pooled", &[&t], patch, q, 1, start, true, None).unwrap())
    });
    // The whole Polach part of `railgrip train` on the bundled soap runs at the pipeline's
    // decimation: pooled, per-run and per-temperature fits, profiles and the temperature
    // forms (all cores).
    let decimate = p.train.decimate;
    let degree = p.train.temperature_degree;
    g.bench_function("campaign_fits_bundled", |b| {
        b.iter(|| fit_campaign(&tables, patch, q, decimate, degree, true))
    });
    g.finish();

    let t0 = Instant::now();
    let f = fit();
    let secs = t0.elapsed().as_secs_f64();
    eprintln!(
        "railgrip fit_polach: {secs:.3} s, {} LM iterations ({}), μ0 {:.5} A {:.4} B {:.4} k_A {:.5} k_S {:.5}, RMSE {:.6}, status {:?}",
        f.iterations, f.stop_reason, f.mu0, f.a_ratio, f.b_s_per_m, f.k_a, f.k_s, f.rmse, f.status
    );

    if std::env::var("RAILGRIP_BENCH_QUICK").as_deref() == Ok("1") {
        eprintln!("SKIPPED scipy peer: RAILGRIP_BENCH_QUICK=1");
        return;
    }
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
    std::fs::create_dir_all(&dir).unwrap();
    let problem = dir.join("polach_problem_150k.json");
    let json = serde_json::json!({
        "v": t.v_mps, "dv": t.dv_mps, "mu": t.mu, "q_n": q,
        "c_per_s": std::f64::consts::PI * patch.g_pa * patch.a_m * patch.b_m * patch.c11 / 4.0,
        "start": [start.mu0, start.a_ratio, start.b_s_per_m, start.k_a, start.k_s / start.k_a],
    });
    std::fs::write(&problem, json.to_string()).unwrap();
    let peer = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("benches/peers/polach_scipy.py");
    match Command::new("python3").arg(&peer).arg(&problem).output() {
        Ok(o) if o.status.success() => {
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            let s = v["seconds"].as_f64().unwrap();
            let x: Vec<f64> = v["params"]
                .as_array()
                .unwrap()
                .iter()
                .map(|a| a.as_f64().unwrap())
                .collect();
            eprintln!(
                "scipy least_squares(method='trf'): {s:.3} s (best of 3), {} evaluations, μ0 {:.5} A {:.4} B {:.4} k_A {:.5} k_S {:.5}, RMSE {:.6} ({}; {}); railgrip {:.1}× faster",
                v["nfev"], x[0], x[1], x[2], x[3], x[4], v["rmse"].as_f64().unwrap(), v["message"], v["versions"].as_str().unwrap_or("versions unknown"), s / secs
            );
        }
        Ok(o) => eprintln!(
            "SKIPPED scipy peer: {}",
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .last()
                .unwrap_or("")
        ),
        Err(e) => eprintln!("SKIPPED scipy peer: no python3 ({e})"),
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
