//! The simulation's state apart from its loop: [`Setup`] holds what a scene fixes for the whole
//! run (derived once), [`SimState`] what a step changes. The stages of a step are methods of
//! [`Setup`] that take the state explicitly — loads and resistances, brakes, contact and wheels,
//! the hysteresis branch, the next step's contact coefficients, the vehicle — each effect's work
//! behind its flag and counted where it is done ([`EffectCounters`]).

use std::f64::consts::PI;

use super::foreign::ScalarLaw;
use super::scene::{Effect, Effects, Scene};
use super::step::{polach_axles, wheel_update, AxleArrays, StepConsts};
use super::wsp::{demand_at, AxleReading, Wsp};
use super::{EffectCounters, SimError};
use crate::format::AXLES;
use crate::simd::{exp_lanes, Select};
use crate::vehicle::G_MPS2;

/// What a scene fixes for the whole run.
pub(super) struct Setup<'a> {
    pub sc: &'a Scene,
    fx: Effects,
    /// Wheel radius r (m), total mass M (kg), step h (s), 1/h, h/M.
    pub r: f64,
    pub h: f64,
    inv_h: f64,
    h_per_mass: f64,
    pub consts: StepConsts,
    /// Per axle: K0 = π G a b c11 / 4 at the static wheel load Q0 (N, N); K ∝ (Q/Q0)^(2/3).
    k0: f64,
    q0: f64,
    /// μ of each axle with cleaning, 1.
    mu_axle: [f64; AXLES],
    /// Static loads N0 (N) and ∂N/∂d under load transfer (N per m/s²).
    load: [f64; AXLES],
    per_decel: [f64; AXLES],
    /// Falling friction's A and B (1, s/m), if the effect is on.
    falling: Option<(f64, f64)>,
    /// Speed factor s(v) = speed_at_zero − speed_slope · v (falling friction).
    speed_slope: f64,
    speed_at_zero: f64,
    grade_force: f64,
    /// First-order lag factors per step: cylinders, hysteresis branch (and a model's slip-rate
    /// input).
    k_cyl: f64,
    k_hyst: f64,
    inv_ddv0: f64,
    /// Each axle's brake coefficient α_i (N m/bar): the pipeline's, off by `brake_scatter`.
    alpha: [f64; AXLES],
    /// `pad_friction`: (rise, 1/v0, n): α_i (1 + rise (1 − v/v0)^n).
    pad: Option<(f64, f64, f64)>,
    /// `load_fluctuation`'s filter, if the effect is on.
    fluctuation: Option<LoadFluctuation>,
    /// The `thermal` effect's constants, if listed.
    thermal: Option<Thermal>,
}

/// The `thermal` effect (docs/simulator.md), per axle, from the slip Δv and contact force T
/// (off the step's critical path, like the other slow coefficients). Every step adds the slip
/// power |T Δv| to a sum; every k steps (k h = `adhesion.thermal_update_ms`, default 0.5 ms —
/// of the order of the contact's transit time 2a/v, 0.3 ms at 120 km/h and 1 ms at 36 km/h
/// for the bundled vehicle; its cost and error are in docs/benchmarks.md) the mean power P̄ over those steps updates:
///
/// - tread temperature θ_w (both wheels of the axle, one heated layer of capacity C):
///   C dθ_w/dt = δ P̄ − h_c (θ_w − θ_amb)            (explicit Euler, step k h)
/// - flash temperature on top, full sliding over the centre strip of the wheel's Hertz patch
///   (seed 000 eq. 9 at depth 0 and eq. 11; [`crate::contact::flash`]):
///   ΔT_f = K δ μ p_max |Δv| √(2a / v) / √(πλρc), K = 1.53 the peak of Jaeger's integral for
///   a semi-elliptic source (computed once by the strip model), μ|Δv| = P̄/N, p_max and a of
///   the patch at the axle's current load (∝ (Q/Q0)^(1/3), refreshed at the output rate like the
///   patch stiffness under load transfer), v ≥ 0.5 m/s; rail steel
///   [assumed: `flash::Material::RAIL_STEEL`];
/// - contact temperature θ_c = θ_w + ΔT_f, and the friction factor, applied from the next
///   step's contact coefficients on
///   f(σ, θ) = (σ/σ0)^(−γ) · [r + (1 − r) e^(−max(0, θ_c − θ_ref)/θ_s)],
///   σ = p_max, σ0 its static value: friction falling with temperature and pressure as seed
///   000's f(σ, θ) does, in a form railgrip assumes (every parameter [assumed]).
struct Thermal {
    partition: f64,
    /// Steps per update k, 1/k, and k h / C (K/J).
    window: u32,
    inv_window: f64,
    h_per_capacity: f64,
    cooling: f64,
    ambient_c: f64,
    reference_c: f64,
    inv_scale: f64,
    residual: f64,
    gamma: f64,
    /// K/√(πλρc), K m²·s^½/W·… : the flash rise per (q0 √tc).
    flash_gain: f64,
    /// Static patch: semi-axis a (m), p_max (Pa).
    a0: f64,
    p0: f64,
}

