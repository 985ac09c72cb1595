//! Polach's creep-force model with falling friction (seed 004_7d175079b70fb95b.txt eq. 1–2;
//! Polach, Wear 258 (2005) 992–1000) and its temperature extension k_A(T), k_S(T) (seed 004
//! eq. 3).
//!
//!   f = F/Q = (2μ/π)·[k_A ε / (1 + (k_A ε)²) + arctan(k_S ε)]           (eq. 1 / 3)
//!   ε = (2/3)·C π a² b s_C / (Q μ),  C = (3/8)(G/a)·c_jj                  (eq. 2)
//!     ⇒ ε = π G a b c_jj s_C / (4 Q μ)
//!   μ = μ0·[(1 − A) e^(−B w) + A]                                          (falling friction)
//!
//! Q wheel load (N), a, b semi-axes (m, a in the rolling direction), G shear modulus (Pa),
//! s_C = √(s_x² + s_y²) combined creepage with s = w/v, w the slip velocity (m/s), v the vehicle
//! speed (m/s), c_jj = √((c11 s_x/s_C)² + (c22 s_y/s_C)²) Kalker's coefficient in the direction of
//! the creepage, A = μ∞/μ0 (–), B (s/m). Small-creep slope: dF/ds = (k_A + k_S)/2 · G a b c11.
//! Requires 0 < k_S ≤ k_A ≤ 1, which also guarantees |F| ≤ μQ.
//! Forces carry the sign of the creepage (see `kalker` for the convention). Spin is ignored.

use super::{check_finite, check_positive, ContactError};
use std::f64::consts::PI;

/// Polach parameters (reference-values.md gives the commonly quoted dry and wet sets).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolachParams {
    /// Maximum friction coefficient μ0 at zero slip velocity, (0, 1.5].
    pub mu0: f64,
    /// Ratio A = μ∞/μ0 of friction at infinite slip velocity, (0, 1].
    pub a_ratio: f64,
    /// Exponential decrease B of friction with slip velocity, s/m, ≥ 0.
    pub b_s_per_m: f64,
    /// Reduction factor k_A in the area of adhesion, (0, 1].
    pub k_a: f64,
    /// Reduction factor k_S in the area of slip, (0, k_A].
    pub k_s: f64,
}

impl PolachParams {
    /// Polach 2005, dry rail: k_A 1.00, k_S 0.40, μ0 0.55, A 0.40, B 0.60 s/m.
    pub const DRY: PolachParams = PolachParams {
        mu0: 0.55,
        a_ratio: 0.40,
        b_s_per_m: 0.60,
        k_a: 1.00,
        k_s: 0.40,
    };
    /// Polach 2005, wet rail: k_A 0.30, k_S 0.10, μ0 0.30, A 0.40, B 0.20 s/m.
    pub const WET: PolachParams = PolachParams {
        mu0: 0.30,
        a_ratio: 0.40,
        b_s_per_m: 0.20,
        k_a: 0.30,
        k_s: 0.10,
    };

    /// Checks the parameter domain.
    pub fn check(&self) -> Result<(), ContactError> {
        let p = self;
        for (what, x) in [
            ("mu0", p.mu0),
            ("A", p.a_ratio),
            ("B", p.b_s_per_m),
            ("k_A", p.k_a),
            ("k_S", p.k_s),
        ] {
            check_finite(what, x)?;
        }
        let d = |what, value, valid| Err(ContactError::Domain { what, value, valid });
        if !(p.mu0 > 0.0 && p.mu0 <= 1.5) {
            return d("mu0", p.mu0, "0 < mu0 <= 1.5");
        }
        if !(p.a_ratio > 0.0 && p.a_ratio <= 1.0) {
            return d("A", p.a_ratio, "0 < A <= 1 (mu at infinite slip / mu0)");
        }
        if p.b_s_per_m < 0.0 {
            return d("B", p.b_s_per_m, "B >= 0 (s/m)");
        }
        if !(p.k_a > 0.0 && p.k_a <= 1.0) {
            return d("k_A", p.k_a, "0 < k_A <= 1");
        }
        if !(p.k_s > 0.0 && p.k_s <= p.k_a) {
            return d("k_S", p.k_s, "0 < k_S <= k_A");
        }
        Ok(())
    }

