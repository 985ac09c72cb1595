//! Simulator speed: a 20-s, 4-axle braking at the default 0.1 ms step with every effect
//! (`sim/full/20s`) against the minimal scene with none (`sim/minimal/20s`); throughput is in
//! integration steps. Afterwards it prints the real-time factor of each and the step-size
//! trade-off of the full scene: real-time factor against the error of the truth (μ of axle 1,
//! vehicle speed) relative to a 0.02 ms reference run; then what each effect costs alone (the
//! minimal scene plus that one effect) and the FASTSIM law's cost by grid
//! (`sim/thermal/20s`, `sim/fastsim_10x10/20s` in criterion as well), and the `thermal`
//! effect's update interval against its error. `sim/cube_root/*`: the patch refresh's four
//! cube roots per logger record under `load_transfer` — `f64::cbrt` (correctly rounded,
//! a call per root) against `railgrip_simd::cbrt4` (the same bits, on vector lanes), 1 024
//! sets of four load ratios each.
//!
//!     cargo bench --bench sim

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use railgrip::sim::{self, Scene};

const ALL: &str = r#"effects = ["load_transfer", "wsp", "hysteresis", "falling_friction", "temperature", "cleaning",
  "running_resistance", "gradient", "radar_noise", "radar_spikes", "tacho_quantization", "pressure_noise", "thermal"]"#;

fn scene(effects: &str, step_ms: f64) -> Scene {
    let text = format!(
        "name = \"bench\"\nseed = 1\n{effects}\n[run]\ninitial_speed_kmh = 120.0\nmax_duration_s = 20.0\nstep_ms = {step_ms}\n"
    );
    Scene::from_toml(&text, "bench.toml", None).unwrap()
}

/// The minimal scene driven by FASTSIM on an n × n grid, at 0.1 ms steps.
fn fastsim_scene(n: usize) -> Scene {
    fastsim_scene_at(n, 0.1)
}

/// The same at `step_ms`.
fn fastsim_scene_at(n: usize, step_ms: f64) -> Scene {
    let text = format!(
        "name = \"bench\"\nseed = 1\neffects = []\n[run]\ninitial_speed_kmh = 120.0\nmax_duration_s = 20.0\nstep_ms = {step_ms}\n[adhesion]\nlaw = \"fastsim\"\nfastsim_grid = {n}\n"
    );
    Scene::from_toml(&text, "bench.toml", None).unwrap()
}

fn real_time_factor(sc: &Scene) -> f64 {
    let runs = 5;
    let t = Instant::now();
    let mut simulated = 0.0;
    for _ in 0..runs {
        simulated += black_box(sim::simulate(sc, None).unwrap()).duration_s;
    }
    simulated / t.elapsed().as_secs_f64()
}

fn bench(c: &mut Criterion) {
    let full = scene(ALL, 0.1);
    let minimal = scene("effects = []", 0.1);
    let steps = sim::simulate(&full, None).unwrap().steps;
    let mut g = c.benchmark_group("sim");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    g.throughput(Throughput::Elements(steps));
    g.bench_function("full/20s", |b| {
        b.iter(|| sim::simulate(black_box(&full), None).unwrap().steps)
    });
    g.bench_function("minimal/20s", |b| {
        b.iter(|| sim::simulate(black_box(&minimal), None).unwrap().steps)
    });
    let thermal = scene("effects = [\"thermal\"]", 0.1);
    g.bench_function("thermal/20s", |b| {
        b.iter(|| sim::simulate(black_box(&thermal), None).unwrap().steps)
    });
    let fastsim = fastsim_scene(10);
    g.bench_function("fastsim_10x10/20s", |b| {
        b.iter(|| sim::simulate(black_box(&fastsim), None).unwrap().steps)
    });
    g.finish();

    eprintln!("effect alone | real-time factor | cost vs minimal");
    let base = real_time_factor(&minimal);
    for e in sim::Effect::ALL {
        let sc = scene(&format!("effects = [\"{}\"]", e.name()), 0.1);
        let rtf = real_time_factor(&sc);
        eprintln!(
            "{:18} | {rtf:8.0} | {:+.0} %",
            e.name(),
            100.0 * (base / rtf - 1.0)
        );
    }
    for n in [5, 10, 20] {
        let rtf = real_time_factor(&fastsim_scene(n));
        eprintln!(
            "law fastsim {n}x{n}   | {rtf:8.1} | {:+.0} %",
            100.0 * (base / rtf - 1.0)
        );
    }
    // The FASTSIM law's error from the step (its slope is a forward difference, two calls).
    let reference = sim::simulate(&fastsim_scene_at(10, 0.02), None).unwrap();
    let out = sim::simulate(&fastsim_scene(10), None).unwrap();
    let n = out.truth.time_s.len().min(reference.truth.time_s.len());
    let mut se = 0.0;
    for a in 0..4 {
        for i in 0..n {
            se += (out.truth.mu[a][i] - reference.truth.mu[a][i]).powi(2);
        }
    }
    eprintln!(
        "law fastsim 10x10 at 0.1 ms: RMS μ error of all axles vs 0.02 ms {:.2e}",
        (se / (4 * n) as f64).sqrt()
    );

    eprintln!(
        "real-time factor at 0.1 ms: full {:.0}x, minimal {:.0}x",
        real_time_factor(&full),
        real_time_factor(&minimal)
    );
    let reference = sim::simulate(&scene(ALL, 0.02), None).unwrap();
    eprintln!("step ms | real-time factor | RMS μ error axle 1 | max |v - v_ref| m/s  (full scene, vs 0.02 ms)");
    for step in [0.05, 0.1, 0.2, 0.4] {
        let sc = scene(ALL, step);
        let out = sim::simulate(&sc, None).unwrap();
        let n = out.truth.time_s.len().min(reference.truth.time_s.len());
        let mut se = 0.0;
        let mut dv: f64 = 0.0;
        for i in 0..n {
            se += (out.truth.mu[0][i] - reference.truth.mu[0][i]).powi(2);
            dv = dv.max((out.truth.v_mps[i] - reference.truth.v_mps[i]).abs());
        }
        eprintln!(
            "{step:7} | {:16.0} | {:18.5} | {:.4}",
            real_time_factor(&sc),
            (se / n as f64).sqrt(),
            dv
        );
    }
    thermal_update_tradeoff(base);
}

