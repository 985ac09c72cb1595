//! The per-run stage of a campaign: find the logs, then for each run, independently (one bad
//! file fails its own run, not the campaign), reuse what is unchanged since the last run or
//! ingest, condition, estimate and write its estimates table and record.
//!
//! A run is reused (not recomputed) when its `run.json` says `ok` for the same input hash —
//! SHA-256 over the log's bytes, its metadata sidecar's and the pipeline's text — and its
//! estimates table exists.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use sha2::{Digest, Sha256};

use super::{CampaignError, OutDir, RunRecord, RunStatus};
use crate::config::Pipeline;
use crate::format::AXLES;
use crate::identify::dataset::RunTable;
use crate::ingest::LogSource;

/// Log files (`.csv`, `.mcap`) below `root`, recursively, in path order; hidden entries and
/// `skip` (the output folder, when it lies inside) are left out.
pub fn discover(root: &Path, skip: Option<&Path>) -> Result<Vec<PathBuf>, CampaignError> {
    Ok(discover_all(root, skip)?.0)
}

/// [`discover`], and every other file below `root` with why it is not a log (a
/// `random.bin` in a campaign was skipped without a word). Hidden entries (`.name`) and the
/// output folder are left out silently; a metadata sidecar beside its log is part of the log.
pub fn discover_all(
    root: &Path,
    skip: Option<&Path>,
) -> Result<(Vec<PathBuf>, Vec<super::Skipped>), CampaignError> {
    let bad = |path: &Path, source: std::io::Error| CampaignError::Read {
        path: path.to_path_buf(),
        source,
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
    let mut files = Vec::new();
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
            } else {
                files.push(path);
            }
        }
    }
    Ok(classify(root, files))
}

