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

pub mod scene;
mod step;

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use crate::contact::ContactError;
use crate::format::{self, McapCompression, RunMetadata, SeriesRef, Signal, AXLES};
use crate::rng::Rng;
use crate::simd::{exp_lanes, Isa, Portable, Select};
#[cfg(target_arch = "x86_64")]
use crate::simd::{Avx2, Avx512, F64x4};
pub use scene::{AdhesionLaw, Effect, Effects, Scene};
use step::{polach_axles, wheel_update, AxleArrays, StepConsts};

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
    #[error("{path}: cannot write: {message}")]
    Write { path: PathBuf, message: String },
}

impl From<std::io::Error> for SimError {
    fn from(e: std::io::Error) -> Self {
        SimError::Write {
            path: PathBuf::new(),
            message: e.to_string(),
        }
    }
}

/// How many times each effect's stage ran.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct EffectCounters(pub [u64; 12]);

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
    pub steps: u64,
    /// Simulated time, s.
    pub duration_s: f64,
}

/// Wheel-slide protection state of one axle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum WspState {
    /// Brake as demanded.
    Apply,
    /// A slide was detected; the valve vents after the reaction delay.
    Detect,
    /// Venting the cylinder.
    Dump,
    /// Keeping the cylinder pressure, at most `hold_max_s`.
    Hold,
}

/// Per-axle contact constants: ε = K Δv / (v Q μ) with K = π G a b c11 / 4 (N) at wheel load
/// Q; K0 at the static load Q0, K ∝ (Q/Q0)^(2/3) under load transfer.
#[derive(Debug, Clone, Copy)]
struct AxleContact {
    k0: f64,
    q0: f64,
}

/// Hysteresis branch factor for the slip rate `ddv`: the recovery branch (dΔv/dt < 0) lower
/// by `depth`, blended smoothly by the algebraic sigmoid z/√(1 + z²), z = (dΔv/dt)/ddv0.
/// The step loop lags it with the time constant `hysteresis_time_constant_s`: the contact's
/// branch has memory, and applying it instantly closes an algebraic loop (force → slip rate
/// → force, loop gain ≈ N μ depth r² / (2 ddv0 J) ≈ 6 for the UIC-Z1) that the explicit
/// step turns into a relay chatter at the step rate.
#[inline(always)]
fn hysteresis_target<V: Select>(depth: f64, ddv: V, inv_ddv0: f64) -> V {
    let z = ddv.mul(ddv.like(inv_ddv0));
    let one = ddv.like(1.0);
    one.sub(
        ddv.like(depth * 0.5)
            .mul(one.sub(z.div(z.fma(z, one).sqrt()))),
    )
}

/// μ and dμ/dΔv from a learned model at slip `w` (m/s), slip rate `ddv` (m/s²), speed `v`
/// (m/s); the slope by a central difference over ±0.1 mm/s (the model is continuous; the
/// implicit wheel step only needs the stiffness's size), never negative.
fn model_adhesion(m: &crate::model::Model, w: f64, ddv: f64, v: f64) -> (f64, f64) {
    const H: f64 = 1e-4;
    let mu = m.mu_v(w, ddv, v);
    let slope = (m.mu_v(w + H, ddv, v) - m.mu_v(w - H, ddv, v)) / (2.0 * H);
    (
        mu,
        if slope.is_finite() {
            slope.max(0.0)
        } else {
            0.0
        },
    )
}

/// Linear interpolation of the brake demand, held after the last point; `cursor` advances.
#[inline]
fn demand_at(points: &[(f64, f64)], t: f64, cursor: &mut usize) -> f64 {
    while *cursor + 1 < points.len() && points[*cursor + 1].0 <= t {
        *cursor += 1;
    }
    let (t0, p0) = points[*cursor];
    if t <= t0 || *cursor + 1 == points.len() {
        return if t < points[0].0 { points[0].1 } else { p0 };
    }
    let (t1, p1) = points[*cursor + 1];
    p0 + (p1 - p0) * (t - t0) / (t1 - t0)
}

