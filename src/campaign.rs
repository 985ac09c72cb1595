//! A test campaign end to end (`railgrip run`): find the runs under a folder, ingest, condition
//! and estimate each (independently: one bad file fails its own run, not the campaign), keep
//! what is unchanged since the last run, and write the per-run estimates and the summary.
//!
//! Output layout (every file written atomically):
//! - `<out>/runs/<run>/estimates.parquet` — the estimates table (README, "Estimates table");
//! - `<out>/runs/<run>/run.json` — the run's [`RunRecord`], with the SHA-256 of its inputs;
//! - `<out>/summary.csv`, `<out>/summary.parquet` — one row per run ([`SUMMARY_COLUMNS`]).
//!
//! A run is reused (not recomputed) when its `run.json` says `ok` for the same input hash —
//! SHA-256 over the log's bytes, its metadata sidecar's and the pipeline's text — and its
//! estimates table exists.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::format::AXLES;
use crate::identify::dataset::RunTable;
use crate::ingest::LogSource;
use crate::Pipeline;

/// What happened to one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    /// Name: the log's path below the campaign folder without extension, `/` → `__`.
    pub run: String,
    /// The log file.
    pub source: String,
    /// `ok` or `failed`.
    pub status: String,
    /// Why it failed (file, place and what to do, as the stage reported it).
    pub error: Option<String>,
    /// True when the outputs of an earlier run with the same inputs were kept.
    pub reused: bool,
    /// Time to ingest, condition, estimate and write, s (of the run that computed it).
    pub duration_s: f64,
    pub initial_speed_kmh: Option<f64>,
    pub ambient_temperature_c: Option<f64>,
    pub condition: Option<String>,
    /// Per axle 1..4 over valid samples (None when an axle has none).
    pub peak_mu: [Option<f64>; AXLES],
    pub max_dv_mps: [Option<f64>; AXLES],
    /// Ingest warnings and despiking, one line each.
    pub warnings: Vec<String>,
    /// SHA-256 of the log, its sidecar and the pipeline text.
    pub input_sha256: String,
}

/// The campaign as `railgrip run` left it (`<out>/campaign.json`): what `railgrip report`
/// rebuilds the report from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CampaignRecord {
    /// The campaign folder.
    pub archive: String,
    pub runs: Vec<RunRecord>,
    /// Rail condition the models were trained on.
    pub condition: Option<String>,
    /// Why no models were trained.
    pub model_error: Option<String>,
    pub notes: Vec<String>,
    /// Pipeline file name and its validation axles (seed 002 Fig. 10 uses the first).
    pub pipeline: String,
    pub validation_axles: Vec<u8>,
}

impl CampaignRecord {
    pub const FILE: &'static str = "campaign.json";

    /// Writes `<out>/campaign.json` atomically.
    pub fn write(&self, out: &Path) -> Result<PathBuf, CampaignError> {
        let path = out.join(Self::FILE);
        let text = serde_json::to_string_pretty(self).expect("records serialise") + "\n";
        crate::atomic::write_atomically(&path, |w| w.write_all(text.as_bytes())).map_err(|e| {
            CampaignError::Write {
                path: path.clone(),
                message: e.to_string(),
            }
        })?;
        Ok(path)
    }

    /// Reads `<out>/campaign.json`.
    pub fn read(out: &Path) -> Result<CampaignRecord, CampaignError> {
        let path = out.join(Self::FILE);
        let bad = |message: String| CampaignError::Input {
            path: path.clone(),
            message,
            hint: "give an output folder of `railgrip run` (it writes campaign.json)".into(),
        };
        let text = std::fs::read_to_string(&path).map_err(|e| bad(e.to_string()))?;
        serde_json::from_str(&text).map_err(|e| bad(format!("not a campaign record: {e}")))
    }
}

/// Columns of `summary.csv` / `summary.parquet`, in order.
pub const SUMMARY_COLUMNS: [&str; 17] = [
    "run",
    "status",
    "error",
    "reused",
    "duration_s",
    "initial_speed_kmh",
    "ambient_temperature_c",
    "condition",
    "peak_mu_1",
    "peak_mu_2",
    "peak_mu_3",
    "peak_mu_4",
    "max_dv_mps_1",
    "max_dv_mps_2",
    "max_dv_mps_3",
    "max_dv_mps_4",
    "warnings",
];

/// Why the campaign as a whole could not go on.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    #[error("{path}: {message}. Hint: {hint}")]
    Input {
        path: PathBuf,
        message: String,
        hint: String,
    },
    #[error("{path}: cannot write: {message}")]
    Write { path: PathBuf, message: String },
}