impl Thermal {
    fn new(sc: &Scene) -> Result<Thermal, crate::contact::ContactError> {
        use crate::contact::fastsim::Field;
        use crate::contact::flash::{flash_temperature, full_sliding, Heating, Material};
        let t = &sc.adhesion.thermal;
        let (hz, _, _) = crate::vehicle::wheel_hertz(&sc.vehicle, &sc.contact)?;
        // K/√(πλρc) from the library's strip model: unit full-sliding source over the centre
        // strip (a = b = 1 mm, N = 1, μ = 1, slip 1 m/s, v = 1 m/s).
        let mut field = Field::new(200, 1);
        full_sliding(1e-3, 1e-3, 1.0, 1.0, 1.0, &mut field)?;
        let rise = flash_temperature(
            &field,
            1.0,
            &Material::RAIL_STEEL,
            &Heating {
                partition: 1.0,
                initial_temperature_c: 0.0,
                after_s: 0.0,
            },
        )?
        .peak_c;
        let q_unit = 1.5 / (PI * 1e-6);
        let flash_gain = rise / (q_unit * (2e-3f64).sqrt());
        let window = (t.update_ms * 1e-3 / sc.run.step_s).round().clamp(1.0, 1e6) as u32;
        Ok(Thermal {
            partition: t.partition,
            window,
            inv_window: 1.0 / window as f64,
            h_per_capacity: window as f64 * sc.run.step_s / t.tread_capacity_j_per_k,
            cooling: t.cooling_w_per_k,
            ambient_c: sc.run.ambient_temperature_c,
            reference_c: t.reference_c,
            inv_scale: 1.0 / t.scale_k,
            residual: t.residual,
            gamma: t.pressure_exponent,
            flash_gain,
            a0: hz.a_m,
            p0: hz.p_max_pa,
        })
    }
}

/// What a step changes.
#[derive(Debug, Clone)]
pub(super) struct SimState {
    /// Vehicle speed v, m/s.
    pub v: f64,
    /// Vehicle deceleration over the last step, m/s².
    pub decel: f64,
    /// The axles' wheel speeds and contact coefficients, as the axle step reads them.
    pub ax: AxleArrays,
    /// Axle loads N in use this step, and prepared for the next, N.
    pub normal: [f64; AXLES],
    pub normal_next: [f64; AXLES],
    /// 1/(2K) per axle at the current load, 1/N.
    pub half_inv_k: [f64; AXLES],
    /// Hertz semi-axes per axle relative to the static load's, (Q/Q0)^(1/3) (1 without load
    /// transfer; the `fastsim` law resizes its patch by it).
    pub patch_ratio: [f64; AXLES],
    /// Wheel angle θ, rad (the tachometers count its pulses).
    pub theta: [f64; AXLES],
    /// Cylinder pressure, bar.
    pub p: [f64; AXLES],
    /// Slip Δv at the start of the step (m/s), slip rate dΔv/dt (m/s²), its lagged value (the
    /// model law's input) and the wheel's ω̇ (rad/s²) over the last step.
    pub slip: [f64; AXLES],
    pub ddv: [f64; AXLES],
    pub ddv_lag: [f64; AXLES],
    pub omega_dot: [f64; AXLES],
    pub wsp: [Wsp; AXLES],
    /// Position in each axle's brake-demand profile.
    pub cursor: [usize; AXLES],
    /// `thermal`: the patch at the axle's load — √(2a) (m^½), p_max (Pa) and the pressure
    /// factor (p_max/p_max,0)^(−γ) — refreshed with the patch stiffness under load transfer.
    pub thermal_sqrt_2a: [f64; AXLES],
    pub thermal_p_max: [f64; AXLES],
    pub thermal_pressure: [f64; AXLES],
    /// `thermal`: tread and contact temperature (°C) and the friction factor f(σ, θ) (1
    /// without the effect).
    pub tread_c: [f64; AXLES],
    pub contact_c: [f64; AXLES],
    pub thermal_factor: [f64; AXLES],
    /// `thermal`: Σ |T Δv| over the steps since the last update (W), and their count.
    pub thermal_power: [f64; AXLES],
    pub thermal_steps: u32,
    /// `load_fluctuation`: each axle's load factor 1 + ε (1 without the effect), the band
    /// filter's four sections with their states (None without the effect), and its noise
    /// source.
    pub load_factor: [f64; AXLES],
    pub fluct_state: Option<[FluctSections; AXLES]>,
    pub fluct_rng: crate::rng::Rng,
}

