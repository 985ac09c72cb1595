//! A test campaign end to end (`railgrip run`), as one library call: [`run`] finds the logs of a
//! campaign folder or archive, estimates every run in parallel ([`runs`]: a run that fails is a
//! record, not an abort), trains and exports the models on the pooled estimates of one rail
//! condition ([`train`]), and writes the summary ([`summary`]), `campaign.json` and the report.
//! [`OutDir`] (module `outdir`, shared with the report) owns every output path. Progress goes to a [`Progress`] the caller supplies (the
//! CLI draws bars from it); the library never prints.

pub mod calibration;
pub mod pool;
mod remote;
pub mod runs;
pub mod summary;
pub mod tables;
pub mod train;

use std::path::{Path, PathBuf};
use std::time::Instant;

pub use crate::outdir::{
    generation_id, CampaignRecord, ModelPaths, OutDir, RecordError, RunRecord, RunStatus,
    RunTiming, Skipped, Timings,
};
pub use pool::{ParkedRun, Pool, PooledRun};
pub use remote::{campaign_logs_at, estimate_run_at, models_at, run_at, sources_at};
pub use runs::{
    discover, discover_all, failed_record, input_hash, process_run, recall_run, run_name,
};
pub use summary::{write_summary, SUMMARY_COLUMNS};
pub use tables::{load_pooled, load_tables};
pub use train::{train_models, train_pooled, CampaignModels};

use crate::config::Pipeline;
use crate::identify::choice::Choice;
use crate::identify::dataset::RunTable;
use crate::ingest::LogSource;
use crate::model::Epoch;

