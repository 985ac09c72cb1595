//! Model files of kind `polach`: Polach's creep-force law with falling friction (seed 004
//! 004_7d175079b70fb95b.txt eq. 1–2; Polach, Wear 258 (2005) 992–1000) and, when fitted over
//! several ambient temperatures, a temperature law: k_A(T) and k_S(T) (seed 004 eq. 3) and/or
//! μ0(T) (the adhesion level moving with temperature, seed 004 Fig. 2), in the form the fit
//! chose by BIC (`identify::polach::fit_temperature_forms`), written by `identify::export`.
//!
//! Evaluation ([`super::Model::mu_vt`], and the C header step for step), μ = F/Q of one wheel:
//! 1. w = |Δv| (m/s); w = 0 gives μ = 0. Speed v (m/s): NaN → the reference speed (median of the
//!    fitted samples), below [`MIN_SPEED_MPS`] → that floor (the creepage w/v grows without
//!    bound as v → 0 and μ tends to the friction coefficient; the floor keeps it finite).
//! 2. μ0, k_A, k_S: the file's values, or with a temperature law and a finite T,
//!    k_A(T), k_S(T) = Σ c_i T^i (Horner, T clamped to the fitted range), and μ0(T) likewise
//!    when the law has μ0 coefficients (else the file's μ0). With a speed law ([`SpeedSpec`]),
//!    μ0 × g(v), v (after step 1) clamped to the law's fitted range: the adhesion level falling
//!    with rolling speed (seed 002 Fig. 8), which Polach's law alone does not have — it makes
//!    μ fall with slip velocity only (seed 004 eq. 2).
//! 3. μ_w = μ0 [(1 − A) e^(−B w) + A]; ε = K (w / v_s) / μ_w with K = π G a b c11 / (4 Q)
//!    (eq. 2 with C = (3/8)(G/a) c11, the creepage s = w/v_s and the wheel load Q of the fit);
//!    v_s is the speed after step 1 (Polach's creepage), or the file's `creepage_speed_mps`
//!    where the fit chose the slip-velocity form ([`PolachSpec::creepage_speed_mps`]);
//!    μ = sign(Δv) · (2 μ_w / π) [k_A ε / (1 + (k_A ε)²) + arctan(k_S ε)] (eq. 1).
//!
//! dΔv/dt is not an input of this law (it is accepted and ignored, so simulators call either
//! kind the same way). Inputs outside the fitted domain are evaluated by the law
//! (`outside_domain = "law"`), except the temperature, which is clamped.

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use super::{Defect, ModelFile};
use railgrip_contact::polach::{horner, PolachParams};

/// Name of the optional third input of a Polach model with a temperature law.
pub const TEMPERATURE_INPUT: &str = "ambient_temperature_c";

/// Most coefficients of a temperature-law polynomial: k_S(T) = k_A(T) · (k_S/k_A)(T) of
/// degrees up to 5 each (`train.temperature_degree` ≤ 5) has 11.
pub const MAX_COEFFICIENTS: usize = 11;

/// Speeds below this (m/s) are evaluated at this speed.
pub const MIN_SPEED_MPS: f64 = 0.1;

/// Points of the fitted temperature range at which a temperature law is checked to keep
/// 0 < k_S(T) ≤ k_A(T) ≤ 1.
const TEMPERATURE_CHECKS: usize = 1001;

