//! FASTSIM: Kalker's simplified theory of rolling contact (seed 001_20bb3776135e7607.txt,
//! section on the simplified theory; Kalker, "A fast algorithm for the simplified theory of
//! rolling contact", Vehicle System Dynamics 11 (1982) 1–13), on a Hertz ellipse, with
//! longitudinal and lateral creepage and spin, the modified FASTSIM of Spiryagin, Polach & Cole
//! (Vehicle System Dynamics 51, 2013) and Polach's falling friction.
//!
//! **Model.** The surface is a bed of independent springs: the tangential displacement u_i
//! (m) at a point is L_i times the traction p_i (Pa) there. With the flexibilities
//! (reference-values.md, "Kalker linear-theory coefficients")
//!
//!   L1 = 8a / (3 C11 G),   L2 = 8a / (3 C22 G),   L3 = π a √(a/b) / (4 C23 G)   (m/Pa)
//!
//! the small-creepage forces equal Kalker's linear theory exactly: F_x = G a b C11 ξ,
//! F_y = G a b C22 η + G (ab)^(3/2) C23 φ (tested). A particle entering at the leading edge
//! x = a(y) = a √(1 − y²/b²) and moving towards −a(y) accumulates, while it sticks,
//!
//!   dp_x = (ξ/L1 − φ y / L3) dx,    dp_y = (η/L2 + φ x / L3) dx            (per dx travelled)
//!
//! and where |p| would exceed the traction bound g = μ p_n(x, y) it slides with |p| = g in the
//! direction of the trial traction. The normal pressure p_n is Kalker's parabolic one,
//! 2N/(πab)·(1 − x²/a² − y²/b²) (with which FASTSIM was made), or Hertz's elliptic one,
//! 3N/(2πab)·√(1 − x²/a² − y²/b²) (seed 001 eq. 5), scaled on each grid so that the cells
//! carry exactly N (a coarse midpoint sum of the pressure over- or undershoots N; with the
//! scale |F| ≤ μN holds on every grid and full sliding gives exactly μN).
//!
//! **Sign convention:** railgrip's (see [`super::kalker`]): creepage ξ = s_x = Δv/v positive in
//! braking, spin φ in 1/m, and the traction is the one the rail exerts against the wheel's
//! sliding, so F has the sign of the creepage.
//!
//! **Slip velocity field.** In a sliding cell the local slip (dimensionless, relative to the
//! rolling speed V) is what the springs could not take up, s_i = L_i (p_trial,i − p_i)/dx, and
//! its velocity V·|s| (m/s); in a sticking cell it is 0. The frictional power density |p|·V|s|
//! (W/m²) is the heat source of [`super::flash`].
//!
//! **Grid.** ny strips of equal width across y ∈ (−b, b) (the strip's value at its centre y_j);
//! each strip is cut into nx cells of length dx = 2a(y_j)/nx; tractions and the bound are
//! evaluated at cell centres (the first step travels half a cell from the leading edge) and
//! integrated by the midpoint rule — exact along x for the linear, sticking solution, and a
//! small creepage sticks everywhere (a bound evaluated on the trailing edge itself would be 0
//! and make the last cell slide at any creepage). The spin term of p_y integrates x over the
//! travel exactly. Error: O(1/ny²) in the sticking regime, lower order once the slip boundary
//! crosses cells (measured in docs/contact.md).
//!
//! **Modified FASTSIM** (Spiryagin et al. 2013): the stiffness is reduced by
//! k = k0·[α∞ + (1 − α∞)/(1 + β ε)], L_i → L_i / k, with ε = G π a b C11 |s| / (4 N μ) the
//! gradient of the tangential stress of Polach's model (seed 004 eq. 2), |s| = √(ξ² + η²).
//! The form is as railgrip states it from the paper; it was not checked against the paper's
//! text here (no copy in ../shared/seeds).
//!
//! **Falling friction** (Polach 2005; seed 004): μ = μ0·[(1 − A) e^(−B w) + A] with w = V|s|
//! the creep velocity of the contact (m/s), one μ for the whole patch (as Polach and Spiryagin
//! et al. use it; a local μ(w(x, y)) would make each cell implicit).
//!
//! No allocation per call: [`Fastsim::forces`] keeps two running tractions; [`Fastsim::solve`]
//! writes the field into a [`Field`] allocated once with the grid.

