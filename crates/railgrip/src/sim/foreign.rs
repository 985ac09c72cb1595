//! Adhesion laws from outside the families railgrip fits — truth that the identification has
//! not seen (a network or Polach fit tested only on Polach-made data is tested on its
//! own assumptions).
//!
//! - [`LossRecovery`]: separate curves for a growing slip (adhesion being lost) and a falling
//!   one (being recovered), each of Pacejka's "magic formula" shape (Bakker, Nyborg & Pacejka,
//!   SAE 870421, 1987; here with E = 0): μ_b(Δv) = D sin(C atan(B Δv)), peak D at
//!   Δv_p = tan(π/(2C))/B, falling to D sin(Cπ/2) at large slip. The two are blended by the
//!   lagged slip rate q: μ = β μ_loss + (1 − β) μ_rec, β = ½ (1 + z/√(1 + z²)), z = q/q0.
//!   Both peaks scale with speed by one of two forms ([`SpeedForm`]): `ratio`,
//!   D(v) = D (1 + κ (v_ref − v)/(v_ref + v)), flat at the top (like Curtius–Kniffler's
//!   7.5/(v + 44) + 0.161, v in km/h: −4 % from 120 to 160 km/h), or `quadratic`,
//!   D(v) = D (1 + κ (1 − (v/v_ref)²)), steeper at the top, as adhesion on wet and
//!   contaminated rail falls with rolling speed in seed 002 Fig. 8 (κ = 0.16, v_ref = 120 km/h:
//!   −12 % from 120 to 160 km/h, −18 % from 160 to 200 km/h); with the `temperature` effect,
//!   with the ambient temperature, D(T) = D (1 + τ (20 °C − T)); and by the run's rail
//!   condition, D × s (`level_scale`: the run-to-run spread of a contamination).
//!   Every parameter is [assumed]: chosen to look like soap-contaminated rail (seed 002
//!   Fig. 7–8, μ 0.02–0.10, peak near 1 m/s), not fitted to anything.
//! - [`SlipTable`]: μ(Δv) tabulated per speed, linear between nodes in Δv and in speed, held
//!   constant beyond the last nodes: a sharp peak and a plateau that no smooth law has.
//!
//! Both are odd in Δv, like the Polach law (μ(−Δv) = −μ(Δv)).

use std::f64::consts::PI;

/// One branch of [`LossRecovery`]: peak μ, the slip at the peak (m/s) and the large-slip level
/// as a fraction of the peak.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Branch {
    pub peak_mu: f64,
    pub peak_slip_mps: f64,
    pub residual: f64,
}

impl Branch {
    /// Magic-formula coefficients (B in s/m, C): C = 2 − (2/π) asin(residual) so that
    /// D sin(Cπ/2) = residual · D; B = tan(π/(2C))/Δv_p so that the peak sits at Δv_p.
    /// Needs 0 < residual < 1 and Δv_p > 0 (checked by the scene).
    fn shape(self) -> (f64, f64) {
        let c = 2.0 - 2.0 / PI * self.residual.asin();
        let b = (PI / (2.0 * c)).tan() / self.peak_slip_mps;
        (b, c)
    }
}

/// How the peaks of [`LossRecovery`] scale with speed v (m/s), κ and v_ref given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpeedForm {
    /// 1 + κ (v_ref − v)/(v_ref + |v|): bounded, flat at the top.
    Ratio,
    /// 1 + κ (1 − (v/v_ref)²): falls faster the faster the train runs; positive only below
    /// v_ref √(1 + 1/κ) (the scene checks its initial speed).
    Quadratic,
}

impl SpeedForm {
    /// The name in scene files.
    pub fn name(self) -> &'static str {
        match self {
            SpeedForm::Ratio => "ratio",
            SpeedForm::Quadratic => "quadratic",
        }
    }

    /// The peaks' factor at speed `v` (m/s), coefficient `kappa` and reference `v_ref` (m/s).
    #[inline]
    pub fn factor(self, kappa: f64, v_ref: f64, v: f64) -> f64 {
        match self {
            SpeedForm::Ratio => 1.0 + kappa * (v_ref - v) / (v_ref + v.abs()),
            SpeedForm::Quadratic => {
                let r = v / v_ref;
                1.0 + kappa * (1.0 - r * r)
            }
        }
    }
}