/// Parameters of a `polach` model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PolachSpec {
    /// μ0, friction coefficient at zero slip velocity (–).
    pub mu0: f64,
    /// A = μ∞/μ0 (–).
    pub a_ratio: f64,
    /// B, exponential decrease of friction with slip velocity (s/m).
    pub b_s_per_m: f64,
    /// k_A, k_S: reduction factors in the areas of adhesion and slip (–).
    pub k_a: f64,
    pub k_s: f64,
    /// Standard errors of (μ0, A, B, k_A, k_S) from the fit's covariance; null where a
    /// parameter is not identifiable from the data.
    pub standard_errors: [Option<f64>; 5],
    /// The Hertz patch of one wheel at the static wheel load.
    pub patch: PatchSpec,
    /// Q, the static wheel load the fit used (N).
    pub wheel_load_n: f64,
    /// Speed used when the caller gives none (m/s).
    pub reference_speed_mps: f64,
    /// k_A(T), k_S(T) when fitted over two or more ambient temperatures.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature: Option<TemperatureSpec>,
    /// μ0's speed law g(v), when the fit chose one (an older railgrip refuses the file by its
    /// unknown field rather than evaluating it without).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<SpeedSpec>,
    /// The speed v_s the creepage s = w/v_s is taken at (m/s). Absent: the rolling speed v —
    /// Polach's creepage (seed 004 eq. 2), whose creep slope per m/s of slip falls as 1/v.
    /// Given: this fixed speed (the fit's reference speed) — the slip-velocity form, whose
    /// slope per m/s of slip is the same at every speed, as in adhesion curves measured over
    /// slip velocity (seed 002 Fig. 8); chosen by BIC against Polach's
    /// (`identify::polach::fit_campaign`). An older railgrip refuses a file with it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub creepage_speed_mps: Option<f64>,
}

/// Curtius–Kniffler's speed constant, m/s: their μ(v) = 7.5/(v + 44) + 0.161, v in km/h.
pub const CURTIUS_KNIFFLER_SPEED_MPS: f64 = 44.0 / 3.6;

/// Most coefficients of a polynomial speed law.
pub const MAX_SPEED_COEFFICIENTS: usize = 3;

/// Points of the fitted speed range at which a speed law is checked.
const SPEED_CHECKS: usize = 1001;

/// The adhesion level's speed law: μ0(v[, T]) = μ0[(T)] · g(v), g(v) = 1 + Σ_j c_j φ_j(v),
/// g(v_ref) = 1 at the file's reference speed v_ref (m/s).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedSpec {
    /// `"polynomial"`: φ_j = u^j, u = v/v_ref − 1, j = 1 … n (n ≤ 3);
    /// `"curtius_kniffler"`: one φ = (v_ref + v_c)/(v + v_c) − 1 with v_c = 44 km/h — the
    /// shape of Curtius & Kniffler's 7.5/(v + 44) + 0.161 (Elektrische Bahnen 20 (1950)),
    /// its level and depth fitted.
    pub form: String,
    /// c_1 … c_n (–).
    pub coefficients: Vec<f64>,
    /// The speeds the fit covers (m/s); v outside is clamped to it.
    pub fitted_range_mps: [f64; 2],
}

impl SpeedSpec {
    /// g(v) at speed `v` (m/s) with the file's reference speed `v_ref` (m/s), as the evaluator
    /// computes it.
    pub fn factor(&self, v_ref: f64, v: f64) -> f64 {
        SpeedEval::new(self, v_ref).factor(v)
    }
}

/// A checked speed law for evaluation.
#[derive(Debug, Clone)]
pub(crate) struct SpeedEval {
    kneed: bool,
    coefficients: Vec<f64>,
    v_ref: f64,
    lo: f64,
    hi: f64,
}

impl SpeedEval {
    pub(crate) fn new(s: &SpeedSpec, v_ref: f64) -> SpeedEval {
        SpeedEval {
            kneed: s.form == "curtius_kniffler",
            coefficients: s.coefficients.clone(),
            v_ref,
            lo: s.fitted_range_mps[0],
            hi: s.fitted_range_mps[1],
        }
    }

    /// g(v), v (m/s) clamped to the fitted range; the C header does the same operations.
    #[inline]
    pub(crate) fn factor(&self, v: f64) -> f64 {
        let v = v.clamp(self.lo, self.hi);
        if self.kneed {
            let phi =
                (self.v_ref + CURTIUS_KNIFFLER_SPEED_MPS) / (v + CURTIUS_KNIFFLER_SPEED_MPS) - 1.0;
            1.0 + self.coefficients[0] * phi
        } else {
            let u = v / self.v_ref - 1.0;
            1.0 + u * horner(&self.coefficients, u)
        }
    }
}

