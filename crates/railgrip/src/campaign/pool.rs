//! The runs' tables on their way to the models, held within `train.max_pooled_samples`.
//!
//! The models train on at most `train.max_pooled_samples` pooled valid samples: over it, every
//! run and axle keeps every m-th sample ([`crate::identify::pooled_thinning`]), and m depends
//! on every run's counts. So that the campaign's tables do not all wait in memory until the
//! last run is estimated (a 10 000-run campaign's would take ~32 GB), a [`Pool`] holds a
//! run's table only while the tables it holds stay within the limit; any other run's table is
//! *parked*: only its counts are kept, and the table is read back from the estimates file the
//! run wrote, already thinned, when the models need it ([`into_tables`]). A parked table reads
//! back the same numbers as the held one (the estimates file keeps every column in full), so
//! the models are the same bytes whichever runs were parked.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::format::RunMetadata;
use crate::identify::dataset::RunTable;
use crate::identify::{CampaignRun, IdentifyError};

/// A run's table, in memory or parked in its estimates file.
#[derive(Debug, Clone)]
pub enum PooledRun {
    Held(RunTable),
    Parked(ParkedRun),
}

/// A run whose table waits in its estimates file: what choosing the condition and the thinning
/// need, and the provenance the read-back table gets.
#[derive(Debug, Clone)]
pub struct ParkedRun {
    /// The estimates table (`railgrip estimate`'s format) it is read back from.
    pub path: PathBuf,
    pub name: String,
    pub source: String,
    pub sha256: String,
    pub metadata: RunMetadata,
    /// Valid samples of each axle block.
    pub counts: Vec<usize>,
    /// SHA-256 of the file when it was parked: read back, it must be the same file.
    pub file_sha256: String,
}

impl From<RunTable> for PooledRun {
    fn from(t: RunTable) -> PooledRun {
        PooledRun::Held(t)
    }
}

impl CampaignRun for PooledRun {
    fn run_name(&self) -> &str {
        match self {
            PooledRun::Held(t) => &t.name,
            PooledRun::Parked(p) => &p.name,
        }
    }
    fn run_metadata(&self) -> &RunMetadata {
        match self {
            PooledRun::Held(t) => &t.metadata,
            PooledRun::Parked(p) => &p.metadata,
        }
    }
    fn axle_counts(&self) -> Vec<usize> {
        match self {
            PooledRun::Held(t) => t.axle_counts(),
            PooledRun::Parked(p) => p.counts.clone(),
        }
    }
}

impl PooledRun {
    /// Parks `table`, to be read back from `path` (the estimates file it was read from or
    /// written to), whose SHA-256 is `file_sha256` when known (else it is computed here); held
    /// instead when the file cannot be hashed (it could not be read back).
    pub fn park(table: RunTable, path: &Path, file_sha256: Option<String>) -> PooledRun {
        let Some(file_sha256) = file_sha256.or_else(|| crate::hash::sha256_file(path).ok()) else {
            return PooledRun::Held(table);
        };
        PooledRun::Parked(ParkedRun {
            path: path.to_path_buf(),
            counts: table.axle_counts(),
            name: table.name,
            source: table.source,
            sha256: table.sha256,
            metadata: table.metadata,
            file_sha256,
        })
    }

    /// The table thinned to every `m`-th sample of each axle ([`RunTable::thin`]); a parked
    /// one read back from its file, which must be the file it was parked with (its SHA-256).
    pub fn into_thinned(self, m: usize) -> Result<RunTable, IdentifyError> {
        let mut t = match self {
            PooledRun::Held(t) => t,
            PooledRun::Parked(p) => {
                // `read_parquet` gives the table the file's own SHA-256.
                let mut t = RunTable::read_parquet(&p.path).map_err(|e| IdentifyError::Input {
                    file: p.path.display().to_string(),
                    message: format!(
                        "run {}: its estimates table, left in this file for the training, does not read back ({})",
                        p.name,
                        match &e {
                            IdentifyError::Input { message, .. } => message.clone(),
                            IdentifyError::Table { source, .. } => source.to_string(),
                            IdentifyError::Read { source, .. } => source.to_string(),
                            other => other.to_string(),
                        }
                    ),
                    hint: "run the campaign again and leave its output folder (or the tables given) alone while it runs".into(),
                })?;
                if t.sha256 != p.file_sha256 || t.axle_counts() != p.counts {
                    return Err(IdentifyError::Input {
                        file: p.path.display().to_string(),
                        message: format!(
                            "run {}: the estimates file changed between its estimate and the training (its SHA-256 was {}, now {})",
                            p.name, p.file_sha256, t.sha256
                        ),
                        hint: "run the campaign again and leave its output folder (or the tables given) alone while it runs".into(),
                    });
                }
                t.name = p.name;
                t.source = p.source;
                t.sha256 = p.sha256;
                t.metadata = p.metadata;
                t
            }
        };
        t.thin(m);
        Ok(t)
    }
}

/// Holds runs' tables while the samples it holds stay within a limit, and parks the rest
/// ([`PooledRun::park`]). Safe to share between the threads that estimate the runs; which runs
/// are held then depends on the order they finish, the tables the models get do not.
#[derive(Debug)]
pub struct Pool {
    limit: usize,
    held: AtomicUsize,
}

impl Pool {
    /// A pool for `limit` samples: `train.max_pooled_samples`, which the thinning brings the
    /// models' samples within anyway.
    pub fn new(limit: usize) -> Pool {
        Pool {
            limit,
            held: AtomicUsize::new(0),
        }
    }

    /// `table` held, or parked in `path` when holding it would take the pool over its limit.
    pub fn admit(&self, table: RunTable, path: &Path) -> PooledRun {
        self.admit_known(table, path, None)
    }

    /// [`Pool::admit`] for a table [`RunTable::read_parquet`] read from `path` itself, whose
    /// `sha256` is therefore the file's: it is not hashed again when parked.
    pub fn admit_read(&self, table: RunTable, path: &Path) -> PooledRun {
        let sha = table.sha256.clone();
        self.admit_known(table, path, Some(sha))
    }

    fn admit_known(&self, table: RunTable, path: &Path, file_sha256: Option<String>) -> PooledRun {
        let n = table.len();
        let fits = self
            .held
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |h| {
                (h + n <= self.limit).then_some(h + n)
            })
            .is_ok();
        if fits {
            PooledRun::Held(table)
        } else {
            PooledRun::park(table, path, file_sha256)
        }
    }
}

/// The runs' tables, each thinned by `m`: the held ones first (giving their memory back), then
/// the parked ones read back one at a time, so that at most one full table is in memory beside
/// the thinned ones. In the order given.
pub fn into_tables(mut runs: Vec<PooledRun>, m: usize) -> Result<Vec<RunTable>, IdentifyError> {
    for r in &mut runs {
        if let PooledRun::Held(t) = r {
            t.thin(m);
        }
    }
    runs.into_iter()
        .map(|r| match r {
            PooledRun::Held(t) => Ok(t),
            parked => parked.into_thinned(m),
        })
        .collect()
}
