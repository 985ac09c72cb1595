//! Scene files (`pipelines/scenes/*.toml`): raw serde types, checked into a [`Scene`] of
//! section structs, one per TOML section (run, vehicle, brake, adhesion, contact, wsp, sensors,
//! resistance), each with its key table and check side by side.
//!
//! Every key is documented in docs/simulator.md ("Scene file", rendered from the key tables; a test
//! keeps them equal); a rejected value is reported as `file: key = value: allowed range
//! (default)`, like the pipeline file.

use std::fmt;
use std::path::Path;

use serde::Deserialize;

use crate::config::rule::{closed, open_lo, Checker, Default, Key, Range};
use crate::config::{self, ConfigError, ContactConfig, Pipeline, Vehicle};
use crate::contact::polach::{PolachParams, TemperatureLaw};

/// An effect a scene can ask for. Each is its own stage of the step loop and costs nothing
/// when not listed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Effect {
    /// Normal loads from seed 002 eq. 12–13; without it the loads are static.
    LoadTransfer,
    /// Wheel-slide protection: dump / hold / re-apply per axle.
    Wsp,
    /// Lower adhesion while the slip is recovering (dΔv/dt < 0) than while it grows.
    Hysteresis,
    /// Friction falling with slip velocity (Polach A, B) and with vehicle speed.
    FallingFriction,
    /// k_A(T), k_S(T) at the scene's ambient temperature (seed 004 eq. 3).
    Temperature,
    /// Later axles see cleaner rail.
    Cleaning,
    /// Davis running resistance a + b v + c v².
    RunningResistance,
    /// Track gradient.
    Gradient,
    /// Gaussian noise on the radar speed.
    RadarNoise,
    /// Occasional spikes on the radar speed.
    RadarSpikes,
    /// Tachometer pulse counting over a window.
    TachoQuantization,
    /// Gaussian noise on the cylinder pressures.
    PressureNoise,
    /// Contact temperature per axle from the slip power (tread heating + flash temperature),
    /// friction lowered with it by f(σ, θ) (seed 000 in spirit; [`ThermalParams`]).
    Thermal,
}

impl Effect {
    pub const ALL: [Effect; 13] = [
        Effect::LoadTransfer,
        Effect::Wsp,
        Effect::Hysteresis,
        Effect::FallingFriction,
        Effect::Temperature,
        Effect::Cleaning,
        Effect::RunningResistance,
        Effect::Gradient,
        Effect::RadarNoise,
        Effect::RadarSpikes,
        Effect::TachoQuantization,
        Effect::PressureNoise,
        Effect::Thermal,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Effect::LoadTransfer => "load_transfer",
            Effect::Wsp => "wsp",
            Effect::Hysteresis => "hysteresis",
            Effect::FallingFriction => "falling_friction",
            Effect::Temperature => "temperature",
            Effect::Cleaning => "cleaning",
            Effect::RunningResistance => "running_resistance",
            Effect::Gradient => "gradient",
            Effect::RadarNoise => "radar_noise",
            Effect::RadarSpikes => "radar_spikes",
            Effect::TachoQuantization => "tacho_quantization",
            Effect::PressureNoise => "pressure_noise",
            Effect::Thermal => "thermal",
        }
    }

    /// Position in [`Effect::ALL`] (the declaration order; tested).
    #[inline(always)]
    pub const fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The set of effects a scene lists.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Effects(u32);

impl Effects {
    pub fn all() -> Self {
        Effects(Effect::ALL.iter().fold(0, |m, e| m | 1 << e.index()))
    }
    pub fn none() -> Self {
        Effects(0)
    }
    pub fn with(self, e: Effect) -> Self {
        Effects(self.0 | 1 << e.index())
    }
    #[inline]
    pub fn has(self, e: Effect) -> bool {
        self.0 & (1 << e.index()) != 0
    }
    pub fn names(self) -> Vec<&'static str> {
        Effect::ALL
            .iter()
            .filter(|e| self.has(**e))
            .map(|e| e.name())
            .collect()
    }
}

