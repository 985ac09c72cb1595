//! Wheel–rail contact mechanics: a leaf library of pure functions of physical inputs, no I/O,
//! depending on nothing else in the crate.
//!
//! | module | law | source |
//! |---|---|---|
//! | [`hertz`] | normal contact: ellipse semi-axes, area, pressure; m, n from elliptic integrals | seed 001 eq. 1–5 |
//! | [`kalker`] | linear theory: C11, C22, C23 by table interpolation; linear creep forces; validity (eq. 9) | seed 002 eq. 6, seed 001 eq. 9–11, Kalker 1990 Table E.3 |
//! | [`saturation`] | Shen–Hedrick–Elkins saturation of the linear forces | seed 002 eq. 8 (corrected) |
//! | [`polach`] | Polach creep force with falling friction, k_A(T), k_S(T) | seed 004 eq. 1–3, Polach 2005 |
//! | [`fastsim`] | Kalker's FASTSIM (parabolic or elliptic bound, spin, modified FASTSIM, falling friction): forces, moment, slip area, traction and slip-velocity field | seed 001; Kalker 1982; Spiryagin et al. 2013 |
//! | [`flash`] | flash temperature by the strip (bar) model from the slip field or full sliding | seed 000 eq. 3–11 (eq. 10 corrected), seed 003 |
//! | [`kalker`] (also) | spin coefficient C33 and the linear spin moment | Kalker 1990 Table E.3 |
//!
//! Every function checks its domain and returns [`ContactError`] outside it: never NaN.

pub mod fastsim;
pub mod flash;
pub mod hertz;
pub mod kalker;
pub mod polach;
pub mod saturation;

/// An input outside a law's valid domain.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContactError {
    #[error("{what} = {value} is outside its domain: {valid}")]
    Domain {
        what: &'static str,
        value: f64,
        valid: &'static str,
    },
}

pub(crate) fn check_finite(what: &'static str, x: f64) -> Result<(), ContactError> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(ContactError::Domain {
            what,
            value: x,
            valid: "a finite number",
        })
    }
}

/// A finite value > 0, or a domain error naming `what`.
pub(crate) fn check_positive(what: &'static str, x: f64) -> Result<(), ContactError> {
    check_finite(what, x)?;
    if x > 0.0 {
        Ok(())
    } else {
        Err(ContactError::Domain {
            what,
            value: x,
            valid: "> 0",
        })
    }
}

/// Shear modulus G = E / (2(1 + ν)), Pa.
pub fn shear_modulus_pa(youngs_modulus_pa: f64, poisson: f64) -> f64 {
    youngs_modulus_pa / (2.0 * (1.0 + poisson))
}

/// Linear (Kalker) longitudinal force saturated by Shen–Hedrick–Elkins, in one call: the
/// "linear + saturation" law of seed 002 eq. 6–8 for pure longitudinal creepage `s` (–),
/// friction `mu`, normal force `normal_n` (N) and patch (G a b C11). Returns F_x, N.
#[inline]
pub fn linear_saturated_fx(
    patch: &polach::ContactPatch,
    mu: f64,
    normal_n: f64,
    s: f64,
) -> Result<f64, ContactError> {
    check_finite("creepage s", s)?;
    let fx = patch.g_pa * patch.a_m * patch.b_m * patch.c11 * s;
    Ok(saturation::saturate(fx, 0.0, mu, normal_n)?.0)
}