/// Separate loss and recovery curves blended by the lagged slip rate (see the module text).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossRecovery {
    pub loss: Branch,
    pub recovery: Branch,
    /// q0 of the blend, m/s².
    pub blend_ddv_mps2: f64,
    /// κ: the peaks' speed dependence, 1.
    pub speed_coefficient: f64,
    /// How the peaks scale with speed.
    pub speed_form: SpeedForm,
    /// s: the run's rail condition as a factor of both peaks, 1.
    pub level_scale: f64,
    /// v_ref, m/s.
    pub reference_speed_mps: f64,
    /// τ: the peaks' temperature dependence, 1/K (applied with the `temperature` effect).
    pub temperature_coefficient_per_k: f64,
}

/// [`LossRecovery`] prepared for a run: magic-formula coefficients, peaks at the run's ambient
/// temperature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreparedLossRecovery {
    /// (D, B, C) of the loss and the recovery branch.
    loss: (f64, f64, f64),
    recovery: (f64, f64, f64),
    inv_q0: f64,
    kappa: f64,
    v_ref: f64,
    form: SpeedForm,
}

impl LossRecovery {
    /// The law at ambient temperature `t_c` (°C; `None`: no temperature dependence).
    pub fn prepare(&self, t_c: Option<f64>) -> PreparedLossRecovery {
        let temp = self.level_scale
            * t_c.map_or(1.0, |t| {
                1.0 + self.temperature_coefficient_per_k * (20.0 - t)
            });
        let coef = |br: Branch| {
            let (b, c) = br.shape();
            (br.peak_mu * temp, b, c)
        };
        PreparedLossRecovery {
            loss: coef(self.loss),
            recovery: coef(self.recovery),
            inv_q0: 1.0 / self.blend_ddv_mps2,
            kappa: self.speed_coefficient,
            v_ref: self.reference_speed_mps,
            form: self.speed_form,
        }
    }
}

impl PreparedLossRecovery {
    /// The peaks' speed factor at `v` (m/s).
    #[inline]
    pub fn speed_factor(&self, v: f64) -> f64 {
        self.form.factor(self.kappa, self.v_ref, v)
    }

    /// μ at slip `w` (m/s), lagged slip rate `q` (m/s²) and speed `v` (m/s).
    pub fn mu(&self, w: f64, q: f64, v: f64) -> f64 {
        let speed = self.speed_factor(v);
        let curve = |(d, b, c): (f64, f64, f64)| d * (c * (b * w).atan()).sin();
        let z = q * self.inv_q0;
        let beta = 0.5 * (1.0 + z / (1.0 + z * z).sqrt());
        speed * (beta * curve(self.loss) + (1.0 - beta) * curve(self.recovery))
    }

    /// Peak μ of the loss and the recovery branch at speed `v` (m/s).
    pub fn peaks(&self, v: f64) -> (f64, f64) {
        let speed = self.speed_factor(v);
        (speed * self.loss.0, speed * self.recovery.0)
    }
}

/// μ(Δv) tabulated per speed (see the module text).
#[derive(Debug, Clone, PartialEq)]
pub struct SlipTable {
    /// Speed nodes, m/s, strictly increasing.
    pub speeds_mps: Vec<f64>,
    /// Slip nodes, m/s, strictly increasing, the first 0.
    pub slips_mps: Vec<f64>,
    /// μ per speed node (rows) and slip node (columns), the first column 0.
    pub mu: Vec<Vec<f64>>,
}

