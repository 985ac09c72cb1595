//! Hertz normal contact of wheel and rail (seed 001_20bb3776135e7607.txt eq. 1–5).
//!
//! Semi-axes: a_e = m·c, b_e = n·c with c = [3 N (1 − ν²) / (2 E (A + B))]^(1/3) (eq. 1), where
//! A and B are the principal relative curvatures (eq. 2, 1/m), θ = arccos(|B − A| / (A + B))
//! (eq. 3), area π a b (eq. 4), pressure p(x, y) = p_max √(1 − (x/a)² − (y/b)²) with
//! p_max = 3N / (2π a b) (eq. 5). Identical materials for wheel and rail (one E, one ν).
//!
//! m and n come from complete elliptic integrals, not a table. With k = (minor/major semi-axis)
//! and e² = 1 − k² (Johnson, Contact Mechanics, 1985, eq. 4.39–4.41):
//!   B/A = [E(e)/k² − K(e)] / [K(e) − E(e)]       (the larger over the smaller curvature),
//!   m = [2 E(e) / (π k²)]^(1/3),  n = k·m.
//! The major semi-axis lies in the direction of the smaller curvature sum.

use super::{check_finite, ContactError};
use std::f64::consts::{FRAC_PI_2, PI};

/// Complete elliptic integrals of the first and second kind, K(e) and E(e), for modulus
/// e = √(1 − k²), given the complementary modulus k ∈ (0, 1], by the arithmetic–geometric
/// mean (Abramowitz & Stegun 17.6). Relative accuracy ~1e-15.
pub fn elliptic_ke(k: f64) -> (f64, f64) {
    let (mut a, mut b) = (1.0f64, k);
    let mut c2 = 1.0 - k * k; // c_0² = e²
    let mut sum = 0.5 * c2; // Σ 2^(n−1) c_n², n = 0
    let mut pow = 0.5;
    for _ in 0..40 {
        let an = 0.5 * (a + b);
        let cn = 0.5 * (a - b);
        b = (a * b).sqrt();
        a = an;
        pow *= 2.0;
        c2 = cn * cn;
        sum += pow * c2;
        if c2 <= 1e-32 * a * a {
            break;
        }
    }
    let kk = PI / (2.0 * a);
    (kk, kk * (1.0 - sum))
}

/// B/A as a function of the semi-axis ratio k (minor/major), and K(e), E(e).
fn curvature_ratio(k: f64) -> (f64, f64, f64) {
    let (kk, ee) = elliptic_ke(k);
    ((ee / (k * k) - kk) / (kk - ee), kk, ee)
}

/// The Hertz coefficients for a given θ: the major one `m`, the minor one `n`, and the ratio
/// k = n/m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HertzCoefficients {
    pub m: f64,
    pub n: f64,
    pub k: f64,
}

/// Largest curvature ratio B/A accepted (k ≈ 1e-5): beyond it the contact is a line, not an
/// ellipse.
pub const MAX_CURVATURE_RATIO: f64 = 1e8;

/// m and n for the ratio `r` = (larger curvature sum) / (smaller), r ≥ 1.
///
/// Solves B/A(k) = r for k by safeguarded Newton steps in ln k (derivative by a secant of the
/// last two iterates) from Greenwood's estimate k ≈ r^(−2/3); near r = 1 uses the series
/// B/A ≈ 1 + (3/4) e².
pub fn coefficients_for_ratio(r: f64) -> Result<HertzCoefficients, ContactError> {
    if !(r.is_finite() && r >= 1.0) || r > MAX_CURVATURE_RATIO {
        return Err(ContactError::Domain {
            what: "curvature ratio B/A",
            value: r,
            valid: "1 <= B/A <= 1e8 (an elliptic contact)",
        });
    }
    let k = if r - 1.0 < 1e-6 {
        // e² ≈ (4/3)(r − 1); second-order error ~e⁴ < 2e-12.
        (1.0 - 4.0 / 3.0 * (r - 1.0)).sqrt()
    } else {
        solve_k(r)
    };
    let (_, ee) = elliptic_ke(k);
    let m = (2.0 * ee / (PI * k * k)).cbrt();
    Ok(HertzCoefficients { m, n: k * m, k })
}