/// The load fluctuation's band filter: two high-pass and two low-pass second-order sections.
const FLUCT_SECTIONS: usize = 4;

/// One axle's band filter: its sections, each with its state (the biquad crate's Direct Form
/// II transposed).
pub(super) type FluctSections = [biquad::DirectForm2Transposed<f64>; FLUCT_SECTIONS];

/// The `load_fluctuation` effect: per axle, white noise through a band-pass of two 4th-order
/// Butterworth filters, a high-pass at the band's bottom and a low-pass at its top (each two
/// of the biquad crate's bilinear-transform sections, Q = 1/(2 cos(π/8)) = 0.541196 and
/// 1/(2 cos(3π/8)) = 1.306563, as [`crate::signal::filter`]'s low-pass; at the step's rate 1/h,
/// h in s), scaled so that ε (relative, –) has the rms `run.load_fluctuation_rms` — the gain
/// from the filter's impulse response, Σ g_k² = 1 for the unit-variance input. 86 % of ε's
/// variance lies inside the band (a first-order band-pass kept 37 % of it, so at [2, 10] Hz and
/// 1.5 % rms only 0.92 % rms lay between 2 and 10 Hz). The band's top is at most 100 Hz and the
/// step at most 1 ms (the scene's rules), so every section lies below half the step rate.
#[derive(Debug, Clone, Copy)]
pub(super) struct LoadFluctuation {
    /// Each section's coefficients (a0 = 1).
    sections: [biquad::Coefficients<f64>; FLUCT_SECTIONS],
    gain: f64,
}

impl LoadFluctuation {
    /// The filter for the step `h` (s).
    fn new(sc: &Scene, h: f64) -> Result<LoadFluctuation, String> {
        use biquad::{Coefficients, ToHertz, Type};
        let [lo, hi] = sc.run.load_fluctuation_band_hz;
        let fs = 1.0 / h;
        const Q: [f64; 2] = [0.541_196_100_146_197, 1.306_562_964_876_376_6];
        let section = |kind: Type<f64>, f: f64, q: f64| {
            Coefficients::<f64>::from_params(kind, fs.hz(), f.hz(), q).map_err(|e| {
                format!(
                    "run.load_fluctuation_band_hz: {f} Hz at the step's {fs} Hz: {e:?} (the band must lie below half the step rate)"
                )
            })
        };
        let sections = [
            section(Type::HighPass, lo, Q[0])?,
            section(Type::HighPass, lo, Q[1])?,
            section(Type::LowPass, hi, Q[0])?,
            section(Type::LowPass, hi, Q[1])?,
        ];
        let mut f = LoadFluctuation {
            sections,
            gain: 1.0,
        };
        // Energy of the impulse response over 20 / (2π f_low) s (~7.7 time constants of the
        // high-pass's slowest pole, Q = 1.31: what is left is ~1e-7 of the energy).
        let steps = (20.0 / (std::f64::consts::TAU * lo * h)).ceil() as usize + 10;
        let mut state = f.sections();
        let mut energy = 0.0;
        for n in 0..steps {
            let y = LoadFluctuation::filter(&mut state, if n == 0 { 1.0 } else { 0.0 });
            energy += y * y;
        }
        f.gain = sc.run.load_fluctuation_rms / energy.sqrt();
        Ok(f)
    }

    /// The four sections at rest (zero states), for one axle.
    fn sections(&self) -> FluctSections {
        self.sections.map(biquad::DirectForm2Transposed::<f64>::new)
    }

