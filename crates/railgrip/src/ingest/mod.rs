//! Ingest: one braking-test log (CSV or MCAP, data-contract.md) → a validated, uniformly
//! sampled [`RunLog`] in canonical units.
//!
//! Steps: sniff the format from the bytes (MCAP magic, else text CSV) → read each mapped
//! channel in its own unit and convert (`units`) → apply the plausibility limits → resample
//! every channel onto one uniform time base by linear interpolation (`resample`). A hole in a
//! channel longer than `ingest.max_gap_ms` is never bridged: the samples inside it carry NaN in
//! that channel, `valid = false`, and the hole is listed in [`RunLog::gaps`] and the warnings.
//!
//! Architecture invariant: only this module reads input logs; everything after it sees
//! canonical units (s, m/s, rad/s, bar gauge).

mod csv;
mod decode_error;
mod mcap;
mod protobuf;
mod resample;
mod ros2;

use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::config::{IngestConfig, Pipeline, PlausibilityAction};
use crate::format::{RunMetadata, Signal, AXLES};
use rayon::prelude::*;

pub use decode_error::DecodeError;
pub use mcap::{FieldPath, MessageDecoder, SUPPORTED_ENCODINGS};
pub use resample::linear_interpolation_bound;

/// The input format a log was read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFormat {
    Csv,
    Mcap,
}

impl fmt::Display for LogFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LogFormat::Csv => "CSV",
            LogFormat::Mcap => "MCAP",
        })
    }
}

/// Where in an input file something is.
#[derive(Debug, Clone, PartialEq)]
pub enum Location {
    /// 1-based line of a CSV file (line 1 is the header).
    CsvLine(usize),
    /// An MCAP message: topic, 0-based index among that topic's messages, log time.
    Mcap {
        topic: String,
        message: usize,
        log_time_ns: u64,
    },
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::CsvLine(l) => write!(f, "line {l}"),
            Location::Mcap {
                topic,
                message,
                log_time_ns,
            } => {
                write!(
                    f,
                    "topic {topic}, message #{message} (log_time {log_time_ns} ns)"
                )
            }
        }
    }
}

