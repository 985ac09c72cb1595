//! Scene-driven braking simulator: runs with known truth for tests, the bundled archive and
//! closed-loop checks. A scene pays only for the effects it lists: each effect is a stage of
//! the step loop behind its flag, and [`EffectCounters`] counts every evaluation.
//!
//! Model (one rigid car body on two bogies, four axles, axle 1 leading):
//! - vehicle: M v̇ = −Σ T_i − F_res(v) − M g sin(atan(i/1000)),  M = m_c + 2 m_b;
//! - axle i: J ω̇_i = T_i r − C_f,i,  C_f,i = α_i p_i while the wheel turns (seed 002 eq. 9–10);
//!   a wheel that reaches ω = 0 stays locked while T_i r ≤ α_i p_i (static brake) and is
//!   released when the contact torque exceeds it: no chatter around ω = 0;
//! - contact: T_i = μ_i N_i with μ_i from Polach (seed 004 eq. 1–2) on the Hertz + Kalker patch
//!   of the vehicle's wheel at its load, per wheel Q = N_i/2 (the patch stiffness is refreshed
//!   at the output rate as the load changes, a b ∝ Q^(2/3));
//! - brake cylinder: first order, ṗ = (p_cmd − p)/τ.
//!
//! Integrator: fixed step (default 0.1 ms), explicit Euler for the vehicle and the cylinders
//! and linearly-implicit (Rosenbrock–Euler) Euler for the wheels,
//!   ω_{n+1} = ω_n + h f(ω_n) / (1 + h r² k_n / J),  k_n = ∂T/∂Δv ≥ 0 (analytic),
//! because the creep stiffness k grows like 1/v: near standstill the wheel time constant
//! J/(r² k) falls below the step and explicit Euler would oscillate, while the implicit
//! correction keeps the step stable at the cost of one extra derivative per axle. The force
//! applied over the step (to the wheel, the vehicle and the truth table) is the creep force
//! linearised at the new wheel speed, T* = T(ω_n) − r k_n N (ω_{n+1} − ω_n), so J ω̇ = T* r − α p
//! holds exactly step by step (with T(ω_n) instead, a stiff dry contact would break the balance
//! by h r² k N / J ≈ 15 % of J ω̇). The hysteresis branch factor is lagged by
//! `hysteresis_time_constant_s` (an instant one closes an algebraic loop that chatters).
//!
//! Speed (what the step costs): the step is a dependency chain — wheel speeds → slip →
//! creep force → new wheel speeds → vehicle speed → next slip — so its latency sets the
//! real-time factor. [`step`] evaluates the four axles side by side (one AVX2 register, or
//! one axle at a time on the portable path, bit-identical), the Polach law as fractions over
//! one denominator with a division-free atan, and one division per wheel update. The contact
//! law's slowly varying coefficients — the axle loads under load transfer (from the
//! deceleration), the falling-friction factor (from the slip) and its speed factor, and the
//! hysteresis branch factor (from the slip rate) — are evaluated from the state at the start of
//! the previous step, off that chain: a 0.1 ms delay in quantities that change over tens of
//! milliseconds (the loads by ~1e-3 of themselves per step at most).

pub mod foreign;
mod output;
pub mod scene;
mod sensors;
mod state;
mod step;
mod wsp;

use std::path::PathBuf;

use crate::contact::ContactError;
use crate::format::{RunMetadata, AXLES};
use crate::model::Model;
#[cfg(target_arch = "x86_64")]
use crate::simd::{Avx2, Avx512, F64x4};
use crate::simd::{Isa, Portable, Select};
use foreign::ScalarLaw;
pub use output::{read_truth_samples, truth_f32, OutputFormat, TRUTH_COLUMNS, TRUTH_MISMATCH_KEY};
pub use scene::{AdhesionLaw, Effect, Effects, Scene};
use sensors::Logger;
pub use state::brake_coefficients;
use state::Setup;

/// The simulator's random numbers (SplitMix64; sensor noise and spikes come from it, seeded by
/// the scene's `seed`): public so that tests and tools can draw the same streams.
pub use crate::rng::Rng;
pub use crate::vehicle::{axle_loads, static_axle_load, G_MPS2};

