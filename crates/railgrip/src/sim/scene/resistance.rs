//! `[resistance]`: Davis running resistance a + b v + c v².

use crate::config::rule::{closed, Checker, Key};
use crate::config::ConfigError;

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Resistance {
        pub davis_a_n: Option<f64>,
        pub davis_b_n_per_mps: Option<f64>,
        pub davis_c_n_per_mps2: Option<f64>,
    }
}

/// `[resistance]`: Davis running resistance a + b v + c v².
#[derive(Debug, Clone, PartialEq)]
pub struct ResistanceSection {
    pub davis_a_n: f64,
    pub davis_b_n_per_mps: f64,
    pub davis_c_n_per_mps2: f64,
}

pub(super) const DAVIS_A: Key = Key::num(
    "resistance.davis_a_n",
    "N",
    closed(0.0, 1e5),
    1200.0,
    "`running_resistance`: a",
);
pub(super) const DAVIS_B: Key = Key::num(
    "resistance.davis_b_n_per_mps",
    "N/(m/s)",
    closed(0.0, 1e4),
    30.0,
    "b",
);
pub(super) const DAVIS_C: Key = Key::num(
    "resistance.davis_c_n_per_mps2",
    "N/(m/s)²",
    closed(0.0, 1e3),
    6.0,
    "c",
);

/// The keys of `[resistance]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[&DAVIS_A, &DAVIS_B, &DAVIS_C];

impl Checker<'_> {
    /// `[resistance]` checked.
    pub(crate) fn resistance(&self, r: &raw::Resistance) -> Result<ResistanceSection, ConfigError> {
        Ok(ResistanceSection {
            davis_a_n: self.value(&DAVIS_A, r.davis_a_n)?,
            davis_b_n_per_mps: self.value(&DAVIS_B, r.davis_b_n_per_mps)?,
            davis_c_n_per_mps2: self.value(&DAVIS_C, r.davis_c_n_per_mps2)?,
        })
    }
}