/// A log that cannot be ingested. Every message names the file, where in it, what is wrong, and
/// what to do.
#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    #[error("{path}: file not found. Hint: check the path; railgrip reads .csv and .mcap logs")]
    NotFound { path: PathBuf },
    #[error("{path}: cannot read: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: the file is empty. Hint: the logger wrote nothing; re-export the run")]
    Empty { path: PathBuf },
    #[error("{path}: neither CSV nor MCAP: {found}. Hint: railgrip reads MCAP (magic bytes 0x89 'MCAP0') and comma-separated text with a header row")]
    UnknownFormat { path: PathBuf, found: String },
    #[error("{path}: missing CSV column(s) {missing}; the header has {present}. Hint: {hint}")]
    CsvMissingColumns {
        path: PathBuf,
        missing: String,
        present: String,
        hint: String,
    },
    #[error("{path}: line {line}, column {column:?}: {what}. Hint: {hint}")]
    CsvBadCell {
        path: PathBuf,
        line: usize,
        column: String,
        what: String,
        hint: String,
    },
    #[error("{path}: line {line}: {what}. Hint: {hint}")]
    CsvBadLine {
        path: PathBuf,
        line: usize,
        what: String,
        hint: String,
    },
    #[error("{path}: CSV could not be parsed: {message}. Hint: check that the file is comma-separated with '.' as decimal point")]
    CsvParse { path: PathBuf, message: String },
    #[error("{path}: {location}: time {t_s} s does not increase after {t_prev_s} s ({channel}). Hint: timestamps must be strictly increasing; remove the repeated or reordered rows")]
    TimeNotIncreasing {
        path: PathBuf,
        location: Location,
        channel: String,
        t_prev_s: f64,
        t_s: f64,
    },
    #[error("{path}: {what} after {messages} message(s): {source}. Hint: {hint}")]
    McapRead {
        path: PathBuf,
        messages: usize,
        what: &'static str,
        hint: &'static str,
        #[source]
        source: ::mcap::McapError,
    },
    #[error("{path}: topic {topic} has message encoding {encoding:?}; railgrip reads {supported}. Hint: re-record the channel in one of these encodings or convert the file")]
    McapEncoding {
        path: PathBuf,
        topic: String,
        encoding: String,
        supported: &'static str,
    },
    #[error("{path}: topic {topic}: {what}. Hint: {hint}")]
    McapSchema {
        path: PathBuf,
        topic: String,
        what: String,
        hint: String,
    },
    /// A mapped field path of a protobuf or CDR channel that does not parse.
    #[error("{path}: topic {topic}: {source}. Hint: {hint}")]
    McapFieldPath {
        path: PathBuf,
        topic: String,
        hint: &'static str,
        #[source]
        source: Box<DecodeError>,
    },
    /// A channel's schema (`schema_encoding` "protobuf" or "ros2msg") that does not compile
    /// for the mapped field paths.
    #[error("{path}: topic {topic}: {schema_encoding} schema {schema}: {source}. Hint: {hint}")]
    McapDecoder {
        path: PathBuf,
        topic: String,
        schema_encoding: &'static str,
        schema: String,
        hint: &'static str,
        #[source]
        source: Box<DecodeError>,
    },
    #[error("{path}: missing MCAP topic(s) {missing}; the file has {present}. Hint: map the signals to topics in [ingest.mcap] of the pipeline, e.g. v_radar = {{ topic = \"/radar/speed\", field = \"v\", unit = \"m/s\" }}")]
    McapMissingTopics {
        path: PathBuf,
        missing: String,
        present: String,
    },
    #[error("{path}: topic {topic} ({signal}) has no messages. Hint: the logger recorded nothing on this channel; check the sensor or map {signal} to another topic in [ingest.mcap]")]
    McapNoMessages {
        path: PathBuf,
        topic: String,
        signal: Signal,
    },
    #[error("{path}: {location}: {what}. Hint: {hint}")]
    McapBadMessage {
        path: PathBuf,
        location: Location,
        what: String,
        hint: String,
    },
    /// A JSON message that is not an object with the mapped number fields.
    #[error("{path}: {location}: {source}. Hint: {hint}")]
    McapJsonMessage {
        path: PathBuf,
        location: Location,
        hint: String,
        #[source]
        source: Box<DecodeError>,
    },
    /// A protobuf or CDR message (`decoder` names which) that does not decode against its
    /// schema; `sequence` is the message's sequence number.
    #[error("{path}: {location}: sequence {sequence}: the {decoder} message does not decode against its schema: {source}. Hint: the message or its schema is damaged; check the file with `mcap doctor` or re-record it")]
    McapUndecodable {
        path: PathBuf,
        location: Location,
        sequence: u32,
        decoder: &'static str,
        #[source]
        source: Box<DecodeError>,
    },
    #[error("{path}: {location}: {signal} = {value} {unit} is outside the plausibility limits [{min}, {max}] {unit}. Hint: fix the sensor data, or set ingest.plausibility.action = \"warn\" to drop such samples")]
    Implausible {
        path: PathBuf,
        location: Location,
        signal: Signal,
        value: f64,
        min: f64,
        max: f64,
        unit: &'static str,
    },
    #[error("{path}: the channels do not overlap long enough to resample: {what}. Hint: every signal must have data over a common time span of at least two samples")]
    NoOverlap { path: PathBuf, what: String },
    /// The channels' common time span would make a uniform grid beyond the limits (two
    /// rows 1e9 s apart once asked for terabytes).
    #[error("{path}: the channels span {span_s:.6e} s from t = {t_start} s, {samples:.3e} samples at {rate_hz} Hz; the limit is ingest.max_duration_s = {limit_s} s and 2e7 samples. Hint: {hint}")]
    TooLong {
        path: PathBuf,
        span_s: f64,
        t_start: f64,
        samples: f64,
        rate_hz: f64,
        limit_s: f64,
        hint: String,
    },
    #[error("{path}: bad run metadata in {source_name}: {what}. Hint: {hint}")]
    Metadata {
        path: PathBuf,
        source_name: String,
        what: String,
        hint: String,
    },
    #[error(transparent)]
    Write(#[from] crate::table::TableError),
}

