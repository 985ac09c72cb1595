//! A calibration as the estimation applies it: per-axle brake coefficients, the pad
//! friction's speed law, the radar's scale and latency and the tachometers' delay — fitted
//! from a campaign's runs ([`crate::estimate::selfcal`]) and carried with the pipeline
//! ([`super::Pipeline::calibrated`]), so that every way of estimating a run applies the same.

use crate::format::AXLES;

/// The speed form of the pad friction: constant; linear, φ = 1 − v/v_ref (the first-order form of a
/// friction that rises as the sliding speed falls [assumed]); quadratic and cubic,
/// φ = max(0, 1 − v/v_ref)^2 and ^3 (a rise that gathers towards standstill; the shape varies
/// with the pad material, so the powers are candidates for BIC, not a law [assumed]); two
/// mixtures of neighbouring powers, φ = (1 − w) φ_linear + w φ_quadratic and
/// (1 − w) φ_quadratic + w φ_cubic with 0 ≤ w ≤ 1 fitted (a shape between two of the powers,
/// one parameter more [assumed]); or Karwatzki's, φ = k(v)/k(v_ref) − 1
/// with k(v) = (v + 100)/(5 v + 100), v in km/h — the speed factor of Karwatzki's empirical
/// formula for cast-iron blocks (as given in Wende, *Fahrdynamik des Schienenverkehrs*,
/// Teubner 2003).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PadForm {
    Constant,
    Linear,
    Quadratic,
    Cubic,
    #[serde(rename = "linear-quadratic")]
    LinearQuadratic,
    #[serde(rename = "quadratic-cubic")]
    QuadraticCubic,
    Karwatzki,
}

impl PadForm {
    pub const ALL: [PadForm; 7] = [
        PadForm::Constant,
        PadForm::Linear,
        PadForm::Quadratic,
        PadForm::Cubic,
        PadForm::LinearQuadratic,
        PadForm::QuadraticCubic,
        PadForm::Karwatzki,
    ];

    pub fn name(self) -> &'static str {
        match self {
            PadForm::Constant => "constant",
            PadForm::Linear => "linear",
            PadForm::Quadratic => "quadratic",
            PadForm::Cubic => "cubic",
            PadForm::LinearQuadratic => "linear-quadratic",
            PadForm::QuadraticCubic => "quadratic-cubic",
            PadForm::Karwatzki => "karwatzki",
        }
    }

    /// Whether the form is a mixture of two powers, with a weight w to fit.
    pub fn mixes(self) -> bool {
        matches!(self, PadForm::LinearQuadratic | PadForm::QuadraticCubic)
    }

    /// The form's name, with a mixture's weight `mix`: "quadratic-cubic, w = 0.48" (the
    /// other forms' name alone).
    pub fn label(self, mix: f64) -> String {
        if self.mixes() {
            format!("{}, w = {mix:.2}", self.name())
        } else {
            self.name().to_string()
        }
    }

    /// φ(v), zero at `v_ref` (m/s); `mix` is a mixture's weight w (0 ≤ w ≤ 1; the other forms
    /// ignore it).
    pub fn phi(self, v_mps: f64, v_ref_mps: f64, mix: f64) -> f64 {
        let u = 1.0 - v_mps / v_ref_mps;
        let power = |n: i32| u.max(0.0).powi(n);
        match self {
            PadForm::Constant => 0.0,
            PadForm::Linear => u,
            PadForm::Quadratic => power(2),
            PadForm::Cubic => power(3),
            PadForm::LinearQuadratic => (1.0 - mix) * u + mix * power(2),
            PadForm::QuadraticCubic => (1.0 - mix) * power(2) + mix * power(3),
            PadForm::Karwatzki => {
                let k = |v: f64| {
                    let kmh = 3.6 * v.max(0.0);
                    (kmh + 100.0) / (5.0 * kmh + 100.0)
                };
                k(v_mps) / k(v_ref_mps) - 1.0
            }
        }
    }
}