    /// One sample `x` through an axle's four sections in turn, the gain not applied.
    #[inline(always)]
    fn filter(state: &mut FluctSections, x: f64) -> f64 {
        use biquad::Biquad;
        state.iter_mut().fold(x, |y, s| s.run(y))
    }
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

/// μ and dμ/dΔv from a scalar law (a learned model, a foreign law) at slip `w` (m/s), slip
/// rate `ddv` (m/s²), speed `v` (m/s), patch size `patch` relative to the static load's; the
/// slope by a forward difference over 0.1 mm/s away from zero slip (two calls, not a central
/// difference's three: the laws are continuous and the implicit wheel step only needs the
/// stiffness's size), never negative.
fn scalar_adhesion(m: &ScalarLaw, w: f64, ddv: f64, v: f64, patch: f64) -> (f64, f64) {
    const H: f64 = 1e-4;
    let mu = m.mu(w, ddv, v, patch);
    let h = if w < 0.0 { -H } else { H };
    let slope = (m.mu(w + h, ddv, v, patch) - mu) / h;
    (
        mu,
        if slope.is_finite() {
            slope.max(0.0)
        } else {
            0.0
        },
    )
}

/// The brake coefficients α_i (N m/bar) the simulated vehicle has: the pipeline's, each off by
/// a relative scatter with `brake_scatter` (1σ = `brake.alpha_scatter`), drawn from
/// `brake.scatter_seed` — the vehicle's, not the run's noise seed (which the log carries): the
/// same vehicle in every run of a campaign, and the sensors' noise the same with and without.
pub fn brake_coefficients(sc: &Scene) -> [f64; AXLES] {
    let mut alpha = sc.vehicle.brake_torque_nm_per_bar;
    if sc.effects.has(Effect::BrakeScatter) {
        let mut rng = crate::rng::Rng::new(sc.brake.scatter_seed ^ 0x6272_616b_655f_7363);
        for a in alpha.iter_mut() {
            *a *= 1.0 + sc.brake.alpha_scatter * rng.normal();
        }
    }
    alpha
}

/// The speed v0 of the `pad_friction` law, m/s: `brake.pad_friction_v0_kmh`, or the run's
/// initial speed when that is 0.
pub fn pad_friction_v0_mps(sc: &Scene) -> f64 {
    let kmh = if sc.brake.pad_friction_v0_kmh > 0.0 {
        sc.brake.pad_friction_v0_kmh
    } else {
        sc.run.initial_speed_kmh
    };
    kmh / 3.6
}

impl<'a> Setup<'a> {
    /// The run's constants; the effects that act once (temperature, cleaning, gradient) are
    /// applied and counted here. (`Setup::new`, `initial_state` and `Logger::new` are inlined
    /// into the step loop so that the setup, the state and the counters stay local to it: a
    /// local whose address escapes into a call is kept in memory, which cost the full scene
    /// ~10 % more instructions.)
    #[inline(always)]
    pub(super) fn new(sc: &'a Scene, counters: &mut EffectCounters) -> Result<Setup<'a>, SimError> {
        let fx = sc.effects;
        let veh = &sc.vehicle;
        let ad = &sc.adhesion;
        let mass = veh.body_mass_kg + 2.0 * veh.bogie_mass_kg;
        let h = sc.run.step_s;
        // Contact patch of one wheel at the static load (Hertz, seed 001; Kalker c11).
        let contact_err = |source| SimError::Contact {
            scene: sc.name.clone(),
            source,
        };
        let (patch, q0) = crate::vehicle::wheel_patch(veh, &sc.contact).map_err(contact_err)?;
        let k0 = PI * patch.g_pa * patch.a_m * patch.b_m * patch.c11 / 4.0;
        if fx.has(Effect::Temperature) {
            // Polach: k(T) here; a model or loss_recovery: applied when the law is loaded.
            counters.hit(Effect::Temperature);
        }
        let polach_law = matches!(ad.law, super::scene::AdhesionLaw::Polach);
        let (k_a, k_s) = if fx.has(Effect::Temperature) && polach_law {
            ad.temperature_law
                .eval(sc.run.ambient_temperature_c)
                .map_err(contact_err)?
        } else {
            (ad.polach.k_a, ad.polach.k_s)
        };
        let mut mu_axle = [ad.polach.mu0; AXLES];
        if fx.has(Effect::Cleaning) {
            for (i, m) in mu_axle.iter_mut().enumerate() {
                counters.hit(Effect::Cleaning);
                *m *= 1.0 + ad.cleaning_per_axle * i as f64;
            }
        }
        let grade_force = if fx.has(Effect::Gradient) {
            counters.hit(Effect::Gradient);
            mass * G_MPS2 * (sc.run.gradient_permille / 1000.0).atan().sin()
        } else {
            0.0
        };
        if fx.has(Effect::BrakeScatter) {
            counters.add(Effect::BrakeScatter, AXLES as u64);
        }
        let alpha = brake_coefficients(sc);
        let pad = fx.has(Effect::PadFriction).then(|| {
            (
                sc.brake.pad_friction_rise,
                1.0 / pad_friction_v0_mps(sc).max(1e-3),
                sc.brake.pad_friction_exponent,
            )
        });
        // The simulated vehicle's load transfer: with `pivot_force`, the body's inertia force
        // on each bogie at the pivot height too ((m_c/2) h_b / l2 per unit deceleration);
        // without, eq. 12–13 alone — whatever the pipeline's vehicle says.
        let mut physical = veh.clone();
        physical.pivot_force_load_transfer = fx.has(Effect::PivotForce);
        if fx.has(Effect::PivotForce) {
            counters.add(Effect::PivotForce, AXLES as u64);
        }
        let (load, per_decel) = crate::vehicle::axle_load_coefficients(&physical);
        // Without load transfer the loads stay static: N = N0 + d · 0, the same operations.
        let per_decel = if fx.has(Effect::LoadTransfer) {
            per_decel
        } else {
            [0.0; AXLES]
        };
        Ok(Setup {
            sc,
            fx,
            r: veh.wheel_radius_m,
            h,
            inv_h: 1.0 / h,
            h_per_mass: h / mass,
            consts: StepConsts {
                r: veh.wheel_radius_m,
                j: veh.axle_inertia_kgm2,
                h,
                k_a,
                k_s,
            },
            k0,
            q0,
            mu_axle,
            load,
            per_decel,
            falling: fx
                .has(Effect::FallingFriction)
                .then_some((ad.polach.a_ratio, ad.polach.b_s_per_m)),
            speed_slope: ad.speed_coefficient / ad.reference_speed_mps,
            speed_at_zero: 1.0 + ad.speed_coefficient,
            grade_force,
            k_cyl: 1.0 - (-h / sc.brake.cylinder_time_constant_s).exp(),
            k_hyst: 1.0 - (-h / ad.hysteresis_time_constant_s).exp(),
            inv_ddv0: 1.0 / ad.hysteresis_ddv_mps2,
            alpha,
            pad,
            fluctuation: if fx.has(Effect::LoadFluctuation) {
                Some(LoadFluctuation::new(sc, h).map_err(|what| SimError::Scene {
                    scene: sc.name.clone(),
                    what,
                    hint:
                        "lower run.load_fluctuation_band_hz's top, or the simulator's step".into(),
                })?)
            } else {
                None
            },
            thermal: if fx.has(Effect::Thermal) {
                Some(Thermal::new(sc).map_err(contact_err)?)
            } else {
                None
            },
        })
    }

    /// The state at the start: rolling at the initial speed, brakes released, the contact
    /// coefficients of the first step prepared.
    #[inline(always)]
    pub(super) fn initial_state<V: Select>(
        &self,
        isa: V::Isa,
        counters: &mut EffectCounters,
    ) -> SimState {
        let v = self.sc.run.initial_speed_mps;
        let hyst = if self.fx.has(Effect::Hysteresis) {
            hysteresis_target(self.sc.adhesion.hysteresis_depth, 0.0, 1.0)
        } else {
            1.0
        };
        let mut st = SimState {
            v,
            decel: 0.0,
            ax: AxleArrays {
                omega: [v / self.r; AXLES],
                hyst: [hyst; AXLES],
                ..Default::default()
            },
            normal: [0.0; AXLES],
            normal_next: [0.0; AXLES],
            half_inv_k: [0.5 / self.k0; AXLES],
            patch_ratio: [1.0; AXLES],
            theta: [0.0; AXLES],
            p: [0.0; AXLES],
            slip: [0.0; AXLES],
            ddv: [0.0; AXLES],
            ddv_lag: [0.0; AXLES],
            omega_dot: [0.0; AXLES],
            wsp: [Wsp::default(); AXLES],
            cursor: [0; AXLES],
            thermal_sqrt_2a: [self.thermal.as_ref().map_or(0.0, |th| (2.0 * th.a0).sqrt()); AXLES],
            thermal_p_max: [self.thermal.as_ref().map_or(0.0, |th| th.p0); AXLES],
            thermal_pressure: [1.0; AXLES],
            tread_c: [self.sc.run.ambient_temperature_c; AXLES],
            contact_c: [self.sc.run.ambient_temperature_c; AXLES],
            thermal_factor: [1.0; AXLES],
            thermal_power: [0.0; AXLES],
            thermal_steps: 0,
            load_factor: [1.0; AXLES],
            fluct_state: self.fluctuation.as_ref().map(|f| [f.sections(); AXLES]),
            // Seeded from the run's noise seed by the step loop.
            fluct_rng: crate::rng::Rng::new(0),
        };
        let speed = self.speed_factor(v);
        self.prepare::<V>(isa, speed, &mut st, counters);
        st.normal = st.normal_next;
        st
    }

    /// Falling friction's speed factor s(v) (1 without the effect).
    #[inline(always)]
    fn speed_factor(&self, v: f64) -> f64 {
        if self.falling.is_some() {
            self.speed_slope.mul_add(-v, self.speed_at_zero).max(0.2)
        } else {
            1.0
        }
    }

    /// Falling friction's speed factor for this step, counted per axle.
    #[inline(always)]
    pub(super) fn speed_factor_counted(&self, v: f64, counters: &mut EffectCounters) -> f64 {
        if self.falling.is_some() {
            counters.add(Effect::FallingFriction, AXLES as u64);
        }
        self.speed_factor(v)
    }

    /// The vehicle speed after the step's resistances alone (gradient, running resistance).
    #[inline(always)]
    pub(super) fn resisted_speed(&self, v: f64, counters: &mut EffectCounters) -> f64 {
        let mut resist = self.grade_force;
        if self.fx.has(Effect::RunningResistance) {
            counters.hit(Effect::RunningResistance);
            let d = &self.sc.resistance;
            resist += d.davis_a_n + d.davis_b_n_per_mps * v + d.davis_c_n_per_mps2 * v * v;
        }
        (-resist).mul_add(self.h_per_mass, v)
    }

    /// The brakes at time `t`: demand, wheel-slide protection (per axle, before the contact:
    /// it reads the slip and the wheel's deceleration, not the force), cylinders; sets the
    /// slip at the step's start and the brake torques.
    #[inline(always)]
    pub(super) fn brakes(&self, t: f64, st: &mut SimState, counters: &mut EffectCounters) {
        let sc = self.sc;
        let wsp = self.fx.has(Effect::Wsp);
        if wsp {
            counters.add(Effect::Wsp, AXLES as u64);
        }
        let (r, h, k_cyl, v, decel) = (self.r, self.h, self.k_cyl, st.v, st.decel);
        let (demand_bar, wsp_keys) = (&sc.brake.demand_bar, &sc.wsp);
        // Pad friction: one factor for the four axles at this speed.
        let pad = match self.pad {
            Some((rise, inv_v0, n)) => {
                counters.add(Effect::PadFriction, AXLES as u64);
                let x = (1.0 - v * inv_v0).max(0.0);
                // The linear law as it was (the same bits), other shapes by their power.
                1.0 + rise * if n == 1.0 { x } else { x.powf(n) }
            }
            None => 1.0,
        };
        for (a, profile) in demand_bar.iter().enumerate() {
            let demand = demand_at(profile, t, &mut st.cursor[a]);
            let w = (-r).mul_add(st.ax.omega[a], v);
            st.slip[a] = w;
            let p = st.p[a];
            let cmd = if wsp {
                let reading = AxleReading {
                    v_mps: v,
                    slip_mps: w,
                    slip_rate_mps2: st.ddv[a],
                    decel_excess_mps2: -r * st.omega_dot[a] - decel,
                    p_bar: p,
                };
                st.wsp[a].command(wsp_keys, h, &reading, demand)
            } else {
                demand
            };
            let p = p + (cmd - p) * k_cyl;
            st.p[a] = p;
            // Without pad friction `pad` is 1 and α × 1 is α: the same bits as before it.
            st.ax.brake[a] = (self.alpha[a] * pad) * p;
        }
    }

    /// Contact and wheels of the four axles (Polach on `V` lanes, or a scalar law — a learned
    /// model, a foreign law — one axle at a time); returns ΣT* (N).
    #[inline(always)]
    pub(super) fn contact_and_wheels<V: Select>(
        &self,
        isa: V::Isa,
        model: Option<&ScalarLaw>,
        st: &mut SimState,
    ) -> f64 {
        st.normal = st.normal_next;
        let Some(m) = model else {
            return polach_axles::<V>(isa, &self.consts, st.v, &mut st.ax);
        };
        for a in 0..AXLES {
            // The law's slip-rate input is lagged like the hysteresis branch: fed instantly
            // it closes the same force → slip-rate → force loop.
            st.ddv_lag[a] += (st.ddv[a] - st.ddv_lag[a]) * self.k_hyst;
            let (mu, slope) =
                scalar_adhesion(m, st.slip[a], st.ddv_lag[a], st.v, st.patch_ratio[a]);
            let (mu, slope) = if self.thermal.is_some() {
                (mu * st.thermal_factor[a], slope * st.thermal_factor[a])
            } else {
                (mu, slope)
            };
            let ax = &mut st.ax;
            (ax.omega[a], ax.locked[a], ax.t_star[a]) = wheel_update::<f64>(
                &self.consts,
                ax.omega[a],
                ax.locked[a],
                ax.brake[a],
                st.normal[a],
                mu,
                slope,
                1.0,
            );
        }
        let t = &st.ax.t_star;
        (t[0] + t[2]) + (t[1] + t[3])
    }

    /// The hysteresis branch factor for the next step (see [`hysteresis_target`]), lagged by
    /// `k_hyst`, from this step's starting slip rate: off the step's critical path.
    #[inline(always)]
    pub(super) fn hysteresis<V: Select>(
        &self,
        isa: V::Isa,
        st: &mut SimState,
        counters: &mut EffectCounters,
    ) {
        if !self.fx.has(Effect::Hysteresis) {
            return;
        }
        counters.add(Effect::Hysteresis, AXLES as u64);
        let depth = self.sc.adhesion.hysteresis_depth;
        let mut i = 0;
        while i < AXLES {
            let target =
                hysteresis_target(depth, V::load_scalars(isa, &st.ddv[i..]), self.inv_ddv0);
            let old = V::load(isa, &st.ax.hyst[i..]);
            target
                .sub(old)
                .fma(V::splat(isa, self.k_hyst), old)
                .store(&mut st.ax.hyst[i..]);
            i += V::N;
        }
    }

    /// The contact law's coefficients for the next axle step, from the state at this step's
    /// start (deceleration, slip) and the speed factor `speed` (1; 1 without falling friction):
    /// N = N0 + d ∂N/∂d under load transfer (seed 002 eq. 12–13,
    /// [`crate::vehicle::axle_load_coefficients`]; ∂N/∂d = 0 without it), μ = μ_axle s(v)
    /// ((1 − A) e^(−B|Δv|) + A), and from them `ax.d_per_v` = (N/2) μ/K and `ax.pn` = (2/π) μ N;
    /// N goes to `normal_next`.
    #[inline(always)]
    pub(super) fn prepare<V: Select>(
        &self,
        isa: V::Isa,
        speed: f64,
        st: &mut SimState,
        counters: &mut EffectCounters,
    ) {
        if self.fx.has(Effect::LoadTransfer) {
            counters.add(Effect::LoadTransfer, AXLES as u64);
        }
        let mut i = 0;
        while i < AXLES {
            // N0 + d ∂N/∂d, with ∂N/∂d = 0 without load transfer (see `Setup::new`).
            let n = V::splat(isa, st.decel).fma(
                V::load(isa, &self.per_decel[i..]),
                V::load(isa, &self.load[i..]),
            );
            let mut mu = V::load(isa, &self.mu_axle[i..]).mul(V::splat(isa, speed));
            if let Some((a, b)) = self.falling {
                let e = exp_lanes(
                    V::load_scalars(isa, &st.slip[i..])
                        .abs()
                        .mul(V::splat(isa, -b)),
                );
                mu = mu.mul(e.fma(V::splat(isa, 1.0 - a), V::splat(isa, a)));
            }
            if self.thermal.is_some() {
                mu = mu.mul(V::load(isa, &st.thermal_factor[i..]));
            }
            // With `load_fluctuation`, × (1 + ε); without, N as it is (the same bits).
            let n = if self.fluctuation.is_some() {
                n.mul(V::load(isa, &st.load_factor[i..]))
            } else {
                n
            };
            n.store(&mut st.normal_next[i..]);
            n.mul(V::load(isa, &st.half_inv_k[i..]))
                .mul(mu)
                .store(&mut st.ax.d_per_v[i..]);
            V::splat(isa, std::f64::consts::FRAC_2_PI)
                .mul(mu)
                .mul(n)
                .store(&mut st.ax.pn[i..]);
            i += V::N;
        }
    }

    /// The `load_fluctuation` effect's stage: each axle's load factor 1 + ε for the next step
    /// (see [`LoadFluctuation`]).
    #[inline(always)]
    pub(super) fn fluctuate(&self, st: &mut SimState, counters: &mut EffectCounters) {
        let (Some(f), Some(sections)) = (&self.fluctuation, &mut st.fluct_state) else {
            return;
        };
        counters.add(Effect::LoadFluctuation, AXLES as u64);
        for (factor, axle) in st.load_factor.iter_mut().zip(sections.iter_mut()) {
            let w = st.fluct_rng.normal();
            *factor = 1.0 + f.gain * LoadFluctuation::filter(axle, w);
        }
    }

    /// The `thermal` effect's stage (see [`Thermal`]): every step the slip power |T Δv| is
    /// summed; every k-th step (`adhesion.thermal_update_ms`) the temperatures are brought up
    /// to date from the mean power and the friction factor the next step's contact
    /// coefficients use is renewed.
    #[inline(always)]
    pub(super) fn thermal<V: Select>(
        &self,
        isa: V::Isa,
        st: &mut SimState,
        counters: &mut EffectCounters,
    ) {
        let Some(th) = &self.thermal else {
            return;
        };
        counters.add(Effect::Thermal, AXLES as u64);
        let mut i = 0;
        // The four axles side by side (the same operations on every path: bit-identical).
        while i < AXLES {
            let w = V::load_scalars(isa, &st.slip[i..]).abs();
            let t = V::load(isa, &st.ax.t_star[i..]).abs();
            t.fma(w, V::load(isa, &st.thermal_power[i..]))
                .store(&mut st.thermal_power[i..]);
            i += V::N;
        }
        st.thermal_steps += 1;
        if st.thermal_steps < th.window {
            return;
        }
        st.thermal_steps = 0;
        let splat = |x: f64| V::splat(isa, x);
        let gain = splat(th.flash_gain * th.partition / st.v.max(0.5).sqrt());
        let mut i = 0;
        while i < AXLES {
            // Mean slip power over the window, P̄ = Σ|T Δv| / k (W).
            let power = V::load(isa, &st.thermal_power[i..]).mul(splat(th.inv_window));
            splat(0.0).store(&mut st.thermal_power[i..]);
            let n = V::load(isa, &st.normal[i..]);
            let tread = V::load(isa, &st.tread_c[i..]);
            // C dθ_w/dt = δ P̄ − h_c (θ_w − θ_amb), one Euler step of k h.
            let heat = splat(th.partition)
                .mul(power)
                .sub(splat(th.cooling).mul(tread.sub(splat(th.ambient_c))));
            let tread = heat.fma(splat(th.h_per_capacity), tread);
            tread.store(&mut st.tread_c[i..]);
            // μ |Δv| = P̄ / N (the loads stay positive; floored at 1 N against a division by 0).
            let mu_w = power.div(n.max(splat(1.0)));
            let theta = gain
                .mul(mu_w)
                .mul(V::load(isa, &st.thermal_p_max[i..]))
                .fma(V::load(isa, &st.thermal_sqrt_2a[i..]), tread);
            theta.store(&mut st.contact_c[i..]);
            // Below θ_ref the friction is unchanged (e^0 = 1, exactly: `exp_lanes(±0) = 1`).
            // While no lane is above it — braking without a slide — the exponential is
            // skipped with the same bits (the lanes read back from the store).
            let hot = if st.contact_c[i..i + V::N]
                .iter()
                .any(|t| *t > th.reference_c)
            {
                let excess = theta.sub(splat(th.reference_c)).max(splat(0.0));
                exp_lanes(excess.mul(splat(-th.inv_scale)))
            } else {
                splat(1.0)
            };
            hot.fma(splat(1.0 - th.residual), splat(th.residual))
                .mul(V::load(isa, &st.thermal_pressure[i..]))
                .store(&mut st.thermal_factor[i..]);
            i += V::N;
        }
    }

    /// Refreshes the patch constant for the wheel loads (a b ∝ Q^(2/3)) under load transfer
    /// (at the output rate: the loads change slowly). The four cube roots on `V`'s lanes
    /// ([`crate::simd::cbrt4`], correctly rounded: the bits of `f64::cbrt`).
    #[inline(always)]
    pub(super) fn refresh_patch<V: Select>(
        &self,
        isa: V::Isa,
        st: &mut SimState,
        counters: &mut EffectCounters,
    ) {
        if !self.fx.has(Effect::LoadTransfer) {
            return;
        }
        let ratios = crate::simd::cbrt4::<V>(isa, st.normal.map(|n| n * 0.5 / self.q0));
        for (a, ratio) in ratios.into_iter().enumerate() {
            counters.hit(Effect::LoadTransfer);
            st.half_inv_k[a] = 0.5 / (self.k0 * ratio * ratio);
            st.patch_ratio[a] = ratio.max(1e-2);
            // The thermal effect's patch follows the load too (a, p_max ∝ Q^(1/3)).
            if let Some(th) = &self.thermal {
                let ratio = ratio.max(1e-2);
                st.thermal_sqrt_2a[a] = (2.0 * th.a0 * ratio).sqrt();
                st.thermal_p_max[a] = th.p0 * ratio;
                st.thermal_pressure[a] = ratio.powf(-th.gamma);
            }
        }
    }

    /// The vehicle and the wheels' derived quantities after a step with ΣT* = `total_t` (N)
    /// from the speed `v_resisted` the resistances alone leave; `omega` the wheel speeds at
    /// the step's start.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // four arrays indexed by axle
    pub(super) fn advance(
        &self,
        st: &mut SimState,
        omega: &[f64; AXLES],
        total_t: f64,
        v_resisted: f64,
    ) {
        let v = st.v;
        let v_new = total_t.mul_add(-self.h_per_mass, v_resisted).max(0.0);
        st.decel = (v - v_new) * self.inv_h;
        for a in 0..AXLES {
            st.omega_dot[a] = (st.ax.omega[a] - omega[a]) * self.inv_h;
            st.theta[a] += st.ax.omega[a] * self.h;
            // Slip rates use the vehicle's change too.
            let w_new = (-self.r).mul_add(st.ax.omega[a], v);
            st.ddv[a] = (w_new - st.slip[a]) * self.inv_h - st.decel;
        }
        st.v = v_new;
    }
}
