//! Contact flash temperature: the strip (bar) model of seed 000_1da9721a35dd2615.txt on a
//! heat source from the FASTSIM slip field or from full sliding, validated against the V-Track
//! measurements of seed 003_e1250fe8e2165249.txt (tests/contact_fastsim.rs, docs/contact.md).
//!
//! **Model** (seed 000 eq. 3–11). Every surface point of the rail crosses the contact along a
//! strip parallel to the rolling direction, in the time 2a(y)/V. At high Péclet number
//! (Pe = V·2a/κ > 20, seed 000 eq. 6; κ = λ/(ρc)) heat flows only into the depth, so each point
//! is the end of a heat-insulated bar (seed 000 eq. 7) heated at its surface by the flux
//!
//!   q = δ · |p| · v_slip        (W/m²; seed 000 eq. 3, seed 003 eq. 4: Q = δ μ v_s P)
//!
//! with δ the heat partition to the rail. For a constant flux q switched on at t = 0 the
//! surface of a semi-infinite body warms by (Carslaw & Jaeger 1959, §2.9; seed 000 eq. 9 at
//! depth k = 0)
//!
//!   ΔT(t) = 2 q √t / √(π λ ρ c).
//!
//! **Correction:** seed 000 eq. 10 prints this as 2q√t/√(λcρ): eq. 9 at k = 0 gives the factor
//! 1/√π, which eq. 10 drops. Without it every temperature rise would be √π ≈ 1.77 times too
//! high; railgrip uses eq. 9.
//!
//! The flux is piecewise constant over the cells a point crosses (seed 000 eq. 8); the rise is
//! the superposition seed 000 describes (each cell's source switched on and off, eq. 11):
//!
//!   ΔT(t) = (2/√(πλρc)) Σ_i q_i [√(t − t_i) − √(t − t_{i+1})]₊,   t_i = i·dx/V,
//!
//! which is exact for piecewise-constant q (tested against the closed form) and converges to
//! Jaeger's integral ΔT(t) = (1/√(πλρc)) ∫ q(τ)/√(t − τ) dτ for a smooth source (tested
//! against scipy quadrature, tests/data/flash/). The cell's flux is its centre value (the
//! midpoint rule FASTSIM integrates the forces with).
//!
//! Results: the hottest point of every strip (the peak contact temperature), the temperature at
//! the trailing edge, and the temperature a chosen time after the point left the contact (what
//! an infrared camera behind the wheel sees; seed 003 measured 1.09 ms behind). Material
//! constants do not depend on temperature within one passage (evaluate them at the bulk
//! temperature); there is no cooling to the air (seed 003 §2.1: negligible within ms).

use super::fastsim::Field;
use super::{check_finite, check_positive, ContactError};
use std::f64::consts::PI;

/// Absolute zero, °C.
pub const ABSOLUTE_ZERO_C: f64 = -273.15;

/// Thermal constants of the body the heat flows into.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Thermal conductivity λ, W/(m·K).
    pub conductivity_w_per_mk: f64,
    /// Specific heat capacity c, J/(kg·K).
    pub specific_heat_j_per_kgk: f64,
    /// Density ρ, kg/m³.
    pub density_kg_per_m3: f64,
}

impl Material {
    /// Rail steel as handbooks give it near 200 °C [assumed: λ 48 W/(m·K), c 500 J/(kg·K),
    /// ρ 7850 kg/m³; pearlitic carbon steel].
    pub const RAIL_STEEL: Material = Material {
        conductivity_w_per_mk: 48.0,
        specific_heat_j_per_kgk: 500.0,
        density_kg_per_m3: 7850.0,
    };

    pub fn check(&self) -> Result<(), ContactError> {
        for (what, x, hi, valid) in [
            (
                "thermal conductivity",
                self.conductivity_w_per_mk,
                1e3,
                "0 < lambda <= 1000 W/(m K)",
            ),
            (
                "specific heat",
                self.specific_heat_j_per_kgk,
                1e4,
                "0 < c <= 10000 J/(kg K)",
            ),
            (
                "density",
                self.density_kg_per_m3,
                3e4,
                "0 < rho <= 30000 kg/m3",
            ),
        ] {
            check_finite(what, x)?;
            if !(x > 0.0 && x <= hi) {
                return Err(ContactError::Domain {
                    what,
                    value: x,
                    valid,
                });
            }
        }
        Ok(())
    }