/// Raw serde types of a scene file.
pub mod raw {
    use super::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Scene {
        pub name: Option<String>,
        pub seed: Option<u64>,
        #[serde(default)]
        pub effects: Vec<String>,
        /// `pipeline = "path"` (relative to the scene file, or "default"), or the pipeline's
        /// `[vehicle]` keys inline.
        pub vehicle: Option<toml::Table>,
        #[serde(default)]
        pub run: Run,
        #[serde(default)]
        pub brake: Brake,
        #[serde(default)]
        pub adhesion: Adhesion,
        #[serde(default)]
        pub contact: crate::config::raw::Contact,
        #[serde(default)]
        pub wsp: Wsp,
        #[serde(default)]
        pub sensors: Sensors,
        #[serde(default)]
        pub resistance: Resistance,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Run {
        pub initial_speed_kmh: Option<f64>,
        pub stop_speed_kmh: Option<f64>,
        pub max_duration_s: Option<f64>,
        pub step_ms: Option<f64>,
        pub output_rate_hz: Option<f64>,
        pub ambient_temperature_c: Option<f64>,
        pub gradient_permille: Option<f64>,
        pub condition: Option<String>,
        pub direction: Option<String>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Brake {
        pub demand_bar: Option<Vec<[f64; 2]>>,
        pub demand_bar_per_axle: Option<Vec<Vec<[f64; 2]>>>,
        pub cylinder_time_constant_s: Option<f64>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Adhesion {
        pub law: Option<String>,
        pub model: Option<String>,
        pub mu0: Option<f64>,
        pub a_ratio: Option<f64>,
        pub b_s_per_m: Option<f64>,
        pub k_a: Option<f64>,
        pub k_s: Option<f64>,
        pub speed_coefficient: Option<f64>,
        pub reference_speed_kmh: Option<f64>,
        pub hysteresis_depth: Option<f64>,
        pub hysteresis_ddv_mps2: Option<f64>,
        pub hysteresis_time_constant_s: Option<f64>,
        pub cleaning_per_axle: Option<f64>,
        pub temperature_k_a: Option<Vec<f64>>,
        pub temperature_k_s: Option<Vec<f64>>,
        pub temperature_range_c: Option<[f64; 2]>,
        pub loss_peak_mu: Option<f64>,
        pub loss_peak_slip_mps: Option<f64>,
        pub loss_residual: Option<f64>,
        pub recovery_peak_mu: Option<f64>,
        pub recovery_peak_slip_mps: Option<f64>,
        pub recovery_residual: Option<f64>,
        pub peak_speed_coefficient: Option<f64>,
        pub peak_temperature_coefficient_per_k: Option<f64>,
        pub table_speeds_kmh: Option<Vec<f64>>,
        pub table_slips_mps: Option<Vec<f64>>,
        pub table_mu: Option<Vec<Vec<f64>>>,
        pub fastsim_grid: Option<f64>,
        pub fastsim_bound: Option<String>,
        pub fastsim_k0: Option<f64>,
        pub fastsim_alpha_inf: Option<f64>,
        pub fastsim_beta: Option<f64>,
        pub thermal_partition: Option<f64>,
        pub thermal_tread_capacity_j_per_k: Option<f64>,
        pub thermal_cooling_w_per_k: Option<f64>,
        pub thermal_reference_c: Option<f64>,
        pub thermal_scale_k: Option<f64>,
        pub thermal_residual: Option<f64>,
        pub thermal_pressure_exponent: Option<f64>,
        pub thermal_update_ms: Option<f64>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Wsp {
        pub dump_slip_mps: Option<f64>,
        pub reapply_slip_mps: Option<f64>,
        pub decel_limit_mps2: Option<f64>,
        pub reaction_delay_ms: Option<f64>,
        pub dump_slip_ratio: Option<f64>,
        pub hold_max_s: Option<f64>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Sensors {
        pub radar_noise_mps: Option<f64>,
        pub radar_spike_rate_hz: Option<f64>,
        pub radar_spike_mps: Option<f64>,
        pub tacho_pulses_per_rev: Option<f64>,
        pub tacho_window_ms: Option<f64>,
        pub pressure_noise_bar: Option<f64>,
        pub radar_rate_hz: Option<f64>,
        pub tacho_rate_hz: Option<f64>,
        pub pressure_rate_hz: Option<f64>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Resistance {
        pub davis_a_n: Option<f64>,
        pub davis_b_n_per_mps: Option<f64>,
        pub davis_c_n_per_mps2: Option<f64>,
    }
}

/// Which adhesion law drives the wheels.
#[derive(Debug, Clone, PartialEq)]
pub enum AdhesionLaw {
    /// Polach's creep force (seed 004 eq. 1–2) on a Hertz + Kalker contact, with the effects
    /// the scene lists (falling friction and speed dependence, hysteresis, k(T), cleaning) —
    /// the truth law of the bundled archive.
    Polach,
    /// A model file (`railgrip train`'s output, docs/model-files.md, kind mlp or polach):
    /// μ(Δv, dΔv/dt, v) from the model's evaluator. The model carries the adhesion effects
    /// itself, so a scene with it may not list falling_friction, hysteresis or cleaning;
    /// `temperature` is allowed for a Polach model with a temperature law and sets k_A(T),
    /// k_S(T) at the scene's ambient temperature. The path is resolved against the scene
    /// file's folder.
    Model(std::path::PathBuf),
    /// Separate loss and recovery curves blended by the lagged slip rate
    /// ([`super::foreign::LossRecovery`]): a law outside the families railgrip fits. Carries its
    /// own speed dependence and branches, so falling_friction, hysteresis and cleaning may not
    /// be listed; `temperature` scales its peaks.
    LossRecovery(super::foreign::LossRecovery),
    /// μ(Δv) tabulated per speed ([`super::foreign::SlipTable`]): a sharp peak and a plateau.
    /// No effect of the Polach law may be listed, nor `temperature`.
    Table(super::foreign::SlipTable),
    /// Kalker's FASTSIM ([`crate::contact::fastsim`]) on the wheel's Hertz patch (at the static
    /// load; with `load_transfer` listed it follows the wheel's load), with Polach's falling
    /// friction μ0[(1 − A)e^(−Bw) + A] (`mu0`, `a_ratio`, `b_s_per_m`) and optionally the modified FASTSIM's stiffness reduction. Carries its own
    /// friction law, so falling_friction, hysteresis, cleaning and temperature may not be listed.
    Fastsim(FastsimLaw),
}

/// `law = "fastsim"`: the grid, the bound and the optional stiffness reduction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FastsimLaw {
    /// Cells per side (nx = ny).
    pub grid: usize,
    pub bound: crate::contact::fastsim::Bound,
    pub reduction: Option<crate::contact::fastsim::Reduction>,
}

/// The `thermal` effect's parameters (every one [assumed]; docs/simulator.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalParams {
    /// Share δ of the slip power that heats the wheel (the rest goes into the rail).
    pub partition: f64,
    /// Heat capacity of an axle's heated tread layer (both wheels), J/K.
    pub tread_capacity_j_per_k: f64,
    /// Heat loss of the tread to the air and the wheel body, W/K.
    pub cooling_w_per_k: f64,
    /// Contact temperature below which friction does not change, °C.
    pub reference_c: f64,
    /// Temperature scale of the friction loss above it, K.
    pub scale_k: f64,
    /// Friction left at very high temperature, as a fraction.
    pub residual: f64,
    /// γ of the pressure factor (σ/σ0)^(−γ).
    pub pressure_exponent: f64,
    /// Interval at which temperatures and the friction factor are brought up to date from the
    /// slip power summed since the last update, ms (a whole number of steps, at least one).
    pub update_ms: f64,
}

impl AdhesionLaw {
    /// The name used in scene files.
    pub fn name(&self) -> &'static str {
        match self {
            AdhesionLaw::Polach => "polach",
            AdhesionLaw::Model(_) => "model",
            AdhesionLaw::LossRecovery(_) => "loss_recovery",
            AdhesionLaw::Table(_) => "table",
            AdhesionLaw::Fastsim(_) => "fastsim",
        }
    }
}

/// A validated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub name: String,
    pub seed: u64,
    pub effects: Effects,
    pub vehicle: Vehicle,
    pub run: RunSection,
    pub brake: BrakeSection,
    pub adhesion: AdhesionSection,
    /// Wheel–rail contact material and profile radii (the pipeline's `[contact]` keys).
    pub contact: ContactConfig,
    pub wsp: WspSection,
    pub sensors: SensorsSection,
    pub resistance: ResistanceSection,
}

const fn text(
    name: &'static str,
    unit: &'static str,
    range: &'static str,
    default: &'static str,
    meaning: &'static str,
) -> Key {
    Key {
        name,
        unit,
        range: Range::Text(range),
        default: Default::Text(default),
        meaning,
    }
}

// ---------------------------------------------------------------------------------- top level

const NAME: Key = text("name", "", "text", "\"scene\"", "run name in the metadata");
const SEED: Key = text(
    "seed",
    "",
    "0..2⁶⁴−1",
    "1",
    "sensor noise (`railgrip simulate --seed` overrides)",
);
const EFFECTS: Key = text(
    "effects",
    "",
    "names from the effects table",
    "[] (none)",
    "the effects the step loop evaluates",
);
const VEHICLE: Key = text(
    "vehicle.pipeline",
    "",
    "a pipeline file (relative to the scene) or `\"default\"`",
    "embedded UIC-Z1",
    "the vehicle; or give the pipeline's `[vehicle]` keys inline instead",
);

/// The keys of the top level and `[vehicle]`, in the order of the documented table.
pub const TOP_KEYS: &[&Key] = &[&NAME, &SEED, &EFFECTS, &VEHICLE];

// ---------------------------------------------------------------------------------- [run]

/// `[run]`: the braking run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSection {
    /// Initial speed as written in the scene, km/h (reported in the run metadata).
    pub initial_speed_kmh: f64,
    /// Initial speed, m/s.
    pub initial_speed_mps: f64,
    /// The run ends when the vehicle is slower than this, m/s.
    pub stop_speed_mps: f64,
    pub max_duration_s: f64,
    /// Integration step, s.
    pub step_s: f64,
    /// Rate of the CSV output and the truth table, Hz.
    pub output_rate_hz: f64,
    pub ambient_temperature_c: f64,
    /// Track gradient, ‰ (positive uphill).
    pub gradient_permille: f64,
    pub condition: String,
    pub direction: String,
}

const INITIAL_SPEED: Key = Key::num(
    "run.initial_speed_kmh",
    "km/h",
    closed(1.0, 400.0),
    120.0,
    "start of the braking",
);
const STOP_SPEED: Key = Key::num(
    "run.stop_speed_kmh",
    "km/h",
    closed(0.5, 400.0),
    3.0,
    "end of the braking, below the initial speed",
);
const MAX_DURATION: Key = Key::num(
    "run.max_duration_s",
    "s",
    closed(0.1, 36_000.0),
    300.0,
    "longest simulated time",
);
const STEP: Key = Key::num(
    "run.step_ms",
    "ms",
    closed(0.01, 1.0),
    0.1,
    "integration step, at most half the output period",
);
const OUTPUT_RATE: Key = Key::num(
    "run.output_rate_hz",
    "Hz",
    closed(10.0, 10_000.0),
    417.0,
    "CSV and truth rate",
);
const AMBIENT: Key = Key::num(
    "run.ambient_temperature_c",
    "°C",
    closed(-60.0, 60.0),
    20.0,
    "for `temperature` and the metadata",
);
const GRADIENT: Key = Key::num(
    "run.gradient_permille",
    "‰",
    closed(-60.0, 60.0),
    0.0,
    "for `gradient` (positive uphill)",
);
const CONDITION: Key = text("run.condition", "", "text", "\"soap\"", "metadata");
const DIRECTION: Key = text("run.direction", "", "text", "\"forward\"", "metadata");

/// The keys of `[run]`, in the order of the documented table.
pub const RUN_KEYS: &[&Key] = &[
    &INITIAL_SPEED,
    &STOP_SPEED,
    &MAX_DURATION,
    &STEP,
    &OUTPUT_RATE,
    &AMBIENT,
    &GRADIENT,
    &CONDITION,
    &DIRECTION,
];

impl RunSection {
    fn check(c: &Checker, r: &raw::Run) -> Result<RunSection, ConfigError> {
        let initial_kmh = c.value(&INITIAL_SPEED, r.initial_speed_kmh)?;
        let stop_kmh = c.value(&STOP_SPEED, r.stop_speed_kmh)?;
        if stop_kmh >= initial_kmh {
            return Err(c.invalid(
                STOP_SPEED.name,
                stop_kmh,
                format!("must be below {} = {initial_kmh}", INITIAL_SPEED.name),
            ));
        }
        let step_ms = c.value(&STEP, r.step_ms)?;
        let output_rate_hz = c.value(&OUTPUT_RATE, r.output_rate_hz)?;
        if step_ms * 1e-3 > 0.5 / output_rate_hz {
            return Err(c.invalid(STEP.name, step_ms, "must be at most half the output period"));
        }
        Ok(RunSection {
            initial_speed_kmh: initial_kmh,
            initial_speed_mps: initial_kmh / 3.6,
            stop_speed_mps: stop_kmh / 3.6,
            max_duration_s: c.value(&MAX_DURATION, r.max_duration_s)?,
            step_s: step_ms * 1e-3,
            output_rate_hz,
            ambient_temperature_c: c.value(&AMBIENT, r.ambient_temperature_c)?,
            gradient_permille: c.value(&GRADIENT, r.gradient_permille)?,
            condition: r.condition.clone().unwrap_or_else(|| "soap".into()),
            direction: r.direction.clone().unwrap_or_else(|| "forward".into()),
        })
    }
}

// ---------------------------------------------------------------------------------- [brake]

/// `[brake]`: the demanded cylinder pressures and the cylinders.
#[derive(Debug, Clone, PartialEq)]
pub struct BrakeSection {
    /// Brake-cylinder pressure demand per axle (t s, p bar), piecewise linear, held after the
    /// last point.
    pub demand_bar: [Vec<(f64, f64)>; 4],
    pub cylinder_time_constant_s: f64,
}

const DEMAND: Key = text(
    "brake.demand_bar",
    "[s, bar]",
    "[t, p] points, t increasing, 0 ≤ p ≤ 20",
    "[[0, 0], [1, 0], [2.5, 3.8]]",
    "cylinder-pressure demand of every axle, piecewise linear, held after the last point",
);
const DEMAND_PER_AXLE: Key = text(
    "brake.demand_bar_per_axle",
    "4 × [s, bar]",
    "four such profiles",
    "–",
    "the demand per axle instead",
);
const CYLINDER: Key = Key::num(
    "brake.cylinder_time_constant_s",
    "s",
    closed(0.005, 5.0),
    0.15,
    "first-order cylinder",
);

/// The keys of `[brake]`, in the order of the documented table.
pub const BRAKE_KEYS: &[&Key] = &[&DEMAND, &DEMAND_PER_AXLE, &CYLINDER];

impl BrakeSection {
    fn check(c: &Checker, b: &raw::Brake) -> Result<BrakeSection, ConfigError> {
        let profile = |key: &str, d: &Vec<[f64; 2]>| -> Result<Vec<(f64, f64)>, ConfigError> {
            if d.is_empty()
                || d.windows(2).any(|w| w[1][0] <= w[0][0])
                || d.iter()
                    .any(|p| !p[0].is_finite() || !(0.0..=20.0).contains(&p[1]))
            {
                return Err(c.invalid(
                    key,
                    format!("{d:?}"),
                    "must list [t_s, p_bar] points with strictly increasing t and 0 <= p <= 20 bar",
                ));
            }
            Ok(d.iter().map(|p| (p[0], p[1])).collect())
        };
        let demand_bar: [Vec<(f64, f64)>; 4] = match (&b.demand_bar, &b.demand_bar_per_axle) {
            (Some(_), Some(_)) => {
                return Err(c.invalid(
                    DEMAND_PER_AXLE.name,
                    format!("given with {}", DEMAND.name),
                    "give one of the two",
                ))
            }
            (_, Some(per)) => {
                if per.len() != 4 {
                    return Err(c.invalid(
                        DEMAND_PER_AXLE.name,
                        format!("{} profiles", per.len()),
                        "must list exactly 4 profiles, axles 1..4",
                    ));
                }
                let mut out: [Vec<(f64, f64)>; 4] = std::array::from_fn(|_| Vec::new());
                for (i, d) in per.iter().enumerate() {
                    out[i] = profile(&format!("{}[{i}]", DEMAND_PER_AXLE.name), d)?;
                }
                out
            }
            (Some(d), None) => {
                let one = profile(DEMAND.name, d)?;
                [one.clone(), one.clone(), one.clone(), one]
            }
            (None, None) => std::array::from_fn(|_| vec![(0.0, 0.0), (1.0, 0.0), (2.5, 3.8)]),
        };
        Ok(BrakeSection {
            demand_bar,
            cylinder_time_constant_s: c.value(&CYLINDER, b.cylinder_time_constant_s)?,
        })
    }
}

// ---------------------------------------------------------------------------------- [adhesion]

/// `[adhesion]`: the truth law and its effects' parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct AdhesionSection {
    pub law: AdhesionLaw,
    pub polach: PolachParams,
    /// μ0 scales by 1 + c (v_ref − v)/v_ref with the falling_friction effect.
    pub speed_coefficient: f64,
    pub reference_speed_mps: f64,
    pub hysteresis_depth: f64,
    pub hysteresis_ddv_mps2: f64,
    /// Lag of the hysteresis branch factor behind the slip rate, s.
    pub hysteresis_time_constant_s: f64,
    pub cleaning_per_axle: f64,
    pub temperature_law: TemperatureLaw,
    pub thermal: ThermalParams,
}