/// Log files (`.csv`, `.mcap`) below `root`, recursively, in path order; hidden entries and
/// `skip` (the output folder, when it lies inside) are left out.
pub fn discover(root: &Path, skip: Option<&Path>) -> Result<Vec<PathBuf>, CampaignError> {
    let bad = |path: &Path, e: std::io::Error| CampaignError::Input {
        path: path.to_path_buf(),
        message: e.to_string(),
        hint: "give a folder of braking-run logs (.csv with .meta.toml, .mcap)".into(),
    };
    let meta = std::fs::metadata(root).map_err(|e| bad(root, e))?;
    if !meta.is_dir() {
        return Err(CampaignError::Input {
            path: root.to_path_buf(),
            message: "not a folder".into(),
            hint: "give the folder that holds the campaign's logs".into(),
        });
    }
    let skip = skip.and_then(|s| s.canonicalize().ok());
    let mut found = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        if skip
            .as_ref()
            .is_some_and(|s| dir.canonicalize().ok().as_ref() == Some(s))
        {
            continue;
        }
        for entry in std::fs::read_dir(&dir).map_err(|e| bad(&dir, e))? {
            let entry = entry.map_err(|e| bad(&dir, e))?;
            let path = entry.path();
            if entry.file_name().to_string_lossy().starts_with('.') {
                continue;
            }
            let ft = entry.file_type().map_err(|e| bad(&path, e))?;
            if ft.is_dir() {
                stack.push(path);
            } else if path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("csv") || e.eq_ignore_ascii_case("mcap"))
            {
                found.push(path);
            }
        }
    }
    found.sort();
    Ok(found)
}

/// The run name of `path` below `root`: the relative path without extension, `/` → `__`,
/// characters outside `[A-Za-z0-9._-]` → `_`.
pub fn run_name(root: &Path, path: &Path) -> String {
    let rel = path.strip_prefix(root).unwrap_or(path).with_extension("");
    let parts: Vec<String> = rel
        .components()
        .map(|c| {
            c.as_os_str()
                .to_string_lossy()
                .chars()
                .map(|ch| {
                    if ch.is_ascii_alphanumeric() || "._-".contains(ch) {
                        ch
                    } else {
                        '_'
                    }
                })
                .collect()
        })
        .collect();
    parts.join("__")
}

/// SHA-256 (hex) over the log's bytes, its metadata sidecar's (when there is one) and the
/// pipeline text: what decides whether a run's outputs are still current. Also returns the
/// SHA-256 of the log alone (the model files' provenance).
pub fn input_hash(src: &LogSource, pipeline: &Pipeline) -> std::io::Result<(String, String)> {
    use std::io::Read as _;
    let hex = |d: &[u8]| d.iter().map(|b| format!("{b:02x}")).collect::<String>();
    // One streaming pass over the log feeds both hashes (no copy of a large file in memory).
    let (mut log, mut h) = (Sha256::new(), Sha256::new());
    let mut r = src.open()?;
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = r.read(&mut buf)?;
        if n == 0 {
            break;
        }
        log.update(&buf[..n]);
        h.update(&buf[..n]);
    }
    let log = hex(&log.finalize());
    h.update(b"\0sidecar\0");
    if let (_, Some(side)) = src.sidecar()? {
        h.update(side);
    }
    h.update(b"\0pipeline\0");
    h.update(pipeline.text.as_bytes());
    Ok((hex(&h.finalize()), log))
}

/// Processes one run into `<runs_dir>/<name>/`: reuses earlier outputs for the same inputs
/// unless `force`, else ingests, estimates and writes. Never fails as a whole: a failure is a
/// record with status `failed` (and no estimates table left behind).
pub fn process_run(
    src: &LogSource,
    name: &str,
    runs_dir: &Path,
    pipeline: &Pipeline,
    force: bool,
) -> (RunRecord, Option<RunTable>) {
    let t0 = Instant::now();
    let path = src.name();
    let dir = runs_dir.join(name);
    let record_path = dir.join("run.json");
    let table_path = dir.join("estimates.parquet");
    let mut rec = RunRecord {
        run: name.to_string(),
        source: path.display().to_string(),
        status: "failed".into(),
        error: None,
        reused: false,
        duration_s: 0.0,
        initial_speed_kmh: None,
        ambient_temperature_c: None,
        condition: None,
        peak_mu: [None; AXLES],
        max_dv_mps: [None; AXLES],
        warnings: vec![],
        input_sha256: String::new(),
    };
    let (hash, log_sha) = match input_hash(src, pipeline) {
        Ok(h) => h,
        Err(e) => {
            rec.error = Some(format!("{}: cannot read: {e}", path.display()));
            return (rec, None);
        }
    };
    rec.input_sha256 = hash.clone();
    if !force {
        let earlier = std::fs::read_to_string(&record_path)
            .ok()
            .and_then(|t| serde_json::from_str::<RunRecord>(&t).ok());
        if let Some(mut old) = earlier {
            if old.status == "ok" && old.input_sha256 == hash && table_path.exists() {
                if let Ok(mut table) = RunTable::read_parquet(&table_path) {
                    table.name = name.to_string();
                    table.source = rec.source.clone();
                    old.reused = true;
                    old.source = rec.source.clone();
                    return (old, Some(table));
                }
            }
        }
    }
    type AnyError = Box<dyn std::error::Error + Send + Sync>;
    let result = (|| -> Result<RunTable, AnyError> {
        let log = crate::ingest::ingest_source(src, pipeline)?;
        let e = crate::estimate::estimate(&log, pipeline)?;
        e.write_named(&dir, "estimates", false)?;
        rec.initial_speed_kmh = e.metadata.initial_speed_kmh;
        rec.ambient_temperature_c = e.metadata.ambient_temperature_c;
        rec.condition = e.metadata.condition.clone();
        for (a, s) in e.summary().iter().enumerate() {
            rec.peak_mu[a] = s.peak_mu.is_finite().then_some(s.peak_mu);
            rec.max_dv_mps[a] = s.max_dv_mps.is_finite().then_some(s.max_dv_mps);
        }
        rec.warnings = log.warnings.iter().map(|w| w.message.clone()).collect();
        if e.despiked > 0 {
            rec.warnings.push(format!(
                "{} radar sample(s) replaced by despiking",
                e.despiked
            ));
        }
        Ok(RunTable::from_estimates(name, &rec.source, &log_sha, &e))
    })();
    rec.duration_s = t0.elapsed().as_secs_f64();
    let table = match result {
        Ok(t) => {
            rec.status = "ok".into();
            Some(t)
        }
        Err(e) => {
            rec.error = Some(e.to_string());
            // No stale table that would look like this run's result.
            let _ = std::fs::remove_file(&table_path);
            None
        }
    };
    let text = serde_json::to_string_pretty(&rec).expect("records serialise") + "\n";
    let saved = std::fs::create_dir_all(&dir).and_then(|_| {
        crate::atomic::write_atomically(&record_path, |w| w.write_all(text.as_bytes()))
    });
    if let Err(e) = saved {
        rec.status = "failed".into();
        rec.error = Some(format!("{}: cannot write: {e}", record_path.display()));
        return (rec, None);
    }
    (rec, table)
}

