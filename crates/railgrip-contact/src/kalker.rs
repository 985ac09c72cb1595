//! Kalker's linear theory: creepage coefficients C11, C22, C23, C33 and the linear creep
//! forces and spin moment (seed 002_8d8769283f5e9cb6.txt eq. 6, seed 001_20bb3776135e7607.txt
//! eq. 9–11).
//!
//! Coefficients: Kalker 1990, Table E.3, as listed in ../shared/design/reference-values.md,
//! interpolated linearly in g = min(a/b, b/a) and, across ν, linearly in 1/C. C33 has tables
//! for ν = 0, 0.25 and 0.5 on both branches (a ≤ b and a > b); ν = 0.25 is [pub], ν = 0 and 0.5
//! are [derived] (reference-values.md says how).
//!
//! Sign convention (railgrip's, used by every contact law here): creepage s = Δv / v with
//! Δv = v − r ω the slip velocity (positive in braking), and the tangential force T is the force
//! the rail exerts on the wheel *against* the wheel's sliding, positive when it retards the
//! vehicle. So T has the sign of s: T_x = G a b C11 s_x. The seeds write F = −f ξ with the
//! creepage of the contact point's velocity (r ω − v); that is the same force.

// Kalker's table holds C22 = 3.14 (ν = 0.25, a/b = 0.6; ν = 0.5, a/b = 0.5): a measurement, not π.
#![allow(clippy::approx_constant)]

use super::{check_finite, ContactError};

/// g = a/b or b/a at the table's rows.
const G: [f64; 10] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0];

/// ν = 0.25, a ≤ b (rows g = a/b): C11, C22, C23.
const NU025_A_LE_B: [[f64; 3]; 10] = [
    [3.31, 2.52, 0.473],
    [3.37, 2.63, 0.603],
    [3.44, 2.75, 0.715],
    [3.53, 2.88, 0.823],
    [3.62, 3.01, 0.929],
    [3.72, 3.14, 1.03],
    [3.81, 3.28, 1.14],
    [3.91, 3.41, 1.25],
    [4.01, 3.54, 1.36],
    [4.12, 3.67, 1.47],
];
/// ν = 0.25, a > b (rows g = b/a).
const NU025_A_GT_B: [[f64; 3]; 10] = [
    [11.7, 12.8, 14.6],
    [7.78, 8.14, 6.63],
    [6.34, 6.40, 4.32],
    [5.57, 5.48, 3.24],
    [5.10, 4.90, 2.62],
    [4.78, 4.50, 2.23],
    [4.54, 4.21, 1.95],
    [4.36, 3.99, 1.75],
    [4.22, 3.81, 1.59],
    [4.12, 3.67, 1.47],
];
/// ν = 0, a ≤ b: C11 = C22 and C23.
const NU0_C11: [f64; 10] = [2.51, 2.59, 2.68, 2.78, 2.88, 2.98, 3.09, 3.19, 3.29, 3.40];
const NU0_C23: [f64; 10] = [
    0.334, 0.483, 0.607, 0.720, 0.827, 0.930, 1.03, 1.13, 1.23, 1.33,
];
/// ν = 0.5, a ≤ b, at g = 0.1, 0.5, 1.0 only.
const NU05_G: [f64; 3] = [0.1, 0.5, 1.0];
const NU05: [[f64; 3]; 3] = [[4.85, 2.53, 0.731], [4.83, 3.14, 1.07], [5.20, 3.98, 1.63]];

/// C33 on the rows g = 0.1 … 1.0: a ≤ b (g = a/b) and a > b (g = b/a), for ν = 0, 0.25, 0.5.
const C33_A_LE_B: [[f64; 10]; 3] = [
    [6.42, 3.46, 2.49, 2.02, 1.74, 1.56, 1.43, 1.34, 1.27, 1.21],
    [8.28, 4.27, 2.96, 2.32, 1.93, 1.68, 1.50, 1.37, 1.27, 1.19],
    [11.7, 5.66, 3.72, 2.77, 2.22, 1.86, 1.60, 1.42, 1.27, 1.16],
];
const C33_A_GT_B: [[f64; 10]; 3] = [
    [
        0.795, 0.828, 0.868, 0.912, 0.958, 1.01, 1.05, 1.10, 1.16, 1.21,
    ],
    [
        0.526, 0.601, 0.674, 0.747, 0.819, 0.892, 0.965, 1.040, 1.110, 1.19,
    ],
    [
        0.228, 0.341, 0.446, 0.549, 0.650, 0.751, 0.852, 0.954, 1.06, 1.16,
    ],
];

