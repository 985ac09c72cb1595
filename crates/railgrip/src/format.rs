//! The braking-log format, v1 (../shared/design/data-contract.md): the one place that spells
//! channel names, CSV columns, MCAP topics and fields, units and metadata keys.
//!
//! Readers (`ingest`) and writers (this module, used by tests, benchmarks and the simulator)
//! share these definitions, so nothing else in the crate writes a topic or column name.
//!
//! Architecture invariant: a new signal or topic is added here and nowhere else.

use std::collections::BTreeMap;
use std::io::{self, Seek, Write};

use crate::units::Quantity;

/// Number of axles in a log (axle 1 leads in the running direction).
pub const AXLES: usize = 4;

/// Canonical CSV: name of the time column (seconds since the start of the record).
pub const CSV_TIME_COLUMN: &str = "t";
/// Name of the MCAP metadata record that carries the run's metadata.
pub const MCAP_METADATA_NAME: &str = "run";
/// MCAP message encoding railgrip reads and writes.
pub const MCAP_MESSAGE_ENCODING: &str = "json";
/// MCAP schema encoding railgrip writes.
pub const MCAP_SCHEMA_ENCODING: &str = "jsonschema";
/// Suffix of the metadata sidecar of a CSV run: `<stem>.meta.toml`.
pub const SIDECAR_SUFFIX: &str = ".meta.toml";
/// A simulated run's truth table beside its log: `<stem>.truth.parquet` (`railgrip simulate`;
/// read by `railgrip study`).
pub const TRUTH_SUFFIX: &str = ".truth.parquet";

/// Column names of the resampled `*.runlog.parquet` table.
pub const RUNLOG_TIME_COLUMN: &str = "time_s";
pub const RUNLOG_VALID_COLUMN: &str = "valid";

/// One measured signal of a braking log.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Signal {
    /// Vehicle speed from the Doppler radar, m/s.
    VRadar,
    /// Axle angular speed from the tachometer, rad/s; axle number 1..=4.
    Omega(u8),
    /// Brake-cylinder pressure, bar gauge; axle number 1..=4.
    Pressure(u8),
}

const KEYS: [&str; 9] = [
    "v_radar", "omega1", "omega2", "omega3", "omega4", "p1", "p2", "p3", "p4",
];
const TOPICS: [&str; 9] = [
    "/radar/speed",
    "/axle1/omega",
    "/axle2/omega",
    "/axle3/omega",
    "/axle4/omega",
    "/axle1/brake_pressure",
    "/axle2/brake_pressure",
    "/axle3/brake_pressure",
    "/axle4/brake_pressure",
];
const RUNLOG_COLUMNS: [&str; 9] = [
    "v_radar_mps",
    "omega1_radps",
    "omega2_radps",
    "omega3_radps",
    "omega4_radps",
    "p1_bar",
    "p2_bar",
    "p3_bar",
    "p4_bar",
];

impl Signal {
    /// All signals in their canonical order: v_radar, omega1..4, p1..4.
    pub const ALL: [Signal; 9] = [
        Signal::VRadar,
        Signal::Omega(1),
        Signal::Omega(2),
        Signal::Omega(3),
        Signal::Omega(4),
        Signal::Pressure(1),
        Signal::Pressure(2),
        Signal::Pressure(3),
        Signal::Pressure(4),
    ];

    /// Position in [`Signal::ALL`].
    pub fn index(self) -> usize {
        match self {
            Signal::VRadar => 0,
            Signal::Omega(a) => a as usize,
            Signal::Pressure(a) => 4 + a as usize,
        }
    }

    /// The signal's key in configs and its canonical CSV column: `v_radar`, `omega1`, `p1`.
    pub fn key(self) -> &'static str {
        KEYS[self.index()]
    }

    /// Canonical MCAP topic.
    pub fn mcap_topic(self) -> &'static str {
        TOPICS[self.index()]
    }

    /// JSON field of the canonical MCAP payload: `v`, `omega`, `p`.
    pub fn mcap_field(self) -> &'static str {
        match self {
            Signal::VRadar => "v",
            Signal::Omega(_) => "omega",
            Signal::Pressure(_) => "p",
        }
    }

    /// Column of the resampled run-log table, with its unit: `omega1_radps`.
    pub fn runlog_column(self) -> &'static str {
        RUNLOG_COLUMNS[self.index()]
    }

    pub fn quantity(self) -> Quantity {
        match self {
            Signal::VRadar => Quantity::Speed,
            Signal::Omega(_) => Quantity::AngularSpeed,
            Signal::Pressure(_) => Quantity::Pressure,
        }
    }

    /// JSON Schema of the canonical MCAP payload, as written to the file's schema record.
    pub fn mcap_schema(self) -> String {
        let (title, unit) = match self {
            Signal::VRadar => ("railgrip.RadarSpeed", "m/s"),
            Signal::Omega(_) => ("railgrip.AxleAngularSpeed", "rad/s"),
            Signal::Pressure(_) => ("railgrip.BrakeCylinderPressure", "bar"),
        };
        format!(
            r#"{{"title":"{title}","type":"object","properties":{{"{f}":{{"type":"number","description":"{unit}"}}}},"required":["{f}"]}}"#,
            f = self.mcap_field()
        )
    }
}

