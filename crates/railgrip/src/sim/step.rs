//! The four axles' contact and wheel update of one integration step, written once over
//! [`Select`] lanes: four axles in one AVX2 register, or one axle at a time on the portable
//! path, with the same IEEE operations lane by lane (bit-identical, tested in `sim::tests`).
//!
//! The step's critical path runs ω_n → slip → contact force → ω_{n+1} → vehicle speed →
//! the next step's slip, so its latency, not its operation count, sets the simulator's speed.
//! Hence one division per axle on that path: the Polach law is evaluated as fractions with a
//! common denominator G, and the linearly implicit wheel update divides once by G·(J + h r² N k).

use crate::simd::{atan_parts, Select};

/// Constants of the step.
#[derive(Debug, Clone, Copy)]
pub(super) struct StepConsts {
    /// Wheel radius r, m.
    pub r: f64,
    /// Axle inertia J, kg m².
    pub j: f64,
    /// Step h, s.
    pub h: f64,
    /// Polach k_A, k_S (seed 004 eq. 2), 1.
    pub k_a: f64,
    pub k_s: f64,
}

/// Per-axle inputs and state, one array per quantity (axle 1 first). The step loads them as
/// vectors; the ones on the step's critical path are written as vectors too (a vector load of
/// four separate scalar stores cannot be forwarded from the store buffer and waits for them).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct AxleArrays {
    /// Wheel speed ω, rad/s (state; updated).
    pub omega: [f64; 4],
    /// 1.0 while the wheel is locked by the static brake, else 0.0 (state; updated).
    pub locked: [f64; 4],
    /// (N/2) μ / K per unit vehicle speed, 1: d = v · this is the slip at which ε = 1 (m/s);
    /// N the axle load (N), μ the friction coefficient, K = π G a b c11 / 4 the patch constant.
    pub d_per_v: [f64; 4],
    /// (2/π) μ N, N.
    pub pn: [f64; 4],
    /// Hysteresis branch factor, 1 (1 without the effect).
    pub hyst: [f64; 4],
    /// Brake torque α p while the wheel turns, N m.
    pub brake: [f64; 4],
    /// Out: the creep force applied over the step, T* (N).
    pub t_star: [f64; 4],
}

/// Polach's adhesion (seed 004 eq. 1–2, the creep-force law of seed 001 with ε from Kalker's
/// c11 on the Hertz patch) of `V::N` axles as fractions over one denominator G:
///
///   T/N  = (2μ/π) (x/(1 + x²) + atan y) = (2μ/π) · Rn / G,
///   ∂(T/N)/∂Δv = (2μ/π) (k_A (1 − x²)/(1 + x²)² + k_S/(1 + y²)) ∂ε/∂Δv = (2μ/π) · Sn / G,
///
/// with ε = Δv / d (d = v Q μ / K, m/s), x = k_A ε = a/d, y = k_S ε = b/d (a = k_A Δv,
/// b = k_S Δv), E = d² + a², F = d² + b², atan(|b|/d) = off + num/den ([`atan_parts`]) and
/// G = E² F den:
///   Rn = a d E F den + off G + num E² F,
///   Sn = d den (k_A (d² − a²) F + k_S E²).
/// Returns (Rn, max(Sn, 0), G) with G > 0. Every quantity is a product of the inputs without division, so no
/// division waits on the slip before the wheel update's one. Magnitudes: G ~ max(|b|, d)¹⁹;
/// the scene's validated ranges keep d in about [1e−9, 1e4] m/s and |Δv| below 1e3 m/s, far
/// from overflow and underflow (tested at the extremes).
#[inline(always)]
pub(super) fn polach_fractions<V: Select>(c: &StepConsts, dv: V, d: V) -> (V, V, V) {
    let isa = dv.isa();
    let a = dv.mul(V::splat(isa, c.k_a));
    let b = dv.mul(V::splat(isa, c.k_s));
    let (off, num, den) = atan_parts(b, d);
    let d2 = d.mul(d);
    let e = a.fma(a, d2);
    let f = b.fma(b, d2);
    let e2 = e.mul(e);
    let e2f = e2.mul(f);
    let g = e2f.mul(den);
    let atan_g = off.fma(g, num.mul(e2f));
    let rn = a.mul(d).fma(e.mul(f).mul(den), atan_g);
    // Past the creep peak the slope can turn negative; the implicit step takes no negative
    // stiffness (it would weaken the wheel's damping and, at worst, divide by ~0).
    let sn = d
        .mul(den)
        .mul(
            V::splat(isa, c.k_a)
                .mul(a.fnma(a, d2))
                .fma(f, V::splat(isa, c.k_s).mul(e2)),
        )
        .max(V::splat(isa, 0.0));
    (rn, sn, g)
}