impl From<std::io::Error> for IngestError {
    fn from(source: std::io::Error) -> Self {
        IngestError::Io {
            path: PathBuf::new(),
            source,
        }
    }
}

/// What kind of recoverable oddity a warning reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WarningKind {
    /// A hole in a channel longer than `max_gap_ms`: samples marked invalid.
    Gap,
    /// Data before the last channel starts or after the first one ends was cut off.
    Trimmed,
    /// Raw samples outside the plausibility limits were dropped.
    Implausible,
    /// Cells without a value (a CSV log's empty or NaN cells): missing samples of that channel.
    Missing,
    /// No metadata found (sidecar or MCAP record): nothing lost, but later stages lack it.
    NoMetadata,
}

impl WarningKind {
    /// True when the warning means some input was skipped or lost (CLI exit code 3).
    pub fn loses_data(self) -> bool {
        !matches!(self, WarningKind::NoMetadata)
    }
}

/// A recoverable oddity, carried with the result and shown to the user.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    pub kind: WarningKind,
    pub message: String,
}

/// A hole in one channel that was not interpolated across.
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    pub signal: Signal,
    /// Time of the last sample before the hole, s.
    pub from_s: f64,
    /// Time of the first sample after the hole, s.
    pub to_s: f64,
    /// True when the hole was bridged (`ingest.bridge_gap_ms`): the samples inside carry
    /// interpolated values and stay valid for the filters, and conditioning masks them with
    /// the filters' support around them.
    pub bridged: bool,
}

/// What was found in one input channel.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelSummary {
    pub signal: Signal,
    /// CSV column or MCAP topic/field it was read from.
    pub source: String,
    /// Samples read (before plausibility drops).
    pub samples: usize,
    /// Samples dropped by the plausibility limits.
    pub dropped: usize,
    /// Rate found: 1 / median sample step, Hz.
    pub rate_hz: f64,
    /// Longest step between kept samples, s.
    pub max_step_s: f64,
    /// Smallest and largest kept value, canonical unit.
    pub min: f64,
    pub max: f64,
}

/// One run on a uniform time base, canonical units.
///
/// Samples with `valid[i] == false` lie in an unbridged gap of at least one channel; the
/// channels with no data there hold NaN at `i`. Everything else is finite.
#[derive(Debug, Clone)]
pub struct RunLog {
    pub source: PathBuf,
    pub format: LogFormat,
    /// Rate of the time base, Hz.
    pub sample_rate_hz: f64,
    /// Time since the start of the record, s: `time_s[i] = time_s[0] + i / sample_rate_hz`.
    pub time_s: Vec<f64>,
    /// Radar vehicle speed, m/s.
    pub v_radar_mps: Vec<f64>,
    /// Axle angular speeds, rad/s, axles 1..4.
    pub omega_radps: [Vec<f64>; AXLES],
    /// Brake-cylinder pressures, bar gauge, axles 1..4.
    pub p_bar: [Vec<f64>; AXLES],
    pub valid: Vec<bool>,
    pub metadata: RunMetadata,
    /// Log time of t = 0 s (the file's first message on a mapped topic), ns (MCAP only).
    pub start_log_time_ns: Option<u64>,
    /// In [`Signal::ALL`] order.
    pub channels: Vec<ChannelSummary>,
    pub gaps: Vec<Gap>,
    pub warnings: Vec<Warning>,
}

impl RunLog {
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// The resampled values of one signal.
    pub fn signal(&self, s: Signal) -> &[f64] {
        match s {
            Signal::VRadar => &self.v_radar_mps,
            Signal::Omega(a) => &self.omega_radps[a as usize - 1],
            Signal::Pressure(a) => &self.p_bar[a as usize - 1],
        }
    }

