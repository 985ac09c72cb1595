//! Scene files (`pipelines/scenes/*.toml`): raw serde types, checked into a [`Scene`] of
//! section structs, one per TOML section (run, vehicle, brake, adhesion, contact, wsp, sensors,
//! resistance), each with its key table and check side by side.
//!
//! Every key is documented in docs/simulator.md ("Scene file", rendered from the key tables; a test
//! keeps them equal); a rejected value is reported as `file: key = value: allowed range
//! (default)`, like the pipeline file.

use std::fmt;
use std::path::Path;

use crate::config::rule::{Checker, Default, Key, Range};
use crate::config::{self, ConfigError, ContactConfig, Pipeline, Vehicle};

mod adhesion;
mod brake;
mod laws;
mod resistance;
mod run;
mod sensors;
mod thermal;
mod wsp;

pub use adhesion::{AdhesionLaw, AdhesionSection};
pub use brake::BrakeSection;
pub use laws::FastsimLaw;
pub use resistance::ResistanceSection;
pub use run::RunSection;
use run::AMBIENT;
pub use sensors::SensorsSection;
pub use thermal::ThermalParams;
pub use wsp::WspSection;

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
    /// Each axle's brake coefficient α_i off the pipeline's by a relative scatter drawn from
    /// the vehicle's seed (`brake.alpha_scatter` 1σ, `brake.scatter_seed`): the brake rig an
    /// estimator does not know.
    BrakeScatter,
    /// Pad friction rising as the train slows: α_i(v) = α_i (1 + rise max(0, 1 − v/v0)), v0
    /// `brake.pad_friction_v0_kmh` or the run's initial speed (`brake.pad_friction_rise` at
    /// standstill).
    PadFriction,
    /// A radar that reads `sensors.radar_scale` × the speed of `sensors.radar_latency_s` ago.
    RadarError,
    /// Each axle's load fluctuates about its eq. 12–13 value (track irregularities, the
    /// suspension): relative band-limited noise, `run.load_fluctuation_rms` in
    /// `run.load_fluctuation_band_hz`.
    LoadFluctuation,
    /// The body's inertia force acts on each bogie at the pivot height and shifts load within
    /// the bogie, (m_c/2) h_b d / l2 per axle — a share eq. 12–13 leave out.
    PivotForce,
}

impl Effect {
    pub const ALL: [Effect; 18] = [
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
        Effect::BrakeScatter,
        Effect::PadFriction,
        Effect::RadarError,
        Effect::LoadFluctuation,
        Effect::PivotForce,
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
            Effect::BrakeScatter => "brake_scatter",
            Effect::PadFriction => "pad_friction",
            Effect::RadarError => "radar_error",
            Effect::LoadFluctuation => "load_fluctuation",
            Effect::PivotForce => "pivot_force",
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
    use serde::Deserialize;

    pub use super::adhesion::raw::Adhesion;
    pub use super::brake::raw::Brake;
    pub use super::resistance::raw::Resistance;
    pub use super::run::raw::Run;
    pub use super::sensors::raw::Sensors;
    pub use super::wsp::raw::Wsp;

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
    "sensor noise (`railgrip simulate --seed N` draws it from N and this seed together; give each scene of a campaign its own)",
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

/// The scene file's sections and their key tables, in the order of the documented table (`[contact]` is the
/// pipeline's).
pub const SECTIONS: &[(&str, &[&Key])] = &[
    ("top", TOP_KEYS),
    ("run", run::KEYS),
    ("brake", brake::KEYS),
    ("adhesion", adhesion::KEYS),
    ("contact", crate::config::contact::KEYS),
    ("wsp", wsp::KEYS),
    ("sensors", sensors::KEYS),
    ("resistance", resistance::KEYS),
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
        let run = c.run(&r.run)?;
        let adhesion = c.adhesion(&r.adhesion, dir)?;
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
            brake: c.brake(&r.brake)?,
            adhesion,
            contact: c.contact(r.contact)?,
            wsp: c.wsp(&r.wsp)?,
            sensors: c.sensors(&r.sensors, run.output_rate_hz)?,
            resistance: c.resistance(&r.resistance)?,
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