/// Why a simulation could not run or its output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("scene {scene}: {what}. Hint: {hint}")]
    Scene {
        scene: String,
        what: String,
        hint: String,
    },
    #[error("scene {scene}: contact geometry: {source}. Hint: check [contact] and the vehicle's wheel radius")]
    Contact {
        scene: String,
        #[source]
        source: ContactError,
    },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Table(#[from] crate::table::TableError),
}

/// How many times each effect's stage ran.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct EffectCounters(pub [u64; Effect::ALL.len()]);

impl EffectCounters {
    #[inline]
    fn hit(&mut self, e: Effect) {
        self.0[e.index()] += 1;
    }
    #[inline]
    fn add(&mut self, e: Effect, n: u64) {
        self.0[e.index()] += n;
    }
    pub fn get(&self, e: Effect) -> u64 {
        self.0[e.index()]
    }
}

/// Samples of one measured channel: logger time (s since the start) and value.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Series {
    pub time_s: Vec<f64>,
    pub values: Vec<f64>,
}

/// The true state per output sample and axle.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Truth {
    pub time_s: Vec<f64>,
    pub v_mps: Vec<f64>,
    pub omega_radps: [Vec<f64>; AXLES],
    pub p_bar: [Vec<f64>; AXLES],
    pub normal_n: [Vec<f64>; AXLES],
    pub tangential_n: [Vec<f64>; AXLES],
    pub mu: [Vec<f64>; AXLES],
    pub dv_mps: [Vec<f64>; AXLES],
    pub ddv_mps2: [Vec<f64>; AXLES],
    /// Contact temperature θ_c (°C) with the `thermal` effect; empty without it.
    pub contact_temperature_c: [Vec<f64>; AXLES],
}

impl Truth {
    /// Samples of every axle, for [`crate::score::score`], with the run's ambient temperature
    /// `t_c` (°C; the scene's `run.ambient_temperature_c`).
    pub fn samples(&self, t_c: f64) -> Vec<crate::score::Sample> {
        let mut out = Vec::with_capacity(AXLES * self.time_s.len());
        for a in 0..AXLES {
            for i in 0..self.time_s.len() {
                out.push(crate::score::Sample {
                    axle: a as u8 + 1,
                    dv_mps: self.dv_mps[a][i],
                    ddv_mps2: self.ddv_mps2[a][i],
                    v_mps: self.v_mps[i],
                    t_c,
                    mu: self.mu[a][i],
                });
            }
        }
        out
    }
}

/// What a simulation produced.
#[derive(Debug, Clone)]
pub struct SimOutput {
    pub scene: Scene,
    /// Measured channels in [`Signal::ALL`] order.
    pub channels: Vec<Series>,
    pub truth: Truth,
    pub metadata: RunMetadata,
    pub counters: EffectCounters,
    /// The mismatch the scene put between the vehicle and what an estimator's pipeline says
    /// (with `brake_scatter`, `pad_friction` or `radar_error`): the truth a calibration is
    /// scored against, written into the truth table's metadata (`railgrip.truth`), never into
    /// the log.
    pub mismatch: Option<Mismatch>,
    pub steps: u64,
    /// Simulated time, s.
    pub duration_s: f64,
}

/// `law = "fastsim"` on the wheel's patch at the static load (resized per step under
/// `load_transfer`, see [`foreign::PreparedFastsim`]).
fn fastsim_law(sc: &Scene, f: &scene::FastsimLaw) -> Result<ScalarLaw, SimError> {
    use crate::contact::fastsim::{Fastsim, Friction, Patch};
    let contact_err = |source| SimError::Contact {
        scene: sc.name.clone(),
        source,
    };
    let (hz, kc, q) = crate::vehicle::wheel_hertz(&sc.vehicle, &sc.contact).map_err(contact_err)?;
    let g = crate::contact::shear_modulus_pa(sc.contact.youngs_modulus_pa, sc.contact.poisson);
    let mut solver = Fastsim::new(f.grid, f.grid, f.bound).map_err(contact_err)?;
    if let Some(r) = f.reduction {
        solver = solver.modified(r).map_err(contact_err)?;
    }
    let p = &sc.adhesion.polach;
    Ok(ScalarLaw::Fastsim(Box::new(foreign::PreparedFastsim {
        solver,
        patch: Patch::new(&hz, g, &kc, q),
        friction: Friction {
            mu0: p.mu0,
            a_ratio: p.a_ratio,
            b_s_per_m: p.b_s_per_m,
        },
    })))
}

