//! Conditioning + estimation of a 1-hour run (1.5 M samples at 417 Hz, 9 channels) on one
//! core (`estimate/1h`), beside the bare cost of the same low-pass filtering done channel by
//! channel with the biquad crate's `DirectForm2Transposed::run` (`biquad_bare/1h`: 9 channels
//! forward and backward, no padding, no despiking, no derivatives, no estimation). For scipy's
//! time on the same job run `python3 tests/data/signal/make_reference.py`.
//!
//! Afterwards it prints what the tachometer/pressure cut-off does to accuracy: μ RMSE against
//! the simulator's truth (valid samples with Δv > 0.2 m/s, mean over the axles) for the bundled
//! soap scene with clean sensors and with its sensor effects (noise, spikes, tachometer
//! quantisation), at 4, 6, 8 and 12 Hz, and for the causal mode at 4 Hz.
//!
//!     cargo bench --bench estimate

#[path = "../tests/common/mod.rs"]
mod common;

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use biquad::{Biquad, DirectForm2Transposed};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use railgrip::format::{Signal, AXLES};
use railgrip::ingest::RunLog;
use railgrip::signal::LowPass4;
use railgrip::Pipeline;

const FS: f64 = 417.0;

/// One hour of the analytic braking signals of tests/common with radar noise and spikes.
fn hour() -> RunLog {
    let n = (3600.0 * FS) as usize;
    let time_s: Vec<f64> = (0..n).map(|i| i as f64 / FS).collect();
    let mut rng = common::Rng::new(5);
    let mut sig = |s: Signal| -> Vec<f64> {
        time_s
            .iter()
            .map(|&t| {
                let x = common::analytic(s, t);
                if s == Signal::VRadar {
                    let spike = if rng.uniform() < 0.3 / FS { 3.0 } else { 0.0 };
                    x + 0.05 * (rng.uniform() - 0.5) + spike
                } else {
                    x
                }
            })
            .collect()
    };
    let v = sig(Signal::VRadar);
    let omega = std::array::from_fn(|a| sig(Signal::Omega(a as u8 + 1)));
    let p = std::array::from_fn(|a| sig(Signal::Pressure(a as u8 + 1)));
    common::runlog("hour.csv", FS, time_s, v, omega, p)
}

/// The bare filtering: each of the 9 channels forward and backward through two biquads.
fn biquad_bare(log: &RunLog, filters: &[LowPass4; 3]) -> f64 {
    let mut acc = 0.0;
    let chans: Vec<(&[f64], &LowPass4)> = std::iter::once((&log.v_radar_mps[..], &filters[0]))
        .chain(log.omega_radps.iter().map(|w| (&w[..], &filters[1])))
        .chain(log.p_bar.iter().map(|p| (&p[..], &filters[2])))
        .collect();
    let mut y = vec![0.0; log.len()];
    for (x, f) in chans {
        let [c1, c2] = f
            .sections()
            .map(|[b0, b1, b2, a1, a2]| biquad::Coefficients { a1, a2, b0, b1, b2 });
        let mut s1 = DirectForm2Transposed::<f64>::new(c1);
        let mut s2 = DirectForm2Transposed::<f64>::new(c2);
        for (o, &v) in y.iter_mut().zip(x) {
            *o = s2.run(s1.run(v));
        }
        let mut s1 = DirectForm2Transposed::<f64>::new(c1);
        let mut s2 = DirectForm2Transposed::<f64>::new(c2);
        for o in y.iter_mut().rev() {
            *o = s2.run(s1.run(*o));
        }
        acc += y[y.len() / 2];
    }
    acc
}

