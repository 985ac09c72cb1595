//! `[ingest]`: the uniform time base, the gap rule, plausibility limits and where each signal
//! is in a CSV or MCAP log (`[ingest.csv]`, `[ingest.mcap]`; data-contract names by default).

use super::rule::{closed, g, Checker, Default, Key, Range};
use super::ConfigError;
use crate::format::Signal;
use crate::units::{Quantity, Unit};

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Ingest {
        pub sample_rate_hz: Option<f64>,
        pub max_gap_ms: Option<f64>,
        pub max_duration_s: Option<f64>,
        pub bridge_gap_ms: Option<f64>,
        #[serde(default)]
        pub plausibility: Plausibility,
        #[serde(default)]
        pub csv: CsvMapping,
        #[serde(default)]
        pub mcap: McapMapping,
    }

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Plausibility {
        pub action: Option<String>,
        pub speed_min_mps: Option<f64>,
        pub speed_max_mps: Option<f64>,
        pub omega_min_radps: Option<f64>,
        pub omega_max_radps: Option<f64>,
        pub pressure_min_bar: Option<f64>,
        pub pressure_max_bar: Option<f64>,
    }

    #[derive(Debug, Clone, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct CsvColumn {
        pub column: Option<String>,
        pub unit: Option<String>,
    }

    #[derive(Debug, Clone, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct McapField {
        pub topic: Option<String>,
        pub field: Option<String>,
        pub unit: Option<String>,
        pub time: Option<String>,
    }

    /// `[ingest.csv]`: signal key (`time`, `v_radar`, `omega1`..`omega4`, `p1`..`p4`) → column.
    pub type CsvMapping = std::collections::BTreeMap<String, CsvColumn>;
    /// `[ingest.mcap]`: signal key (`v_radar`, `omega1`..`omega4`, `p1`..`p4`) → topic/field.
    pub type McapMapping = std::collections::BTreeMap<String, McapField>;
}

/// What to do with a raw sample outside the plausibility limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlausibilityAction {
    /// Drop the sample (treated as missing, bridged only if the hole is shorter than
    /// `max_gap_ms`) and report the count as a warning.
    Warn,
    /// Reject the file with an error naming the first such sample.
    Error,
}

/// Limits on raw samples, canonical units.
#[derive(Debug, Clone, PartialEq)]
pub struct Plausibility {
    pub action: PlausibilityAction,
    pub speed_mps: (f64, f64),
    pub omega_radps: (f64, f64),
    pub pressure_bar: (f64, f64),
}

impl Plausibility {
    /// The (min, max) limits that apply to a signal, in its canonical unit.
    pub fn limits(&self, signal: Signal) -> (f64, f64) {
        match signal {
            Signal::VRadar => self.speed_mps,
            Signal::Omega(_) => self.omega_radps,
            Signal::Pressure(_) => self.pressure_bar,
        }
    }
}

/// Where a signal is in a CSV log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CsvColumn {
    pub column: String,
    pub unit: Unit,
}

/// Where a signal is in an MCAP log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct McapField {
    pub topic: String,
    /// A field name (JSON: a top-level key) or a path into nested messages, `twist.linear.x`,
    /// with `[k]` picking element k of an array or repeated field (protobuf, ROS 2).
    pub field: String,
    pub unit: Unit,
    /// `time = "header"`: the message's own stamp (ROS 2 `header.stamp`, protobuf
    /// `header.stamp` or `timestamp`) instead of the MCAP log time.
    pub header_time: bool,
}

/// Ingest settings.
#[derive(Debug, Clone, PartialEq)]
pub struct IngestConfig {
    /// Rate of the uniform time base, Hz.
    pub sample_rate_hz: f64,
    /// Longest hole in a channel that is interpolated across linearly like any sample step, s.
    pub max_gap_s: f64,
    /// Longest hole bridged by cubic Hermite interpolation (holes longer than `max_gap_s`
    /// and at most this), s; the bridged samples and the filters' support around them are
    /// masked after conditioning. Not above `max_gap_s`: no bridging.
    pub bridge_gap_s: f64,
    /// Longest run the resampler accepts, s (bounds the uniform grid it allocates).
    pub max_duration_s: f64,
    pub plausibility: Plausibility,
    pub csv_time: CsvColumn,
    /// CSV columns in [`Signal::ALL`] order.
    pub csv: [CsvColumn; 9],
    /// MCAP fields in [`Signal::ALL`] order.
    pub mcap: [McapField; 9],
}