/// The scalar law a scene's adhesion law names — a model file loaded, a foreign law prepared
/// — checked against the scene's effects (None for the Polach law).
fn load_law(sc: &Scene) -> Result<Option<ScalarLaw>, SimError> {
    let law = &sc.adhesion.law;
    if matches!(law, AdhesionLaw::Polach) {
        return Ok(None);
    }
    let fx = sc.effects;
    let err = |what: String, hint: &str| SimError::Scene {
        scene: sc.name.clone(),
        what,
        hint: hint.into(),
    };
    // `temperature` applies to a model with a temperature law (a campaign's Polach model) and
    // to loss_recovery; checked below.
    let clash: Vec<&str> = [
        Effect::FallingFriction,
        Effect::Hysteresis,
        Effect::Cleaning,
    ]
    .into_iter()
    .filter(|e| fx.has(*e))
    .map(|e| e.name())
    .collect();
    if !clash.is_empty() {
        return Err(err(
            format!(
                "effects {} describe the Polach truth law, but adhesion.law = \"{}\"",
                clash.join(", "),
                law.name()
            ),
            "this law carries its own speed dependence and branches: remove them from effects",
        ));
    }
    let with_t = fx.has(Effect::Temperature);
    let path = match law {
        AdhesionLaw::Polach => unreachable!("returned above"),
        AdhesionLaw::LossRecovery(l) => {
            let t = with_t.then_some(sc.run.ambient_temperature_c);
            // The peaks' factor 1 + τ (20 °C − T) must stay positive (μ ≥ 0).
            if let Some(t) = t {
                let factor = 1.0 + l.temperature_coefficient_per_k * (20.0 - t);
                if factor < 0.05 {
                    return Err(err(
                        format!(
                            "adhesion.peak_temperature_coefficient_per_k = {} at run.ambient_temperature_c = {t} scales the peaks by {factor:.3}",
                            l.temperature_coefficient_per_k
                        ),
                        "the factor 1 + τ (20 °C − T) must be at least 0.05: choose a smaller coefficient or another temperature",
                    ));
                }
            }
            // The speed factor must stay positive over the run (v ≤ the initial speed; both
            // forms fall monotonically with speed).
            let v0 = sc.run.initial_speed_kmh / 3.6;
            let speed = l
                .speed_form
                .factor(l.speed_coefficient, l.reference_speed_mps, v0);
            if speed < 0.05 {
                return Err(err(
                    format!(
                        "adhesion.peak_speed_coefficient = {} ({}) at run.initial_speed_kmh = {} scales the peaks by {speed:.3}",
                        l.speed_coefficient,
                        l.speed_form.name(),
                        sc.run.initial_speed_kmh
                    ),
                    "the speed factor must be at least 0.05 up to the initial speed: choose a smaller coefficient, a higher adhesion.reference_speed_kmh or peak_speed_form = \"ratio\"",
                ));
            }
            return Ok(Some(ScalarLaw::LossRecovery(l.prepare(t))));
        }
        AdhesionLaw::Table(_) if with_t => {
            return Err(err(
                "effect temperature with adhesion.law = \"table\"".into(),
                "the table has no temperature dependence: remove temperature from effects",
            ));
        }
        AdhesionLaw::Table(t) => return Ok(Some(ScalarLaw::Table(t.clone()))),
        AdhesionLaw::Fastsim(_) if with_t => {
            return Err(err(
                "effect temperature with adhesion.law = \"fastsim\"".into(),
                "FASTSIM has no k(T): remove temperature from effects (the thermal effect works with it)",
            ));
        }
        AdhesionLaw::Fastsim(f) => return fastsim_law(sc, f).map(Some),
        AdhesionLaw::Model(path) => path,
    };
    let m = Model::load(path).map_err(|e| {
        err(
            format!("adhesion.model: {e}"),
            "give a model file written by `railgrip train`",
        )
    })?;
    if !with_t {
        return Ok(Some(ScalarLaw::Model(Box::new(m), f64::NAN)));
    }
    // A network with the ambient temperature as an input takes the scene's.
    if m.file.input_set().has_temperature() && m.file.kind == crate::model::ModelKind::Mlp {
        return Ok(Some(ScalarLaw::Model(
            Box::new(m),
            sc.run.ambient_temperature_c,
        )));
    }
    m.at_temperature(sc.run.ambient_temperature_c)
        .map(|m| Some(ScalarLaw::Model(Box::new(m), f64::NAN)))
        .map_err(|e| {
            err(
                format!("effect temperature with adhesion.model: {e}"),
                "remove temperature from effects, or use a Polach model fitted at several ambient temperatures that cover run.ambient_temperature_c, or a network with the input ambient_temperature_c",
            )
        })
}

