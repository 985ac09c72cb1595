//! The pipeline file: raw serde types ([`raw`]), checked into validated types ([`Pipeline`]).
//!
//! Stages only ever see validated types. Every check names the key, the value found, the
//! allowed range and the default, e.g.
//! `ingest.max_gap_ms = -5: must be > 2.398 ms (one sample period) and <= 10000 (default 50)`.
//! The options are documented in README.md ("Pipeline file").

use std::fmt;
use std::path::Path;

use crate::format::{Signal, AXLES};
use crate::units::{Quantity, Unit};

/// The embedded default pipeline (`pipelines/uic_z1.toml`).
pub const DEFAULT_PIPELINE_TOML: &str = include_str!("../pipelines/uic_z1.toml");
/// How the embedded default is named in messages and provenance.
pub const DEFAULT_PIPELINE_NAME: &str = "<embedded pipelines/uic_z1.toml>";

/// A pipeline file that could not be read or does not pass its checks.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error(
        "{file}: cannot read the pipeline file: {source}. Hint: check the path given to --pipeline"
    )]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: not a valid pipeline file: {message}")]
    Syntax { file: String, message: String },
    #[error("{file}: {key} = {value}: {rule}")]
    Invalid {
        file: String,
        key: String,
        value: String,
        rule: String,
    },
    #[error("{file}: {key} is missing: {rule}")]
    Missing {
        file: String,
        key: String,
        rule: String,
    },
}

/// Raw serde types: exactly the TOML's shape, every field optional so that checks, not serde,
/// produce the messages.
pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Pipeline {
        pub vehicle: Option<Vehicle>,
        #[serde(default)]
        pub ingest: Ingest,
        #[serde(default)]
        pub filters: Filters,
        #[serde(default)]
        pub estimate: Estimate,
        #[serde(default)]
        pub contact: Contact,
        #[serde(default)]
        pub train: Train,
    }

    /// `[contact]` of a pipeline file, and of a scene file (same keys, same checks).
    #[derive(Debug, Default, Clone, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Contact {
        pub youngs_modulus_pa: Option<f64>,
        pub poisson: Option<f64>,
        pub wheel_lateral_radius_m: Option<f64>,
        pub rail_lateral_radius_m: Option<f64>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Train {
        pub hidden: Option<f64>,
        pub inputs: Option<Vec<String>>,
        pub split: Option<String>,
        pub train_axles: Option<Vec<u8>>,
        pub val_axles: Option<Vec<u8>>,
        pub val_every: Option<f64>,
        pub block_s: Option<f64>,
        pub decimate: Option<f64>,
        pub seed: Option<u64>,
        pub epochs: Option<f64>,
        pub goal: Option<f64>,
        pub max_fail: Option<f64>,
        pub min_grad: Option<f64>,
        pub mu: Option<f64>,
        pub mu_dec: Option<f64>,
        pub mu_inc: Option<f64>,
        pub mu_max: Option<f64>,
        pub creep_blend_mps: Option<f64>,
        pub temperature_degree: Option<f64>,
        pub condition: Option<String>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Filters {
        pub mode: Option<String>,
        pub radar_cutoff_hz: Option<f64>,
        pub tacho_cutoff_hz: Option<f64>,
        pub pressure_cutoff_hz: Option<f64>,
        pub despike: Option<bool>,
        pub despike_half_window_s: Option<f64>,
        pub despike_threshold: Option<f64>,
        pub despike_min_deviation_mps: Option<f64>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Estimate {
        pub phase: Option<String>,
        pub min_speed_mps: Option<f64>,
        pub min_pressure_bar: Option<f64>,
        pub locked_wheel_speed_mps: Option<f64>,
        pub sliding_threshold_mps: Option<f64>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Vehicle {
        pub name: Option<String>,
        pub body_mass_kg: Option<f64>,
        pub bogie_mass_kg: Option<f64>,
        pub axle_inertia_kgm2: Option<f64>,
        pub wheel_radius_m: Option<f64>,
        pub bogie_pivot_distance_m: Option<f64>,
        pub bogie_wheelbase_m: Option<f64>,
        pub body_cog_height_m: Option<f64>,
        pub pivot_height_m: Option<f64>,
        pub bogie_cog_height_m: Option<f64>,
        pub brake_torque_nm_per_bar: Option<Vec<f64>>,
        pub max_brake_pressure_bar: Option<f64>,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Ingest {
        pub sample_rate_hz: Option<f64>,
        pub max_gap_ms: Option<f64>,
        #[serde(default)]
        pub plausibility: Plausibility,
        #[serde(default)]
        pub csv: CsvMapping,
        #[serde(default)]
        pub mcap: McapMapping,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Plausibility {
        pub action: Option<String>,
        pub speed_min_mps: Option<f64>,
        pub speed_max_mps: Option<f64>,
        pub omega_min_radps: Option<f64>,
        pub omega_max_radps: Option<f64>,
        pub pressure_min_bar: Option<f64>,
        pub pressure_max_bar: Option<f64>,
    }

    #[derive(Debug, Clone, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct CsvColumn {
        pub column: Option<String>,
        pub unit: Option<String>,
    }

    #[derive(Debug, Clone, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct McapField {
        pub topic: Option<String>,
        pub field: Option<String>,
        pub unit: Option<String>,
    }

    /// `[ingest.csv]`: signal key (`time`, `v_radar`, `omega1`..`omega4`, `p1`..`p4`) → column.
    pub type CsvMapping = std::collections::BTreeMap<String, CsvColumn>;
    /// `[ingest.mcap]`: signal key (`v_radar`, `omega1`..`omega4`, `p1`..`p4`) → topic/field.
    pub type McapMapping = std::collections::BTreeMap<String, McapField>;
}

/// A validated pipeline.
#[derive(Debug, Clone, PartialEq)]
pub struct Pipeline {
    /// Where it was read from (a path, or [`DEFAULT_PIPELINE_NAME`]).
    pub source: String,
    /// The exact text it was parsed from (for provenance hashes).
    pub text: String,
    pub vehicle: Vehicle,
    pub ingest: IngestConfig,
    pub filters: FilterConfig,
    pub estimate: EstimateConfig,
    pub contact: ContactConfig,
    pub train: TrainConfig,
}

/// The vehicle: masses, inertia and the geometry of the load-transfer model of seed 002
/// eq. 12–13 (002_8d8769283f5e9cb6.txt, Fig. 6).
#[derive(Debug, Clone, PartialEq)]
pub struct Vehicle {
    pub name: String,
    /// Car-body mass m_c, kg.
    pub body_mass_kg: f64,
    /// Mass of one bogie including its wheelsets m_b, kg.
    pub bogie_mass_kg: f64,
    /// Moment of inertia J of one wheelset about its axle, kg·m².
    pub axle_inertia_kgm2: f64,
    /// Wheel rolling radius r, m.
    pub wheel_radius_m: f64,
    /// Distance between bogie pivots l1, m.
    pub bogie_pivot_distance_m: f64,
    /// Bogie wheelbase l2, m.
    pub bogie_wheelbase_m: f64,
    /// Height of the car body's centre of gravity h1 above the rail, m.
    pub body_cog_height_m: f64,
    /// Height hb of the body–bogie connection above the rail, m.
    pub pivot_height_m: f64,
    /// Height of the bogie's centre of gravity h2 above the rail, m.
    pub bogie_cog_height_m: f64,
    /// Brake-torque coefficient α_i of seed 002 eq. 10 per axle, N·m/bar.
    pub brake_torque_nm_per_bar: [f64; AXLES],
    /// Highest brake-cylinder pressure the brake can apply, bar.
    pub max_brake_pressure_bar: f64,
}

/// What to do with a raw sample outside the plausibility limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlausibilityAction {
    /// Drop the sample (treated as missing, bridged only if the hole is shorter than
    /// `max_gap_ms`) and report the count as a warning.
    Warn,
    /// Reject the file with an error naming the first such sample.
    Error,
}

/// Limits on raw samples, canonical units.
#[derive(Debug, Clone, PartialEq)]
pub struct Plausibility {
    pub action: PlausibilityAction,
    pub speed_mps: (f64, f64),
    pub omega_radps: (f64, f64),
    pub pressure_bar: (f64, f64),
}

impl Plausibility {
    /// The (min, max) limits that apply to a signal, in its canonical unit.
    pub fn limits(&self, signal: Signal) -> (f64, f64) {
        match signal {
            Signal::VRadar => self.speed_mps,
            Signal::Omega(_) => self.omega_radps,
            Signal::Pressure(_) => self.pressure_bar,
        }
    }
}

/// Where a signal is in a CSV log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CsvColumn {
    pub column: String,
    pub unit: Unit,
}