const LAW: Key = Key {
    name: "adhesion.law",
    unit: "",
    range: Range::Choice(&["polach", "model", "loss_recovery", "table", "fastsim"]),
    default: Default::Text("\"polach\""),
    meaning: "Polach's law with the listed effects; `\"model\"` with `model = \"file.json\"`: a model file from `railgrip train` (path relative to the scene) drives the wheels, its slip-rate input lagged by `hysteresis_time_constant_s`; `\"loss_recovery\"` and `\"table\"`: laws outside the families railgrip fits (truth for testing identification; docs/simulator.md#foreign-laws); `\"fastsim\"`: Kalker's FASTSIM with Polach's falling friction (mu0, a_ratio, b_s_per_m). With any but polach, falling_friction, hysteresis and cleaning may not be listed; `temperature` only for a Polach model with a temperature law, a network with the input ambient_temperature_c (it takes run.ambient_temperature_c; without the effect, its reference temperature) or loss_recovery",
};
const MODEL: Key = text(
    "adhesion.model",
    "",
    "a model file",
    "–",
    "with `law = \"model\"`",
);
const MU0: Key = Key::num(
    "adhesion.mu0",
    "",
    closed(0.005, 1.5),
    0.085,
    "Polach μ0 of soap-contaminated rail [assumed, tuned to seed 002 Fig. 7–8]",
);
const A_RATIO: Key = Key::num(
    "adhesion.a_ratio",
    "",
    closed(0.01, 1.0),
    0.4,
    "Polach A = μ∞/μ0 [assumed]",
);
const B: Key = Key::num(
    "adhesion.b_s_per_m",
    "s/m",
    closed(0.0, 10.0),
    0.3,
    "Polach B, friction falling with slip velocity [assumed]",
);
const K_A: Key = Key::num(
    "adhesion.k_a",
    "",
    closed(1e-4, 1.0),
    0.1,
    "Polach k_A at +20 °C [assumed]",
);
const K_S: Key = Key::num(
    "adhesion.k_s",
    "",
    closed(1e-5, 1.0),
    0.05,
    "Polach k_S at +20 °C, at most k_A [assumed]",
);
const SPEED_COEFFICIENT: Key = Key::num(
    "adhesion.speed_coefficient",
    "",
    closed(-2.0, 2.0),
    0.25,
    "`falling_friction`: μ0 × (1 + c (v_ref − v)/v_ref)",
);
const REFERENCE_SPEED: Key = Key::num(
    "adhesion.reference_speed_kmh",
    "km/h",
    closed(1.0, 400.0),
    120.0,
    "v_ref of the speed dependence",
);
const HYSTERESIS_DEPTH: Key = Key::num(
    "adhesion.hysteresis_depth",
    "",
    closed(0.0, 0.9),
    0.3,
    "`hysteresis`: recovery branch lower by this fraction",
);
const HYSTERESIS_DDV: Key = Key::num(
    "adhesion.hysteresis_ddv_mps2",
    "m/s²",
    closed(1e-3, 100.0),
    0.5,
    "slip rate scale of the branch blend",
);
const HYSTERESIS_TAU: Key = Key::num(
    "adhesion.hysteresis_time_constant_s",
    "s",
    closed(1e-3, 10.0),
    0.02,
    "lag of the branch factor (and of a model's slip-rate input)",
);
const CLEANING: Key = Key::num(
    "adhesion.cleaning_per_axle",
    "",
    closed(0.0, 2.0),
    0.05,
    "`cleaning`: axle i's μ × (1 + this·(i − 1))",
);
const TEMPERATURE_K_A: Key = text(
    "adhesion.temperature_k_a",
    "",
    "coefficients, ascending powers of T in °C",
    "k20·(1 + 0.015u − 1.875e-4u²), u = 20 − T",
    "`temperature`: k_A(T) [assumed shape of seed 004's trend]",
);
const TEMPERATURE_K_S: Key = text(
    "adhesion.temperature_k_s",
    "",
    "coefficients, ascending powers of T in °C",
    "the same shape from k_s",
    "`temperature`: k_S(T) [assumed]",
);
const TEMPERATURE_RANGE: Key = text(
    "adhesion.temperature_range_c",
    "°C",
    "[lo, hi]",
    "[−40, 20]",
    "where the k(T) polynomials hold",
);

