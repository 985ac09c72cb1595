//! `[contact]`: wheel–rail contact geometry and material for the Hertz patch (seed 001 eq. 1–5)
//! behind the Polach fits and the models' linear creep region; scene files take the same keys.

use super::rule::{closed, Checker, Key};
use super::ConfigError;

pub mod raw {
    use serde::Deserialize;

    /// `[contact]` of a pipeline file, and of a scene file (same keys, same checks).
    #[derive(Debug, Default, Clone, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Contact {
        pub youngs_modulus_pa: Option<f64>,
        pub poisson: Option<f64>,
        pub wheel_lateral_radius_m: Option<f64>,
        pub rail_lateral_radius_m: Option<f64>,
    }
}

/// Contact material and profile radii.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactConfig {
    /// Young's modulus E, Pa.
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio ν.
    pub poisson: f64,
    /// Lateral profile radius of the wheel, m (negative: concave).
    pub wheel_lateral_radius_m: f64,
    /// Lateral profile radius of the rail head, m.
    pub rail_lateral_radius_m: f64,
}

const YOUNG: Key = Key::num(
    "contact.youngs_modulus_pa",
    "Pa",
    closed(1e9, 1e12),
    2.1e11,
    "Young's modulus of wheel and rail steel",
);
const POISSON: Key = Key::num(
    "contact.poisson",
    "",
    closed(0.0, 0.49),
    0.3,
    "Poisson's ratio of the steel",
);
const WHEEL_RADIUS: Key = Key::num(
    "contact.wheel_lateral_radius_m",
    "m",
    closed(-1e3, 1e3),
    -0.5,
    "lateral profile radius of the wheel (negative: concave) [assumed]",
);
const RAIL_RADIUS: Key = Key::num(
    "contact.rail_lateral_radius_m",
    "m",
    closed(0.05, 1e3),
    0.3,
    "lateral profile radius of the rail head [assumed]",
);

/// The keys of `[contact]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[&YOUNG, &POISSON, &WHEEL_RADIUS, &RAIL_RADIUS];

impl Checker<'_> {
    pub(crate) fn contact(&self, c: raw::Contact) -> Result<ContactConfig, ConfigError> {
        Ok(ContactConfig {
            youngs_modulus_pa: self.value(&YOUNG, c.youngs_modulus_pa)?,
            poisson: self.value(&POISSON, c.poisson)?,
            wheel_lateral_radius_m: self.value(&WHEEL_RADIUS, c.wheel_lateral_radius_m)?,
            rail_lateral_radius_m: self.value(&RAIL_RADIUS, c.rail_lateral_radius_m)?,
        })
    }
}