/// Runs a scene. `seed` overrides the scene's seed.
pub fn simulate(sc: &Scene, seed: Option<u64>) -> Result<SimOutput, SimError> {
    let fx = sc.effects;
    let model = match &sc.law {
        AdhesionLaw::Polach => None,
        AdhesionLaw::Model(path) => {
            // `temperature` applies to a model with a temperature law (a campaign's Polach
            // model); checked below when the model is loaded.
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
                return Err(SimError::Scene {
                    scene: sc.name.clone(),
                    what: format!(
                        "effects {} describe the Polach truth law, but adhesion.law = \"model\"",
                        clash.join(", ")
                    ),
                    hint: "a learned model carries those effects itself: remove them from effects"
                        .into(),
                });
            }
            let m = crate::model::Model::load(path).map_err(|e| SimError::Scene {
                scene: sc.name.clone(),
                what: format!("adhesion.model: {e}"),
                hint: "give a model file written by `railgrip train`".into(),
            })?;
            Some(if fx.has(Effect::Temperature) {
                m.at_temperature(sc.ambient_temperature_c)
                    .map_err(|e| SimError::Scene {
                        scene: sc.name.clone(),
                        what: format!("effect temperature with adhesion.model: {e}"),
                        hint: "remove temperature from effects, or use a Polach model fitted at several ambient temperatures that cover run.ambient_temperature_c".into(),
                    })?
            } else {
                m
            })
        }
    };
    let seed = seed.unwrap_or(sc.seed);
    let run = run_detected(sc, model.as_ref(), seed)?;
    let veh = &sc.vehicle;
    let h = sc.step_s;

    let metadata = RunMetadata {
        ambient_temperature_c: Some(sc.ambient_temperature_c),
        initial_speed_kmh: Some(sc.initial_speed_kmh),
        vehicle: Some(veh.name.clone()),
        condition: Some(sc.condition.clone()),
        direction: Some(sc.direction.clone()),
        other: [
            ("scene".to_string(), sc.name.clone()),
            ("seed".to_string(), seed.to_string()),
            ("effects".to_string(), fx.names().join(",")),
            (
                "generator".to_string(),
                concat!("railgrip ", env!("CARGO_PKG_VERSION"), " simulate").to_string(),
            ),
        ]
        .into(),
    };
    let (channels, truth, counters, n) = run;
    Ok(SimOutput {
        scene: sc.clone(),
        channels,
        truth,
        metadata,
        counters,
        steps: n,
        duration_s: n as f64 * h,
    })
}

/// Normal deviates for the sensor noise, both of each Box–Muller pair (one log, one sqrt and
/// one sin_cos per two deviates).
#[derive(Default)]
struct Normals {
    spare: Option<f64>,
}

impl Normals {
    fn next(&mut self, rng: &mut Rng) -> f64 {
        match self.spare.take() {
            Some(x) => x,
            None => {
                let (x, y) = rng.normal_pair();
                self.spare = Some(y);
                x
            }
        }
    }
}

/// What [`prepare`] needs besides the state.
struct Prepare<'a> {
    /// μ of each axle with cleaning, 1.
    mu_axle: &'a [f64; AXLES],
    /// Static loads N0 (N) and ∂N/∂d (N per m/s², zeros without load transfer).
    load: &'a [f64; AXLES],
    per_decel: &'a [f64; AXLES],
    /// Falling friction's A and B (1, s/m), if the effect is on.
    falling: Option<(f64, f64)>,
}