const LOSS_PEAK: Key = Key::num(
    "adhesion.loss_peak_mu",
    "",
    closed(0.005, 1.5),
    0.1,
    "`loss_recovery`: peak μ of the loss branch (growing slip) at v_ref [assumed]",
);
const LOSS_SLIP: Key = Key::num(
    "adhesion.loss_peak_slip_mps",
    "m/s",
    closed(0.01, 20.0),
    0.8,
    "… the slip at that peak [assumed]",
);
const LOSS_RESIDUAL: Key = Key::num(
    "adhesion.loss_residual",
    "",
    closed(0.05, 0.95),
    0.55,
    "… μ at large slip as a fraction of the peak [assumed]",
);
const RECOVERY_PEAK: Key = Key::num(
    "adhesion.recovery_peak_mu",
    "",
    closed(0.005, 1.5),
    0.065,
    "`loss_recovery`: peak μ of the recovery branch (falling slip) at v_ref [assumed]",
);
const RECOVERY_SLIP: Key = Key::num(
    "adhesion.recovery_peak_slip_mps",
    "m/s",
    closed(0.01, 20.0),
    1.6,
    "… the slip at that peak [assumed]",
);
const RECOVERY_RESIDUAL: Key = Key::num(
    "adhesion.recovery_residual",
    "",
    closed(0.05, 0.95),
    0.8,
    "… μ at large slip as a fraction of the peak [assumed]",
);
const PEAK_SPEED: Key = Key::num(
    "adhesion.peak_speed_coefficient",
    "",
    closed(-0.9, 0.9),
    0.3,
    "`loss_recovery`: peaks × (1 + κ (v_ref − v)/(v_ref + v)) [assumed]",
);
const PEAK_TEMPERATURE: Key = Key::num(
    "adhesion.peak_temperature_coefficient_per_k",
    "1/K",
    closed(-0.02, 0.02),
    0.006,
    "`loss_recovery` with `temperature`: peaks × (1 + τ (20 °C − T)) [assumed]",
);
const TABLE_SPEEDS: Key = text(
    "adhesion.table_speeds_kmh",
    "km/h",
    "strictly increasing speeds",
    "[80, 140, 200]",
    "`table`: the speed nodes (μ held beyond the first and last) [assumed]",
);
const TABLE_SLIPS: Key = text(
    "adhesion.table_slips_mps",
    "m/s",
    "0, then strictly increasing",
    "[0, 0.15, 0.4, 0.6, 0.8, 1.2, 2.5, 20]",
    "`table`: the slip nodes (μ held beyond the last) [assumed]",
);
const TABLE_MU: Key = text(
    "adhesion.table_mu",
    "",
    "one row per speed, one μ in [0, 1.5] per slip node, 0 at zero slip",
    "a peak of 0.105 / 0.090 / 0.074 at 0.6 m/s, a plateau from 2.5 m/s",
    "`table`: μ, linear between nodes [assumed]",
);