use super::{check_finite, check_positive, ContactError};
use std::f64::consts::PI;

/// Largest number of cells per side of the grid.
pub const MAX_CELLS_PER_SIDE: usize = 1000;

/// The traction bound's pressure distribution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bound {
    /// Kalker's FASTSIM pressure 2N/(πab)(1 − x²/a² − y²/b²).
    Parabolic,
    /// Hertz's 3N/(2πab)√(1 − x²/a² − y²/b²).
    Elliptic,
}

impl Bound {
    pub fn name(self) -> &'static str {
        match self {
            Bound::Parabolic => "parabolic",
            Bound::Elliptic => "elliptic",
        }
    }
}

/// The stiffness reduction of the modified FASTSIM (Spiryagin et al. 2013).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reduction {
    /// k0: the reduction at zero creepage, (0, 1].
    pub k0: f64,
    /// α∞: the fraction of k0 left at large creepage, (0, 1].
    pub alpha_inf: f64,
    /// β: how fast the reduction falls with ε, ≥ 0.
    pub beta: f64,
}

impl Reduction {
    /// Checks the domain.
    pub fn check(&self) -> Result<(), ContactError> {
        for (what, x) in [
            ("k0", self.k0),
            ("alpha_inf", self.alpha_inf),
            ("beta", self.beta),
        ] {
            check_finite(what, x)?;
        }
        let d = |what, value, valid| Err(ContactError::Domain { what, value, valid });
        if !(self.k0 > 0.0 && self.k0 <= 1.0) {
            return d("k0", self.k0, "0 < k0 <= 1");
        }
        if !(self.alpha_inf > 0.0 && self.alpha_inf <= 1.0) {
            return d("alpha_inf", self.alpha_inf, "0 < alpha_inf <= 1");
        }
        if self.beta < 0.0 {
            return d("beta", self.beta, "beta >= 0");
        }
        Ok(())
    }

    /// k(ε) = k0 [α∞ + (1 − α∞)/(1 + β ε)].
    #[inline]
    pub fn factor(&self, epsilon: f64) -> f64 {
        self.k0 * (self.alpha_inf + (1.0 - self.alpha_inf) / (1.0 + self.beta * epsilon))
    }
}

/// The contact: Hertz semi-axes, shear modulus, Kalker's coefficients, normal force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Patch {
    /// Semi-axis in the rolling direction, m.
    pub a_m: f64,
    /// Semi-axis across it, m.
    pub b_m: f64,
    /// Shear modulus G, Pa.
    pub g_pa: f64,
    pub c11: f64,
    pub c22: f64,
    pub c23: f64,
    /// Normal force N, newtons.
    pub normal_n: f64,
}

impl Patch {
    /// From a Hertz contact at `normal_n` and the Kalker coefficients of its aspect ratio.
    pub fn new(
        hertz: &super::hertz::HertzContact,
        g_pa: f64,
        c: &super::kalker::KalkerCoefficients,
        normal_n: f64,
    ) -> Patch {
        Patch {
            a_m: hertz.a_m,
            b_m: hertz.b_m,
            g_pa,
            c11: c.c11,
            c22: c.c22,
            c23: c.c23,
            normal_n,
        }
    }

    /// Checks every value is finite and positive.
    pub fn check(&self) -> Result<(), ContactError> {
        for (what, x) in [
            ("semi-axis a", self.a_m),
            ("semi-axis b", self.b_m),
            ("shear modulus G", self.g_pa),
            ("c11", self.c11),
            ("c22", self.c22),
            ("c23", self.c23),
            ("normal force N", self.normal_n),
        ] {
            check_positive(what, x)?;
        }
        Ok(())
    }

    /// The flexibilities L1, L2, L3, m/Pa (module text).
    pub fn flexibilities(&self) -> [f64; 3] {
        let (a, b, g) = (self.a_m, self.b_m, self.g_pa);
        [
            8.0 * a / (3.0 * self.c11 * g),
            8.0 * a / (3.0 * self.c22 * g),
            PI * a * (a / b).sqrt() / (4.0 * self.c23 * g),
        ]
    }
}

/// Friction: μ0 and Polach's falling friction μ0[(1 − A) e^(−B w) + A] (A = 1 or B = 0:
/// constant μ0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Friction {
    /// μ0, (0, 1.5].
    pub mu0: f64,
    /// A = μ∞/μ0, (0, 1].
    pub a_ratio: f64,
    /// B, s/m, ≥ 0.
    pub b_s_per_m: f64,
}