/// C33 at g on one branch, ν-interpolated linearly in 1/C like the other coefficients.
fn c33(branch: &[[f64; 10]; 3], g: f64, nu: f64) -> f64 {
    let at = |k: usize| lerp_table(&G, &branch[k], g);
    let (lo, hi, t) = if nu <= 0.25 {
        (at(0), at(1), nu / 0.25)
    } else {
        (at(1), at(2), (nu - 0.25) / 0.25)
    };
    if t == 0.0 {
        return lo;
    }
    if t == 1.0 {
        return hi;
    }
    1.0 / ((1.0 - t) / lo + t / hi)
}

/// Kalker's coefficients at one (a/b, ν).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KalkerCoefficients {
    pub c11: f64,
    pub c22: f64,
    pub c23: f64,
    /// Spin coefficient C33 (spin moment M_z = G (ab)² C33 φ − …).
    pub c33: f64,
    /// True when a > b and ν ≠ 0.25: the table has that branch for ν = 0.25 only, so the
    /// ν-dependence is carried over from the a = b row (an approximation, documented).
    pub nu_extrapolated: bool,
}

/// The bracketing interval of `x` in the ascending `xs` and the fraction within it.
fn bracket(xs: &[f64], x: f64) -> (usize, f64) {
    let i = xs
        .windows(2)
        .position(|w| x <= w[1])
        .unwrap_or(xs.len() - 2);
    (i, (x - xs[i]) / (xs[i + 1] - xs[i]))
}

fn lerp_table(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    let (i, t) = bracket(xs, x);
    ys[i] + t * (ys[i + 1] - ys[i])
}

fn row(table: &[[f64; 3]], xs: &[f64], g: f64) -> [f64; 3] {
    let (i, t) = bracket(xs, g);
    std::array::from_fn(|j| table[i][j] + t * (table[i + 1][j] - table[i][j]))
}

/// ν-interpolation of 1/C between the tables at ν = 0, 0.25, 0.5 (a ≤ b, g = a/b).
fn a_le_b(g: f64, nu: f64) -> [f64; 3] {
    let c025 = row(&NU025_A_LE_B, &G, g);
    let c0 = [
        lerp_table(&G, &NU0_C11, g),
        lerp_table(&G, &NU0_C11, g),
        lerp_table(&G, &NU0_C23, g),
    ];
    let c05 = row(&NU05, &NU05_G, g);
    let (lo, hi, t) = if nu <= 0.25 {
        (c0, c025, nu / 0.25)
    } else {
        (c025, c05, (nu - 0.25) / 0.25)
    };
    // Table nodes exactly (1/(1/C) would round off the last digit).
    if t == 0.0 {
        return lo;
    }
    if t == 1.0 {
        return hi;
    }
    std::array::from_fn(|j| 1.0 / ((1.0 - t) / lo[j] + t / hi[j]))
}

/// Kalker's C11, C22, C23 for semi-axes a (rolling direction) and b, Poisson's ratio ν.
///
/// Domain: 0.1 ≤ a/b ≤ 10 (the table's range; outside it Kalker's asymptotic expressions would
/// be needed) and 0 ≤ ν ≤ 0.5.
pub fn coefficients(a_m: f64, b_m: f64, nu: f64) -> Result<KalkerCoefficients, ContactError> {
    check_finite("semi-axis a", a_m)?;
    check_finite("semi-axis b", b_m)?;
    check_finite("Poisson's ratio", nu)?;
    if a_m <= 0.0 || b_m <= 0.0 {
        return Err(ContactError::Domain {
            what: "semi-axes a, b",
            value: a_m.min(b_m),
            valid: "a > 0 and b > 0 (m)",
        });
    }
    if !(0.0..=0.5).contains(&nu) {
        return Err(ContactError::Domain {
            what: "Poisson's ratio",
            value: nu,
            valid: "0 <= nu <= 0.5 (Kalker's table)",
        });
    }
    let ratio = a_m / b_m;
    if !(0.1..=10.0).contains(&ratio) {
        return Err(ContactError::Domain {
            what: "a/b",
            value: ratio,
            valid: "0.1 <= a/b <= 10: beyond Kalker's table (asymptotic range not implemented)",
        });
    }
    if ratio <= 1.0 {
        let [c11, c22, c23] = a_le_b(ratio, nu);
        return Ok(KalkerCoefficients {
            c11,
            c22,
            c23,
            c33: c33(&C33_A_LE_B, ratio, nu),
            nu_extrapolated: false,
        });
    }
    let g = 1.0 / ratio;
    let base = row(&NU025_A_GT_B, &G, g);
    let c33 = c33(&C33_A_GT_B, g, nu);
    if (nu - 0.25).abs() < 1e-12 {
        return Ok(KalkerCoefficients {
            c11: base[0],
            c22: base[1],
            c23: base[2],
            c33,
            nu_extrapolated: false,
        });
    }
    // Carry the ν-dependence of the round contact (both branches meet at a = b).
    let at_nu = a_le_b(1.0, nu);
    let at_025 = a_le_b(1.0, 0.25);
    let [c11, c22, c23] = std::array::from_fn(|j| base[j] * at_nu[j] / at_025[j]);
    Ok(KalkerCoefficients {
        c11,
        c22,
        c23,
        c33,
        nu_extrapolated: true,
    })
}