/// Where a signal is in an MCAP log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct McapField {
    pub topic: String,
    pub field: String,
    pub unit: Unit,
}

#[derive(Debug, Clone, PartialEq)]
pub struct IngestConfig {
    /// Rate of the uniform time base, Hz.
    pub sample_rate_hz: f64,
    /// Longest hole in a channel that is bridged by linear interpolation, s.
    pub max_gap_s: f64,
    pub plausibility: Plausibility,
    pub csv_time: CsvColumn,
    /// CSV columns in [`Signal::ALL`] order.
    pub csv: [CsvColumn; 9],
    /// MCAP fields in [`Signal::ALL`] order.
    pub mcap: [McapField; 9],
}

impl IngestConfig {
    pub fn csv_column(&self, s: Signal) -> &CsvColumn {
        &self.csv[s.index()]
    }
    pub fn mcap_field(&self, s: Signal) -> &McapField {
        &self.mcap[s.index()]
    }
}

/// How the low-pass filters run (seed 002, "Data from test runs").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FilterMode {
    /// Forward–backward (like scipy's `sosfiltfilt` / MATLAB's `filtfilt`): no phase shift,
    /// squared magnitude response. The default for offline analysis.
    ZeroPhase,
    /// One forward pass, as in the paper: delays each signal by the filter's group delay
    /// (0.277 s at 1.5 Hz, 0.104 s at 4 Hz), which shifts slip against pressure.
    Causal,
}

impl FilterMode {
    pub fn name(self) -> &'static str {
        match self {
            FilterMode::ZeroPhase => "zero_phase",
            FilterMode::Causal => "causal",
        }
    }
}

/// `[filters]`: signal conditioning before estimation.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterConfig {
    pub mode: FilterMode,
    /// Cut-off of the radar speed's 4th-order Butterworth low-pass, Hz.
    pub radar_cutoff_hz: f64,
    /// Cut-off for the tachometers (axle angular speeds), Hz.
    pub tacho_cutoff_hz: f64,
    /// Cut-off for the brake-cylinder pressures, Hz.
    pub pressure_cutoff_hz: f64,
    /// Hampel despiking of the radar speed before the low-pass (None: off).
    pub despike: Option<DespikeConfig>,
}

/// Hampel filter parameters (radar speed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DespikeConfig {
    /// Half-width of the centred window, s.
    pub half_window_s: f64,
    /// Threshold in robust standard deviations (1.4826 × median absolute deviation).
    pub threshold: f64,
    /// Deviations from the window median at or below this are never replaced, m/s.
    pub min_deviation_mps: f64,
}

/// Which slip definition applies (seed 002 eq. 2–5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Δv = v − rω (eq. 2), slip ratio Δv / v (eq. 4).
    Braking,
    /// Δv = rω − v (eq. 3), slip ratio Δv / (rω) (eq. 5).
    Traction,
}

/// `[estimate]`: per-sample adhesion estimation and its validity mask.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateConfig {
    pub phase: Phase,
    /// Samples with a filtered vehicle speed below this are masked (slip ratio and the
    /// torque balance lose meaning towards standstill), m/s.
    pub min_speed_mps: f64,
    /// Samples whose filtered cylinder pressure is below this are masked (brake not applied), bar.
    pub min_pressure_bar: f64,
    /// A wheel whose peripheral speed rω is below this is locked: its brake torque is static
    /// friction, not αp, so the torque balance does not hold and the sample is masked, m/s.
    pub locked_wheel_speed_mps: f64,
    /// Slip velocity above which an axle counts as sliding in summaries, m/s.
    pub sliding_threshold_mps: f64,
}