    /// Thermal diffusivity κ = λ/(ρc), m²/s.
    pub fn diffusivity_m2_per_s(&self) -> f64 {
        self.conductivity_w_per_mk / (self.density_kg_per_m3 * self.specific_heat_j_per_kgk)
    }

    /// √(π λ ρ c), W·s^½/(m²·K).
    fn pi_effusivity(&self) -> f64 {
        (PI * self.conductivity_w_per_mk * self.density_kg_per_m3 * self.specific_heat_j_per_kgk)
            .sqrt()
    }
}

/// How the frictional heat enters the body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Heating {
    /// Heat partition δ to this body, (0, 1].
    pub partition: f64,
    /// Bulk temperature before the contact, °C (> −273.15).
    pub initial_temperature_c: f64,
    /// When to report the "after" temperature: this long after a point leaves the contact, s
    /// (≥ 0; 0 is the trailing edge).
    pub after_s: f64,
}

impl Heating {
    pub fn check(&self) -> Result<(), ContactError> {
        check_finite("heat partition", self.partition)?;
        check_finite("initial temperature", self.initial_temperature_c)?;
        check_finite("time after the contact", self.after_s)?;
        if !(self.partition > 0.0 && self.partition <= 1.0) {
            return Err(ContactError::Domain {
                what: "heat partition",
                value: self.partition,
                valid: "0 < partition <= 1",
            });
        }
        if self.initial_temperature_c <= ABSOLUTE_ZERO_C {
            return Err(ContactError::Domain {
                what: "initial temperature",
                value: self.initial_temperature_c,
                valid: "above absolute zero (-273.15 °C)",
            });
        }
        if !(0.0..=10.0).contains(&self.after_s) {
            return Err(ContactError::Domain {
                what: "time after the contact",
                value: self.after_s,
                valid: "0 <= t <= 10 s",
            });
        }
        Ok(())
    }
}

/// Temperatures of one contact passage, °C.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlashTemperature {
    /// The hottest surface temperature anywhere in the contact (max over strips and cells).
    pub peak_c: f64,
    /// The hottest strip's temperature at the trailing edge.
    pub trailing_edge_c: f64,
    /// The hottest value over strips, `Heating::after_s` after leaving the contact.
    pub after_c: f64,
    /// Péclet number V·2a/κ of the centre strip (the model needs > 20, seed 000 eq. 6).
    pub peclet: f64,
}

/// Flash temperatures of a passage over the contact whose traction and slip `field` FASTSIM
/// (or [`full_sliding`]) made, at rolling speed `speed_mps` (m/s). Cost O(nx² · ny).
pub fn flash_temperature(
    field: &Field,
    speed_mps: f64,
    material: &Material,
    heating: &Heating,
) -> Result<FlashTemperature, ContactError> {
    material.check()?;
    heating.check()?;
    check_finite("rolling speed V", speed_mps)?;
    if speed_mps <= 0.0 {
        return Err(ContactError::Domain {
            what: "rolling speed V",
            value: speed_mps,
            valid: "V > 0 (m/s): a standing contact has no flash temperature",
        });
    }
    let (nx, ny) = (field.nx, field.ny);
    field.check_shape()?;
    let gain = 2.0 * heating.partition / material.pi_effusivity();
    let (mut peak, mut trailing, mut after) = (0.0f64, 0.0f64, 0.0f64);
    let mut widest = 0.0f64;
    for j in 0..ny {
        let dx = field.dx_m[j];
        widest = widest.max(dx * nx as f64);
        if dx <= 0.0 {
            continue;
        }
        let dt = dx / speed_mps;
        let sdt = dt.sqrt();
        let row = j * nx;
        let q = |i: usize| field.power_density(row + i);
        // Rise at the end of cell m: Σ_{i ≤ m} q_i (√(m + 1 − i) − √(m − i)) √dt.
        for m in 0..nx {
            let mut s = 0.0;
            for i in 0..=m {
                let k = (m - i) as f64;
                s += q(i) * ((k + 1.0).sqrt() - k.sqrt());
            }
            let rise = gain * sdt * s;
            peak = peak.max(rise);
            if m == nx - 1 {
                trailing = trailing.max(rise);
            }
        }
        // `after_s` past the trailing edge: t = nx dt + after.
        let t = nx as f64 * dt + heating.after_s;
        let mut s = 0.0;
        for i in 0..nx {
            let t0 = t - i as f64 * dt;
            let t1 = (t0 - dt).max(0.0);
            s += q(i) * (t0.sqrt() - t1.sqrt());
        }
        after = after.max(gain * s);
    }
    let t0 = heating.initial_temperature_c;
    Ok(FlashTemperature {
        peak_c: t0 + peak,
        trailing_edge_c: t0 + trailing,
        after_c: t0 + after,
        peclet: speed_mps * widest / material.diffusivity_m2_per_s(),
    })
}