/// A scene's adhesion law as a function μ(Δv, dΔv/dt, v) at the scene's ambient temperature:
/// the truth the [`crate::score::curve`] view compares a model with at any speed. Laws given in
/// closed form only — `loss_recovery`, `table` and a model file; the Polach law's effects
/// (hysteresis lag, per-axle cleaning) and FASTSIM's patch are states of a running simulation.
#[derive(Debug, Clone)]
pub struct TrueLaw(ScalarLaw);

impl TrueLaw {
    /// The law of `sc` (checked as [`simulate`] checks it); `None` for `polach` and `fastsim`.
    pub fn of(sc: &Scene) -> Result<Option<TrueLaw>, SimError> {
        if matches!(
            sc.adhesion.law,
            AdhesionLaw::Polach | AdhesionLaw::Fastsim(_)
        ) {
            return Ok(None);
        }
        Ok(load_law(sc)?.map(TrueLaw))
    }

    /// μ at slip `dv` (m/s), slip rate `ddv` (m/s²; the simulator lags it, the law does not)
    /// and speed `v` (m/s).
    pub fn mu(&self, dv: f64, ddv: f64, v: f64) -> f64 {
        self.0.mu(dv, ddv, v, 1.0)
    }
}

/// The noise seed of a scene with seed `scene_seed` in a campaign simulated with seed
/// `campaign`: one SplitMix64 step from both, so that the scenes of one campaign draw
/// independent noise (a campaign's runs sharing one stream would share their noise, and its
/// errors would not average over the runs) and each campaign seed gives another realisation.
/// Scenes with the same own seed still draw the same noise: a campaign's scenes need their own.
pub fn noise_seed(campaign: u64, scene_seed: u64) -> u64 {
    crate::rng::Rng::new(campaign.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ scene_seed).next_u64()
}

/// The noise seed `sc` is simulated with: its own, or with a campaign's `seed`
/// [`noise_seed`]`(seed, its own)`.
pub fn run_seed(sc: &Scene, seed: Option<u64>) -> u64 {
    seed.map_or(sc.seed, |s| noise_seed(s, sc.seed))
}

/// Runs a scene with the noise of [`run_seed`] (the log's metadata and the truth name that
/// seed: a scene file with it reproduces the run).
pub fn simulate(sc: &Scene, seed: Option<u64>) -> Result<SimOutput, SimError> {
    let model = load_law(sc)?;
    let seed = run_seed(sc, seed);
    let (channels, truth, counters, n) = run_detected(sc, model.as_ref(), seed)?;
    let metadata = RunMetadata {
        ambient_temperature_c: Some(sc.run.ambient_temperature_c),
        initial_speed_kmh: Some(sc.run.initial_speed_kmh),
        vehicle: Some(sc.vehicle.name.clone()),
        condition: Some(sc.run.condition.clone()),
        direction: Some(sc.run.direction.clone()),
        other: [
            ("scene".to_string(), sc.name.clone()),
            ("seed".to_string(), seed.to_string()),
            // The calibration mismatches are left out: the log must not tell an estimator
            // what to look for (the truth table has them).
            (
                "effects".to_string(),
                sc.effects
                    .names()
                    .into_iter()
                    .filter(|n| !MISMATCH_EFFECTS.iter().any(|e| e.name() == *n))
                    .collect::<Vec<_>>()
                    .join(","),
            ),
            (
                "generator".to_string(),
                concat!("railgrip ", env!("CARGO_PKG_VERSION"), " simulate").to_string(),
            ),
        ]
        .into(),
    };
    Ok(SimOutput {
        scene: sc.clone(),
        channels,
        truth,
        metadata,
        counters,
        mismatch: Mismatch::of(sc),
        steps: n,
        duration_s: n as f64 * sc.run.step_s,
    })
}

