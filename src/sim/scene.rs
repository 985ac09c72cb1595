//! Scene files (`pipelines/scenes/*.toml`): raw serde types, checked into a [`Scene`].
//!
//! Every key is documented in README.md ("Scene file"); a rejected value is reported as
//! `file: key = value: allowed range (default)`, like the pipeline file.

use std::fmt;
use std::path::Path;

use serde::Deserialize;

use crate::config::{self, ConfigError, Pipeline, Vehicle};
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
}

impl Effect {
    pub const ALL: [Effect; 12] = [
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
        }
    }

    pub fn index(self) -> usize {
        Effect::ALL.iter().position(|e| *e == self).expect("listed")
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
    /// A model file (`railgrip train`'s output, README "Model files", kind mlp or polach):
    /// μ(Δv, dΔv/dt, v) from the model's evaluator. The model carries the adhesion effects
    /// itself, so a scene with it may not list falling_friction, hysteresis or cleaning;
    /// `temperature` is allowed for a Polach model with a temperature law and sets k_A(T),
    /// k_S(T) at the scene's ambient temperature. The path is resolved against the scene
    /// file's folder.
    Model(std::path::PathBuf),
}

/// A validated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub name: String,
    pub seed: u64,
    pub effects: Effects,
    pub vehicle: Vehicle,
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
    /// Brake-cylinder pressure demand per axle (t s, p bar), piecewise linear, held after the
    /// last point.
    pub demand_bar: [Vec<(f64, f64)>; 4],
    pub cylinder_time_constant_s: f64,
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
    /// Wheel–rail contact material and profile radii (the pipeline's `[contact]` keys).
    pub contact: crate::config::ContactConfig,
    pub dump_slip_mps: f64,
    pub reapply_slip_mps: f64,
    pub decel_limit_mps2: f64,
    /// Relative dump threshold: the WSP dumps above max(dump_slip_mps, ratio·v).
    pub dump_slip_ratio: f64,
    /// Time from detecting a slide to venting the cylinder, s.
    pub reaction_delay_s: f64,
    /// Longest hold before re-applying, s.
    pub hold_max_s: f64,
    pub radar_noise_mps: f64,
    pub radar_spike_rate_hz: f64,
    pub radar_spike_mps: f64,
    pub tacho_pulses_per_rev: f64,
    pub tacho_window_s: f64,
    pub pressure_noise_bar: f64,
    pub radar_rate_hz: f64,
    pub tacho_rate_hz: f64,
    pub pressure_rate_hz: f64,
    pub davis_a_n: f64,
    pub davis_b_n_per_mps: f64,
    pub davis_c_n_per_mps2: f64,
}

