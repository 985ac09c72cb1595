//! Nanoseconds per evaluation of each contact law, over 1024 varied inputs per iteration
//! (no constant folding): `contact/<law>/1024`.
//!
//!     cargo bench --bench contact
//!
//! Targets (this 2-core machine): linear + saturation ≤ 20 ns, Polach ≤ 100 ns, Hertz with
//! elliptic integrals ≤ 1 µs per call, FASTSIM 20 × 20 ≤ 5 µs per call
//! (`contact_fastsim/<bound>/<n>x<n>`: one call at a creepage in the saturating range), and the
//! V-Track flash temperature (FASTSIM 20 × 20 field + strip model) per evaluation.

use std::hint::black_box;

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use railgrip::contact::fastsim::{Bound, Creepage, Fastsim, Friction, Patch};
use railgrip::contact::flash::{flash_temperature, Heating, Material};
use railgrip::contact::hertz::hertz_from_curvatures;
use railgrip::contact::kalker;
use railgrip::contact::linear_saturated_fx;
use railgrip::contact::polach::{polach, ContactPatch, PolachParams};

const N: usize = 1024;

/// The closed-form laws: linear + saturation, Polach, Kalker's linear creep.
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

/// FASTSIM per grid and bound, the modified FASTSIM, the flash temperature; then the peers.
fn bench_fastsim(c: &mut Criterion) {
    let mut g = c.benchmark_group("contact_fastsim");
    let h = hertz_from_curvatures(50_000.0, 2.1e11, 0.3, 0.5 / 0.46, 0.5 / 0.3).unwrap();
    let k = kalker::coefficients(h.a_m, h.b_m, 0.3).unwrap();
    let fp = Patch::new(
        &h,
        railgrip::contact::shear_modulus_pa(2.1e11, 0.3),
        &k,
        50_000.0,
    );
    let fr = Friction::constant(0.3);
    let cr = Creepage {
        sx: 1.5e-3,
        sy: 2e-4,
        spin_per_m: 0.1,
        speed_mps: 20.0,
    };
    for bound in [Bound::Elliptic, Bound::Parabolic] {
        for n in [10, 20, 50, 100, 200] {
            let fs = Fastsim::new(n, n, bound).unwrap();
            g.bench_function(format!("{}/{n}x{n}", bound.name()), |b| {
                b.iter(|| fs.forces(black_box(&fp), &fr, black_box(&cr)).unwrap().fx_n)
            });
        }
    }
    // Seed 003's V-Track case at 10 % slip (tests/contact_fastsim.rs builds the same patch).
    let vt = Patch {
        a_m: 1.412e-3,
        b_m: 1.339e-3,
        g_pa: railgrip::contact::shear_modulus_pa(201e9, 0.307),
        c11: 4.2,
        c22: 3.8,
        c23: 1.5,
        normal_n: 4000.0,
    };
    let v = 16.0 / 3.6;
    let cv = Creepage {
        sx: 0.1,
        sy: 0.0,
        spin_per_m: 0.0,
        speed_mps: v,
    };
    let material = Material {
        conductivity_w_per_mk: 6.99,
        specific_heat_j_per_kgk: 539.5,
        density_kg_per_m3: 7850.0,
    };
    let heating = Heating {
        partition: 0.5,
        initial_temperature_c: 200.0,
        after_s: 1.09e-3,
    };
    for n in [20, 40] {
        let fs = Fastsim::new(n, n, Bound::Elliptic).unwrap();
        let mut field = fs.field();
        g.bench_function(format!("flash_v_track/{n}x{n}"), |b| {
            b.iter(|| {
                fs.solve(black_box(&vt), &Friction::constant(0.45), &cv, &mut field)
                    .unwrap();
                flash_temperature(&field, v, &material, &heating)
                    .unwrap()
                    .after_c
            })
        });
    }
    g.finish();
    fastsim_peers(&fp, &fr, &cr);
}

/// FASTSIM against the peers a Python user would pick (`benches/peers/fastsim_numpy.py`:
/// numpy with the strips vectorised, and the plain loop compiled by numba), on identical
/// inputs in the same run: forces compared, time per call best of 5 on each side (railgrip's
/// own loop here; the criterion rows above are the reported figures). Skipped with a message
/// without python3 and numpy (numba optional). Printed with this CPU and the peers' versions,
/// numba's with the CPU its LLVM compiles for and the host's widest vector extension.
fn fastsim_peers(fp: &Patch, fr: &Friction, cr: &Creepage) {
    use std::process::Command;
    let grids = [10usize, 20, 50, 100, 200];
    let [l1, l2, l3] = fp.flexibilities();
    let problem = serde_json::json!({
        "a": fp.a_m, "b": fp.b_m, "l1": l1, "l2": l2, "l3": l3, "normal_n": fp.normal_n,
        "mu": fr.mu0, "sx": cr.sx, "sy": cr.sy, "spin": cr.spin_per_m, "elliptic": true,
        "grids": grids,
    });
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("fastsim_problem.json");
    std::fs::write(&path, problem.to_string()).unwrap();
    let peer =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/fastsim_numpy.py");
    let out = match Command::new("python3").arg(&peer).arg(&path).output() {
        Ok(o) if o.status.success() => o.stdout,
        Ok(o) => {
            eprintln!(
                "SKIPPED FASTSIM peers: {}",
                String::from_utf8_lossy(&o.stderr)
                    .lines()
                    .last()
                    .unwrap_or("")
            );
            return;
        }
        Err(e) => {
            eprintln!("SKIPPED FASTSIM peers: no python3 ({e})");
            return;
        }
    };
    let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
    if v["numba"] != true {
        eprintln!("(numba missing: pip install numba for the compiled peer)");
    }
    eprintln!("contact: CPU {}", common::cpu_line());
    eprintln!(
        "FASTSIM (elliptic bound) against Python peers ({}), same inputs, same run, µs per call:",
        v["versions"].as_str().unwrap_or("versions unknown")
    );
    eprintln!(
        "  grid     railgrip   numpy (×)          numba (×)          largest |ΔF|/μN vs railgrip"
    );
    for n in grids {
        let fs = Fastsim::new(n, n, Bound::Elliptic).unwrap();
        let ours = fs.forces(fp, fr, cr).unwrap();
        let calls = (400_000 / (n * n)).max(20);
        let mut best = f64::INFINITY;
        for _ in 0..5 {
            let t = std::time::Instant::now();
            for _ in 0..calls {
                black_box(fs.forces(black_box(fp), fr, black_box(cr)).unwrap().fx_n);
            }
            best = best.min(t.elapsed().as_secs_f64() / calls as f64);
        }
        let us = best * 1e6;
        let row = &v["grids"][n.to_string()];
        let cell = |k: &str| -> (String, f64) {
            match row.get(k) {
                Some(r) => {
                    let f: Vec<f64> = r["forces"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|x| x.as_f64().unwrap())
                        .collect();
                    let d = [(f[0] - ours.fx_n).abs(), (f[1] - ours.fy_n).abs()]
                        .into_iter()
                        .fold(0.0f64, f64::max)
                        / (fr.mu0 * fp.normal_n);
                    let t = r["us"].as_f64().unwrap();
                    (format!("{t:>9.2} ({:>6.1}×)", t / us), d)
                }
                None => ("        –          ".into(), 0.0),
            }
        };
        let (np, dn) = cell("numpy");
        let (nb, db) = cell("numba");
        eprintln!("  {n:>3}²  {us:>10.2}   {np}  {nb}  {:.1e}", dn.max(db));
    }
}

criterion_group!(benches, bench, bench_fastsim);
criterion_main!(benches);
