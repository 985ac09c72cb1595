//! `railgrip contact`: creep curves of the contact laws for one patch, side by side, as CSV —
//! and, for FASTSIM, the flash temperature of each point (railgrip::contact).

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Context as _;
use railgrip::contact::fastsim::{Bound, Creepage, Fastsim, Field, Friction, Patch, Reduction};
use railgrip::contact::flash::{flash_temperature, Heating, Material};
use railgrip::contact::hertz::{hertz, HertzContact, HertzInput};
use railgrip::contact::kalker::KalkerCoefficients;
use railgrip::contact::polach::{polach, ContactPatch, PolachParams};
use railgrip::contact::{kalker, linear_saturated_fx, shear_modulus_pa};

use super::EXIT_OK;

/// A contact law of the library.
#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq, Debug)]
pub enum Law {
    /// Kalker's linear theory, F = G a b C11 ξ (unbounded).
    Linear,
    /// Linear + Shen–Hedrick–Elkins saturation.
    Saturated,
    /// Polach with falling friction (seed 004).
    Polach,
    /// FASTSIM (Kalker's simplified theory).
    Fastsim,
    /// FASTSIM with Spiryagin et al.'s stiffness reduction (--k0, --alpha-inf, --beta).
    FastsimModified,
}

impl Law {
    fn name(self) -> &'static str {
        match self {
            Law::Linear => "linear",
            Law::Saturated => "saturated",
            Law::Polach => "polach",
            Law::Fastsim => "fastsim",
            Law::FastsimModified => "fastsim_modified",
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq, Debug)]
pub enum BoundArg {
    Elliptic,
    Parabolic,
}

#[derive(clap::Args)]
pub struct Args {
    /// Laws to compute, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "linear,saturated,polach,fastsim"
    )]
    law: Vec<Law>,
    /// Wheel load (normal force of one wheel), N.
    #[arg(long, default_value_t = 50_000.0)]
    load_n: f64,
    /// Wheel rolling radius, m.
    #[arg(long, default_value_t = 0.46)]
    wheel_radius_m: f64,
    /// Wheel profile radius across the rolling direction, m (negative: concave; inf: cylinder).
    #[arg(long, default_value_t = -0.5, allow_hyphen_values = true)]
    wheel_lateral_radius_m: f64,
    /// Rail head (crown) radius, m.
    #[arg(long, default_value_t = 0.3)]
    rail_lateral_radius_m: f64,
    /// Young's modulus, Pa.
    #[arg(long, default_value_t = 2.1e11)]
    youngs_modulus_pa: f64,
    /// Poisson's ratio.
    #[arg(long, default_value_t = 0.3)]
    poisson: f64,
    /// Friction coefficient μ0 (at zero slip velocity).
    #[arg(long, default_value_t = 0.3)]
    mu0: f64,
    /// Falling friction A = μ∞/μ0 (1: constant friction).
    #[arg(long, default_value_t = 1.0)]
    a_ratio: f64,
    /// Falling friction B, s/m.
    #[arg(long, default_value_t = 0.0)]
    b_s_per_m: f64,
    /// Polach's k_A and k_S.
    #[arg(long, default_value_t = 1.0)]
    k_a: f64,
    #[arg(long, default_value_t = 0.4)]
    k_s: f64,
    /// Rolling speed, km/h.
    #[arg(long, default_value_t = 60.0)]
    speed_kmh: f64,
    /// Largest longitudinal creepage ξ (the curve runs 0 … this).
    #[arg(long, default_value_t = 0.02)]
    creepage_max: f64,
    /// Points on the curve.
    #[arg(long, default_value_t = 101)]
    steps: usize,
    /// Lateral creepage η held for the whole curve.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    lateral_creepage: f64,
    /// Spin φ held for the whole curve, 1/m.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    spin_per_m: f64,
    /// FASTSIM grid: N × N cells (1 … 1000).
    #[arg(long, default_value_t = 20)]
    grid: usize,
    /// FASTSIM traction bound.
    #[arg(long, value_enum, default_value = "elliptic")]
    bound: BoundArg,
    /// Modified FASTSIM: k0, α∞, β [assumed defaults].
    #[arg(long, default_value_t = 0.6)]
    k0: f64,
    #[arg(long, default_value_t = 0.2)]
    alpha_inf: f64,
    #[arg(long, default_value_t = 0.4)]
    beta: f64,
    /// Add flash temperatures (strip model on the FASTSIM slip field) to the first FASTSIM law.
    #[arg(long)]
    temperature: bool,
    /// Bulk temperature before the contact, °C.
    #[arg(long, default_value_t = 20.0, allow_hyphen_values = true)]
    initial_temperature_c: f64,
    /// Heat partition to the rail.
    #[arg(long, default_value_t = 0.5)]
    partition: f64,
    /// Thermal conductivity, W/(m·K).
    #[arg(long, default_value_t = 48.0)]
    conductivity: f64,
    /// Specific heat, J/(kg·K).
    #[arg(long, default_value_t = 500.0)]
    specific_heat: f64,
    /// Density, kg/m³.
    #[arg(long, default_value_t = 7850.0)]
    density: f64,
    /// Report the temperature this long after a point leaves the contact, ms.
    #[arg(long, default_value_t = 0.0)]
    after_ms: f64,
    /// Write the CSV here (default: standard output).
    #[arg(long, short)]
    out: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<u8> {
    check(&args)?;
    let laws = Laws::new(&args)?;
    let mut field = laws.plain.field();
    let mut text = header(&args, laws.thermal.is_some()).join(",") + "\n";
    for i in 0..args.steps {
        let sx = args.creepage_max * i as f64 / (args.steps - 1) as f64;
        let row = laws.row(&args, sx, &mut field)?;
        let cells: Vec<String> = row.iter().map(|x| format!("{x}")).collect();
        text += &cells.join(",");
        text.push('\n');
    }
    let (h, k) = (&laws.hertz, &laws.kalker);
    eprintln!(
        "patch: a = {:.3} mm, b = {:.3} mm, p_max = {:.0} MPa, C11 {:.3}, C22 {:.3}, C23 {:.3}, C33 {:.3}",
        h.a_m * 1e3,
        h.b_m * 1e3,
        h.p_max_pa / 1e6,
        k.c11,
        k.c22,
        k.c23,
        k.c33
    );
    match &args.out {
        Some(path) => {
            railgrip_io::atomic::write_atomically(path, |w| w.write_all(text.as_bytes()))
                .with_context(|| format!("{}: cannot write", path.display()))?;
            eprintln!("wrote {} ({} points)", path.display(), args.steps);
        }
        None => std::io::stdout().write_all(text.as_bytes())?,
    }
    Ok(EXIT_OK)
}