/// Checks a speed law: its form and coefficients, its range, and 0.05 ≤ g(v) with
/// μ0_max · g(v) ≤ 1.5 over the range (`mu0_max`: the largest μ0, over temperature too).
pub fn check_speed_law(s: &SpeedSpec, v_ref: f64, mu0_max: f64) -> Result<(), Defect> {
    let n = s.coefficients.len();
    let ok_count = match s.form.as_str() {
        "polynomial" => (1..=MAX_SPEED_COEFFICIENTS).contains(&n),
        "curtius_kniffler" => n == 1,
        other => {
            return Err(Defect::Value(format!(
                "polach.speed.form = {other:?}: must be \"polynomial\" or \"curtius_kniffler\""
            )))
        }
    };
    if !ok_count {
        return Err(Defect::Value(format!(
            "polach.speed ({}) has {n} coefficients: a polynomial takes 1 to {MAX_SPEED_COEFFICIENTS}, curtius_kniffler 1",
            s.form
        )));
    }
    let [lo, hi] = s.fitted_range_mps;
    if s.coefficients.iter().any(|c| !c.is_finite())
        || !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && lo <= hi)
    {
        return Err(Defect::Value(
            "polach.speed: coefficients or fitted range not finite (the range must be ≥ 0)".into(),
        ));
    }
    let e = SpeedEval::new(s, v_ref);
    for i in 0..SPEED_CHECKS {
        let v = lo + (hi - lo) * i as f64 / (SPEED_CHECKS - 1) as f64;
        let g = e.factor(v);
        if !(g >= 0.05 && mu0_max * g <= 1.5) {
            return Err(Defect::Value(format!(
                "polach.speed: μ0's speed factor g({v:.3} m/s) = {g:.4} leaves 0.05 ≤ g and μ0 g ≤ 1.5 (largest μ0 {mu0_max})"
            )));
        }
    }
    Ok(())
}

/// Hertz + Kalker patch of one wheel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatchSpec {
    /// Semi-axes, a in the rolling direction (m).
    pub a_m: f64,
    pub b_m: f64,
    /// Shear modulus G (Pa).
    pub shear_modulus_pa: f64,
    /// Kalker's longitudinal coefficient c11 (–).
    pub c11: f64,
}

/// μ0(T), k_A(T), k_S(T) as polynomials in the ambient temperature T (°C).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemperatureSpec {
    /// μ0(T) coefficients in ascending powers of T (°C); empty: μ0 does not depend on T.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mu0: Vec<f64>,
    /// k_A(T), k_S(T) coefficients in ascending powers of T (°C) (one coefficient: constant).
    pub k_a: Vec<f64>,
    pub k_s: Vec<f64>,
    /// The temperatures the fit covers (°C); T outside is clamped to it.
    pub fitted_range_c: [f64; 2],
}

/// Checks a `polach` model file: names, sections, parameter domain, and that a temperature
/// law keeps 0 < μ0 ≤ 1.5 and 0 < k_S ≤ k_A ≤ 1 over its range.
pub(crate) fn check(m: &ModelFile) -> Result<(), Defect> {
    let Some(p) = &m.polach else {
        return Err(Defect::MissingSection {
            kind: "polach",
            section: "polach",
        });
    };
    if !m.layers.is_empty() || m.creep.is_some() || !m.history.is_empty() {
        return Err(Defect::ForeignSection {
            kind: "polach",
            what: "layers, creep or history",
        });
    }
    let names: Vec<&str> = m.inputs.iter().map(|i| i.name.as_str()).collect();
    let expected: &[&str] = if p.temperature.is_some() {
        &["dv_mps", "v_mps", TEMPERATURE_INPUT]
    } else {
        &["dv_mps", "v_mps"]
    };
    if names != expected {
        return Err(Defect::Inputs {
            found: names.iter().map(|n| n.to_string()).collect(),
            expected: format!("{expected:?} (a temperature input goes with a temperature law)"),
        });
    }
    if m.outside_domain != "law" {
        return Err(Defect::OutsideDomain {
            found: m.outside_domain.clone(),
            expected: "law",
            note: " (kind polach)",
        });
    }
    for i in &m.inputs {
        let all = [i.norm_min, i.norm_max, i.domain_min, i.domain_max];
        if all.iter().any(|v| !v.is_finite()) || i.domain_min > i.domain_max {
            return Err(Defect::InputRange {
                input: i.name.clone(),
                what: "range not finite or min above max",
            });
        }
    }
    check_spec(p)?;
    if let Some(t) = &p.temperature {
        let dom = &m.inputs[2];
        if dom.domain_min != t.fitted_range_c[0] || dom.domain_max != t.fitted_range_c[1] {
            return Err(Defect::InputRange {
                input: TEMPERATURE_INPUT.into(),
                what: "domain differs from polach.temperature.fitted_range_c",
            });
        }
    }
    if let Some(sp) = &p.speed {
        let dom = &m.inputs[1];
        if dom.domain_min != sp.fitted_range_mps[0] || dom.domain_max != sp.fitted_range_mps[1] {
            return Err(Defect::InputRange {
                input: "v_mps".into(),
                what: "domain differs from polach.speed.fitted_range_mps",
            });
        }
    }
    Ok(())
}