impl Friction {
    /// A constant friction coefficient.
    pub fn constant(mu: f64) -> Friction {
        Friction {
            mu0: mu,
            a_ratio: 1.0,
            b_s_per_m: 0.0,
        }
    }

    pub fn check(&self) -> Result<(), ContactError> {
        super::polach::PolachParams {
            mu0: self.mu0,
            a_ratio: self.a_ratio,
            b_s_per_m: self.b_s_per_m,
            k_a: 1.0,
            k_s: 1.0,
        }
        .check()
    }

    /// μ at creep velocity `w` (m/s).
    #[inline]
    pub fn mu(&self, w_mps: f64) -> f64 {
        self.mu0 * ((1.0 - self.a_ratio) * (-self.b_s_per_m * w_mps.abs()).exp() + self.a_ratio)
    }
}

/// Creepages: ξ = s_x, η = s_y (–), spin φ (1/m), and the rolling speed V (m/s) that turns
/// them into velocities (falling friction, slip velocity field).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Creepage {
    pub sx: f64,
    pub sy: f64,
    pub spin_per_m: f64,
    pub speed_mps: f64,
}

impl Creepage {
    pub fn check(&self) -> Result<(), ContactError> {
        check_finite("creepage s_x", self.sx)?;
        check_finite("creepage s_y", self.sy)?;
        check_finite("spin", self.spin_per_m)?;
        check_finite("rolling speed V", self.speed_mps)?;
        if self.speed_mps < 0.0 {
            return Err(ContactError::Domain {
                what: "rolling speed V",
                value: self.speed_mps,
                valid: "V >= 0 (m/s)",
            });
        }
        Ok(())
    }
}

/// What FASTSIM returns.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Forces {
    /// Longitudinal force, N.
    pub fx_n: f64,
    /// Lateral force, N.
    pub fy_n: f64,
    /// Moment of the traction about the contact normal, N·m.
    pub mz_nm: f64,
    /// Fraction of the contact area that slides, 0…1.
    pub slip_fraction: f64,
    /// The friction coefficient used (after falling friction).
    pub mu: f64,
    /// The stiffness factor k used (1 without the modified FASTSIM).
    pub stiffness_factor: f64,
    /// Frictional power V (F_x ξ + F_y η + M_z φ), W (the heat the contact makes: in steady
    /// rolling the creep forces' work is all dissipated by the sliding). The field's
    /// Σ |p| V |s| dA agrees within 0.2 % in full sliding and 3–4 % in partial slip with spin
    /// or lateral creepage (the three flexibilities make the local slip approximate; tested).
    pub power_w: f64,
}

/// The traction and slip field of one solution, cell by cell: strip j, cell i at
/// `j * nx + i`, x and y the cell's centre (where its traction and bound are evaluated).
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    pub nx: usize,
    pub ny: usize,
    /// Cell position, m (x rolling direction: the leading edge is +a).
    pub x_m: Vec<f64>,
    pub y_m: Vec<f64>,
    /// Traction, Pa.
    pub px_pa: Vec<f64>,
    pub py_pa: Vec<f64>,
    /// Slip velocity, m/s (0 where the cell sticks).
    pub slip_velocity_mps: Vec<f64>,
    /// Normal pressure of the bound's distribution, Pa.
    pub pressure_pa: Vec<f64>,
    /// Cell length along x of each strip, m, and the strip width, m.
    pub dx_m: Vec<f64>,
    pub dy_m: f64,
}

impl Field {
    /// A field for an nx × ny grid (allocates once).
    pub fn new(nx: usize, ny: usize) -> Field {
        let n = nx * ny;
        Field {
            nx,
            ny,
            x_m: vec![0.0; n],
            y_m: vec![0.0; n],
            px_pa: vec![0.0; n],
            py_pa: vec![0.0; n],
            slip_velocity_mps: vec![0.0; n],
            pressure_pa: vec![0.0; n],
            dx_m: vec![0.0; ny],
            dy_m: 0.0,
        }
    }

