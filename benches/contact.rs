//! Nanoseconds per evaluation of each contact law, over 1024 varied inputs per iteration
//! (no constant folding): `contact/<law>/1024`.
//!
//!     cargo bench --bench contact
//!
//! Targets (this 2-core machine): linear + saturation ≤ 20 ns, Polach ≤ 100 ns, Hertz with
//! elliptic integrals ≤ 1 µs per call.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use railgrip::contact::hertz::hertz_from_curvatures;
use railgrip::contact::kalker;
use railgrip::contact::linear_saturated_fx;
use railgrip::contact::polach::{polach, ContactPatch, PolachParams};

const N: usize = 1024;

fn bench(c: &mut Criterion) {
    let patch = ContactPatch {
        a_m: 0.0043,
        b_m: 0.006,
        g_pa: 8.08e10,
        c11: 3.8,
        c22: 3.2,
    };
    let slips: Vec<f64> = (0..N).map(|i| (i as f64 + 0.5) * 5.0 / N as f64).collect();
    let loads: Vec<f64> = (0..N)
        .map(|i| 40_000.0 + 60_000.0 * i as f64 / N as f64)
        .collect();

    let mut g = c.benchmark_group("contact");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("linear_saturated/1024", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (w, q) in slips.iter().zip(&loads) {
                acc += linear_saturated_fx(black_box(&patch), 0.3, *q, w / 30.0).unwrap();
            }
            acc
        })
    });
    g.bench_function("polach/1024", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (w, q) in slips.iter().zip(&loads) {
                acc += polach(black_box(&patch), &PolachParams::WET, *q, 30.0, *w, 0.0)
                    .unwrap()
                    .fx_n;
            }
            acc
        })
    });
    let curv: Vec<f64> = (0..N).map(|i| 0.05 + 0.9 * i as f64 / N as f64).collect();
    g.bench_function("hertz/1024", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (ct, q) in curv.iter().zip(&loads) {
                acc += hertz_from_curvatures(*q, 2.1e11, 0.3, black_box(1.087), *ct)
                    .unwrap()
                    .a_m;
            }
            acc
        })
    });
    let aspect: Vec<f64> = (0..N).map(|i| 0.1 + 9.8 * i as f64 / N as f64).collect();
    g.bench_function("kalker_coefficients/1024", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for ct in &aspect {
                acc += kalker::coefficients(black_box(*ct), 1.0, 0.3).unwrap().c11;
            }
            acc
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