/// The checks of a Polach law on its own (a `polach` file's section, or a residual network's
/// `base`): the parameter domain, the patch, the standard errors, and that the temperature and
/// speed laws keep their bounds over their ranges.
pub(crate) fn check_spec(p: &PolachSpec) -> Result<(), Defect> {
    PolachParams {
        mu0: p.mu0,
        a_ratio: p.a_ratio,
        b_s_per_m: p.b_s_per_m,
        k_a: p.k_a,
        k_s: p.k_s,
    }
    .check()
    .map_err(Defect::Polach)?;
    let pt = &p.patch;
    for (what, x) in [
        ("patch.a_m", pt.a_m),
        ("patch.b_m", pt.b_m),
        ("patch.shear_modulus_pa", pt.shear_modulus_pa),
        ("patch.c11", pt.c11),
        ("wheel_load_n", p.wheel_load_n),
        ("reference_speed_mps", p.reference_speed_mps),
        (
            "creepage_speed_mps",
            p.creepage_speed_mps.unwrap_or(p.reference_speed_mps),
        ),
    ] {
        if !(x.is_finite() && x > 0.0) {
            return Err(Defect::Value(format!(
                "polach.{what} = {x} must be finite and > 0"
            )));
        }
    }
    if p.standard_errors
        .iter()
        .flatten()
        .any(|s| !(s.is_finite() && *s >= 0.0))
    {
        return Err(Defect::Value(
            "polach.standard_errors must be finite and >= 0 (or null)".into(),
        ));
    }
    if let Some(t) = &p.temperature {
        let [lo, hi] = t.fitted_range_c;
        if t.k_a.is_empty()
            || t.k_s.is_empty()
            || t.k_a
                .iter()
                .chain(&t.k_s)
                .chain(&t.mu0)
                .any(|c| !c.is_finite())
            || !(lo.is_finite() && hi.is_finite() && lo <= hi)
        {
            return Err(Defect::Value(
                "polach.temperature: coefficients or fitted range not finite".into(),
            ));
        }
        // A file with 10⁶ coefficients took 3.6 s to check and made an 18 MB header.
        for (what, c) in [("mu0", &t.mu0), ("k_a", &t.k_a), ("k_s", &t.k_s)] {
            if c.len() > MAX_COEFFICIENTS {
                return Err(Defect::Value(format!(
                    "polach.temperature.{what} has {} coefficients; at most {MAX_COEFFICIENTS} (k_S = k_A · k_S/k_A of degree 5 each has 11)",
                    c.len()
                )));
            }
        }
        check_law(t, p.mu0)?;
    }
    if let Some(sp) = &p.speed {
        check_speed_law(sp, p.reference_speed_mps, mu0_max(p))?;
    }
    Ok(())
}

/// The largest μ0 of a spec: its μ0, or the largest of μ0(T) over the temperature range.
fn mu0_max(p: &PolachSpec) -> f64 {
    largest_mu0(p.mu0, p.temperature.as_ref())
}