impl std::fmt::Display for Signal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// `<run>.railgrip.mcap`, railgrip's results as MCAP for Foxglove: one JSON topic per
/// quantity, `/railgrip/v_mps` for the vehicle and `/railgrip/axle<i>/<field>` per axle, each
/// message `{"<field>": value}` (null where the value is not finite), at the log times of the
/// input's samples. (field, JSON type, description with unit) per axle topic; `mu_model` only
/// when a model was replayed.
pub const REPLAY_AXLE_FIELDS: [(&str, &str, &str); 7] = [
    ("dv_mps", "number", "slip velocity Δv = v − rω, m/s"),
    ("ddv_mps2", "number", "slip rate dΔv/dt, m/s²"),
    ("normal_N", "number", "normal load N (load transfer), N"),
    (
        "tangential_N",
        "number",
        "tangential force T (torque balance), N",
    ),
    (
        "mu",
        "number",
        "adhesion coefficient μ = T/N from the torque balance",
    ),
    (
        "valid",
        "boolean",
        "true where the sample is used for identification",
    ),
    (
        "mu_model",
        "number",
        "the model's μ replayed on this run's Δv, dΔv/dt (and v, T)",
    ),
];
/// The vehicle's topic in `<run>.railgrip.mcap` and its field.
pub const REPLAY_SPEED_TOPIC: &str = "/railgrip/v_mps";
pub const REPLAY_SPEED_FIELD: (&str, &str, &str) =
    ("v_mps", "number", "vehicle speed v (radar, filtered), m/s");

/// The topic of per-axle quantity `field` of axle `axle` (1-based) in `<run>.railgrip.mcap`.
pub fn replay_topic(axle: usize, field: &str) -> String {
    format!("/railgrip/axle{axle}/{field}")
}

/// The JSON schema of a replay topic with one field.
pub fn replay_schema(field: &str, json_type: &str, description: &str) -> String {
    serde_json::json!({
        "title": format!("railgrip.{field}"),
        "type": "object",
        "properties": { field: { "type": [json_type, "null"], "description": description } },
        "required": [field],
    })
    .to_string()
}

/// Typed run metadata (MCAP record "run" or the CSV sidecar). Unknown keys are kept in `other`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunMetadata {
    /// Ambient temperature during the test, °C.
    pub ambient_temperature_c: Option<f64>,
    /// Speed at brake application, km/h.
    pub initial_speed_kmh: Option<f64>,
    pub vehicle: Option<String>,
    /// Rail condition, e.g. `dry`, `wet`, `soap`.
    pub condition: Option<String>,
    /// Running direction, free text.
    pub direction: Option<String>,
    /// Every other key, verbatim.
    pub other: BTreeMap<String, String>,
}

/// A metadata value that does not have the type its key needs.
#[derive(Debug, Clone, PartialEq)]
pub struct MetadataValueError {
    pub key: String,
    pub value: String,
    pub expected: &'static str,
}

impl RunMetadata {
    pub const AMBIENT_TEMPERATURE_C: &'static str = "ambient_temperature_c";
    pub const INITIAL_SPEED_KMH: &'static str = "initial_speed_kmh";
    pub const VEHICLE: &'static str = "vehicle";
    pub const CONDITION: &'static str = "condition";
    pub const DIRECTION: &'static str = "direction";

