//! The training tables of a mix of inputs — what `railgrip train` and the Python package's
//! `train` take: estimates tables, run logs (estimated on the fly), campaign folders and
//! archives (their logs as [`super::run`] finds them); logs and campaigns also as
//! `s3://BUCKET/KEY` or `s3://BUCKET/PREFIX`.

use std::path::{Path, PathBuf};

use super::pool::{Pool, PooledRun};
use super::CampaignError;
use crate::config::Pipeline;
use crate::identify::dataset::RunTable;
use crate::ingest::LogSource;

/// One input: an estimates table or a log with its run name.
enum Input {
    Table(PathBuf),
    Log(String, LogSource),
}

/// The run name of a single log: its file stem.
fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "run".into())
}

/// Expands folders and archives into their logs (as `railgrip run` lists them).
fn expand(inputs: &[PathBuf]) -> Result<Vec<Input>, CampaignError> {
    let mut out = Vec::new();
    for given in inputs {
        let text = given.display().to_string();
        let p = match crate::store::Location::parse(&text)? {
            crate::store::Location::Local(p) => p,
            crate::store::Location::S3 { bucket, prefix } => {
                // A log in a bucket, or a campaign there (a prefix of logs or an archive object).
                let lower = prefix.to_ascii_lowercase();
                if lower.ends_with(".parquet") {
                    return Err(CampaignError::Input {
                        path: given.clone(),
                        message: "an estimates table in a bucket".into(),
                        hint: "give the run's log (s3://…/run.csv or .mcap), or copy the table to a local path".into(),
                    });
                }
                if lower.ends_with(".csv") || lower.ends_with(".mcap") {
                    out.push(Input::Log(stem(given), LogSource::at(&text)?));
                } else {
                    let b = crate::store::Bucket::connect(&bucket)?;
                    for (run, src) in super::remote::bucket_sources(&b, &prefix, None)?.0 {
                        out.push(Input::Log(run, src));
                    }
                }
                continue;
            }
        };
        if text.ends_with(".parquet") {
            out.push(Input::Table(p));
        } else if p.is_dir() || crate::archive::kind_of(&p).is_some() {
            for (run, src) in super::sources(&p, None)? {
                out.push(Input::Log(run, src));
            }
        } else {
            out.push(Input::Log(stem(&p), LogSource::File(p)));
        }
    }
    Ok(out)
}

/// Reads `inputs` as run tables, in parallel, in the order given (a folder's or archive's logs
/// in the order `railgrip run` lists them): `*.parquet` are estimates tables written by
/// `railgrip estimate` (their valid rows), anything else a log, folder or archive, estimated
/// with `pipeline`. The first input that fails is the error (it names the file).
pub fn load_tables(
    inputs: &[PathBuf],
    pipeline: &Pipeline,
) -> Result<Vec<RunTable>, CampaignError> {
    load_each(inputs, pipeline, |t, _| t)
}

/// [`load_tables`] for the models ([`super::train_pooled`]): an estimates table is held while
/// the tables held stay within `train.max_pooled_samples`, else parked in its own file and
/// read back thinned ([`super::pool`]). A log estimated on the fly has no file to be read back
/// from, so its table is always held.
pub fn load_pooled(
    inputs: &[PathBuf],
    pipeline: &Pipeline,
) -> Result<Vec<PooledRun>, CampaignError> {
    let pool = Pool::new(pipeline.train.max_pooled_samples);
    load_each(inputs, pipeline, |t, file| match file {
        Some(p) => pool.admit_read(t, p),
        None => PooledRun::Held(t),
    })
}

/// Each input's table given to `keep` with the estimates file it was read from (None for a
/// log, estimated on the fly). Every input is read before the first error (in the inputs'
/// order) is returned.
fn load_each<T: Send>(
    inputs: &[PathBuf],
    pipeline: &Pipeline,
    keep: impl Fn(RunTable, Option<&Path>) -> T + Sync,
) -> Result<Vec<T>, CampaignError> {
    let inputs = expand(inputs)?;
    // As many threads as rayon's global pool, at most two inputs per thread under way (the
    // reads go through polars' pool: [`crate::parallel::each`]).
    let pool = crate::parallel::pool(None)?;
    crate::parallel::each(&pool, &inputs, |input| -> Result<T, CampaignError> {
        let (run, src) = match input {
            Input::Table(p) => return Ok(keep(RunTable::read_parquet(p)?, Some(p))),
            Input::Log(run, src) => (run, src),
        };
        // A log in a bucket is fetched once for the estimation and the hash.
        let src = &src.fetched().map_err(|source| CampaignError::Read {
            path: src.name().to_path_buf(),
            source,
        })?;
        let name = src.name().display().to_string();
        let log = crate::ingest::ingest_source(src, pipeline)?;
        let e = crate::estimate::estimate(&log, pipeline)?;
        let (_, sha) = super::input_hash(src, pipeline).map_err(|source| CampaignError::Read {
            path: src.name().to_path_buf(),
            source,
        })?;
        Ok(keep(RunTable::from_estimates(run, &name, &sha, &e), None))
    })
    .into_iter()
    .collect()
}
