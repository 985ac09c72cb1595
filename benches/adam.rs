//! Mini-batch Adam through burn against PyTorch on identical inputs, and what deeper networks
//! cost to evaluate.
//!
//!     cargo bench --bench adam
//!
//! Data: the bundled soap runs (estimated here), inputs (Δv, dΔv/dt, v), training axle 2 /
//! validation axle 3 as in seed 002, every 4th valid sample (the default pipeline's
//! decimation); networks 3-H-H-1 from railgrip's Nguyen–Widrow start (seed 1), Adam with
//! learning rate 0.003, mini-batches of 128.
//!
//! Criterion times one Adam epoch of 3-32-32-1 (`adam/epoch_3-32-32-1`) and the evaluation of
//! networks of one and two hidden layers (`model_deep/…`: 1 024 single calls, one batch of
//! 1 024), and prints the same networks' exported C header timed at `cc -O2` and
//! `cc -O3 -march=native` (skipped without cc). Then, once, side by side on the same samples, initial weights and hyperparameters
//! (burn's betas and epsilon), for H = 8, 32, 64: railgrip's `adam::train` for 10 epochs
//! without early stopping, and `benches/peers/adam_torch.py` (PyTorch, float64, 1 thread and
//! all threads) — seconds per epoch and the validation MSE after the last epoch. The PyTorch
//! peer is skipped with a message when python3 with torch is missing (`pip install torch`).
//! What the comparison depends on is printed with it: this CPU (model, the vector path
//! railgrip takes, logical CPUs) and the peer's torch version, the vector extension its CPU
//! kernels dispatch to, and whether it has MKL and oneDNN.

use std::hint::black_box;
use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use railgrip::config::{Optimizer, SplitConfig};
use railgrip::identify::adam::{self, AdamData, AdamSettings};
use railgrip::identify::dataset::{Dataset, Normalised};
use railgrip::identify::mlp::{self, Arch};
use railgrip::identify::InputSet;
use railgrip::model::{c_header, Model};
use railgrip::Pipeline;

fn data() -> Dataset {
    let tables = common::bundled_tables(|n| n.starts_with("soap_"));
    let split = SplitConfig::Axles {
        train: vec![2],
        val: vec![3],
    };
    Dataset::build(&tables, InputSet::DvDdvV, &split, 4).unwrap()
}

fn settings(epochs: usize) -> AdamSettings {
    AdamSettings {
        optimizer: Optimizer::Adam,
        learning_rate: 0.003,
        weight_decay: 0.0,
        batch: 128,
        max_epochs: epochs,
        // No early stopping: every epoch runs.
        patience: epochs + 1,
    }
}

/// A trained model file of `layers` (a few Adam epochs: weights of a realistic size).
fn model(layers: &str) -> Model {
    let text = railgrip::config::DEFAULT_PIPELINE_TOML
        .replace(
            "hidden = 10\n",
            &format!("layers = {layers}\noptimizer = \"adam\"\n"),
        )
        .replace(
            "inputs = [\"dv_mps\", \"ddv_mps2\"]",
            "inputs = [\"dv_mps\", \"ddv_mps2\", \"v_mps\"]",
        )
        .replace("epochs = 1000", "epochs = 3");
    let pipeline = Pipeline::from_toml(&text, "bench pipeline").unwrap();
    let tables = common::bundled_tables(|n| n.starts_with("soap_"));
    let mut t = railgrip::identify::train_mlp(&tables, &pipeline.train, None).unwrap();
    t.reference_speed_mps = railgrip::identify::median_speed(&tables);
    let creep = railgrip::identify::creep_spec(&pipeline, t.reference_speed_mps).unwrap();
    let provenance = railgrip::model::Provenance {
        inputs: vec![],
        pipeline: "bench".into(),
        pipeline_sha256: String::new(),
        seed: 1,
        crate_version: String::new(),
        created: String::new(),
        generation: None,
        calibration: None,
    };
    let file = railgrip::identify::export::mlp_file(&t, creep, provenance, None).unwrap();
    Model::new(file).unwrap()
}

