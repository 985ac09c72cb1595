//! Campaigns in buckets: the logs of an `s3://bucket/prefix` (a "folder" of logs, or one
//! archive object), and output folders in a bucket, staged in a local folder and written back
//! object by object ([`run_at`]).
//!
//! An output prefix is written so that a reader never takes a half-written campaign for a
//! finished one: `campaign.json` and the report are removed first and written last, every
//! other object in between, each by one atomic PUT; objects of an earlier campaign that this
//! one no longer writes (a replay MCAP without `--mcap`) are removed.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::{
    run_sources, sources_all, CampaignError, CampaignProgress, Given, Options, OutDir, Outcome,
    Part, Skipped, Sources,
};
use crate::config::Pipeline;
use crate::ingest::LogSource;
use crate::store::{join, Bucket, Location, ObjectLog};

/// [`super::run`] with the campaign and the output folder given as locations: local paths,
/// `file://PATH` or `s3://BUCKET/PREFIX` (credentials and endpoint from the AWS environment
/// variables, see [`crate::store`]). The same inputs give the same files wherever they live;
/// the outcome names output files by their URIs.
pub fn run_at(
    archive: &str,
    out: &str,
    pipeline: &Pipeline,
    options: Options,
    progress: CampaignProgress<'_>,
) -> Result<Outcome, CampaignError> {
    let out_at = Location::parse(out)?;
    let (root, (logs, skipped)) = sources_at(archive, Some(&out_at))?;
    run_logs_at(
        &root, logs, skipped, out_at, pipeline, options, progress, None,
    )
}

/// One run of the campaign at `archive` into `out` (locations as [`run_at`] takes them), as an
/// estimate shard of that run alone writes it, without listing the campaign when the run's
/// `log` location is given (a file or an object, as [`campaign_logs_at`] names it; a member of
/// an archive has none, and the archive is read to find it). The outcome's record and table
/// are what [`models_at`] takes. This is the work of one task on a cluster (one Ray task per
/// run): each task reads its own log and its own run's outputs only.
pub fn estimate_run_at(
    archive: &str,
    run: &str,
    log: Option<&str>,
    out: &str,
    pipeline: &Pipeline,
    options: Options,
    progress: CampaignProgress<'_>,
) -> Result<Outcome, CampaignError> {
    let out_at = Location::parse(out)?;
    let (root, logs, skipped) = match log {
        Some(l) => {
            let root = Location::parse(archive)?.root();
            (root, vec![(run.to_string(), LogSource::at(l)?)], vec![])
        }
        None => {
            let (root, (logs, skipped)) = sources_at(archive, Some(&out_at))?;
            let mine: Vec<(String, LogSource)> =
                logs.into_iter().filter(|(name, _)| name == run).collect();
            if mine.is_empty() {
                return Err(CampaignError::Input {
                    path: root,
                    message: format!("the campaign has no run named {run:?}"),
                    hint: "give a run name as the campaign's listing gives it (railgrip.ray lists them with _native.campaign_runs)".into(),
                });
            }
            (root, mine, skipped)
        }
    };
    let options = Options {
        part: Part::Estimate(super::Shard { k: 1, n: 1 }),
        tables: true,
        ..options
    };
    run_logs_at(
        &root, logs, skipped, out_at, pipeline, options, progress, None,
    )
}

/// The models part of the campaign at `archive` ([`Part::Models`]) trained on the runs as
/// their estimate tasks returned them (`given`: every run of the campaign, records and
/// tables), instead of reading them back from `out`; the summary, `campaign.json` and the
/// report are written as [`run_at`] writes them, from `out`'s run folders.
pub fn models_at(
    archive: &str,
    out: &str,
    pipeline: &Pipeline,
    options: Options,
    progress: CampaignProgress<'_>,
    given: Given,
) -> Result<Outcome, CampaignError> {
    let out_at = Location::parse(out)?;
    let (root, (logs, skipped)) = sources_at(archive, Some(&out_at))?;
    let options = Options {
        part: Part::Models,
        ..options
    };
    run_logs_at(
        &root,
        logs,
        skipped,
        out_at,
        pipeline,
        options,
        progress,
        Some(given),
    )
}