/// Writes `summary.csv` and `summary.parquet` into `out`, one row per record.
pub fn write_summary(out: &Path, records: &[RunRecord]) -> Result<Vec<PathBuf>, CampaignError> {
    use polars::prelude::*;
    let s = |f: &dyn Fn(&RunRecord) -> Option<String>| -> Vec<Option<String>> {
        records.iter().map(f).collect()
    };
    let n = |f: &dyn Fn(&RunRecord) -> Option<f64>| -> Vec<Option<f64>> {
        records.iter().map(f).collect()
    };
    let mut cols: Vec<Column> = vec![
        Column::new("run".into(), s(&|r| Some(r.run.clone()))),
        Column::new("status".into(), s(&|r| Some(r.status.clone()))),
        Column::new("error".into(), s(&|r| r.error.clone())),
        Column::new(
            "reused".into(),
            records.iter().map(|r| r.reused).collect::<Vec<bool>>(),
        ),
        Column::new("duration_s".into(), n(&|r| Some(r.duration_s))),
        Column::new("initial_speed_kmh".into(), n(&|r| r.initial_speed_kmh)),
        Column::new(
            "ambient_temperature_c".into(),
            n(&|r| r.ambient_temperature_c),
        ),
        Column::new("condition".into(), s(&|r| r.condition.clone())),
    ];
    for a in 0..AXLES {
        cols.push(Column::new(
            format!("peak_mu_{}", a + 1).into(),
            n(&|r| r.peak_mu[a]),
        ));
    }
    for a in 0..AXLES {
        cols.push(Column::new(
            format!("max_dv_mps_{}", a + 1).into(),
            n(&|r| r.max_dv_mps[a]),
        ));
    }
    cols.push(Column::new(
        "warnings".into(),
        s(&|r| Some(r.warnings.join("; "))),
    ));
    let werr = |path: &Path| {
        let path = path.to_path_buf();
        move |e: std::io::Error| CampaignError::Write {
            path: path.clone(),
            message: e.to_string(),
        }
    };
    let mut df = DataFrame::new(records.len(), cols).map_err(|e| CampaignError::Write {
        path: out.join("summary.parquet"),
        message: e.to_string(),
    })?;
    let csv = out.join("summary.csv");
    crate::atomic::write_atomically(&csv, |f| {
        CsvWriter::new(f)
            .include_header(true)
            .finish(&mut df)
            .map_err(std::io::Error::other)
    })
    .map_err(werr(&csv))?;
    let pq = out.join("summary.parquet");
    crate::atomic::write_atomically(&pq, |f| {
        ParquetWriter::new(f)
            .with_compression(ParquetCompression::Zstd(None))
            .finish(&mut df)
            .map(|_| ())
            .map_err(std::io::Error::other)
    })
    .map_err(werr(&pq))?;
    Ok(vec![csv, pq])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_names_are_flat_and_safe() {
        let root = Path::new("/c");
        assert_eq!(run_name(root, Path::new("/c/a.csv")), "a");
        assert_eq!(
            run_name(root, Path::new("/c/day 1/run+2.mcap")),
            "day_1__run_2"
        );
    }
}