/// Why the campaign as a whole could not go on.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    #[error("{path}: {message}. Hint: {hint}")]
    Input {
        path: PathBuf,
        message: String,
        hint: String,
    },
    #[error("{path}: {source}. Hint: give a folder of braking-run logs (.csv with .meta.toml, .mcap) or an archive of one")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Table(#[from] crate::table::TableError),
    #[error(transparent)]
    Record(#[from] RecordError),
    #[error(transparent)]
    Archive(#[from] crate::archive::ArchiveError),
    #[error(transparent)]
    Store(#[from] crate::store::StoreError),
    /// An error of a campaign whose output folder is in a bucket, its message naming the
    /// output's URI (not the local staging folder).
    #[error("{0}")]
    Remote(String),
    #[error(transparent)]
    Ingest(#[from] crate::ingest::IngestError),
    #[error(transparent)]
    Estimate(#[from] crate::estimate::EstimateError),
    #[error(transparent)]
    Identify(#[from] crate::identify::IdentifyError),
    #[error("cannot start the worker threads: {0}")]
    Threads(#[from] rayon::ThreadPoolBuildError),
}

/// How [`run`] goes about it.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Runs estimated in parallel (None: one per core).
    pub jobs: Option<usize>,
    /// Recompute every run even when its inputs and the pipeline are unchanged.
    pub force: bool,
    /// Write `runs/<run>/<run>.railgrip.mcap` per run: estimates and the network's μ replayed.
    /// Without it such files of an earlier run are removed.
    pub mcap: bool,
    /// The whole job, or the part a scheduler's job does ([`Part`]).
    pub part: Part,
    /// An estimate shard returns its runs' tables in [`Outcome::tables`], for a caller that
    /// trains on them in memory (a Ray task per run); without it the shard keeps none, so that
    /// a shard of thousands of runs does not hold them all, and the models part reads them
    /// back from the output folder.
    pub tables: bool,
}

/// Which part of a campaign one call does. A scheduler (a Slurm job array, any cluster) runs
/// the estimate shards as separate jobs on a shared output folder, then the models part once
/// they are all done; the result is the same files as one [`run`] (but `timings.json`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Part {
    /// Everything: estimate, train, report.
    #[default]
    All,
    /// Estimate one shard of the runs into the output folder (each run's folder as [`run`]
    /// writes it); no models, no summary, no report.
    Estimate(Shard),
    /// Train and report from the runs the shards estimated: every run of the campaign must be
    /// there for its current inputs (a missing or stale run is an error naming it).
    Models,
    /// Fit the campaign's calibration (when the pipeline asks for one) into the output
    /// folder's `calibration.json`, which the estimate shards and the models part then take;
    /// no runs, no models.
    Calibrate,
}

/// Shard `k` of `n` (1-based): the runs whose position in the campaign's order (0-based) is
/// k − 1 modulo n.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub k: usize,
    pub n: usize,
}

impl Shard {
    /// Parses `K/N` with 1 ≤ K ≤ N.
    pub fn parse(text: &str) -> Result<Shard, String> {
        let bad = || format!("--shard {text:?}: write K/N with 1 ≤ K ≤ N, e.g. 3/16");
        let (k, n) = text.split_once('/').ok_or_else(bad)?;
        let (k, n): (usize, usize) = (
            k.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if k == 0 || k > n {
            return Err(bad());
        }
        Ok(Shard { k, n })
    }

    /// Whether the run at `index` (0-based, in the campaign's order) is this shard's.
    pub fn has(&self, index: usize) -> bool {
        index % self.n == self.k - 1
    }
}

/// The stages of a campaign, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    Estimate,
    Train,
    Report,
}

impl Stage {
    pub fn name(self) -> &'static str {
        match self {
            Stage::Estimate => "estimate",
            Stage::Train => "train",
            Stage::Report => "report",
        }
    }
}

/// What a campaign reports while it works. Runs finish on worker threads, so implementations
/// are shared (`&self`, `Sync`).
pub enum Event<'a> {
    /// The estimate stage starts: `runs` logs from `source` on `threads` worker threads.
    EstimateStarts {
        runs: usize,
        source: &'a Path,
        threads: usize,
    },
    /// One run finished (ok, reused or failed).
    RunDone(&'a RunRecord),
    /// The train stage starts.
    TrainStarts,
    /// The network finished an epoch.
    Epoch(&'a Epoch),
    /// A stage ended.
    StageDone(Stage),
}

pub use crate::progress::{Progress, Quiet};

/// What receives a campaign's [`Event`]s: any [`Progress`] of them (a closure, [`Quiet`], the
/// CLI's bars).
pub type CampaignProgress<'p> = &'p dyn for<'a> Progress<Event<'a>>;

/// What [`run`] did.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The campaign folder or archive.
    pub archive: PathBuf,
    pub records: Vec<RunRecord>,
    /// The rail condition the models were trained on.
    pub condition: Option<String>,
    /// Model files written.
    pub models: Vec<PathBuf>,
    /// Why no models were trained.
    pub model_error: Option<String>,
    /// The campaign's model file (`campaign.json`'s `chosen_model`); which candidate it is and
    /// why is [`Outcome::choice`]'s ([`Choice::why`]).
    pub chosen: Option<PathBuf>,
    /// The model choice: every candidate's held-out scores (as `models/mlp.choice.json`).
    pub choice: Option<Choice>,
    /// The network's plausibility audit (docs/model-files.md#plausibility-audit); a failed audit still
    /// writes the model, marked.
    pub audit: Option<crate::model::AuditSpec>,
    pub notes: Vec<String>,
    /// The report, when it could be written (else a note says why).
    pub report: Option<PathBuf>,
    /// Wall time per stage and in total, s.
    pub stages: Vec<(String, f64)>,
    /// Files that are not logs, with why.
    pub skipped: Vec<Skipped>,
    /// An estimate shard's run tables when [`Options::tables`] asks for them (its runs that
    /// could be estimated, reused ones read back), in the order of its records; empty
    /// otherwise, and for a whole campaign, whose tables go to the training stage.
    pub tables: Vec<RunTable>,
}

/// The runs of a campaign as estimate shards returned them ([`Outcome::records`] and
/// [`Outcome::tables`]): what the models part trains on instead of reading the runs back from
/// the output folder ([`models_at`]).
pub type Given = Vec<(RunRecord, Option<RunTable>)>;

impl Outcome {
    /// [`Outcome::chosen`] as JSON, `{"path": …, "why": …}` (`run --json`, Python's `Campaign`).
    pub fn chosen_json(&self) -> Option<serde_json::Value> {
        let (p, c) = self.chosen.as_ref().zip(self.choice.as_ref())?;
        Some(serde_json::json!({"path": p.display().to_string(), "why": c.why()}))
    }
    pub fn failed(&self) -> usize {
        self.records.iter().filter(|r| !r.ok()).count()
    }
    pub fn reused(&self) -> usize {
        self.records.iter().filter(|r| r.reused).count()
    }
}

/// The bundled archive of this source tree (`fixtures/archive`).
pub fn bundled_archive() -> PathBuf {
    crate::config::source_tree().join("fixtures/archive")
}

/// The logs of a campaign with their run names: a folder, searched on disk (leaving out
/// `skip`, the output folder when it lies inside), or an archive file, read in place.
pub fn sources(
    root: &Path,
    skip: Option<&Path>,
) -> Result<Vec<(String, LogSource)>, CampaignError> {
    Ok(sources_all(root, skip)?.0)
}

/// A campaign's logs with their run names, and the files that are not logs with why.
pub type Sources = (Vec<(String, LogSource)>, Vec<Skipped>);

/// [`sources`], and the files that are not logs with why.
pub fn sources_all(root: &Path, skip: Option<&Path>) -> Result<Sources, CampaignError> {
    let (logs, skipped): Sources = if root.is_file() {
        let (logs, skipped) =
            crate::archive::read_archive_all(root, crate::archive::Limits::default())?;
        (
            logs.into_iter()
                .map(|s| (run_name(root, s.name()), s))
                .collect(),
            skipped
                .into_iter()
                .map(|(path, reason)| Skipped {
                    path: path.into(),
                    reason,
                })
                .collect(),
        )
    } else {
        let (logs, skipped) = discover_all(root, skip)?;
        (
            logs.into_iter()
                .map(|p| (run_name(root, &p), LogSource::File(p)))
                .collect(),
            skipped,
        )
    };
    if logs.is_empty() {
        return Err(CampaignError::Input {
            path: root.to_path_buf(),
            message: "no .csv or .mcap logs found (searched recursively)".into(),
            hint: "give the folder that holds the campaign's logs".into(),
        });
    }
    Ok((unique_names(logs), skipped))
}

/// Run names made unique (`x.csv` and `x.mcap` once shared `runs/x/`, the last
/// writer winning): where names collide, each gets its log's extension (`x_csv`, `x_mcap`);
/// where they still collide (names that sanitise alike, `a b.csv` and `a_b.csv`), a counter in
/// the order of the logs' paths (`a_b_csv`, `a_b_csv_2`): the same names on every run, for a
/// folder and for an archive of it.
pub(super) fn unique_names(mut logs: Vec<(String, LogSource)>) -> Vec<(String, LogSource)> {
    let count = |logs: &[(String, LogSource)], n: &str| logs.iter().filter(|(m, _)| m == n).count();
    let collided: Vec<bool> = logs.iter().map(|(n, _)| count(&logs, n) > 1).collect();
    for ((name, src), hit) in logs.iter_mut().zip(collided) {
        if hit {
            let ext = src
                .name()
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase())
                .unwrap_or_default();
            name.push('_');
            name.push_str(if ext.is_empty() { "log" } else { &ext });
        }
    }
    // Counters in the order of the logs' paths (an archive lists its members in any order).
    let mut order: Vec<usize> = (0..logs.len()).collect();
    order.sort_by(|&a, &b| logs[a].1.name().cmp(logs[b].1.name()));
    let mut seen: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
    for i in order {
        let name = &mut logs[i].0;
        let k = seen.entry(name.clone()).or_insert(0);
        *k += 1;
        if *k > 1 {
            name.push_str(&format!("_{k}"));
        }
    }
    logs
}

/// Runs the campaign at `root` (a folder or an archive file) into `out`: every run, the
/// models, the summary, `campaign.json` and the report. Fails as a whole only when the
/// campaign cannot be read or its outputs cannot be written; failed runs and models that
/// could not be trained are in the [`Outcome`].
pub fn run(
    root: &Path,
    out: &OutDir,
    pipeline: &Pipeline,
    options: Options,
    progress: CampaignProgress<'_>,
) -> Result<Outcome, CampaignError> {
    let (logs, skipped) = sources_all(root, Some(out.root()))?;
    run_sources(root, logs, skipped, out, pipeline, options, progress, None)
}

/// [`run`] on the logs of the campaign `root` as found ([`sources_all`], or the objects below
/// an `s3://` prefix). The models part trains on the `given` runs when there are some (every
/// run of `logs` must be among them), else on the runs read back from `out`.
#[allow(clippy::too_many_arguments)]
fn run_sources(
    root: &Path,
    logs: Vec<(String, LogSource)>,
    skipped: Vec<Skipped>,
    out: &OutDir,
    pipeline: &Pipeline,
    options: Options,
    progress: CampaignProgress<'_>,
    given: Option<Given>,
) -> Result<Outcome, CampaignError> {
    let t_all = Instant::now();
    // The calibration first: every run's estimate depends on it.
    let t = Instant::now();
    let cal = campaign_calibration(&logs, pipeline, options, out, root)?;
    let cal_s = t.elapsed().as_secs_f64();
    match options.part {
        Part::Estimate(shard) => {
            let mut o = estimate_shard(
                root,
                logs,
                skipped,
                out,
                &cal.pipeline,
                options,
                shard,
                progress,
            )?;
            o.notes.extend(cal.note);
            return Ok(o);
        }
        Part::Calibrate => return calibrate_part(root, skipped, out, cal, cal_s),
        Part::All | Part::Models => {}
    }
    let pipeline = &cal.pipeline;
    prepare_output(out)?;
    let mut stages = Vec::new();
    // A reused calibration is the file already there (fitted on the same inputs).
    if cal.reused || write_calibration_file(out, cal.record.as_ref(), options.part)? {
        stages.push(("calibrate".to_string(), cal_s));
    }

    let t = Instant::now();
    let (records, tables) = campaign_runs(root, &logs, out, pipeline, options, given, progress)?;
    stages.push((
        Stage::Estimate.name().to_string(),
        t.elapsed().as_secs_f64(),
    ));
    progress.event(Event::StageDone(Stage::Estimate));

    let generation = generation_id(&pipeline.text, &records);
    let t = Instant::now();
    let trained = train_stage(tables, out, pipeline, &generation, progress)?;
    stages.push((Stage::Train.name().to_string(), t.elapsed().as_secs_f64()));
    progress.event(Event::StageDone(Stage::Train));

    let t = Instant::now();
    let mut replay_notes = replay_stage(out, &records, &trained, options.mcap, options.jobs);
    stages.push(("replay".to_string(), t.elapsed().as_secs_f64()));

    let t = Instant::now();
    write_summary(out, &records)?;
    CampaignRecord {
        archive: root.display().to_string(),
        runs: records.clone(),
        condition: trained.condition.clone(),
        model_error: trained.model_error.clone(),
        notes: trained.notes.clone(),
        pipeline: pipeline.source.clone(),
        validation_axles: match &pipeline.train.split {
            crate::config::SplitConfig::Axles { val, .. } => val.clone(),
            _ => vec![],
        },
        skipped: skipped.clone(),
        generation: Some(generation.clone()),
        calibration: pipeline.calibrated.clone(),
        chosen_model: trained.chosen.as_ref().map(|p| {
            format!(
                "models/{}",
                p.file_name().unwrap_or_default().to_string_lossy()
            )
        }),
    }
    .write(out)?;
    let mut notes = cal_notes(&cal, None);
    notes.extend(trained.notes);
    notes.append(&mut replay_notes);
    let report = match crate::report::write_report(out) {
        Ok(p) => Some(p),
        Err(e) => {
            notes.push(format!("report: {e}"));
            None
        }
    };
    stages.push((Stage::Report.name().to_string(), t.elapsed().as_secs_f64()));
    progress.event(Event::StageDone(Stage::Report));
    stages.push(("total".to_string(), t_all.elapsed().as_secs_f64()));
    Timings {
        generation: generation.clone(),
        finished: crate::outdir::utc_now_rfc3339(),
        jobs: options
            .jobs
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
        stages: stages.clone(),
        runs: records
            .iter()
            .map(|r| RunTiming {
                run: r.run.clone(),
                reused: r.reused,
                duration_s: (!r.reused).then_some(r.duration_s),
            })
            .collect(),
        train_epochs: trained.epochs,
        train_s: trained.train_s,
        calibration_reused: cal.reused,
    }
    .write(out)?;
    Ok(Outcome {
        archive: root.to_path_buf(),
        records,
        condition: trained.condition,
        models: trained.models,
        chosen: trained.chosen,
        choice: trained.choice,
        model_error: trained.model_error,
        audit: trained.audit,
        notes,
        report,
        stages,
        skipped,
        tables: vec![],
    })
}

/// The pipeline the campaign's runs are estimated with, the calibration record behind it and
/// whether that was reused from `out` ([`calibration::calibrated_pipeline`]). A part of a
/// scheduled campaign that is not given the calibration takes the one its calibrate part wrote
/// into `out` ([`Part::Calibrate`]), when there is one.
fn campaign_calibration(
    logs: &[(String, LogSource)],
    pipeline: &Pipeline,
    options: Options,
    out: &OutDir,
    root: &Path,
) -> Result<calibration::CampaignCalibrated, CampaignError> {
    if options.part == Part::Calibrate && pipeline.calibrated.is_some() {
        return Err(CampaignError::Input {
            path: out.root().to_path_buf(),
            message: "the calibrate part was given a calibration: it fits the campaign's own".into(),
            hint: "leave the calibration out of the calibrate part (give it to the estimate and models parts instead, or let them take OUT/calibration.json)".into(),
        });
    }
    let computes = matches!(options.part, Part::All | Part::Calibrate);
    let written = out.root().join(calibration::CALIBRATION_FILE);
    let taken;
    let pipeline = if !computes
        && pipeline.calibrated.is_none()
        && pipeline.estimate.calibration.fitted().is_some()
        && written.is_file()
    {
        let mut p = pipeline.clone();
        p.calibrated = Some(calibration::read_calibration(&written).map_err(|e| {
            CampaignError::Input {
                path: written.clone(),
                message: format!("the campaign's calibration, which this part takes from the output folder, cannot be used: {e}"),
                hint: "write it again with `railgrip run ARCHIVE --out OUT --stage calibrate` (the same archive, pipeline and --out)".into(),
            }
        })?);
        taken = p;
        &taken
    } else {
        pipeline
    };
    calibration::calibrated_pipeline(
        logs,
        pipeline,
        options,
        computes,
        // An estimate part may see one run alone (a task on a cluster): its runs must be among
        // the calibration's; the models part sees them all.
        !matches!(options.part, Part::Estimate(_)),
        root,
        (!options.force && computes).then_some(written.as_path()),
    )
}

/// The notes on a campaign's calibration, in the order the outcome gives them: why "auto" fitted
/// none, the calibration applied (with `file`, where it was written), and the fit's own notes.
fn cal_notes(cal: &calibration::CampaignCalibrated, file: Option<&Path>) -> Vec<String> {
    let mut notes: Vec<String> = cal.note.iter().cloned().collect();
    if let Some(c) = &cal.pipeline.calibrated {
        notes.push(match file {
            Some(f) => format!(
                "{} ({}{})",
                c.summary(),
                f.display(),
                if cal.reused {
                    ", reused: fitted on the same inputs"
                } else {
                    ""
                }
            ),
            None => c.summary(),
        });
    }
    if let Some(r) = cal
        .record
        .as_ref()
        .filter(|r| r.calibrated.source != calibration::NONE_SOURCE)
    {
        notes.extend(r.notes.iter().map(|n| format!("calibration: {n}")));
    }
    notes
}

/// The calibrate part ([`Part::Calibrate`]): the calibration fitted (or reused) written into
/// `out`, or, when none applies, an earlier one removed; the outcome carries no runs.
fn calibrate_part(
    root: &Path,
    skipped: Vec<Skipped>,
    out: &OutDir,
    cal: calibration::CampaignCalibrated,
    seconds: f64,
) -> Result<Outcome, CampaignError> {
    std::fs::create_dir_all(out.root()).map_err(|source| CampaignError::Write {
        path: out.root().to_path_buf(),
        source,
    })?;
    // The calibrate part starts a scheduled campaign: the earlier one's record and report go
    // until its models part writes them again (as an estimate shard removes them).
    remove_campaign_results(out)?;
    write_calibration_file(out, cal.record.as_ref(), Part::Calibrate)?;
    let file = out.root().join(calibration::CALIBRATION_FILE);
    let mut notes = cal_notes(
        &cal,
        cal.pipeline.calibrated.is_some().then_some(file.as_path()),
    );
    if notes.is_empty() {
        notes
            .push("calibration: none (estimate.calibration = \"pipeline\"): nothing to fit".into());
    }
    Ok(Outcome {
        archive: root.to_path_buf(),
        records: vec![],
        condition: None,
        models: vec![],
        model_error: None,
        chosen: None,
        choice: None,
        audit: None,
        notes,
        report: None,
        stages: vec![
            ("calibrate".to_string(), seconds),
            ("total".to_string(), seconds),
        ],
        skipped,
        tables: vec![],
    })
}

/// Writes the calibration this campaign fitted as `calibration.json` (true), or, for a whole
/// campaign that fitted none (no calibration, or one given), removes an earlier campaign's:
/// it would describe runs estimated otherwise.
fn write_calibration_file(
    out: &OutDir,
    record: Option<&calibration::CalibrationRecord>,
    part: Part,
) -> Result<bool, CampaignError> {
    if let Some(record) = record {
        calibration::write_calibration(out.root(), record)?;
        return Ok(true);
    }
    if matches!(part, Part::All | Part::Calibrate) {
        let stale = out.root().join(calibration::CALIBRATION_FILE);
        match std::fs::remove_file(&stale) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(CampaignError::Write {
                    path: stale,
                    source: e,
                })
            }
            _ => {}
        }
    }
    Ok(false)
}

