//! The campaign's calibration stage, before its runs are estimated, when the pipeline asks
//! for one (`estimate.calibration`):
//! - "campaign": every run is conditioned once more for the pooled balance of
//!   [`crate::estimate::selfcal`] (per-axle α, the pad friction's speed law, the running
//!   resistance, the radar's scale and latency, the tachometers' delay);
//! - "dry-run": one α for all axles from each run's full-adhesion samples
//!   ([`crate::estimate::calibrate`]), pooled over the runs where that fit succeeds
//!   (inverse-variance weights), the radar trusted.
//!
//! The estimates then depend on the whole campaign: the flow is calibrate → estimate, and a
//! run's reuse key includes the calibration. The result is written as `calibration.json` in
//! the output folder; a scheduler's estimate shards and models part are given that file
//! (`--calibration`), and refuse one fitted on other runs or with another pipeline file.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::{CampaignError, Options};
use crate::config::calibrated::{Calibrated, Corrections, Errors, PadLaw};
use crate::config::{CalibrationSource, Pipeline};
use crate::estimate::calibrate::{calibrate, AlphaFit, Resistance};
use crate::estimate::selfcal::{CampaignCalibration, CampaignCalibrator, MIN_RUNS};
use crate::format::AXLES;
use crate::ingest::LogSource;

/// One run's α and its standard error (N·m/bar), or why the run gives none.
type RunAlpha = Result<(f64, f64), String>;

/// The calibration file's name in the output folder.
pub const CALIBRATION_FILE: &str = "calibration.json";

/// `calibration.json`: what the estimation applies, and the fit behind it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CalibrationRecord {
    pub calibrated: Calibrated,
    /// `[vehicle]`'s α, N·m/bar: what the calibrated α replace (their ratio is the calibration's
    /// effect on each axle's brake force, so on μ).
    pub pipeline_alpha_nm_per_bar: [f64; AXLES],
    /// The campaign's self-calibration ("campaign").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub campaign: Option<CampaignCalibration>,
    /// The pooled full-adhesion fit ("dry-run").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dry_run: Option<DryRunFit>,
    /// What could not be calibrated, runs left out and why.
    pub notes: Vec<String>,
    /// SHA-256 over railgrip's version and the calibration's method, the pipeline file's text and
    /// every run's name, log and sidecar, in the campaign's order ([`campaign_inputs_sha256`]):
    /// a whole campaign run again with the same inputs reuses this record instead of fitting it
    /// again (empty in files of older versions: never reused).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub inputs_sha256: String,
}

/// The calibration's method and record, for [`campaign_inputs_sha256`]: changed with either.
const CALIBRATION_METHOD: &str =
    "calibration 7 (per-run constants; pooled errors over τ; coefficients from the balance integrated over time; five pad forms and two mixtures; errors in the record; α errors carry the delays' and the scale's; CSV cells without a value are missing samples; the radar's noise and the residual over it)\0";

/// The SHA-256 (hex) of what a campaign's calibration depends on: railgrip's version and the
/// calibration's method ([`CALIBRATION_METHOD`]), the pipeline file's text and, in the
/// campaign's order, every run's name, log bytes and sidecar (as a run's reuse key has them).
/// A run that cannot be read hashes its error, so it never matches a readable one. Reads every
/// log once more (for a bucket, fetches it).
pub fn campaign_inputs_sha256(logs: &[(String, LogSource)], pipeline: &Pipeline) -> String {
    let mut h = Sha256::new();
    h.update(concat!("railgrip ", env!("CARGO_PKG_VERSION"), "\0").as_bytes());
    // What a calibration record holds beyond the crate's version: a record written before its
    // method or fields changed is fitted again rather than reused.
    h.update(CALIBRATION_METHOD.as_bytes());
    h.update(b"pipeline\0");
    h.update(pipeline.text.as_bytes());
    for (name, src) in logs {
        h.update(b"\0run\0");
        h.update(name.as_bytes());
        h.update(b"\0");
        // A log that fails part-way hashes what it gave and then its error.
        if let Err(e) = src
            .fetched()
            .and_then(|s| super::runs::hash_log_and_sidecar(&s, &mut h))
        {
            h.update(format!("\0unreadable: {e}").as_bytes());
        }
    }
    crate::hash::hex(&h.finalize())
}

