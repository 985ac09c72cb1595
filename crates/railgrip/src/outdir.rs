//! A campaign's output folder: where every output goes (every path below the folder is
//! spelled here and nowhere else) and the records that describe its runs ([`RunRecord`],
//! `run.json`) and the whole campaign ([`CampaignRecord`], `campaign.json`). The campaign
//! writes them, the report reads them.
//!
//! ```text
//! <out>/runs/<run>/estimates.parquet   the run's estimates table (docs/input-logs.md#estimates-table)
//! <out>/runs/<run>/run.json            its RunRecord, with the SHA-256 of its inputs
//! <out>/summary.csv, summary.parquet   one row per run (SUMMARY_COLUMNS)
//! <out>/models/                        mlp.json, mlp.h, mlp.history.csv, mlp.polach.json,
//!                                      mlp.polach.h, mlp.polach-fits.json (ModelPaths)
//! <out>/campaign.json                  the CampaignRecord the report is rebuilt from
//! <out>/report/index.html              the validation report
//! ```

use std::io::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::format::AXLES;

/// A record file that could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error(
        "{path}: {source}. Hint: give an output folder of `railgrip run` (it writes campaign.json)"
    )]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not a campaign record: {source}. Hint: rerun `railgrip run` to rewrite it")]
    Parse {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// The output folder of `railgrip run`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutDir {
    root: PathBuf,
}

impl OutDir {
    pub fn new(root: impl Into<PathBuf>) -> OutDir {
        OutDir { root: root.into() }
    }
    pub fn root(&self) -> &Path {
        &self.root
    }
    /// The folder of per-run outputs.
    pub fn runs(&self) -> PathBuf {
        self.root.join("runs")
    }
    /// The folder of one run's outputs.
    pub fn run_dir(&self, run: &str) -> PathBuf {
        self.runs().join(run)
    }
    pub fn run_record(&self, run: &str) -> PathBuf {
        self.run_dir(run).join("run.json")
    }
    /// The run's estimates table; its stem is [`OutDir::ESTIMATES_STEM`].
    pub fn run_estimates(&self, run: &str) -> PathBuf {
        self.run_dir(run)
            .join(format!("{}.parquet", Self::ESTIMATES_STEM))
    }
    pub const ESTIMATES_STEM: &'static str = "estimates";
    /// The run's `<run>.railgrip.mcap` (estimates and model replay for Foxglove).
    pub fn run_replay(&self, run: &str) -> PathBuf {
        self.run_dir(run).join(format!("{run}.railgrip.mcap"))
    }
    pub fn summary_csv(&self) -> PathBuf {
        self.root.join("summary.csv")
    }
    pub fn summary_parquet(&self) -> PathBuf {
        self.root.join("summary.parquet")
    }
    pub fn campaign_record(&self) -> PathBuf {
        self.root.join("campaign.json")
    }
    /// The campaign's model files (name `mlp`).
    pub fn models(&self) -> ModelPaths {
        ModelPaths::new(self.root.join("models"), "mlp")
    }
    pub fn timings(&self) -> PathBuf {
        self.root.join("timings.json")
    }
    pub fn report_dir(&self) -> PathBuf {
        self.root.join("report")
    }
    pub fn report_html(&self) -> PathBuf {
        self.report_dir().join("index.html")
    }
}

/// The files of one set of models named `name` in `dir` (`railgrip train --out DIR --name
/// NAME`, or a campaign's `models/` with name `mlp`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelPaths {
    pub dir: PathBuf,
    pub name: String,
}

