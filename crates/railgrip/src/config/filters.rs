//! `[filters]`: signal conditioning before estimation (seed 002, "Data from test runs"):
//! 4th-order Butterworth low-passes and Hampel despiking of the radar.

use super::rule::{closed, g, open_lo, Checker, Default, Key, Range};
use super::ConfigError;

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Filters {
        pub mode: Option<String>,
        pub radar_cutoff_hz: Option<f64>,
        pub tacho_cutoff_hz: Option<f64>,
        pub pressure_cutoff_hz: Option<f64>,
        pub despike: Option<bool>,
        pub despike_half_window_s: Option<f64>,
        pub despike_threshold: Option<f64>,
        pub despike_min_deviation_mps: Option<f64>,
    }
}

/// How the low-pass filters run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FilterMode {
    /// Forward–backward (like scipy's `sosfiltfilt` / MATLAB's `filtfilt`): no phase shift,
    /// squared magnitude response. The default for offline analysis.
    ZeroPhase,
    /// One forward pass, as in the paper: delays each signal by the filter's group delay
    /// (0.277 s at 1.5 Hz, 0.104 s at 4 Hz), which shifts slip against pressure.
    Causal,
}

impl FilterMode {
    pub fn name(self) -> &'static str {
        match self {
            FilterMode::ZeroPhase => "zero_phase",
            FilterMode::Causal => "causal",
        }
    }
}

/// Conditioning settings.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterConfig {
    pub mode: FilterMode,
    /// Cut-off of the radar speed's 4th-order Butterworth low-pass, Hz.
    pub radar_cutoff_hz: f64,
    /// Cut-off for the tachometers (axle angular speeds), Hz.
    pub tacho_cutoff_hz: f64,
    /// Cut-off for the brake-cylinder pressures, Hz.
    pub pressure_cutoff_hz: f64,
    /// Hampel despiking of the radar speed before the low-pass (None: off).
    pub despike: Option<DespikeConfig>,
}

/// Hampel filter parameters (radar speed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DespikeConfig {
    /// Half-width of the centred window, s.
    pub half_window_s: f64,
    /// Threshold in robust standard deviations (1.4826 × median absolute deviation).
    pub threshold: f64,
    /// Deviations from the window median at or below this are never replaced, m/s.
    pub min_deviation_mps: f64,
}

const MODE: Key = Key {
    name: "filters.mode",
    unit: "",
    range: Range::Choice(&["zero_phase", "causal"]),
    default: Default::Text("\"zero_phase\""),
    meaning: "forward–backward (like filtfilt), or one pass as in seed 002",
};
const fn cutoff(name: &'static str, default: f64, meaning: &'static str) -> Key {
    Key {
        name,
        unit: "Hz",
        range: Range::Text("(0, fs/2)"),
        default: Default::Num(default),
        meaning,
    }
}
const RADAR: Key = cutoff("filters.radar_cutoff_hz", 1.5, "radar low-pass [pub]");
const TACHO: Key = cutoff("filters.tacho_cutoff_hz", 4.0, "tachometer low-pass [pub]");
const PRESSURE: Key = cutoff(
    "filters.pressure_cutoff_hz",
    4.0,
    "pressure low-pass; the tachometers' cut-off keeps T_i in phase [assumed]",
);
const DESPIKE: Key = Key {
    name: "filters.despike",
    unit: "",
    range: Range::Text("true, false"),
    default: Default::Text("true"),
    meaning: "Hampel filter on the radar before its low-pass",
};
const HALF_WINDOW: Key = Key::num(
    "filters.despike_half_window_s",
    "s",
    open_lo(0.0, 10.0),
    0.025,
    "half-width of the Hampel window, at least one sample",
);
const THRESHOLD: Key = Key::num(
    "filters.despike_threshold",
    "",
    open_lo(0.0, 100.0),
    3.0,
    "robust standard deviations (1.4826 × MAD)",
);
const MIN_DEVIATION: Key = Key::num(
    "filters.despike_min_deviation_mps",
    "m/s",
    closed(0.0, 100.0),
    0.5,
    "never replace a sample closer than this to the window median",
);

/// The keys of `[filters]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
    &MODE,
    &RADAR,
    &TACHO,
    &PRESSURE,
    &DESPIKE,
    &HALF_WINDOW,
    &THRESHOLD,
    &MIN_DEVIATION,
];

impl Checker<'_> {
    /// `[filters]` at sample rate `fs` (Hz): cut-offs below fs/2, a despiking window of at
    /// least one sample.
    pub(crate) fn filters(&self, f: raw::Filters, fs: f64) -> Result<FilterConfig, ConfigError> {
        let mode = self.choice(
            &MODE,
            f.mode,
            &[
                ("zero_phase", FilterMode::ZeroPhase),
                ("causal", FilterMode::Causal),
            ],
            FilterMode::ZeroPhase,
        )?;
        let cutoff = |k: &Key, v: Option<f64>| -> Result<f64, ConfigError> {
            let Default::Num(default) = k.default else {
                unreachable!("cut-offs have numeric defaults")
            };
            let rule = Key {
                range: Range::Num {
                    lo: 0.0,
                    lo_open: true,
                    hi: fs / 2.0,
                    hi_open: true,
                },
                ..*k
            };
            match v {
                None => Ok(default),
                Some(x) if rule.contains(x) => Ok(x),
                Some(x) => Err(self.invalid(
                    k.name,
                    g(x),
                    format!(
                        "{}; the upper bound is half of ingest.sample_rate_hz = {}",
                        rule.rule_text(),
                        g(fs)
                    ),
                )),
            }
        };
        let half_window_s = self.value(&HALF_WINDOW, f.despike_half_window_s)?;
        if half_window_s * fs < 1.0 {
            return Err(self.invalid(
                HALF_WINDOW.name,
                g(half_window_s),
                format!(
                    "must span at least one sample ({} s at ingest.sample_rate_hz = {})",
                    g(1.0 / fs),
                    g(fs)
                ),
            ));
        }
        let despike = DespikeConfig {
            half_window_s,
            threshold: self.value(&THRESHOLD, f.despike_threshold)?,
            min_deviation_mps: self.value(&MIN_DEVIATION, f.despike_min_deviation_mps)?,
        };
        Ok(FilterConfig {
            mode,
            radar_cutoff_hz: cutoff(&RADAR, f.radar_cutoff_hz)?,
            tacho_cutoff_hz: cutoff(&TACHO, f.tacho_cutoff_hz)?,
            pressure_cutoff_hz: cutoff(&PRESSURE, f.pressure_cutoff_hz)?,
            despike: f.despike.unwrap_or(true).then_some(despike),
        })
    }
}