/// One estimate shard ([`Part::Estimate`]): this shard's runs into `out`, as [`run`]'s first
/// stage writes them (reused when current unless `force`). The campaign's record and report
/// are removed (they no longer describe the runs); the other shards' files are left alone.
#[allow(clippy::too_many_arguments)]
fn estimate_shard(
    root: &Path,
    logs: Vec<(String, LogSource)>,
    skipped: Vec<Skipped>,
    out: &OutDir,
    pipeline: &Pipeline,
    options: Options,
    shard: Shard,
    progress: CampaignProgress<'_>,
) -> Result<Outcome, CampaignError> {
    let t = Instant::now();
    let mine: Vec<(String, LogSource)> = logs
        .into_iter()
        .enumerate()
        .filter(|(i, _)| shard.has(*i))
        .map(|(_, l)| l)
        .collect();
    make_output_folders(out)?;
    remove_campaign_results(out)?;
    let (records, tables) = if options.tables {
        estimate_runs(root, &mine, out, pipeline, options, progress)?
    } else {
        let (records, _) = estimate_each(root, &mine, out, pipeline, options, progress, |_, _| ())?;
        (records, vec![])
    };
    progress.event(Event::StageDone(Stage::Estimate));
    let elapsed = t.elapsed().as_secs_f64();
    Ok(Outcome {
        archive: root.to_path_buf(),
        records,
        condition: None,
        models: vec![],
        model_error: None,
        chosen: None,
        choice: None,
        audit: None,
        notes: vec![format!(
            "estimate shard {}/{}: {} of the campaign's runs; train and report with --stage models once every shard is done",
            shard.k,
            shard.n,
            mine.len()
        )],
        report: None,
        stages: vec![
            (Stage::Estimate.name().to_string(), elapsed),
            ("total".to_string(), elapsed),
        ],
        skipped,
        tables,
    })
}