/// The curve's range, points and speed.
fn check(args: &Args) -> anyhow::Result<()> {
    if args.steps < 2 || args.steps > 100_000 {
        anyhow::bail!("--steps {} must be 2 ..= 100000", args.steps);
    }
    if !(args.creepage_max.is_finite() && args.creepage_max > 0.0 && args.creepage_max <= 1.0) {
        anyhow::bail!(
            "--creepage-max {} must be in (0, 1] (a slip ratio)",
            args.creepage_max
        );
    }
    if !(args.speed_kmh.is_finite() && args.speed_kmh > 0.0 && args.speed_kmh <= 1000.0) {
        anyhow::bail!("--speed-kmh {} must be in (0, 1000]", args.speed_kmh);
    }
    Ok(())
}

/// The CSV header: creepage and slip velocity, then per law its columns, then the flash
/// temperatures.
fn header(args: &Args, thermal: bool) -> Vec<String> {
    let mut header = vec!["creepage".to_string(), "slip_velocity_mps".to_string()];
    for l in &args.law {
        let n = l.name();
        header.push(format!("fx_{n}_N"));
        header.push(format!("mu_{n}"));
        if matches!(l, Law::Fastsim | Law::FastsimModified) {
            header.push(format!("fy_{n}_N"));
            header.push(format!("mz_{n}_Nm"));
            header.push(format!("slip_fraction_{n}"));
        }
    }
    if thermal {
        header.extend(["peak_temperature_c", "after_temperature_c", "power_W"].map(String::from));
    }
    header
}

/// The patch and every law of the command line, checked.
struct Laws {
    hertz: HertzContact,
    kalker: KalkerCoefficients,
    g: f64,
    patch: Patch,
    cpatch: ContactPatch,
    friction: Friction,
    polach: PolachParams,
    plain: Fastsim,
    modified: Fastsim,
    /// With --temperature: the material, the heating and the FASTSIM law it follows.
    thermal: Option<(Material, Heating, Law)>,
}