    /// Builds typed metadata from string key/values (the MCAP form).
    pub fn from_pairs(pairs: &BTreeMap<String, String>) -> Result<Self, MetadataValueError> {
        let mut m = RunMetadata::default();
        for (k, v) in pairs {
            let number = |expected| {
                let x: f64 = v.trim().parse().map_err(|_| MetadataValueError {
                    key: k.clone(),
                    value: v.clone(),
                    expected,
                })?;
                if x.is_finite() {
                    Ok(Some(x))
                } else {
                    Err(MetadataValueError {
                        key: k.clone(),
                        value: v.clone(),
                        expected,
                    })
                }
            };
            match k.as_str() {
                Self::AMBIENT_TEMPERATURE_C => m.ambient_temperature_c = number("a number in °C")?,
                Self::INITIAL_SPEED_KMH => m.initial_speed_kmh = number("a number in km/h")?,
                Self::VEHICLE => m.vehicle = Some(v.clone()),
                Self::CONDITION => m.condition = Some(v.clone()),
                Self::DIRECTION => m.direction = Some(v.clone()),
                _ => {
                    m.other.insert(k.clone(), v.clone());
                }
            }
        }
        Ok(m)
    }

    /// The string key/values of this metadata (the MCAP form), numbers in shortest round-trip
    /// notation.
    pub fn to_pairs(&self) -> BTreeMap<String, String> {
        let mut p = self.other.clone();
        if let Some(x) = self.ambient_temperature_c {
            p.insert(Self::AMBIENT_TEMPERATURE_C.into(), format!("{x:?}"));
        }
        if let Some(x) = self.initial_speed_kmh {
            p.insert(Self::INITIAL_SPEED_KMH.into(), format!("{x:?}"));
        }
        for (k, v) in [
            (Self::VEHICLE, &self.vehicle),
            (Self::CONDITION, &self.condition),
            (Self::DIRECTION, &self.direction),
        ] {
            if let Some(v) = v {
                p.insert(k.into(), v.clone());
            }
        }
        p
    }

    /// The sidecar TOML text: numbers as TOML floats, everything else as strings.
    pub fn to_sidecar_toml(&self) -> String {
        let mut s = String::new();
        for (k, v) in self.to_pairs() {
            let numeric = k == Self::AMBIENT_TEMPERATURE_C || k == Self::INITIAL_SPEED_KMH;
            if numeric {
                s.push_str(&format!("{k} = {v}\n"));
            } else {
                s.push_str(&format!("{k} = {}\n", toml_string(&v)));
            }
        }
        s
    }
}

fn toml_string(v: &str) -> String {
    let mut out = String::with_capacity(v.len() + 2);
    out.push('"');
    for c in v.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// One signal's samples for writing: times in seconds since the start of the record and
/// values in the signal's canonical unit.
#[derive(Debug, Clone, Copy)]
pub struct SeriesRef<'a> {
    pub signal: Signal,
    pub time_s: &'a [f64],
    pub values: &'a [f64],
}

/// Writes a canonical CSV (header `t,v_radar,omega1..4,p1..4`) from one shared time column and
/// the nine signals in [`Signal::ALL`] order. Numbers use Rust's shortest round-trip notation,
/// so reading back is exact.
pub fn write_canonical_csv<W: Write>(
    mut w: W,
    time_s: &[f64],
    columns: [&[f64]; 9],
) -> io::Result<()> {
    for c in &columns {
        if c.len() != time_s.len() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "every column must have as many rows as the time column",
            ));
        }
    }
    w.write_all(CSV_TIME_COLUMN.as_bytes())?;
    for s in Signal::ALL {
        w.write_all(b",")?;
        w.write_all(s.key().as_bytes())?;
    }
    w.write_all(b"\n")?;
    let mut line = String::with_capacity(256);
    for (i, t) in time_s.iter().enumerate() {
        use std::fmt::Write as _;
        line.clear();
        let _ = write!(line, "{t:?}");
        for c in &columns {
            let _ = write!(line, ",{:?}", c[i]);
        }
        line.push('\n');
        w.write_all(line.as_bytes())?;
    }
    w.flush()
}

/// Compression of MCAP chunks written by [`write_mcap`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum McapCompression {
    None,
    Zstd,
    Lz4,
}

