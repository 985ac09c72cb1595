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

pub mod scene;

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use crate::contact::ContactError;
use crate::format::{self, McapCompression, RunMetadata, SeriesRef, Signal, AXLES};
use crate::rng::Rng;
pub use scene::{AdhesionLaw, Effect, Effects, Scene};

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

/// Per-axle contact constants: ε = K s / (Q μ) with K = π G a b c11 / 4 at wheel load Q.
#[derive(Debug, Clone, Copy)]
struct AxleContact {
    k0: f64,
    q0: f64,
    k: f64,
}

/// Adhesion of one axle for the current state: the ratio T/N and its slope ∂(T/N)/∂Δv (1/(m/s)).
#[inline]
#[allow(clippy::too_many_arguments)]
fn adhesion(
    sc: &Scene,
    fx: Effects,
    counters: &mut EffectCounters,
    k_a: f64,
    k_s: f64,
    mu_axle: f64,
    contact: f64,
    q_wheel: f64,
    v: f64,
    w: f64,
    hyst: f64,
) -> (f64, f64) {
    let mut mu = mu_axle;
    if fx.has(Effect::FallingFriction) {
        counters.hit(Effect::FallingFriction);
        let speed = (1.0
            + sc.speed_coefficient * (sc.reference_speed_mps - v) / sc.reference_speed_mps)
            .max(0.2);
        mu *= speed
            * ((1.0 - sc.polach.a_ratio) * (-sc.polach.b_s_per_m * w.abs()).exp()
                + sc.polach.a_ratio);
    }
    if v <= 0.0 {
        return (0.0, 0.0);
    }
    let eps_per_w = contact / (v * q_wheel * mu);
    let eps = eps_per_w * w;
    let (x, y) = (k_a * eps, k_s * eps);
    let two_mu_pi = 2.0 * mu * (1.0 / PI);
    let inv_x = 1.0 / (1.0 + x * x);
    let mut ratio = two_mu_pi * (x * inv_x + y.atan());
    let mut slope =
        two_mu_pi * (k_a * (1.0 - x * x) * inv_x * inv_x + k_s / (1.0 + y * y)) * eps_per_w;
    if fx.has(Effect::Hysteresis) {
        // The branch factor (see `hysteresis_target`), lagged by the step loop.
        ratio *= hyst;
        slope *= hyst;
    }
    (ratio, slope.max(0.0))
}

