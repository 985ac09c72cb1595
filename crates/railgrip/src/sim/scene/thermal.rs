//! The `thermal` effect's `[adhesion]` keys: tread heating, flash temperature and the friction
//! it lowers (every value [assumed]).

use super::adhesion::raw;
use crate::config::rule::{closed, open_lo, Checker, Key};
use crate::config::ConfigError;

/// The `thermal` effect's parameters (every one [assumed]; docs/simulator.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalParams {
    /// Share δ of the slip power that heats the wheel (the rest goes into the rail).
    pub partition: f64,
    /// Heat capacity of an axle's heated tread layer (both wheels), J/K.
    pub tread_capacity_j_per_k: f64,
    /// Heat loss of the tread to the air and the wheel body, W/K.
    pub cooling_w_per_k: f64,
    /// Contact temperature below which friction does not change, °C.
    pub reference_c: f64,
    /// Temperature scale of the friction loss above it, K.
    pub scale_k: f64,
    /// Friction left at very high temperature, as a fraction.
    pub residual: f64,
    /// γ of the pressure factor (σ/σ0)^(−γ).
    pub pressure_exponent: f64,
    /// Interval at which temperatures and the friction factor are brought up to date from the
    /// slip power summed since the last update, ms (a whole number of steps, at least one).
    pub update_ms: f64,
}

pub(super) const THERMAL_PARTITION: Key = Key::num(
    "adhesion.thermal_partition",
    "",
    open_lo(0.0, 1.0),
    0.5,
    "`thermal`: share of the slip power heating the wheel tread and the flash [assumed]",
);
pub(super) const THERMAL_CAPACITY: Key = Key::num(
    "adhesion.thermal_tread_capacity_j_per_k",
    "J/K",
    closed(100.0, 1e7),
    2.3e4,
    "`thermal`: heat capacity of an axle's heated tread layer (two 1 cm × 0.1 m rims of steel) [assumed]",
);
pub(super) const THERMAL_COOLING: Key = Key::num(
    "adhesion.thermal_cooling_w_per_k",
    "W/K",
    closed(0.0, 1e5),
    50.0,
    "`thermal`: the tread's heat loss to air and wheel body [assumed]",
);
pub(super) const THERMAL_REFERENCE: Key = Key::num(
    "adhesion.thermal_reference_c",
    "°C",
    closed(-50.0, 1000.0),
    100.0,
    "`thermal`: contact temperature up to which friction is unchanged [assumed]",
);
pub(super) const THERMAL_SCALE: Key = Key::num(
    "adhesion.thermal_scale_k",
    "K",
    closed(1.0, 5000.0),
    300.0,
    "`thermal`: friction × [r + (1 − r) e^(−(θ − θ_ref)/scale)] above θ_ref [assumed]",
);
pub(super) const THERMAL_RESIDUAL: Key = Key::num(
    "adhesion.thermal_residual",
    "",
    closed(0.05, 1.0),
    0.5,
    "`thermal`: r, the friction left at very high contact temperature [assumed]",
);
pub(super) const THERMAL_PRESSURE: Key = Key::num(
    "adhesion.thermal_pressure_exponent",
    "",
    closed(0.0, 1.0),
    0.1,
    "`thermal`: friction × (p_max/p_max,static)^(−γ) [assumed]",
);
pub(super) const THERMAL_UPDATE: Key = Key::num(
    "adhesion.thermal_update_ms",
    "ms",
    closed(0.001, 10.0),
    0.5,
    "`thermal`: temperatures and friction factor brought up to date at this interval (rounded to whole steps, at least one) from the slip power summed every step; docs/benchmarks.md gives its cost and error",
);

impl Checker<'_> {
    /// The `thermal` effect's keys of `[adhesion]`, checked.
    pub(super) fn thermal(&self, a: &raw::Adhesion) -> Result<ThermalParams, ConfigError> {
        Ok(ThermalParams {
            partition: self.value(&THERMAL_PARTITION, a.thermal_partition)?,
            tread_capacity_j_per_k: self
                .value(&THERMAL_CAPACITY, a.thermal_tread_capacity_j_per_k)?,
            cooling_w_per_k: self.value(&THERMAL_COOLING, a.thermal_cooling_w_per_k)?,
            reference_c: self.value(&THERMAL_REFERENCE, a.thermal_reference_c)?,
            scale_k: self.value(&THERMAL_SCALE, a.thermal_scale_k)?,
            residual: self.value(&THERMAL_RESIDUAL, a.thermal_residual)?,
            pressure_exponent: self.value(&THERMAL_PRESSURE, a.thermal_pressure_exponent)?,
            update_ms: self.value(&THERMAL_UPDATE, a.thermal_update_ms)?,
        })
    }
}