/// A fully sliding contact: traction μ p_n (elliptic, Hertz) against the slip, slip velocity
/// `slip_mps` everywhere; written into `field` (any grid). `normal_n` N over semi-axes `a_m`,
/// `b_m` (m). Seed 003 eq. 4 with the Hertz pressure.
pub fn full_sliding(
    a_m: f64,
    b_m: f64,
    normal_n: f64,
    mu: f64,
    slip_mps: f64,
    field: &mut Field,
) -> Result<(), ContactError> {
    for (what, x) in [
        ("semi-axis a", a_m),
        ("semi-axis b", b_m),
        ("normal force N", normal_n),
        ("friction coefficient", mu),
    ] {
        check_positive(what, x)?;
    }
    check_finite("slip velocity", slip_mps)?;
    field.check_shape()?;
    let (nx, ny) = (field.nx, field.ny);
    let p0 = 1.5 * normal_n / (PI * a_m * b_m);
    let dy = 2.0 * b_m / ny as f64;
    field.dy_m = dy;
    for j in 0..ny {
        let y = -b_m + (j as f64 + 0.5) * dy;
        let ey = 1.0 - (y / b_m) * (y / b_m);
        let ay = a_m * ey.sqrt();
        let dx = 2.0 * ay / nx as f64;
        field.dx_m[j] = dx;
        for i in 0..nx {
            let k = j * nx + i;
            let x = ay - (i as f64 + 0.5) * dx;
            let pn = p0 * (ey - (x / a_m) * (x / a_m)).max(0.0).sqrt();
            field.x_m[k] = x;
            field.y_m[k] = y;
            field.pressure_pa[k] = pn;
            field.px_pa[k] = mu * pn;
            field.py_pa[k] = 0.0;
            field.slip_velocity_mps[k] = slip_mps.abs();
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn heating() -> Heating {
        Heating {
            partition: 0.5,
            initial_temperature_c: 20.0,
            after_s: 0.0,
        }
    }

    #[test]
    fn a_uniform_source_gives_carslaw_and_jaeger_exactly() {
        // One strip, uniform power density P: ΔT(end) = 2 δ P √t / √(πλρc).
        let mut f = Field::new(50, 1);
        f.dx_m[0] = 1e-4;
        f.dy_m = 1e-3;
        for k in 0..50 {
            f.px_pa[k] = 3e8;
            f.slip_velocity_mps[k] = 0.5;
        }
        let m = Material::RAIL_STEEL;
        let v = 10.0;
        let r = flash_temperature(&f, v, &m, &heating()).unwrap();
        let t = 50.0 * 1e-4 / v;
        let q = 0.5 * 3e8 * 0.5;
        let exact = 2.0 / m.pi_effusivity() * q * t.sqrt();
        assert!(
            (r.trailing_edge_c - 20.0 - exact).abs() < 1e-9 * exact,
            "{} vs {exact}",
            r.trailing_edge_c - 20.0
        );
        assert_eq!(
            r.peak_c, r.trailing_edge_c,
            "a constant source heats to the end"
        );
    }

    #[test]
    fn bad_inputs_are_errors() {
        let f = Field::new(4, 4);
        let m = Material::RAIL_STEEL;
        assert!(flash_temperature(&f, 0.0, &m, &heating()).is_err());
        let mut h = heating();
        h.initial_temperature_c = -300.0;
        assert!(flash_temperature(&f, 1.0, &m, &h).is_err());
        h = heating();
        h.partition = 1.5;
        assert!(flash_temperature(&f, 1.0, &m, &h).is_err());
        let mut bad = m;
        bad.conductivity_w_per_mk = f64::NAN;
        assert!(flash_temperature(&f, 1.0, &bad, &heating()).is_err());
        let mut short = Field::new(4, 4);
        short.px_pa.pop();
        assert!(flash_temperature(&short, 1.0, &m, &heating()).is_err());
        let mut g = Field::new(4, 4);
        assert!(full_sliding(0.0, 1e-3, 1e3, 0.3, 1.0, &mut g).is_err());
        assert!(full_sliding(1e-3, 1e-3, 1e3, 0.3, f64::INFINITY, &mut g).is_err());
    }
}