/// α_i(v) = α_i (1 + γ φ(v)).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PadLaw {
    pub form: PadForm,
    /// γ (–).
    pub gamma: f64,
    /// One standard error of γ (0 for the constant form; NaN where it could not be computed).
    #[serde(with = "nan_as_null")]
    pub gamma_se: f64,
    /// The speed where α_i(v) = α_i, m/s.
    pub v_ref_mps: f64,
    /// A mixture's weight w ([`PadForm::phi`]); 0, and not written, for the other forms.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub mix: f64,
}

/// Whether a value is 0 (serde's `skip_serializing_if` for a mixture's weight).
#[allow(clippy::trivially_copy_pass_by_ref)]
pub(crate) fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl PadLaw {
    /// No speed dependence.
    pub fn constant() -> PadLaw {
        PadLaw {
            form: PadForm::Constant,
            gamma: 0.0,
            gamma_se: 0.0,
            v_ref_mps: 1.0,
            mix: 0.0,
        }
    }

    /// φ(v) of the law's form ([`PadForm::phi`]).
    pub fn phi(&self, v_mps: f64) -> f64 {
        self.form.phi(v_mps, self.v_ref_mps, self.mix)
    }

    /// The form's name, with a mixture's weight: "quadratic-cubic, w = 0.48".
    pub fn label(&self) -> String {
        self.form.label(self.mix)
    }

    /// 1 + γ φ(v).
    pub fn factor(&self, v_mps: f64) -> f64 {
        1.0 + self.gamma * self.phi(v_mps)
    }

    /// The relative rise from the top speed to standstill, γ φ(0).
    pub fn rise_to_standstill(&self) -> f64 {
        self.factor(0.0) - 1.0
    }
}

/// What the estimation applies: per-axle α at the top speed, the pad law, and the radar's
/// scale and latency, the tachometers' delay. The identity (α as `[vehicle]` gives them,
/// constant pad friction, scale 1, no delays) changes nothing.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Corrections {
    pub alpha_nm_per_bar: [f64; AXLES],
    pub pad: PadLaw,
    pub radar_scale: f64,
    pub radar_latency_s: f64,
    pub tacho_delay_s: f64,
}

/// A calibration with what it was fitted on: the pipeline carries it
/// ([`super::Pipeline::calibrated`]); a campaign refuses one fitted on other runs or with
/// another pipeline file.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Calibrated {
    /// "campaign" or "dry-run" (`estimate.calibration`), or "none": `"auto"` could fit none
    /// (too few runs with samples for the balance, or a fit that failed) and the runs are
    /// estimated with the pipeline's values (a record that says so, written as
    /// `calibration.json`, for the later parts of a scheduled campaign).
    pub source: String,
    pub corrections: Corrections,
    /// The campaign's runs (names, in the campaign's order): the campaign it belongs to.
    /// [`Errors::fitted_runs`] says how many of them gave the fit its samples.
    pub runs: Vec<String>,
    /// SHA-256 of the pipeline file's text it was fitted with.
    pub pipeline_sha256: String,
    /// The SHA-256 of the inputs it was fitted on (`calibration.json`'s `inputs_sha256`), when
    /// it was read from such a record: a campaign's models part refuses one fitted on other
    /// logs. Not part of the calibration as written (campaign.json, the runs' reuse keys).
    #[serde(skip)]
    pub inputs_sha256: Option<String>,
    /// Its uncertainties and its effect on μ, where it was fitted with them (a campaign's or a
    /// dry run's; not "none", nor a record written before them): [`Calibrated::summary`]
    /// prints them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub errors: Option<Errors>,
}