/// Splits a campaign's files (hidden entries already left out) into its logs (`.csv`,
/// `.mcap`, in path order) and the files that are not logs with why; a metadata sidecar
/// beside its log and a simulated run's truth table beside its log belong to the run.
pub(crate) fn classify(root: &Path, files: Vec<PathBuf>) -> (Vec<PathBuf>, Vec<super::Skipped>) {
    let (mut found, mut others): (Vec<PathBuf>, Vec<PathBuf>) = files.into_iter().partition(|p| {
        p.extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv") || e.eq_ignore_ascii_case("mcap"))
    });
    found.sort();
    others.sort();
    let is_log = |p: &Path| found.binary_search(&p.to_path_buf()).is_ok();
    let skipped = others
        .into_iter()
        .filter_map(|path| {
            let name = path.file_name()?.to_string_lossy().into_owned();
            let reason = match name
                .to_ascii_lowercase()
                .strip_suffix(crate::format::SIDECAR_SUFFIX)
            {
                Some(_) => {
                    let stem = &name[..name.len() - crate::format::SIDECAR_SUFFIX.len()];
                    let log = path.with_file_name(format!("{stem}.csv"));
                    if is_log(&log) {
                        return None;
                    }
                    format!("a metadata sidecar without its log ({stem}.csv is not beside it)")
                }
                None => {
                    // A simulated run's truth table beside its log belongs to the run.
                    let lower = name.to_ascii_lowercase();
                    if let Some(stem) = lower
                        .strip_suffix(crate::format::TRUTH_SUFFIX)
                        .map(|_| &name[..name.len() - crate::format::TRUTH_SUFFIX.len()])
                    {
                        if ["csv", "mcap"]
                            .iter()
                            .any(|e| is_log(&path.with_file_name(format!("{stem}.{e}"))))
                        {
                            return None;
                        }
                    }
                    "not a .csv or .mcap log".to_string()
                }
            };
            Some(super::Skipped {
                path: path.strip_prefix(root).unwrap_or(&path).to_path_buf(),
                reason,
            })
        })
        .collect();
    (found, skipped)
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

/// Streams `src`'s log into `h`, then `\0sidecar\0` and its sidecar (if any); returns the log's
/// own SHA-256 (hex). What a run's reuse key and a campaign's calibration key hash of a log.
pub(crate) fn hash_log_and_sidecar(src: &LogSource, h: &mut Sha256) -> std::io::Result<String> {
    let log = crate::hash::sha256_stream(src.open()?, &mut [h])?;
    h.update(b"\0sidecar\0");
    if let (_, Some(side)) = src.sidecar()? {
        h.update(side);
    }
    Ok(log)
}

/// SHA-256 (hex) over the log's bytes, its metadata sidecar's (when there is one), the
/// pipeline text and the calibration it carries (if any): what decides whether a run's outputs are still current. Also returns the
/// SHA-256 of the log alone (the model files' provenance). One streaming pass over the log.
pub fn input_hash(src: &LogSource, pipeline: &Pipeline) -> std::io::Result<(String, String)> {
    let mut h = Sha256::new();
    let log = hash_log_and_sidecar(src, &mut h)?;
    h.update(b"\0pipeline\0");
    h.update(pipeline.text.as_bytes());
    if let Some(c) = &pipeline.calibrated {
        h.update(b"\0calibration\0");
        h.update(
            serde_json::to_string(&c.corrections)
                .expect("a calibration serialises")
                .as_bytes(),
        );
    }
    Ok((crate::hash::hex(&h.finalize()), log))
}

/// Why a run could not be estimated (becomes its record's `error`).
#[derive(Debug, thiserror::Error)]
enum RunError {
    #[error(transparent)]
    Ingest(#[from] crate::ingest::IngestError),
    #[error(transparent)]
    Estimate(#[from] crate::estimate::EstimateError),
}

/// Processes one run into `out`'s folder for `name`: reuses earlier outputs for the same
/// inputs unless `force`, else ingests, estimates and writes. Never fails as a whole: a failure
/// is a record with status failed (and no estimates table left behind).
pub fn process_run(
    src: &LogSource,
    name: &str,
    out: &OutDir,
    pipeline: &Pipeline,
    force: bool,
) -> (RunRecord, Option<RunTable>) {
    let t0 = Instant::now();
    let mut rec = new_record(src, name);
    // A log in a bucket is fetched once, here, for the hash and the estimation.
    let hashed = src
        .fetched()
        .and_then(|s| input_hash(&s, pipeline).map(|h| (s, h)));
    let (src, (hash, log_sha)) = match hashed {
        Ok(x) => x,
        Err(e) => {
            rec.error = Some(format!("{}: cannot read: {e}", src.name().display()));
            return (rec, None);
        }
    };
    let src = &src;
    rec.input_sha256 = hash;
    if !force {
        if let Some(reused) = reuse(&rec, name, out, &log_sha) {
            return reused;
        }
    }
    let result = estimate_run(src, name, out, pipeline, &mut rec, &log_sha);
    rec.duration_s = t0.elapsed().as_secs_f64();
    let table = match result {
        Ok(t) => {
            rec.status = RunStatus::Ok;
            Some(t)
        }
        Err(e) => {
            rec.error = Some(e.to_string());
            // No stale table that would look like this run's result.
            let _ = std::fs::remove_file(out.run_estimates(name));
            None
        }
    };
    let record_path = out.run_record(name);
    let text = serde_json::to_string_pretty(&rec).expect("records serialise") + "\n";
    let saved = std::fs::create_dir_all(out.run_dir(name)).and_then(|_| {
        crate::atomic::write_atomically(&record_path, |w| w.write_all(text.as_bytes()))
    });
    if let Err(e) = saved {
        rec.status = RunStatus::Failed;
        rec.error = Some(format!("{}: cannot write: {e}", record_path.display()));
        return (rec, None);
    }
    (rec, table)
}

/// A run's record before anything is known: failed, no figures.
fn new_record(src: &LogSource, name: &str) -> RunRecord {
    failed_record(name, &src.name().display().to_string(), None)
}

/// The record of run `name` (log `source`) that failed for `error` before anything was known
/// of it: no figures. A scheduler's own failure (a task that never finished) is such a run.
pub fn failed_record(name: &str, source: &str, error: Option<String>) -> RunRecord {
    RunRecord {
        run: name.to_string(),
        source: source.to_string(),
        status: RunStatus::Failed,
        error,
        reused: false,
        duration_s: 0.0,
        initial_speed_kmh: None,
        ambient_temperature_c: None,
        condition: None,
        peak_mu: [None; AXLES],
        max_dv_mps: [None; AXLES],
        warnings: vec![],
        input_sha256: String::new(),
        start_log_time_ns: None,
    }
}

/// What an estimate shard wrote for run `name` ([`super::Part::Models`]): its record and
/// (for a run that succeeded) its table, when the record is for the run's current inputs —
/// the log, its sidecar and the pipeline, by hash. A run that failed in its shard is its
/// failed record, as [`process_run`] would make it. Else why not: missing or stale.
pub fn recall_run(
    src: &LogSource,
    name: &str,
    out: &OutDir,
    pipeline: &Pipeline,
) -> Result<(RunRecord, Option<RunTable>), String> {
    let (hash, log_sha) = match src.fetched().and_then(|s| input_hash(&s, pipeline)) {
        Ok(h) => h,
        // As in one run: a log that cannot be read is its run's failed record (one run writes
        // no record for it either).
        Err(e) => {
            let mut rec = new_record(src, name);
            rec.error = Some(format!("{}: cannot read: {e}", src.name().display()));
            return Ok((rec, None));
        }
    };
    let path = out.run_record(name);
    let text = std::fs::read_to_string(&path).map_err(|_| "not estimated".to_string())?;
    let mut old: RunRecord = serde_json::from_str(&text)
        .map_err(|e| format!("{}: unreadable record: {e}", path.display()))?;
    if old.input_sha256 != hash {
        return Err(
            "stale: its log, sidecar or the pipeline changed since it was estimated".into(),
        );
    }
    let now = RunRecord {
        input_sha256: hash,
        source: src.name().display().to_string(),
        ..old.clone()
    };
    if !old.ok() {
        old.source = now.source;
        old.reused = true;
        return Ok((old, None));
    }
    reuse(&now, name, out, &log_sha).ok_or_else(|| {
        format!(
            "{}: its estimates table does not read back",
            out.run_estimates(name).display()
        )
    })
}

/// The earlier outputs of run `name` when its record says ok for the same input hash and its
/// estimates table reads back. The table's provenance is the log's SHA-256 `log_sha` (not the
/// estimates table's own hash, which a reused run once carried).
fn reuse(
    now: &RunRecord,
    name: &str,
    out: &OutDir,
    log_sha: &str,
) -> Option<(RunRecord, Option<RunTable>)> {
    let text = std::fs::read_to_string(out.run_record(name)).ok()?;
    let mut old: RunRecord = serde_json::from_str(&text).ok()?;
    let table_path = out.run_estimates(name);
    if !(old.ok() && old.input_sha256 == now.input_sha256 && table_path.exists()) {
        return None;
    }
    let mut table = RunTable::read_parquet(&table_path).ok()?;
    table.name = name.to_string();
    table.source = now.source.clone();
    table.sha256 = log_sha.to_string();
    old.reused = true;
    old.source = now.source.clone();
    Some((old, Some(table)))
}

/// Ingests, estimates and writes run `name`, filling `rec`'s figures; the run's table for the
/// models, with `log_sha` as its provenance.
fn estimate_run(
    src: &LogSource,
    name: &str,
    out: &OutDir,
    pipeline: &Pipeline,
    rec: &mut RunRecord,
    log_sha: &str,
) -> Result<RunTable, RunError> {
    let log = crate::ingest::ingest_source(src, pipeline)?;
    let e = crate::estimate::estimate(&log, pipeline)?;
    e.write_named(&out.run_dir(name), OutDir::ESTIMATES_STEM, false)?;
    rec.initial_speed_kmh = e.metadata.initial_speed_kmh;
    rec.start_log_time_ns = log.start_log_time_ns;
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
    Ok(RunTable::from_estimates(name, &rec.source, log_sha, &e))
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