    /// Every per-cell vector holds nx × ny values and `dx_m` ny (the fields are public, so a
    /// hand-made field is checked before it is indexed).
    pub fn check_shape(&self) -> Result<(), ContactError> {
        let cells = self.nx * self.ny;
        let per_cell = [
            &self.x_m,
            &self.y_m,
            &self.px_pa,
            &self.py_pa,
            &self.slip_velocity_mps,
            &self.pressure_pa,
        ];
        if self.dx_m.len() != self.ny || per_cell.iter().any(|v| v.len() != cells) {
            return Err(ContactError::Domain {
                what: "field cells",
                value: cells as f64,
                valid: "nx × ny cells and ny strip lengths: make the field with Field::new or Fastsim::field",
            });
        }
        Ok(())
    }

    /// Frictional power density of cell k, W/m²: |p| · slip velocity.
    pub fn power_density(&self, k: usize) -> f64 {
        self.px_pa[k].hypot(self.py_pa[k]) * self.slip_velocity_mps[k]
    }
}

/// A FASTSIM solver for one grid and bound, optionally modified (Spiryagin et al. 2013).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fastsim {
    nx: usize,
    ny: usize,
    bound: Bound,
    reduction: Option<Reduction>,
    /// The pressure's scale on this grid: the exact integral of the normalised pressure over
    /// the unit ellipse divided by its midpoint sum, so that the cells carry exactly N.
    pressure_scale: f64,
}

impl Fastsim {
    /// nx cells along the rolling direction per strip, ny strips; each 1 … 1000.
    pub fn new(nx: usize, ny: usize, bound: Bound) -> Result<Fastsim, ContactError> {
        for (what, n) in [
            ("FASTSIM cells along x", nx),
            ("FASTSIM strips across y", ny),
        ] {
            if n == 0 || n > MAX_CELLS_PER_SIDE {
                return Err(ContactError::Domain {
                    what,
                    value: n as f64,
                    valid: "1 ..= 1000 cells per side",
                });
            }
        }
        // Σ shape(x_c, y_j) dx dy over the unit circle's cells (the grid scales with a and b,
        // so this depends on nx, ny and the bound only).
        let (mut sum, dy) = (0.0, 2.0 / ny as f64);
        for j in 0..ny {
            let y = -1.0 + (j as f64 + 0.5) * dy;
            let ey = 1.0 - y * y;
            let dx = 2.0 * ey.sqrt() / nx as f64;
            for i in 0..nx {
                let x = ey.sqrt() - (i as f64 + 0.5) * dx;
                let e = (ey - x * x).max(0.0);
                sum += dx
                    * dy
                    * if bound == Bound::Elliptic {
                        e.sqrt()
                    } else {
                        e
                    };
            }
        }
        let exact = if bound == Bound::Elliptic {
            2.0 * PI / 3.0
        } else {
            PI / 2.0
        };
        Ok(Fastsim {
            nx,
            ny,
            bound,
            reduction: None,
            pressure_scale: exact / sum,
        })
    }

    /// The modified FASTSIM with the stiffness reduction `r`.
    pub fn modified(mut self, r: Reduction) -> Result<Fastsim, ContactError> {
        r.check()?;
        self.reduction = Some(r);
        Ok(self)
    }

    pub fn grid(&self) -> (usize, usize) {
        (self.nx, self.ny)
    }

    pub fn bound(&self) -> Bound {
        self.bound
    }

    /// A field sized for this solver's grid.
    pub fn field(&self) -> Field {
        Field::new(self.nx, self.ny)
    }

    /// Forces, moment, slip fraction and power; no allocation.
    pub fn forces(
        &self,
        patch: &Patch,
        friction: &Friction,
        creep: &Creepage,
    ) -> Result<Forces, ContactError> {
        self.run(patch, friction, creep, None)
    }

    /// As [`Fastsim::forces`], and the traction and slip field into `field` (from
    /// [`Fastsim::field`]; an error if its grid differs).
    pub fn solve(
        &self,
        patch: &Patch,
        friction: &Friction,
        creep: &Creepage,
        field: &mut Field,
    ) -> Result<Forces, ContactError> {
        field.check_shape()?;
        if field.nx != self.nx || field.ny != self.ny {
            return Err(ContactError::Domain {
                what: "field grid (cells)",
                value: (field.nx * field.ny) as f64,
                valid: "the solver's nx × ny: make it with Fastsim::field",
            });
        }
        self.run(patch, friction, creep, Some(field))
    }

