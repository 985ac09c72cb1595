//! Conditioning + estimation of a 1-hour run (1.5 M samples at 417 Hz, 9 channels) on one
//! core (`estimate/1h`), beside the bare cost of the same low-pass filtering done channel by
//! channel with the biquad crate's `DirectForm2Transposed::run` (`biquad_bare/1h`: 9 channels
//! forward and backward, no padding, no despiking, no derivatives, no estimation). For scipy's
//! time on the same job run `python3 tests/data/signal/make_reference.py`.
//!
//!     cargo bench --bench estimate

#[path = "../tests/common/mod.rs"]
mod common;

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use biquad::{Biquad, DirectForm2Transposed};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use railgrip::format::{RunMetadata, Signal, AXLES};
use railgrip::ingest::{LogFormat, RunLog};
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
    RunLog {
        source: PathBuf::from("hour.csv"),
        format: LogFormat::Csv,
        sample_rate_hz: FS,
        v_radar_mps: sig(Signal::VRadar),
        omega_radps: std::array::from_fn(|a| sig(Signal::Omega(a as u8 + 1))),
        p_bar: std::array::from_fn(|a| sig(Signal::Pressure(a as u8 + 1))),
        valid: vec![true; n],
        metadata: RunMetadata::default(),
        start_log_time_ns: None,
        channels: Vec::new(),
        gaps: Vec::new(),
        warnings: Vec::new(),
        time_s,
    }
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
}

criterion_group!(benches, bench);
criterion_main!(benches);
