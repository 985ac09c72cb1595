//! `[brake]`: the demanded cylinder pressures and the cylinders.

use super::text;
use crate::config::rule::{closed, int, Checker, Key};
use crate::config::ConfigError;

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Brake {
        pub demand_bar: Option<Vec<[f64; 2]>>,
        pub demand_bar_per_axle: Option<Vec<Vec<[f64; 2]>>>,
        pub cylinder_time_constant_s: Option<f64>,
        pub alpha_scatter: Option<f64>,
        pub scatter_seed: Option<f64>,
        pub pad_friction_rise: Option<f64>,
        pub pad_friction_v0_kmh: Option<f64>,
        pub pad_friction_exponent: Option<f64>,
    }
}

/// `[brake]`: the demanded cylinder pressures and the cylinders.
#[derive(Debug, Clone, PartialEq)]
pub struct BrakeSection {
    /// Brake-cylinder pressure demand per axle (t s, p bar), piecewise linear, held after the
    /// last point.
    pub demand_bar: [Vec<(f64, f64)>; 4],
    pub cylinder_time_constant_s: f64,
    /// `brake_scatter`: 1σ relative scatter of each axle's brake coefficient.
    pub alpha_scatter: f64,
    /// `brake_scatter`: the seed of the draw — the vehicle's identity, the same for every run
    /// of a campaign that shares it (not the run's noise seed, and not written to the log).
    pub scatter_seed: u64,
    /// `pad_friction`: the brake coefficient's relative rise from the initial speed to
    /// standstill.
    pub pad_friction_rise: f64,
    /// `pad_friction`: the speed v0 above which the brake coefficient is α_i, km/h; 0 for the
    /// run's initial speed. Give the campaign's top speed for one vehicle's pads in every run
    /// (pad friction depends on the speed, not on where the brake began).
    pub pad_friction_v0_kmh: f64,
    /// `pad_friction`: the exponent n of its shape, (1 − v/v0)^n: 1 linear; 1, 2 and 3 are
    /// among the calibration's forms, others (0.5–4) lie between or beyond them.
    pub pad_friction_exponent: f64,
}

pub(super) const DEMAND: Key = text(
    "brake.demand_bar",
    "[s, bar]",
    "[t, p] points, t increasing, 0 ≤ p ≤ 20",
    "[[0, 0], [1, 0], [2.5, 3.8]]",
    "cylinder-pressure demand of every axle, piecewise linear, held after the last point",
);
pub(super) const DEMAND_PER_AXLE: Key = text(
    "brake.demand_bar_per_axle",
    "4 × [s, bar]",
    "four such profiles",
    "–",
    "the demand per axle instead",
);
pub(super) const CYLINDER: Key = Key::num(
    "brake.cylinder_time_constant_s",
    "s",
    closed(0.005, 5.0),
    0.15,
    "first-order cylinder",
);

pub(super) const SCATTER: Key = Key::num(
    "brake.alpha_scatter",
    "–",
    closed(0.0, 0.2),
    0.02,
    "`brake_scatter`: 1σ relative scatter of each axle's brake coefficient α_i from the pipeline's, drawn from `brake.scatter_seed`",
);
pub(super) const SCATTER_SEED: Key = Key::num(
    "brake.scatter_seed",
    "",
    int(0.0, 1e9),
    1.0,
    "`brake_scatter`: the seed of the draw, the vehicle's identity (runs of one vehicle share it; not the noise seed, not in the log)",
);
pub(super) const PAD_RISE: Key = Key::num(
    "brake.pad_friction_rise",
    "–",
    closed(-0.5, 0.5),
    0.05,
    "`pad_friction`: α_i(v) = α_i (1 + rise max(0, 1 − v/v0)^n), v the train's speed, the rise from v0 to standstill",
);
pub(super) const PAD_V0: Key = Key::num(
    "brake.pad_friction_v0_kmh",
    "km/h",
    closed(0.0, 600.0),
    0.0,
    "`pad_friction`: v0 of that law; 0 for the run's initial speed (give the campaign's top speed for one vehicle's pads in every run)",
);

pub(super) const PAD_EXPONENT: Key = Key::num(
    "brake.pad_friction_exponent",
    "–",
    closed(0.5, 4.0),
    1.0,
    "`pad_friction`: n of that law: 1 linear; other powers test the calibration's choice of form (its candidates: constant, linear, quadratic, cubic, the linear–quadratic and quadratic–cubic mixtures, Karwatzki's; n = 2.5 lies between two powers) [assumed]",
);

/// The keys of `[brake]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
    &DEMAND,
    &DEMAND_PER_AXLE,
    &CYLINDER,
    &SCATTER,
    &SCATTER_SEED,
    &PAD_RISE,
    &PAD_V0,
    &PAD_EXPONENT,
];

impl Checker<'_> {
    /// `[brake]` checked.
    pub(crate) fn brake(&self, b: &raw::Brake) -> Result<BrakeSection, ConfigError> {
        let profile = |key: &str, d: &Vec<[f64; 2]>| -> Result<Vec<(f64, f64)>, ConfigError> {
            if d.is_empty()
                || d.windows(2).any(|w| w[1][0] <= w[0][0])
                || d.iter()
                    .any(|p| !p[0].is_finite() || !(0.0..=20.0).contains(&p[1]))
            {
                return Err(self.invalid(
                    key,
                    format!("{d:?}"),
                    "must list [t_s, p_bar] points with strictly increasing t and 0 <= p <= 20 bar",
                ));
            }
            Ok(d.iter().map(|p| (p[0], p[1])).collect())
        };
        let demand_bar: [Vec<(f64, f64)>; 4] = match (&b.demand_bar, &b.demand_bar_per_axle) {
            (Some(_), Some(_)) => {
                return Err(self.invalid(
                    DEMAND_PER_AXLE.name,
                    format!("given with {}", DEMAND.name),
                    "give one of the two",
                ))
            }
            (_, Some(per)) => {
                if per.len() != 4 {
                    return Err(self.invalid(
                        DEMAND_PER_AXLE.name,
                        format!("{} profiles", per.len()),
                        "must list exactly 4 profiles, axles 1..4",
                    ));
                }
                let mut out: [Vec<(f64, f64)>; 4] = std::array::from_fn(|_| Vec::new());
                for (i, d) in per.iter().enumerate() {
                    out[i] = profile(&format!("{}[{i}]", DEMAND_PER_AXLE.name), d)?;
                }
                out
            }
            (Some(d), None) => {
                let one = profile(DEMAND.name, d)?;
                [one.clone(), one.clone(), one.clone(), one]
            }
            (None, None) => std::array::from_fn(|_| vec![(0.0, 0.0), (1.0, 0.0), (2.5, 3.8)]),
        };
        Ok(BrakeSection {
            demand_bar,
            cylinder_time_constant_s: self.value(&CYLINDER, b.cylinder_time_constant_s)?,
            alpha_scatter: self.value(&SCATTER, b.alpha_scatter)?,
            scatter_seed: self.value(&SCATTER_SEED, b.scatter_seed)? as u64,
            pad_friction_rise: self.value(&PAD_RISE, b.pad_friction_rise)?,
            pad_friction_v0_kmh: self.value(&PAD_V0, b.pad_friction_v0_kmh)?,
            pad_friction_exponent: self.value(&PAD_EXPONENT, b.pad_friction_exponent)?,
        })
    }
}