    /// Duration from the first to the last sample, s.
    pub fn duration_s(&self) -> f64 {
        match (self.time_s.first(), self.time_s.last()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    }

    /// True when some input was skipped or lost (gaps, trimmed edges, dropped samples).
    pub fn lost_data(&self) -> bool {
        self.warnings.iter().any(|w| w.kind.loses_data())
    }

    /// Number of samples with `valid == false`.
    pub fn invalid_samples(&self) -> usize {
        self.valid.iter().filter(|v| !**v).count()
    }

    /// Maximal runs of valid samples, as index ranges.
    pub fn valid_segments(&self) -> Vec<Range<usize>> {
        let mut out = Vec::new();
        let mut start = None;
        for (i, &v) in self.valid.iter().enumerate() {
            match (v, start) {
                (true, None) => start = Some(i),
                (false, Some(s)) => {
                    out.push(s..i);
                    start = None;
                }
                _ => {}
            }
        }
        if let Some(s) = start {
            out.push(s..self.valid.len());
        }
        out
    }
}

/// One input channel as read, canonical units, before resampling. NaN values are samples
/// dropped by the plausibility limits (treated as missing).
pub(crate) struct RawChannel {
    pub signal: Signal,
    pub source: String,
    /// Shared between channels of a CSV (one time column).
    pub time_s: Arc<Vec<f64>>,
    pub values: Vec<f64>,
    /// Where each raw sample came from, for error messages.
    pub locate: Locator,
    /// Samples set to NaN by the plausibility limits.
    pub dropped: usize,
}

/// Maps a raw sample index back to its place in the file.
#[derive(Clone)]
pub(crate) enum Locator {
    /// Sample `i` is on CSV data row `i` (line numbers come from a rescan on the error path).
    CsvRows(Arc<LogSource>),
    /// Sample `i` is on CSV data row `rows[i]` (a channel with cells without a value keeps
    /// only its other rows).
    CsvRowsOf(Arc<LogSource>, Arc<Vec<usize>>),
    /// Sample `i` is message `i` (in time order) of the topic, at log time t_ref + t.
    Mcap { topic: String, t_ref_ns: u64 },
}

impl Locator {
    fn locate(&self, i: usize, time_s: &[f64]) -> Location {
        match self {
            Locator::CsvRows(path) => Location::CsvLine(csv::line_of_row(path, i)),
            Locator::CsvRowsOf(path, rows) => Location::CsvLine(csv::line_of_row(path, rows[i])),
            Locator::Mcap { topic, t_ref_ns } => Location::Mcap {
                topic: topic.clone(),
                message: i,
                log_time_ns: (*t_ref_ns as i128 + (time_s[i] * 1e9).round() as i128).max(0) as u64,
            },
        }
    }
}

/// Where a log's bytes are: a file, or a member of a campaign archive held in memory (with
/// its metadata sidecar, for CSV logs). Errors name [`LogSource::name`].
#[derive(Debug, Clone)]
pub enum LogSource {
    File(PathBuf),
    Memory {
        /// Shown in messages, e.g. `campaign.zip/day1/run.csv`.
        name: PathBuf,
        bytes: Arc<[u8]>,
        /// The `<stem>.meta.toml` member beside a CSV log, if the archive has one.
        sidecar: Option<Arc<[u8]>>,
    },
    /// An object in a bucket (named `s3://bucket/key`), fetched when read:
    /// [`LogSource::fetched`] reads it and its sidecar once into memory.
    Object {
        name: PathBuf,
        object: crate::store::ObjectLog,
    },
}

impl LogSource {
    /// The name errors and outputs use.
    pub fn name(&self) -> &Path {
        match self {
            LogSource::File(p) => p,
            LogSource::Memory { name, .. } | LogSource::Object { name, .. } => name,
        }
    }