/// The true values behind the calibration effects of a run ([`SimOutput::mismatch`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Mismatch {
    /// Each axle's brake coefficient at the initial speed, N m/bar (`brake_scatter`; else the
    /// pipeline's).
    pub brake_torque_nm_per_bar: [f64; AXLES],
    /// α_i(v) = α_i (1 + rise max(0, 1 − v/v0)^n) (`pad_friction`; else 0).
    pub pad_friction_rise: f64,
    /// The speed v0 of that law, m/s (`brake.pad_friction_v0_kmh`, or the initial speed).
    pub pad_friction_v0_mps: f64,
    /// The exponent n of that law (`brake.pad_friction_exponent`: 1 linear).
    pub pad_friction_exponent: f64,
    /// Radar reading / true speed (`radar_error`; else 1).
    pub radar_scale: f64,
    /// The radar's delay, s (`radar_error`; else 0).
    pub radar_latency_s: f64,
    /// Relative rms of the axle loads' fluctuation (`load_fluctuation`; else 0).
    pub load_fluctuation_rms: f64,
    /// The pivot force's share of the load transfer is in the loads (`pivot_force`).
    pub pivot_force: bool,
}

/// The effects that put the simulated vehicle off what the pipeline says (left out of the
/// log's `effects` list; their truth is in [`Mismatch`]).
pub const MISMATCH_EFFECTS: [Effect; 5] = [
    Effect::BrakeScatter,
    Effect::PadFriction,
    Effect::RadarError,
    Effect::LoadFluctuation,
    Effect::PivotForce,
];

impl Mismatch {
    /// The true pad factor α_i(v) / α_i at speed `v_mps`: 1 + rise max(0, 1 − v/v0)^n.
    pub fn pad_factor(&self, v_mps: f64) -> f64 {
        let x = (1.0 - v_mps / self.pad_friction_v0_mps).max(0.0);
        1.0 + self.pad_friction_rise * x.powf(self.pad_friction_exponent)
    }

    /// The mismatch of scene `sc`, None when it asks for no mismatch effect.
    pub fn of(sc: &Scene) -> Option<Mismatch> {
        let fx = sc.effects;
        if !MISMATCH_EFFECTS.iter().any(|e| fx.has(*e)) {
            return None;
        }
        let radar = fx.has(Effect::RadarError);
        Some(Mismatch {
            brake_torque_nm_per_bar: state::brake_coefficients(sc),
            pad_friction_rise: if fx.has(Effect::PadFriction) {
                sc.brake.pad_friction_rise
            } else {
                0.0
            },
            pad_friction_v0_mps: state::pad_friction_v0_mps(sc),
            pad_friction_exponent: sc.brake.pad_friction_exponent,
            radar_scale: if radar { sc.sensors.radar_scale } else { 1.0 },
            radar_latency_s: if radar {
                sc.sensors.radar_latency_s
            } else {
                0.0
            },
            load_fluctuation_rms: if fx.has(Effect::LoadFluctuation) {
                sc.run.load_fluctuation_rms
            } else {
                0.0
            },
            pivot_force: fx.has(Effect::PivotForce),
        })
    }
}

/// What the step loop produced: channels, truth, counters, steps.
type RunResult = (Vec<Series>, Truth, EffectCounters, u64);

/// The step loop on the portable path (one axle per lane).
fn run_portable(sc: &Scene, model: Option<&ScalarLaw>, seed: u64) -> Result<RunResult, SimError> {
    run::<f64>(Portable, sc, model, seed)
}

/// The step loop with the four axles in one AVX2 register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn run_avx2(
    isa: Avx2,
    sc: &Scene,
    model: Option<&ScalarLaw>,
    seed: u64,
) -> Result<RunResult, SimError> {
    run::<F64x4>(isa, sc, model, seed)
}

/// [`run_avx2`] compiled with AVX-512VL as well: the same AVX2 operations, with 32 vector
/// registers instead of 16 (fewer spills) and masked blends.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
fn run_avx512vl(
    isa: Avx512,
    sc: &Scene,
    model: Option<&ScalarLaw>,
    seed: u64,
) -> Result<RunResult, SimError> {
    run::<F64x4>(isa.avx2(), sc, model, seed)
}

/// The step loop on the widest path this CPU has.
fn run_detected(sc: &Scene, model: Option<&ScalarLaw>, seed: u64) -> Result<RunResult, SimError> {
    match Isa::detect() {
        // SAFETY: the token proves AVX2, FMA, AVX-512F and AVX-512VL on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512(t) => unsafe { run_avx512vl(t, sc, model, seed) },
        // SAFETY: the token proves AVX2 and FMA on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2(t) => unsafe { run_avx2(t, sc, model, seed) },
        _ => run_portable(sc, model, seed),
    }
}