/// The linearly implicit (Rosenbrock–Euler) wheel update of `V::N` axles given the contact as
/// fractions T = pn·Rn/G, N ∂μ/∂Δv = pn·Sn/G (N, N/(m/s)):
///   ω_{n+1} = ω_n + h (T r − α p) / (J + h r² N k)
///           = ω_n + h (pn Rn r − α p G) / (J G + h r² pn Sn),
/// one division on the critical path (1/G, in parallel, gives T and the stiffness). The force
/// applied over the step is T* = T − r N k (ω_{n+1} − ω_n). A locked wheel (ω = 0) stays
/// locked while T r ≤ α p and is released when the contact torque exceeds the static brake;
/// a turning wheel whose update reaches ω ≤ 0 locks (ω = 0, T* = T).
/// Returns (ω_{n+1}, locked as 1.0/0.0, T*).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn wheel_update<V: Select>(
    c: &StepConsts,
    omega: V,
    locked: V,
    brake: V,
    pn: V,
    rn: V,
    sn: V,
    g: V,
) -> (V, V, V) {
    let isa = omega.isa();
    let r = V::splat(isa, c.r);
    let pnsn = pn.mul(sn);
    let den = V::splat(isa, c.j).fma(g, V::splat(isa, c.h * c.r * c.r).mul(pnsn));
    let torque = pn.mul(rn);
    let num = brake
        .mul(V::splat(isa, c.h))
        .fnma(g, pn.mul(V::splat(isa, c.h * c.r)).mul(rn));
    let d_omega = num.div(den);
    let inv_g = V::splat(isa, 1.0).div(g);
    let t = torque.mul(inv_g);
    let k_r = pnsn.mul(inv_g).mul(r);
    let was_locked = V::splat(isa, 0.5).lt(locked);
    let releases = V::and(was_locked, brake.lt(t.mul(r)));
    let stays = V::and_not(releases, was_locked);
    let candidate = omega.add(d_omega);
    let lock = V::or(stays, candidate.le(V::splat(isa, 0.0)));
    let zero = V::splat(isa, 0.0);
    (
        V::select(lock, zero, candidate),
        V::select(lock, V::splat(isa, 1.0), zero),
        V::select(lock, t, k_r.fnma(d_omega, t)),
    )
}