impl IngestConfig {
    pub fn csv_column(&self, s: Signal) -> &CsvColumn {
        &self.csv[s.index()]
    }
    pub fn mcap_field(&self, s: Signal) -> &McapField {
        &self.mcap[s.index()]
    }
}

const RATE: Key = Key::num(
    "ingest.sample_rate_hz",
    "Hz",
    closed(1.0, 100_000.0),
    417.0,
    "rate of the uniform time base",
);
const MAX_GAP: Key = Key {
    name: "ingest.max_gap_ms",
    unit: "ms",
    range: Range::Text("(one sample period, 10000]"),
    default: Default::Num(50.0),
    meaning: "longest hole in a channel interpolated across; longer ones are masked",
};
const BRIDGE_GAP: Key = Key::num(
    "ingest.bridge_gap_ms",
    "ms",
    closed(0.0, 10_000.0),
    500.0,
    "longest hole (above max_gap_ms) bridged by cubic Hermite interpolation so the filters run through it; only the bridged samples and the filters' support around them are masked. Longer holes split the filters; 0 never bridges",
);
const MAX_DURATION: Key = Key::num(
    "ingest.max_duration_s",
    "s",
    closed(1.0, 86_400.0),
    14_400.0,
    "longest run accepted: the common time span of the channels (bounds the uniform grid, also at most 2·10⁷ samples); a longer span is an error that names the file and hints at a wrong time unit",
);
const ACTION: Key = Key {
    name: "ingest.plausibility.action",
    unit: "",
    range: Range::Choice(&["warn", "error"]),
    default: Default::Text("\"warn\""),
    meaning: "drop an implausible sample and report it, or reject the file",
};
const fn limit(name: &'static str, unit: &'static str, default: f64, meaning: &'static str) -> Key {
    Key::num(name, unit, closed(-1e6, 1e6), default, meaning)
}
const SPEED_MIN: Key = limit(
    "ingest.plausibility.speed_min_mps",
    "m/s",
    -0.5,
    "lowest plausible radar speed",
);
const SPEED_MAX: Key = limit(
    "ingest.plausibility.speed_max_mps",
    "m/s",
    100.0,
    "highest plausible radar speed, above the lowest",
);
const OMEGA_MIN: Key = limit(
    "ingest.plausibility.omega_min_radps",
    "rad/s",
    -0.5,
    "lowest plausible axle speed",
);
const OMEGA_MAX: Key = limit(
    "ingest.plausibility.omega_max_radps",
    "rad/s",
    250.0,
    "highest plausible axle speed, above the lowest",
);
const PRESSURE_MIN: Key = limit(
    "ingest.plausibility.pressure_min_bar",
    "bar",
    -0.5,
    "lowest plausible cylinder pressure",
);
const PRESSURE_MAX: Key = limit(
    "ingest.plausibility.pressure_max_bar",
    "bar",
    10.0,
    "highest plausible cylinder pressure, above the lowest",
);
const CSV: Key = Key {
    name: "ingest.csv.<signal>",
    unit: "",
    range: Range::Text("`{ column, unit }`"),
    default: Default::Text("canonical column and unit"),
    meaning: "`time`, `v_radar`, `omega1..4`, `p1..4`",
};
const MCAP: Key = Key {
    name: "ingest.mcap.<signal>",
    unit: "",
    range: Range::Text("`{ topic, field, unit, time }`"),
    default: Default::Text("canonical topic, field and unit; `time = \"log\"`"),
    meaning: "`v_radar`, `omega1..4`, `p1..4`; `field` a path (`twist.linear.x`, `velocity[2]`) in protobuf/ROS 2 messages; `time = \"header\"` takes the message's header stamp",
};