/// The largest adhesion level of base `mu0` and a temperature law `t` (the largest of μ0(T) at
/// the checked temperatures of its range when it has μ0 coefficients): what
/// [`check_speed_law`] takes as `mu0_max`.
pub fn largest_mu0(mu0: f64, t: Option<&TemperatureSpec>) -> f64 {
    match t {
        Some(t) if !t.mu0.is_empty() => {
            let [lo, hi] = t.fitted_range_c;
            (0..TEMPERATURE_CHECKS)
                .map(|i| {
                    horner(
                        &t.mu0,
                        lo + (hi - lo) * i as f64 / (TEMPERATURE_CHECKS - 1) as f64,
                    )
                })
                .fold(mu0, f64::max)
        }
        _ => mu0,
    }
}

/// Whether a temperature law keeps 0 < μ0(T) ≤ 1.5 and 0 < k_S(T) ≤ k_A(T) ≤ 1 at
/// [`TEMPERATURE_CHECKS`] points of its fitted range (`mu0` when the law has no μ0(T)).
pub fn check_law(t: &TemperatureSpec, mu0: f64) -> Result<(), Defect> {
    let [lo, hi] = t.fitted_range_c;
    for i in 0..TEMPERATURE_CHECKS {
        let temp = lo + (hi - lo) * i as f64 / (TEMPERATURE_CHECKS - 1) as f64;
        let (ka, ks) = (horner(&t.k_a, temp), horner(&t.k_s, temp));
        let m = if t.mu0.is_empty() {
            mu0
        } else {
            horner(&t.mu0, temp)
        };
        if !(ka > 0.0 && ka <= 1.0 && ks > 0.0 && ks <= ka && m > 0.0 && m <= 1.5) {
            return Err(Defect::TemperatureLaw {
                t_c: temp,
                mu0: m,
                k_a: ka,
                k_s: ks,
            });
        }
    }
    Ok(())
}

/// Why a model cannot be fixed at an ambient temperature ([`super::Model::at_temperature`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TemperatureError {
    #[error("this model has no temperature law (only Polach models fitted at two or more ambient temperatures have one)")]
    NotPolach,
    #[error("this Polach model has no temperature law (it was fitted at fewer than two ambient temperatures, or its data chose none)")]
    NoLaw,
    #[error("ambient temperature {t_c} °C is outside the range the temperature law was fitted over, {lo} … {hi} °C")]
    Outside { t_c: f64, lo: f64, hi: f64 },
}

/// The evaluator of a `polach` model.
#[derive(Debug, Clone)]
pub(crate) struct PolachEval {
    mu0: f64,
    a_ratio: f64,
    b: f64,
    k_a: f64,
    k_s: f64,
    /// K = π G a b c11 / (4 Q): ε = K s / μ_w.
    stiffness: f64,
    v_ref: f64,
    /// The fixed creepage speed of the slip-velocity form (m/s); `None`: the rolling speed.
    creepage_speed: Option<f64>,
    /// Fitted Δv and v ranges (m/s), for [`super::Model::in_domain`].
    dv: (f64, f64),
    v: (f64, f64),
    temperature: Option<TemperatureEval>,
    speed: Option<SpeedEval>,
}

/// The temperature law of an evaluator: μ0(T) (empty: constant), k_A(T), k_S(T), range (°C).
#[derive(Debug, Clone)]
struct TemperatureEval {
    mu0: Vec<f64>,
    k_a: Vec<f64>,
    k_s: Vec<f64>,
    lo: f64,
    hi: f64,
}

impl TemperatureEval {
    /// (μ0, k_A, k_S) at T (°C), T clamped to the range; `mu0` when the law has no μ0(T).
    #[inline]
    fn at(&self, t_c: f64, mu0: f64) -> (f64, f64, f64) {
        let t = t_c.clamp(self.lo, self.hi);
        let m = if self.mu0.is_empty() {
            mu0
        } else {
            horner(&self.mu0, t)
        };
        (m, horner(&self.k_a, t), horner(&self.k_s, t))
    }
}

