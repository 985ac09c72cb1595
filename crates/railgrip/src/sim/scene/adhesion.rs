//! `[adhesion]`: the truth law (Polach's, a model file, or a law outside the fitted
//! families) and its effects' parameters.

use std::path::Path;

use super::laws::{
    fastsim_law, loss_recovery, slip_table, FastsimLaw, FASTSIM_ALPHA_INF, FASTSIM_BETA,
    FASTSIM_BOUND, FASTSIM_GRID, FASTSIM_K0, LEVEL_SCALE, LOSS_PEAK, LOSS_RESIDUAL, LOSS_SLIP,
    PEAK_SPEED, PEAK_SPEED_FORM, PEAK_TEMPERATURE, RECOVERY_PEAK, RECOVERY_RESIDUAL, RECOVERY_SLIP,
    TABLE_MU, TABLE_SLIPS, TABLE_SPEEDS,
};
use super::text;
use super::thermal::{
    ThermalParams, THERMAL_CAPACITY, THERMAL_COOLING, THERMAL_PARTITION, THERMAL_PRESSURE,
    THERMAL_REFERENCE, THERMAL_RESIDUAL, THERMAL_SCALE, THERMAL_UPDATE,
};
use crate::config::rule::{closed, Checker, Default, Key, Range};
use crate::config::ConfigError;
use crate::contact::polach::{PolachParams, TemperatureLaw};

pub mod raw {
    use serde::Deserialize;

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
        pub peak_speed_form: Option<String>,
        pub level_scale: Option<f64>,
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
    /// ([`crate::sim::foreign::LossRecovery`]): a law outside the families railgrip fits. Carries its
    /// own speed dependence and branches, so falling_friction, hysteresis and cleaning may not
    /// be listed; `temperature` scales its peaks.
    LossRecovery(crate::sim::foreign::LossRecovery),
    /// μ(Δv) tabulated per speed ([`crate::sim::foreign::SlipTable`]): a sharp peak and a plateau.
    /// No effect of the Polach law may be listed, nor `temperature`.
    Table(crate::sim::foreign::SlipTable),
    /// Kalker's FASTSIM ([`crate::contact::fastsim`]) on the wheel's Hertz patch (at the static
    /// load; with `load_transfer` listed it follows the wheel's load), with Polach's falling
    /// friction μ0[(1 − A)e^(−Bw) + A] (`mu0`, `a_ratio`, `b_s_per_m`) and optionally the modified FASTSIM's stiffness reduction. Carries its own
    /// friction law, so falling_friction, hysteresis, cleaning and temperature may not be listed.
    Fastsim(FastsimLaw),
}