/// Hysteresis branch factor for the slip rate `ddv`: the recovery branch (dΔv/dt < 0) lower
/// by `depth`, blended smoothly by the algebraic sigmoid z/√(1 + z²), z = (dΔv/dt)/ddv0.
/// The step loop lags it with the time constant `hysteresis_time_constant_s`: the contact's
/// branch has memory, and applying it instantly closes an algebraic loop (force → slip rate
/// → force, loop gain ≈ N μ depth r² / (2 ddv0 J) ≈ 6 for the UIC-Z1) that the explicit
/// step turns into a relay chatter at the step rate.
#[inline]
fn hysteresis_target(depth: f64, ddv: f64, inv_ddv0: f64) -> f64 {
    let z = ddv * inv_ddv0;
    1.0 - depth * 0.5 * (1.0 - z / (1.0 + z * z).sqrt())
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
    let veh = &sc.vehicle;
    let r = veh.wheel_radius_m;
    let j = veh.axle_inertia_kgm2;
    let mass = veh.body_mass_kg + 2.0 * veh.bogie_mass_kg;
    let h = sc.step_s;
    let mut rng = Rng::new(seed.unwrap_or(sc.seed));
    let mut counters = EffectCounters::default();

    // Contact patch of one wheel at the static load (Hertz, seed 001; Kalker c11).
    let contact_err = |source| SimError::Contact {
        scene: sc.name.clone(),
        source,
    };
    let (patch, q0) = crate::vehicle::wheel_patch(veh, &sc.contact).map_err(contact_err)?;
    let k0 = PI * patch.g_pa * patch.a_m * patch.b_m * patch.c11 / 4.0;
    let mut contact = [AxleContact { k0, q0, k: k0 }; AXLES];

    let (k_a, k_s) = if fx.has(Effect::Temperature) {
        counters.hit(Effect::Temperature);
        sc.temperature_law
            .eval(sc.ambient_temperature_c)
            .map_err(contact_err)?
    } else {
        (sc.polach.k_a, sc.polach.k_s)
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

    // State.
    let mut v = sc.initial_speed_mps;
    let mut omega = [v / r; AXLES];
    let mut theta = [0.0f64; AXLES];
    let mut p = [0.0f64; AXLES];
    let mut locked = [false; AXLES];
    let mut wsp = [WspState::Apply; AXLES];
    let mut hold_cmd = [0.0f64; AXLES];
    let mut wsp_timer = [0.0f64; AXLES];
    let mut ddv = [0.0f64; AXLES];
    let mut hyst = [hysteresis_target(sc.hysteresis_depth, 0.0, 1.0); AXLES];
    let mut ddv_lag = [0.0f64; AXLES];
    let mut omega_dot = [0.0f64; AXLES];
    let mut decel = 0.0f64;
    let mut normal = [static_axle_load(veh); AXLES];
    let mut tangential = [0.0f64; AXLES];
    let mut cursor = [0usize; AXLES];

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
    let inv_h = 1.0 / h;
    let inv_ddv0 = 1.0 / sc.hysteresis_ddv_mps2;
    let mut channels: Vec<Series> = (0..9).map(|_| Series::default()).collect();
    let mut truth = Truth::default();
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
        // ---- outputs at their logger instants (state at the first step at or after them)
        for (g, rate) in rates.iter().enumerate() {
            while next_t[g] <= t + 1e-12 {
                // Logger clock at µs resolution.
                let ts = round_to(next_k[g] as f64 / rate, 1e6);
                match g {
                    0 => {
                        let mut m = v;
                        if fx.has(Effect::RadarNoise) {
                            counters.hit(Effect::RadarNoise);
                            m += sc.radar_noise_mps * rng.normal();
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
                                m += sc.pressure_noise_bar * rng.normal();
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
                            truth.tangential_n[a].push(tangential[a]);
                            truth.mu[a].push(tangential[a] / normal[a]);
                            truth.dv_mps[a].push(v - r * omega[a]);
                            truth.ddv_mps2[a].push(ddv[a]);
                        }
                        if fx.has(Effect::LoadTransfer) {
                            // Refresh the patch stiffness for the wheel loads (a b ∝ Q^(2/3)).
                            for (c, nn) in contact.iter_mut().zip(&normal) {
                                counters.hit(Effect::LoadTransfer);
                                let ratio = (nn * 0.5 / c.q0).cbrt();
                                c.k = c.k0 * ratio * ratio;
                            }
                        }
                    }
                }
                next_k[g] += 1;
                next_t[g] = next_k[g] as f64 / rate;
            }
        }
        if v <= sc.stop_speed_mps || n >= max_steps {
            break;
        }

        // ---- loads and resistances
        if fx.has(Effect::LoadTransfer) {
            counters.hit(Effect::LoadTransfer);
            normal = axle_loads(veh, decel);
        }
        let mut resist = grade_force;
        if fx.has(Effect::RunningResistance) {
            counters.hit(Effect::RunningResistance);
            resist += sc.davis_a_n + sc.davis_b_n_per_mps * v + sc.davis_c_n_per_mps2 * v * v;
        }

        // ---- axles
        let mut total_t = 0.0;
        for a in 0..AXLES {
            let demand = demand_at(&sc.demand_bar[a], t, &mut cursor[a]);
            let w = v - r * omega[a];
            if fx.has(Effect::Hysteresis) {
                counters.hit(Effect::Hysteresis);
                let target = hysteresis_target(sc.hysteresis_depth, ddv[a], inv_ddv0);
                hyst[a] += (target - hyst[a]) * k_hyst;
            }
            let (ratio, slope) = match &model {
                None => adhesion(
                    sc,
                    fx,
                    &mut counters,
                    k_a,
                    k_s,
                    mu_axle[a],
                    contact[a].k,
                    normal[a] / 2.0,
                    v,
                    w,
                    hyst[a],
                ),
                Some(m) => {
                    // The model's slip-rate input is lagged like the hysteresis branch: fed
                    // instantly it closes the same force → slip-rate → force loop.
                    ddv_lag[a] += (ddv[a] - ddv_lag[a]) * k_hyst;
                    model_adhesion(m, w, ddv_lag[a], v)
                }
            };
            let t_a = ratio * normal[a];

            let cmd = if fx.has(Effect::Wsp) {
                counters.hit(Effect::Wsp);
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
            let brake = veh.brake_torque_nm_per_bar[a] * p[a];
            let old = omega[a];
            if locked[a] && t_a * r > brake {
                locked[a] = false;
            }
            // Force applied over the step: the creep force linearised at the new wheel speed,
            // T* = T(ω_n) − r (dμ/dΔv) N (ω_{n+1} − ω_n). With it the wheel's momentum balance
            // J ω̇ = T* r − α p holds exactly for the linearly implicit step below, and the
            // vehicle feels the same force (the truth table records T*).
            let mut t_star = t_a;
            if !locked[a] {
                let f = (t_a * r - brake) / j;
                let stiff = h * r * r * slope * normal[a] / j;
                omega[a] = old + h * f / (1.0 + stiff);
                if omega[a] <= 0.0 {
                    omega[a] = 0.0;
                    locked[a] = true;
                } else {
                    t_star = t_a - r * slope * normal[a] * (omega[a] - old);
                }
            }
            tangential[a] = t_star;
            total_t += t_star;
            omega_dot[a] = (omega[a] - old) * inv_h;
            theta[a] += omega[a] * h;
            let w_new = v - r * omega[a];
            ddv[a] = (w_new - w) * inv_h;
        }
        let v_new = (v + h * (-total_t - resist) / mass).max(0.0);
        decel = (v - v_new) * inv_h;
        // Slip rates use the vehicle's change too.
        for x in ddv.iter_mut() {
            *x -= decel;
        }
        v = v_new;
        n += 1;
    }

    let metadata = RunMetadata {
        ambient_temperature_c: Some(sc.ambient_temperature_c),
        initial_speed_kmh: Some(sc.initial_speed_kmh),
        vehicle: Some(veh.name.clone()),
        condition: Some(sc.condition.clone()),
        direction: Some(sc.direction.clone()),
        other: [
            ("scene".to_string(), sc.name.clone()),
            ("seed".to_string(), seed.unwrap_or(sc.seed).to_string()),
            ("effects".to_string(), fx.names().join(",")),
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
        steps: n,
        duration_s: n as f64 * h,
    })
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