/// One α from the runs' full-adhesion samples.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DryRunFit {
    /// Pooled α, N·m/bar, and its standard error.
    pub alpha_nm_per_bar: f64,
    pub alpha_se: f64,
    /// (run, α, se) of each run the fit succeeded on.
    pub runs: Vec<(String, f64, f64)>,
}

/// SHA-256 (hex) of the pipeline file's text.
pub fn pipeline_sha256(pipeline: &Pipeline) -> String {
    crate::hash::hex(&Sha256::digest(pipeline.text.as_bytes()))
}

/// The source of a record saying that "auto" fitted no calibration ([`Calibrated::source`]).
pub const NONE_SOURCE: &str = "none";

/// What [`calibrated_pipeline`] gives: the pipeline the runs are estimated with and how it came
/// to be.
#[derive(Debug)]
pub struct CampaignCalibrated {
    /// The pipeline, carrying the calibration when one applies.
    pub pipeline: Pipeline,
    /// The record fitted (or reused) here — for "auto" without a calibration, the record that
    /// says so ([`NONE_SOURCE`]); None when the pipeline asks for none or one was given.
    pub record: Option<CalibrationRecord>,
    /// Whether `record` is `previous`, reused.
    pub reused: bool,
    /// Why a pipeline with "auto" estimates with its own values, for the report.
    pub note: Option<String>,
}

/// The pipeline the campaign's runs are estimated with: `pipeline` as it is when it asks for
/// no calibration; with a given calibration checked against the campaign; else, for a whole
/// campaign (`compute`), with the calibration fitted here (and its record). A part of a
/// scheduled campaign (`compute` false) must be given it; `whole`: `logs` are every run of the
/// campaign (not one task's run alone). `previous`: an earlier `calibration.json` of this
/// output folder, reused instead of fitting again when it was fitted on the same inputs (the
/// pipeline file and every run's log and sidecar, by hash) — as unchanged runs' estimates are.
///
/// "auto" is "campaign" but where the campaign's calibration cannot be fitted (fewer than
/// [`MIN_RUNS`] runs with samples for the balance, or a fit that fails): the pipeline as it
/// is, with a note saying why, and a record of that ([`NONE_SOURCE`]) for the later parts of a
/// scheduled campaign. A part given no calibration at all keeps the pipeline as it is where
/// fewer than [`MIN_RUNS`] runs are listed (one task's run alone).
pub fn calibrated_pipeline(
    logs: &[(String, LogSource)],
    pipeline: &Pipeline,
    options: Options,
    compute: bool,
    whole: bool,
    where_: &Path,
    previous: Option<&Path>,
) -> Result<CampaignCalibrated, CampaignError> {
    let mode = pipeline.estimate.calibration;
    let as_is = |note: Option<String>| {
        let mut p = pipeline.clone();
        p.calibrated = None;
        CampaignCalibrated {
            pipeline: p,
            record: None,
            reused: false,
            note,
        }
    };
    if mode.fitted().is_none() {
        if pipeline.calibrated.is_some() {
            return Err(CampaignError::Input {
                path: where_.to_path_buf(),
                message: "a calibration was given, but the pipeline's estimate.calibration is \"pipeline\"".into(),
                hint: "set estimate.calibration to the calibration's source, or leave --calibration out".into(),
            });
        }
        return Ok(as_is(None));
    }
    if let Some(given) = &pipeline.calibrated {
        check_given(given, logs, pipeline, where_, whole)?;
        if whole && !compute {
            check_inputs(given, logs, pipeline, where_)?;
        }
        return Ok(if given.source == NONE_SOURCE {
            as_is(Some(auto_note(&format!(
                "the campaign's calibrate part fitted none over its {} runs",
                given.runs.len()
            ))))
        } else {
            CampaignCalibrated {
                pipeline: pipeline.clone(),
                record: None,
                reused: false,
                note: None,
            }
        });
    }
    if !compute {
        if mode == CalibrationSource::Auto && logs.len() < MIN_RUNS {
            return Ok(as_is(Some(auto_note(&format!(
                "the campaign has {} run{}",
                logs.len(),
                if logs.len() == 1 { "" } else { "s" }
            )))));
        }
        return Err(CampaignError::Input {
            path: where_.to_path_buf(),
            message: format!(
                "estimate.calibration = \"{}\": the runs are estimated with the campaign's calibration, which was not given",
                mode.name()
            ),
            hint: "fit it once with `railgrip run ARCHIVE --out OUT --stage calibrate` (or `railgrip calibrate --campaign ARCHIVE --out OUT`), which writes OUT/calibration.json, before the other parts; or give it with --calibration FILE".into(),
        });
    }
    // Hashed before the fit: a log changed while it is fitted is not recorded as fitted.
    let inputs = campaign_inputs_sha256(logs, pipeline);
    let (record, reused) = match previous.and_then(|f| reusable(f, &inputs, pipeline)) {
        Some(r) => (r, true),
        None => (
            fit_campaign(logs, pipeline, options, where_, inputs)?,
            false,
        ),
    };
    let mut c = as_is(None);
    if record.calibrated.source == NONE_SOURCE {
        c.note = record.notes.first().cloned();
    } else {
        c.pipeline.calibrated = Some(record.calibrated.clone());
    }
    c.record = Some(record);
    c.reused = reused;
    Ok(c)
}