/// The Polach step of all four axles at vehicle speed `v` (m/s): the contact from the slip
/// Δv = v − r ω and d = v · `d_per_v` ([`polach_fractions`]), then [`wheel_update`] with
/// T = (2/π) μ N · hyst · Rn/G; updates `s.omega`, `s.locked`, `s.t_star` and returns ΣT* (N).
#[inline(always)]
pub(super) fn polach_axles<V: Select>(
    isa: V::Isa,
    c: &StepConsts,
    v: f64,
    s: &mut AxleArrays,
) -> f64 {
    let vv = V::splat(isa, v);
    let mut i = 0;
    let mut t_star = vv;
    while i < 4 {
        let omega = V::load(isa, &s.omega[i..]);
        let dv = V::splat(isa, c.r).fnma(omega, vv);
        let d = vv.mul(V::load(isa, &s.d_per_v[i..]));
        let (rn, sn, g) = polach_fractions(c, dv, d);
        let pn = V::load(isa, &s.pn[i..]).mul(V::load(isa, &s.hyst[i..]));
        let (omega_new, locked);
        (omega_new, locked, t_star) = wheel_update(
            c,
            omega,
            V::load(isa, &s.locked[i..]),
            V::load_scalars(isa, &s.brake[i..]),
            pn,
            rn,
            sn,
            g,
        );
        omega_new.store(&mut s.omega[i..]);
        locked.store(&mut s.locked[i..]);
        t_star.store(&mut s.t_star[i..]);
        i += V::N;
    }
    V::total4(t_star, &s.t_star)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const C: StepConsts = StepConsts {
        r: 0.46,
        j: 120.0,
        h: 1e-4,
        k_a: 0.1,
        k_s: 0.05,
    };

    /// Polach's T/N and its slope written plainly (seed 004 eq. 1–2, libm atan).
    fn reference(dv: f64, d: f64) -> (f64, f64) {
        let eps = dv / d;
        let (x, y) = (C.k_a * eps, C.k_s * eps);
        let ratio = x / (1.0 + x * x) + y.atan();
        let slope = (C.k_a * (1.0 - x * x) / (1.0 + x * x).powi(2) + C.k_s / (1.0 + y * y)) / d;
        (ratio, slope.max(0.0))
    }

    fn fractions(dv: f64, d: f64) -> (f64, f64) {
        let (rn, sn, g) = polach_fractions(&C, dv, d);
        assert!(g > 0.0 && g.is_finite(), "G = {g} at dv {dv}, d {d}");
        (rn / g, sn / g)
    }

    #[test]
    fn fractions_match_the_plain_formula_over_the_domain() {
        let mut worst: (f64, f64) = (0.0, 0.0);
        for i in 0..=600 {
            let dv = 10f64.powf(-8.0 + 11.0 * i as f64 / 600.0);
            for d in [1e-9, 1e-5, 3e-3, 0.1, 1.0, 50.0, 1e4] {
                for s in [1.0, -1.0] {
                    let (r, k) = fractions(s * dv, d);
                    let (r0, k0) = reference(s * dv, d);
                    worst.0 = worst.0.max(((r - r0) / r0).abs());
                    if k0 > 1e-300 {
                        worst.1 = worst.1.max((k - k0).abs() / k0.max(1e-12 * C.k_s / d));
                    }
                }
            }
        }
        assert!(worst.0 < 1e-14, "T/N worst relative error {:e}", worst.0);
        assert!(worst.1 < 1e-12, "slope worst relative error {:e}", worst.1);
        assert_eq!(fractions(0.0, 0.3).0, 0.0);
    }

    proptest! {
        #[test]
        fn ratio_is_odd_and_bounded_slope_even_and_non_negative(dv in -50.0f64..50.0, d in 1e-6f64..1e3) {
            let (r, k) = fractions(dv, d);
            let (rm, km) = fractions(-dv, d);
            prop_assert!((r + rm).abs() <= 1e-15 * r.abs().max(1e-300));
            prop_assert_eq!(k, km);
            // |x/(1+x²) + atan y| ≤ 1/2 + π/2.
            prop_assert!(r.abs() <= 0.5 + std::f64::consts::FRAC_PI_2);
            prop_assert!(k >= 0.0 && k.is_finite());
        }
    }

    #[test]
    fn wheel_update_keeps_a_locked_wheel_locked_until_the_contact_exceeds_the_brake() {
        let (w, l, t) = wheel_update(&C, 0.0, 1.0, 5000.0, 1e4, 0.05, 0.0, 1.0);
        assert_eq!((w, l, t), (0.0, 1.0, 500.0));
        let (w, l, _) = wheel_update(&C, 0.0, 1.0, 100.0, 1e4, 0.05, 0.0, 1.0);
        assert!(w > 0.0 && l == 0.0);
    }
}