/// Writes a canonical MCAP: one JSON channel per series (topic and field per the contract),
/// messages interleaved in time order across channels, the metadata record "run", chunks
/// compressed as asked, chunk indexes but no per-message index records. `t0_ns` is the log
/// time of t = 0 s.
pub fn write_mcap<W: Write + Seek>(
    w: W,
    series: &[SeriesRef<'_>],
    metadata: &RunMetadata,
    compression: McapCompression,
    t0_ns: u64,
) -> Result<(), mcap::McapError> {
    let compression = match compression {
        McapCompression::None => None,
        McapCompression::Zstd => Some(mcap::Compression::Zstd),
        McapCompression::Lz4 => Some(mcap::Compression::Lz4),
    };
    let mut writer = mcap::WriteOptions::new()
        .compression(compression)
        .profile("")
        .library(concat!("railgrip ", env!("CARGO_PKG_VERSION")))
        // Chunk indexes stay; per-message index records (16 bytes a message, uncompressed)
        // would double the size of these small-message logs.
        .emit_message_indexes(false)
        // zstd on the calling thread: its worker threads (one a physical CPU by default) took a
        // lock per message for these small messages (the same bytes here, ~10 % of `railgrip
        // simulate`'s whole process on 2 cores), and campaigns already write runs side by side.
        .compression_threads(0)
        .create(w)?;
    let mut channel_ids = Vec::with_capacity(series.len());
    for s in series {
        let schema = s.signal.mcap_schema();
        let name = serde_json::from_str::<serde_json::Value>(&schema)
            .ok()
            .and_then(|v| v["title"].as_str().map(str::to_owned))
            .unwrap_or_default();
        let schema_id = writer.add_schema(&name, MCAP_SCHEMA_ENCODING, schema.as_bytes())?;
        let id = writer.add_channel(
            schema_id,
            s.signal.mcap_topic(),
            MCAP_MESSAGE_ENCODING,
            &BTreeMap::new(),
        )?;
        channel_ids.push(id);
    }
    writer.write_metadata(&mcap::records::Metadata {
        name: MCAP_METADATA_NAME.to_string(),
        metadata: metadata.to_pairs(),
    })?;
    // k-way merge by time across the series.
    let mut cursor = vec![0usize; series.len()];
    let mut sequence = vec![0u32; series.len()];
    let mut payload = String::with_capacity(64);
    loop {
        let mut best: Option<(usize, f64)> = None;
        for (k, s) in series.iter().enumerate() {
            if let Some(&t) = s.time_s.get(cursor[k]) {
                if best.is_none_or(|(_, bt)| t < bt) {
                    best = Some((k, t));
                }
            }
        }
        let Some((k, t)) = best else { break };
        let s = &series[k];
        let value = s.values[cursor[k]];
        cursor[k] += 1;
        payload.clear();
        {
            use std::fmt::Write as _;
            let _ = write!(payload, "{{\"{}\":{:?}}}", s.signal.mcap_field(), value);
        }
        let log_time = t0_ns + (t * 1e9).round().max(0.0) as u64;
        writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel_ids[k],
                sequence: sequence[k],
                log_time,
                publish_time: log_time,
            },
            payload.as_bytes(),
        )?;
        sequence[k] = sequence[k].wrapping_add(1);
    }
    writer.finish()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signal_names_follow_the_contract() {
        let keys: Vec<_> = Signal::ALL.iter().map(|s| s.key()).collect();
        assert_eq!(
            keys,
            ["v_radar", "omega1", "omega2", "omega3", "omega4", "p1", "p2", "p3", "p4"]
        );
        assert_eq!(Signal::Omega(3).mcap_topic(), "/axle3/omega");
        assert_eq!(Signal::Pressure(2).mcap_topic(), "/axle2/brake_pressure");
        assert_eq!(Signal::VRadar.mcap_topic(), "/radar/speed");
        for (i, s) in Signal::ALL.iter().enumerate() {
            assert_eq!(s.index(), i);
            let schema: serde_json::Value = serde_json::from_str(&s.mcap_schema()).unwrap();
            assert_eq!(schema["required"][0], s.mcap_field());
        }
    }

    #[test]
    fn metadata_round_trips_through_pairs_and_rejects_bad_numbers() {
        let m = RunMetadata {
            ambient_temperature_c: Some(-20.5),
            initial_speed_kmh: Some(160.0),
            vehicle: Some("UIC-Z1".into()),
            condition: Some("soap".into()),
            direction: None,
            other: [("operator".to_string(), "a \"quoted\" name".to_string())].into(),
        };
        assert_eq!(RunMetadata::from_pairs(&m.to_pairs()).unwrap(), m);
        let toml_text = m.to_sidecar_toml();
        let parsed: toml::Table = toml::from_str(&toml_text).unwrap();
        assert_eq!(parsed["ambient_temperature_c"].as_float(), Some(-20.5));
        assert_eq!(parsed["operator"].as_str(), Some("a \"quoted\" name"));

        let bad = [("ambient_temperature_c".to_string(), "cold".to_string())].into();
        let e = RunMetadata::from_pairs(&bad).unwrap_err();
        assert_eq!(e.key, "ambient_temperature_c");
        assert_eq!(e.value, "cold");
    }
}
