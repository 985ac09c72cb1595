//! Levenberg–Marquardt per epoch against the strongest peer a user would pick: MATLAB trainlm
//! written with numpy (`benches/peers/trainlm_numpy.py`), on identical inputs in the same run.
//!
//!     cargo bench --bench lm
//!
//! Problems (normalised as railgrip trains them, validation stop off so both run 20 epochs):
//! - `lm/2-10-1/15k`: the seed 002 network (Δv, dΔv/dt → 10 tanh → μ), the first 15 000
//!   training (axle 2) and validation (axle 3) samples of the bundled soap runs, decimation 4;
//! - `lm/3-40-1/15k`: the same with speed as a third input and 40 neurons (P = 201);
//! - `lm/2-10-1/1M`: one million training and 250 000 validation samples of a smooth synthetic
//!   law (5 epochs; railgrip only; `LM_SKIP_1M=1` leaves it out).
//!
//! `…/normal_equations` and `…/sse` time one epoch's parts: JᵀJ and Jᵀr (the Jacobian built
//! block by block, the symmetric rank-k update), and one error evaluation (a trial step).
//!
//! For each 15k problem, railgrip's per-epoch time (criterion; throughput in epochs/s, and best
//! of 3 trainings as the peer times itself) is printed beside numpy's with one BLAS thread and
//! with all threads (best of 3 trainings) with the ratios, and the per-epoch training MSEs of
//! the two are compared (relative difference over the first 20 epochs). First it prints what
//! the ratio depends on: the CPU (model, the vector path railgrip takes, logical CPUs) and the peer's
//! numpy version, BLAS and its run-time kernel, numpy's SIMD extensions and np.tanh's ns per
//! element. Without python3 and numpy the peer is skipped with a message.

use std::path::PathBuf;
use std::time::Duration;

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use railgrip::config::SplitConfig;
use railgrip::identify::dataset::{Dataset, RunTable};
use railgrip::identify::lm::{self, LevenbergMarquardt, LmSettings};
use railgrip::identify::mlp::{self, Shape};
use railgrip::identify::InputSet;
use railgrip::identify::MlpProblem;
use railgrip::model::Epoch;

const EPOCHS: u64 = 20;

fn settings(epochs: u64) -> LmSettings {
    LmSettings {
        epochs,
        min_grad: 0.0,
        max_fail: 1_000_000,
        ..LmSettings::default()
    }
}

/// A normalised problem as `train_on` builds it, and its input count.
struct Data {
    k: usize,
    x: Vec<f64>,
    y: Vec<f64>,
    vx: Vec<f64>,
    vy: Vec<f64>,
    scale: f64,
}

/// The first `n` samples of each set of `d`, scaled as training scales them.
fn normalise(d: &Dataset, n: usize) -> Data {
    let m = d.head(n).normalised();
    Data {
        k: d.inputs.count(),
        x: m.x,
        y: m.y,
        vx: m.vx,
        vy: m.vy,
        scale: m.scale,
    }
}

fn seed002(tables: &[RunTable], inputs: InputSet, n: usize) -> Data {
    let split = SplitConfig::Axles {
        train: vec![2],
        val: vec![3],
    };
    let d = Dataset::build(tables, inputs, &split, 4).unwrap();
    assert!(
        d.n_train() >= n && d.n_val() >= n,
        "{} {}",
        d.n_train(),
        d.n_val()
    );
    normalise(&d, n)
}

/// `n` training and `n / 4` validation samples of
/// μ = 0.08 (1 − e^(−2Δv)) e^(−0.1Δv) + 0.01 dΔv/dt.
fn synthetic(n: usize) -> Data {
    let mut rng = railgrip::sim::Rng::new(5);
    let mut d = Dataset {
        inputs: InputSet::DvDdv,
        train_x: Vec::with_capacity(2 * n),
        train_y: Vec::with_capacity(n),
        val_x: vec![],
        val_y: vec![],
    };
    for i in 0..n + n / 4 {
        let (dv, ddv) = (4.0 * rng.uniform(), 6.0 * rng.uniform() - 3.0);
        let mu = 0.08 * (1.0 - (-2.0 * dv).exp()) * (-0.1 * dv).exp() + 0.01 * ddv;
        let (x, y) = if i < n {
            (&mut d.train_x, &mut d.train_y)
        } else {
            (&mut d.val_x, &mut d.val_y)
        };
        x.extend([dv, ddv]);
        y.push(mu);
    }
    normalise(&d, n)
}