/// The `thermal` effect's update interval: real-time factor and the RMS μ error of all axles
/// against a run at 0.02 ms steps updated every step, in a sliding scene (thermal alone: the
/// wheels lock and slide) and a WSP scene (thermal, wsp, load_transfer).
fn thermal_update_tradeoff(minimal_rtf: f64) {
    let with = |effects: &str, step: f64, update: f64| {
        let text = format!(
            "name = \"bench\"\nseed = 1\neffects = [{effects}]\n[run]\ninitial_speed_kmh = 120.0\nmax_duration_s = 20.0\nstep_ms = {step}\n[adhesion]\nthermal_update_ms = {update}\n"
        );
        Scene::from_toml(&text, "bench.toml", None).unwrap()
    };
    eprintln!("thermal update ms | scene | real-time factor | cost vs minimal | RMS μ error (vs 0.02 ms steps, every step)");
    for (name, effects) in [
        ("slide", "\"thermal\""),
        ("wsp", "\"thermal\", \"wsp\", \"load_transfer\""),
    ] {
        let reference = sim::simulate(&with(effects, 0.02, 0.02), None).unwrap();
        for update in [0.1, 0.2, 0.5, 1.0, 2.0] {
            let sc = with(effects, 0.1, update);
            let out = sim::simulate(&sc, None).unwrap();
            let n = out.truth.time_s.len().min(reference.truth.time_s.len());
            let mut se = 0.0;
            for a in 0..4 {
                for i in 0..n {
                    se += (out.truth.mu[a][i] - reference.truth.mu[a][i]).powi(2);
                }
            }
            let rtf = real_time_factor(&sc);
            eprintln!(
                "{update:17} | {name:5} | {rtf:16.0} | {:+14.0} % | {:.2e}",
                100.0 * (minimal_rtf / rtf - 1.0),
                (se / (4 * n) as f64).sqrt()
            );
        }
    }
}

/// `f64::cbrt` against [`railgrip_simd::cbrt4`] on the widest lanes this CPU has, on the
/// load ratios a braking sees (0.7–1.3).
fn cube_root(c: &mut Criterion) {
    use railgrip_simd::{cbrt4, Isa, Portable};
    let sets: Vec<[f64; 4]> = (0..1024)
        .map(|i| std::array::from_fn(|a| 0.7 + 0.6 * ((i * 4 + a) as f64 / 4096.0)))
        .collect();
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn lanes(isa: railgrip_simd::Avx2, sets: &[[f64; 4]]) -> f64 {
        sets.iter()
            .map(|x| cbrt4::<railgrip_simd::F64x4>(isa, *x).iter().sum::<f64>())
            .sum()
    }
    let mut g = c.benchmark_group("sim/cube_root");
    g.throughput(Throughput::Elements(4 * sets.len() as u64));
    g.bench_function("std", |b| {
        b.iter(|| {
            black_box(&sets)
                .iter()
                .map(|x| x.map(f64::cbrt).iter().sum::<f64>())
                .sum::<f64>()
        })
    });
    match Isa::detect() {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512(t) => g.bench_function("railgrip_cbrt4", |b| {
            // SAFETY: the token proves AVX2 and FMA.
            b.iter(|| unsafe { lanes(t.avx2(), black_box(&sets)) })
        }),
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2(t) => g.bench_function("railgrip_cbrt4", |b| {
            // SAFETY: the token proves AVX2 and FMA.
            b.iter(|| unsafe { lanes(t, black_box(&sets)) })
        }),
        _ => g.bench_function("railgrip_cbrt4", |b| {
            b.iter(|| {
                black_box(&sets)
                    .iter()
                    .map(|x| cbrt4::<f64>(Portable, *x).iter().sum::<f64>())
                    .sum::<f64>()
            })
        }),
    };
    g.finish();
}

criterion_group!(benches, bench, cube_root);
criterion_main!(benches);