/// The note of an "auto" campaign estimated with the pipeline's own values.
fn auto_note(why: &str) -> String {
    format!(
        "calibration: none ({why}): the runs are estimated with [vehicle]'s α and the radar as logged (estimate.calibration = \"auto\" calibrates a campaign of {MIN_RUNS} or more runs whose calibration can be fitted)"
    )
}

/// The record of an "auto" campaign that fitted no calibration, and why.
fn none_record(
    logs: &[(String, LogSource)],
    pipeline: &Pipeline,
    why: &str,
    inputs_sha256: String,
) -> CalibrationRecord {
    let alpha = pipeline.vehicle.brake_torque_nm_per_bar;
    CalibrationRecord {
        calibrated: Calibrated {
            source: NONE_SOURCE.to_string(),
            corrections: Corrections {
                alpha_nm_per_bar: alpha,
                pad: PadLaw::constant(),
                radar_scale: 1.0,
                radar_latency_s: 0.0,
                tacho_delay_s: 0.0,
            },
            runs: logs.iter().map(|(n, _)| n.clone()).collect(),
            pipeline_sha256: pipeline_sha256(pipeline),
            inputs_sha256: None,
            errors: None,
        },
        pipeline_alpha_nm_per_bar: alpha,
        campaign: None,
        dry_run: None,
        notes: vec![auto_note(why)],
        inputs_sha256,
    }
}

/// The calibration record in `file` when it was fitted on these inputs
/// ([`CalibrationRecord::inputs_sha256`]) for this kind of calibration (for "auto", also the
/// record that it fitted none); None otherwise (no file, unreadable, another version's without
/// the hash, other inputs).
fn reusable(file: &Path, inputs: &str, pipeline: &Pipeline) -> Option<CalibrationRecord> {
    let text = std::fs::read_to_string(file).ok()?;
    let record: CalibrationRecord = serde_json::from_str(&text).ok()?;
    let fits = !record.inputs_sha256.is_empty()
        && source_fits(&record.calibrated.source, pipeline)
        && record.inputs_sha256 == inputs;
    fits.then_some(record)
}

/// Whether a calibration of `source` is one `pipeline` asks for.
fn source_fits(source: &str, pipeline: &Pipeline) -> bool {
    Some(source) == fitted_name(pipeline)
        || (source == NONE_SOURCE && pipeline.estimate.calibration == CalibrationSource::Auto)
}

/// Refuses, for a campaign's models part, a calibration fitted on logs or sidecars that have
/// changed since (by [`CalibrationRecord::inputs_sha256`], where the calibration came with it).
fn check_inputs(
    given: &Calibrated,
    logs: &[(String, LogSource)],
    pipeline: &Pipeline,
    where_: &Path,
) -> Result<(), CampaignError> {
    match &given.inputs_sha256 {
        Some(h) if !h.is_empty() && *h != campaign_inputs_sha256(logs, pipeline) => {
            Err(CampaignError::Input {
                path: where_.to_path_buf(),
                message: "the given calibration was fitted on other inputs: a log or sidecar of the campaign changed since, or it was written by another railgrip version or calibration method".into(),
                hint: "fit it again (`railgrip run ARCHIVE --out OUT --stage calibrate`, or `railgrip calibrate --campaign`) and estimate the runs again with it".into(),
            })
        }
        _ => Ok(()),
    }
}

