//! `[vehicle]`: masses, inertia and the geometry of the load-transfer model of seed 002
//! eq. 12–13 (002_8d8769283f5e9cb6.txt, Fig. 6). No key has a silent default in a user's file:
//! a missing key quotes the UIC-Z1 value of the embedded pipeline.

use super::rule::{closed, g, open_lo, Checker, Default, Key, Range};
use super::ConfigError;
use crate::format::AXLES;

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Vehicle {
        pub name: Option<String>,
        pub body_mass_kg: Option<f64>,
        pub bogie_mass_kg: Option<f64>,
        pub axle_inertia_kgm2: Option<f64>,
        pub wheel_radius_m: Option<f64>,
        pub bogie_pivot_distance_m: Option<f64>,
        pub bogie_wheelbase_m: Option<f64>,
        pub body_cog_height_m: Option<f64>,
        pub pivot_height_m: Option<f64>,
        pub bogie_cog_height_m: Option<f64>,
        pub brake_torque_nm_per_bar: Option<Vec<f64>>,
        pub max_brake_pressure_bar: Option<f64>,
        pub pivot_force_load_transfer: Option<bool>,
    }
}

/// The vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct Vehicle {
    pub name: String,
    /// Car-body mass m_c, kg.
    pub body_mass_kg: f64,
    /// Mass of one bogie including its wheelsets m_b, kg.
    pub bogie_mass_kg: f64,
    /// Moment of inertia J of one wheelset about its axle, kg·m².
    pub axle_inertia_kgm2: f64,
    /// Wheel rolling radius r, m.
    pub wheel_radius_m: f64,
    /// Distance between bogie pivots l1, m.
    pub bogie_pivot_distance_m: f64,
    /// Bogie wheelbase l2, m.
    pub bogie_wheelbase_m: f64,
    /// Height of the car body's centre of gravity h1 above the rail, m.
    pub body_cog_height_m: f64,
    /// Height hb of the body–bogie connection above the rail, m.
    pub pivot_height_m: f64,
    /// Height of the bogie's centre of gravity h2 above the rail, m.
    pub bogie_cog_height_m: f64,
    /// Brake-torque coefficient α_i of seed 002 eq. 10 per axle, N·m/bar.
    pub brake_torque_nm_per_bar: [f64; AXLES],
    /// Highest brake-cylinder pressure the brake can apply, bar.
    pub max_brake_pressure_bar: f64,
    /// Include the pivot force's share of the load transfer ([`crate::vehicle::axle_loads`]).
    pub pivot_force_load_transfer: bool,
}

const fn required(
    name: &'static str,
    unit: &'static str,
    range: Range,
    uic_z1: f64,
    meaning: &'static str,
) -> Key {
    Key {
        name,
        unit,
        range,
        default: Default::Required(uic_z1),
        meaning,
    }
}

const NAME: Key = Key {
    name: "vehicle.name",
    unit: "",
    range: Range::Text("text"),
    default: Default::Text("`\"unnamed vehicle\"`"),
    meaning: "vehicle name for reports",
};
const BODY_MASS: Key = required(
    "vehicle.body_mass_kg",
    "kg",
    open_lo(1000.0, 200_000.0),
    34000.0,
    "car body m_c (seed 002 eq. 12) [assumed]",
);
const BOGIE_MASS: Key = required(
    "vehicle.bogie_mass_kg",
    "kg",
    open_lo(100.0, 50_000.0),
    7000.0,
    "one bogie incl. wheelsets m_b (eq. 13) [assumed]",
);
const INERTIA: Key = required(
    "vehicle.axle_inertia_kgm2",
    "kg·m²",
    open_lo(1.0, 2000.0),
    120.0,
    "wheelset inertia J (eq. 9) [assumed]",
);
const RADIUS: Key = required(
    "vehicle.wheel_radius_m",
    "m",
    closed(0.2, 0.7),
    0.445,
    "rolling radius r [assumed]",
);
const PIVOTS: Key = required(
    "vehicle.bogie_pivot_distance_m",
    "m",
    closed(1.0, 40.0),
    19.0,
    "l1 (eq. 12) [pub]",
);
const WHEELBASE: Key = required(
    "vehicle.bogie_wheelbase_m",
    "m",
    closed(0.5, 5.0),
    2.56,
    "l2 (eq. 13), shorter than l1 [pub]",
);
const BODY_COG: Key = required(
    "vehicle.body_cog_height_m",
    "m",
    open_lo(0.0, 5.0),
    1.75,
    "h1 [assumed]",
);
const PIVOT_HEIGHT: Key = required(
    "vehicle.pivot_height_m",
    "m",
    open_lo(0.0, 5.0),
    0.85,
    "hb, not above h1 [assumed]",
);
const BOGIE_COG: Key = required(
    "vehicle.bogie_cog_height_m",
    "m",
    open_lo(0.0, 5.0),
    0.55,
    "h2 [assumed]",
);
const ALPHA: Key = Key {
    name: "vehicle.brake_torque_nm_per_bar",
    unit: "N·m/bar",
    range: open_lo(0.0, 100_000.0),
    default: Default::Text("required (UIC-Z1: [1600, 1600, 1600, 1600])"),
    meaning:
        "α_i of C_f,i = α_i p_i (eq. 10), four values (axles 1..4), each in the range [assumed]",
};
const MAX_PRESSURE: Key = required(
    "vehicle.max_brake_pressure_bar",
    "bar",
    open_lo(0.0, 20.0),
    3.8,
    "highest cylinder pressure [assumed]",
);