/// The linear creep forces and spin moment of a contact (seed 002 eq. 6; seed 001 eq. 10–11;
/// Kalker 1990).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearCreep {
    /// Longitudinal force G a b C11 s_x, N.
    pub fx_n: f64,
    /// Lateral force G a b C22 s_y + G (ab)^(3/2) C23 φ, N.
    pub fy_n: f64,
    /// Spin moment about the contact normal, N·m: M_z = G (ab)² C33 φ − G (ab)^(3/2) C23 s_y.
    /// Kalker writes M_z = G (ab)^(3/2) C23 η − G (ab)² C33 φ for the moment on the body with
    /// the creepage of the contact point; here, as for the forces, the moment of the traction
    /// that opposes the sliding, so both terms change sign.
    pub mz_nm: f64,
    /// Seed 001 eq. 9: |s| + |φ/1000| ≤ 0.002 (φ in 1/m), where the linear theory holds.
    pub within_linear_validity: bool,
}

/// Linear creep forces for shear modulus `g_pa` (Pa), semi-axes (m), coefficients, creepages
/// s_x, s_y (dimensionless) and spin φ (1/m).
pub fn linear_creep(
    g_pa: f64,
    a_m: f64,
    b_m: f64,
    c: &KalkerCoefficients,
    sx: f64,
    sy: f64,
    spin_per_m: f64,
) -> Result<LinearCreep, ContactError> {
    for (what, x) in [
        ("shear modulus G", g_pa),
        ("creepage s_x", sx),
        ("creepage s_y", sy),
        ("spin", spin_per_m),
    ] {
        check_finite(what, x)?;
    }
    if g_pa <= 0.0 {
        return Err(ContactError::Domain {
            what: "shear modulus G",
            value: g_pa,
            valid: "G > 0 (Pa)",
        });
    }
    let ab = a_m * b_m;
    let ab15 = ab * ab.sqrt();
    Ok(LinearCreep {
        fx_n: g_pa * ab * c.c11 * sx,
        fy_n: g_pa * ab * c.c22 * sy + g_pa * ab15 * c.c23 * spin_per_m,
        mz_nm: g_pa * ab * ab * c.c33 * spin_per_m - g_pa * ab15 * c.c23 * sy,
        within_linear_validity: sx.hypot(sy) + (spin_per_m / 1000.0).abs() <= 0.002,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_rows_are_reproduced_exactly() {
        for (i, g) in G.iter().enumerate() {
            let c = coefficients(*g, 1.0, 0.25).unwrap();
            assert_eq!([c.c11, c.c22, c.c23], NU025_A_LE_B[i], "a/b = {g}");
            // b/a = g is reached through a/b = 1/g: equal up to that division's rounding.
            let c = coefficients(1.0, *g, 0.25).unwrap();
            for (x, y) in [c.c11, c.c22, c.c23].iter().zip(NU025_A_GT_B[i]) {
                assert!((x - y).abs() < 1e-12 * y, "b/a = {g}: {x} vs {y}");
            }
            let c = coefficients(*g, 1.0, 0.0).unwrap();
            assert!((c.c11 - NU0_C11[i]).abs() < 1e-12 && (c.c23 - NU0_C23[i]).abs() < 1e-12);
        }
        let c = coefficients(0.5, 1.0, 0.5).unwrap();
        assert!(
            (c.c11 - 4.83).abs() < 1e-12
                && (c.c22 - 3.14).abs() < 1e-12
                && (c.c23 - 1.07).abs() < 1e-12
        );
    }

    #[test]
    fn interpolation_is_linear_in_g_and_in_inverse_c_across_nu() {
        let c = coefficients(0.35, 1.0, 0.25).unwrap();
        assert!((c.c11 - 0.5 * (3.44 + 3.53)).abs() < 1e-12);
        let c = coefficients(0.5, 1.0, 0.375).unwrap();
        let expect = 1.0 / (0.5 / 3.62 + 0.5 / 4.83);
        assert!((c.c11 - expect).abs() < 1e-12, "{} vs {expect}", c.c11);
        assert!(!c.nu_extrapolated);
        let c = coefficients(2.0, 1.0, 0.3).unwrap();
        assert!(c.nu_extrapolated);
    }

    #[test]
    fn branches_meet_at_the_round_contact_for_any_nu() {
        for nu in [0.0, 0.1, 0.25, 0.3, 0.5] {
            let lo = coefficients(1.0, 1.0, nu).unwrap();
            let hi = coefficients(1.0 + 1e-12, 1.0, nu).unwrap();
            assert!(
                (lo.c11 - hi.c11).abs() < 1e-9 && (lo.c23 - hi.c23).abs() < 1e-9,
                "ν {nu}"
            );
        }
    }

    #[test]
    fn c33_reproduces_its_rows_on_both_branches_for_each_nu() {
        for (k, nu) in [0.0, 0.25, 0.5].into_iter().enumerate() {
            for (i, g) in G.iter().enumerate() {
                let lo = coefficients(*g, 1.0, nu).unwrap().c33;
                assert!((lo - C33_A_LE_B[k][i]).abs() < 1e-12, "ν {nu} a/b {g}");
                let hi = coefficients(1.0, *g, nu).unwrap().c33;
                assert!((hi - C33_A_GT_B[k][i]).abs() < 1e-9, "ν {nu} b/a {g}: {hi}");
            }
        }
        // Between ν nodes: linear in 1/C.
        let c = coefficients(0.5, 1.0, 0.125).unwrap().c33;
        assert!((c - 1.0 / (0.5 / 1.74 + 0.5 / 1.93)).abs() < 1e-12);
        // The branches meet at a = b.
        let (lo, hi) = (
            coefficients(1.0, 1.0, 0.3).unwrap().c33,
            coefficients(1.0 + 1e-12, 1.0, 0.3).unwrap().c33,
        );
        assert!((lo - hi).abs() < 1e-9);
    }

    #[test]
    fn spin_moment_follows_kalker_with_the_opposing_traction_sign() {
        let c = coefficients(0.5, 1.0, 0.25).unwrap();
        let (g, a, b) = (8.1e10, 0.003, 0.006);
        let ab: f64 = a * b;
        let f = linear_creep(g, a, b, &c, 0.0, 0.0, 0.5).unwrap();
        assert!((f.mz_nm - g * ab * ab * 1.93 * 0.5).abs() < 1e-9 * f.mz_nm.abs());
        let f = linear_creep(g, a, b, &c, 0.0, 1e-3, 0.0).unwrap();
        let expect = -g * ab.powf(1.5) * 0.929 * 1e-3;
        assert!((f.mz_nm - expect).abs() < 1e-9 * expect.abs());
        // Odd in (s_y, φ) together.
        let p = linear_creep(g, a, b, &c, 0.0, 1e-3, 0.2).unwrap();
        let m = linear_creep(g, a, b, &c, 0.0, -1e-3, -0.2).unwrap();
        assert_eq!(p.mz_nm, -m.mz_nm);
    }

    #[test]
    fn outside_the_table_is_an_error() {
        assert!(coefficients(0.05, 1.0, 0.25).is_err());
        assert!(coefficients(1.0, 0.05, 0.25).is_err());
        assert!(coefficients(0.5, 1.0, 0.6).is_err());
        assert!(coefficients(0.0, 1.0, 0.25).is_err());
        assert!(coefficients(f64::NAN, 1.0, 0.25).is_err());
    }

    #[test]
    fn linear_law_and_validity_condition() {
        let c = coefficients(0.5, 1.0, 0.25).unwrap();
        let f = linear_creep(8.1e10, 0.003, 0.006, &c, 0.001, 0.0, 0.0).unwrap();
        assert!((f.fx_n - 8.1e10 * 1.8e-5 * 3.62 * 0.001).abs() < 1e-6);
        assert!(f.within_linear_validity);
        let f = linear_creep(8.1e10, 0.003, 0.006, &c, 0.0015, 0.0, 1.0).unwrap();
        assert!(!f.within_linear_validity, "0.0015 + 0.001 > 0.002");
    }
}