/// The contact law's coefficients for the axle step at deceleration `decel` (m/s²), slip
/// `slip` (m/s), speed factor `speed` (1; 1 without falling friction) and 1/(2K) `half_inv_k`
/// (1/N): N = N0 + d ∂N/∂d (seed 002 eq. 12–13, [`crate::vehicle::axle_load_coefficients`]),
/// μ = μ_axle s(v) ((1 − A) e^(−B|Δv|) + A), and from them `ax.d_per_v` = (N/2) μ/K and
/// `ax.pn` = (2/π) μ N; N goes to `normal`.
#[inline(always)]
fn prepare<V: Select>(
    isa: V::Isa,
    p: &Prepare,
    half_inv_k: &[f64; AXLES],
    speed: f64,
    decel: f64,
    slip: &[f64; AXLES],
    ax: &mut AxleArrays,
    normal: &mut [f64; AXLES],
) {
    let mut i = 0;
    while i < AXLES {
        let n =
            V::splat(isa, decel).fma(V::load(isa, &p.per_decel[i..]), V::load(isa, &p.load[i..]));
        let mut mu = V::load(isa, &p.mu_axle[i..]).mul(V::splat(isa, speed));
        if let Some((a, b)) = p.falling {
            let e = exp_lanes(
                V::load_scalars(isa, &slip[i..])
                    .abs()
                    .mul(V::splat(isa, -b)),
            );
            mu = mu.mul(e.fma(V::splat(isa, 1.0 - a), V::splat(isa, a)));
        }
        n.store(&mut normal[i..]);
        n.mul(V::load(isa, &half_inv_k[i..]))
            .mul(mu)
            .store(&mut ax.d_per_v[i..]);
        V::splat(isa, std::f64::consts::FRAC_2_PI)
            .mul(mu)
            .mul(n)
            .store(&mut ax.pn[i..]);
        i += V::N;
    }
}

/// What the step loop produced: channels, truth, counters, steps.
type RunResult = (Vec<Series>, Truth, EffectCounters, u64);

/// The step loop on the portable path (one axle per lane).
fn run_portable(
    sc: &Scene,
    model: Option<&crate::model::Model>,
    seed: u64,
) -> Result<RunResult, SimError> {
    run::<f64>(Portable, sc, model, seed)
}

/// The step loop with the four axles in one AVX2 register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn run_avx2(
    isa: Avx2,
    sc: &Scene,
    model: Option<&crate::model::Model>,
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
    model: Option<&crate::model::Model>,
    seed: u64,
) -> Result<RunResult, SimError> {
    run::<F64x4>(isa.avx2(), sc, model, seed)
}