/// `work` on every run, in parallel on a pool of `options.jobs` threads, at most two runs per
/// thread under way ([`crate::parallel::each`]), in the order of `logs`; the progress sees the
/// stage start and each run's record as `record` finds it.
fn each_run<T: Send>(
    root: &Path,
    logs: &[(String, LogSource)],
    options: Options,
    progress: CampaignProgress<'_>,
    work: impl Fn(&str, &LogSource) -> T + Sync,
    record: impl Fn(&T) -> Option<&RunRecord> + Sync,
) -> Result<Vec<T>, CampaignError> {
    let pool = crate::parallel::pool(options.jobs)?;
    progress.event(Event::EstimateStarts {
        runs: logs.len(),
        source: root,
        threads: pool.current_num_threads(),
    });
    Ok(crate::parallel::each(&pool, logs, |(name, src)| {
        let done = work(name, src);
        if let Some(rec) = record(&done) {
            progress.event(Event::RunDone(rec));
        }
        done
    }))
}

/// Stage 1 of a whole campaign or its models part: the runs estimated, recalled from the
/// estimate shards' outputs or given, their tables waiting for the models within
/// `train.max_pooled_samples` ([`pool`]).
fn campaign_runs(
    root: &Path,
    logs: &[(String, LogSource)],
    out: &OutDir,
    pipeline: &Pipeline,
    options: Options,
    given: Option<Given>,
    progress: CampaignProgress<'_>,
) -> Result<(Vec<RunRecord>, Vec<PooledRun>), CampaignError> {
    let pool = Pool::new(pipeline.train.max_pooled_samples);
    let admit = |name: &str, t: RunTable| pool.admit(t, &out.run_estimates(name));
    match (options.part, given) {
        (Part::Models, Some(given)) => {
            let (records, tables) = given_runs(logs, out, given)?;
            Ok((records, tables.into_iter().map(PooledRun::from).collect()))
        }
        (Part::Models, None) => recall_runs(root, logs, out, pipeline, options, progress, &admit),
        _ => estimate_each(root, logs, out, pipeline, options, progress, admit),
    }
}

