//! `[wsp]`: wheel-slide protection thresholds.

use crate::config::rule::{closed, Checker, Key};
use crate::config::ConfigError;

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Wsp {
        pub dump_slip_mps: Option<f64>,
        pub reapply_slip_mps: Option<f64>,
        pub decel_limit_mps2: Option<f64>,
        pub reaction_delay_ms: Option<f64>,
        pub dump_slip_ratio: Option<f64>,
        pub hold_max_s: Option<f64>,
    }
}

/// `[wsp]`: wheel-slide protection thresholds (railgrip's [assumed] values; `sim::wsp`).
#[derive(Debug, Clone, PartialEq)]
pub struct WspSection {
    pub dump_slip_mps: f64,
    pub reapply_slip_mps: f64,
    pub decel_limit_mps2: f64,
    /// Relative dump threshold: the WSP dumps above max(dump_slip_mps, ratio·v).
    pub dump_slip_ratio: f64,
    /// Time from detecting a slide to venting the cylinder, s.
    pub reaction_delay_s: f64,
    /// Longest hold before re-applying, s.
    pub hold_max_s: f64,
}

pub(super) const DUMP_SLIP: Key = Key::num(
    "wsp.dump_slip_mps",
    "m/s",
    closed(0.05, 20.0),
    1.0,
    "dump above this slip [assumed]",
);
pub(super) const DUMP_RATIO: Key = Key::num(
    "wsp.dump_slip_ratio",
    "",
    closed(0.0, 1.0),
    0.1,
    "… or above this fraction of v [assumed]",
);
pub(super) const REAPPLY: Key = Key::num(
    "wsp.reapply_slip_mps",
    "m/s",
    closed(0.01, 10.0),
    0.3,
    "re-apply below this slip, below the dump slip [assumed]",
);
pub(super) const DECEL_LIMIT: Key = Key::num(
    "wsp.decel_limit_mps2",
    "m/s²",
    closed(0.1, 100.0),
    4.0,
    "detect when the wheel decelerates this much faster than the vehicle [assumed]",
);
pub(super) const DELAY: Key = Key::num(
    "wsp.reaction_delay_ms",
    "ms",
    closed(0.0, 1000.0),
    80.0,
    "from detection to venting [assumed]",
);
pub(super) const HOLD_MAX: Key = Key::num(
    "wsp.hold_max_s",
    "s",
    closed(0.01, 10.0),
    0.4,
    "longest hold before re-applying [assumed]",
);

/// The keys of `[wsp]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
    &DUMP_SLIP,
    &DUMP_RATIO,
    &REAPPLY,
    &DECEL_LIMIT,
    &DELAY,
    &HOLD_MAX,
];

impl Checker<'_> {
    /// `[wsp]` checked.
    pub(crate) fn wsp(&self, w: &raw::Wsp) -> Result<WspSection, ConfigError> {
        let reapply = self.value(&REAPPLY, w.reapply_slip_mps)?;
        let dump = self.value(&DUMP_SLIP, w.dump_slip_mps)?;
        if reapply >= dump {
            return Err(self.invalid(
                REAPPLY.name,
                reapply,
                format!("must be below {} = {dump}", DUMP_SLIP.name),
            ));
        }
        Ok(WspSection {
            dump_slip_mps: dump,
            reapply_slip_mps: reapply,
            decel_limit_mps2: self.value(&DECEL_LIMIT, w.decel_limit_mps2)?,
            dump_slip_ratio: self.value(&DUMP_RATIO, w.dump_slip_ratio)?,
            reaction_delay_s: self.value(&DELAY, w.reaction_delay_ms)? * 1e-3,
            hold_max_s: self.value(&HOLD_MAX, w.hold_max_s)?,
        })
    }
}