    /// μ at slip velocity `w` (m/s): μ0[(1 − A) e^(−B|w|) + A].
    #[inline]
    pub fn mu(&self, w_mps: f64) -> f64 {
        self.mu0 * ((1.0 - self.a_ratio) * (-self.b_s_per_m * w_mps.abs()).exp() + self.a_ratio)
    }
}

/// Contact geometry and stiffness for Polach: semi-axes (m), shear modulus (Pa), Kalker's c11
/// (longitudinal) and c22 (lateral).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPatch {
    pub a_m: f64,
    pub b_m: f64,
    pub g_pa: f64,
    pub c11: f64,
    pub c22: f64,
}

impl ContactPatch {
    pub fn check(&self) -> Result<(), ContactError> {
        for (what, x) in [
            ("semi-axis a", self.a_m),
            ("semi-axis b", self.b_m),
            ("shear modulus G", self.g_pa),
            ("c11", self.c11),
            ("c22", self.c22),
        ] {
            check_positive(what, x)?;
        }
        Ok(())
    }
}

/// Result of one Polach evaluation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolachForce {
    /// Longitudinal and lateral tangential forces, N (sign of the creepage).
    pub fx_n: f64,
    pub fy_n: f64,
    /// Friction coefficient at this slip velocity.
    pub mu: f64,
    /// Gradient of tangential stress ε (–).
    pub epsilon: f64,
}

/// Evaluates Polach's model for wheel load `q_n` (N), vehicle speed `v_mps` (m/s) and slip
/// velocities `wx_mps`, `wy_mps` (m/s).
///
/// Domain: Q > 0, v ≥ 0, finite inputs, valid parameters and patch. At v = 0 the creepage is
/// undefined: zero slip gives zero force, nonzero slip is an error.
#[inline]
pub fn polach(
    patch: &ContactPatch,
    p: &PolachParams,
    q_n: f64,
    v_mps: f64,
    wx_mps: f64,
    wy_mps: f64,
) -> Result<PolachForce, ContactError> {
    for (what, x) in [
        ("wheel load Q", q_n),
        ("speed v", v_mps),
        ("slip velocity w_x", wx_mps),
        ("slip velocity w_y", wy_mps),
    ] {
        check_finite(what, x)?;
    }
    if q_n <= 0.0 {
        return Err(ContactError::Domain {
            what: "wheel load Q",
            value: q_n,
            valid: "Q > 0 (N)",
        });
    }
    if v_mps < 0.0 {
        return Err(ContactError::Domain {
            what: "speed v",
            value: v_mps,
            valid: "v >= 0 (m/s)",
        });
    }
    let w = wx_mps.hypot(wy_mps);
    let mu = p.mu(w);
    if w == 0.0 {
        return Ok(PolachForce {
            fx_n: 0.0,
            fy_n: 0.0,
            mu,
            epsilon: 0.0,
        });
    }
    if v_mps == 0.0 {
        return Err(ContactError::Domain {
            what: "speed v",
            value: v_mps,
            valid: "v > 0 when the slip velocity is nonzero (creepage w/v undefined at standstill)",
        });
    }
    let (ux, uy) = (wx_mps / w, wy_mps / w);
    let s_c = w / v_mps;
    let c_jj = (patch.c11 * ux).hypot(patch.c22 * uy);
    let eps = PI * patch.g_pa * patch.a_m * patch.b_m * c_jj * s_c / (4.0 * q_n * mu);
    let ka = p.k_a * eps;
    let f = 2.0 * mu / PI * (ka / (1.0 + ka * ka) + (p.k_s * eps).atan());
    let force = f * q_n;
    Ok(PolachForce {
        fx_n: force * ux,
        fy_n: force * uy,
        mu,
        epsilon: eps,
    })
}