    fn run(
        &self,
        patch: &Patch,
        friction: &Friction,
        creep: &Creepage,
        mut field: Option<&mut Field>,
    ) -> Result<Forces, ContactError> {
        patch.check()?;
        friction.check()?;
        creep.check()?;
        let (a, b, n) = (patch.a_m, patch.b_m, patch.normal_n);
        let s_abs = creep.sx.hypot(creep.sy);
        let mu = friction.mu(creep.speed_mps * s_abs);
        let k = match self.reduction {
            Some(r) => r.factor(PI * patch.g_pa * a * b * patch.c11 * s_abs / (4.0 * n * mu)),
            None => 1.0,
        };
        let [l1, l2, l3] = patch.flexibilities().map(|l| l / k);
        let (inv_l1, inv_l2, inv_l3) = (1.0 / l1, 1.0 / l2, 1.0 / l3);
        let (pn0, elliptic) = match self.bound {
            Bound::Parabolic => (2.0 * n / (PI * a * b), false),
            Bound::Elliptic => (1.5 * n / (PI * a * b), true),
        };
        let pn0 = pn0 * self.pressure_scale;
        let dy = 2.0 * b / self.ny as f64;
        let v = creep.speed_mps;
        if let Some(f) = field.as_deref_mut() {
            f.dy_m = dy;
        }
        let cst = StripConsts {
            a,
            inv_a: 1.0 / a,
            pn0,
            elliptic,
            mu,
            l1,
            l2,
            v,
            gx0: creep.sx * inv_l1,
            gy: creep.sy * inv_l2,
            gs: creep.spin_per_m * inv_l3,
        };
        let mut acc = Sums::default();
        // Strips y and −y share their length and cells: two independent dependency chains
        // side by side (each cell's trial traction needs the previous cell's), then the
        // middle strip of an odd count alone.
        for j in 0..self.ny / 2 {
            let jm = self.ny - 1 - j;
            let y = -b + (j as f64 + 0.5) * dy;
            match field.as_deref_mut() {
                Some(f) => self.strips::<2, true>(&cst, [y, -y], [j, jm], b, dy, &mut acc, Some(f)),
                None => self.strips::<2, false>(&cst, [y, -y], [j, jm], b, dy, &mut acc, None),
            }
        }
        if self.ny % 2 == 1 {
            let j = self.ny / 2;
            let y = -b + (j as f64 + 0.5) * dy;
            match field {
                Some(f) => self.strips::<1, true>(&cst, [y], [j], b, dy, &mut acc, Some(f)),
                None => self.strips::<1, false>(&cst, [y], [j], b, dy, &mut acc, None),
            }
        }
        let Sums {
            fx,
            fy,
            mz,
            slide_area,
        } = acc;
        // Steady rolling: the creep forces' power is all dissipated (the springs' energy does
        // not change), P = V (F_x ξ + F_y η + M_z φ).
        let power = (v * (fx * creep.sx + fy * creep.sy + mz * creep.spin_per_m)).max(0.0);
        Ok(Forces {
            fx_n: fx,
            fy_n: fy,
            mz_nm: mz,
            slip_fraction: (slide_area / (PI * a * b)).min(1.0),
            mu,
            stiffness_factor: k,
            power_w: power,
        })
    }
}

/// Per-call constants of the strip loop.
struct StripConsts {
    a: f64,
    inv_a: f64,
    pn0: f64,
    elliptic: bool,
    mu: f64,
    l1: f64,
    l2: f64,
    v: f64,
    /// ξ/L1, η/L2, φ/L3.
    gx0: f64,
    gy: f64,
    gs: f64,
}

/// Integrated forces of the strips done so far.
#[derive(Default)]
struct Sums {
    fx: f64,
    fy: f64,
    mz: f64,
    slide_area: f64,
}