/// The keys of `[ingest]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
    &RATE,
    &MAX_GAP,
    &BRIDGE_GAP,
    &MAX_DURATION,
    &ACTION,
    &SPEED_MIN,
    &SPEED_MAX,
    &OMEGA_MIN,
    &OMEGA_MAX,
    &PRESSURE_MIN,
    &PRESSURE_MAX,
    &CSV,
    &MCAP,
];

impl Checker<'_> {
    pub(crate) fn ingest(&self, i: raw::Ingest) -> Result<IngestConfig, ConfigError> {
        let fs = self.value(&RATE, i.sample_rate_hz)?;
        let max_gap_ms = self.max_gap_ms(i.max_gap_ms, fs)?;
        let plausibility = self.plausibility(i.plausibility)?;
        let signal_keys: Vec<&str> = Signal::ALL.iter().map(|s| s.key()).collect();
        if let Some(k) = i
            .csv
            .keys()
            .find(|k| k.as_str() != "time" && !signal_keys.contains(&k.as_str()))
        {
            return Err(self.invalid(
                &format!("ingest.csv.{k}"),
                "{ … }",
                format!(
                    "unknown signal; the signals are time, {}",
                    signal_keys.join(", ")
                ),
            ));
        }
        if let Some(k) = i.mcap.keys().find(|k| !signal_keys.contains(&k.as_str())) {
            return Err(self.invalid(
                &format!("ingest.mcap.{k}"),
                "{ … }",
                format!("unknown signal; the signals are {}", signal_keys.join(", ")),
            ));
        }
        let csv_time = self.csv_column(
            "ingest.csv.time",
            i.csv.get("time"),
            crate::format::CSV_TIME_COLUMN,
            Quantity::Time,
        )?;
        let mut csv = Vec::with_capacity(9);
        let mut mcap = Vec::with_capacity(9);
        for s in Signal::ALL {
            csv.push(self.csv_column(
                &format!("ingest.csv.{}", s.key()),
                i.csv.get(s.key()),
                s.key(),
                s.quantity(),
            )?);
            let m: McapField =
                self.mcap_field(&format!("ingest.mcap.{}", s.key()), i.mcap.get(s.key()), s)?;
            // One topic, one clock: its messages are timed once for all its signals.
            if let Some((other, o)) =
                Signal::ALL
                    .iter()
                    .zip(&mcap)
                    .find(|(_, o): &(_, &McapField)| {
                        o.topic == m.topic && o.header_time != m.header_time
                    })
            {
                return Err(self.invalid(
                    &format!("ingest.mcap.{}.time", s.key()),
                    format!("{:?}", if m.header_time { "header" } else { "log" }),
                    format!(
                        "{} on the same topic {} has time = {:?}; signals sharing a topic share its time",
                        other.key(),
                        m.topic,
                        if o.header_time { "header" } else { "log" }
                    ),
                ));
            }
            mcap.push(m);
        }
        Ok(IngestConfig {
            sample_rate_hz: fs,
            max_gap_s: max_gap_ms * 1e-3,
            bridge_gap_s: self.value(&BRIDGE_GAP, i.bridge_gap_ms)? * 1e-3,
            max_duration_s: self.value(&MAX_DURATION, i.max_duration_s)?,
            plausibility,
            csv_time,
            csv: csv.try_into().expect("nine signals"),
            mcap: mcap.try_into().expect("nine signals"),
        })
    }

    /// `ingest.max_gap_ms`: longer than one sample period at `fs` Hz, at most 10 s.
    fn max_gap_ms(&self, v: Option<f64>, fs: f64) -> Result<f64, ConfigError> {
        let rule = Key {
            range: Range::Num {
                lo: 1000.0 / fs,
                lo_open: true,
                hi: 10_000.0,
                hi_open: false,
            },
            ..MAX_GAP
        };
        match v {
            None if rule.contains(50.0) => Ok(50.0),
            None => Err(self.missing(
                MAX_GAP.name,
                format!(
                    "the default 50 ms is not longer than one sample period at {} Hz; {}",
                    g(fs),
                    rule.rule_text()
                ),
            )),
            Some(x) if !rule.contains(x) => Err(self.invalid(
                MAX_GAP.name,
                g(x),
                format!("{}; the lower bound is one sample period", rule.rule_text()),
            )),
            Some(x) => Ok(x),
        }
    }

    fn plausibility(&self, p: raw::Plausibility) -> Result<Plausibility, ConfigError> {
        let action = self.choice(
            &ACTION,
            p.action,
            &[
                ("warn", PlausibilityAction::Warn),
                ("error", PlausibilityAction::Error),
            ],
            PlausibilityAction::Warn,
        )?;
        let pair = |k_lo: &Key, lo: Option<f64>, k_hi: &Key, hi: Option<f64>| {
            let lo = self.value(k_lo, lo)?;
            let hi = self.value(k_hi, hi)?;
            if lo >= hi {
                return Err(self.invalid(
                    k_hi.name,
                    g(hi),
                    format!("must be greater than {} = {}", k_lo.name, g(lo)),
                ));
            }
            Ok((lo, hi))
        };
        Ok(Plausibility {
            action,
            speed_mps: pair(&SPEED_MIN, p.speed_min_mps, &SPEED_MAX, p.speed_max_mps)?,
            omega_radps: pair(&OMEGA_MIN, p.omega_min_radps, &OMEGA_MAX, p.omega_max_radps)?,
            pressure_bar: pair(
                &PRESSURE_MIN,
                p.pressure_min_bar,
                &PRESSURE_MAX,
                p.pressure_max_bar,
            )?,
        })
    }

    fn unit(&self, key: &str, text: Option<&str>, q: Quantity) -> Result<Unit, ConfigError> {
        let Some(text) = text else {
            return Ok(q.canonical());
        };
        Unit::parse(q, text).ok_or_else(|| {
            self.invalid(
                &format!("{key}.unit"),
                format!("{text:?}"),
                format!(
                    "unknown {q} unit; use one of {} (default \"{}\")",
                    q.accepted()
                        .iter()
                        .map(|u| format!("\"{u}\""))
                        .collect::<Vec<_>>()
                        .join(", "),
                    q.canonical()
                ),
            )
        })
    }

    fn name(&self, key: &str, v: Option<&str>, default: &str) -> Result<String, ConfigError> {
        match v {
            None => Ok(default.to_string()),
            Some(s) if s.trim().is_empty() => Err(self.invalid(
                key,
                "\"\"",
                format!("must not be empty (default \"{default}\")"),
            )),
            Some(s) => Ok(s.to_string()),
        }
    }

    fn csv_column(
        &self,
        key: &str,
        r: Option<&raw::CsvColumn>,
        default: &str,
        q: Quantity,
    ) -> Result<CsvColumn, ConfigError> {
        Ok(CsvColumn {
            column: self.name(
                &format!("{key}.column"),
                r.and_then(|r| r.column.as_deref()),
                default,
            )?,
            unit: self.unit(key, r.and_then(|r| r.unit.as_deref()), q)?,
        })
    }

    fn mcap_field(
        &self,
        key: &str,
        r: Option<&raw::McapField>,
        s: Signal,
    ) -> Result<McapField, ConfigError> {
        Ok(McapField {
            topic: self.name(
                &format!("{key}.topic"),
                r.and_then(|r| r.topic.as_deref()),
                s.mcap_topic(),
            )?,
            field: self.name(
                &format!("{key}.field"),
                r.and_then(|r| r.field.as_deref()),
                s.mcap_field(),
            )?,
            unit: self.unit(key, r.and_then(|r| r.unit.as_deref()), s.quantity())?,
            header_time: match r.and_then(|r| r.time.as_deref()) {
                None | Some("log") => false,
                Some("header") => true,
                Some(other) => {
                    return Err(self.invalid(
                        &format!("{key}.time"),
                        format!("{other:?}"),
                        "use \"log\" (the MCAP log time, default) or \"header\" (the message's header stamp)".to_string(),
                    ))
                }
            },
        })
    }
}