/// The runs the estimate shards wrote ([`Part::Models`]), each checked against its current
/// inputs, each table given to `admit` (held or parked). Records in the order of `logs`; an
/// error names every run that is missing or stale.
fn recall_runs(
    root: &Path,
    logs: &[(String, LogSource)],
    out: &OutDir,
    pipeline: &Pipeline,
    options: Options,
    progress: CampaignProgress<'_>,
    admit: &(impl Fn(&str, RunTable) -> PooledRun + Sync),
) -> Result<(Vec<RunRecord>, Vec<PooledRun>), CampaignError> {
    let found = each_run(
        root,
        logs,
        options,
        progress,
        |name, src| {
            runs::recall_run(src, name, out, pipeline)
                .map(|(rec, table)| (rec, table.map(|t| admit(name, t))))
                .map_err(|why| format!("{name} ({why})"))
        },
        |r| r.as_ref().ok().map(|(rec, _)| rec),
    )?;
    let missing: Vec<String> = found
        .iter()
        .filter_map(|r| r.as_ref().err().cloned())
        .collect();
    if !missing.is_empty() {
        return Err(CampaignError::Input {
            path: out.runs(),
            message: format!(
                "{} of the campaign's {} runs are not estimated for their current inputs: {}",
                missing.len(),
                logs.len(),
                missing.join(", ")
            ),
            hint: "run `railgrip run --stage estimate --shard K/N` for every shard K of N (the same archive, pipeline and --out) before --stage models".into(),
        });
    }
    let (records, tables): (Vec<RunRecord>, Vec<Option<PooledRun>>) =
        found.into_iter().flatten().unzip();
    Ok((records, tables.into_iter().flatten().collect()))
}

