//! The `[adhesion]` keys and checks of the laws besides Polach's: `loss_recovery` and `table`
//! (outside the families railgrip fits) and `fastsim`.

use super::adhesion::raw;
use super::adhesion::{HYSTERESIS_DDV, REFERENCE_SPEED};
use super::text;
use crate::config::rule::{closed, Checker, Default, Key, Range};
use crate::config::ConfigError;

/// `law = "fastsim"`: the grid, the bound and the optional stiffness reduction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FastsimLaw {
    /// Cells per side (nx = ny).
    pub grid: usize,
    pub bound: crate::contact::fastsim::Bound,
    pub reduction: Option<crate::contact::fastsim::Reduction>,
}

pub(super) const LOSS_PEAK: Key = Key::num(
    "adhesion.loss_peak_mu",
    "",
    closed(0.005, 1.5),
    0.1,
    "`loss_recovery`: peak μ of the loss branch (growing slip) at v_ref [assumed]",
);
pub(super) const LOSS_SLIP: Key = Key::num(
    "adhesion.loss_peak_slip_mps",
    "m/s",
    closed(0.01, 20.0),
    0.8,
    "… the slip at that peak [assumed]",
);
pub(super) const LOSS_RESIDUAL: Key = Key::num(
    "adhesion.loss_residual",
    "",
    closed(0.05, 0.95),
    0.55,
    "… μ at large slip as a fraction of the peak [assumed]",
);
pub(super) const RECOVERY_PEAK: Key = Key::num(
    "adhesion.recovery_peak_mu",
    "",
    closed(0.005, 1.5),
    0.065,
    "`loss_recovery`: peak μ of the recovery branch (falling slip) at v_ref [assumed]",
);
pub(super) const RECOVERY_SLIP: Key = Key::num(
    "adhesion.recovery_peak_slip_mps",
    "m/s",
    closed(0.01, 20.0),
    1.6,
    "… the slip at that peak [assumed]",
);
pub(super) const RECOVERY_RESIDUAL: Key = Key::num(
    "adhesion.recovery_residual",
    "",
    closed(0.05, 0.95),
    0.8,
    "… μ at large slip as a fraction of the peak [assumed]",
);
pub(super) const PEAK_SPEED: Key = Key::num(
    "adhesion.peak_speed_coefficient",
    "",
    closed(-0.9, 0.9),
    0.3,
    "`loss_recovery`: peaks × (1 + κ (v_ref − v)/(v_ref + v)) [assumed]",
);
pub(super) const PEAK_SPEED_FORM: Key = Key {
    name: "adhesion.peak_speed_form",
    unit: "",
    range: Range::Choice(&["ratio", "quadratic"]),
    default: Default::Text("\"ratio\""),
    meaning: "`loss_recovery`: how the peaks fall with speed: `\"ratio\"` × (1 + κ (v_ref − v)/(v_ref + v)), flat at the top; `\"quadratic\"` × (1 + κ (1 − (v/v_ref)²)), steeper at the top (docs/simulator.md#foreign-laws) [assumed]",
};
pub(super) const LEVEL_SCALE: Key = Key::num(
    "adhesion.level_scale",
    "",
    closed(0.2, 5.0),
    1.0,
    "`loss_recovery`: both peaks × this — the run's rail condition (run-to-run spread) [assumed]",
);
pub(super) const PEAK_TEMPERATURE: Key = Key::num(
    "adhesion.peak_temperature_coefficient_per_k",
    "1/K",
    closed(-0.02, 0.02),
    0.006,
    "`loss_recovery` with `temperature`: peaks × (1 + τ (20 °C − T)) [assumed]",
);

pub(super) const TABLE_SPEEDS: Key = text(
    "adhesion.table_speeds_kmh",
    "km/h",
    "strictly increasing speeds",
    "[80, 140, 200]",
    "`table`: the speed nodes (μ held beyond the first and last) [assumed]",
);
pub(super) const TABLE_SLIPS: Key = text(
    "adhesion.table_slips_mps",
    "m/s",
    "0, then strictly increasing",
    "[0, 0.15, 0.4, 0.6, 0.8, 1.2, 2.5, 20]",
    "`table`: the slip nodes (μ held beyond the last) [assumed]",
);
pub(super) const TABLE_MU: Key = text(
    "adhesion.table_mu",
    "",
    "one row per speed, one μ in [0, 1.5] per slip node, 0 at zero slip",
    "a peak of 0.105 / 0.090 / 0.074 at 0.6 m/s, a plateau from 2.5 m/s",
    "`table`: μ, linear between nodes [assumed]",
);