const FASTSIM_GRID: Key = Key::num(
    "adhesion.fastsim_grid",
    "cells",
    closed(1.0, 1000.0),
    10.0,
    "`fastsim`: cells per side of the grid (cost grows with its square)",
);
const FASTSIM_BOUND: Key = Key {
    name: "adhesion.fastsim_bound",
    unit: "",
    range: Range::Choice(&["elliptic", "parabolic"]),
    default: Default::Text("\"elliptic\""),
    meaning: "`fastsim`: the traction bound's pressure (Hertz or Kalker's parabolic)",
};
const FASTSIM_K0: Key = text(
    "adhesion.fastsim_k0",
    "",
    "(0, 1]",
    "– (plain FASTSIM)",
    "`fastsim`: the modified FASTSIM's k0 (Spiryagin et al. 2013); with alpha_inf and beta",
);
const FASTSIM_ALPHA_INF: Key = text(
    "adhesion.fastsim_alpha_inf",
    "",
    "(0, 1]",
    "1",
    "… α∞: the stiffness left at large creepage, as a fraction of k0",
);
const FASTSIM_BETA: Key = text(
    "adhesion.fastsim_beta",
    "",
    "≥ 0",
    "0",
    "… β: how fast the stiffness falls with Polach's ε",
);
const THERMAL_PARTITION: Key = Key::num(
    "adhesion.thermal_partition",
    "",
    open_lo(0.0, 1.0),
    0.5,
    "`thermal`: share of the slip power heating the wheel tread and the flash [assumed]",
);
const THERMAL_CAPACITY: Key = Key::num(
    "adhesion.thermal_tread_capacity_j_per_k",
    "J/K",
    closed(100.0, 1e7),
    2.3e4,
    "`thermal`: heat capacity of an axle's heated tread layer (two 1 cm × 0.1 m rims of steel) [assumed]",
);
const THERMAL_COOLING: Key = Key::num(
    "adhesion.thermal_cooling_w_per_k",
    "W/K",
    closed(0.0, 1e5),
    50.0,
    "`thermal`: the tread's heat loss to air and wheel body [assumed]",
);
const THERMAL_REFERENCE: Key = Key::num(
    "adhesion.thermal_reference_c",
    "°C",
    closed(-50.0, 1000.0),
    100.0,
    "`thermal`: contact temperature up to which friction is unchanged [assumed]",
);
const THERMAL_SCALE: Key = Key::num(
    "adhesion.thermal_scale_k",
    "K",
    closed(1.0, 5000.0),
    300.0,
    "`thermal`: friction × [r + (1 − r) e^(−(θ − θ_ref)/scale)] above θ_ref [assumed]",
);
const THERMAL_RESIDUAL: Key = Key::num(
    "adhesion.thermal_residual",
    "",
    closed(0.05, 1.0),
    0.5,
    "`thermal`: r, the friction left at very high contact temperature [assumed]",
);
const THERMAL_PRESSURE: Key = Key::num(
    "adhesion.thermal_pressure_exponent",
    "",
    closed(0.0, 1.0),
    0.1,
    "`thermal`: friction × (p_max/p_max,static)^(−γ) [assumed]",
);
const THERMAL_UPDATE: Key = Key::num(
    "adhesion.thermal_update_ms",
    "ms",
    closed(0.001, 10.0),
    0.5,
    "`thermal`: temperatures and friction factor brought up to date at this interval (rounded to whole steps, at least one) from the slip power summed every step; docs/benchmarks.md gives its cost and error",
);

/// The keys of `[adhesion]`, in the order of the documented table.
pub const ADHESION_KEYS: &[&Key] = &[
    &LAW,
    &MODEL,
    &MU0,
    &A_RATIO,
    &B,
    &K_A,
    &K_S,
    &SPEED_COEFFICIENT,
    &REFERENCE_SPEED,
    &HYSTERESIS_DEPTH,
    &HYSTERESIS_DDV,
    &HYSTERESIS_TAU,
    &CLEANING,
    &TEMPERATURE_K_A,
    &TEMPERATURE_K_S,
    &TEMPERATURE_RANGE,
    &LOSS_PEAK,
    &LOSS_SLIP,
    &LOSS_RESIDUAL,
    &RECOVERY_PEAK,
    &RECOVERY_SLIP,
    &RECOVERY_RESIDUAL,
    &PEAK_SPEED,
    &PEAK_TEMPERATURE,
    &TABLE_SPEEDS,
    &TABLE_SLIPS,
    &TABLE_MU,
    &FASTSIM_GRID,
    &FASTSIM_BOUND,
    &FASTSIM_K0,
    &FASTSIM_ALPHA_INF,
    &FASTSIM_BETA,
    &THERMAL_PARTITION,
    &THERMAL_CAPACITY,
    &THERMAL_COOLING,
    &THERMAL_REFERENCE,
    &THERMAL_SCALE,
    &THERMAL_RESIDUAL,
    &THERMAL_PRESSURE,
    &THERMAL_UPDATE,
];