    /// The log at a location: a path, `file://PATH` or `s3://BUCKET/KEY` (with the
    /// `<stem>.meta.toml` beside a CSV log when the bucket has one).
    pub fn at(text: &str) -> Result<LogSource, crate::store::StoreError> {
        use crate::store::{Location, ObjectLog};
        Ok(match Location::parse(text)? {
            Location::Local(p) => LogSource::File(p),
            Location::S3 { bucket, prefix } => {
                let object = ObjectLog::at(&bucket, &prefix)?;
                LogSource::Object {
                    name: PathBuf::from(object.bucket.uri(&prefix)),
                    object,
                }
            }
        })
    }

    /// The same log with its bytes at hand: an object in a bucket fetched into memory (the log
    /// and its sidecar, one GET each), any other source as it is.
    pub fn fetched(&self) -> std::io::Result<LogSource> {
        let LogSource::Object { name, object } = self else {
            return Ok(self.clone());
        };
        let bytes = object.bucket.get(&object.key, MAX_OBJECT_LOG_BYTES)?;
        let sidecar = match &object.sidecar {
            Some(k) => Some(
                object
                    .bucket
                    .get(k, crate::input::MAX_SIDECAR_BYTES)?
                    .into(),
            ),
            None => None,
        };
        Ok(LogSource::Memory {
            name: name.clone(),
            bytes: bytes.into(),
            sidecar,
        })
    }

    /// A reader over the log's bytes from the start.
    pub(crate) fn open(&self) -> std::io::Result<Box<dyn std::io::Read + Send>> {
        Ok(match self {
            LogSource::File(p) => Box::new(crate::input::open_regular(p)?),
            LogSource::Memory { bytes, .. } => Box::new(std::io::Cursor::new(Arc::clone(bytes))),
            LogSource::Object { object, .. } => Box::new(std::io::Cursor::new(
                object.bucket.get(&object.key, MAX_OBJECT_LOG_BYTES)?,
            )),
        })
    }

    /// Size in bytes.
    pub(crate) fn len(&self) -> std::io::Result<u64> {
        Ok(match self {
            LogSource::File(p) => crate::input::check_regular(p)?.len(),
            LogSource::Memory { bytes, .. } => bytes.len() as u64,
            LogSource::Object { object, .. } => object.size,
        })
    }