impl ModelPaths {
    pub fn new(dir: impl Into<PathBuf>, name: &str) -> ModelPaths {
        ModelPaths {
            dir: dir.into(),
            name: name.to_string(),
        }
    }
    fn file(&self, suffix: &str) -> PathBuf {
        self.dir.join(format!("{}{suffix}", self.name))
    }
    /// The network model file.
    pub fn mlp(&self) -> PathBuf {
        self.file(".json")
    }
    /// Its C header (symbol prefix [`ModelPaths::mlp_prefix`]).
    pub fn mlp_header(&self) -> PathBuf {
        self.file(".h")
    }
    pub fn history_csv(&self) -> PathBuf {
        self.file(".history.csv")
    }
    /// The Polach model file.
    pub fn polach(&self) -> PathBuf {
        self.file(".polach.json")
    }
    /// Its C header (symbol prefix [`ModelPaths::polach_prefix`]).
    pub fn polach_header(&self) -> PathBuf {
        self.file(".polach.h")
    }
    /// Every Polach fit (pooled, per run, per temperature) and k(T).
    pub fn polach_fits(&self) -> PathBuf {
        self.file(".polach-fits.json")
    }
    /// Leave-one-run-out scores of the network (JSON: a list of {run, samples, rmse_mu}).
    pub fn leave_one_run_out(&self) -> PathBuf {
        self.file(".leave-one-run-out.json")
    }
    /// The model choice: every candidate's held-out scores and the chosen one.
    pub fn choice(&self) -> PathBuf {
        self.file(".choice.json")
    }
    /// The file tag of model-choice candidate `candidate` other than `mlp` and `polach`
    /// (`mlp_3in` → `3in`, `residual` → `residual`).
    fn tag(candidate: &str) -> &str {
        candidate.strip_prefix("mlp_").unwrap_or(candidate)
    }
    /// The model file of candidate `candidate` (`mlp`: [`ModelPaths::mlp`], `polach`:
    /// [`ModelPaths::polach`], others `<name>.<tag>.json`).
    pub fn candidate(&self, candidate: &str) -> PathBuf {
        match candidate {
            "mlp" => self.mlp(),
            "polach" => self.polach(),
            c => self.file(&format!(".{}.json", Self::tag(c))),
        }
    }
    /// The C header of candidate `candidate`.
    pub fn candidate_header(&self, candidate: &str) -> PathBuf {
        match candidate {
            "mlp" => self.mlp_header(),
            "polach" => self.polach_header(),
            c => self.file(&format!(".{}.h", Self::tag(c))),
        }
    }
    /// The C symbol prefix of candidate `candidate`.
    pub fn candidate_prefix(&self, candidate: &str) -> String {
        match candidate {
            "mlp" => self.mlp_prefix(),
            "polach" => self.polach_prefix(),
            c => format!("{}_{}", self.name, Self::tag(c)),
        }
    }
    pub fn mlp_prefix(&self) -> String {
        self.name.clone()
    }
    pub fn polach_prefix(&self) -> String {
        format!("{}_polach", self.name)
    }
}

/// How a run ended (`"ok"` / `"failed"` in `run.json`, `campaign.json` and the summary).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RunStatus {
    Ok,
    Failed,
}

impl RunStatus {
    pub fn as_str(self) -> &'static str {
        match self {
            RunStatus::Ok => "ok",
            RunStatus::Failed => "failed",
        }
    }
}

/// What happened to one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    /// Name: the log's path below the campaign folder without extension, `/` → `__`.
    pub run: String,
    /// The log file.
    pub source: String,
    pub status: RunStatus,
    /// Why it failed (file, place and what to do, as the stage reported it).
    pub error: Option<String>,
    /// True when the outputs of an earlier run with the same inputs were kept. Not written
    /// (how this invocation got the run, like its time, is in `timings.json`).
    #[serde(default, skip_serializing)]
    pub reused: bool,
    /// Time to ingest, condition, estimate and write, s (of the run that computed it). Not
    /// written to `run.json`/`campaign.json` (the same inputs give the same bytes);
    /// `timings.json` has it.
    #[serde(default, skip_serializing)]
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
    /// Log time of the run's t = 0, ns (MCAP logs), for the replay MCAP's time base.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_log_time_ns: Option<u64>,
}

impl RunRecord {
    pub fn ok(&self) -> bool {
        self.status == RunStatus::Ok
    }
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
    /// Files of the campaign that are not logs, with why (absent in files of older versions).
    #[serde(default)]
    pub skipped: Vec<Skipped>,
    /// This campaign generation: the first 16 hex digits of SHA-256 over the pipeline text
    /// and every run's name, status and input hash ([`generation_id`]). The model files, the
    /// fits and scores files carry it; the report reads only files of its generation.
    #[serde(default)]
    pub generation: Option<String>,
    /// The campaign's model, `models/<file>` (the candidate `train.model` chose; absent when no
    /// model was trained and in files of older versions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chosen_model: Option<String>,
    /// The calibration the runs were estimated with (`estimate.calibration` "campaign" or
    /// "dry-run"; absent for "pipeline").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<crate::config::calibrated::Calibrated>,
}

/// The generation id of a campaign with `pipeline_text` and these runs (see
/// [`CampaignRecord::generation`]): the same inputs give the same id, so outputs stay
/// byte-identical between identical runs.
pub fn generation_id(pipeline_text: &str, runs: &[RunRecord]) -> String {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    h.update(pipeline_text.as_bytes());
    for r in runs {
        h.update(b"\0run\0");
        h.update(r.run.as_bytes());
        h.update(b"\0");
        h.update(r.status.as_str().as_bytes());
        h.update(b"\0");
        h.update(r.input_sha256.as_bytes());
    }
    crate::hash::hex(&h.finalize())[..16].to_string()
}