const PIVOT_FORCE: Key = Key {
    name: "vehicle.pivot_force_load_transfer",
    unit: "",
    range: Range::Text("true, false"),
    default: Default::Text("false"),
    meaning: "add the pivot force's share of the load transfer within each bogie, (m_c/2) h_b d / l2, which eq. 12–13 leave out (true for bogies that take the body's braking force at the pivot height)",
};

/// The keys of `[vehicle]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
    &NAME,
    &BODY_MASS,
    &BOGIE_MASS,
    &INERTIA,
    &RADIUS,
    &PIVOTS,
    &WHEELBASE,
    &BODY_COG,
    &PIVOT_HEIGHT,
    &BOGIE_COG,
    &ALPHA,
    &MAX_PRESSURE,
    &PIVOT_FORCE,
];

impl Checker<'_> {
    pub(crate) fn vehicle(&self, v: Option<raw::Vehicle>) -> Result<Vehicle, ConfigError> {
        let v = v.ok_or_else(|| {
            self.missing(
                "[vehicle]",
                "every pipeline describes its vehicle; copy the [vehicle] section of pipelines/uic_z1.toml and edit it",
            )
        })?;
        // In the order of the documented table, so that the first missing key is the one named.
        let body_mass_kg = self.value(&BODY_MASS, v.body_mass_kg)?;
        let bogie_mass_kg = self.value(&BOGIE_MASS, v.bogie_mass_kg)?;
        let axle_inertia_kgm2 = self.value(&INERTIA, v.axle_inertia_kgm2)?;
        let wheel_radius_m = self.value(&RADIUS, v.wheel_radius_m)?;
        let l1 = self.value(&PIVOTS, v.bogie_pivot_distance_m)?;
        let l2 = self.value(&WHEELBASE, v.bogie_wheelbase_m)?;
        if l2 >= l1 {
            return Err(self.invalid(
                WHEELBASE.name,
                g(l2),
                format!("must be shorter than {} = {}", PIVOTS.name, g(l1)),
            ));
        }
        let h1 = self.value(&BODY_COG, v.body_cog_height_m)?;
        let hb = self.value(&PIVOT_HEIGHT, v.pivot_height_m)?;
        if hb > h1 {
            return Err(self.invalid(
                PIVOT_HEIGHT.name,
                g(hb),
                format!(
                    "must not be above the body's centre of gravity {} = {}",
                    BODY_COG.name,
                    g(h1)
                ),
            ));
        }
        Ok(Vehicle {
            name: v.name.unwrap_or_else(|| "unnamed vehicle".to_string()),
            body_mass_kg,
            bogie_mass_kg,
            axle_inertia_kgm2,
            wheel_radius_m,
            bogie_pivot_distance_m: l1,
            bogie_wheelbase_m: l2,
            body_cog_height_m: h1,
            pivot_height_m: hb,
            bogie_cog_height_m: self.value(&BOGIE_COG, v.bogie_cog_height_m)?,
            brake_torque_nm_per_bar: self.alpha(v.brake_torque_nm_per_bar)?,
            max_brake_pressure_bar: self.value(&MAX_PRESSURE, v.max_brake_pressure_bar)?,
            pivot_force_load_transfer: v.pivot_force_load_transfer.unwrap_or(false),
        })
    }

    fn alpha(&self, a: Option<Vec<f64>>) -> Result<[f64; AXLES], ConfigError> {
        let a = a.ok_or_else(|| {
            self.missing(
                ALPHA.name,
                "give alpha_i of seed 002 eq. 10 for axles 1..4 in N·m/bar, e.g. [1600.0, 1600.0, 1600.0, 1600.0]",
            )
        })?;
        if a.len() != AXLES {
            return Err(self.invalid(
                ALPHA.name,
                format!("{a:?}"),
                "must list exactly 4 values, one per axle",
            ));
        }
        for (i, x) in a.iter().enumerate() {
            if !ALPHA.contains(*x) {
                return Err(self.invalid(
                    &format!("{}[{i}] (axle {})", ALPHA.name, i + 1),
                    g(*x),
                    ALPHA.rule_text(),
                ));
            }
        }
        Ok([a[0], a[1], a[2], a[3]])
    }
}