/// The step loop on the widest path this CPU has.
fn run_detected(
    sc: &Scene,
    model: Option<&crate::model::Model>,
    seed: u64,
) -> Result<RunResult, SimError> {
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
/// instantiation performs the same IEEE operations (bit-identical results).
#[inline(always)]
fn run<V: Select>(
    isa: V::Isa,
    sc: &Scene,
    model: Option<&crate::model::Model>,
    seed: u64,
) -> Result<RunResult, SimError> {
    let fx = sc.effects;
    let veh = &sc.vehicle;
    let r = veh.wheel_radius_m;
    let mass = veh.body_mass_kg + 2.0 * veh.bogie_mass_kg;
    let h = sc.step_s;
    let mut rng = Rng::new(seed);
    let mut normals = Normals::default();
    let mut counters = EffectCounters::default();

    // Contact patch of one wheel at the static load (Hertz, seed 001; Kalker c11).
    let contact_err = |source| SimError::Contact {
        scene: sc.name.clone(),
        source,
    };
    let (patch, q0) = crate::vehicle::wheel_patch(veh, &sc.contact).map_err(contact_err)?;
    let k0 = PI * patch.g_pa * patch.a_m * patch.b_m * patch.c11 / 4.0;
    let contact = [AxleContact { k0, q0 }; AXLES];

    let (k_a, k_s) = if fx.has(Effect::Temperature) {
        counters.hit(Effect::Temperature);
        sc.temperature_law
            .eval(sc.ambient_temperature_c)
            .map_err(contact_err)?
    } else {
        (sc.polach.k_a, sc.polach.k_s)
    };
    let consts = StepConsts {
        r,
        j: veh.axle_inertia_kgm2,
        h,
        k_a,
        k_s,
    };
    let mut mu_axle = [sc.polach.mu0; AXLES];
    if fx.has(Effect::Cleaning) {
        for (i, m) in mu_axle.iter_mut().enumerate() {
            counters.hit(Effect::Cleaning);
            *m *= 1.0 + sc.cleaning_per_axle * i as f64;
        }
    }
    let grade_force = if fx.has(Effect::Gradient) {
        counters.hit(Effect::Gradient);
        mass * G_MPS2 * (sc.gradient_permille / 1000.0).atan().sin()
    } else {
        0.0
    };
    let k_cyl = 1.0 - (-h / sc.cylinder_time_constant_s).exp();
    let k_hyst = 1.0 - (-h / sc.hysteresis_time_constant_s).exp();
    let falling = fx.has(Effect::FallingFriction);
    let hysteresis = fx.has(Effect::Hysteresis);
    // Falling friction μ = μ_axle · s(v) · ((1 − A) e^(−B|Δv|) + A), s(v) the speed factor.
    let speed_slope = sc.speed_coefficient / sc.reference_speed_mps;
    let speed_at_zero = 1.0 + sc.speed_coefficient;
    let (fall_a, fall_b) = (sc.polach.a_ratio, sc.polach.b_s_per_m);
    // State.
    let mut v = sc.initial_speed_mps;
    let (load, per_decel) = crate::vehicle::axle_load_coefficients(veh);
    let per_decel = if fx.has(Effect::LoadTransfer) {
        per_decel
    } else {
        [0.0; AXLES]
    };
    let mut ax = AxleArrays {
        omega: [v / r; AXLES],
        hyst: [if hysteresis {
            hysteresis_target(sc.hysteresis_depth, 0.0, 1.0)
        } else {
            1.0
        }; AXLES],
        ..Default::default()
    };
    let mut half_inv_k = [0.5 / k0; AXLES];
    // The contact law's slowly varying coefficients — the axle loads (load transfer), the
    // falling-friction and speed factors — are taken at the start of the previous step
    // (`prepare`): then the step's critical path starts at the vehicle and wheel speeds alone.
    let mut normal_next = [0.0; AXLES];
    let prep = Prepare {
        mu_axle: &mu_axle,
        load: &load,
        per_decel: &per_decel,
        falling: falling.then_some((fall_a, fall_b)),
    };
    let initial_speed = if falling {
        speed_slope.mul_add(-v, speed_at_zero).max(0.2)
    } else {
        1.0
    };
    prepare::<V>(
        isa,
        &prep,
        &half_inv_k,
        initial_speed,
        0.0,
        &[0.0; AXLES],
        &mut ax,
        &mut normal_next,
    );
    let mut normal = normal_next;
    let mut theta = [0.0f64; AXLES];
    let mut p = [0.0f64; AXLES];
    let mut wsp = [WspState::Apply; AXLES];
    let mut hold_cmd = [0.0f64; AXLES];
    let mut wsp_timer = [0.0f64; AXLES];
    let mut ddv = [0.0f64; AXLES];
    let mut ddv_lag = [0.0f64; AXLES];
    let mut omega_dot = [0.0f64; AXLES];
    let mut decel = 0.0f64;
    let mut cursor = [0usize; AXLES];
    let mut slip = [0.0f64; AXLES];

    // Output schedules: logger sample k of a channel group is at k / rate.
    let rates = [
        sc.radar_rate_hz,
        sc.tacho_rate_hz,
        sc.pressure_rate_hz,
        sc.output_rate_hz,
    ];
    let mut next_k = [0u64; 4];
    // Logger time of the next sample of each group (k / rate), compared without dividing.
    let mut next_t = [0.0f64; 4];
    // The earliest of them.
    let mut next_due = 0.0f64;
    let inv_h = 1.0 / h;
    let h_per_mass = h / mass;
    let inv_ddv0 = 1.0 / sc.hysteresis_ddv_mps2;
    // Room for the whole run up front (at most ten minutes' worth): no reallocation and copy
    // while the step loop runs.
    let room = |rate: f64| ((sc.max_duration_s.min(600.0) * rate).ceil() as usize) + 2;
    let series = |rate: f64| Series {
        time_s: Vec::with_capacity(room(rate)),
        values: Vec::with_capacity(room(rate)),
    };
    let mut channels: Vec<Series> = (0..9)
        .map(|i| {
            series(
                rates[if i == 0 {
                    0
                } else if i < 5 {
                    1
                } else {
                    2
                }],
            )
        })
        .collect();
    let column = || Vec::with_capacity(room(sc.output_rate_hz));
    let columns = || std::array::from_fn(|_| column());
    let mut truth = Truth {
        time_s: column(),
        v_mps: column(),
        omega_radps: columns(),
        p_bar: columns(),
        normal_n: columns(),
        tangential_n: columns(),
        mu: columns(),
        dv_mps: columns(),
        ddv_mps2: columns(),
    };
    let pulse_angle = std::f64::consts::TAU / sc.tacho_pulses_per_rev;
    let window = ((sc.tacho_window_s * sc.tacho_rate_hz).round() as usize).max(1);
    let mut theta_hist: Vec<[f64; AXLES]> = vec![[0.0; AXLES]; window + 1];
    let mut spike_prob = sc.radar_spike_rate_hz / sc.radar_rate_hz;
    if !spike_prob.is_finite() {
        spike_prob = 0.0;
    }

    let max_steps = (sc.max_duration_s / h).ceil() as u64;
    let mut n: u64 = 0;
    loop {
        let t = n as f64 * h;
        let omega = ax.omega;
        // ---- outputs at their logger instants (state at the first step at or after them)
        let outputs_due = t + 1e-12 >= next_due;
        for (g, rate) in rates.iter().enumerate() {
            if !outputs_due {
                break;
            }
            while next_t[g] <= t + 1e-12 {
                // Logger clock at µs resolution.
                let ts = round_to(next_k[g] as f64 / rate, 1e6);
                match g {
                    0 => {
                        let mut m = v;
                        if fx.has(Effect::RadarNoise) {
                            counters.hit(Effect::RadarNoise);
                            m += sc.radar_noise_mps * normals.next(&mut rng);
                        }
                        if fx.has(Effect::RadarSpikes) {
                            counters.hit(Effect::RadarSpikes);
                            if rng.uniform() < spike_prob {
                                m += if rng.uniform() < 0.5 { -1.0 } else { 1.0 }
                                    * sc.radar_spike_mps
                                    * (0.5 + rng.uniform());
                            }
                        }
                        push(&mut channels[0], ts, round_to(m.max(0.0), 1e3));
                    }
                    1 => {
                        let k = next_k[1] as usize;
                        let slot = k % (window + 1);
                        theta_hist[slot] = theta;
                        for a in 0..AXLES {
                            let m = if fx.has(Effect::TachoQuantization) {
                                counters.hit(Effect::TachoQuantization);
                                // Pulses counted over the last `window` samples.
                                let span = k.min(window);
                                if span == 0 {
                                    omega[a]
                                } else {
                                    let old = theta_hist[(k - span) % (window + 1)][a];
                                    let count = (theta[a] / pulse_angle).floor()
                                        - (old / pulse_angle).floor();
                                    count * pulse_angle * rate / span as f64
                                }
                            } else {
                                omega[a]
                            };
                            push(&mut channels[1 + a], ts, round_to(m, 1e4));
                        }
                    }
                    2 => {
                        for a in 0..AXLES {
                            let mut m = p[a];
                            if fx.has(Effect::PressureNoise) {
                                counters.hit(Effect::PressureNoise);
                                m += sc.pressure_noise_bar * normals.next(&mut rng);
                            }
                            push(&mut channels[5 + a], ts, round_to(m, 1e3));
                        }
                    }
                    _ => {
                        truth.time_s.push(ts);
                        truth.v_mps.push(v);
                        for a in 0..AXLES {
                            truth.omega_radps[a].push(omega[a]);
                            truth.p_bar[a].push(p[a]);
                            truth.normal_n[a].push(normal[a]);
                            truth.tangential_n[a].push(ax.t_star[a]);
                            truth.mu[a].push(ax.t_star[a] / normal[a]);
                            truth.dv_mps[a].push(v - r * omega[a]);
                            truth.ddv_mps2[a].push(ddv[a]);
                        }
                        if fx.has(Effect::LoadTransfer) {
                            // Refresh the patch constant for the wheel loads (a b ∝ Q^(2/3)).
                            for a in 0..AXLES {
                                counters.hit(Effect::LoadTransfer);
                                let c = &contact[a];
                                let ratio = (normal[a] * 0.5 / c.q0).cbrt();
                                half_inv_k[a] = 0.5 / (c.k0 * ratio * ratio);
                            }
                        }
                    }
                }
                next_k[g] += 1;
                next_t[g] = next_k[g] as f64 / rate;
            }
        }
        if outputs_due {
            next_due = next_t.iter().copied().fold(f64::INFINITY, f64::min);
        }
        if v <= sc.stop_speed_mps || n >= max_steps {
            break;
        }

        // ---- loads and resistances
        if fx.has(Effect::LoadTransfer) {
            // The loads themselves: N = N0 + d ∂N/∂d in the axle step.
            counters.hit(Effect::LoadTransfer);
        }
        let mut resist = grade_force;
        if fx.has(Effect::RunningResistance) {
            counters.hit(Effect::RunningResistance);
            resist += sc.davis_a_n + sc.davis_b_n_per_mps * v + sc.davis_c_n_per_mps2 * v * v;
        }
        let speed_factor = if falling {
            counters.add(Effect::FallingFriction, AXLES as u64);
            speed_slope.mul_add(-v, speed_at_zero).max(0.2)
        } else {
            1.0
        };
        let v_resisted = (-resist).mul_add(h_per_mass, v);
        // ---- brakes: demand, wheel-slide protection, cylinders (per axle, before the
        // contact: WSP reads the slip and the wheel's deceleration, not the force)
        if fx.has(Effect::Wsp) {
            counters.add(Effect::Wsp, AXLES as u64);
        }
        for a in 0..AXLES {
            let demand = demand_at(&sc.demand_bar[a], t, &mut cursor[a]);
            let w = (-r).mul_add(omega[a], v);
            slip[a] = w;
            let cmd = if fx.has(Effect::Wsp) {
                let wheel_decel_excess = -r * omega_dot[a] - decel;
                let dump_at = sc.dump_slip_mps.max(sc.dump_slip_ratio * v);
                let sliding = w > dump_at || wheel_decel_excess > sc.decel_limit_mps2;
                wsp_timer[a] += h;
                let next = match wsp[a] {
                    WspState::Apply if sliding => WspState::Detect,
                    WspState::Detect if wsp_timer[a] >= sc.reaction_delay_s => WspState::Dump,
                    WspState::Dump if w < dump_at && ddv[a] < 0.0 => {
                        hold_cmd[a] = p[a];
                        WspState::Hold
                    }
                    WspState::Hold if w < sc.reapply_slip_mps || wsp_timer[a] >= sc.hold_max_s => {
                        WspState::Apply
                    }
                    WspState::Hold if w > dump_at && ddv[a] > 0.0 => WspState::Dump,
                    s => s,
                };
                if next != wsp[a] {
                    wsp_timer[a] = 0.0;
                    wsp[a] = next;
                }
                match wsp[a] {
                    WspState::Apply | WspState::Detect => demand,
                    WspState::Dump => 0.0,
                    WspState::Hold => hold_cmd[a].min(demand),
                }
            } else {
                demand
            };
            p[a] += (cmd - p[a]) * k_cyl;
            ax.brake[a] = veh.brake_torque_nm_per_bar[a] * p[a];
        }

        // ---- contact and wheels
        normal = normal_next;
        let total_t = match model {
            None => polach_axles::<V>(isa, &consts, v, &mut ax),
            Some(m) => {
                for a in 0..AXLES {
                    // The model's slip-rate input is lagged like the hysteresis branch: fed
                    // instantly it closes the same force → slip-rate → force loop.
                    ddv_lag[a] += (ddv[a] - ddv_lag[a]) * k_hyst;
                    let (mu, slope) = model_adhesion(m, slip[a], ddv_lag[a], v);
                    let (w, l, t) = wheel_update::<f64>(
                        &consts,
                        ax.omega[a],
                        ax.locked[a],
                        ax.brake[a],
                        normal[a],
                        mu,
                        slope,
                        1.0,
                    );
                    (ax.omega[a], ax.locked[a], ax.t_star[a]) = (w, l, t);
                }
                (ax.t_star[0] + ax.t_star[2]) + (ax.t_star[1] + ax.t_star[3])
            }
        };
        if hysteresis {
            counters.add(Effect::Hysteresis, AXLES as u64);
            // The branch factor for the next step (see `hysteresis_target`), lagged by
            // `k_hyst`, from this step's starting slip rate: off the step's critical path.
            let mut i = 0;
            while i < AXLES {
                let target = hysteresis_target(
                    sc.hysteresis_depth,
                    V::load_scalars(isa, &ddv[i..]),
                    inv_ddv0,
                );
                let old = V::load(isa, &ax.hyst[i..]);
                target
                    .sub(old)
                    .fma(V::splat(isa, k_hyst), old)
                    .store(&mut ax.hyst[i..]);
                i += V::N;
            }
        }
        // The next step's contact coefficients, from this step's start (off the critical path).
        prepare::<V>(
            isa,
            &prep,
            &half_inv_k,
            speed_factor,
            decel,
            &slip,
            &mut ax,
            &mut normal_next,
        );

        let v_new = total_t.mul_add(-h_per_mass, v_resisted).max(0.0);
        decel = (v - v_new) * inv_h;
        for a in 0..AXLES {
            omega_dot[a] = (ax.omega[a] - omega[a]) * inv_h;
            theta[a] += ax.omega[a] * h;
            // Slip rates use the vehicle's change too.
            let w_new = (-r).mul_add(ax.omega[a], v);
            ddv[a] = (w_new - slip[a]) * inv_h - decel;
        }
        v = v_new;
        n += 1;
    }
    Ok((channels, truth, counters, n))
}

/// A truth value as stored: float32 rounded to 16 significant bits (relative resolution
/// 2^-16 ≈ 1.5e-5; μ to ~1e-6, far below any estimator's error). The low mantissa bits of
/// simulated doubles are noise to a compressor; dropping them keeps the bundled archive small.
pub fn truth_f32(x: f64) -> f32 {
    let b = (x as f32).to_bits();
    if !(x as f32).is_finite() {
        return x as f32;
    }
    f32::from_bits(b.wrapping_add(0x80) & !0xFF)
}

#[inline]
fn push(s: &mut Series, t: f64, v: f64) {
    s.time_s.push(t);
    s.values.push(v);
}

/// Rounds to a resolution of 1/inv (a logger's resolution; keeps files small and exact).
#[inline]
fn round_to(x: f64, inv: f64) -> f64 {
    (x * inv).round() / inv
}

/// Output formats of `railgrip simulate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    Csv,
    Mcap,
    Both,
}