impl Scene {
    /// Reads and checks a scene file.
    pub fn load(path: &Path) -> Result<Scene, ConfigError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            file: file.clone(),
            source,
        })?;
        Self::from_toml(&text, &file, path.parent())
    }

    /// Parses and checks scene TOML; `dir` resolves `vehicle.pipeline` paths.
    pub fn from_toml(text: &str, file: &str, dir: Option<&Path>) -> Result<Scene, ConfigError> {
        let r: raw::Scene = toml::from_str(text).map_err(|e| ConfigError::Syntax {
            file: file.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let c = config::Checker { file };
        let vehicle = match r.vehicle {
            None => Pipeline::default_uic_z1().vehicle,
            Some(mut t) => match t.remove("pipeline") {
                Some(_) if !t.is_empty() => {
                    return Err(c.invalid(
                        "vehicle",
                        "a pipeline and inline keys",
                        "give either pipeline = \"file\" or the vehicle keys, not both",
                    ))
                }
                Some(toml::Value::String(p)) if p == "default" => {
                    Pipeline::default_uic_z1().vehicle
                }
                Some(toml::Value::String(p)) => {
                    let path = dir.map(|d| d.join(&p)).unwrap_or_else(|| p.clone().into());
                    Pipeline::load(Some(&path))?.vehicle
                }
                Some(other) => {
                    return Err(c.invalid(
                        "vehicle.pipeline",
                        other,
                        "must be a file path (string) or \"default\"",
                    ))
                }
                None => {
                    let raw: config::raw::Vehicle =
                        t.try_into()
                            .map_err(|e: toml::de::Error| ConfigError::Syntax {
                                file: file.to_string(),
                                message: format!("[vehicle]: {}", e.to_string().trim_end()),
                            })?;
                    config::check_vehicle(raw, file)?
                }
            },
        };
        let mut effects = Effects::none();
        for name in &r.effects {
            match Effect::ALL.iter().find(|e| e.name() == name) {
                Some(e) => effects = effects.with(*e),
                None => {
                    return Err(c.invalid(
                        "effects",
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
        let run = &r.run;
        let initial_kmh = c.num(
            "run.initial_speed_kmh",
            run.initial_speed_kmh,
            1.0,
            400.0,
            Some(120.0),
            "km/h",
        )?;
        let stop_kmh = c.num(
            "run.stop_speed_kmh",
            run.stop_speed_kmh,
            0.5,
            400.0,
            Some(3.0),
            "km/h",
        )?;
        if stop_kmh >= initial_kmh {
            return Err(c.invalid(
                "run.stop_speed_kmh",
                stop_kmh,
                format!("must be below run.initial_speed_kmh = {initial_kmh}"),
            ));
        }
        let step_ms = c.num("run.step_ms", run.step_ms, 0.01, 1.0, Some(0.1), "ms")?;
        let output_rate_hz = c.num(
            "run.output_rate_hz",
            run.output_rate_hz,
            10.0,
            10_000.0,
            Some(417.0),
            "Hz",
        )?;
        if step_ms * 1e-3 > 0.5 / output_rate_hz {
            return Err(c.invalid(
                "run.step_ms",
                step_ms,
                "must be at most half the output period",
            ));
        }
        let check_profile =
            |key: &str, d: &Vec<[f64; 2]>| -> Result<Vec<(f64, f64)>, ConfigError> {
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
        let demand: [Vec<(f64, f64)>; 4] = match (&r.brake.demand_bar, &r.brake.demand_bar_per_axle)
        {
            (Some(_), Some(_)) => {
                return Err(c.invalid(
                    "brake.demand_bar_per_axle",
                    "given with brake.demand_bar",
                    "give one of the two",
                ))
            }
            (_, Some(per)) => {
                if per.len() != 4 {
                    return Err(c.invalid(
                        "brake.demand_bar_per_axle",
                        format!("{} profiles", per.len()),
                        "must list exactly 4 profiles, axles 1..4",
                    ));
                }
                let mut out: [Vec<(f64, f64)>; 4] = Default::default();
                for (i, d) in per.iter().enumerate() {
                    out[i] = check_profile(&format!("brake.demand_bar_per_axle[{i}]"), d)?;
                }
                out
            }
            (Some(d), None) => {
                let one = check_profile("brake.demand_bar", d)?;
                [one.clone(), one.clone(), one.clone(), one]
            }
            (None, None) => std::array::from_fn(|_| vec![(0.0, 0.0), (1.0, 0.0), (2.5, 3.8)]),
        };
        let a = &r.adhesion;
        let law = match (a.law.as_deref(), &a.model) {
            (None | Some("polach"), None) => AdhesionLaw::Polach,
            (Some("model"), Some(m)) => {
                let p = std::path::Path::new(m);
                AdhesionLaw::Model(match dir {
                    Some(d) if p.is_relative() => d.join(p),
                    _ => p.to_path_buf(),
                })
            }
            (Some("model"), None) => {
                return Err(c.invalid(
                    "adhesion.model",
                    "missing",
                    "law = \"model\" needs model = \"file.json\"",
                ))
            }
            (Some(other), _) if other != "polach" => {
                return Err(c.invalid(
                    "adhesion.law",
                    format!("{other:?}"),
                    "must be \"polach\" or \"model\" (default \"polach\")",
                ))
            }
            _ => return Err(c.invalid("adhesion.model", "given", "only with law = \"model\"")),
        };
        // Soap-contaminated rail (seed 002 Fig. 7–8: μ 0.02–0.10, peak at ~1 m/s slip).
        let polach = PolachParams {
            mu0: c.num("adhesion.mu0", a.mu0, 0.005, 1.5, Some(0.085), "")?,
            a_ratio: c.num("adhesion.a_ratio", a.a_ratio, 0.01, 1.0, Some(0.4), "")?,
            b_s_per_m: c.num(
                "adhesion.b_s_per_m",
                a.b_s_per_m,
                0.0,
                10.0,
                Some(0.3),
                "s/m",
            )?,
            k_a: c.num("adhesion.k_a", a.k_a, 1e-4, 1.0, Some(0.1), "")?,
            k_s: c.num("adhesion.k_s", a.k_s, 1e-5, 1.0, Some(0.05), "")?,
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
        let ambient = c.num(
            "run.ambient_temperature_c",
            run.ambient_temperature_c,
            -60.0,
            60.0,
            Some(20.0),
            "°C",
        )?;
        // With a learned model the model's own temperature law is checked when it is loaded.
        if effects.has(Effect::Temperature) && !matches!(law, AdhesionLaw::Model(_)) {
            temperature_law.eval(ambient).map_err(|e| {
                c.invalid(
                    "run.ambient_temperature_c",
                    ambient,
                    format!("with the temperature effect: {e}"),
                )
            })?;
        }
        let reapply = c.num(
            "wsp.reapply_slip_mps",
            r.wsp.reapply_slip_mps,
            0.01,
            10.0,
            Some(0.3),
            "m/s",
        )?;
        let dump = c.num(
            "wsp.dump_slip_mps",
            r.wsp.dump_slip_mps,
            0.05,
            20.0,
            Some(1.0),
            "m/s",
        )?;
        if reapply >= dump {
            return Err(c.invalid(
                "wsp.reapply_slip_mps",
                reapply,
                format!("must be below wsp.dump_slip_mps = {dump}"),
            ));
        }
        let s = &r.sensors;
        Ok(Scene {
            name: r.name.unwrap_or_else(|| "scene".into()),
            seed: r.seed.unwrap_or(1),
            effects,
            vehicle,
            initial_speed_kmh: initial_kmh,
            initial_speed_mps: initial_kmh / 3.6,
            stop_speed_mps: stop_kmh / 3.6,
            max_duration_s: c.num(
                "run.max_duration_s",
                run.max_duration_s,
                0.1,
                36_000.0,
                Some(300.0),
                "s",
            )?,
            step_s: step_ms * 1e-3,
            output_rate_hz,
            ambient_temperature_c: ambient,
            gradient_permille: c.num(
                "run.gradient_permille",
                run.gradient_permille,
                -60.0,
                60.0,
                Some(0.0),
                "‰",
            )?,
            condition: run.condition.clone().unwrap_or_else(|| "soap".into()),
            direction: run.direction.clone().unwrap_or_else(|| "forward".into()),
            demand_bar: demand,
            cylinder_time_constant_s: c.num(
                "brake.cylinder_time_constant_s",
                r.brake.cylinder_time_constant_s,
                0.005,
                5.0,
                Some(0.15),
                "s",
            )?,
            law,
            polach,
            speed_coefficient: c.num(
                "adhesion.speed_coefficient",
                a.speed_coefficient,
                -2.0,
                2.0,
                Some(0.25),
                "",
            )?,
            reference_speed_mps: c.num(
                "adhesion.reference_speed_kmh",
                a.reference_speed_kmh,
                1.0,
                400.0,
                Some(120.0),
                "km/h",
            )? / 3.6,
            hysteresis_depth: c.num(
                "adhesion.hysteresis_depth",
                a.hysteresis_depth,
                0.0,
                0.9,
                Some(0.3),
                "",
            )?,
            hysteresis_ddv_mps2: c.num(
                "adhesion.hysteresis_ddv_mps2",
                a.hysteresis_ddv_mps2,
                1e-3,
                100.0,
                Some(0.5),
                "m/s²",
            )?,
            hysteresis_time_constant_s: c.num(
                "adhesion.hysteresis_time_constant_s",
                a.hysteresis_time_constant_s,
                1e-3,
                10.0,
                Some(0.02),
                "s",
            )?,
            cleaning_per_axle: c.num(
                "adhesion.cleaning_per_axle",
                a.cleaning_per_axle,
                0.0,
                2.0,
                Some(0.05),
                "",
            )?,
            temperature_law,
            contact: c.contact(r.contact.clone())?,
            dump_slip_mps: dump,
            reapply_slip_mps: reapply,
            decel_limit_mps2: c.num(
                "wsp.decel_limit_mps2",
                r.wsp.decel_limit_mps2,
                0.1,
                100.0,
                Some(4.0),
                "m/s²",
            )?,
            dump_slip_ratio: c.num(
                "wsp.dump_slip_ratio",
                r.wsp.dump_slip_ratio,
                0.0,
                1.0,
                Some(0.1),
                "",
            )?,
            reaction_delay_s: c.num(
                "wsp.reaction_delay_ms",
                r.wsp.reaction_delay_ms,
                0.0,
                1000.0,
                Some(80.0),
                "ms",
            )? * 1e-3,
            hold_max_s: c.num(
                "wsp.hold_max_s",
                r.wsp.hold_max_s,
                0.01,
                10.0,
                Some(0.4),
                "s",
            )?,
            radar_noise_mps: c.num(
                "sensors.radar_noise_mps",
                s.radar_noise_mps,
                0.0,
                10.0,
                Some(0.05),
                "m/s",
            )?,
            radar_spike_rate_hz: c.num(
                "sensors.radar_spike_rate_hz",
                s.radar_spike_rate_hz,
                0.0,
                100.0,
                Some(0.3),
                "Hz",
            )?,
            radar_spike_mps: c.num(
                "sensors.radar_spike_mps",
                s.radar_spike_mps,
                0.0,
                100.0,
                Some(3.0),
                "m/s",
            )?,
            tacho_pulses_per_rev: c.num(
                "sensors.tacho_pulses_per_rev",
                s.tacho_pulses_per_rev,
                1.0,
                100_000.0,
                Some(1000.0),
                "",
            )?,
            tacho_window_s: c.num(
                "sensors.tacho_window_ms",
                s.tacho_window_ms,
                0.1,
                1000.0,
                Some(20.0),
                "ms",
            )? * 1e-3,
            pressure_noise_bar: c.num(
                "sensors.pressure_noise_bar",
                s.pressure_noise_bar,
                0.0,
                5.0,
                Some(0.01),
                "bar",
            )?,
            radar_rate_hz: c.num(
                "sensors.radar_rate_hz",
                s.radar_rate_hz,
                1.0,
                10_000.0,
                Some(output_rate_hz),
                "Hz",
            )?,
            tacho_rate_hz: c.num(
                "sensors.tacho_rate_hz",
                s.tacho_rate_hz,
                1.0,
                10_000.0,
                Some(output_rate_hz),
                "Hz",
            )?,
            pressure_rate_hz: c.num(
                "sensors.pressure_rate_hz",
                s.pressure_rate_hz,
                1.0,
                10_000.0,
                Some(output_rate_hz),
                "Hz",
            )?,
            davis_a_n: c.num(
                "resistance.davis_a_n",
                r.resistance.davis_a_n,
                0.0,
                1e5,
                Some(1200.0),
                "N",
            )?,
            davis_b_n_per_mps: c.num(
                "resistance.davis_b_n_per_mps",
                r.resistance.davis_b_n_per_mps,
                0.0,
                1e4,
                Some(30.0),
                "N/(m/s)",
            )?,
            davis_c_n_per_mps2: c.num(
                "resistance.davis_c_n_per_mps2",
                r.resistance.davis_c_n_per_mps2,
                0.0,
                1e3,
                Some(6.0),
                "N/(m/s)²",
            )?,
        })
    }

    /// True when every channel runs at the output rate (the CSV shape).
    pub fn single_rate(&self) -> bool {
        [
            self.radar_rate_hz,
            self.tacho_rate_hz,
            self.pressure_rate_hz,
        ]
        .iter()
        .all(|r| *r == self.output_rate_hz)
    }
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