impl AdhesionSection {
    fn check(
        c: &Checker,
        a: &raw::Adhesion,
        dir: Option<&Path>,
    ) -> Result<AdhesionSection, ConfigError> {
        let law = match (a.law.as_deref(), &a.model) {
            (None | Some("polach"), None) => AdhesionLaw::Polach,
            (Some("model"), Some(m)) => {
                let p = Path::new(m);
                AdhesionLaw::Model(match dir {
                    Some(d) if p.is_relative() => d.join(p),
                    _ => p.to_path_buf(),
                })
            }
            (Some("model"), None) => {
                return Err(c.invalid(
                    MODEL.name,
                    "missing",
                    "law = \"model\" needs model = \"file.json\"",
                ))
            }
            (Some("loss_recovery"), None) => AdhesionLaw::LossRecovery(loss_recovery(c, a)?),
            (Some("table"), None) => AdhesionLaw::Table(slip_table(c, a)?),
            (Some("fastsim"), None) => AdhesionLaw::Fastsim(fastsim_law(c, a)?),
            (Some(other), None) if other != "polach" => {
                return Err(c.invalid(
                    LAW.name,
                    format!("{other:?}"),
                    "must be one of \"polach\", \"model\", \"loss_recovery\", \"table\", \"fastsim\" (default \"polach\")",
                ))
            }
            _ => return Err(c.invalid(MODEL.name, "given", "only with law = \"model\"")),
        };
        let lr_given = [
            a.loss_peak_mu,
            a.loss_peak_slip_mps,
            a.loss_residual,
            a.recovery_peak_mu,
            a.recovery_peak_slip_mps,
            a.recovery_residual,
            a.peak_speed_coefficient,
            a.peak_temperature_coefficient_per_k,
        ]
        .iter()
        .any(Option::is_some);
        if lr_given && !matches!(law, AdhesionLaw::LossRecovery(_)) {
            return Err(c.invalid(
                "adhesion.loss_*/recovery_*/peak_*",
                "given",
                "only with law = \"loss_recovery\"",
            ));
        }
        let table_given =
            a.table_speeds_kmh.is_some() || a.table_slips_mps.is_some() || a.table_mu.is_some();
        if table_given && !matches!(law, AdhesionLaw::Table(_)) {
            return Err(c.invalid("adhesion.table_*", "given", "only with law = \"table\""));
        }
        let fastsim_given = a.fastsim_grid.is_some()
            || a.fastsim_bound.is_some()
            || a.fastsim_k0.is_some()
            || a.fastsim_alpha_inf.is_some()
            || a.fastsim_beta.is_some();
        if fastsim_given && !matches!(law, AdhesionLaw::Fastsim(_)) {
            return Err(c.invalid("adhesion.fastsim_*", "given", "only with law = \"fastsim\""));
        }
        // Soap-contaminated rail (seed 002 Fig. 7–8: μ 0.02–0.10, peak at ~1 m/s slip).
        let polach = PolachParams {
            mu0: c.value(&MU0, a.mu0)?,
            a_ratio: c.value(&A_RATIO, a.a_ratio)?,
            b_s_per_m: c.value(&B, a.b_s_per_m)?,
            k_a: c.value(&K_A, a.k_a)?,
            k_s: c.value(&K_S, a.k_s)?,
        };
        polach
            .check()
            .map_err(|e| c.invalid("adhesion", "k_a/k_s", e.to_string()))?;
        let (t_lo, t_hi) = match a.temperature_range_c {
            Some([lo, hi]) => (lo, hi),
            None => (-40.0, 20.0),
        };
        let temperature_law = TemperatureLaw::new(
            a.temperature_k_a
                .clone()
                .unwrap_or_else(|| default_k_temperature(polach.k_a)),
            a.temperature_k_s
                .clone()
                .unwrap_or_else(|| default_k_temperature(polach.k_s)),
            (t_lo, t_hi),
        )
        .map_err(|e| c.invalid("adhesion.temperature_*", "", e.to_string()))?;
        Ok(AdhesionSection {
            law,
            polach,
            speed_coefficient: c.value(&SPEED_COEFFICIENT, a.speed_coefficient)?,
            reference_speed_mps: c.value(&REFERENCE_SPEED, a.reference_speed_kmh)? / 3.6,
            hysteresis_depth: c.value(&HYSTERESIS_DEPTH, a.hysteresis_depth)?,
            hysteresis_ddv_mps2: c.value(&HYSTERESIS_DDV, a.hysteresis_ddv_mps2)?,
            hysteresis_time_constant_s: c.value(&HYSTERESIS_TAU, a.hysteresis_time_constant_s)?,
            cleaning_per_axle: c.value(&CLEANING, a.cleaning_per_axle)?,
            temperature_law,
            thermal: ThermalParams {
                partition: c.value(&THERMAL_PARTITION, a.thermal_partition)?,
                tread_capacity_j_per_k: c
                    .value(&THERMAL_CAPACITY, a.thermal_tread_capacity_j_per_k)?,
                cooling_w_per_k: c.value(&THERMAL_COOLING, a.thermal_cooling_w_per_k)?,
                reference_c: c.value(&THERMAL_REFERENCE, a.thermal_reference_c)?,
                scale_k: c.value(&THERMAL_SCALE, a.thermal_scale_k)?,
                residual: c.value(&THERMAL_RESIDUAL, a.thermal_residual)?,
                pressure_exponent: c.value(&THERMAL_PRESSURE, a.thermal_pressure_exponent)?,
                update_ms: c.value(&THERMAL_UPDATE, a.thermal_update_ms)?,
            },
        })
    }
}

/// `law = "fastsim"`'s grid, bound and optional reduction.
fn fastsim_law(c: &Checker, a: &raw::Adhesion) -> Result<FastsimLaw, ConfigError> {
    use crate::contact::fastsim::{Bound, Reduction};
    let grid = c.value(&FASTSIM_GRID, a.fastsim_grid)?;
    if grid.fract() != 0.0 {
        return Err(c.invalid(FASTSIM_GRID.name, grid, "a whole number of cells"));
    }
    let bound = match a.fastsim_bound.as_deref() {
        None | Some("elliptic") => Bound::Elliptic,
        Some("parabolic") => Bound::Parabolic,
        Some(other) => {
            return Err(c.invalid(
                FASTSIM_BOUND.name,
                format!("{other:?}"),
                "must be \"elliptic\" or \"parabolic\"",
            ))
        }
    };
    let reduction = match (a.fastsim_k0, a.fastsim_alpha_inf, a.fastsim_beta) {
        (None, None, None) => None,
        (Some(k0), alpha, beta) => {
            let r = Reduction {
                k0,
                alpha_inf: alpha.unwrap_or(1.0),
                beta: beta.unwrap_or(0.0),
            };
            r.check()
                .map_err(|e| c.invalid("adhesion.fastsim_k0/alpha_inf/beta", "", e.to_string()))?;
            Some(r)
        }
        (None, _, _) => {
            return Err(c.invalid(
                FASTSIM_K0.name,
                "missing",
                "fastsim_alpha_inf and fastsim_beta need fastsim_k0 (the modified FASTSIM)",
            ))
        }
    };
    Ok(FastsimLaw {
        grid: grid as usize,
        bound,
        reduction,
    })
}

/// `law = "loss_recovery"`'s parameters (the blend's scale and the speed reference are the
/// hysteresis and speed keys).
fn loss_recovery(
    c: &Checker,
    a: &raw::Adhesion,
) -> Result<super::foreign::LossRecovery, ConfigError> {
    use super::foreign::{Branch, LossRecovery};
    Ok(LossRecovery {
        loss: Branch {
            peak_mu: c.value(&LOSS_PEAK, a.loss_peak_mu)?,
            peak_slip_mps: c.value(&LOSS_SLIP, a.loss_peak_slip_mps)?,
            residual: c.value(&LOSS_RESIDUAL, a.loss_residual)?,
        },
        recovery: Branch {
            peak_mu: c.value(&RECOVERY_PEAK, a.recovery_peak_mu)?,
            peak_slip_mps: c.value(&RECOVERY_SLIP, a.recovery_peak_slip_mps)?,
            residual: c.value(&RECOVERY_RESIDUAL, a.recovery_residual)?,
        },
        blend_ddv_mps2: c.value(&HYSTERESIS_DDV, a.hysteresis_ddv_mps2)?,
        speed_coefficient: c.value(&PEAK_SPEED, a.peak_speed_coefficient)?,
        reference_speed_mps: c.value(&REFERENCE_SPEED, a.reference_speed_kmh)? / 3.6,
        temperature_coefficient_per_k: c
            .value(&PEAK_TEMPERATURE, a.peak_temperature_coefficient_per_k)?,
    })
}

/// `law = "table"`'s table (the built-in one where keys are left out).
fn slip_table(c: &Checker, a: &raw::Adhesion) -> Result<super::foreign::SlipTable, ConfigError> {
    let d = super::foreign::SlipTable::default_table();
    let t = super::foreign::SlipTable {
        speeds_mps: match &a.table_speeds_kmh {
            Some(v) => v.iter().map(|x| x / 3.6).collect(),
            None => d.speeds_mps,
        },
        slips_mps: a.table_slips_mps.clone().unwrap_or(d.slips_mps),
        mu: a.table_mu.clone().unwrap_or(d.mu),
    };
    t.check()
        .map_err(|e| c.invalid("adhesion.table_*", "", e))?;
    Ok(t)
}

// ---------------------------------------------------------------------------------- [wsp]