/// Index i and weight f with x between nodes i and i + 1 (f = 0 and 1 at them); clamped to
/// the ends.
fn bracket(nodes: &[f64], x: f64) -> (usize, f64) {
    let last = nodes.len() - 1;
    if last == 0 || x <= nodes[0] {
        return (0, 0.0);
    }
    if x >= nodes[last] {
        return (last - 1, 1.0);
    }
    let i = nodes.partition_point(|n| *n <= x) - 1;
    (i, (x - nodes[i]) / (nodes[i + 1] - nodes[i]))
}

impl SlipTable {
    /// The built-in table: a sharp peak at 0.6 m/s (lower and later at speed), a dip and a
    /// plateau from 2.5 m/s [assumed].
    pub fn default_table() -> SlipTable {
        SlipTable {
            speeds_mps: vec![80.0 / 3.6, 140.0 / 3.6, 200.0 / 3.6],
            slips_mps: vec![0.0, 0.15, 0.4, 0.6, 0.8, 1.2, 2.5, 20.0],
            mu: vec![
                vec![0.0, 0.045, 0.085, 0.105, 0.080, 0.060, 0.055, 0.055],
                vec![0.0, 0.035, 0.070, 0.090, 0.072, 0.052, 0.046, 0.046],
                vec![0.0, 0.028, 0.058, 0.074, 0.064, 0.045, 0.038, 0.038],
            ],
        }
    }

    /// Checks the shape; a message saying what is wrong.
    pub fn check(&self) -> Result<(), String> {
        let increasing = |xs: &[f64]| xs.windows(2).all(|w| w[1] > w[0]);
        if self.speeds_mps.is_empty() || !increasing(&self.speeds_mps) {
            return Err("table_speeds_kmh must be at least one speed, strictly increasing".into());
        }
        if self.slips_mps.len() < 2 || self.slips_mps[0] != 0.0 || !increasing(&self.slips_mps) {
            return Err(
                "table_slips_mps must start at 0 and increase strictly (at least two nodes)".into(),
            );
        }
        if self.mu.len() != self.speeds_mps.len() {
            return Err(format!(
                "table_mu has {} rows, one per speed needs {}",
                self.mu.len(),
                self.speeds_mps.len()
            ));
        }
        for (i, row) in self.mu.iter().enumerate() {
            if row.len() != self.slips_mps.len() {
                return Err(format!(
                    "table_mu row {} has {} values, one per slip node needs {}",
                    i + 1,
                    row.len(),
                    self.slips_mps.len()
                ));
            }
            if row[0] != 0.0 || row.iter().any(|m| !(0.0..=1.5).contains(m)) {
                return Err(format!(
                    "table_mu row {}: μ must be in [0, 1.5] and 0 at zero slip",
                    i + 1
                ));
            }
        }
        if self
            .speeds_mps
            .iter()
            .chain(&self.slips_mps)
            .any(|x| !x.is_finite())
        {
            return Err("table nodes must be finite".into());
        }
        Ok(())
    }

    /// μ at slip `w` (m/s) and speed `v` (m/s): bilinear, odd in `w`.
    pub fn mu(&self, w: f64, v: f64) -> f64 {
        let (j, g) = bracket(&self.slips_mps, w.abs());
        let (i, f) = bracket(&self.speeds_mps, v);
        let row = |r: &[f64]| {
            if self.slips_mps.len() == 1 {
                r[0]
            } else {
                r[j] + g * (r[j + 1] - r[j])
            }
        };
        let lo = row(&self.mu[i]);
        let m = if self.speeds_mps.len() == 1 {
            lo
        } else {
            lo + f * (row(&self.mu[i + 1]) - lo)
        };
        m.copysign(w)
    }
}

/// A law evaluated one axle at a time in the step loop (every law but Polach's, which runs on
/// SIMD lanes): μ at slip `w` (m/s), lagged slip rate `q` (m/s²) and speed `v` (m/s).
#[derive(Debug, Clone)]
pub(super) enum ScalarLaw {
    /// A model file, and the ambient temperature (°C) its network takes as a fourth input
    /// (NaN: the file's reference; only networks with a temperature input use it).
    Model(Box<crate::model::Model>, f64),
    LossRecovery(PreparedLossRecovery),
    Table(SlipTable),
    Fastsim(Box<PreparedFastsim>),
}