/// The step loop, generic over the lanes the axles' contact and wheel update run on; every
/// instantiation performs the same IEEE operations (bit-identical results). Each step:
/// sensors and truth at their logger instants → resistances → brakes (demand, WSP,
/// cylinders) → contact and wheels → hysteresis branch and the next step's contact
/// coefficients (off the critical path) → vehicle.
#[inline(always)]
fn run<V: Select>(
    isa: V::Isa,
    sc: &Scene,
    model: Option<&ScalarLaw>,
    seed: u64,
) -> Result<RunResult, SimError> {
    let mut counters = EffectCounters::default();
    let setup = Setup::new(sc, &mut counters)?;
    let mut st = setup.initial_state::<V>(isa, &mut counters);
    // The load fluctuation's own stream of the run's seed (the sensors' noise stays the same
    // with and without it).
    st.fluct_rng = crate::rng::Rng::new(seed ^ 0x6c6f_6164_5f66_6c75);
    let mut log = Logger::new(sc, seed);
    let max_steps = (sc.run.max_duration_s / setup.h).ceil() as u64;
    let mut n: u64 = 0;
    loop {
        let t = n as f64 * setup.h;
        let omega = st.ax.omega;
        if log.due(t) && log.record(t, &st, &mut counters) {
            setup.refresh_patch::<V>(isa, &mut st, &mut counters);
        }
        if st.v <= sc.run.stop_speed_mps || n >= max_steps {
            break;
        }
        let v_resisted = setup.resisted_speed(st.v, &mut counters);
        let speed_factor = setup.speed_factor_counted(st.v, &mut counters);
        setup.brakes(t, &mut st, &mut counters);
        let total_t = setup.contact_and_wheels::<V>(isa, model, &mut st);
        setup.thermal::<V>(isa, &mut st, &mut counters);
        setup.hysteresis::<V>(isa, &mut st, &mut counters);
        setup.fluctuate(&mut st, &mut counters);
        setup.prepare::<V>(isa, speed_factor, &mut st, &mut counters);
        setup.advance(&mut st, &omega, total_t, v_resisted);
        n += 1;
    }
    Ok((log.channels, log.truth, counters, n))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every compiled path of the step loop gives the portable path's bits.
    #[test]
    fn every_compiled_path_gives_the_portable_bits() {
        let text = r#"name = "paths"
seed = 3
effects = ["load_transfer", "wsp", "hysteresis", "falling_friction", "temperature", "cleaning",
  "running_resistance", "gradient", "radar_noise", "radar_spikes", "tacho_quantization", "pressure_noise", "thermal"]
[run]
initial_speed_kmh = 120.0
max_duration_s = 4.0
"#;
        let sc = Scene::from_toml(text, "paths.toml", None).unwrap();
        let (channels, truth, counters, n) = run_portable(&sc, None, 3).unwrap();
        let mut paths: Vec<(&str, RunResult)> = Vec::new();
        for isa in Isa::all_available() {
            match isa {
                // SAFETY: the token proves the instructions.
                #[cfg(target_arch = "x86_64")]
                Isa::Avx2(t) => paths.push(("avx2", unsafe { run_avx2(t, &sc, None, 3) }.unwrap())),
                // SAFETY: the token proves the instructions.
                #[cfg(target_arch = "x86_64")]
                Isa::Avx512(t) => paths.push((
                    "avx512vl",
                    unsafe { run_avx512vl(t, &sc, None, 3) }.unwrap(),
                )),
                _ => {}
            }
        }
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for (name, (c2, t2, k2, n2)) in paths {
            assert_eq!(n, n2, "{name}: steps");
            assert_eq!(counters, k2, "{name}: counters");
            for a in 0..AXLES {
                assert_eq!(
                    bits(&truth.omega_radps[a]),
                    bits(&t2.omega_radps[a]),
                    "{name}: ω"
                );
                assert_eq!(
                    bits(&truth.tangential_n[a]),
                    bits(&t2.tangential_n[a]),
                    "{name}: T"
                );
                assert_eq!(bits(&truth.normal_n[a]), bits(&t2.normal_n[a]), "{name}: N");
            }
            assert_eq!(bits(&truth.v_mps), bits(&t2.v_mps), "{name}: v");
            assert_eq!(channels, c2, "{name}: channels");
        }
    }
}
