//! `[run]`: the braking run — speeds, duration, step, output rate, ambient temperature.

use super::text;
use crate::config::rule::{closed, Checker, Key};
use crate::config::ConfigError;

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Run {
        pub initial_speed_kmh: Option<f64>,
        pub stop_speed_kmh: Option<f64>,
        pub max_duration_s: Option<f64>,
        pub step_ms: Option<f64>,
        pub output_rate_hz: Option<f64>,
        pub ambient_temperature_c: Option<f64>,
        pub gradient_permille: Option<f64>,
        pub load_fluctuation_rms: Option<f64>,
        pub load_fluctuation_band_hz: Option<[f64; 2]>,
        pub condition: Option<String>,
        pub direction: Option<String>,
    }
}

/// `[run]`: the braking run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSection {
    /// Initial speed as written in the scene, km/h (reported in the run metadata).
    pub initial_speed_kmh: f64,
    /// Initial speed, m/s.
    pub initial_speed_mps: f64,
    /// The run ends when the vehicle is slower than this, m/s.
    pub stop_speed_mps: f64,
    pub max_duration_s: f64,
    /// Integration step, s.
    pub step_s: f64,
    /// Rate of the CSV output and the truth table, Hz.
    pub output_rate_hz: f64,
    pub ambient_temperature_c: f64,
    /// Track gradient, ‰ (positive uphill).
    pub gradient_permille: f64,
    /// `load_fluctuation`: relative rms of each wheel load's fluctuation, and its band (Hz).
    pub load_fluctuation_rms: f64,
    pub load_fluctuation_band_hz: [f64; 2],
    pub condition: String,
    pub direction: String,
}

pub(super) const INITIAL_SPEED: Key = Key::num(
    "run.initial_speed_kmh",
    "km/h",
    closed(1.0, 400.0),
    120.0,
    "start of the braking",
);
pub(super) const STOP_SPEED: Key = Key::num(
    "run.stop_speed_kmh",
    "km/h",
    closed(0.5, 400.0),
    3.0,
    "end of the braking, below the initial speed",
);
pub(super) const MAX_DURATION: Key = Key::num(
    "run.max_duration_s",
    "s",
    closed(0.1, 36_000.0),
    300.0,
    "longest simulated time",
);
pub(super) const STEP: Key = Key::num(
    "run.step_ms",
    "ms",
    closed(0.01, 1.0),
    0.1,
    "integration step, at most half the output period",
);
pub(super) const OUTPUT_RATE: Key = Key::num(
    "run.output_rate_hz",
    "Hz",
    closed(10.0, 10_000.0),
    417.0,
    "CSV and truth rate",
);
pub(super) const AMBIENT: Key = Key::num(
    "run.ambient_temperature_c",
    "°C",
    closed(-60.0, 60.0),
    20.0,
    "for `temperature` and the metadata",
);
pub(super) const GRADIENT: Key = Key::num(
    "run.gradient_permille",
    "‰",
    closed(-60.0, 60.0),
    0.0,
    "for `gradient` (positive uphill)",
);
pub(super) const LOAD_FLUCT: Key = Key::num(
    "run.load_fluctuation_rms",
    "–",
    closed(0.0, 0.2),
    0.015,
    "`load_fluctuation`: relative rms of each axle's load fluctuation (track irregularity, suspension)",
);
pub(super) const LOAD_BAND: Key = text(
    "run.load_fluctuation_band_hz",
    "[Hz, Hz]",
    "0.1 ≤ low < high ≤ 100",
    "[2, 10]",
    "`load_fluctuation`: its band (4th-order Butterworth high-pass at low, low-pass at high)",
);
pub(super) const CONDITION: Key = text("run.condition", "", "text", "\"soap\"", "metadata");
pub(super) const DIRECTION: Key = text("run.direction", "", "text", "\"forward\"", "metadata");

/// The keys of `[run]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
    &INITIAL_SPEED,
    &STOP_SPEED,
    &MAX_DURATION,
    &STEP,
    &OUTPUT_RATE,
    &AMBIENT,
    &GRADIENT,
    &LOAD_FLUCT,
    &LOAD_BAND,
    &CONDITION,
    &DIRECTION,
];

impl Checker<'_> {
    /// `[run]` checked.
    pub(crate) fn run(&self, r: &raw::Run) -> Result<RunSection, ConfigError> {
        let initial_kmh = self.value(&INITIAL_SPEED, r.initial_speed_kmh)?;
        let stop_kmh = self.value(&STOP_SPEED, r.stop_speed_kmh)?;
        if stop_kmh >= initial_kmh {
            return Err(self.invalid(
                STOP_SPEED.name,
                stop_kmh,
                format!("must be below {} = {initial_kmh}", INITIAL_SPEED.name),
            ));
        }
        let step_ms = self.value(&STEP, r.step_ms)?;
        let output_rate_hz = self.value(&OUTPUT_RATE, r.output_rate_hz)?;
        if step_ms * 1e-3 > 0.5 / output_rate_hz {
            return Err(self.invalid(STEP.name, step_ms, "must be at most half the output period"));
        }
        Ok(RunSection {
            initial_speed_kmh: initial_kmh,
            initial_speed_mps: initial_kmh / 3.6,
            stop_speed_mps: stop_kmh / 3.6,
            max_duration_s: self.value(&MAX_DURATION, r.max_duration_s)?,
            step_s: step_ms * 1e-3,
            output_rate_hz,
            ambient_temperature_c: self.value(&AMBIENT, r.ambient_temperature_c)?,
            gradient_permille: self.value(&GRADIENT, r.gradient_permille)?,
            load_fluctuation_rms: self.value(&LOAD_FLUCT, r.load_fluctuation_rms)?,
            load_fluctuation_band_hz: match r.load_fluctuation_band_hz {
                None => [2.0, 10.0],
                Some([lo, hi]) if lo >= 0.1 && lo < hi && hi <= 100.0 => [lo, hi],
                Some(b) => {
                    return Err(self.invalid(
                        LOAD_BAND.name,
                        format!("{b:?}"),
                        "must be [low, high] with 0.1 <= low < high <= 100 Hz (below 0.1 Hz the filter takes minutes of steps to settle: its start-up grows as 1/low)",
                    ))
                }
            },
            condition: r.condition.clone().unwrap_or_else(|| "soap".into()),
            direction: r.direction.clone().unwrap_or_else(|| "forward".into()),
        })
    }
}