/// The `given` runs in the order of `logs` (records and tables as the estimate shards returned
/// them). Refused, naming the runs: a run of `logs` that is not given, one given twice, one
/// the campaign does not have, a table beside a failed record or under another run's name.
fn given_runs(
    logs: &[(String, LogSource)],
    out: &OutDir,
    given: Given,
) -> Result<(Vec<RunRecord>, Vec<RunTable>), CampaignError> {
    let mut by_name: std::collections::HashMap<String, (RunRecord, Option<RunTable>)> =
        std::collections::HashMap::new();
    let mut wrong = Vec::new();
    for (rec, table) in given {
        match &table {
            Some(_) if !rec.ok() => {
                wrong.push(format!("{}: a table beside a failed record", rec.run))
            }
            Some(t) if t.name != rec.run => wrong.push(format!(
                "{}: the table of run {:?} beside its record",
                rec.run, t.name
            )),
            None if rec.ok() => wrong.push(format!("{}: an ok record without its table", rec.run)),
            _ => {}
        }
        let name = rec.run.clone();
        if by_name.insert(name.clone(), (rec, table)).is_some() {
            wrong.push(format!("{name}: given twice"));
        }
    }
    let mut missing = Vec::new();
    let (mut records, mut tables) = (Vec::new(), Vec::new());
    for (name, _) in logs {
        match by_name.remove(name) {
            Some((rec, table)) => {
                records.push(rec);
                tables.extend(table);
            }
            None => missing.push(name.clone()),
        }
    }
    let mut foreign: Vec<String> = by_name.into_keys().collect();
    foreign.sort();
    wrong.extend(
        foreign
            .into_iter()
            .map(|n| format!("{n}: not a run of this campaign")),
    );
    if !missing.is_empty() {
        wrong.insert(
            0,
            format!(
                "{} of the campaign's {} runs were not given: {}",
                missing.len(),
                logs.len(),
                missing.join(", ")
            ),
        );
    }
    if !wrong.is_empty() {
        return Err(CampaignError::Input {
            path: out.runs(),
            message: wrong.join("; "),
            hint: "give every run of the campaign once, each with the record and table its estimate task returned".into(),
        });
    }
    Ok((records, tables))
}