/// `[wsp]`: wheel-slide protection thresholds (railgrip's [assumed] values; `sim::wsp`).
#[derive(Debug, Clone, PartialEq)]
pub struct WspSection {
    pub dump_slip_mps: f64,
    pub reapply_slip_mps: f64,
    pub decel_limit_mps2: f64,
    /// Relative dump threshold: the WSP dumps above max(dump_slip_mps, ratio·v).
    pub dump_slip_ratio: f64,
    /// Time from detecting a slide to venting the cylinder, s.
    pub reaction_delay_s: f64,
    /// Longest hold before re-applying, s.
    pub hold_max_s: f64,
}

const DUMP_SLIP: Key = Key::num(
    "wsp.dump_slip_mps",
    "m/s",
    closed(0.05, 20.0),
    1.0,
    "dump above this slip [assumed]",
);
const DUMP_RATIO: Key = Key::num(
    "wsp.dump_slip_ratio",
    "",
    closed(0.0, 1.0),
    0.1,
    "… or above this fraction of v [assumed]",
);
const REAPPLY: Key = Key::num(
    "wsp.reapply_slip_mps",
    "m/s",
    closed(0.01, 10.0),
    0.3,
    "re-apply below this slip, below the dump slip [assumed]",
);
const DECEL_LIMIT: Key = Key::num(
    "wsp.decel_limit_mps2",
    "m/s²",
    closed(0.1, 100.0),
    4.0,
    "detect when the wheel decelerates this much faster than the vehicle [assumed]",
);
const DELAY: Key = Key::num(
    "wsp.reaction_delay_ms",
    "ms",
    closed(0.0, 1000.0),
    80.0,
    "from detection to venting [assumed]",
);
const HOLD_MAX: Key = Key::num(
    "wsp.hold_max_s",
    "s",
    closed(0.01, 10.0),
    0.4,
    "longest hold before re-applying [assumed]",
);

/// The keys of `[wsp]`, in the order of the documented table.
pub const WSP_KEYS: &[&Key] = &[
    &DUMP_SLIP,
    &DUMP_RATIO,
    &REAPPLY,
    &DECEL_LIMIT,
    &DELAY,
    &HOLD_MAX,
];

impl WspSection {
    fn check(c: &Checker, w: &raw::Wsp) -> Result<WspSection, ConfigError> {
        let reapply = c.value(&REAPPLY, w.reapply_slip_mps)?;
        let dump = c.value(&DUMP_SLIP, w.dump_slip_mps)?;
        if reapply >= dump {
            return Err(c.invalid(
                REAPPLY.name,
                reapply,
                format!("must be below {} = {dump}", DUMP_SLIP.name),
            ));
        }
        Ok(WspSection {
            dump_slip_mps: dump,
            reapply_slip_mps: reapply,
            decel_limit_mps2: c.value(&DECEL_LIMIT, w.decel_limit_mps2)?,
            dump_slip_ratio: c.value(&DUMP_RATIO, w.dump_slip_ratio)?,
            reaction_delay_s: c.value(&DELAY, w.reaction_delay_ms)? * 1e-3,
            hold_max_s: c.value(&HOLD_MAX, w.hold_max_s)?,
        })
    }
}

// ---------------------------------------------------------------------------------- [sensors]

/// `[sensors]`: what the logger sees of the truth.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorsSection {
    pub radar_noise_mps: f64,
    pub radar_spike_rate_hz: f64,
    pub radar_spike_mps: f64,
    pub tacho_pulses_per_rev: f64,
    pub tacho_window_s: f64,
    pub pressure_noise_bar: f64,
    pub radar_rate_hz: f64,
    pub tacho_rate_hz: f64,
    pub pressure_rate_hz: f64,
}

const RADAR_NOISE: Key = Key::num(
    "sensors.radar_noise_mps",
    "m/s",
    closed(0.0, 10.0),
    0.05,
    "`radar_noise`: standard deviation",
);
const SPIKE_RATE: Key = Key::num(
    "sensors.radar_spike_rate_hz",
    "Hz",
    closed(0.0, 100.0),
    0.3,
    "`radar_spikes`: mean rate",
);
const SPIKE: Key = Key::num(
    "sensors.radar_spike_mps",
    "m/s",
    closed(0.0, 100.0),
    3.0,
    "`radar_spikes`: amplitude (× 0.5–1.5, either sign)",
);
const PULSES: Key = Key::num(
    "sensors.tacho_pulses_per_rev",
    "",
    closed(1.0, 100_000.0),
    1000.0,
    "`tacho_quantization`: pulses per revolution",
);
const WINDOW: Key = Key::num(
    "sensors.tacho_window_ms",
    "ms",
    closed(0.1, 1000.0),
    20.0,
    "`tacho_quantization`: counting window",
);
const PRESSURE_NOISE: Key = Key::num(
    "sensors.pressure_noise_bar",
    "bar",
    closed(0.0, 5.0),
    0.01,
    "`pressure_noise`: standard deviation",
);
const fn rate(name: &'static str, meaning: &'static str) -> Key {
    Key {
        name,
        unit: "Hz",
        range: closed(1.0, 10_000.0),
        default: Default::Text("the output rate"),
        meaning,
    }
}
const RADAR_RATE: Key = rate(
    "sensors.radar_rate_hz",
    "radar logger rate (rates other than the output rate: MCAP only)",
);
const TACHO_RATE: Key = rate("sensors.tacho_rate_hz", "tachometer logger rate");
const PRESSURE_RATE: Key = rate("sensors.pressure_rate_hz", "pressure logger rate");

/// The keys of `[sensors]`, in the order of the documented table.
pub const SENSORS_KEYS: &[&Key] = &[
    &RADAR_NOISE,
    &SPIKE_RATE,
    &SPIKE,
    &PULSES,
    &WINDOW,
    &PRESSURE_NOISE,
    &RADAR_RATE,
    &TACHO_RATE,
    &PRESSURE_RATE,
];

impl SensorsSection {
    fn check(
        c: &Checker,
        s: &raw::Sensors,
        output_rate_hz: f64,
    ) -> Result<SensorsSection, ConfigError> {
        Ok(SensorsSection {
            radar_noise_mps: c.value(&RADAR_NOISE, s.radar_noise_mps)?,
            radar_spike_rate_hz: c.value(&SPIKE_RATE, s.radar_spike_rate_hz)?,
            radar_spike_mps: c.value(&SPIKE, s.radar_spike_mps)?,
            tacho_pulses_per_rev: c.value(&PULSES, s.tacho_pulses_per_rev)?,
            tacho_window_s: c.value(&WINDOW, s.tacho_window_ms)? * 1e-3,
            pressure_noise_bar: c.value(&PRESSURE_NOISE, s.pressure_noise_bar)?,
            radar_rate_hz: c.value_or(&RADAR_RATE, s.radar_rate_hz, output_rate_hz)?,
            tacho_rate_hz: c.value_or(&TACHO_RATE, s.tacho_rate_hz, output_rate_hz)?,
            pressure_rate_hz: c.value_or(&PRESSURE_RATE, s.pressure_rate_hz, output_rate_hz)?,
        })
    }
}

// ---------------------------------------------------------------------------------- [resistance]

