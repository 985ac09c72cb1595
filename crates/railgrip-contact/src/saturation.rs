//! Saturation of linear creep forces by the modified Johnson–Vermeulen coefficient of Shen,
//! Hedrick and Elkins (seed 002_8d8769283f5e9cb6.txt eq. 8):
//!
//!   x = F_R / (μN),  F_R = √(F_x² + F_y²)
//!   k_s = (1/x)·(x − x²/3 + x³/27)   for x ≤ 3,
//!   k_s = 1/x                         for x > 3,
//!
//! and the saturated forces are k_s·(F_x, F_y), so |F| ≤ μN and |F| is continuous, smooth and
//! non-decreasing in F_R, reaching μN at F_R = 3μN with zero slope.
//!
//! The seed prints the polynomial as x − x²/9 − x³/27. That version also reaches 1 at x = 3, but
//! it rises above μN (1.26 μN at x = 2) and then falls: a misprint of Shen–Hedrick–Elkins
//! (Vehicle System Dynamics 12, 1983), which railgrip does not reproduce (see the test
//! `seed_002_eq_8_as_printed_would_exceed_mu_n`).

use super::{check_finite, ContactError};

/// The saturated force ratio S(x) = |F|/(μN) = x·k_s for x = F_R/(μN) ≥ 0:
/// x − x²/3 + x³/27 below 3, 1 from there on (the law itself; the model evaluators' creep
/// region and their C header use exactly these operations).
#[inline]
pub fn she_ratio(x: f64) -> f64 {
    if x < 3.0 {
        x - x * x / 3.0 + x * x * x / 27.0
    } else {
        1.0
    }
}

/// The saturation coefficient k_s = S(x)/x for x = F_R/(μN) ≥ 0 ([`she_ratio`]; 1 at x ≤ 0).
#[inline]
pub fn she_coefficient(x: f64) -> f64 {
    if x <= 0.0 {
        1.0
    } else {
        she_ratio(x) / x
    }
}

/// Saturates linear creep forces (N) for friction coefficient μ and normal force N (N).
/// Returns the saturated (F_x, F_y) in newtons.
#[inline]
pub fn saturate(fx_n: f64, fy_n: f64, mu: f64, normal_n: f64) -> Result<(f64, f64), ContactError> {
    check_finite("F_x", fx_n)?;
    check_finite("F_y", fy_n)?;
    check_finite("friction coefficient mu", mu)?;
    check_finite("normal force N", normal_n)?;
    if mu <= 0.0 {
        return Err(ContactError::Domain {
            what: "friction coefficient mu",
            value: mu,
            valid: "mu > 0",
        });
    }
    if normal_n <= 0.0 {
        return Err(ContactError::Domain {
            what: "normal force N",
            value: normal_n,
            valid: "N > 0 (the wheel must press on the rail)",
        });
    }
    let k = she_coefficient(fx_n.hypot(fy_n) / (mu * normal_n));
    Ok((k * fx_n, k * fy_n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn continuous_and_smooth_at_three_mu_n_and_bounded() {
        let below = 3.0 * she_coefficient(3.0 - 1e-9);
        let above = 3.0 * she_coefficient(3.0 + 1e-9);
        assert!((below - 1.0).abs() < 1e-8 && (above - 1.0).abs() < 1e-8);
        let mut prev = 0.0;
        for i in 1..=600 {
            let x = i as f64 * 0.01;
            let f = x * she_coefficient(x);
            assert!(f <= 1.0 + 1e-15 && f >= prev - 1e-15, "x {x}: {f}");
            prev = f;
        }
        // Small forces pass unchanged to first order.
        assert!((she_coefficient(1e-6) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn seed_002_eq_8_as_printed_would_exceed_mu_n() {
        let printed = |x: f64| x - x * x / 9.0 - x * x * x / 27.0;
        assert!(
            (printed(3.0) - 1.0).abs() < 1e-12,
            "continuous at 3 like the correct law"
        );
        assert!(
            printed(2.0) > 1.25,
            "but 1.26 μN at F_R = 2μN: not a saturation"
        );
        assert!((2.0 * she_coefficient(2.0) - (2.0 - 4.0 / 3.0 + 8.0 / 27.0)).abs() < 1e-15);
    }

    #[test]
    fn saturate_keeps_direction_and_rejects_bad_inputs() {
        let (fx, fy) = saturate(30_000.0, 40_000.0, 0.3, 50_000.0).unwrap();
        assert!((fx / fy - 0.75).abs() < 1e-12);
        assert!(
            (fx.hypot(fy) - 15_000.0).abs() < 1e-6,
            "F_R = 50 kN > 3μN = 45 kN saturates at μN"
        );
        assert!(saturate(1.0, 0.0, 0.0, 1.0).is_err());
        assert!(saturate(1.0, 0.0, 0.3, -1.0).is_err());
        assert!(saturate(f64::INFINITY, 0.0, 0.3, 1.0).is_err());
    }
}