/// Bisection-safeguarded secant iteration on f(u) = ln(B/A(e^u)) − ln r, u = ln k ∈ [ln 1e-6, 0).
fn solve_k(r: f64) -> f64 {
    let target = r.ln();
    let f = |u: f64| curvature_ratio(u.exp()).0.ln() - target;
    // f decreases in u (larger k → rounder ellipse → smaller ratio).
    let (mut lo, mut hi) = (-14.0f64, -1e-9f64); // f(lo) > 0 > f(hi)
    let mut u0 = (-2.0 / 3.0 * target).clamp(lo + 1e-3, hi - 1e-12);
    let mut f0 = f(u0);
    let mut u1 = (u0 + if f0 > 0.0 { 0.05 } else { -0.05 }).clamp(lo, hi);
    let mut f1 = f(u1);
    for _ in 0..60 {
        if f1 > 0.0 {
            lo = lo.max(u1)
        } else {
            hi = hi.min(u1)
        }
        if f0 > 0.0 {
            lo = lo.max(u0)
        } else {
            hi = hi.min(u0)
        }
        let mut u2 = if f1 != f0 {
            u1 - f1 * (u1 - u0) / (f1 - f0)
        } else {
            0.5 * (lo + hi)
        };
        if !(u2 > lo && u2 < hi) {
            u2 = 0.5 * (lo + hi);
        }
        if (u2 - u1).abs() < 1e-15 {
            return u2.exp();
        }
        u0 = u1;
        f0 = f1;
        u1 = u2;
        f1 = f(u1);
        if f1 == 0.0 {
            break;
        }
    }
    u1.exp()
}

/// Inputs of a Hertz contact. Radii are signed: positive for a convex surface (centre of
/// curvature inside the body), negative for concave, `f64::INFINITY` for flat.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HertzInput {
    /// Normal force N, newtons, > 0.
    pub normal_n: f64,
    /// Young's modulus E of wheel and rail, Pa, > 0 (steel 2.1e11).
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio ν, 0 ≤ ν < 0.5 (steel 0.3).
    pub poisson: f64,
    /// Wheel rolling radius (longitudinal curvature), m.
    pub wheel_rolling_radius_m: f64,
    /// Wheel profile radius in the lateral plane, m (negative for a concave throat).
    pub wheel_lateral_radius_m: f64,
    /// Rail radius in the running direction, m (`INFINITY` on straight track).
    pub rail_longitudinal_radius_m: f64,
    /// Rail head (crown) radius in the lateral plane, m.
    pub rail_lateral_radius_m: f64,
}

/// The contact ellipse and its pressure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HertzContact {
    /// Semi-axis in the rolling direction, m.
    pub a_m: f64,
    /// Semi-axis across the rolling direction, m.
    pub b_m: f64,
    /// Area π a b (eq. 4), m².
    pub area_m2: f64,
    /// Peak pressure 3N/(2π a b) (eq. 5), Pa.
    pub p_max_pa: f64,
    /// θ of eq. 3, radians.
    pub theta_rad: f64,
    pub coefficients: HertzCoefficients,
}

impl HertzContact {
    /// Normal pressure at (x, y) in the contact plane (x rolling direction), Pa; 0 outside the
    /// ellipse (seed 001 eq. 5).
    pub fn pressure_pa(&self, x_m: f64, y_m: f64) -> f64 {
        let r = 1.0 - (x_m / self.a_m).powi(2) - (y_m / self.b_m).powi(2);
        if r > 0.0 {
            self.p_max_pa * r.sqrt()
        } else {
            0.0
        }
    }

    /// a/b.
    pub fn aspect(&self) -> f64 {
        self.a_m / self.b_m
    }
}