/// `[contact]`: wheel–rail contact geometry and material for the Hertz patch (seed 001
/// eq. 1–5) behind the Polach fits and the models' linear creep region.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactConfig {
    /// Young's modulus E, Pa.
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio ν.
    pub poisson: f64,
    /// Lateral profile radius of the wheel, m (negative: concave).
    pub wheel_lateral_radius_m: f64,
    /// Lateral profile radius of the rail head, m.
    pub rail_lateral_radius_m: f64,
}

/// How training and validation samples are chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum SplitConfig {
    /// By axle, pooled over the runs (seed 002: train on axle 2, validate on axle 3).
    Axles { train: Vec<u8>, val: Vec<u8> },
    /// Every `every`-th run validates.
    Runs { every: usize },
    /// Every `every`-th block of `block_s` seconds validates.
    Blocks { block_s: f64, every: usize },
}

/// `[train]`: the network, its data and MATLAB trainlm's settings
/// (../shared/design/reference-values.md).
#[derive(Debug, Clone, PartialEq)]
pub struct TrainConfig {
    pub hidden: usize,
    /// Speed v as a third input.
    pub with_speed: bool,
    pub split: SplitConfig,
    /// Keep every n-th valid sample of a run and axle.
    pub decimate: usize,
    pub seed: u64,
    pub epochs: u64,
    pub goal: f64,
    pub max_fail: u32,
    pub min_grad: f64,
    pub mu: f64,
    pub mu_dec: f64,
    pub mu_inc: f64,
    pub mu_max: f64,
    /// Width of the small-slip region where the model blends from the linear creep law into
    /// the network, m/s.
    pub creep_blend_mps: f64,
    /// Polynomial degree of the k_A(T), k_S(T) fits.
    pub temperature_degree: usize,
    /// Rail condition (run metadata `condition`) whose runs train the models; None: the
    /// campaign's most common condition.
    pub condition: Option<String>,
}

impl Pipeline {
    /// The embedded default pipeline.
    pub fn default_uic_z1() -> Pipeline {
        Self::from_toml(DEFAULT_PIPELINE_TOML, DEFAULT_PIPELINE_NAME)
            .expect("the embedded default pipeline passes its own checks (tested)")
    }

    /// Loads `path`, or the embedded default when `None`.
    pub fn load(path: Option<&Path>) -> Result<Pipeline, ConfigError> {
        match path {
            None => Ok(Self::default_uic_z1()),
            Some(p) => {
                let file = p.display().to_string();
                let text = std::fs::read_to_string(p).map_err(|source| ConfigError::Read {
                    file: file.clone(),
                    source,
                })?;
                Self::from_toml(&text, &file)
            }
        }
    }