fn train(p: &MlpProblem, theta0: &[f64], epochs: u64) -> Vec<Epoch> {
    let (solver, _) = lm::run(
        p,
        LevenbergMarquardt::new(settings(epochs)),
        theta0.to_vec(),
    )
    .unwrap();
    solver.history().to_vec()
}

fn bench(c: &mut Criterion) {
    let tables = common::bundled_tables(|n| n.starts_with("soap_"));
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
    std::fs::create_dir_all(&dir).unwrap();
    let mut g = c.benchmark_group("lm");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    let mut peers = Vec::new();
    for (name, inputs, hidden) in [
        ("2-10-1/15k", InputSet::DvDdv, 10),
        ("3-40-1/15k", InputSet::DvDdvV, 40),
    ] {
        let d = seed002(&tables, inputs, 15_000);
        let shape = Shape::one(d.k, hidden);
        let theta0 = mlp::nguyen_widrow(shape, 1);
        let json = dir.join(format!("trainlm_{}.json", name.replace('/', "_")));
        common::write_trainlm_problem(
            &json,
            d.k,
            hidden,
            (&d.x, &d.y, &d.vx, &d.vy),
            d.scale,
            &theta0,
            &settings(EPOCHS),
        );
        let p = MlpProblem::new(shape, d.x, d.y, d.vx, d.vy, d.scale);
        {
            use railgrip::identify::lm::LeastSquares;
            g.throughput(Throughput::Elements(1));
            g.bench_function(format!("{name}/normal_equations"), |b| {
                b.iter(|| p.normal_equations(&theta0).sse)
            });
            g.bench_function(format!("{name}/sse"), |b| b.iter(|| p.sse(&theta0)));
        }
        let ours = train(&p, &theta0, EPOCHS);
        g.throughput(Throughput::Elements(ours.len() as u64));
        g.bench_function(name, |b| b.iter(|| train(&p, &theta0, EPOCHS)));
        // railgrip's seconds per epoch timed as the peer times itself (best of 3 trainings),
        // for the ratio printed beside the peer's.
        let per_epoch = (0..3)
            .map(|_| {
                let t = std::time::Instant::now();
                let n = train(&p, &theta0, EPOCHS).len().max(1);
                t.elapsed().as_secs_f64() / n as f64
            })
            .fold(f64::INFINITY, f64::min);
        peers.push((name, shape.n_params(), json, ours, per_epoch));
    }
    eprintln!("lm: CPU {}", common::cpu_line());
    if let Some((_, _, json, _, _)) = peers.first() {
        match common::numpy_environment(json) {
            Ok(line) => eprintln!("lm: peer {line}"),
            Err(e) => eprintln!("SKIPPED numpy peer: {e}"),
        }
    }
    for (name, n_params, json, ours, per_epoch) in peers {
        match (
            common::trainlm_numpy(&json, 3, Some(1), ""),
            common::trainlm_numpy(&json, 3, None, ""),
        ) {
            (Ok((one, mse)), Ok((all, _))) => {
                let worst = ours
                    .iter()
                    .zip(&mse)
                    .take(20)
                    .map(|(a, b)| ((a.train_mse - b) / b).abs())
                    .fold(0.0f64, f64::max);
                eprintln!(
                    "lm/{name} (P = {n_params}): railgrip {:.3} ms/epoch (best of 3 trainings, every logical CPU); numpy trainlm {:.3} ms/epoch on 1 BLAS thread, {:.3} ms/epoch on all: numpy time / railgrip time {:.1}x / {:.1}x; {} vs {} epochs; worst relative difference of the training MSE over the first 20 epochs {worst:.2e}",
                    per_epoch * 1e3,
                    one * 1e3,
                    all * 1e3,
                    one / per_epoch,
                    all / per_epoch,
                    ours.len(),
                    mse.len()
                );
            }
            (Err(e), _) | (_, Err(e)) => eprintln!("SKIPPED numpy peer for lm/{name}: {e}"),
        }
    }
    if std::env::var("LM_SKIP_1M").is_err() {
        let d = synthetic(1_000_000);
        let shape = Shape::one(2, 10);
        let theta0 = mlp::nguyen_widrow(shape, 1);
        let p = MlpProblem::new(shape, d.x, d.y, d.vx, d.vy, d.scale);
        g.throughput(Throughput::Elements(5));
        g.bench_function("2-10-1/1M", |b| b.iter(|| train(&p, &theta0, 5)));
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