/// Hertz contact from the principal relative curvatures (1/m): `curv_long` = ½(1/R_wheel,x +
/// 1/R_rail,x) in the rolling direction, `curv_lat` = ½(1/R_wheel,y + 1/R_rail,y) across it.
/// Both must be > 0. Seed 001 Table 1 (S1002/60E1) has A = 0.104 (lateral), B = 1.087
/// (longitudinal).
pub fn hertz_from_curvatures(
    normal_n: f64,
    youngs_modulus_pa: f64,
    poisson: f64,
    curv_long: f64,
    curv_lat: f64,
) -> Result<HertzContact, ContactError> {
    check_finite("normal force N", normal_n)?;
    check_finite("Young's modulus E", youngs_modulus_pa)?;
    check_finite("Poisson's ratio", poisson)?;
    check_finite("longitudinal curvature", curv_long)?;
    check_finite("lateral curvature", curv_lat)?;
    if normal_n <= 0.0 {
        return Err(ContactError::Domain {
            what: "normal force N",
            value: normal_n,
            valid: "N > 0 (the wheel must press on the rail)",
        });
    }
    if youngs_modulus_pa <= 0.0 {
        return Err(ContactError::Domain {
            what: "Young's modulus E",
            value: youngs_modulus_pa,
            valid: "E > 0",
        });
    }
    if !(0.0..0.5).contains(&poisson) {
        return Err(ContactError::Domain {
            what: "Poisson's ratio",
            value: poisson,
            valid: "0 <= nu < 0.5",
        });
    }
    for (what, c) in [
        ("longitudinal curvature", curv_long),
        ("lateral curvature", curv_lat),
    ] {
        if c <= 0.0 {
            return Err(ContactError::Domain {
                what,
                value: c,
                valid: "> 0 (1/m): the surfaces must be conformal enough to touch in an ellipse",
            });
        }
    }
    let (small, large) = if curv_long <= curv_lat {
        (curv_long, curv_lat)
    } else {
        (curv_lat, curv_long)
    };
    let coefficients = coefficients_for_ratio(large / small)?;
    let sum = curv_long + curv_lat;
    let c = (3.0 * normal_n * (1.0 - poisson * poisson) / (2.0 * youngs_modulus_pa * sum)).cbrt();
    let (major, minor) = (coefficients.m * c, coefficients.n * c);
    // The major semi-axis lies along the smaller curvature.
    let (a_m, b_m) = if curv_long <= curv_lat {
        (major, minor)
    } else {
        (minor, major)
    };
    let area_m2 = PI * a_m * b_m;
    Ok(HertzContact {
        a_m,
        b_m,
        area_m2,
        p_max_pa: 1.5 * normal_n / area_m2,
        theta_rad: ((large - small) / sum).acos(),
        coefficients,
    })
}

/// Hertz contact from the radii of wheel and rail (seed 001 eq. 2).
pub fn hertz(input: &HertzInput) -> Result<HertzContact, ContactError> {
    let inv = |r: f64| if r.is_infinite() { 0.0 } else { 1.0 / r };
    for (what, r) in [
        ("wheel rolling radius", input.wheel_rolling_radius_m),
        ("wheel lateral radius", input.wheel_lateral_radius_m),
        ("rail longitudinal radius", input.rail_longitudinal_radius_m),
        ("rail lateral radius", input.rail_lateral_radius_m),
    ] {
        if r.is_nan() || r == 0.0 {
            return Err(ContactError::Domain {
                what,
                value: r,
                valid: "a nonzero radius in m, or infinity for a flat surface",
            });
        }
    }
    let curv_long =
        0.5 * (inv(input.wheel_rolling_radius_m) + inv(input.rail_longitudinal_radius_m));
    let curv_lat = 0.5 * (inv(input.wheel_lateral_radius_m) + inv(input.rail_lateral_radius_m));
    hertz_from_curvatures(
        input.normal_n,
        input.youngs_modulus_pa,
        input.poisson,
        curv_long,
        curv_lat,
    )
}