/// Stage 1: every run, in parallel on a pool of `options.jobs` threads, each on its own.
/// Records in the order of `logs`; tables of the runs that could be estimated.
pub fn estimate_runs(
    root: &Path,
    logs: &[(String, LogSource)],
    out: &OutDir,
    pipeline: &Pipeline,
    options: Options,
    progress: CampaignProgress<'_>,
) -> Result<(Vec<RunRecord>, Vec<RunTable>), CampaignError> {
    estimate_each(root, logs, out, pipeline, options, progress, |_, t| t)
}

/// Stage 1 with `keep` taking each estimated run's table as it is done.
fn estimate_each<T: Send>(
    root: &Path,
    logs: &[(String, LogSource)],
    out: &OutDir,
    pipeline: &Pipeline,
    options: Options,
    progress: CampaignProgress<'_>,
    keep: impl Fn(&str, RunTable) -> T + Sync,
) -> Result<(Vec<RunRecord>, Vec<T>), CampaignError> {
    let results = each_run(
        root,
        logs,
        options,
        progress,
        |name, src| {
            let (rec, table) = process_run(src, name, out, pipeline, options.force);
            (rec, table.map(|t| keep(name, t)))
        },
        |(rec, _)| Some(rec),
    )?;
    let (records, tables): (Vec<RunRecord>, Vec<Option<T>>) = results.into_iter().unzip();
    Ok((records, tables.into_iter().flatten().collect()))
}

/// Makes the output folder ready before any work (a read-only folder was found only
/// after training, and a killed re-run could leave new models beside an old report): creates
/// its folders and writes a probe file in each (the error names the folder and the OS cause),
/// removes the temporary files of earlier runs that no longer live, and removes the campaign
/// record and the report, which the end of this run writes again — so a run that does not
/// finish leaves no report that looks current.
pub fn prepare_output(out: &OutDir) -> Result<(), CampaignError> {
    make_output_folders(out)?;
    crate::atomic::remove_stale_temporaries(out.root(), 3);
    remove_campaign_results(out)
}

/// Creates the output's folders and writes a probe file in each (the error names the folder
/// and the OS cause).
fn make_output_folders(out: &OutDir) -> Result<(), CampaignError> {
    let models = out.models();
    for dir in [
        out.root().to_path_buf(),
        out.runs(),
        models.dir.clone(),
        out.report_dir(),
    ] {
        // Unique across the nodes of a shared file system (shards on several machines).
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let probe = dir.join(format!(".railgrip-probe-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&dir)
            .and_then(|_| std::fs::write(&probe, b"probe"))
            .and_then(|_| std::fs::remove_file(&probe))
            .map_err(|source| CampaignError::Write { path: dir, source })?;
    }
    Ok(())
}

/// Removes the campaign record and the report, which only a finished campaign writes.
fn remove_campaign_results(out: &OutDir) -> Result<(), CampaignError> {
    for f in [out.campaign_record(), out.report_html()] {
        match std::fs::remove_file(&f) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(CampaignError::Write { path: f, source: e })
            }
            _ => {}
        }
    }
    // The runs' own report pages (large campaigns) go with the page that links them.
    let pages = out.report_dir().join("runs");
    match std::fs::remove_dir_all(&pages) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(CampaignError::Write {
            path: pages,
            source: e,
        }),
        _ => Ok(()),
    }
}