/// Speed below which FASTSIM's creepage is taken at this speed, m/s: s = Δv / max(v, 0.5)
/// (creepage is undefined at standstill; the Polach law of the simulator floors v too).
pub(super) const FASTSIM_MIN_SPEED_MPS: f64 = 0.5;

/// `law = "fastsim"` prepared for a run: the solver, the wheel's patch at its static load Q0
/// (FASTSIM is evaluated per wheel: μ = F_x / Q), the friction. Under load transfer the patch
/// follows the wheel's load Q: Hertz's semi-axes grow as (Q/Q0)^(1/3) at a fixed aspect ratio
/// (seed 001 eq. 1–5), so Kalker's coefficients stay and only a, b and N are rescaled.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct PreparedFastsim {
    pub solver: crate::contact::fastsim::Fastsim,
    pub patch: crate::contact::fastsim::Patch,
    pub friction: crate::contact::fastsim::Friction,
}

impl PreparedFastsim {
    /// μ at slip `w` (m/s), speed `v` (m/s) and patch size `ratio` = (Q/Q0)^(1/3): F_x/Q of
    /// the creepage w / max(v, 0.5). Inputs are finite in a running simulation; a domain error
    /// (none expected) gives 0.
    #[inline]
    pub(super) fn mu(&self, w: f64, v: f64, ratio: f64) -> f64 {
        let v = v.max(FASTSIM_MIN_SPEED_MPS);
        let c = crate::contact::fastsim::Creepage {
            sx: w / v,
            sy: 0.0,
            spin_per_m: 0.0,
            speed_mps: v,
        };
        let mut patch = self.patch;
        if ratio != 1.0 {
            patch.a_m *= ratio;
            patch.b_m *= ratio;
            patch.normal_n *= ratio * ratio * ratio;
        }
        self.solver
            .forces(&patch, &self.friction, &c)
            .map_or(0.0, |f| f.fx_n / patch.normal_n)
    }
}

impl ScalarLaw {
    /// μ at slip `w` (m/s), lagged slip rate `q` (m/s²), speed `v` (m/s); `patch`, the Hertz
    /// semi-axes relative to the static load's (1 without load transfer), is read by the
    /// `fastsim` law only (the others are laws of μ, not of a contact patch).
    #[inline]
    pub(super) fn mu(&self, w: f64, q: f64, v: f64, patch: f64) -> f64 {
        match self {
            ScalarLaw::Model(m, t_c) => m.mu_vt(w, q, v, *t_c),
            ScalarLaw::LossRecovery(l) => l.mu(w, q, v),
            ScalarLaw::Table(t) => t.mu(w, v),
            ScalarLaw::Fastsim(f) => f.mu(w, v, patch),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn law() -> PreparedLossRecovery {
        LossRecovery {
            loss: Branch {
                peak_mu: 0.1,
                peak_slip_mps: 0.8,
                residual: 0.55,
            },
            recovery: Branch {
                peak_mu: 0.065,
                peak_slip_mps: 1.6,
                residual: 0.8,
            },
            blend_ddv_mps2: 0.5,
            speed_coefficient: 0.3,
            speed_form: SpeedForm::Ratio,
            level_scale: 1.0,
            reference_speed_mps: 120.0 / 3.6,
            temperature_coefficient_per_k: 0.006,
        }
        .prepare(None)
    }

    #[test]
    fn branches_peak_where_asked_and_settle_at_the_residual() {
        let l = law();
        let v = 120.0 / 3.6;
        // Far into growing slip the loss branch alone.
        let grid = |q: f64| -> (f64, f64) {
            (1..=4000)
                .map(|i| i as f64 * 1e-3)
                .map(|w| (w, l.mu(w, q, v)))
                .fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a })
        };
        let (w, m) = grid(1e6);
        assert!((w - 0.8).abs() <= 1e-3 && (m - 0.1).abs() < 1e-9, "{w} {m}");
        let (w, m) = grid(-1e6);
        assert!(
            (w - 1.6).abs() <= 1e-3 && (m - 0.065).abs() < 1e-9,
            "{w} {m}"
        );
        assert!((l.mu(1e4, 1e6, v) - 0.055).abs() < 1e-3);
        // Odd in slip; loss above recovery at the loss peak.
        assert_eq!(l.mu(-0.5, 1.0, v), -l.mu(0.5, 1.0, v));
        assert!(l.mu(0.8, 2.0, v) > l.mu(0.8, -2.0, v));
        // Slower is grippier.
        assert!(l.peaks(80.0 / 3.6).0 > l.peaks(200.0 / 3.6).0);
    }