/// k_A(T) and k_S(T) (seed 004 eq. 3): polynomials in the ambient temperature T (°C) with the
/// range they were fitted over. railgrip's own form: seed 004 gives only the trend (adhesion
/// rises from +20 °C to −20 °C and dips slightly to −40 °C), no published coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct TemperatureLaw {
    /// Coefficients of k_A in ascending powers of T (°C).
    pub k_a: Vec<f64>,
    /// Coefficients of k_S in ascending powers of T (°C).
    pub k_s: Vec<f64>,
    /// Temperatures the fit covers, °C (min, max).
    pub fitted_range_c: (f64, f64),
}

/// A polynomial with coefficients in ascending powers at `t`, by Horner's rule (the k(T)
/// evaluation every evaluator of k_A(T), k_S(T) shares, C header included).
#[inline]
pub fn horner(c: &[f64], t: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, ci| acc * t + ci)
}

impl TemperatureLaw {
    pub fn new(
        k_a: Vec<f64>,
        k_s: Vec<f64>,
        fitted_range_c: (f64, f64),
    ) -> Result<Self, ContactError> {
        if k_a.is_empty() || k_s.is_empty() || k_a.iter().chain(&k_s).any(|c| !c.is_finite()) {
            return Err(ContactError::Domain {
                what: "k(T) coefficients",
                value: f64::NAN,
                valid: "at least one finite coefficient each for k_A and k_S",
            });
        }
        let (lo, hi) = fitted_range_c;
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(ContactError::Domain {
                what: "fitted temperature range",
                value: lo,
                valid: "finite, min <= max (°C)",
            });
        }
        Ok(TemperatureLaw {
            k_a,
            k_s,
            fitted_range_c,
        })
    }

    /// (k_A, k_S) at T (°C). Outside the fitted range: an error (use [`Self::eval_clamped`] to
    /// hold the value at the nearest end instead). Values violating 0 < k_S ≤ k_A ≤ 1 are
    /// errors.
    pub fn eval(&self, t_c: f64) -> Result<(f64, f64), ContactError> {
        check_finite("temperature", t_c)?;
        let (lo, hi) = self.fitted_range_c;
        if t_c < lo || t_c > hi {
            return Err(ContactError::Domain {
                what: "temperature (°C)",
                value: t_c,
                valid: "inside the range k(T) was fitted over",
            });
        }
        self.values(t_c)
    }

    /// (k_A, k_S) at T clamped into the fitted range: the documented limit for simulators that
    /// run outside it.
    pub fn eval_clamped(&self, t_c: f64) -> Result<(f64, f64), ContactError> {
        check_finite("temperature", t_c)?;
        self.values(t_c.clamp(self.fitted_range_c.0, self.fitted_range_c.1))
    }

    fn values(&self, t: f64) -> Result<(f64, f64), ContactError> {
        let (ka, ks) = (horner(&self.k_a, t), horner(&self.k_s, t));
        if !(ka > 0.0 && ka <= 1.0) {
            return Err(ContactError::Domain {
                what: "k_A(T)",
                value: ka,
                valid: "0 < k_A <= 1 at this temperature",
            });
        }
        if !(ks > 0.0 && ks <= ka) {
            return Err(ContactError::Domain {
                what: "k_S(T)",
                value: ks,
                valid: "0 < k_S <= k_A at this temperature",
            });
        }
        Ok((ka, ks))
    }

    /// Polach parameters at temperature T: `base` with k_A, k_S replaced by k_A(T), k_S(T).
    pub fn params_at(&self, base: &PolachParams, t_c: f64) -> Result<PolachParams, ContactError> {
        let (k_a, k_s) = self.eval(t_c)?;
        Ok(PolachParams { k_a, k_s, ..*base })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UIC-Z1-like patch: Q = 50 kN per wheel, a = 4.3 mm, b = 6 mm, G = 80.8 GPa.
    pub(crate) fn patch() -> ContactPatch {
        ContactPatch {
            a_m: 0.0043,
            b_m: 0.006,
            g_pa: 8.08e10,
            c11: 3.8,
            c22: 3.2,
        }
    }

    #[test]
    fn small_creep_slope_is_half_sum_of_k_times_kalker() {
        for p in [PolachParams::DRY, PolachParams::WET] {
            let (q, v) = (50_000.0, 30.0);
            let w = 1e-7 * v;
            let f = polach(&patch(), &p, q, v, w, 0.0).unwrap();
            let pt = patch();
            let expected = (p.k_a + p.k_s) / 2.0 * pt.g_pa * pt.a_m * pt.b_m * pt.c11;
            let slope = f.fx_n / (w / v);
            assert!(
                (slope - expected).abs() / expected < 1e-4,
                "{slope} vs {expected}"
            );
        }
    }

    #[test]
    fn odd_bounded_and_a_peak_then_decline_for_dry_and_wet() {
        for p in [PolachParams::DRY, PolachParams::WET] {
            let (q, v) = (50_000.0, 30.0);
            let f = |w: f64| polach(&patch(), &p, q, v, w, 0.0).unwrap().fx_n;
            let mut peak_w = 0.0;
            let mut peak = 0.0;
            for i in 1..=1000 {
                let w = i as f64 * 0.01;
                let fw = f(w);
                assert!((f(-w) + fw).abs() < 1e-9 * fw.abs().max(1.0), "odd");
                assert!(fw.abs() <= p.mu(w) * q * (1.0 + 1e-12), "bounded by μQ");
                if fw > peak {
                    peak = fw;
                    peak_w = w;
                }
            }
            assert!(
                peak_w > 0.01 && peak_w < 10.0,
                "interior peak at {peak_w} m/s"
            );
            assert!(f(10.0) < 0.9 * peak, "declines after the peak");
        }
    }

    #[test]
    fn standstill_and_bad_parameters() {
        let p = PolachParams::DRY;
        assert_eq!(polach(&patch(), &p, 5e4, 0.0, 0.0, 0.0).unwrap().fx_n, 0.0);
        assert!(polach(&patch(), &p, 5e4, 0.0, 0.1, 0.0).is_err());
        assert!(polach(&patch(), &p, 0.0, 10.0, 0.1, 0.0).is_err());
        assert!(polach(&patch(), &p, 5e4, f64::NAN, 0.1, 0.0).is_err());
        assert!(PolachParams {
            k_s: 0.5,
            k_a: 0.3,
            ..p
        }
        .check()
        .is_err());
        assert!(PolachParams::DRY.check().is_ok() && PolachParams::WET.check().is_ok());
    }

    #[test]
    fn temperature_law_evaluates_inside_its_range_and_limits_outside() {
        // Rises from +20 °C to −20 °C, dips to −40 °C (seed 004's trend).
        let law = TemperatureLaw::new(
            vec![0.6, -0.01, -0.0002],
            vec![0.3, -0.005, -0.0001],
            (-40.0, 20.0),
        )
        .unwrap();
        let (ka20, _) = law.eval(20.0).unwrap();
        let (ka_m20, ks_m20) = law.eval(-20.0).unwrap();
        let (ka_m40, _) = law.eval(-40.0).unwrap();
        assert!(ka_m20 > ka20 && ka_m40 < ka_m20, "{ka20} {ka_m20} {ka_m40}");
        assert!(ks_m20 <= ka_m20);
        assert!(law.eval(30.0).is_err());
        assert_eq!(law.eval_clamped(30.0).unwrap(), law.eval(20.0).unwrap());
        let p = law.params_at(&PolachParams::WET, 0.0).unwrap();
        assert_eq!((p.k_a, p.k_s), (0.6, 0.3));
        assert!(TemperatureLaw::new(vec![], vec![1.0], (0.0, 1.0)).is_err());
        let bad = TemperatureLaw::new(vec![1.5], vec![0.1], (0.0, 1.0)).unwrap();
        assert!(bad.eval(0.5).is_err(), "k_A > 1");
    }
}