    /// The metadata sidecar `<stem>.meta.toml` beside a CSV log: its name and, when it
    /// exists, its bytes.
    pub fn sidecar(&self) -> std::io::Result<(PathBuf, Option<Vec<u8>>)> {
        let name = self.name();
        let stem = name
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let side = name.with_file_name(format!("{stem}{}", crate::format::SIDECAR_SUFFIX));
        match self {
            LogSource::File(_) => match crate::input::read_limited(
                &side,
                crate::input::MAX_SIDECAR_BYTES,
                "metadata sidecar",
            ) {
                Ok(b) => Ok((side, Some(b))),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok((side, None)),
                Err(e) => Err(e),
            },
            LogSource::Object { object, .. } => match &object.sidecar {
                Some(k) => Ok((
                    side,
                    Some(object.bucket.get(k, crate::input::MAX_SIDECAR_BYTES)?),
                )),
                None => Ok((side, None)),
            },
            LogSource::Memory { sidecar, .. } => match sidecar {
                Some(b) if b.len() as u64 > crate::input::MAX_SIDECAR_BYTES => {
                    Err(std::io::Error::new(
                        std::io::ErrorKind::InvalidData,
                        format!(
                            "{} is {} bytes, over the {}-byte limit for a metadata sidecar",
                            side.display(),
                            b.len(),
                            crate::input::MAX_SIDECAR_BYTES
                        ),
                    ))
                }
                _ => Ok((side, sidecar.as_ref().map(|b| b.to_vec()))),
            },
        }
    }
}

/// Reads the log at `path` with the pipeline's ingest settings.
pub fn ingest_file(path: &Path, pipeline: &Pipeline) -> Result<RunLog, IngestError> {
    ingest_source(&LogSource::File(path.to_path_buf()), pipeline)
}

/// Largest log railgrip fetches from a bucket, bytes (as an archive member: 2 GiB).
pub const MAX_OBJECT_LOG_BYTES: u64 = 2 << 30;

/// Reads a log from a file, from memory (an archive member) or from a bucket with the
/// pipeline's ingest settings.
pub fn ingest_source(src: &LogSource, pipeline: &Pipeline) -> Result<RunLog, IngestError> {
    if let LogSource::Object { .. } = src {
        let fetched = src.fetched().map_err(|e| IngestError::Io {
            path: src.name().to_path_buf(),
            source: e,
        })?;
        return ingest_source(&fetched, pipeline);
    }
    let path = src.name();
    let cfg = &pipeline.ingest;
    let format = sniff(src)?;
    let (channels, metadata, start_log_time_ns, mut warnings) = match format {
        LogFormat::Csv => {
            let (channels, mut w) = csv::read(src, cfg)?;
            let (metadata, w_meta) = csv::read_sidecar(src)?;
            w.extend(w_meta);
            (channels, metadata, None, w)
        }
        LogFormat::Mcap => {
            let r = mcap::read(src, cfg)?;
            (r.channels, r.metadata, Some(r.t0_ns), r.warnings)
        }
    };
    let mut channels = channels;
    let checked: Vec<Result<Option<Warning>, IngestError>> = channels
        .par_iter_mut()
        .map(|ch| apply_plausibility(path, ch, cfg))
        .collect();
    for w in checked {
        warnings.extend(w?);
    }
    let dropped: Vec<usize> = channels.iter().map(|c| c.dropped).collect();
    let r = resample::resample(path, &channels, cfg)?;
    warnings.extend(r.warnings);
    let channel_summaries = channels
        .iter()
        .zip(r.stats)
        .map(|(ch, st)| ChannelSummary {
            signal: ch.signal,
            source: ch.source.clone(),
            samples: ch.values.len(),
            dropped: dropped[ch.signal.index()],
            rate_hz: st.rate_hz,
            max_step_s: st.max_step_s,
            min: st.min,
            max: st.max,
        })
        .collect();
    let mut columns = r.columns.into_iter();
    let mut next = || columns.next().expect("nine resampled columns");
    let v_radar_mps = next();
    let omega_radps = [next(), next(), next(), next()];
    let p_bar = [next(), next(), next(), next()];
    Ok(RunLog {
        source: path.to_path_buf(),
        format,
        sample_rate_hz: cfg.sample_rate_hz,
        time_s: r.time_s,
        v_radar_mps,
        omega_radps,
        p_bar,
        valid: r.valid,
        metadata,
        start_log_time_ns,
        channels: channel_summaries,
        gaps: r.gaps,
        warnings,
    })
}

/// Decides the format from the first bytes, never from the extension.
fn sniff(src: &LogSource) -> Result<LogFormat, IngestError> {
    let path = src.name();
    let mut f = src.open().map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => IngestError::NotFound {
            path: path.to_path_buf(),
        },
        _ => IngestError::Io {
            path: path.to_path_buf(),
            source: e,
        },
    })?;
    let mut head = [0u8; 4096];
    let mut n = 0;
    loop {
        let k = f.read(&mut head[n..]).map_err(|e| IngestError::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
        if k == 0 {
            break;
        }
        n += k;
        if n == head.len() {
            break;
        }
    }
    let head = &head[..n];
    if head.is_empty() {
        return Err(IngestError::Empty {
            path: path.to_path_buf(),
        });
    }
    if head.starts_with(::mcap::MAGIC) {
        return Ok(LogFormat::Mcap);
    }
    // Text: no NUL, valid UTF-8 (allowing a character cut at the end of the window), and a
    // first line with at least one comma.
    let text = match std::str::from_utf8(head) {
        Ok(t) => Some(t),
        Err(e) if e.error_len().is_none() => std::str::from_utf8(&head[..e.valid_up_to()]).ok(),
        Err(_) => None,
    };
    match text {
        Some(t) if !t.contains('\0') => {
            let first = t
                .trim_start_matches('\u{feff}')
                .lines()
                .next()
                .unwrap_or("");
            if first.contains(',') {
                Ok(LogFormat::Csv)
            } else {
                Err(IngestError::UnknownFormat {
                    path: path.to_path_buf(),
                    found: format!(
                        "text whose first line has no comma ({:?})",
                        first.chars().take(60).collect::<String>()
                    ),
                })
            }
        }
        _ => Err(IngestError::UnknownFormat {
            path: path.to_path_buf(),
            found: format!(
                "binary data starting with {}",
                head.iter()
                    .take(8)
                    .map(|b| format!("{b:02x}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            ),
        }),
    }
}

/// Applies the plausibility limits to a raw channel: with `warn`, out-of-limit samples become
/// NaN (missing) and are counted; with `error`, the first one is an error naming its place.
fn apply_plausibility(
    path: &Path,
    ch: &mut RawChannel,
    cfg: &IngestConfig,
) -> Result<Option<Warning>, IngestError> {
    let (lo, hi) = cfg.plausibility.limits(ch.signal);
    let mut first: Option<(usize, f64)> = None;
    let mut count = 0usize;
    for (i, v) in ch.values.iter_mut().enumerate() {
        if *v < lo || *v > hi {
            if first.is_none() {
                first = Some((i, *v));
            }
            if cfg.plausibility.action == PlausibilityAction::Error {
                break;
            }
            *v = f64::NAN;
            count += 1;
        }
    }
    let Some((i, value)) = first else {
        return Ok(None);
    };
    let unit = ch.signal.quantity().canonical().symbol();
    if cfg.plausibility.action == PlausibilityAction::Error {
        return Err(IngestError::Implausible {
            path: path.to_path_buf(),
            location: ch.locate.locate(i, &ch.time_s),
            signal: ch.signal,
            value,
            min: lo,
            max: hi,
            unit,
        });
    }
    ch.dropped = count;
    Ok(Some(Warning {
        kind: WarningKind::Implausible,
        message: format!(
            "{}: {count} sample(s) outside [{lo}, {hi}] {unit} dropped, the first {value} {unit} at {} (t = {:.3} s)",
            ch.signal,
            ch.locate.locate(i, &ch.time_s),
            ch.time_s[i]
        ),
    }))
}

/// Reads the sidecar-style key/values of a metadata table, typed.
pub(crate) fn metadata_from_pairs(
    path: &Path,
    source_name: &str,
    pairs: &BTreeMap<String, String>,
) -> Result<RunMetadata, IngestError> {
    RunMetadata::from_pairs(pairs).map_err(|e| IngestError::Metadata {
        path: path.to_path_buf(),
        source_name: source_name.to_string(),
        what: format!("{} = {:?} is not {}", e.key, e.value, e.expected),
        hint: format!("write {} as a plain number, e.g. {} = 5.0", e.key, e.key),
    })
}

/// Writes the run log as a Parquet table (`time_s`, the nine `*_<unit>` columns, `valid`), NaN
/// in gaps written as null. Atomic: the file appears complete or not at all.
pub fn write_runlog_parquet(log: &RunLog, out: &Path) -> Result<(), IngestError> {
    use polars::prelude::*;
    let mut cols: Vec<Column> = Vec::with_capacity(11);
    cols.push(
        Float64Chunked::from_vec(crate::format::RUNLOG_TIME_COLUMN.into(), log.time_s.clone())
            .into_column(),
    );
    for s in Signal::ALL {
        let ca: Float64Chunked = log
            .signal(s)
            .iter()
            .map(|v| v.is_finite().then_some(*v))
            .collect();
        cols.push(ca.with_name(s.runlog_column().into()).into_column());
    }
    cols.push(
        BooleanChunked::from_slice(crate::format::RUNLOG_VALID_COLUMN.into(), &log.valid)
            .into_column(),
    );
    let mut df = crate::table::frame(log.len(), cols, out)?;
    Ok(crate::table::write_parquet(&mut df, out, None)?)
}