    proptest::proptest! {
        /// Both laws are finite, odd, have the sign of the slip and never exceed their peaks.
        #[test]
        fn finite_odd_and_bounded_by_the_peaks(
            w in -50.0f64..50.0, q in -100.0f64..100.0, v in 0.0f64..120.0
        ) {
            let l = law();
            let m = l.mu(w, q, v);
            let (pl, pr) = l.peaks(v);
            proptest::prop_assert!(m.is_finite());
            proptest::prop_assert!(m * w.signum() >= 0.0);
            proptest::prop_assert!(m.abs() <= pl.max(pr) * (1.0 + 1e-12));
            proptest::prop_assert_eq!(l.mu(-w, q, v), -m);
            let t = SlipTable::default_table();
            let m = t.mu(w, v);
            proptest::prop_assert!(m.is_finite() && m * w.signum() >= 0.0 && m.abs() <= 0.105);
            proptest::prop_assert_eq!(t.mu(-w, v), -m);
        }
    }

    #[test]
    fn table_interpolates_and_holds_at_the_ends() {
        let t = SlipTable::default_table();
        t.check().unwrap();
        let v80 = 80.0 / 3.6;
        assert_eq!(t.mu(0.6, v80), 0.105);
        assert!((t.mu(0.7, v80) - 0.0925).abs() < 1e-12);
        assert_eq!(t.mu(50.0, v80), 0.055);
        assert_eq!(t.mu(0.6, 10.0), 0.105);
        assert!((t.mu(0.6, 110.0 / 3.6) - 0.0975).abs() < 1e-12);
        assert_eq!(t.mu(-0.6, v80), -0.105);
        let mut bad = t.clone();
        bad.mu[1].pop();
        assert!(bad.check().unwrap_err().contains("row 2"));
    }

    #[test]
    fn the_fastsim_patch_follows_the_wheel_load() {
        use crate::contact::fastsim::{Bound, Fastsim, Friction, Patch};
        let law = PreparedFastsim {
            solver: Fastsim::new(12, 12, Bound::Elliptic).unwrap(),
            patch: Patch {
                a_m: 6e-3,
                b_m: 4e-3,
                g_pa: 8e10,
                c11: 4.1,
                c22: 3.6,
                c23: 1.6,
                normal_n: 60e3,
            },
            friction: Friction::constant(0.3),
        };
        let v = 20.0;
        for ratio in [0.9_f64, 1.1, 1.25] {
            // Creep region: F_x = G a b C11 ξ grows as ratio², Q as ratio³ → μ ∝ 1/ratio
            // (the grid is relative to the patch, so the discrete solution scales exactly).
            let w = 1e-6 * v;
            let (m1, mr) = (law.mu(w, v, 1.0), law.mu(w, v, ratio));
            assert!((mr * ratio / m1 - 1.0).abs() < 1e-9, "{ratio}: {m1} {mr}");
            // Full sliding: μ whatever the load.
            let (m1, mr) = (law.mu(0.5 * v, v, 1.0), law.mu(0.5 * v, v, ratio));
            assert!(
                (mr - m1).abs() < 1e-12 && (m1 - 0.3).abs() < 1e-9,
                "{m1} {mr}"
            );
        }
    }
}