/// θ (radians) → m, n: θ = arccos((B − A)/(A + B)) with B ≥ A, so B/A = (1 + cos θ)/(1 − cos θ).
pub fn coefficients_for_theta(theta_rad: f64) -> Result<HertzCoefficients, ContactError> {
    check_finite("theta", theta_rad)?;
    if !(theta_rad > 0.0 && theta_rad <= FRAC_PI_2 + 1e-12) {
        return Err(ContactError::Domain {
            what: "theta",
            value: theta_rad,
            valid: "0 < theta <= pi/2",
        });
    }
    let c = theta_rad.cos().max(0.0);
    coefficients_for_ratio((1.0 + c) / (1.0 - c))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elliptic_integrals_match_tabulated_values() {
        // K and E at modulus sin 45° (k' = cos 45°), Abramowitz & Stegun Table 17.1.
        let (k, e) = elliptic_ke(std::f64::consts::FRAC_1_SQRT_2);
        assert!((k - 1.854_074_677_301_372).abs() < 1e-14, "{k}");
        assert!((e - 1.350_643_881_047_675_5).abs() < 1e-14, "{e}");
        let (k, e) = elliptic_ke(1.0);
        assert_eq!((k, e), (FRAC_PI_2, FRAC_PI_2));
    }

    #[test]
    fn m_n_reproduce_reference_values_to_three_digits() {
        // reference-values.md (Hertz): θ → (m, n).
        for (deg, m, n) in [
            (30.0, 2.731, 0.493),
            (35.0, 2.396, 0.531),
            (45.0, 1.927, 0.604),
            (60.0, 1.486, 0.717),
            (90.0, 1.0, 1.0),
        ] {
            let c = coefficients_for_theta(f64::to_radians(deg)).unwrap();
            assert!((c.m - m).abs() < 0.0015, "θ {deg}: m {} vs {m}", c.m);
            assert!((c.n - n).abs() < 0.0015, "θ {deg}: n {} vs {n}", c.n);
        }
    }

    #[test]
    fn circular_contact_is_exact() {
        // Sphere-like contact: equal curvatures → a = b = c, m = n = 1 exactly.
        let h = hertz_from_curvatures(10_000.0, 2.1e11, 0.3, 1.0, 1.0).unwrap();
        let c = (3.0 * 10_000.0 * (1.0 - 0.09) / (2.0 * 2.1e11 * 2.0f64)).cbrt();
        assert_eq!(h.coefficients.m, 1.0);
        assert_eq!(h.coefficients.n, 1.0);
        assert_eq!(h.a_m, c);
        assert_eq!(h.b_m, c);
        assert_eq!(h.p_max_pa, 1.5 * 10_000.0 / (PI * c * c));
    }

    #[test]
    fn seed_001_table_1_s1002_on_60e1() {
        // A = 0.104 1/m (lateral), B = 1.087 1/m (longitudinal), E = 210 GPa, ν = 0.3.
        for (n_kn, a_cm, b_cm, p_kn_cm2) in
            [(40.0, 0.317, 1.465, 41.2), (110.0, 0.444, 2.053, 57.7)]
        {
            let h = hertz_from_curvatures(n_kn * 1e3, 2.1e11, 0.3, 1.087, 0.104).unwrap();
            let rel = |x: f64, y: f64| (x - y).abs() / y;
            assert!(
                rel(h.a_m * 100.0, a_cm) < 0.015,
                "{n_kn} kN: a {} cm",
                h.a_m * 100.0
            );
            assert!(
                rel(h.b_m * 100.0, b_cm) < 0.015,
                "{n_kn} kN: b {} cm",
                h.b_m * 100.0
            );
            assert!(
                rel(h.p_max_pa / 1e7, p_kn_cm2) < 0.015,
                "{n_kn} kN: p_max {} kN/cm²",
                h.p_max_pa / 1e7
            );
            assert!((h.theta_rad.to_degrees() - 34.4).abs() < 0.1);
        }
    }

    #[test]
    fn radii_with_flat_rail_and_concave_wheel() {
        let flat_wheel = HertzInput {
            normal_n: 60_000.0,
            youngs_modulus_pa: 2.1e11,
            poisson: 0.3,
            wheel_rolling_radius_m: 0.46,
            wheel_lateral_radius_m: f64::INFINITY,
            rail_longitudinal_radius_m: f64::INFINITY,
            rail_lateral_radius_m: 0.3,
        };
        // Lateral curvature ½/0.3 = 1.667 > longitudinal ½/0.46 = 1.087: long axis runs along the rail.
        let h = hertz(&flat_wheel).unwrap();
        assert!(h.a_m > h.b_m, "{h:?}");
        // A concave wheel profile (−0.5 m) lowers the lateral curvature to 0.667 < 1.087.
        let concave = hertz(&HertzInput {
            wheel_lateral_radius_m: -0.5,
            ..flat_wheel
        })
        .unwrap();
        assert!(
            concave.a_m < concave.b_m && concave.b_m > h.b_m,
            "{concave:?}"
        );
        let same = hertz_from_curvatures(
            60_000.0,
            2.1e11,
            0.3,
            0.5 / 0.46,
            0.5 * (1.0 / 0.3 - 1.0 / 0.5),
        )
        .unwrap();
        assert_eq!(same, concave);
        assert!(hertz(&HertzInput {
            rail_lateral_radius_m: 0.0,
            ..flat_wheel
        })
        .is_err());
    }

    #[test]
    fn out_of_domain_inputs_are_errors_not_nan() {
        assert!(hertz_from_curvatures(0.0, 2.1e11, 0.3, 1.0, 0.1).is_err());
        assert!(hertz_from_curvatures(-5.0, 2.1e11, 0.3, 1.0, 0.1).is_err());
        assert!(hertz_from_curvatures(f64::NAN, 2.1e11, 0.3, 1.0, 0.1).is_err());
        assert!(hertz_from_curvatures(1e4, 2.1e11, 0.5, 1.0, 0.1).is_err());
        assert!(hertz_from_curvatures(1e4, 2.1e11, 0.3, 1.0, 0.0).is_err());
        assert!(
            hertz_from_curvatures(1e4, 2.1e11, 0.3, 1.0, 1e-9).is_err(),
            "ratio 1e9 is a line contact"
        );
        let e = hertz_from_curvatures(-5.0, 2.1e11, 0.3, 1.0, 0.1)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "normal force N = -5 is outside its domain: N > 0 (the wheel must press on the rail)"
        );
    }
}