/// With `mcap`, writes each estimated run's `<run>.railgrip.mcap` (its estimates and the
/// campaign's chosen model's μ, or the estimates alone when no model was trained), in parallel;
/// without, removes such files an earlier run left (they would show an older model).
/// A run whose replay cannot be written gets a note; the others go on.
fn replay_stage(
    out: &OutDir,
    records: &[RunRecord],
    trained: &Trained,
    mcap: bool,
    jobs: Option<usize>,
) -> Vec<String> {
    if !mcap {
        for r in records {
            let _ = std::fs::remove_file(out.run_replay(&r.run));
        }
        return vec![];
    }
    let mut load_note = None;
    let model = match &trained.chosen {
        Some(chosen) => crate::model::Model::load(chosen)
            .map_err(|e| {
                load_note = Some(format!("replay MCAP files hold the estimates only: {e}"))
            })
            .ok(),
        None => {
            load_note =
                Some("replay MCAP files hold the estimates only: no model was trained".into());
            None
        }
    };
    for r in records.iter().filter(|r| !r.ok()) {
        // A failed run has no estimates; no replay of an earlier run stays beside it.
        let _ = std::fs::remove_file(out.run_replay(&r.run));
    }
    let ok: Vec<&RunRecord> = records.iter().filter(|r| r.ok()).collect();
    let pool = match crate::parallel::pool(jobs) {
        Ok(pool) => pool,
        Err(e) => {
            // None written: none of an earlier run stays beside the new models either.
            for r in &ok {
                let _ = std::fs::remove_file(out.run_replay(&r.run));
            }
            let mut notes = vec![format!("replay MCAP files not written: no threads: {e}")];
            notes.extend(load_note);
            return notes;
        }
    };
    let mut notes: Vec<String> = crate::parallel::each(&pool, &ok, |r| {
        let path = out.run_replay(&r.run);
        crate::replay::ReplayRun::read_parquet(&out.run_estimates(&r.run), r.ambient_temperature_c)
            .and_then(|run| {
                crate::replay::write_replay(
                    &path,
                    &run,
                    model.as_ref(),
                    r.start_log_time_ns.unwrap_or(0),
                )
            })
            .err()
            .map(|e| format!("{}: replay not written: {e}", r.run))
    })
    .into_iter()
    .flatten()
    .collect();
    notes.extend(load_note);
    notes
}

/// What the train stage left.
struct Trained {
    condition: Option<String>,
    models: Vec<PathBuf>,
    model_error: Option<String>,
    audit: Option<crate::model::AuditSpec>,
    notes: Vec<String>,
    /// Network training epochs and seconds (for `timings.json`).
    epochs: usize,
    train_s: Option<f64>,
    /// The chosen model's file, and the choice (which candidate it is and why).
    chosen: Option<PathBuf>,
    choice: Option<Choice>,
}

/// Stage 2: the campaign's models from the pooled tables, written with their C headers.
/// A campaign whose models cannot be trained still completes (the reason is in the outcome);
/// models that cannot be written fail it.
fn train_stage(
    tables: Vec<PooledRun>,
    out: &OutDir,
    pipeline: &Pipeline,
    generation: &str,
    progress: CampaignProgress<'_>,
) -> Result<Trained, CampaignError> {
    let mut t = Trained {
        condition: None,
        models: vec![],
        model_error: None,
        audit: None,
        notes: vec![],
        epochs: 0,
        train_s: None,
        chosen: None,
        choice: None,
    };
    if tables.is_empty() {
        t.model_error = Some("no run could be estimated, so no model was trained".to_string());
        return Ok(t);
    }
    progress.event(Event::TrainStarts);
    let epochs = |e: &Epoch| progress.event(Event::Epoch(e));
    match train_pooled(tables, pipeline, Some(&epochs)) {
        Ok(mut m) => {
            m.set_generation(generation);
            t.epochs = m.trained.history.len();
            t.train_s = m.trained.history.last().map(|e| e.elapsed_s);
            t.condition = Some(m.condition.clone());
            t.notes.extend(m.notes.iter().cloned());
            for (run, c) in &m.skipped {
                t.notes.push(format!(
                    "{run}: not used for the models (condition {c}; they train on {})",
                    m.condition
                ));
            }
            t.audit = m.mlp.audit.clone();
            t.models = m.write(&out.models(), true)?;
            t.chosen = Some(out.models().candidate(&m.choice.chosen));
            t.choice = Some(m.choice.clone());
        }
        Err(e) => t.model_error = Some(e.to_string()),
    }
    Ok(t)
}