impl Fastsim {
    /// L strips of the same length (mirrored in y) at `ys`, indices `js`, side by side.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn strips<const L: usize, const FIELD: bool>(
        &self,
        c: &StripConsts,
        ys: [f64; L],
        js: [usize; L],
        b: f64,
        dy: f64,
        acc: &mut Sums,
        mut field: Option<&mut Field>,
    ) {
        let ey = 1.0 - (ys[0] / b) * (ys[0] / b);
        let ay = c.a * ey.sqrt();
        let dx = 2.0 * ay / self.nx as f64;
        let inv_dx = 1.0 / dx;
        // Sticking increments per dx travelled; the spin term of p_y integrates x over the
        // travel exactly (dp_y/dx ∝ x).
        let gx: [f64; L] = std::array::from_fn(|l| c.gx0 - c.gs * ys[l]);
        let (mut px, mut py) = ([0.0f64; L], [0.0f64; L]);
        let (mut sfx, mut sfy, mut smz) = ([0.0; L], [0.0; L], [0.0; L]);
        let mut n_slide = 0usize;
        let mut x_prev = ay;
        for i in 0..self.nx {
            // Cell centre; the first step travels half a cell from the leading edge.
            let xc = ay - (i as f64 + 0.5) * dx;
            let (step, inv_step) = if i == 0 {
                (0.5 * dx, 2.0 * inv_dx)
            } else {
                (dx, inv_dx)
            };
            let spin_step = c.gs * 0.5 * (x_prev * x_prev - xc * xc);
            // The bound, in units of a (no division per cell); the same for every lane.
            let xu = xc * c.inv_a;
            let e = (ey - xu * xu).max(0.0);
            let pn = c.pn0 * if c.elliptic { e.sqrt() } else { e };
            let g = c.mu * pn;
            for l in 0..L {
                let tx = px[l] + gx[l] * step;
                let ty = py[l] + c.gy * step + spin_step;
                let t2 = tx * tx + ty * ty;
                let (qx, qy, slip_v) = if t2 > g * g {
                    // Slides: |q| = g along the trial traction; the springs' shortfall is
                    // the slip, s_i = L_i (t_i − q_i)/step.
                    let scale = g / t2.sqrt();
                    n_slide += 1;
                    let sv = if FIELD {
                        let rest = 1.0 - scale;
                        let (ux, uy) = (c.l1 * tx * rest, c.l2 * ty * rest);
                        c.v * (ux * ux + uy * uy).sqrt() * inv_step
                    } else {
                        0.0
                    };
                    (tx * scale, ty * scale, sv)
                } else {
                    (tx, ty, 0.0)
                };
                // Midpoint rule over the cell.
                sfx[l] += qx;
                sfy[l] += qy;
                smz[l] += xc * qy - ys[l] * qx;
                if let (true, Some(f)) = (FIELD, field.as_deref_mut()) {
                    let kk = js[l] * self.nx + i;
                    f.x_m[kk] = xc;
                    f.y_m[kk] = ys[l];
                    f.px_pa[kk] = qx;
                    f.py_pa[kk] = qy;
                    f.slip_velocity_mps[kk] = slip_v;
                    f.pressure_pa[kk] = pn;
                }
                px[l] = qx;
                py[l] = qy;
            }
            x_prev = xc;
        }
        let area = dx * dy;
        for l in 0..L {
            acc.fx += sfx[l] * area;
            acc.fy += sfy[l] * area;
            acc.mz += smz[l] * area;
            if let Some(f) = field.as_deref_mut() {
                f.dx_m[js[l]] = dx;
            }
        }
        acc.slide_area += n_slide as f64 * area;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn patch() -> Patch {
        // A UIC-Z1-like wheel on a 60E1 head at 50 kN (a/b ≈ 0.68).
        Patch {
            a_m: 0.0042,
            b_m: 0.0062,
            g_pa: 8.08e10,
            c11: 3.79,
            c22: 3.25,
            c23: 1.11,
            normal_n: 50_000.0,
        }
    }

    #[test]
    fn grid_limits_are_errors() {
        assert!(Fastsim::new(0, 10, Bound::Parabolic).is_err());
        assert!(Fastsim::new(10, 1001, Bound::Elliptic).is_err());
        assert!(Fastsim::new(1000, 1, Bound::Elliptic).is_ok());
    }

    #[test]
    fn zero_creepage_gives_zero_force() {
        let f = Fastsim::new(20, 20, Bound::Elliptic)
            .unwrap()
            .forces(&patch(), &Friction::constant(0.3), &Creepage::default())
            .unwrap();
        assert_eq!(
            (f.fx_n, f.fy_n, f.mz_nm, f.slip_fraction),
            (0.0, 0.0, 0.0, 0.0)
        );
    }

    #[test]
    fn a_field_of_another_grid_is_refused() {
        let fs = Fastsim::new(10, 10, Bound::Elliptic).unwrap();
        let mut f = Field::new(10, 11);
        let c = Creepage {
            sx: 1e-3,
            ..Default::default()
        };
        assert!(fs
            .solve(&patch(), &Friction::constant(0.3), &c, &mut f)
            .is_err());
    }
}