/// `<out>/timings.json`: how this invocation of `railgrip run` went — when, how long each
/// stage and run took, which runs were reused. Kept out of the result files so that the same
/// inputs give the same bytes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    pub generation: String,
    /// UTC, RFC 3339 (`SOURCE_DATE_EPOCH` overrides the clock).
    pub finished: String,
    pub jobs: usize,
    /// Wall time per stage and in total, s.
    pub stages: Vec<(String, f64)>,
    pub runs: Vec<RunTiming>,
    /// Network training: epochs and seconds.
    pub train_epochs: usize,
    pub train_s: Option<f64>,
    /// The campaign's calibration was the output folder's `calibration.json`, fitted on the
    /// same inputs (not fitted again).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub calibration_reused: bool,
}

/// One run's line in [`Timings`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunTiming {
    pub run: String,
    pub reused: bool,
    /// Of the invocation that computed it (a reused run keeps none).
    pub duration_s: Option<f64>,
}

impl Timings {
    /// Writes `<out>/timings.json` atomically.
    pub fn write(&self, out: &OutDir) -> Result<PathBuf, RecordError> {
        write_json(out.timings(), self)
    }
}

/// Writes `value` as pretty JSON to `path`, atomically.
fn write_json(path: PathBuf, value: &impl Serialize) -> Result<PathBuf, RecordError> {
    let text = serde_json::to_string_pretty(value).expect("records serialise") + "\n";
    crate::atomic::write_atomically(&path, |w| w.write_all(text.as_bytes())).map_err(|source| {
        RecordError::Write {
            path: path.clone(),
            source,
        }
    })?;
    Ok(path)
}

/// A file in a campaign that is not a run, and why.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Skipped {
    /// Below the campaign folder (or the member path in an archive).
    pub path: std::path::PathBuf,
    pub reason: String,
}

impl CampaignRecord {
    /// Writes `<out>/campaign.json` atomically.
    pub fn write(&self, out: &OutDir) -> Result<PathBuf, RecordError> {
        write_json(out.campaign_record(), self)
    }

    /// Reads `<out>/campaign.json`.
    pub fn read(out: &OutDir) -> Result<CampaignRecord, RecordError> {
        let path = out.campaign_record();
        let text = std::fs::read_to_string(&path).map_err(|source| RecordError::Read {
            path: path.clone(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|source| RecordError::Parse { path, source })
    }
}

/// Paths of a study's outputs below its folder (`railgrip study --out`): `study.json`,
/// `study.csv`, `study.html`, `cells/<key>.json` and `.model.json`, and the estimates of each
/// conditioning as a campaign output folder `conditioning/<hash>/`.
pub struct StudyPaths {
    pub root: PathBuf,
}

impl StudyPaths {
    pub fn cells(&self) -> PathBuf {
        self.root.join("cells")
    }
    pub fn cell(&self, key: &str) -> PathBuf {
        self.cells().join(format!("{key}.json"))
    }
    pub fn cell_model(&self, key: &str) -> PathBuf {
        self.cells().join(format!("{key}.model.json"))
    }
    pub fn conditioning(&self, key: &str) -> PathBuf {
        self.root.join("conditioning").join(key)
    }
    pub fn json(&self) -> PathBuf {
        self.root.join("study.json")
    }
    pub fn csv(&self) -> PathBuf {
        self.root.join("study.csv")
    }
    pub fn html(&self) -> PathBuf {
        self.root.join("study.html")
    }
}

/// UTC time as RFC 3339 (`SOURCE_DATE_EPOCH` overrides the clock, for reproducible files).
pub fn utc_now_rfc3339() -> String {
    let secs = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|s| s.trim().parse::<i64>().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs() as i64)
                .unwrap_or(0)
        });
    let days = secs.div_euclid(86_400);
    let rem = secs.rem_euclid(86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_the_documented_ones() {
        let o = OutDir::new("/o");
        assert_eq!(
            o.run_estimates("r"),
            Path::new("/o/runs/r/estimates.parquet")
        );
        assert_eq!(o.run_record("r"), Path::new("/o/runs/r/run.json"));
        assert_eq!(o.report_html(), Path::new("/o/report/index.html"));
        let m = o.models();
        assert_eq!(m.polach_header(), Path::new("/o/models/mlp.polach.h"));
        assert_eq!(m.polach_fits(), Path::new("/o/models/mlp.polach-fits.json"));
        assert_eq!(m.polach_prefix(), "mlp_polach");
    }

    #[test]
    fn rfc3339_dates() {
        std::env::set_var("SOURCE_DATE_EPOCH", "1763692800");
        assert_eq!(utc_now_rfc3339(), "2025-11-21T02:40:00Z");
        std::env::set_var("SOURCE_DATE_EPOCH", "951782400");
        assert_eq!(utc_now_rfc3339(), "2000-02-29T00:00:00Z");
        std::env::remove_var("SOURCE_DATE_EPOCH");
    }
}