    /// Parses and checks pipeline TOML; `file` names it in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Pipeline, ConfigError> {
        let raw: raw::Pipeline = toml::from_str(text).map_err(|e| ConfigError::Syntax {
            file: file.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let c = Checker { file };
        let vehicle = c.vehicle(raw.vehicle)?;
        let ingest = c.ingest(raw.ingest)?;
        let filters = c.filters(raw.filters, ingest.sample_rate_hz)?;
        let estimate = c.estimate(raw.estimate)?;
        let contact = c.contact(raw.contact)?;
        let train = c.train(raw.train)?;
        Ok(Pipeline {
            source: file.to_string(),
            text: text.to_string(),
            vehicle,
            ingest,
            filters,
            estimate,
            contact,
            train,
        })
    }
}

/// A numeric rule: inclusive/exclusive bounds and the default, for messages.
struct Rule {
    lo: f64,
    lo_open: bool,
    hi: f64,
    hi_open: bool,
    default: Option<f64>,
    unit: &'static str,
}

impl Rule {
    fn contains(&self, x: f64) -> bool {
        x.is_finite()
            && (if self.lo_open {
                x > self.lo
            } else {
                x >= self.lo
            })
            && (if self.hi_open {
                x < self.hi
            } else {
                x <= self.hi
            })
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let lo = if self.lo_open { ">" } else { ">=" };
        let hi = if self.hi_open { "<" } else { "<=" };
        let u = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        write!(
            f,
            "must be {lo} {}{u} and {hi} {}{u}",
            g(self.lo),
            g(self.hi)
        )?;
        if let Some(d) = self.default {
            write!(f, " (default {}{u})", g(d))?;
        }
        Ok(())
    }
}

/// Shortest readable form of a number for messages.
fn g(x: f64) -> String {
    if x == x.trunc() && x.abs() < 1e15 {
        format!("{}", x as i64)
    } else {
        let s = format!("{x:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

fn closed(lo: f64, hi: f64, default: Option<f64>, unit: &'static str) -> Rule {
    Rule {
        lo,
        lo_open: false,
        hi,
        hi_open: false,
        default,
        unit,
    }
}
fn open_lo(lo: f64, hi: f64, default: Option<f64>, unit: &'static str) -> Rule {
    Rule {
        lo,
        lo_open: true,
        hi,
        hi_open: false,
        default,
        unit,
    }
}

/// Turns raw values into checked ones, naming the file in every error. Shared by pipeline and
/// scene files so both report problems the same way.
pub(crate) struct Checker<'a> {
    pub(crate) file: &'a str,
}

impl Checker<'_> {
    /// A number in the closed range [lo, hi], `default` when absent (an error when there is no
    /// default).
    pub(crate) fn num(
        &self,
        key: &str,
        v: Option<f64>,
        lo: f64,
        hi: f64,
        default: Option<f64>,
        unit: &'static str,
    ) -> Result<f64, ConfigError> {
        let rule = closed(lo, hi, default, unit);
        match (v, default) {
            (None, Some(d)) => Ok(d),
            (None, None) => Err(self.missing(key, format!("give it in {unit}, {rule}"))),
            (Some(x), _) if rule.contains(x) => Ok(x),
            (Some(x), _) => Err(self.invalid(key, g(x), rule)),
        }
    }

    pub(crate) fn invalid(
        &self,
        key: &str,
        value: impl fmt::Display,
        rule: impl fmt::Display,
    ) -> ConfigError {
        ConfigError::Invalid {
            file: self.file.to_string(),
            key: key.to_string(),
            value: value.to_string(),
            rule: rule.to_string(),
        }
    }

    fn missing(&self, key: &str, rule: impl fmt::Display) -> ConfigError {
        ConfigError::Missing {
            file: self.file.to_string(),
            key: key.to_string(),
            rule: rule.to_string(),
        }
    }

    /// A required number within `rule`; `example` is the UIC-Z1 value quoted when it is missing.
    fn required(
        &self,
        key: &str,
        v: Option<f64>,
        rule: Rule,
        example: f64,
    ) -> Result<f64, ConfigError> {
        match v {
            None => Err(self.missing(
                key,
                format!("give it in {}, {rule} (UIC-Z1: {})", rule.unit, g(example)),
            )),
            Some(x) if !rule.contains(x) => Err(self.invalid(key, g(x), rule)),
            Some(x) => Ok(x),
        }
    }

    /// An optional number within `rule`, defaulting to `rule.default`.
    fn optional(&self, key: &str, v: Option<f64>, rule: Rule) -> Result<f64, ConfigError> {
        match v {
            None => Ok(rule.default.expect("optional keys have a default")),
            Some(x) if !rule.contains(x) => Err(self.invalid(key, g(x), rule)),
            Some(x) => Ok(x),
        }
    }

    fn vehicle(&self, v: Option<raw::Vehicle>) -> Result<Vehicle, ConfigError> {
        let v = v.ok_or_else(|| {
            self.missing(
                "[vehicle]",
                "every pipeline describes its vehicle; copy the [vehicle] section of pipelines/uic_z1.toml and edit it",
            )
        })?;
        let k = |name: &str| format!("vehicle.{name}");
        let body = self.required(
            &k("body_mass_kg"),
            v.body_mass_kg,
            open_lo(1000.0, 200_000.0, None, "kg"),
            34000.0,
        )?;
        let bogie = self.required(
            &k("bogie_mass_kg"),
            v.bogie_mass_kg,
            open_lo(100.0, 50_000.0, None, "kg"),
            7000.0,
        )?;
        let j = self.required(
            &k("axle_inertia_kgm2"),
            v.axle_inertia_kgm2,
            open_lo(1.0, 2000.0, None, "kg·m²"),
            120.0,
        )?;
        let r = self.required(
            &k("wheel_radius_m"),
            v.wheel_radius_m,
            closed(0.2, 0.7, None, "m"),
            0.445,
        )?;
        let l1 = self.required(
            &k("bogie_pivot_distance_m"),
            v.bogie_pivot_distance_m,
            closed(1.0, 40.0, None, "m"),
            19.0,
        )?;
        let l2 = self.required(
            &k("bogie_wheelbase_m"),
            v.bogie_wheelbase_m,
            closed(0.5, 5.0, None, "m"),
            2.56,
        )?;
        if l2 >= l1 {
            return Err(self.invalid(
                &k("bogie_wheelbase_m"),
                g(l2),
                format!(
                    "must be shorter than vehicle.bogie_pivot_distance_m = {}",
                    g(l1)
                ),
            ));
        }
        let h1 = self.required(
            &k("body_cog_height_m"),
            v.body_cog_height_m,
            open_lo(0.0, 5.0, None, "m"),
            1.75,
        )?;
        let hb = self.required(
            &k("pivot_height_m"),
            v.pivot_height_m,
            open_lo(0.0, 5.0, None, "m"),
            0.85,
        )?;
        let h2 = self.required(
            &k("bogie_cog_height_m"),
            v.bogie_cog_height_m,
            open_lo(0.0, 5.0, None, "m"),
            0.55,
        )?;
        if hb > h1 {
            return Err(self.invalid(
                &k("pivot_height_m"),
                g(hb),
                format!(
                    "must not be above the body's centre of gravity vehicle.body_cog_height_m = {}",
                    g(h1)
                ),
            ));
        }
        let alpha_key = k("brake_torque_nm_per_bar");
        let alpha = match v.brake_torque_nm_per_bar {
            None => {
                return Err(self.missing(
                    &alpha_key,
                    "give alpha_i of seed 002 eq. 10 for axles 1..4 in N·m/bar, e.g. [1600.0, 1600.0, 1600.0, 1600.0]",
                ))
            }
            Some(a) if a.len() != AXLES => {
                return Err(self.invalid(&alpha_key, format!("{a:?}"), "must list exactly 4 values, one per axle"))
            }
            Some(a) => {
                let rule = open_lo(0.0, 100_000.0, None, "N·m/bar");
                for (i, x) in a.iter().enumerate() {
                    if !rule.contains(*x) {
                        return Err(self.invalid(&format!("{alpha_key}[{i}] (axle {})", i + 1), g(*x), rule));
                    }
                }
                [a[0], a[1], a[2], a[3]]
            }
        };
        let pmax = self.required(
            &k("max_brake_pressure_bar"),
            v.max_brake_pressure_bar,
            open_lo(0.0, 20.0, None, "bar"),
            3.8,
        )?;
        Ok(Vehicle {
            name: v.name.unwrap_or_else(|| "unnamed vehicle".to_string()),
            body_mass_kg: body,
            bogie_mass_kg: bogie,
            axle_inertia_kgm2: j,
            wheel_radius_m: r,
            bogie_pivot_distance_m: l1,
            bogie_wheelbase_m: l2,
            body_cog_height_m: h1,
            pivot_height_m: hb,
            bogie_cog_height_m: h2,
            brake_torque_nm_per_bar: alpha,
            max_brake_pressure_bar: pmax,
        })
    }

    fn choice<T: Copy>(
        &self,
        key: &str,
        v: Option<String>,
        options: &[(&str, T)],
        default: T,
    ) -> Result<T, ConfigError> {
        match v {
            None => Ok(default),
            Some(s) => options
                .iter()
                .find(|(name, _)| *name == s)
                .map(|(_, t)| *t)
                .ok_or_else(|| {
                    let names: Vec<String> =
                        options.iter().map(|(n, _)| format!("\"{n}\"")).collect();
                    self.invalid(
                        key,
                        format!("\"{s}\""),
                        format!("must be one of {}", names.join(", ")),
                    )
                }),
        }
    }

    fn filters(&self, f: raw::Filters, fs: f64) -> Result<FilterConfig, ConfigError> {
        let mode = self.choice(
            "filters.mode",
            f.mode,
            &[
                ("zero_phase", FilterMode::ZeroPhase),
                ("causal", FilterMode::Causal),
            ],
            FilterMode::ZeroPhase,
        )?;
        let cutoff = |key: &str, v: Option<f64>, default: f64| {
            let rule = Rule {
                lo: 0.0,
                lo_open: true,
                hi: fs / 2.0,
                hi_open: true,
                default: Some(default),
                unit: "Hz",
            };
            match v {
                None => Ok(default),
                Some(x) if rule.contains(x) => Ok(x),
                Some(x) => Err(self.invalid(
                    key,
                    g(x),
                    format!(
                        "{rule}; the upper bound is half of ingest.sample_rate_hz = {}",
                        g(fs)
                    ),
                )),
            }
        };
        let radar_cutoff_hz = cutoff("filters.radar_cutoff_hz", f.radar_cutoff_hz, 1.5)?;
        let tacho_cutoff_hz = cutoff("filters.tacho_cutoff_hz", f.tacho_cutoff_hz, 4.0)?;
        let pressure_cutoff_hz = cutoff("filters.pressure_cutoff_hz", f.pressure_cutoff_hz, 4.0)?;
        let half_window_s = self.optional(
            "filters.despike_half_window_s",
            f.despike_half_window_s,
            open_lo(0.0, 10.0, Some(0.025), "s"),
        )?;
        if half_window_s * fs < 1.0 {
            return Err(self.invalid(
                "filters.despike_half_window_s",
                g(half_window_s),
                format!(
                    "must span at least one sample ({} s at ingest.sample_rate_hz = {})",
                    g(1.0 / fs),
                    g(fs)
                ),
            ));
        }
        let threshold = self.optional(
            "filters.despike_threshold",
            f.despike_threshold,
            open_lo(0.0, 100.0, Some(3.0), ""),
        )?;
        let min_deviation_mps = self.optional(
            "filters.despike_min_deviation_mps",
            f.despike_min_deviation_mps,
            closed(0.0, 100.0, Some(0.5), "m/s"),
        )?;
        let despike = f.despike.unwrap_or(true).then_some(DespikeConfig {
            half_window_s,
            threshold,
            min_deviation_mps,
        });
        Ok(FilterConfig {
            mode,
            radar_cutoff_hz,
            tacho_cutoff_hz,
            pressure_cutoff_hz,
            despike,
        })
    }

    fn estimate(&self, e: raw::Estimate) -> Result<EstimateConfig, ConfigError> {
        let phase = self.choice(
            "estimate.phase",
            e.phase,
            &[("braking", Phase::Braking), ("traction", Phase::Traction)],
            Phase::Braking,
        )?;
        Ok(EstimateConfig {
            phase,
            min_speed_mps: self.optional(
                "estimate.min_speed_mps",
                e.min_speed_mps,
                open_lo(0.0, 100.0, Some(1.0), "m/s"),
            )?,
            min_pressure_bar: self.optional(
                "estimate.min_pressure_bar",
                e.min_pressure_bar,
                closed(0.0, 20.0, Some(0.2), "bar"),
            )?,
            locked_wheel_speed_mps: self.optional(
                "estimate.locked_wheel_speed_mps",
                e.locked_wheel_speed_mps,
                open_lo(0.0, 10.0, Some(0.1), "m/s"),
            )?,
            sliding_threshold_mps: self.optional(
                "estimate.sliding_threshold_mps",
                e.sliding_threshold_mps,
                open_lo(0.0, 10.0, Some(0.2), "m/s"),
            )?,
        })
    }

    pub(crate) fn contact(&self, c: raw::Contact) -> Result<ContactConfig, ConfigError> {
        Ok(ContactConfig {
            youngs_modulus_pa: self.optional(
                "contact.youngs_modulus_pa",
                c.youngs_modulus_pa,
                closed(1e9, 1e12, Some(2.1e11), "Pa"),
            )?,
            poisson: self.optional(
                "contact.poisson",
                c.poisson,
                closed(0.0, 0.49, Some(0.3), ""),
            )?,
            wheel_lateral_radius_m: self.optional(
                "contact.wheel_lateral_radius_m",
                c.wheel_lateral_radius_m,
                closed(-1e3, 1e3, Some(-0.5), "m"),
            )?,
            rail_lateral_radius_m: self.optional(
                "contact.rail_lateral_radius_m",
                c.rail_lateral_radius_m,
                closed(0.05, 1e3, Some(0.3), "m"),
            )?,
        })
    }

    fn train(&self, t: raw::Train) -> Result<TrainConfig, ConfigError> {
        let int = |key: &str,
                   v: Option<f64>,
                   lo: f64,
                   hi: f64,
                   default: f64|
         -> Result<f64, ConfigError> {
            let x = self.num(key, v, lo, hi, Some(default), "")?;
            if x.fract() != 0.0 {
                return Err(self.invalid(key, g(x), "must be a whole number"));
            }
            Ok(x)
        };
        let with_speed = match t.inputs.as_deref() {
            None => false,
            Some([a, b]) if a == "dv_mps" && b == "ddv_mps2" => false,
            Some([a, b, c]) if a == "dv_mps" && b == "ddv_mps2" && c == "v_mps" => true,
            Some(other) => {
                return Err(self.invalid(
                    "train.inputs",
                    format!("{other:?}"),
                    "must be [\"dv_mps\", \"ddv_mps2\"] (seed 002) or [\"dv_mps\", \"ddv_mps2\", \"v_mps\"]",
                ))
            }
        };
        let every = int("train.val_every", t.val_every, 2.0, 1000.0, 4.0)? as usize;
        let axles = |key: &str, v: Option<Vec<u8>>, default: u8| -> Result<Vec<u8>, ConfigError> {
            let v = v.unwrap_or_else(|| vec![default]);
            if v.is_empty() || v.iter().any(|a| !(1..=AXLES as u8).contains(a)) {
                return Err(self.invalid(key, format!("{v:?}"), "must list axles 1..4"));
            }
            Ok(v)
        };
        let split = match t.split.as_deref().unwrap_or("axles") {
            "axles" => {
                let train = axles("train.train_axles", t.train_axles, 2)?;
                let val = axles("train.val_axles", t.val_axles, 3)?;
                if let Some(a) = train.iter().find(|a| val.contains(a)) {
                    return Err(self.invalid(
                        "train.val_axles",
                        format!("{val:?}"),
                        format!(
                            "must not repeat a training axle (axle {a} is in train.train_axles)"
                        ),
                    ));
                }
                SplitConfig::Axles { train, val }
            }
            "runs" => SplitConfig::Runs { every },
            "blocks" => SplitConfig::Blocks {
                block_s: self.optional(
                    "train.block_s",
                    t.block_s,
                    open_lo(0.0, 3600.0, Some(5.0), "s"),
                )?,
                every,
            },
            other => {
                return Err(self.invalid(
                    "train.split",
                    format!("\"{other}\""),
                    "must be one of \"axles\", \"runs\", \"blocks\"",
                ))
            }
        };
        let mu_dec = self.num("train.mu_dec", t.mu_dec, 1e-6, 0.999, Some(0.1), "")?;
        let mu_inc = self.num("train.mu_inc", t.mu_inc, 1.001, 1e6, Some(10.0), "")?;
        Ok(TrainConfig {
            hidden: int("train.hidden", t.hidden, 1.0, 200.0, 10.0)? as usize,
            with_speed,
            split,
            decimate: int("train.decimate", t.decimate, 1.0, 1000.0, 4.0)? as usize,
            seed: t.seed.unwrap_or(1),
            epochs: int("train.epochs", t.epochs, 1.0, 1e6, 1000.0)? as u64,
            goal: self.num("train.goal", t.goal, 0.0, 1.0, Some(0.0), "")?,
            max_fail: int("train.max_fail", t.max_fail, 1.0, 1e6, 6.0)? as u32,
            min_grad: self.num("train.min_grad", t.min_grad, 0.0, 1.0, Some(1e-7), "")?,
            mu: self.num("train.mu", t.mu, 1e-12, 1e6, Some(1e-3), "")?,
            mu_dec,
            mu_inc,
            mu_max: self.num("train.mu_max", t.mu_max, 1.0, 1e20, Some(1e10), "")?,
            creep_blend_mps: self.num(
                "train.creep_blend_mps",
                t.creep_blend_mps,
                1e-3,
                5.0,
                Some(0.2),
                "m/s",
            )?,
            temperature_degree: int(
                "train.temperature_degree",
                t.temperature_degree,
                0.0,
                5.0,
                2.0,
            )? as usize,
            condition: match t.condition {
                Some(c) if c.trim().is_empty() => {
                    return Err(self.invalid(
                        "train.condition",
                        "\"\"",
                        "a rail condition as in the runs' metadata, e.g. \"soap\"; leave the key out for the most common one",
                    ))
                }
                c => c,
            },
        })
    }

    fn ingest(&self, i: raw::Ingest) -> Result<IngestConfig, ConfigError> {
        let fs = self.optional(
            "ingest.sample_rate_hz",
            i.sample_rate_hz,
            closed(1.0, 100_000.0, Some(417.0), "Hz"),
        )?;
        let period_ms = 1000.0 / fs;
        let gap_rule = Rule {
            lo: period_ms,
            lo_open: true,
            hi: 10_000.0,
            hi_open: false,
            default: Some(50.0),
            unit: "ms",
        };
        let max_gap_ms = match i.max_gap_ms {
            None if gap_rule.contains(50.0) => 50.0,
            None => {
                return Err(self.missing(
                    "ingest.max_gap_ms",
                    format!(
                    "the default 50 ms is not longer than one sample period at {} Hz; {gap_rule}",
                    g(fs)
                ),
                ))
            }
            Some(x) if !gap_rule.contains(x) => {
                return Err(self.invalid(
                    "ingest.max_gap_ms",
                    g(x),
                    format!("{gap_rule}; the lower bound is one sample period"),
                ))
            }
            Some(x) => x,
        };
        let plausibility = self.plausibility(i.plausibility)?;

        let signal_keys: Vec<&str> = Signal::ALL.iter().map(|s| s.key()).collect();
        if let Some(k) = i
            .csv
            .keys()
            .find(|k| k.as_str() != "time" && !signal_keys.contains(&k.as_str()))
        {
            return Err(self.invalid(
                &format!("ingest.csv.{k}"),
                "{ … }",
                format!(
                    "unknown signal; the signals are time, {}",
                    signal_keys.join(", ")
                ),
            ));
        }
        if let Some(k) = i.mcap.keys().find(|k| !signal_keys.contains(&k.as_str())) {
            return Err(self.invalid(
                &format!("ingest.mcap.{k}"),
                "{ … }",
                format!("unknown signal; the signals are {}", signal_keys.join(", ")),
            ));
        }
        let csv_time = self.csv_column(
            "ingest.csv.time",
            i.csv.get("time"),
            crate::format::CSV_TIME_COLUMN,
            Quantity::Time,
        )?;
        let mut csv = Vec::with_capacity(9);
        let mut mcap = Vec::with_capacity(9);
        for s in Signal::ALL {
            csv.push(self.csv_column(
                &format!("ingest.csv.{}", s.key()),
                i.csv.get(s.key()),
                s.key(),
                s.quantity(),
            )?);
            mcap.push(self.mcap_field(
                &format!("ingest.mcap.{}", s.key()),
                i.mcap.get(s.key()),
                s,
            )?);
        }
        Ok(IngestConfig {
            sample_rate_hz: fs,
            max_gap_s: max_gap_ms * 1e-3,
            plausibility,
            csv_time,
            csv: csv.try_into().expect("nine signals"),
            mcap: mcap.try_into().expect("nine signals"),
        })
    }

    fn plausibility(&self, p: raw::Plausibility) -> Result<Plausibility, ConfigError> {
        let action = match p.action.as_deref() {
            None | Some("warn") => PlausibilityAction::Warn,
            Some("error") => PlausibilityAction::Error,
            Some(other) => {
                return Err(self.invalid(
                    "ingest.plausibility.action",
                    format!("{other:?}"),
                    "must be \"warn\" or \"error\" (default \"warn\")",
                ))
            }
        };
        let pair = |lo_key: &str,
                    lo: Option<f64>,
                    lo_def: f64,
                    hi_key: &str,
                    hi: Option<f64>,
                    hi_def: f64,
                    unit| {
            let k_lo = format!("ingest.plausibility.{lo_key}");
            let k_hi = format!("ingest.plausibility.{hi_key}");
            let lo = self.optional(&k_lo, lo, closed(-1e6, 1e6, Some(lo_def), unit))?;
            let hi = self.optional(&k_hi, hi, closed(-1e6, 1e6, Some(hi_def), unit))?;
            if lo >= hi {
                return Err(self.invalid(
                    &k_hi,
                    g(hi),
                    format!("must be greater than {k_lo} = {}", g(lo)),
                ));
            }
            Ok((lo, hi))
        };
        Ok(Plausibility {
            action,
            speed_mps: pair(
                "speed_min_mps",
                p.speed_min_mps,
                -0.5,
                "speed_max_mps",
                p.speed_max_mps,
                100.0,
                "m/s",
            )?,
            omega_radps: pair(
                "omega_min_radps",
                p.omega_min_radps,
                -0.5,
                "omega_max_radps",
                p.omega_max_radps,
                250.0,
                "rad/s",
            )?,
            pressure_bar: pair(
                "pressure_min_bar",
                p.pressure_min_bar,
                -0.5,
                "pressure_max_bar",
                p.pressure_max_bar,
                10.0,
                "bar",
            )?,
        })
    }

    fn unit(&self, key: &str, text: Option<&str>, q: Quantity) -> Result<Unit, ConfigError> {
        let Some(text) = text else {
            return Ok(q.canonical());
        };
        Unit::parse(q, text).ok_or_else(|| {
            self.invalid(
                &format!("{key}.unit"),
                format!("{text:?}"),
                format!(
                    "unknown {q} unit; use one of {} (default \"{}\")",
                    q.accepted()
                        .iter()
                        .map(|u| format!("\"{u}\""))
                        .collect::<Vec<_>>()
                        .join(", "),
                    q.canonical()
                ),
            )
        })
    }

    fn name(&self, key: &str, v: Option<&str>, default: &str) -> Result<String, ConfigError> {
        match v {
            None => Ok(default.to_string()),
            Some(s) if s.trim().is_empty() => Err(self.invalid(
                key,
                "\"\"",
                format!("must not be empty (default \"{default}\")"),
            )),
            Some(s) => Ok(s.to_string()),
        }
    }

    fn csv_column(
        &self,
        key: &str,
        r: Option<&raw::CsvColumn>,
        default: &str,
        q: Quantity,
    ) -> Result<CsvColumn, ConfigError> {
        Ok(CsvColumn {
            column: self.name(
                &format!("{key}.column"),
                r.and_then(|r| r.column.as_deref()),
                default,
            )?,
            unit: self.unit(key, r.and_then(|r| r.unit.as_deref()), q)?,
        })
    }

    fn mcap_field(
        &self,
        key: &str,
        r: Option<&raw::McapField>,
        s: Signal,
    ) -> Result<McapField, ConfigError> {
        Ok(McapField {
            topic: self.name(
                &format!("{key}.topic"),
                r.and_then(|r| r.topic.as_deref()),
                s.mcap_topic(),
            )?,
            field: self.name(
                &format!("{key}.field"),
                r.and_then(|r| r.field.as_deref()),
                s.mcap_field(),
            )?,
            unit: self.unit(key, r.and_then(|r| r.unit.as_deref()), s.quantity())?,
        })
    }
}

/// Checks a raw `[vehicle]` table (shared by pipeline and scene files); `file` names it in
/// errors.
pub fn check_vehicle(v: raw::Vehicle, file: &str) -> Result<Vehicle, ConfigError> {
    Checker { file }.vehicle(Some(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with_vehicle(extra: &str) -> String {
        let base = DEFAULT_PIPELINE_TOML;
        format!("{base}\n{extra}")
    }

    #[test]
    fn embedded_default_passes_its_checks_with_contract_names() {
        let p = Pipeline::default_uic_z1();
        assert_eq!(p.vehicle.wheel_radius_m, 0.445);
        assert_eq!(p.vehicle.brake_torque_nm_per_bar, [1600.0; 4]);
        assert_eq!(p.ingest.sample_rate_hz, 417.0);
        assert!((p.ingest.max_gap_s - 0.05).abs() < 1e-15);
        for s in Signal::ALL {
            assert_eq!(p.ingest.csv_column(s).column, s.key());
            assert_eq!(p.ingest.mcap_field(s).topic, s.mcap_topic());
            assert_eq!(p.ingest.mcap_field(s).field, s.mcap_field());
            assert_eq!(p.ingest.csv_column(s).unit, s.quantity().canonical());
        }
    }

    #[test]
    fn a_minimal_file_gets_contract_defaults_for_ingest() {
        let vehicle_only: String = DEFAULT_PIPELINE_TOML
            .split("[ingest]")
            .next()
            .unwrap()
            .to_string();
        let p = Pipeline::from_toml(&vehicle_only, "v.toml").unwrap();
        assert_eq!(p.ingest, Pipeline::default_uic_z1().ingest);
    }

    #[test]
    fn out_of_range_value_names_key_value_range_and_default() {
        let text = DEFAULT_PIPELINE_TOML.replace("max_gap_ms = 50.0", "max_gap_ms = -5.0");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "p.toml: ingest.max_gap_ms = -5: must be > 2.3981 ms and <= 10000 ms (default 50 ms); the lower bound is one sample period"
        );
    }

    #[test]
    fn bad_filter_estimate_contact_and_train_keys_name_the_key_and_the_rule() {
        let err = |from: &str, to: &str| {
            assert!(DEFAULT_PIPELINE_TOML.contains(from), "{from}");
            Pipeline::from_toml(&DEFAULT_PIPELINE_TOML.replace(from, to), "p.toml")
                .unwrap_err()
                .to_string()
        };
        let cases = [
            (
                "mode = \"zero_phase\"",
                "mode = \"acausal\"",
                "p.toml: filters.mode = \"acausal\": must be one of \"zero_phase\", \"causal\"",
            ),
            (
                "despike_half_window_s = 0.025",
                "despike_half_window_s = 0.001",
                "filters.despike_half_window_s = 0.001: must span at least one sample",
            ),
            (
                "phase = \"braking\"",
                "phase = \"coasting\"",
                "estimate.phase = \"coasting\": must be one of \"braking\", \"traction\"",
            ),
            (
                "min_speed_mps = 1.0",
                "min_speed_mps = 0.0",
                "estimate.min_speed_mps = 0: must be > 0 m/s",
            ),
            (
                "poisson = 0.3",
                "poisson = 0.5",
                "contact.poisson = 0.5: must be >= 0 and <= 0.49",
            ),
            (
                "split = \"axles\"",
                "split = \"random\"",
                "train.split = \"random\": must be one of \"axles\", \"runs\", \"blocks\"",
            ),
            (
                "val_axles = [3]",
                "val_axles = [2]",
                "train.val_axles = [2]: must not repeat a training axle",
            ),
            (
                "train_axles = [2]",
                "train_axles = [5]",
                "train.train_axles = [5]: must list axles 1..4",
            ),
            (
                "inputs = [\"dv_mps\", \"ddv_mps2\"]",
                "inputs = [\"v_mps\"]",
                "train.inputs = [\"v_mps\"]: must be [\"dv_mps\", \"ddv_mps2\"]",
            ),
            (
                "hidden = 10",
                "hidden = 2.5",
                "train.hidden = 2.5: must be a whole number",
            ),
            (
                "mu_dec = 0.1",
                "mu_dec = 1.5",
                "train.mu_dec = 1.5: must be >= 0",
            ),
            (
                "# condition = \"soap\"",
                "condition = \"\"",
                "train.condition = \"\": a rail condition as in the runs' metadata",
            ),
        ];
        for (from, to, want) in cases {
            let e = err(from, to);
            assert!(e.contains(want), "{to}: {e}");
        }
    }

    #[test]
    fn implausible_vehicle_is_rejected() {
        let text = DEFAULT_PIPELINE_TOML.replace("wheel_radius_m = 0.445", "wheel_radius_m = 4.45");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "p.toml: vehicle.wheel_radius_m = 4.45: must be >= 0.2 m and <= 0.7 m"
        );
        let text = DEFAULT_PIPELINE_TOML
            .replace("bogie_wheelbase_m = 2.56", "bogie_wheelbase_m = 4.0")
            .replace(
                "bogie_pivot_distance_m = 19.0",
                "bogie_pivot_distance_m = 3.0",
            );
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("vehicle.bogie_wheelbase_m = 4: must be shorter than"),
            "{e}"
        );
        let text = DEFAULT_PIPELINE_TOML.replace(
            "[1600.0, 1600.0, 1600.0, 1600.0]",
            "[1600.0, 1600.0, -1.0, 1600.0]",
        );
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("vehicle.brake_torque_nm_per_bar[2] (axle 3) = -1"),
            "{e}"
        );
    }