/// Refuses a calibration for another kind of calibration or fitted with another pipeline file
/// (one run estimated alone: which runs it was fitted on is not checked).
pub fn check_for_run(
    given: &Calibrated,
    pipeline: &Pipeline,
    run: &Path,
) -> Result<(), CampaignError> {
    let why = if !source_fits(&given.source, pipeline) {
        format!(
            "it is a \"{}\" calibration and the pipeline's estimate.calibration is \"{}\"",
            given.source,
            pipeline.estimate.calibration.name()
        )
    } else if given.pipeline_sha256 != pipeline_sha256(pipeline) {
        "it was fitted with another pipeline file".into()
    } else {
        return Ok(());
    };
    Err(CampaignError::Input {
        path: run.to_path_buf(),
        message: format!("the given calibration does not fit this pipeline: {why}"),
        hint: if given.source == NONE_SOURCE {
            "this file records that the campaign fitted no calibration (estimate.calibration = \"auto\"): give the pipeline it was written with (--pipeline), or leave --calibration out".into()
        } else {
            format!("give the pipeline the calibration was fitted with (--pipeline), one with estimate.calibration = \"{}\"{}", given.source, if given.source == "campaign" { " or \"auto\"" } else { "" })
        },
    })
}

/// Refuses a calibration fitted on other runs or with another pipeline file. `whole`: `logs`
/// are the whole campaign (else some of its runs, as one run's task on a cluster sees them).
fn check_given(
    given: &Calibrated,
    logs: &[(String, LogSource)],
    pipeline: &Pipeline,
    where_: &Path,
    whole: bool,
) -> Result<(), CampaignError> {
    let names: Vec<&str> = logs.iter().map(|(n, _)| n.as_str()).collect();
    let fitted: Vec<&str> = given.runs.iter().map(String::as_str).collect();
    let why = if !source_fits(&given.source, pipeline) {
        Some(format!(
            "it is a \"{}\" calibration and the pipeline asks for \"{}\"",
            given.source,
            pipeline.estimate.calibration.name()
        ))
    } else if given.pipeline_sha256 != pipeline_sha256(pipeline) {
        Some("it was fitted with another pipeline file".into())
    } else if names.iter().any(|n| !fitted.contains(n)) || (whole && fitted != names) {
        let missing: Vec<&str> = names
            .iter()
            .filter(|n| !fitted.contains(n))
            .copied()
            .collect();
        let extra: Vec<&str> = fitted
            .iter()
            .filter(|n| !names.contains(n))
            .copied()
            .collect();
        Some(format!(
            "it was fitted on other runs (not fitted: {}; not in the campaign: {})",
            if missing.is_empty() {
                "none".into()
            } else {
                missing.join(", ")
            },
            if extra.is_empty() {
                "none".into()
            } else {
                extra.join(", ")
            }
        ))
    } else {
        None
    };
    match why {
        None => Ok(()),
        Some(why) => Err(CampaignError::Input {
            path: where_.to_path_buf(),
            message: format!("the given calibration does not belong to this campaign: {why}"),
            hint: "fit it again with `railgrip calibrate --campaign ARCHIVE --out OUT` for this archive and pipeline".into(),
        }),
    }
}

/// The source name a calibration for `pipeline` has ([`CalibrationSource::fitted`]).
fn fitted_name(pipeline: &Pipeline) -> Option<&'static str> {
    pipeline
        .estimate
        .calibration
        .fitted()
        .map(CalibrationSource::name)
}

