//! The study's simulator and contact rows: what the simulator's step size
//! and the contact law's grid cost and buy, measured like the model cells.
//!
//! **Simulator** (`[[simulator]]`): a scene run at each `step_ms` against the same scene at
//! `reference_step_ms`: wall time (best of 3), real-time factor (simulated s per wall s), RMS
//! of μ over every axle and output sample against the reference, and the largest |v − v_ref|
//! (m/s). With WSP in the scene, trajectories drift apart in phase, so the μ error also holds
//! cycle timing (docs/simulator.md).
//!
//! **Contact** (`[[contact]]`): for the base pipeline's wheel patch at the static wheel load
//! (Hertz, seed 001 eq. 1–5; Kalker's coefficients, `vehicle::wheel_hertz`), friction μ
//! constant, a sweep of 32 longitudinal creepages up to `creepage_max` at 20 m/s: time per call
//! (ns) and the error of F_x against FASTSIM on a `reference_grid`² grid (seed 001, Kalker's
//! simplified theory), RMS and largest, as a fraction of μN. Laws: `linear` (Kalker, seed 001
//! eq. 10–11), `saturated` (linear + Shen–Hedrick–Elkins, seed 002 eq. 6–8), `polach`
//! (seed 004 eq. 6–10 with k_A = k_S = 1 and constant friction: Polach's approximation of the
//! same theory) and `fastsim` on each `grid`² (elliptic or parabolic bound).

use std::path::PathBuf;
use std::time::Instant;

use super::StudyError;
use crate::config::Pipeline;
use crate::contact::fastsim::{Bound, Creepage, Fastsim, Friction, Patch};
use crate::contact::polach::{polach, ContactPatch, PolachParams};
use crate::sim::Scene;

/// A `[[simulator]]` entry, checked: one scene per step.
#[derive(Debug, Clone)]
pub struct SimSpec {
    pub scene_file: PathBuf,
    /// The scene as the plan names it.
    pub scene_name: String,
    /// (step, scene) per step, ms.
    pub steps: Vec<(f64, Scene)>,
    pub reference_step_ms: f64,
    pub reference: Scene,
}

/// A `[[contact]]` entry, checked.
#[derive(Debug, Clone)]
pub struct ContactSpec {
    pub laws: Vec<String>,
    pub grids: Vec<usize>,
    pub bounds: Vec<Bound>,
    pub reference_grid: usize,
    pub mu: f64,
    pub creepage_max: f64,
}

/// Laws a `[[contact]]` entry may list.
pub const CONTACT_LAWS: [&str; 4] = ["linear", "saturated", "polach", "fastsim"];

/// One simulator row.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SimRow {
    pub scene: String,
    pub step_ms: f64,
    pub reference_step_ms: f64,
    pub wall_s: f64,
    pub real_time_factor: f64,
    pub rms_mu_error: f64,
    pub max_v_error_mps: f64,
}

/// One contact row.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ContactRow {
    /// `fastsim 20×20 elliptic`, `polach`, …
    pub law: String,
    pub ns_per_call: f64,
    /// F_x against the reference FASTSIM, as a fraction of μN.
    pub rms_error: f64,
    pub max_error: f64,
    pub reference: String,
}

/// Runs every simulator entry.
pub fn sim_rows(specs: &[SimSpec]) -> Result<Vec<SimRow>, StudyError> {
    let mut rows = Vec::new();
    let fail = |file: &PathBuf, e: crate::sim::SimError| StudyError::Data {
        what: format!("{}: {e}", file.display()),
        hint: "check the scene the plan's [[simulator]] names".into(),
    };
    for s in specs {
        let reference =
            crate::sim::simulate(&s.reference, None).map_err(|e| fail(&s.scene_file, e))?;
        let rt = &reference.truth;
        for (step, scene) in &s.steps {
            let mut best = f64::INFINITY;
            let mut out = None;
            for _ in 0..3 {
                let t0 = Instant::now();
                let o = crate::sim::simulate(scene, None).map_err(|e| fail(&s.scene_file, e))?;
                best = best.min(t0.elapsed().as_secs_f64());
                out = Some(o);
            }
            let t = out.expect("three runs").truth;
            let n = t.time_s.len().min(rt.time_s.len());
            let (mut sq, mut count, mut dv) = (0.0, 0usize, 0.0f64);
            for i in 0..n {
                for a in 0..crate::format::AXLES {
                    let e = t.mu[a][i] - rt.mu[a][i];
                    sq += e * e;
                    count += 1;
                }
                dv = dv.max((t.v_mps[i] - rt.v_mps[i]).abs());
            }
            let duration = t.time_s.last().copied().unwrap_or(0.0);
            rows.push(SimRow {
                scene: s.scene_name.clone(),
                step_ms: *step,
                reference_step_ms: s.reference_step_ms,
                wall_s: best,
                real_time_factor: duration / best,
                rms_mu_error: (sq / count.max(1) as f64).sqrt(),
                max_v_error_mps: dv,
            });
        }
    }
    Ok(rows)
}