/// The campaign's logs in the campaign's order, as [`run_at`] finds them with its output at
/// `out`: (run name, the log's name as records give it, its location — a file's path or an
/// object's URI; a member of an archive has none).
pub fn campaign_logs_at(
    archive: &str,
    out: Option<&str>,
) -> Result<Vec<(String, String, Option<String>)>, CampaignError> {
    let out = out.map(Location::parse).transpose()?;
    let (_, (logs, _)) = sources_at(archive, out.as_ref())?;
    Ok(logs
        .into_iter()
        .map(|(run, src)| {
            let name = src.name().display().to_string();
            let at = match &src {
                LogSource::File(_) | LogSource::Object { .. } => Some(name.clone()),
                LogSource::Memory { .. } => None,
            };
            (run, name, at)
        })
        .collect())
}

/// [`run_sources`] into the output location `out_at`: a local folder as it is, a bucket's
/// prefix staged in a local folder (pulled before, pushed after).
#[allow(clippy::too_many_arguments)]
fn run_logs_at(
    root: &Path,
    logs: Vec<(String, LogSource)>,
    skipped: Vec<Skipped>,
    out_at: Location,
    pipeline: &Pipeline,
    options: Options,
    progress: CampaignProgress<'_>,
    given: Option<Given>,
) -> Result<Outcome, CampaignError> {
    match out_at {
        Location::Local(dir) => run_sources(
            root,
            logs,
            skipped,
            &OutDir::new(&dir),
            pipeline,
            options,
            progress,
            given,
        ),
        Location::S3 { bucket, prefix } => {
            let b = Bucket::connect(&bucket)?;
            // A shard fetches what its own runs need, a campaign every run's.
            let only: Option<Vec<&str>> = match options.part {
                Part::Estimate(shard) => Some(
                    logs.iter()
                        .enumerate()
                        .filter(|(i, _)| shard.has(*i))
                        .map(|(_, (run, _))| run.as_str())
                        .collect(),
                ),
                Part::Calibrate => Some(vec![]),
                Part::All | Part::Models => None,
            };
            let staged = Staged::pull(Arc::clone(&b), &prefix, only.as_deref())?;
            let result = run_sources(
                root,
                logs,
                skipped,
                &OutDir::new(&staged.dir),
                pipeline,
                options,
                progress,
                given,
            )
            .map_err(|e| staged.remote_error(&e, &b.uri(&prefix), false));
            let o = match result {
                Ok(o) => o,
                Err(e) => {
                    let _ = std::fs::remove_dir_all(&staged.dir);
                    return Err(e);
                }
            };
            // A failed upload keeps the staged outputs and says where they are.
            staged
                .push(&o, options.part)
                .map_err(|e| staged.remote_error(&e, &b.uri(&prefix), true))?;
            let _ = std::fs::remove_dir_all(&staged.dir);
            Ok(staged.rename(o, &b.uri(&prefix)))
        }
    }
}

/// The campaign at `archive` (a path, `file://` or `s3://` location): its root as outputs
/// name it, its logs with their run names and the files that are not logs. `out`, when it lies
/// inside the campaign, is left out of the search.
pub fn sources_at(
    archive: &str,
    out: Option<&Location>,
) -> Result<(PathBuf, Sources), CampaignError> {
    Ok(match Location::parse(archive)? {
        Location::Local(root) => {
            let skip = match out {
                Some(Location::Local(p)) => Some(p.as_path()),
                _ => None,
            };
            let sources = sources_all(&root, skip)?;
            (root, sources)
        }
        Location::S3 { bucket, prefix } => {
            let b = Bucket::connect(&bucket)?;
            let skip = match out {
                Some(Location::S3 {
                    bucket: ob,
                    prefix: op,
                }) if *ob == bucket => Some(op.as_str()),
                _ => None,
            };
            let sources = bucket_sources(&b, &prefix, skip)?;
            (Location::S3 { bucket, prefix }.root(), sources)
        }
    })
}