impl AdhesionLaw {
    /// The run's rail condition: `loss_recovery`'s `level_scale`, which multiplies both peaks,
    /// so μ is proportional to it (docs/simulator.md#foreign-laws); other laws have none.
    pub fn level_scale(&self) -> Option<f64> {
        match self {
            AdhesionLaw::LossRecovery(l) => Some(l.level_scale),
            _ => None,
        }
    }

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

pub(super) const LAW: Key = Key {
    name: "adhesion.law",
    unit: "",
    range: Range::Choice(&["polach", "model", "loss_recovery", "table", "fastsim"]),
    default: Default::Text("\"polach\""),
    meaning: "Polach's law with the listed effects; `\"model\"` with `model = \"file.json\"`: a model file from `railgrip train` (path relative to the scene) drives the wheels, its slip-rate input lagged by `hysteresis_time_constant_s`; `\"loss_recovery\"` and `\"table\"`: laws outside the families railgrip fits (truth for testing identification; docs/simulator.md#foreign-laws); `\"fastsim\"`: Kalker's FASTSIM with Polach's falling friction (mu0, a_ratio, b_s_per_m). With any but polach, falling_friction, hysteresis and cleaning may not be listed; `temperature` only for a Polach model with a temperature law, a network with the input ambient_temperature_c (it takes run.ambient_temperature_c; without the effect, its reference temperature) or loss_recovery",
};
pub(super) const MODEL: Key = text(
    "adhesion.model",
    "",
    "a model file",
    "–",
    "with `law = \"model\"`",
);
pub(super) const MU0: Key = Key::num(
    "adhesion.mu0",
    "",
    closed(0.005, 1.5),
    0.085,
    "Polach μ0 of soap-contaminated rail [assumed, tuned to seed 002 Fig. 7–8]",
);
pub(super) const A_RATIO: Key = Key::num(
    "adhesion.a_ratio",
    "",
    closed(0.01, 1.0),
    0.4,
    "Polach A = μ∞/μ0 [assumed]",
);
pub(super) const B: Key = Key::num(
    "adhesion.b_s_per_m",
    "s/m",
    closed(0.0, 10.0),
    0.3,
    "Polach B, friction falling with slip velocity [assumed]",
);
pub(super) const K_A: Key = Key::num(
    "adhesion.k_a",
    "",
    closed(1e-4, 1.0),
    0.1,
    "Polach k_A at +20 °C [assumed]",
);
pub(super) const K_S: Key = Key::num(
    "adhesion.k_s",
    "",
    closed(1e-5, 1.0),
    0.05,
    "Polach k_S at +20 °C, at most k_A [assumed]",
);
pub(super) const SPEED_COEFFICIENT: Key = Key::num(
    "adhesion.speed_coefficient",
    "",
    closed(-2.0, 2.0),
    0.25,
    "`falling_friction`: μ0 × (1 + c (v_ref − v)/v_ref)",
);
pub(super) const REFERENCE_SPEED: Key = Key::num(
    "adhesion.reference_speed_kmh",
    "km/h",
    closed(1.0, 400.0),
    120.0,
    "v_ref of the speed dependence",
);
pub(super) const HYSTERESIS_DEPTH: Key = Key::num(
    "adhesion.hysteresis_depth",
    "",
    closed(0.0, 0.9),
    0.3,
    "`hysteresis`: recovery branch lower by this fraction",
);
pub(super) const HYSTERESIS_DDV: Key = Key::num(
    "adhesion.hysteresis_ddv_mps2",
    "m/s²",
    closed(1e-3, 100.0),
    0.5,
    "slip rate scale of the branch blend",
);
pub(super) const HYSTERESIS_TAU: Key = Key::num(
    "adhesion.hysteresis_time_constant_s",
    "s",
    closed(1e-3, 10.0),
    0.02,
    "lag of the branch factor (and of a model's slip-rate input)",
);
pub(super) const CLEANING: Key = Key::num(
    "adhesion.cleaning_per_axle",
    "",
    closed(0.0, 2.0),
    0.05,
    "`cleaning`: axle i's μ × (1 + this·(i − 1))",
);
pub(super) const TEMPERATURE_K_A: Key = text(
    "adhesion.temperature_k_a",
    "",
    "coefficients, ascending powers of T in °C",
    "k20·(1 + 0.015u − 1.875e-4u²), u = 20 − T",
    "`temperature`: k_A(T) [assumed shape of seed 004's trend]",
);
pub(super) const TEMPERATURE_K_S: Key = text(
    "adhesion.temperature_k_s",
    "",
    "coefficients, ascending powers of T in °C",
    "the same shape from k_s",
    "`temperature`: k_S(T) [assumed]",
);
pub(super) const TEMPERATURE_RANGE: Key = text(
    "adhesion.temperature_range_c",
    "°C",
    "[lo, hi]",
    "[−40, 20]",
    "where the k(T) polynomials hold",
);

/// The keys of `[adhesion]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
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
    &PEAK_SPEED_FORM,
    &LEVEL_SCALE,
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

impl Checker<'_> {
    /// `[adhesion]` checked.
    pub(crate) fn adhesion(
        &self,
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
                return Err(self.invalid(
                    MODEL.name,
                    "missing",
                    "law = \"model\" needs model = \"file.json\"",
                ))
            }
            (Some("loss_recovery"), None) => AdhesionLaw::LossRecovery(loss_recovery(self, a)?),
            (Some("table"), None) => AdhesionLaw::Table(slip_table(self, a)?),
            (Some("fastsim"), None) => AdhesionLaw::Fastsim(fastsim_law(self, a)?),
            (Some(other), None) if other != "polach" => {
                return Err(self.invalid(
                    LAW.name,
                    format!("{other:?}"),
                    "must be one of \"polach\", \"model\", \"loss_recovery\", \"table\", \"fastsim\" (default \"polach\")",
                ))
            }
            _ => return Err(self.invalid(MODEL.name, "given", "only with law = \"model\"")),
        };
        let lr_given = [
            a.loss_peak_mu,
            a.loss_peak_slip_mps,
            a.loss_residual,
            a.recovery_peak_mu,
            a.recovery_peak_slip_mps,
            a.recovery_residual,
            a.peak_speed_coefficient,
            a.level_scale,
            a.peak_temperature_coefficient_per_k,
        ]
        .iter()
        .any(Option::is_some)
            || a.peak_speed_form.is_some();
        if lr_given && !matches!(law, AdhesionLaw::LossRecovery(_)) {
            return Err(self.invalid(
                "adhesion.loss_*/recovery_*/peak_*",
                "given",
                "only with law = \"loss_recovery\"",
            ));
        }
        let table_given =
            a.table_speeds_kmh.is_some() || a.table_slips_mps.is_some() || a.table_mu.is_some();
        if table_given && !matches!(law, AdhesionLaw::Table(_)) {
            return Err(self.invalid("adhesion.table_*", "given", "only with law = \"table\""));
        }
        let fastsim_given = a.fastsim_grid.is_some()
            || a.fastsim_bound.is_some()
            || a.fastsim_k0.is_some()
            || a.fastsim_alpha_inf.is_some()
            || a.fastsim_beta.is_some();
        if fastsim_given && !matches!(law, AdhesionLaw::Fastsim(_)) {
            return Err(self.invalid("adhesion.fastsim_*", "given", "only with law = \"fastsim\""));
        }
        // Soap-contaminated rail (seed 002 Fig. 7–8: μ 0.02–0.10, peak at ~1 m/s slip).
        let polach = PolachParams {
            mu0: self.value(&MU0, a.mu0)?,
            a_ratio: self.value(&A_RATIO, a.a_ratio)?,
            b_s_per_m: self.value(&B, a.b_s_per_m)?,
            k_a: self.value(&K_A, a.k_a)?,
            k_s: self.value(&K_S, a.k_s)?,
        };
        polach
            .check()
            .map_err(|e| self.invalid("adhesion", "k_a/k_s", e.to_string()))?;
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
        .map_err(|e| self.invalid("adhesion.temperature_*", "", e.to_string()))?;
        Ok(AdhesionSection {
            law,
            polach,
            speed_coefficient: self.value(&SPEED_COEFFICIENT, a.speed_coefficient)?,
            reference_speed_mps: self.value(&REFERENCE_SPEED, a.reference_speed_kmh)? / 3.6,
            hysteresis_depth: self.value(&HYSTERESIS_DEPTH, a.hysteresis_depth)?,
            hysteresis_ddv_mps2: self.value(&HYSTERESIS_DDV, a.hysteresis_ddv_mps2)?,
            hysteresis_time_constant_s: self
                .value(&HYSTERESIS_TAU, a.hysteresis_time_constant_s)?,
            cleaning_per_axle: self.value(&CLEANING, a.cleaning_per_axle)?,
            temperature_law,
            thermal: self.thermal(a)?,
        })
    }
}

/// Default k(T) shape when a scene gives none: k(T) = k20·(1 + 0.015 u − 1.875e-4 u²) with
/// u = 20 − T (°C), over −40…20 °C: ×1.225 at 0 °C, a peak of ×1.30 at −20 °C and ×1.225 at
/// −40 °C — seed 004's trend (adhesion rises from +20 °C to −20 °C and dips slightly towards
/// −40 °C). railgrip's assumption, not published coefficients.
pub(super) fn default_k_temperature(k20: f64) -> Vec<f64> {
    // Expand k20 (1 + a u + b u²), u = 20 − T, into ascending powers of T.
    let (a, b) = (0.015, -1.875e-4);
    vec![
        k20 * (1.0 + 20.0 * a + 400.0 * b),
        k20 * (-a - 40.0 * b),
        k20 * b,
    ]
}