/// Fits the campaign's calibration (`estimate.calibration` of `pipeline`, not "pipeline";
/// "auto" as "campaign") on its runs, conditioned in parallel on `options.jobs` threads; a run
/// that cannot be read is left out with a note (its estimate fails on its own). Too few runs
/// are an error here, also for "auto".
pub fn calibrate_campaign(
    logs: &[(String, LogSource)],
    pipeline: &Pipeline,
    options: Options,
    where_: &Path,
) -> Result<CalibrationRecord, CampaignError> {
    let mut p = pipeline.clone();
    if p.estimate.calibration == CalibrationSource::Auto {
        p.estimate.calibration = CalibrationSource::Campaign;
    }
    let inputs = campaign_inputs_sha256(logs, pipeline);
    fit_campaign(logs, &p, options, where_, inputs)
}

/// [`calibrate_campaign`] with the inputs' hash taken before ([`campaign_inputs_sha256`]);
/// for "auto", where too few runs have samples for the balance or the fit fails, the record
/// that no calibration was fitted, and why ([`NONE_SOURCE`]).
fn fit_campaign(
    logs: &[(String, LogSource)],
    pipeline: &Pipeline,
    options: Options,
    where_: &Path,
    inputs_sha256: String,
) -> Result<CalibrationRecord, CampaignError> {
    let pool = crate::parallel::pool(options.jobs)?;
    let auto = pipeline.estimate.calibration == CalibrationSource::Auto;
    let mode = pipeline
        .estimate
        .calibration
        .fitted()
        .expect("fit_campaign is called for a pipeline that asks for a calibration");
    let mut raw = pipeline.clone();
    raw.calibrated = None;
    let calibrated = |corrections, errors| Calibrated {
        source: mode.name().to_string(),
        corrections,
        runs: logs.iter().map(|(n, _)| n.clone()).collect(),
        pipeline_sha256: pipeline_sha256(pipeline),
        inputs_sha256: None,
        errors: Some(errors),
    };
    let pipeline_alpha = raw.vehicle.brake_torque_nm_per_bar;
    let read = |src: &LogSource| crate::ingest::ingest_source(src, &raw);
    match mode {
        CalibrationSource::Campaign => {
            let mut cal = CampaignCalibrator::new(&raw);
            let prepared: Vec<Result<_, String>> =
                crate::parallel::each(&pool, logs, |(name, src)| {
                    let log = read(src).map_err(|e| format!("{name}: {e}"))?;
                    cal.prepare(&log)
                        .map(|p| p.named(name))
                        .map_err(|e| format!("{name}: {e}"))
                });
            for p in prepared {
                match p {
                    Ok(p) => cal.add_prepared(p),
                    Err(e) => cal.left_out(&e),
                }
            }
            if let Some(why) = cal.too_few().filter(|_| auto) {
                return Ok(none_record(logs, pipeline, &why, inputs_sha256));
            }
            let fit = match cal.finish(where_) {
                Ok(fit) => fit,
                Err(e) if auto => {
                    let why = format!("the campaign's calibration could not be fitted: {e}");
                    return Ok(none_record(logs, pipeline, &why, inputs_sha256));
                }
                Err(e) => return Err(e.into()),
            };
            let notes = fit.notes.clone();
            Ok(CalibrationRecord {
                calibrated: calibrated(
                    fit.corrections(),
                    Errors {
                        alpha_se: fit.alpha_se,
                        radar_scale_se: fit.radar_scale_se,
                        radar_latency_se_s: fit.radar_latency_se,
                        pipeline_alpha_nm_per_bar: pipeline_alpha,
                        fitted_runs: Some(fit.runs),
                    },
                ),
                pipeline_alpha_nm_per_bar: raw.vehicle.brake_torque_nm_per_bar,
                campaign: Some(fit),
                dry_run: None,
                notes,
                inputs_sha256,
            })
        }
        CalibrationSource::DryRun => {
            fit_dry_run(logs, &raw, &pool, where_, inputs_sha256, &calibrated)
        }
        CalibrationSource::Auto | CalibrationSource::Pipeline => {
            unreachable!("fitted() is \"campaign\" or \"dry-run\"")
        }
    }
}