/// A fitted calibration's one-standard-error uncertainties and the pipeline's α it changes.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Errors {
    /// Each α_i's, N·m/bar (NaN where it could not be computed).
    #[serde(with = "nan_as_null_axles")]
    pub alpha_se: [f64; AXLES],
    /// The radar's scale's (NaN where it was not fitted).
    #[serde(with = "nan_as_null", default = "nan")]
    pub radar_scale_se: f64,
    /// The radar's latency's, s (NaN where it was not identified).
    #[serde(with = "nan_as_null", default = "nan")]
    pub radar_latency_se_s: f64,
    /// `[vehicle]`'s α_i, N·m/bar: an axle's brake force, and with it its μ (seed 002 eq. 9:
    /// μ_i N_i r = α_i p_i − J ω̇_i, the inertia's share aside), moves by α_i(v) / this.
    pub pipeline_alpha_nm_per_bar: [f64; AXLES],
    /// How many of [`Calibrated::runs`] the values were fitted on: the runs with samples in
    /// the balance ("campaign") or with full-adhesion samples ("dry-run"); the others failed
    /// to read or had none. Absent in records written before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fitted_runs: Option<usize>,
}

impl Calibrated {
    /// "8 runs", or "3 of 9 runs" where only some of the campaign's runs were fitted on.
    pub fn runs_fitted(&self) -> String {
        let all = self.runs.len();
        match self.errors.as_ref().and_then(|e| e.fitted_runs) {
            Some(n) if n != all => format!("{n} of {all} runs"),
            _ => format!("{all} runs"),
        }
    }

    /// One line for notes and the model files' provenance: the values, and where it has them
    /// ([`Calibrated::errors`]) their standard errors and how far each axle's brake force (and
    /// so its μ) moved from the pipeline's at the top speed and at 10 km/h.
    pub fn summary(&self) -> String {
        let c = &self.corrections;
        if let Some(e) = &self.errors {
            return self.summary_with(e);
        }
        let alpha: Vec<String> = c
            .alpha_nm_per_bar
            .iter()
            .map(|a| format!("{a:.1}"))
            .collect();
        format!(
            "{} calibration over {}: α = [{}] N·m/bar at {:.0} km/h, pad friction {} ({:+.1} % to standstill), radar ×{:.5} and {:.1} ms late, tachometers {:.1} ms late",
            self.source,
            self.runs_fitted(),
            alpha.join(", "),
            c.pad.v_ref_mps * 3.6,
            c.pad.label(),
            c.pad.rise_to_standstill() * 100.0,
            c.radar_scale,
            c.radar_latency_s * 1e3,
            c.tacho_delay_s * 1e3
        )
    }

    fn summary_with(&self, e: &Errors) -> String {
        let c = &self.corrections;
        let pm = |x: f64, se: f64, digits: usize| {
            if se.is_finite() {
                format!("{x:.digits$} ± {se:.digits$}")
            } else {
                format!("{x:.digits$}")
            }
        };
        let alpha: Vec<String> = (0..AXLES)
            .map(|a| pm(c.alpha_nm_per_bar[a], e.alpha_se[a], 1))
            .collect();
        let rise_se = c.pad.gamma_se * c.pad.phi(0.0).abs() * 100.0;
        let rise = if rise_se.is_finite() {
            format!("{:+.2} ± {rise_se:.2}", c.pad.rise_to_standstill() * 100.0)
        } else {
            format!("{:+.2}", c.pad.rise_to_standstill() * 100.0)
        };
        let moved = |v: f64| -> String {
            (0..AXLES)
                .map(|a| {
                    let ratio =
                        c.alpha_nm_per_bar[a] * c.pad.factor(v) / e.pipeline_alpha_nm_per_bar[a];
                    format!("{:+.1}", (ratio - 1.0) * 100.0)
                })
                .collect::<Vec<_>>()
                .join("/")
        };
        // A constant pad law (a dry run's, or the pipeline's α kept) has no speed to name: α
        // and the brake forces' change are the same at every speed.
        let (at, pad, effect) = if c.pad.form == PadForm::Constant {
            (
                String::new(),
                "pad friction constant".to_string(),
                format!("{} % at every speed", moved(c.pad.v_ref_mps)),
            )
        } else {
            (
                format!(" at {:.0} km/h", c.pad.v_ref_mps * 3.6),
                format!("pad friction {} ({rise} % to standstill)", c.pad.label()),
                format!(
                    "{} % at {:.0} km/h and {} % at 10 km/h",
                    moved(c.pad.v_ref_mps),
                    c.pad.v_ref_mps * 3.6,
                    moved(10.0 / 3.6)
                ),
            )
        };
        format!(
            "{} calibration over {}: α = [{}] N·m/bar (1σ){at}, {pad}, radar ×{} and {} ms late, tachometers {:.1} ms late; each axle's brake force, and with it its μ, moved {effect} from [vehicle]'s α",
            self.source,
            self.runs_fitted(),
            alpha.join(", "),
            pm(c.radar_scale, e.radar_scale_se, 5),
            pm(c.radar_latency_s * 1e3, e.radar_latency_se_s * 1e3, 1),
            c.tacho_delay_s * 1e3,
        )
    }
}