fn bench(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let log = hour();
    let p = Pipeline::default_uic_z1();
    let filters = [
        LowPass4::butterworth(p.filters.radar_cutoff_hz, FS).unwrap(),
        LowPass4::butterworth(p.filters.tacho_cutoff_hz, FS).unwrap(),
        LowPass4::butterworth(p.filters.pressure_cutoff_hz, FS).unwrap(),
    ];
    let mut g = c.benchmark_group("estimate");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    g.throughput(Throughput::Elements(log.len() as u64));
    g.bench_function("1h", |b| {
        b.iter(|| {
            pool.install(|| {
                let e = railgrip::estimate::estimate(black_box(&log), &p).unwrap();
                e.axles[AXLES - 1].mu[e.len() / 2]
            })
        })
    });
    g.bench_function("biquad_bare/1h", |b| {
        b.iter(|| biquad_bare(black_box(&log), &filters))
    });
    g.finish();
    accuracy_table();
}

/// μ RMSE against truth per filter setting: (clean sensors, scene's sensors).
fn accuracy_table() {
    use railgrip::sim::{simulate, OutputFormat, Scene};
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let path = root.join("pipelines/scenes/soap_120kmh_p20.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let clean = text
        .replace("\"radar_noise\", ", "")
        .replace("\"radar_spikes\", ", "")
        .replace("\"tacho_quantization\",", "")
        .replace("\"pressure_noise\"", "");
    let dir = tempfile::tempdir().unwrap();
    let runs: Vec<(RunLog, railgrip::sim::Truth)> = [clean, text]
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let sc = Scene::from_toml(t, "scene.toml", path.parent()).unwrap();
            let out = simulate(&sc, None).unwrap();
            let files = out
                .write(dir.path(), &format!("run{k}"), OutputFormat::Csv)
                .unwrap();
            let log = railgrip::ingest_file(&files[0], &Pipeline::default_uic_z1()).unwrap();
            (log, out.truth)
        })
        .collect();
    let base = railgrip::config::DEFAULT_PIPELINE_TOML;
    eprintln!("tacho/pressure cut-off | μ RMSE clean sensors | μ RMSE with sensor effects");
    for (label, edits) in [
        ("4 Hz (default)", vec![]),
        (
            "6 Hz",
            vec![
                ("tacho_cutoff_hz = 4.0 ", "tacho_cutoff_hz = 6.0 "),
                ("pressure_cutoff_hz = 4.0 ", "pressure_cutoff_hz = 6.0 "),
            ],
        ),
        (
            "8 Hz",
            vec![
                ("tacho_cutoff_hz = 4.0 ", "tacho_cutoff_hz = 8.0 "),
                ("pressure_cutoff_hz = 4.0 ", "pressure_cutoff_hz = 8.0 "),
            ],
        ),
        (
            "12 Hz",
            vec![
                ("tacho_cutoff_hz = 4.0 ", "tacho_cutoff_hz = 12.0 "),
                ("pressure_cutoff_hz = 4.0 ", "pressure_cutoff_hz = 12.0 "),
            ],
        ),
        (
            "4 Hz causal",
            vec![("mode = \"zero_phase\"", "mode = \"causal\"")],
        ),
    ] {
        let mut t = base.to_string();
        for (a, b) in edits {
            t = t.replace(a, b);
        }
        let p = Pipeline::from_toml(&t, "p.toml").unwrap();
        let r: Vec<f64> = runs
            .iter()
            .map(|(log, truth)| {
                let e = railgrip::estimate::estimate(log, &p).unwrap();
                let (mut sum, mut k) = (0.0, 0usize);
                for a in 0..AXLES {
                    for (i, &t) in e.time_s.iter().enumerate() {
                        let j = ((t - truth.time_s[0]) * FS).round() as usize;
                        if j < truth.time_s.len() && e.axles[a].valid[i] && truth.dv_mps[a][j] > 0.2
                        {
                            let d = e.axles[a].mu[i] - truth.mu[a][j];
                            sum += d * d;
                            k += 1;
                        }
                    }
                }
                (sum / k as f64).sqrt()
            })
            .collect();
        eprintln!("{label:>22} | {:>20.5} | {:>26.5}", r[0], r[1]);
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
