//! `[sensors]`: what the logger sees of the truth — noise, spikes, quantisation, rates.

use crate::config::rule::{closed, Checker, Default, Key};
use crate::config::ConfigError;

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Sensors {
        pub radar_noise_mps: Option<f64>,
        pub radar_spike_rate_hz: Option<f64>,
        pub radar_spike_mps: Option<f64>,
        pub tacho_pulses_per_rev: Option<f64>,
        pub tacho_window_ms: Option<f64>,
        pub pressure_noise_bar: Option<f64>,
        pub radar_rate_hz: Option<f64>,
        pub tacho_rate_hz: Option<f64>,
        pub pressure_rate_hz: Option<f64>,
        pub radar_scale: Option<f64>,
        pub radar_latency_s: Option<f64>,
    }
}

/// `[sensors]`: what the logger sees of the truth.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorsSection {
    pub radar_noise_mps: f64,
    pub radar_spike_rate_hz: f64,
    pub radar_spike_mps: f64,
    pub tacho_pulses_per_rev: f64,
    pub tacho_window_s: f64,
    pub pressure_noise_bar: f64,
    pub radar_rate_hz: f64,
    pub tacho_rate_hz: f64,
    pub pressure_rate_hz: f64,
    /// `radar_error`: the radar reads this × the true speed …
    pub radar_scale: f64,
    /// … of this long ago, s.
    pub radar_latency_s: f64,
}

pub(super) const RADAR_NOISE: Key = Key::num(
    "sensors.radar_noise_mps",
    "m/s",
    closed(0.0, 10.0),
    0.05,
    "`radar_noise`: standard deviation",
);
pub(super) const SPIKE_RATE: Key = Key::num(
    "sensors.radar_spike_rate_hz",
    "Hz",
    closed(0.0, 100.0),
    0.3,
    "`radar_spikes`: mean rate",
);
pub(super) const SPIKE: Key = Key::num(
    "sensors.radar_spike_mps",
    "m/s",
    closed(0.0, 100.0),
    3.0,
    "`radar_spikes`: amplitude (× 0.5–1.5, either sign)",
);
pub(super) const PULSES: Key = Key::num(
    "sensors.tacho_pulses_per_rev",
    "",
    closed(1.0, 100_000.0),
    1000.0,
    "`tacho_quantization`: pulses per revolution",
);
pub(super) const WINDOW: Key = Key::num(
    "sensors.tacho_window_ms",
    "ms",
    closed(0.1, 1000.0),
    20.0,
    "`tacho_quantization`: counting window",
);
pub(super) const PRESSURE_NOISE: Key = Key::num(
    "sensors.pressure_noise_bar",
    "bar",
    closed(0.0, 5.0),
    0.01,
    "`pressure_noise`: standard deviation",
);
pub(super) const fn rate(name: &'static str, meaning: &'static str) -> Key {
    Key {
        name,
        unit: "Hz",
        range: closed(1.0, 10_000.0),
        default: Default::Text("the output rate"),
        meaning,
    }
}
pub(super) const RADAR_RATE: Key = rate(
    "sensors.radar_rate_hz",
    "radar logger rate (rates other than the output rate: MCAP only)",
);
pub(super) const TACHO_RATE: Key = rate("sensors.tacho_rate_hz", "tachometer logger rate");
pub(super) const PRESSURE_RATE: Key = rate("sensors.pressure_rate_hz", "pressure logger rate");

pub(super) const RADAR_SCALE: Key = Key::num(
    "sensors.radar_scale",
    "–",
    closed(0.9, 1.1),
    1.003,
    "`radar_error`: the radar reads this × the true speed (a scale error, e.g. of the mounting angle)",
);
pub(super) const RADAR_LATENCY: Key = Key::num(
    "sensors.radar_latency_s",
    "s",
    closed(0.0, 0.5),
    0.03,
    "`radar_error`: … of this long ago (the radar's processing delay against the tachometers)",
);

/// The keys of `[sensors]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
    &RADAR_NOISE,
    &SPIKE_RATE,
    &SPIKE,
    &PULSES,
    &WINDOW,
    &PRESSURE_NOISE,
    &RADAR_RATE,
    &TACHO_RATE,
    &PRESSURE_RATE,
    &RADAR_SCALE,
    &RADAR_LATENCY,
];

impl Checker<'_> {
    /// `[sensors]` checked.
    pub(crate) fn sensors(
        &self,
        s: &raw::Sensors,
        output_rate_hz: f64,
    ) -> Result<SensorsSection, ConfigError> {
        Ok(SensorsSection {
            radar_noise_mps: self.value(&RADAR_NOISE, s.radar_noise_mps)?,
            radar_spike_rate_hz: self.value(&SPIKE_RATE, s.radar_spike_rate_hz)?,
            radar_spike_mps: self.value(&SPIKE, s.radar_spike_mps)?,
            tacho_pulses_per_rev: self.value(&PULSES, s.tacho_pulses_per_rev)?,
            tacho_window_s: self.value(&WINDOW, s.tacho_window_ms)? * 1e-3,
            pressure_noise_bar: self.value(&PRESSURE_NOISE, s.pressure_noise_bar)?,
            radar_rate_hz: self.value_or(&RADAR_RATE, s.radar_rate_hz, output_rate_hz)?,
            tacho_rate_hz: self.value_or(&TACHO_RATE, s.tacho_rate_hz, output_rate_hz)?,
            pressure_rate_hz: self.value_or(&PRESSURE_RATE, s.pressure_rate_hz, output_rate_hz)?,
            radar_scale: self.value(&RADAR_SCALE, s.radar_scale)?,
            radar_latency_s: self.value(&RADAR_LATENCY, s.radar_latency_s)?,
        })
    }
}