pub(super) const FASTSIM_GRID: Key = Key::num(
    "adhesion.fastsim_grid",
    "cells",
    closed(1.0, 1000.0),
    10.0,
    "`fastsim`: cells per side of the grid (cost grows with its square)",
);
pub(super) const FASTSIM_BOUND: Key = Key {
    name: "adhesion.fastsim_bound",
    unit: "",
    range: Range::Choice(&["elliptic", "parabolic"]),
    default: Default::Text("\"elliptic\""),
    meaning: "`fastsim`: the traction bound's pressure (Hertz or Kalker's parabolic)",
};
pub(super) const FASTSIM_K0: Key = text(
    "adhesion.fastsim_k0",
    "",
    "(0, 1]",
    "– (plain FASTSIM)",
    "`fastsim`: the modified FASTSIM's k0 (Spiryagin et al. 2013); with alpha_inf and beta",
);
pub(super) const FASTSIM_ALPHA_INF: Key = text(
    "adhesion.fastsim_alpha_inf",
    "",
    "(0, 1]",
    "1",
    "… α∞: the stiffness left at large creepage, as a fraction of k0",
);
pub(super) const FASTSIM_BETA: Key = text(
    "adhesion.fastsim_beta",
    "",
    "≥ 0",
    "0",
    "… β: how fast the stiffness falls with Polach's ε",
);

/// `law = "fastsim"`'s grid, bound and optional reduction.
pub(super) fn fastsim_law(c: &Checker, a: &raw::Adhesion) -> Result<FastsimLaw, ConfigError> {
    use crate::contact::fastsim::{Bound, Reduction};
    let grid = c.value(&FASTSIM_GRID, a.fastsim_grid)?;
    if grid.fract() != 0.0 {
        return Err(c.invalid(FASTSIM_GRID.name, grid, "a whole number of cells"));
    }
    let bound = match a.fastsim_bound.as_deref() {
        None | Some("elliptic") => Bound::Elliptic,
        Some("parabolic") => Bound::Parabolic,
        Some(other) => {
            return Err(c.invalid(
                FASTSIM_BOUND.name,
                format!("{other:?}"),
                "must be \"elliptic\" or \"parabolic\"",
            ))
        }
    };
    let reduction = match (a.fastsim_k0, a.fastsim_alpha_inf, a.fastsim_beta) {
        (None, None, None) => None,
        (Some(k0), alpha, beta) => {
            let r = Reduction {
                k0,
                alpha_inf: alpha.unwrap_or(1.0),
                beta: beta.unwrap_or(0.0),
            };
            r.check()
                .map_err(|e| c.invalid("adhesion.fastsim_k0/alpha_inf/beta", "", e.to_string()))?;
            Some(r)
        }
        (None, _, _) => {
            return Err(c.invalid(
                FASTSIM_K0.name,
                "missing",
                "fastsim_alpha_inf and fastsim_beta need fastsim_k0 (the modified FASTSIM)",
            ))
        }
    };
    Ok(FastsimLaw {
        grid: grid as usize,
        bound,
        reduction,
    })
}

/// `law = "loss_recovery"`'s parameters (the blend's scale and the speed reference are the
/// hysteresis and speed keys).
pub(super) fn loss_recovery(
    c: &Checker,
    a: &raw::Adhesion,
) -> Result<crate::sim::foreign::LossRecovery, ConfigError> {
    use crate::sim::foreign::{Branch, LossRecovery, SpeedForm};
    let speed_form = match a.peak_speed_form.as_deref() {
        None | Some("ratio") => SpeedForm::Ratio,
        Some("quadratic") => SpeedForm::Quadratic,
        Some(other) => {
            return Err(c.invalid(
                PEAK_SPEED_FORM.name,
                format!("{other:?}"),
                "must be \"ratio\" or \"quadratic\"",
            ))
        }
    };
    Ok(LossRecovery {
        loss: Branch {
            peak_mu: c.value(&LOSS_PEAK, a.loss_peak_mu)?,
            peak_slip_mps: c.value(&LOSS_SLIP, a.loss_peak_slip_mps)?,
            residual: c.value(&LOSS_RESIDUAL, a.loss_residual)?,
        },
        recovery: Branch {
            peak_mu: c.value(&RECOVERY_PEAK, a.recovery_peak_mu)?,
            peak_slip_mps: c.value(&RECOVERY_SLIP, a.recovery_peak_slip_mps)?,
            residual: c.value(&RECOVERY_RESIDUAL, a.recovery_residual)?,
        },
        blend_ddv_mps2: c.value(&HYSTERESIS_DDV, a.hysteresis_ddv_mps2)?,
        speed_coefficient: c.value(&PEAK_SPEED, a.peak_speed_coefficient)?,
        speed_form,
        level_scale: c.value(&LEVEL_SCALE, a.level_scale)?,
        reference_speed_mps: c.value(&REFERENCE_SPEED, a.reference_speed_kmh)? / 3.6,
        temperature_coefficient_per_k: c
            .value(&PEAK_TEMPERATURE, a.peak_temperature_coefficient_per_k)?,
    })
}

/// `law = "table"`'s table (the built-in one where keys are left out).
pub(super) fn slip_table(
    c: &Checker,
    a: &raw::Adhesion,
) -> Result<crate::sim::foreign::SlipTable, ConfigError> {
    let d = crate::sim::foreign::SlipTable::default_table();
    let t = crate::sim::foreign::SlipTable {
        speeds_mps: match &a.table_speeds_kmh {
            Some(v) => v.iter().map(|x| x / 3.6).collect(),
            None => d.speeds_mps,
        },
        slips_mps: a.table_slips_mps.clone().unwrap_or(d.slips_mps),
        mu: a.table_mu.clone().unwrap_or(d.mu),
    };
    t.check()
        .map_err(|e| c.invalid("adhesion.table_*", "", e))?;
    Ok(t)
}