/// The logs below `prefix` in `bucket` (or the archive object `prefix` names: `.zip`, `.tar`,
/// `.tar.gz`, `.tgz`, `.tar.zst`), with the run
/// names and skipped files a local folder of the same layout would give; keys below `skip`
/// (an output prefix inside the campaign's) and hidden keys are left out.
pub(super) fn bucket_sources(
    bucket: &Arc<Bucket>,
    prefix: &str,
    skip: Option<&str>,
) -> Result<Sources, CampaignError> {
    let uri = bucket.uri(prefix);
    // An archive object by its name (a local archive is recognised by its first bytes; a
    // key is not fetched to find out).
    let lower = prefix.to_ascii_lowercase();
    if [".zip", ".tar", ".tar.gz", ".tgz", ".tar.zst"]
        .iter()
        .any(|e| lower.ends_with(e))
    {
        return archive_object(bucket, prefix);
    }
    let objects = bucket.list(prefix)?;
    let root = PathBuf::from(&uri);
    let mut sizes = std::collections::BTreeMap::new();
    let files: Vec<PathBuf> = objects
        .into_iter()
        .filter(|o| {
            let rel = o.key.strip_prefix(prefix).unwrap_or(&o.key);
            !rel.split('/').any(|c| c.starts_with('.'))
                && !skip.is_some_and(|s| {
                    !s.is_empty() && (o.key == s || o.key.starts_with(&format!("{s}/")))
                })
        })
        .map(|o| {
            let p = PathBuf::from(bucket.uri(&o.key));
            sizes.insert(p.clone(), (o.key, o.size));
            p
        })
        .collect();
    if files.is_empty() {
        return Err(CampaignError::Input {
            path: root,
            message: "no objects below this prefix".into(),
            hint: "give the prefix that holds the campaign's logs (aws s3 ls s3://BUCKET/PREFIX/ lists them)".into(),
        });
    }
    let (logs, skipped) = super::runs::classify(&root, files);
    if logs.is_empty() {
        return Err(CampaignError::Input {
            path: root,
            message: "no .csv or .mcap logs below this prefix".into(),
            hint: "give the prefix that holds the campaign's logs (aws s3 ls s3://BUCKET/PREFIX/ lists them)".into(),
        });
    }
    let logs = logs
        .into_iter()
        .map(|p| {
            let (key, size) = sizes[&p].clone();
            let side = p.with_extension("").display().to_string() + crate::format::SIDECAR_SUFFIX;
            let sidecar = (p.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")))
                .then(|| sizes.get(Path::new(&side)).map(|(k, _)| k.clone()))
                .flatten();
            let name = super::run_name(&root, &p);
            (
                name,
                LogSource::Object {
                    name: p,
                    object: ObjectLog {
                        bucket: Arc::clone(bucket),
                        key,
                        size,
                        sidecar,
                    },
                },
            )
        })
        .collect();
    Ok((super::unique_names(logs), skipped))
}

/// A campaign archive stored as one object: fetched to a temporary file, read in place like a
/// local archive, its members named below the object's URI.
fn archive_object(bucket: &Arc<Bucket>, key: &str) -> Result<Sources, CampaignError> {
    let uri = PathBuf::from(bucket.uri(key));
    let limits = crate::archive::Limits::default();
    let bytes = bucket.get(key, limits.max_total_bytes)?;
    let name = Path::new(key).file_name().unwrap_or_default();
    let tmp = std::env::temp_dir().join(format!(
        "railgrip-{}-{}",
        std::process::id(),
        name.to_string_lossy()
    ));
    std::fs::write(&tmp, bytes).map_err(|source| CampaignError::Write {
        path: tmp.clone(),
        source,
    })?;
    let listing = sources_all(&tmp, None);
    let _ = std::fs::remove_file(&tmp);
    let (logs, skipped) = listing?;
    let rename = |p: &Path| uri.join(p.strip_prefix(&tmp).unwrap_or(p));
    let logs = logs
        .into_iter()
        .map(|(run, src)| match src {
            LogSource::Memory {
                name,
                bytes,
                sidecar,
            } => (
                run,
                LogSource::Memory {
                    name: rename(&name),
                    bytes,
                    sidecar,
                },
            ),
            other => (run, other),
        })
        .collect();
    let skipped = skipped
        .into_iter()
        .map(|s| Skipped {
            path: s.path,
            reason: s.reason,
        })
        .collect();
    Ok((logs, skipped))
}

/// An output prefix staged in a local folder: what reuse needs (each run's record and
/// estimates table) is fetched before the campaign, everything it writes pushed after.
struct Staged {
    bucket: Arc<Bucket>,
    prefix: String,
    dir: PathBuf,
    /// What was fetched: relative path → SHA-256 of its bytes (an unchanged file is not put
    /// back).
    pulled: std::collections::HashMap<String, String>,
}

/// The files a finished campaign writes last (and a new one removes first).
const LAST: [&str; 2] = ["campaign.json", "report/index.html"];
/// The files railgrip writes at the top of an output folder.
const OWNED_TOP: [&str; 5] = [
    "calibration.json",
    "campaign.json",
    "summary.csv",
    "summary.parquet",
    "timings.json",
];

impl Staged {
    /// Fetches the records and tables of the runs in `only` (every run's when None).
    fn pull(
        bucket: Arc<Bucket>,
        prefix: &str,
        only: Option<&[&str]>,
    ) -> Result<Staged, CampaignError> {
        let dir = crate::store::staging_dir(&bucket.uri(prefix));
        let mut staged = Staged {
            bucket,
            prefix: prefix.to_string(),
            dir,
            pulled: Default::default(),
        };
        if let Err(e) = staged.fetch_runs(only) {
            let _ = std::fs::remove_dir_all(&staged.dir);
            return Err(e);
        }
        Ok(staged)
    }

    /// The objects below `runs/<run>/` of each of `runs` (a shard's own folders: a task per
    /// run must not list them all).
    fn list_runs(&self, runs: &[&str]) -> Result<Vec<crate::store::Object>, CampaignError> {
        let mut all = Vec::new();
        for run in runs {
            all.extend(
                self.bucket
                    .list(&join(&self.prefix, &format!("runs/{run}/")))?,
            );
        }
        Ok(all)
    }

    fn fetch_runs(&mut self, only: Option<&[&str]>) -> Result<(), CampaignError> {
        let listed = match only {
            Some(runs) => self.list_runs(runs)?,
            None => self.bucket.list(&join(&self.prefix, "runs/"))?,
        };
        // The campaign's calibration: what its parts take, and what a whole campaign reuses.
        let cal_key = join(&self.prefix, super::calibration::CALIBRATION_FILE);
        let cal = self
            .bucket
            .head(&cal_key)?
            .map(|size| crate::store::Object { key: cal_key, size });
        let top = join(&self.prefix, "");
        for o in listed.into_iter().chain(cal) {
            let rel = o
                .key
                .strip_prefix(&top)
                .unwrap_or(&o.key)
                .trim_start_matches('/');
            if rel.ends_with(".railgrip.mcap") {
                continue; // rewritten or removed by every campaign
            }
            let bytes = self
                .bucket
                .get(&o.key, crate::ingest::MAX_OBJECT_LOG_BYTES)?;
            let path = self.dir.join(rel);
            let sha = crate::hash::sha256_bytes(&bytes);
            std::fs::create_dir_all(path.parent().unwrap_or(&self.dir))
                .and_then(|_| std::fs::write(&path, bytes))
                .map_err(|source| CampaignError::Write { path, source })?;
            self.pulled.insert(rel.to_string(), sha);
        }
        Ok(())
    }

    /// Writes the staged outputs back: an estimate shard its runs' folders only; a campaign
    /// everything, `campaign.json` and the report last. Objects railgrip wrote before and no
    /// longer writes are removed — only below the names railgrip owns in an output folder
    /// (`runs/<run>/` of the runs written, `models/`, `report/` and the top-level files), never
    /// anything else below the prefix.
    fn push(&self, o: &Outcome, part: Part) -> Result<(), CampaignError> {
        let files = files_below(&self.dir)?;
        let key = |rel: &str| join(&self.prefix, rel);
        let rel_of = |k: &str| -> String {
            k.strip_prefix(&join(&self.prefix, ""))
                .unwrap_or(k)
                .trim_start_matches('/')
                .to_string()
        };
        let run_dirs: Vec<String> = o
            .records
            .iter()
            .map(|r| format!("runs/{}/", r.run))
            .collect();
        if part == Part::Calibrate {
            // The campaign's results no longer describe the runs to be estimated.
            for f in LAST {
                self.bucket.delete(&key(f))?;
            }
            let rel = super::calibration::CALIBRATION_FILE;
            return if files.iter().any(|f| f == rel) {
                self.upload(rel)
            } else {
                Ok(self.bucket.delete(&key(rel))?)
            };
        }
        let shard = matches!(part, Part::Estimate(_));
        // What is there now: a shard looks at its own runs' folders only.
        let listed = if shard {
            let runs: Vec<&str> = o.records.iter().map(|r| r.run.as_str()).collect();
            self.list_runs(&runs)?
        } else {
            self.bucket.list(&self.prefix)?
        };
        let before: Vec<String> = listed.into_iter().map(|o| rel_of(&o.key)).collect();
        let in_runs = |rel: &str| run_dirs.iter().any(|d| rel.starts_with(d.as_str()));
        // The finished campaign's files go first: from here on the prefix is not finished.
        for f in LAST {
            self.bucket.delete(&key(f))?;
        }
        for rel in files
            .iter()
            .filter(|r| !LAST.contains(&r.as_str()) && (!shard || in_runs(r)))
        {
            self.upload(rel)?;
        }
        let owned = |rel: &str| {
            if shard {
                in_runs(rel)
            } else {
                in_runs(rel)
                    || rel.starts_with("models/")
                    || rel.starts_with("report/")
                    || OWNED_TOP.contains(&rel)
            }
        };
        for rel in before.iter().filter(|r| owned(r) && !files.contains(r)) {
            self.bucket.delete(&key(rel))?;
        }
        if !shard {
            for rel in files.iter().filter(|r| LAST.contains(&r.as_str())) {
                self.upload(rel)?;
            }
        }
        Ok(())
    }

    /// Puts one staged file, unless it is the object that was fetched, unchanged.
    fn upload(&self, rel: &str) -> Result<(), CampaignError> {
        let path = self.dir.join(rel);
        let bytes = std::fs::read(&path).map_err(|source| CampaignError::Read { path, source })?;
        if self
            .pulled
            .get(rel)
            .is_some_and(|sha| *sha == crate::hash::sha256_bytes(&bytes))
        {
            return Ok(());
        }
        Ok(self.bucket.put(&join(&self.prefix, rel), bytes)?)
    }

    /// `e` with the staging folder's paths replaced by the output's URI (and, when `kept`,
    /// where the staged outputs wait).
    fn remote_error(&self, e: &CampaignError, uri: &str, kept: bool) -> CampaignError {
        let mut text = e.to_string().replace(&self.dir.display().to_string(), uri);
        if kept {
            text.push_str(&format!(
                " (the outputs are kept in {}; run again to write them)",
                self.dir.display()
            ));
        }
        CampaignError::Remote(text)
    }

    /// The outcome with the staged paths replaced by the prefix's URIs.
    fn rename(&self, mut o: Outcome, uri: &str) -> Outcome {
        let to_uri = |p: &Path| match p.strip_prefix(&self.dir) {
            Ok(rel) => PathBuf::from(uri).join(rel),
            Err(_) => p.to_path_buf(),
        };
        o.models = o.models.iter().map(|p| to_uri(p)).collect();
        o.report = o.report.as_deref().map(to_uri);
        o.chosen = o.chosen.as_deref().map(to_uri);
        let dir = self.dir.display().to_string();
        for n in &mut o.notes {
            *n = n.replace(&dir, uri);
        }
        o
    }
}

/// Every file below `dir`, as `/`-separated relative paths, sorted.
fn files_below(dir: &Path) -> Result<Vec<String>, CampaignError> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries = std::fs::read_dir(&d).map_err(|source| CampaignError::Read {
            path: d.clone(),
            source,
        })?;
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if let Ok(rel) = p.strip_prefix(dir) {
                let rel = rel.to_string_lossy().replace('\\', "/");
                // Temporary files of atomic writes are not outputs.
                if !rel.rsplit('/').next().unwrap_or("").starts_with('.') {
                    out.push(rel);
                }
            }
        }
    }
    out.sort();
    Ok(out)
}