impl Laws {
    fn new(args: &Args) -> anyhow::Result<Laws> {
        let h = hertz(&HertzInput {
            normal_n: args.load_n,
            youngs_modulus_pa: args.youngs_modulus_pa,
            poisson: args.poisson,
            wheel_rolling_radius_m: args.wheel_radius_m,
            wheel_lateral_radius_m: args.wheel_lateral_radius_m,
            rail_longitudinal_radius_m: f64::INFINITY,
            rail_lateral_radius_m: args.rail_lateral_radius_m,
        })
        .context("contact patch (Hertz): check --load-n and the radii")?;
        let k = kalker::coefficients(h.a_m, h.b_m, args.poisson)
            .context("Kalker coefficients: the patch's a/b is outside the table")?;
        let g = shear_modulus_pa(args.youngs_modulus_pa, args.poisson);
        let patch = Patch::new(&h, g, &k, args.load_n);
        let cpatch = ContactPatch {
            a_m: h.a_m,
            b_m: h.b_m,
            g_pa: g,
            c11: k.c11,
            c22: k.c22,
        };
        let friction = Friction {
            mu0: args.mu0,
            a_ratio: args.a_ratio,
            b_s_per_m: args.b_s_per_m,
        };
        friction
            .check()
            .context("friction (--mu0, --a-ratio, --b-s-per-m)")?;
        let pp = PolachParams {
            mu0: args.mu0,
            a_ratio: args.a_ratio,
            b_s_per_m: args.b_s_per_m,
            k_a: args.k_a,
            k_s: args.k_s,
        };
        if args.law.contains(&Law::Polach) {
            pp.check().context("Polach parameters (--k-a, --k-s)")?;
        }
        let bound = match args.bound {
            BoundArg::Elliptic => Bound::Elliptic,
            BoundArg::Parabolic => Bound::Parabolic,
        };
        let plain = Fastsim::new(args.grid, args.grid, bound).context("--grid")?;
        let modified = plain
            .modified(Reduction {
                k0: args.k0,
                alpha_inf: args.alpha_inf,
                beta: args.beta,
            })
            .context("modified FASTSIM (--k0, --alpha-inf, --beta)")?;
        let thermal = if args.temperature {
            let m = Material {
                conductivity_w_per_mk: args.conductivity,
                specific_heat_j_per_kgk: args.specific_heat,
                density_kg_per_m3: args.density,
            };
            let ht = Heating {
                partition: args.partition,
                initial_temperature_c: args.initial_temperature_c,
                after_s: args.after_ms / 1000.0,
            };
            m.check()
                .context("material (--conductivity, --specific-heat, --density)")?;
            ht.check()
                .context("heating (--partition, --initial-temperature-c, --after-ms)")?;
            let first = args
                .law
                .iter()
                .find(|l| matches!(l, Law::Fastsim | Law::FastsimModified))
                .copied()
                .context(
                    "--temperature needs a FASTSIM law in --law (fastsim or fastsim-modified)",
                )?;
            Some((m, ht, first))
        } else {
            None
        };
        Ok(Laws {
            hertz: h,
            kalker: k,
            g,
            patch,
            cpatch,
            friction,
            polach: pp,
            plain,
            modified,
            thermal,
        })
    }

    /// One row of the table at creepage `sx` (`field`: FASTSIM's work space).
    fn row(&self, args: &Args, sx: f64, field: &mut Field) -> anyhow::Result<Vec<f64>> {
        let (h, k, g, v) = (&self.hertz, &self.kalker, self.g, args.speed_kmh / 3.6);
        let (patch, cpatch, friction, pp) =
            (&self.patch, &self.cpatch, &self.friction, &self.polach);
        let (plain, modified, thermal) = (&self.plain, &self.modified, &self.thermal);
        let creep = Creepage {
            sx,
            sy: args.lateral_creepage,
            spin_per_m: args.spin_per_m,
            speed_mps: v,
        };
        let mut row = vec![sx, sx * v];
        let mut thermal_row = None;
        for l in &args.law {
            match l {
                Law::Linear => {
                    let f = kalker::linear_creep(
                        g,
                        h.a_m,
                        h.b_m,
                        k,
                        sx,
                        args.lateral_creepage,
                        args.spin_per_m,
                    )?;
                    row.extend([f.fx_n, f.fx_n / args.load_n]);
                }
                Law::Saturated => {
                    let fx = linear_saturated_fx(cpatch, friction.mu(sx * v), args.load_n, sx)?;
                    row.extend([fx, fx / args.load_n]);
                }
                Law::Polach => {
                    let f = polach(
                        cpatch,
                        pp,
                        args.load_n,
                        v,
                        sx * v,
                        args.lateral_creepage * v,
                    )?;
                    row.extend([f.fx_n, f.fx_n / args.load_n]);
                }
                Law::Fastsim | Law::FastsimModified => {
                    let fs = if *l == Law::Fastsim {
                        &plain
                    } else {
                        &modified
                    };
                    let f = fs.solve(patch, friction, &creep, field)?;
                    // The temperature of the first FASTSIM law, from the field just solved.
                    if let Some((m, ht, first)) = &thermal {
                        if first == l && thermal_row.is_none() {
                            let t = flash_temperature(field, v, m, ht)?;
                            thermal_row = Some([t.peak_c, t.after_c, f.power_w]);
                        }
                    }
                    row.extend([
                        f.fx_n,
                        f.fx_n / args.load_n,
                        f.fy_n,
                        f.mz_nm,
                        f.slip_fraction,
                    ]);
                }
            }
        }
        if let Some(t) = thermal_row {
            row.extend(t);
        }
        Ok(row)
    }
}