/// Runs every contact entry on the pipeline's wheel patch.
pub fn contact_rows(
    specs: &[ContactSpec],
    pipeline: &Pipeline,
) -> Result<Vec<ContactRow>, StudyError> {
    let bad = |e: crate::contact::ContactError| StudyError::Data {
        what: format!("[[contact]] on the base pipeline's wheel patch: {e}"),
        hint: "check [contact] and the vehicle of the base pipeline, and the entry's mu".into(),
    };
    let (hz, kc, q) =
        crate::vehicle::wheel_hertz(&pipeline.vehicle, &pipeline.contact).map_err(bad)?;
    let g = crate::contact::shear_modulus_pa(
        pipeline.contact.youngs_modulus_pa,
        pipeline.contact.poisson,
    );
    let patch = Patch::new(&hz, g, &kc, q);
    let cpatch = ContactPatch {
        a_m: hz.a_m,
        b_m: hz.b_m,
        g_pa: g,
        c11: kc.c11,
        c22: kc.c22,
    };
    let v = 20.0;
    let mut rows = Vec::new();
    for s in specs {
        let fr = Friction::constant(s.mu);
        let sweep: Vec<f64> = (1..=32).map(|k| s.creepage_max * k as f64 / 32.0).collect();
        let creep = |sx: f64| Creepage {
            sx,
            sy: 0.0,
            spin_per_m: 0.0,
            speed_mps: v,
        };
        for bound in &s.bounds {
            let reference_fs =
                Fastsim::new(s.reference_grid, s.reference_grid, *bound).map_err(bad)?;
            let reference: Vec<f64> = sweep
                .iter()
                .map(|&sx| reference_fs.forces(&patch, &fr, &creep(sx)).map(|f| f.fx_n))
                .collect::<Result<_, _>>()
                .map_err(bad)?;
            let reference_name = format!("fastsim {0}×{0} {1}", s.reference_grid, bound.name());
            let mut row = |law: String,
                           f: &dyn Fn(f64) -> Result<f64, crate::contact::ContactError>|
             -> Result<(), StudyError> {
                let got: Vec<f64> = sweep
                    .iter()
                    .map(|&sx| f(sx))
                    .collect::<Result<_, _>>()
                    .map_err(bad)?;
                let scale = s.mu * q;
                let (mut sq, mut mx) = (0.0, 0.0f64);
                for (a, b) in got.iter().zip(&reference) {
                    let e = (a - b).abs() / scale;
                    sq += e * e;
                    mx = mx.max(e);
                }
                let ns = super::timing::ns_per_point(sweep.len(), || {
                    sweep
                        .iter()
                        .map(|&sx| f(std::hint::black_box(sx)).unwrap_or(0.0))
                        .sum()
                });
                rows.push(ContactRow {
                    law,
                    ns_per_call: ns,
                    rms_error: (sq / sweep.len() as f64).sqrt(),
                    max_error: mx,
                    reference: reference_name.clone(),
                });
                Ok(())
            };
            for law in &s.laws {
                match law.as_str() {
                    "linear" => row("linear".into(), &|sx| {
                        crate::contact::kalker::linear_creep(g, hz.a_m, hz.b_m, &kc, sx, 0.0, 0.0)
                            .map(|f| f.fx_n)
                    })?,
                    "saturated" => row("saturated".into(), &|sx| {
                        crate::contact::linear_saturated_fx(&cpatch, s.mu, q, sx)
                    })?,
                    "polach" => {
                        let pp = PolachParams {
                            mu0: s.mu,
                            a_ratio: 1.0,
                            b_s_per_m: 0.0,
                            k_a: 1.0,
                            k_s: 1.0,
                        };
                        row("polach (k_A = k_S = 1)".into(), &|sx| {
                            polach(&cpatch, &pp, q, v, sx * v, 0.0).map(|f| f.fx_n)
                        })?
                    }
                    _ => {
                        for &n in &s.grids {
                            let fs = Fastsim::new(n, n, *bound).map_err(bad)?;
                            row(format!("fastsim {n}×{n} {}", bound.name()), &|sx| {
                                fs.forces(&patch, &fr, &creep(sx)).map(|f| f.fx_n)
                            })?;
                        }
                    }
                }
            }
        }
    }
    Ok(rows)
}