/// Column names of the truth table (`<name>.truth.parquet`), one row per sample and axle:
/// `time_s` Float64, `axle` Int32 (1..4), the rest Float32 at 16 significant bits
/// ([`truth_f32`]).
pub const TRUTH_COLUMNS: [&str; 10] = [
    "time_s",
    "axle",
    "v_mps",
    "omega_radps",
    "p_bar",
    "normal_N",
    "tangential_N",
    "mu",
    "dv_mps",
    "ddv_mps2",
];

impl SimOutput {
    /// Writes the run to `dir`: `<stem>.csv` + `<stem>.meta.toml` and/or `<stem>.mcap`, and
    /// `<stem>.truth.parquet`. Every file is written atomically. Returns the paths written.
    pub fn write(
        &self,
        dir: &Path,
        stem: &str,
        fmt: OutputFormat,
    ) -> Result<Vec<PathBuf>, SimError> {
        let werr = |path: &Path| {
            let path = path.to_path_buf();
            move |e: std::io::Error| SimError::Write {
                path: path.clone(),
                message: e.to_string(),
            }
        };
        std::fs::create_dir_all(dir).map_err(werr(dir))?;
        let mut written = Vec::new();
        if matches!(fmt, OutputFormat::Csv | OutputFormat::Both) {
            if !self.scene.single_rate() {
                return Err(SimError::Scene {
                    scene: self.scene.name.clone(),
                    what: "CSV has one time column, but the scene's sensors run at different rates"
                        .into(),
                    hint: "write MCAP (--format mcap) or give every sensor the output rate".into(),
                });
            }
            let path = dir.join(format!("{stem}.csv"));
            let cols: [&[f64]; 9] = std::array::from_fn(|i| self.channels[i].values.as_slice());
            crate::atomic::write_atomically(&path, |w| {
                format::write_canonical_csv(w, &self.channels[0].time_s, cols)
            })
            .map_err(werr(&path))?;
            written.push(path);
            let side = dir.join(format!("{stem}{}", format::SIDECAR_SUFFIX));
            let text = self.metadata.to_sidecar_toml();
            crate::atomic::write_atomically(&side, |w| {
                std::io::Write::write_all(w, text.as_bytes())
            })
            .map_err(werr(&side))?;
            written.push(side);
        }
        if matches!(fmt, OutputFormat::Mcap | OutputFormat::Both) {
            let path = dir.join(format!("{stem}.mcap"));
            let series: Vec<SeriesRef> = Signal::ALL
                .iter()
                .map(|s| SeriesRef {
                    signal: *s,
                    time_s: &self.channels[s.index()].time_s,
                    values: &self.channels[s.index()].values,
                })
                .collect();
            // A fixed start time keeps the bytes identical for the same scene and seed.
            crate::atomic::write_atomically(&path, |w| {
                let mut buf = std::io::Cursor::new(Vec::new());
                format::write_mcap(
                    &mut buf,
                    &series,
                    &self.metadata,
                    McapCompression::Zstd,
                    1_700_000_000_000_000_000,
                )
                .map_err(|e| std::io::Error::other(e.to_string()))?;
                std::io::Write::write_all(w, buf.get_ref())
            })
            .map_err(werr(&path))?;
            written.push(path);
        }
        let path = dir.join(format!("{stem}.truth.parquet"));
        self.write_truth(&path)?;
        written.push(path);
        Ok(written)
    }