impl PolachEval {
    /// From a checked file.
    pub(crate) fn new(m: &ModelFile) -> PolachEval {
        let p = m
            .polach
            .as_ref()
            .expect("checked: kind polach has a polach section");
        PolachEval {
            dv: (m.inputs[0].domain_min, m.inputs[0].domain_max),
            v: (m.inputs[1].domain_min, m.inputs[1].domain_max),
            ..PolachEval::of_law(p)
        }
    }

    /// The law of a checked spec alone (a residual network's base; no input domain).
    pub(crate) fn of_law(p: &PolachSpec) -> PolachEval {
        PolachEval {
            mu0: p.mu0,
            a_ratio: p.a_ratio,
            b: p.b_s_per_m,
            k_a: p.k_a,
            k_s: p.k_s,
            stiffness: stiffness(p),
            v_ref: p.reference_speed_mps,
            creepage_speed: p.creepage_speed_mps,
            dv: (0.0, f64::INFINITY),
            v: (0.0, f64::INFINITY),
            temperature: p.temperature.as_ref().map(|t| TemperatureEval {
                mu0: t.mu0.clone(),
                k_a: t.k_a.clone(),
                k_s: t.k_s.clone(),
                lo: t.fitted_range_c[0],
                hi: t.fitted_range_c[1],
            }),
            speed: p
                .speed
                .as_ref()
                .map(|s| SpeedEval::new(s, p.reference_speed_mps)),
        }
    }

    /// μ at slip `dv` (m/s), speed `v` (m/s) and ambient temperature `t_c` (°C); see the
    /// module documentation.
    #[inline]
    pub(crate) fn mu_vt(&self, dv: f64, ddv: f64, v: f64, t_c: f64) -> f64 {
        if !(dv.is_finite() && ddv.is_finite()) {
            return f64::NAN;
        }
        let (mut mu0, ka, ks) = match &self.temperature {
            Some(law) if t_c.is_finite() => law.at(t_c, self.mu0),
            _ => (self.mu0, self.k_a, self.k_s),
        };
        let v = if v.is_finite() {
            v.max(MIN_SPEED_MPS)
        } else {
            self.v_ref
        };
        if let Some(s) = &self.speed {
            mu0 *= s.factor(v);
        }
        let w = dv.abs();
        if w == 0.0 {
            return 0.0;
        }
        let mu_w = mu0 * ((1.0 - self.a_ratio) * (-self.b * w).exp() + self.a_ratio);
        let eps = self.stiffness * (w / self.creepage_speed.unwrap_or(v)) / mu_w;
        let x = ka * eps;
        let f = 2.0 * mu_w / PI * (x / (1.0 + x * x) + (ks * eps).atan());
        f.copysign(dv)
    }

    pub(crate) fn in_domain(&self, dv: f64, v: f64) -> bool {
        let w = dv.abs();
        w >= self.dv.0 && w <= self.dv.1 && v >= self.v.0 && v <= self.v.1
    }

    /// This evaluator with μ0, k_A, k_S fixed at their values at T; T must lie in the fitted
    /// range.
    pub(crate) fn at_temperature(&self, t_c: f64) -> Result<PolachEval, TemperatureError> {
        let Some(law) = &self.temperature else {
            return Err(TemperatureError::NoLaw);
        };
        if !(t_c >= law.lo && t_c <= law.hi) {
            return Err(TemperatureError::Outside {
                t_c,
                lo: law.lo,
                hi: law.hi,
            });
        }
        let (mu0, k_a, k_s) = law.at(t_c, self.mu0);
        Ok(PolachEval {
            mu0,
            k_a,
            k_s,
            temperature: None,
            ..self.clone()
        })
    }

    /// (μ0, k_A, k_S) in use without a temperature.
    pub(crate) fn base(&self) -> (f64, f64, f64) {
        (self.mu0, self.k_a, self.k_s)
    }
}

/// K = π G a b c11 / (4 Q) of a spec, the same operations in Rust and C.
pub(crate) fn stiffness(p: &PolachSpec) -> f64 {
    let pt = &p.patch;
    PI * pt.shear_modulus_pa * pt.a_m * pt.b_m * pt.c11 / (4.0 * p.wheel_load_n)
}