/// NaN: the default of a [`nan_as_null`] field a file may lack.
pub fn nan() -> f64 {
    f64::NAN
}

/// Serde for an f64 that may not be a number (a standard error that could not be computed):
/// written as `null`, read back as NaN — JSON has no NaN, and serde_json would write `null`
/// and then refuse to read it.
pub mod nan_as_null {
    pub fn serialize<S: serde::Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
        if x.is_finite() {
            s.serialize_f64(*x)
        } else {
            s.serialize_none()
        }
    }

    pub fn deserialize<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(<Option<f64> as serde::Deserialize>::deserialize(d)?.unwrap_or(f64::NAN))
    }
}

/// [`nan_as_null`] for the four axles' values.
pub mod nan_as_null_axles {
    use crate::format::AXLES;

    pub fn serialize<S: serde::Serializer>(x: &[f64; AXLES], s: S) -> Result<S::Ok, S::Error> {
        let v: Vec<Option<f64>> = x.iter().map(|v| v.is_finite().then_some(*v)).collect();
        serde::Serialize::serialize(&v, s)
    }

    pub fn deserialize<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[f64; AXLES], D::Error> {
        let v = <[Option<f64>; AXLES] as serde::Deserialize>::deserialize(d)?;
        Ok(v.map(|x| x.unwrap_or(f64::NAN)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn calibrated(errors: Option<Errors>) -> Calibrated {
        Calibrated {
            source: "campaign".into(),
            corrections: Corrections {
                alpha_nm_per_bar: [1610.0, 1620.0, 1590.0, 1600.0],
                pad: PadLaw {
                    form: PadForm::Cubic,
                    gamma: 0.05,
                    gamma_se: 0.001,
                    v_ref_mps: 55.0,
                    mix: 0.0,
                },
                radar_scale: 1.003,
                radar_latency_s: 0.03,
                tacho_delay_s: 0.0096,
            },
            runs: vec!["a".into(), "b".into(), "c".into()],
            pipeline_sha256: "00".into(),
            inputs_sha256: None,
            errors,
        }
    }

    /// A record without errors (written before them) reads back without them and prints the
    /// values alone; errors that could not be computed (NaN) are written as null and read back
    /// as NaN, and the summary leaves their ± out.
    #[test]
    fn errors_round_trip_and_older_records_read_without_them() {
        let old = calibrated(None);
        let text = serde_json::to_string(&old).unwrap();
        assert!(!text.contains("errors"), "{text}");
        let back: Calibrated = serde_json::from_str(&text).unwrap();
        assert_eq!(back, old);
        assert!(!back.summary().contains('±'), "{}", back.summary());

        let with = calibrated(Some(Errors {
            alpha_se: [7.0, f64::NAN, 7.2, 7.3],
            radar_scale_se: 4e-5,
            radar_latency_se_s: f64::NAN,
            pipeline_alpha_nm_per_bar: [1600.0; AXLES],
            fitted_runs: None,
        }));
        let text = serde_json::to_string(&with).unwrap();
        assert!(text.contains("null"), "{text}");
        let back: Calibrated = serde_json::from_str(&text).unwrap();
        let e = back.errors.unwrap();
        assert!(e.alpha_se[1].is_nan() && e.radar_latency_se_s.is_nan());
        assert_eq!(e.alpha_se[0], 7.0);
        let line = back.summary();
        assert!(
            line.contains(
                "α = [1610.0 ± 7.0, 1620.0, 1590.0 ± 7.2, 1600.0 ± 7.3] N·m/bar (1σ) at 198 km/h"
            ) && line.contains("pad friction cubic (+5.00 ± 0.10 % to standstill)")
                && line.contains("radar ×1.00300 ± 0.00004 and 30.0 ms late")
                && line.contains(
                    "moved +0.6/+1.2/-0.6/+0.0 % at 198 km/h and +4.9/+5.6/+3.6/+4.3 % at 10 km/h"
                ),
            "{line}"
        );
    }

    /// A mixture's φ is its two powers' at w = 0 and 1, lies between them in between, and
    /// rises monotonically towards standstill; its weight is written only where it is one (a
    /// record of a pure form keeps its bytes) and named in the summary.
    #[test]
    fn a_mixture_lies_between_its_two_powers() {
        let v_ref = 55.0;
        for (mixed, lo, hi) in [
            (
                PadForm::LinearQuadratic,
                PadForm::Linear,
                PadForm::Quadratic,
            ),
            (PadForm::QuadraticCubic, PadForm::Quadratic, PadForm::Cubic),
        ] {
            assert!(mixed.mixes() && !lo.mixes() && !hi.mixes());
            for i in 0..=20 {
                let v = v_ref * f64::from(i) / 20.0;
                let (a, b) = (lo.phi(v, v_ref, 0.3), hi.phi(v, v_ref, 0.3));
                assert_eq!(mixed.phi(v, v_ref, 0.0), a);
                assert_eq!(mixed.phi(v, v_ref, 1.0), b);
                let m = mixed.phi(v, v_ref, 0.3);
                assert!(m >= a.min(b) && m <= a.max(b), "{mixed:?} at {v}: {m}");
                if i > 0 {
                    assert!(m < mixed.phi(v - v_ref / 20.0, v_ref, 0.3));
                }
            }
            assert_eq!(mixed.phi(v_ref, v_ref, 0.3), 0.0);
            assert_eq!(mixed.phi(0.0, v_ref, 0.3), 1.0);
        }
        let mut c = calibrated(None);
        let pure = serde_json::to_string(&c).unwrap();
        assert!(!pure.contains("mix"), "{pure}");
        c.corrections.pad.form = PadForm::QuadraticCubic;
        c.corrections.pad.mix = 0.47;
        let text = serde_json::to_string(&c).unwrap();
        assert!(
            text.contains(r#""form":"quadratic-cubic""#) && text.contains(r#""mix":0.47"#),
            "{text}"
        );
        let back: Calibrated = serde_json::from_str(&text).unwrap();
        assert_eq!(back, c);
        assert!(
            back.summary()
                .contains("pad friction quadratic-cubic, w = 0.47 (+5.0 % to standstill)"),
            "{}",
            back.summary()
        );
    }

    proptest::proptest! {
        /// For every weight and speed below the reference, a mixture's φ lies between its two
        /// powers' and within 0 … 1.
        #[test]
        fn every_mixture_lies_between_its_powers(w in 0.0..=1.0f64, x in 0.0..=1.0f64) {
            let v_ref = 55.0;
            let v = x * v_ref;
            for (mixed, lo, hi) in [
                (PadForm::LinearQuadratic, PadForm::Linear, PadForm::Quadratic),
                (PadForm::QuadraticCubic, PadForm::Quadratic, PadForm::Cubic),
            ] {
                let (a, b) = (lo.phi(v, v_ref, w), hi.phi(v, v_ref, w));
                let m = mixed.phi(v, v_ref, w);
                proptest::prop_assert!(m >= a.min(b) - 1e-15 && m <= a.max(b) + 1e-15);
                proptest::prop_assert!((0.0..=1.0).contains(&m));
            }
        }
    }
}