#[allow(clippy::too_many_lines)] // a test or benchmark: one scenario end to end
fn bench(c: &mut Criterion) {
    let d = data();
    let Normalised {
        x,
        y,
        vx,
        vy,
        scale,
        ..
    } = d.normalised();
    let ad = AdamData {
        x: &x,
        y: &y,
        vx: &vx,
        vy: &vy,
        scale,
    };
    eprintln!("{} training, {} validation samples", y.len(), vy.len());

    let mut g = c.benchmark_group("adam");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    let arch = Arch {
        inputs: 3,
        hidden: vec![32, 32],
    };
    let theta0 = mlp::nguyen_widrow_layers(&arch, 1);
    g.bench_function("epoch_3-32-32-1", |b| {
        b.iter(|| {
            adam::train(&arch, &ad, theta0.clone(), &settings(1), 1, None)
                .unwrap()
                .history[0]
                .val_mse
        })
    });
    g.finish();

    // Evaluation: 1 024 inputs spread over the data.
    let pts: Vec<[f64; 3]> = (0..1024)
        .map(|i| {
            let j = i * (d.n_val() / 1024).max(1);
            let r = &d.val_x[3 * j..3 * j + 3];
            [r[0], r[1], r[2]]
        })
        .collect();
    let dv: Vec<f64> = pts.iter().map(|p| p[0]).collect();
    let ddv: Vec<f64> = pts.iter().map(|p| p[1]).collect();
    let v: Vec<f64> = pts.iter().map(|p| p[2]).collect();
    let mut g = c.benchmark_group("model_deep");
    for layers in ["[10]", "[32]", "[8, 8]", "[32, 32]", "[64, 64]"] {
        let m = model(layers);
        let name = m.file.architecture();
        g.bench_function(format!("mu_1k/{name}"), |b| {
            b.iter(|| {
                let mut s = 0.0;
                for i in 0..dv.len() {
                    s += m.mu_v(black_box(dv[i]), ddv[i], v[i]);
                }
                s
            })
        });
        let mut out = vec![0.0; dv.len()];
        g.bench_function(format!("mu_batch_1k/{name}"), |b| {
            b.iter(|| {
                m.mu_batch(black_box(&dv), &ddv, &v, &mut out);
                out[0]
            })
        });
    }
    g.finish();

    // The exported C header of the same networks (3 inputs: rg_mu_v and the batch with speeds).
    eprintln!("C header of the same networks, ns per μ: single call / batch sample");
    for layers in ["[10]", "[32]", "[8, 8]", "[32, 32]", "[64, 64]"] {
        let m = model(layers);
        let header = c_header::c_header(&m.file, "rg", "bench");
        for r in common::time_c_header(
            &header,
            "rg_mu_v(dv[i], ddv[i], v[i])",
            "rg_mu_batch(dv, ddv, v, out, 1024)",
        ) {
            match r {
                Ok((opt, ns, nb)) => eprintln!(
                    "  {:<12} cc {opt:<17} {ns:8.1} / {nb:8.1}",
                    m.file.architecture()
                ),
                Err(e) => eprintln!("  SKIPPED C header timing: {e}"),
            }
        }
    }

    // Side by side with PyTorch on the same samples, start and hyperparameters.
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
    std::fs::create_dir_all(&dir).unwrap();
    let peer = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("benches/peers/adam_torch.py");
    let epochs = 10;
    eprintln!("adam: CPU {}", common::cpu_line());
    let mut peer_env: Option<String> = None;
    println!(
        "\n{:<12} {:>18} {:>14} {:>18} {:>14} {:>18} {:>14}",
        "network",
        "railgrip s/epoch",
        "val MSE",
        "torch 1 thr s/ep",
        "val MSE",
        "torch all s/ep",
        "val MSE"
    );
    for h in [8, 32, 64] {
        let arch = Arch {
            inputs: 3,
            hidden: vec![h, h],
        };
        let theta0 = mlp::nguyen_widrow_layers(&arch, 1);
        let t0 = Instant::now();
        let fit = adam::train(&arch, &ad, theta0.clone(), &settings(epochs), 1, None).unwrap();
        let ours = t0.elapsed().as_secs_f64() / epochs as f64;
        let ours_val = fit.history.last().unwrap().val_mse;
        let problem = dir.join(format!("adam_problem_{h}.json"));
        let json = serde_json::json!({
            "inputs": 3, "hidden": [h, h], "train_x": x, "train_y": y, "val_x": vx, "val_y": vy,
            "theta0": theta0, "scale": scale, "optimizer": "adam", "learning_rate": 0.003,
            "weight_decay": 0.0, "batch": 128, "epochs": epochs,
        });
        std::fs::write(&problem, json.to_string()).unwrap();
        let mut peer_cols = Vec::new();
        for threads in ["1", "0"] {
            let mut cmd = Command::new("python3");
            cmd.arg(&peer).arg(&problem);
            if threads != "0" {
                cmd.arg(threads);
            }
            match cmd.output() {
                Ok(o) if o.status.success() => {
                    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
                    peer_env.get_or_insert_with(|| {
                        let has = |k: &str| match r[k].as_bool() {
                            Some(true) => "yes",
                            Some(false) => "no",
                            None => "?",
                        };
                        format!(
                            "torch {}, CPU kernels {}, MKL {}, oneDNN {}",
                            r["torch"].as_str().unwrap_or("?"),
                            r["cpu_capability"].as_str().unwrap_or("unknown"),
                            has("mkl"),
                            has("mkldnn")
                        )
                    });
                    peer_cols.push(format!(
                        "{:>18.3} {:>14.3e}",
                        r["s_per_epoch"].as_f64().unwrap(),
                        r["val_mse"]
                            .as_array()
                            .unwrap()
                            .last()
                            .unwrap()
                            .as_f64()
                            .unwrap()
                    ));
                }
                Ok(o) => {
                    eprintln!(
                        "SKIPPED PyTorch peer: python3 {} failed: {} (needs torch: pip install torch)",
                        peer.display(),
                        String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
                    );
                    peer_cols.push(format!("{:>18} {:>14}", "–", "–"));
                }
                Err(e) => {
                    eprintln!("SKIPPED PyTorch peer: no python3 ({e})");
                    peer_cols.push(format!("{:>18} {:>14}", "–", "–"));
                }
            }
        }
        println!(
            "{:<12} {:>18.3} {:>14.3e} {}",
            arch.to_string(),
            ours,
            ours_val,
            peer_cols.join(" ")
        );
    }
    if let Some(env) = peer_env {
        eprintln!("adam: peer {env}");
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