    #[test]
    fn missing_vehicle_key_quotes_the_uic_z1_value() {
        let text = DEFAULT_PIPELINE_TOML.replace("axle_inertia_kgm2 = 120.0", "");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "p.toml: vehicle.axle_inertia_kgm2 is missing: give it in kg·m², must be > 1 kg·m² and <= 2000 kg·m² (UIC-Z1: 120)"
        );
    }

    #[test]
    fn unknown_unit_lists_the_accepted_ones() {
        let text = with_vehicle("");
        let text = text.replace(
            r#"v_radar = { column = "v_radar", unit = "m/s" }"#,
            r#"v_radar = { column = "speed", unit = "mph" }"#,
        );
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            r#"p.toml: ingest.csv.v_radar.unit = "mph": unknown speed unit; use one of "m/s", "km/h" (default "m/s")"#
        );
    }

    #[test]
    fn unknown_keys_and_bad_actions_are_rejected() {
        let text =
            DEFAULT_PIPELINE_TOML.replace("max_gap_ms = 50.0", "max_gap_ms = 50.0\nmax_gapp = 3");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("p.toml: not a valid pipeline file:") && e.contains("max_gapp"),
            "{e}"
        );
        let text = DEFAULT_PIPELINE_TOML.replace(r#"action = "warn""#, r#"action = "ignore""#);
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            r#"p.toml: ingest.plausibility.action = "ignore": must be "warn" or "error" (default "warn")"#
        );
    }

    #[test]
    fn misspelled_signal_in_a_mapping_is_named() {
        let text = DEFAULT_PIPELINE_TOML.replace("omega4 = { column", "omgea4 = { column");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("p.toml: ingest.csv.omgea4 = { … }: unknown signal; the signals are time, v_radar, omega1"), "{e}");
    }

    #[test]
    fn missing_file_error_names_the_file() {
        let e = Pipeline::load(Some(Path::new("/nonexistent/p.toml")))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("/nonexistent/p.toml: cannot read the pipeline file"),
            "{e}"
        );
    }
}
