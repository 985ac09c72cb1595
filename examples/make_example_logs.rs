//! Regenerates the bundled example logs in fixtures/example/ (deterministic):
//!
//!     cargo run --release --example make_example_logs
//!
//! A kinematic stand-in for a soap-contaminated braking test from 120 km/h: radar speed with
//! noise and a few spikes, four tachometers whose wheels slide in WSP-like cycles (later axles
//! slide less: cleaner rail), cylinder pressures dumped while sliding. It has no dynamics and
//! no truth table; the scene-driven simulator (a later issue) replaces it.

#[path = "../tests/common/mod.rs"]
mod common;

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use common::Rng;
use railgrip::format::{self, McapCompression, RunMetadata, SeriesRef, Signal};

const R: f64 = 0.445;

/// Slip velocity of axle `a` at time `t`: WSP cycles of period ~2 s, amplitude falling with
/// the axle number and with speed, m/s.
fn slip(a: usize, t: f64, v: f64) -> f64 {
    let period = 1.6 + 0.35 * a as f64;
    let phase = (t / period + 0.23 * a as f64).fract();
    let peak = (4.5 - 0.9 * a as f64) * (v / 33.3).clamp(0.2, 1.0);
    // Fast rise (loss of adhesion), slower recovery.
    let shape = if phase < 0.3 {
        phase / 0.3
    } else {
        ((1.0 - phase) / 0.7).powf(1.5)
    };
    if t < 1.5 {
        0.0
    } else {
        peak * shape
    }
}

fn main() {
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/example");
    std::fs::create_dir_all(&out).unwrap();
    let fs = 417.0;
    let mut rng = Rng::new(2026);
    let v0 = 120.0 / 3.6;
    let decel = 0.62; // m/s² on soap
    let t_stop = 1.5 + v0 / decel;
    let n = (t_stop * fs) as usize;
    let mut time = Vec::with_capacity(n);
    let mut cols: [Vec<f64>; 9] = Default::default();
    let mut p_state = [0.0f64; 4];
    // Round to a grid of 1/inv: dividing by a power of ten gives the nearest double (no 0.0090…01).
    let round = |x: f64, inv: f64| (x * inv).round() / inv;
    for k in 0..n {
        let t = k as f64 / fs
            + if k == 0 {
                0.0
            } else {
                (rng.uniform() - 0.5) * 0.2 / fs
            };
        let v = if t < 1.5 {
            v0
        } else {
            (v0 - decel * (t - 1.5)).max(0.0)
        };
        let spike = if rng.uniform() < 0.002 {
            (rng.uniform() - 0.5) * 8.0
        } else {
            0.0
        };
        let noise = (rng.uniform() + rng.uniform() + rng.uniform() - 1.5) * 0.08;
        time.push(round(t, 1e6));
        cols[0].push(round((v + noise + spike).max(0.0), 1e3));
        for a in 1..=4 {
            let dv = slip(a, t, v).min(v);
            let w = (v - dv) / R;
            // 100 pulses/rev over a 2.4 ms window quantises ω to 2π/(100·0.0024) ≈ 26 rad/s…
            // too coarse for a demo; use 0.05 rad/s steps as a fine-toothed wheel would give.
            cols[a].push(round(w.max(0.0), 20.0));
            let demand = if t < 1.0 {
                0.0
            } else if dv > 1.0 {
                0.6
            } else {
                3.8
            };
            p_state[a - 1] += (demand - p_state[a - 1]) * (1.0 - (-1.0 / (fs * 0.15)).exp());
            let pn = (rng.uniform() - 0.5) * 0.02;
            cols[4 + a].push(round((p_state[a - 1] + pn).max(0.0), 1e3));
        }
    }
    let meta = RunMetadata {
        ambient_temperature_c: Some(5.0),
        initial_speed_kmh: Some(120.0),
        vehicle: Some("UIC-Z1".into()),
        condition: Some("soap".into()),
        direction: Some("forward".into()),
        other: [(
            "note".to_string(),
            "kinematic example, not a simulation".to_string(),
        )]
        .into(),
    };
    let csv = out.join("soap_120kmh.csv");
    let c: [&[f64]; 9] = std::array::from_fn(|i| cols[i].as_slice());
    format::write_canonical_csv(BufWriter::new(File::create(&csv).unwrap()), &time, c).unwrap();
    std::fs::write(out.join("soap_120kmh.meta.toml"), meta.to_sidecar_toml()).unwrap();

    // The same run as MCAP with the radar at 100 Hz and pressures at 200 Hz.
    let decimate = |every: usize, i: usize| -> (Vec<f64>, Vec<f64>) {
        (
            time.iter().step_by(every).copied().collect(),
            cols[i].iter().step_by(every).copied().collect(),
        )
    };
    let mut owned = Vec::new();
    for s in Signal::ALL {
        let every = match s {
            Signal::VRadar => 4,
            Signal::Omega(_) => 1,
            Signal::Pressure(_) => 2,
        };
        owned.push((s, decimate(every, s.index())));
    }
    let series: Vec<SeriesRef> = owned
        .iter()
        .map(|(s, (t, v))| SeriesRef {
            signal: *s,
            time_s: t,
            values: v,
        })
        .collect();
    let mcap = out.join("soap_120kmh_multirate.mcap");
    format::write_mcap(
        BufWriter::new(File::create(&mcap).unwrap()),
        &series,
        &meta,
        McapCompression::Zstd,
        1_763_600_000_000_000_000,
    )
    .unwrap();
    for p in [csv, mcap] {
        println!(
            "wrote {} ({:.2} MB)",
            p.display(),
            std::fs::metadata(&p).unwrap().len() as f64 / 1e6
        );
    }
}
