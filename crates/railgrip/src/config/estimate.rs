//! `[estimate]`: per-sample adhesion estimation and its validity mask (seed 002 eq. 2–14).

use super::rule::{closed, open_lo, Checker, Default, Key, Range};
use super::ConfigError;

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Estimate {
        pub phase: Option<String>,
        pub min_speed_mps: Option<f64>,
        pub min_pressure_bar: Option<f64>,
        pub locked_wheel_speed_mps: Option<f64>,
        pub sliding_threshold_mps: Option<f64>,
        pub calibration: Option<String>,
    }
}

/// Where the brake coefficients and the radar's corrections come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalibrationSource {
    /// [`CalibrationSource::Campaign`] where a campaign of at least
    /// [`crate::estimate::selfcal::MIN_RUNS`] runs with samples for the balance is estimated
    /// together; [`CalibrationSource::Pipeline`], with a note, where there are fewer (a run
    /// estimated alone, a small campaign): a run cannot calibrate itself (docs/calibration.md).
    Auto,
    /// `[vehicle]`'s α as given, the radar trusted.
    Pipeline,
    /// Fitted from the campaign's own runs (per-axle α, pad friction's speed law, radar scale
    /// and latency, tachometers' delay), then every run estimated with them.
    Campaign,
    /// One α for all axles from the full-adhesion samples of the campaign's runs (seed 002,
    /// after eq. 10), the radar trusted.
    DryRun,
}

impl CalibrationSource {
    pub fn name(self) -> &'static str {
        match self {
            CalibrationSource::Auto => "auto",
            CalibrationSource::Pipeline => "pipeline",
            CalibrationSource::Campaign => "campaign",
            CalibrationSource::DryRun => "dry-run",
        }
    }

    /// The calibration a campaign fits under this source (what a given calibration's
    /// `source` must be): "campaign" for "auto" and "campaign", "dry-run", none for "pipeline".
    pub fn fitted(self) -> Option<CalibrationSource> {
        match self {
            CalibrationSource::Auto | CalibrationSource::Campaign => {
                Some(CalibrationSource::Campaign)
            }
            CalibrationSource::DryRun => Some(CalibrationSource::DryRun),
            CalibrationSource::Pipeline => None,
        }
    }
}

/// Which slip definition applies (seed 002 eq. 2–5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Δv = v − rω (eq. 2), slip ratio Δv / v (eq. 4).
    Braking,
    /// Δv = rω − v (eq. 3), slip ratio Δv / (rω) (eq. 5).
    Traction,
}

/// Estimation settings.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateConfig {
    pub phase: Phase,
    /// Samples with a filtered vehicle speed below this are masked (slip ratio and the
    /// torque balance lose meaning towards standstill), m/s.
    pub min_speed_mps: f64,
    /// Samples whose filtered cylinder pressure is below this are masked (brake not applied), bar.
    pub min_pressure_bar: f64,
    /// A wheel whose peripheral speed rω is below this is locked: its brake torque is static
    /// friction, not αp, so the torque balance does not hold and the sample is masked, m/s.
    pub locked_wheel_speed_mps: f64,
    /// Slip velocity above which an axle counts as sliding in summaries, m/s.
    pub sliding_threshold_mps: f64,
    pub calibration: CalibrationSource,
}

const PHASE: Key = Key {
    name: "estimate.phase",
    unit: "",
    range: Range::Choice(&["braking", "traction"]),
    default: Default::Text("\"braking\""),
    meaning: "slip definitions of seed 002 eq. 2/4 or 3/5 (the contract logs no motor torque, so T_i is from eq. 9 either way)",
};
const MIN_SPEED: Key = Key::num(
    "estimate.min_speed_mps",
    "m/s",
    open_lo(0.0, 100.0),
    1.0,
    "slower samples are masked",
);
const MIN_PRESSURE: Key = Key::num(
    "estimate.min_pressure_bar",
    "bar",
    closed(0.0, 20.0),
    0.2,
    "samples with less cylinder pressure are masked (brake not applied)",
);
const LOCKED: Key = Key::num(
    "estimate.locked_wheel_speed_mps",
    "m/s",
    open_lo(0.0, 10.0),
    0.1,
    "rω below this: wheel locked, masked",
);
const SLIDING: Key = Key::num(
    "estimate.sliding_threshold_mps",
    "m/s",
    open_lo(0.0, 10.0),
    0.2,
    "Δv above this counts as sliding in summaries",
);

const CALIBRATION: Key = Key {
    name: "estimate.calibration",
    unit: "",
    range: Range::Choice(&["auto", "pipeline", "campaign", "dry-run"]),
    default: Default::Text("\"auto\""),
    meaning: "\"campaign\" where 3 or more runs are estimated together, else \"pipeline\" with a note (a run cannot calibrate itself); α and the radar as `[vehicle]` gives them; fitted from the campaign's own runs (per-axle α, pad friction, radar scale and latency, tachometer delay; docs/calibration.md); or one α from the runs' full-adhesion samples",
};

/// The keys of `[estimate]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
    &PHASE,
    &MIN_SPEED,
    &MIN_PRESSURE,
    &LOCKED,
    &SLIDING,
    &CALIBRATION,
];

impl Checker<'_> {
    pub(crate) fn estimate(&self, e: raw::Estimate) -> Result<EstimateConfig, ConfigError> {
        Ok(EstimateConfig {
            phase: self.choice(
                &PHASE,
                e.phase,
                &[("braking", Phase::Braking), ("traction", Phase::Traction)],
                Phase::Braking,
            )?,
            min_speed_mps: self.value(&MIN_SPEED, e.min_speed_mps)?,
            min_pressure_bar: self.value(&MIN_PRESSURE, e.min_pressure_bar)?,
            locked_wheel_speed_mps: self.value(&LOCKED, e.locked_wheel_speed_mps)?,
            sliding_threshold_mps: self.value(&SLIDING, e.sliding_threshold_mps)?,
            calibration: self.choice(
                &CALIBRATION,
                e.calibration,
                &[
                    ("auto", CalibrationSource::Auto),
                    ("pipeline", CalibrationSource::Pipeline),
                    ("campaign", CalibrationSource::Campaign),
                    ("dry-run", CalibrationSource::DryRun),
                ],
                CalibrationSource::Auto,
            )?,
        })
    }
}