/// "dry-run": one α from each run's full-adhesion samples (the runs without them named in the
/// notes), pooled by their errors; `calibrated` makes the record's [`Calibrated`] of its
/// corrections and errors.
fn fit_dry_run(
    logs: &[(String, LogSource)],
    raw: &Pipeline,
    pool: &rayon::ThreadPool,
    where_: &Path,
    inputs_sha256: String,
    calibrated: &dyn Fn(Corrections, Errors) -> Calibrated,
) -> Result<CalibrationRecord, CampaignError> {
    let read = |src: &LogSource| crate::ingest::ingest_source(src, raw);
    let pipeline_alpha = raw.vehicle.brake_torque_nm_per_bar;
    let fits: Vec<(String, RunAlpha)> = crate::parallel::each(pool, logs, |(name, src)| {
        let fit = read(src)
            .map_err(|e| e.to_string())
            .and_then(|log| {
                calibrate(&log, raw, AlphaFit::Common, Resistance::Fit).map_err(|e| e.to_string())
            })
            .map(|c| (c.alpha_nm_per_bar[0], c.alpha_se[0]));
        (name.clone(), fit)
    });
    let ok: Vec<(String, f64, f64)> = fits
        .iter()
        .filter_map(|(n, f)| f.as_ref().ok().map(|(a, se)| (n.clone(), *a, *se)))
        .collect();
    if ok.is_empty() {
        return Err(CampaignError::Input {
            path: where_.to_path_buf(),
            message: "estimate.calibration = \"dry-run\": no run of the campaign has the full-adhesion samples one α needs".into(),
            hint: "add a dry run braked without sliding (e.g. fixtures/archive/dry_120kmh_p20.csv), or use estimate.calibration = \"campaign\"".into(),
        });
    }
    let w: f64 = ok.iter().map(|(_, _, se)| 1.0 / (se * se)).sum();
    let alpha = ok.iter().map(|(_, a, se)| a / (se * se)).sum::<f64>() / w;
    let notes = fits
        .iter()
        .filter_map(|(n, f)| {
            f.as_ref()
                .err()
                .map(|e| format!("{n}: no α from this run: {e}"))
        })
        .collect();
    Ok(CalibrationRecord {
        pipeline_alpha_nm_per_bar: raw.vehicle.brake_torque_nm_per_bar,
        calibrated: calibrated(
            Corrections {
                alpha_nm_per_bar: [alpha; AXLES],
                pad: PadLaw::constant(),
                radar_scale: 1.0,
                radar_latency_s: 0.0,
                tacho_delay_s: 0.0,
            },
            Errors {
                alpha_se: [w.sqrt().recip(); AXLES],
                radar_scale_se: f64::NAN,
                radar_latency_se_s: f64::NAN,
                pipeline_alpha_nm_per_bar: pipeline_alpha,
                fitted_runs: Some(ok.len()),
            },
        ),
        campaign: None,
        dry_run: Some(DryRunFit {
            alpha_nm_per_bar: alpha,
            alpha_se: w.sqrt().recip(),
            runs: ok,
        }),
        notes,
        inputs_sha256,
    })
}

/// Reads a calibration file (`calibration.json` as [`calibrate_campaign`]'s record, or the
/// bare [`Calibrated`] part).
pub fn read_calibration(path: &Path) -> Result<Calibrated, CampaignError> {
    let bad = |message: String| CampaignError::Input {
        path: path.to_path_buf(),
        message,
        hint:
            "give the calibration.json that `railgrip calibrate --campaign` or `railgrip run` wrote"
                .into(),
    };
    let text =
        std::fs::read_to_string(path).map_err(|e| bad(format!("cannot read the file: {e}")))?;
    match serde_json::from_str::<CalibrationRecord>(&text) {
        Ok(r) => Ok(Calibrated {
            inputs_sha256: Some(r.inputs_sha256),
            ..r.calibrated
        }),
        Err(e) => serde_json::from_str::<Calibrated>(&text)
            .map_err(|_| bad(format!("not a calibration file: {e}"))),
    }
}

/// Writes `record` as `dir/calibration.json` (atomically).
pub fn write_calibration(dir: &Path, record: &CalibrationRecord) -> Result<PathBuf, CampaignError> {
    use std::io::Write as _;
    let path = dir.join(CALIBRATION_FILE);
    let text = serde_json::to_string_pretty(record).expect("a calibration serialises") + "\n";
    crate::atomic::write_atomically(&path, |w| w.write_all(text.as_bytes())).map_err(|source| {
        CampaignError::Write {
            path: path.clone(),
            source,
        }
    })?;
    Ok(path)
}