    fn write_truth(&self, path: &Path) -> Result<(), SimError> {
        use polars::prelude::*;
        let tr = &self.truth;
        let n = tr.time_s.len();
        let perr = |e: PolarsError| SimError::Write {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let long = |f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
            (0..n)
                .flat_map(|i| (0..AXLES).map(move |a| (i, a)))
                .map(|(i, a)| f(i, a))
                .collect()
        };
        let long32 = |f: &dyn Fn(usize, usize) -> f64| -> Vec<f32> {
            long(f).into_iter().map(truth_f32).collect()
        };
        let cols = vec![
            Float64Chunked::from_vec(TRUTH_COLUMNS[0].into(), long(&|i, _| tr.time_s[i]))
                .into_column(),
            Int32Chunked::from_vec(
                TRUTH_COLUMNS[1].into(),
                (0..n).flat_map(|_| 1..=AXLES as i32).collect(),
            )
            .into_column(),
            Float32Chunked::from_vec(TRUTH_COLUMNS[2].into(), long32(&|i, _| tr.v_mps[i]))
                .into_column(),
            Float32Chunked::from_vec(
                TRUTH_COLUMNS[3].into(),
                long32(&|i, a| tr.omega_radps[a][i]),
            )
            .into_column(),
            Float32Chunked::from_vec(TRUTH_COLUMNS[4].into(), long32(&|i, a| tr.p_bar[a][i]))
                .into_column(),
            Float32Chunked::from_vec(TRUTH_COLUMNS[5].into(), long32(&|i, a| tr.normal_n[a][i]))
                .into_column(),
            Float32Chunked::from_vec(
                TRUTH_COLUMNS[6].into(),
                long32(&|i, a| tr.tangential_n[a][i]),
            )
            .into_column(),
            Float32Chunked::from_vec(TRUTH_COLUMNS[7].into(), long32(&|i, a| tr.mu[a][i]))
                .into_column(),
            Float32Chunked::from_vec(TRUTH_COLUMNS[8].into(), long32(&|i, a| tr.dv_mps[a][i]))
                .into_column(),
            Float32Chunked::from_vec(TRUTH_COLUMNS[9].into(), long32(&|i, a| tr.ddv_mps2[a][i]))
                .into_column(),
        ];
        let mut df = DataFrame::new(n * AXLES, cols).map_err(perr)?;
        crate::atomic::write_atomically(path, |w| {
            ParquetWriter::new(w)
                .finish(&mut df)
                .map(|_| ())
                .map_err(perr)
        })
        .map_err(|e| match e {
            SimError::Write { message, .. } => SimError::Write {
                path: path.to_path_buf(),
                message,
            },
            other => other,
        })
    }
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
  "running_resistance", "gradient", "radar_noise", "radar_spikes", "tacho_quantization", "pressure_noise"]
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