/// `[resistance]`: Davis running resistance a + b v + c v².
#[derive(Debug, Clone, PartialEq)]
pub struct ResistanceSection {
    pub davis_a_n: f64,
    pub davis_b_n_per_mps: f64,
    pub davis_c_n_per_mps2: f64,
}

const DAVIS_A: Key = Key::num(
    "resistance.davis_a_n",
    "N",
    closed(0.0, 1e5),
    1200.0,
    "`running_resistance`: a",
);
const DAVIS_B: Key = Key::num(
    "resistance.davis_b_n_per_mps",
    "N/(m/s)",
    closed(0.0, 1e4),
    30.0,
    "b",
);
const DAVIS_C: Key = Key::num(
    "resistance.davis_c_n_per_mps2",
    "N/(m/s)²",
    closed(0.0, 1e3),
    6.0,
    "c",
);

/// The keys of `[resistance]`, in the order of the documented table.
pub const RESISTANCE_KEYS: &[&Key] = &[&DAVIS_A, &DAVIS_B, &DAVIS_C];

impl ResistanceSection {
    fn check(c: &Checker, r: &raw::Resistance) -> Result<ResistanceSection, ConfigError> {
        Ok(ResistanceSection {
            davis_a_n: c.value(&DAVIS_A, r.davis_a_n)?,
            davis_b_n_per_mps: c.value(&DAVIS_B, r.davis_b_n_per_mps)?,
            davis_c_n_per_mps2: c.value(&DAVIS_C, r.davis_c_n_per_mps2)?,
        })
    }
}

/// The scene file's sections and their key tables, in the order of the documented table (`[contact]` is the
/// pipeline's).
pub const SECTIONS: &[(&str, &[&Key])] = &[
    ("top", TOP_KEYS),
    ("run", RUN_KEYS),
    ("brake", BRAKE_KEYS),
    ("adhesion", ADHESION_KEYS),
    ("contact", crate::config::contact::KEYS),
    ("wsp", WSP_KEYS),
    ("sensors", SENSORS_KEYS),
    ("resistance", RESISTANCE_KEYS),
];

impl Scene {
    /// Reads and checks a scene file.
    pub fn load(path: &Path) -> Result<Scene, ConfigError> {
        let file = path.display().to_string();
        let text =
            crate::input::read_text_limited(path, crate::input::MAX_CONFIG_BYTES, "scene file")
                .map_err(|source| ConfigError::Read {
                    file: file.clone(),
                    source,
                })?;
        Self::from_toml(&text, &file, path.parent())
    }

    /// Parses and checks scene TOML; `dir` resolves `vehicle.pipeline` and `adhesion.model`
    /// paths.
    pub fn from_toml(text: &str, file: &str, dir: Option<&Path>) -> Result<Scene, ConfigError> {
        let r: raw::Scene = toml::from_str(text).map_err(|e| ConfigError::Syntax {
            file: file.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let c = Checker { file };
        let vehicle = vehicle(&c, r.vehicle, dir)?;
        let effects = effects(&c, &r.effects)?;
        let run = RunSection::check(&c, &r.run)?;
        let adhesion = AdhesionSection::check(&c, &r.adhesion, dir)?;
        // Only the Polach truth law uses k(T) here; a model's own temperature law is checked when
        // it is loaded, and loss_recovery scales its peaks with any temperature.
        if effects.has(Effect::Temperature) && matches!(adhesion.law, AdhesionLaw::Polach) {
            let t = run.ambient_temperature_c;
            adhesion.temperature_law.eval(t).map_err(|e| {
                c.invalid(AMBIENT.name, t, format!("with the temperature effect: {e}"))
            })?;
        }
        Ok(Scene {
            name: r.name.unwrap_or_else(|| "scene".into()),
            seed: r.seed.unwrap_or(1),
            effects,
            vehicle,
            brake: BrakeSection::check(&c, &r.brake)?,
            adhesion,
            contact: c.contact(r.contact)?,
            wsp: WspSection::check(&c, &r.wsp)?,
            sensors: SensorsSection::check(&c, &r.sensors, run.output_rate_hz)?,
            resistance: ResistanceSection::check(&c, &r.resistance)?,
            run,
        })
    }

    /// True when every channel runs at the output rate (the CSV shape).
    pub fn single_rate(&self) -> bool {
        let s = &self.sensors;
        [s.radar_rate_hz, s.tacho_rate_hz, s.pressure_rate_hz]
            .iter()
            .all(|r| *r == self.run.output_rate_hz)
    }
}

/// The scene's vehicle: the embedded default, a pipeline file's, or inline `[vehicle]` keys.
fn vehicle(
    c: &Checker,
    t: Option<toml::Table>,
    dir: Option<&Path>,
) -> Result<Vehicle, ConfigError> {
    let Some(mut t) = t else {
        return Ok(Pipeline::default_uic_z1().vehicle);
    };
    match t.remove("pipeline") {
        Some(_) if !t.is_empty() => Err(c.invalid(
            "vehicle",
            "a pipeline and inline keys",
            "give either pipeline = \"file\" or the vehicle keys, not both",
        )),
        Some(toml::Value::String(p)) if p == "default" => Ok(Pipeline::default_uic_z1().vehicle),
        Some(toml::Value::String(p)) => {
            let path = dir.map(|d| d.join(&p)).unwrap_or_else(|| p.clone().into());
            Ok(Pipeline::load(Some(&path))?.vehicle)
        }
        Some(other) => Err(c.invalid(
            VEHICLE.name,
            other,
            "must be a file path (string) or \"default\"",
        )),
        None => {
            let raw: config::raw::Vehicle =
                t.try_into()
                    .map_err(|e: toml::de::Error| ConfigError::Syntax {
                        file: c.file.to_string(),
                        message: format!("[vehicle]: {}", e.to_string().trim_end()),
                    })?;
            config::check_vehicle(raw, c.file)
        }
    }
}

/// The listed effects.
fn effects(c: &Checker, names: &[String]) -> Result<Effects, ConfigError> {
    let mut effects = Effects::none();
    for name in names {
        match Effect::ALL.iter().find(|e| e.name() == name) {
            Some(e) => effects = effects.with(*e),
            None => {
                return Err(c.invalid(
                    EFFECTS.name,
                    format!("{name:?}"),
                    format!(
                        "unknown effect; the effects are {}",
                        Effect::ALL
                            .iter()
                            .map(|e| e.name())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ))
            }
        }
    }
    Ok(effects)
}

/// Default k(T) shape when a scene gives none: k(T) = k20·(1 + 0.015 u − 1.875e-4 u²) with
/// u = 20 − T (°C), over −40…20 °C: ×1.225 at 0 °C, a peak of ×1.30 at −20 °C and ×1.225 at
/// −40 °C — seed 004's trend (adhesion rises from +20 °C to −20 °C and dips slightly towards
/// −40 °C). railgrip's assumption, not published coefficients.
fn default_k_temperature(k20: f64) -> Vec<f64> {
    // Expand k20 (1 + a u + b u²), u = 20 − T, into ascending powers of T.
    let (a, b) = (0.015, -1.875e-4);
    vec![
        k20 * (1.0 + 20.0 * a + 400.0 * b),
        k20 * (-a - 40.0 * b),
        k20 * b,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effect_index_is_the_position_in_all() {
        for (i, e) in Effect::ALL.iter().enumerate() {
            assert_eq!(e.index(), i, "{e}");
        }
    }
}
