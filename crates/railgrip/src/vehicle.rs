//! The vehicle model shared by the estimator and the simulator: static axle loads and the
//! load transfer of seed 002 (002_8d8769283f5e9cb6.txt) eq. 12–13.

use crate::config::{ContactConfig, Vehicle};
use crate::contact::polach::ContactPatch;
use crate::contact::{hertz, kalker, shear_modulus_pa, ContactError};
use crate::format::AXLES;

/// Standard gravity, m/s².
pub const G_MPS2: f64 = 9.80665;

/// Static axle load without load transfer (half the body and one bogie per bogie, shared by
/// its two axles), N.
pub fn static_axle_load(v: &Vehicle) -> f64 {
    (v.body_mass_kg / 2.0 + v.bogie_mass_kg) * G_MPS2 / 2.0
}

/// The contact patch of one wheel at the static wheel load Q, and Q (N): Hertz semi-axes from
/// the rolling radius and the lateral profile radii (seed 001 eq. 1–5), Kalker's c11, c22 and
/// the shear modulus G. Shared by the simulator's truth law, the Polach fits and the models'
/// creep region.
pub fn wheel_patch(v: &Vehicle, co: &ContactConfig) -> Result<(ContactPatch, f64), ContactError> {
    let (hz, kc, q) = wheel_hertz(v, co)?;
    let patch = ContactPatch {
        a_m: hz.a_m,
        b_m: hz.b_m,
        g_pa: shear_modulus_pa(co.youngs_modulus_pa, co.poisson),
        c11: kc.c11,
        c22: kc.c22,
    };
    Ok((patch, q))
}

/// The Hertz contact of one wheel at the static load, its Kalker coefficients and the wheel
/// load Q (N).
pub fn wheel_hertz(
    v: &Vehicle,
    co: &ContactConfig,
) -> Result<(hertz::HertzContact, kalker::KalkerCoefficients, f64), ContactError> {
    let q = static_axle_load(v) / 2.0;
    let curv_long = 0.5 / v.wheel_radius_m;
    let curv_lat = 0.5 * (1.0 / co.wheel_lateral_radius_m + 1.0 / co.rail_lateral_radius_m);
    let hz =
        hertz::hertz_from_curvatures(q, co.youngs_modulus_pa, co.poisson, curv_long, curv_lat)?;
    let kc = kalker::coefficients(hz.a_m, hz.b_m, co.poisson)?;
    Ok((hz, kc, q))
}

/// Translating mass of the vehicle: body and two bogies, kg.
pub fn total_mass_kg(v: &Vehicle) -> f64 {
    v.body_mass_kg + 2.0 * v.bogie_mass_kg
}

/// Axle loads N_1..N_4 from seed 002 eq. 12–13 written out for the four axles, N, for the
/// vehicle deceleration `decel_mps2` (m/s², positive when braking, negative in traction).
/// Axles are numbered from the leading end in the running direction (data contract), so the
/// front bogie carries axles 1 and 2 and braking loads it:
///
///   N_b1 = m_c g/2 + m_c d (h1 − hb)/l1,  N_b2 = m_c g/2 − m_c d (h1 − hb)/l1      (eq. 12)
///   N_1 = (N_b1 + m_b g)/2 + m_b d h2/l2,  N_2 = (N_b1 + m_b g)/2 − m_b d h2/l2     (eq. 13)
///   N_3 = (N_b2 + m_b g)/2 + m_b d h2/l2,  N_4 = (N_b2 + m_b g)/2 − m_b d h2/l2
///
/// m_c body mass (kg), m_b bogie mass (kg), g (m/s²), d deceleration (m/s²), h1 body centre
/// of gravity, hb body–bogie connection, h2 bogie centre of gravity (heights above the rail,
/// m), l1 bogie pivot distance, l2 bogie wheelbase (m). The sum of the four is the vehicle's
/// weight for every d. Valid while every N_i > 0, i.e. |d| well below g·l2/(2 h2) for a
/// sensible vehicle (the pipeline checks the geometry; the estimator masks samples where a
/// load would not be positive).
pub fn axle_loads(v: &Vehicle, decel_mps2: f64) -> [f64; AXLES] {
    let (mc, mb) = (v.body_mass_kg, v.bogie_mass_kg);
    let pitch =
        mc * decel_mps2 * (v.body_cog_height_m - v.pivot_height_m) / v.bogie_pivot_distance_m;
    let nb1 = mc * G_MPS2 / 2.0 + pitch;
    let nb2 = mc * G_MPS2 / 2.0 - pitch;
    // The bogie's own inertia at its centre of gravity, and with `pivot_force_load_transfer`
    // the body's inertia force each bogie takes at the pivot height, (m_c/2) d h_b.
    let pivot = if v.pivot_force_load_transfer {
        mc / 2.0 * decel_mps2 * v.pivot_height_m
    } else {
        0.0
    };
    let bogie = (mb * decel_mps2 * v.bogie_cog_height_m + pivot) / v.bogie_wheelbase_m;
    [
        (nb1 + mb * G_MPS2) / 2.0 + bogie,
        (nb1 + mb * G_MPS2) / 2.0 - bogie,
        (nb2 + mb * G_MPS2) / 2.0 + bogie,
        (nb2 + mb * G_MPS2) / 2.0 - bogie,
    ]
}

/// [`axle_loads`] as N_i = N0_i + d · c_i (it is linear in the deceleration d): returns (N0_i
/// the static loads (N), c_i = ∂N_i/∂d (N per m/s²)), c = (±m_c (h1 − hb)/(2 l1) ± m_b h2/l2)
/// from eq. 12–13. The simulator evaluates the loads this way, one fused multiply-add per axle.
pub fn axle_load_coefficients(v: &Vehicle) -> ([f64; AXLES], [f64; AXLES]) {
    let pitch =
        v.body_mass_kg * (v.body_cog_height_m - v.pivot_height_m) / v.bogie_pivot_distance_m / 2.0;
    let pivot = if v.pivot_force_load_transfer {
        v.body_mass_kg / 2.0 * v.pivot_height_m
    } else {
        0.0
    };
    let bogie = (v.bogie_mass_kg * v.bogie_cog_height_m + pivot) / v.bogie_wheelbase_m;
    (
        axle_loads(v, 0.0),
        [pitch + bogie, pitch - bogie, -pitch + bogie, -pitch - bogie],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Pipeline;

    #[test]
    fn loads_sum_to_the_weight_and_braking_loads_the_front() {
        let v = Pipeline::default_uic_z1().vehicle;
        let w = total_mass_kg(&v) * G_MPS2;
        let st = axle_loads(&v, 0.0);
        assert!(st.iter().all(|n| (n - static_axle_load(&v)).abs() < 1e-9));
        for d in [-1.5, 0.3, 1.2] {
            let n = axle_loads(&v, d);
            assert!((n.iter().sum::<f64>() - w).abs() < 1e-6 * w);
            assert_eq!(n[0] > n[3], d > 0.0);
            assert_eq!(n[0] > n[1], d > 0.0);
            let (base, per) = axle_load_coefficients(&v);
            for i in 0..AXLES {
                let lin = d.mul_add(per[i], base[i]);
                assert!(
                    (lin - n[i]).abs() <= 1e-9 * n[i],
                    "axle {i}: {lin} vs {}",
                    n[i]
                );
            }
        }
    }
}
