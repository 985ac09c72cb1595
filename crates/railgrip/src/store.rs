//! Object storage: campaign folders, logs and output folders addressed as
//! `s3://bucket/prefix` (Amazon S3 and S3-compatible servers, through the `object_store`
//! crate) besides local paths and `file://` URIs.
//!
//! Credentials and the endpoint come from the AWS environment variables `object_store` reads
//! (`AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_SESSION_TOKEN`, `AWS_REGION` or
//! `AWS_DEFAULT_REGION`, `AWS_ENDPOINT_URL` for another server, `AWS_ALLOW_HTTP=true` for a
//! plain-HTTP one). Every call blocks on a small runtime of its own; requests are retried
//! (3 times, 30 s in all) and a connection that does not open within 5 s is an error naming
//! the URI. Each object is written by one PUT, which S3 makes atomic: a reader sees the whole
//! object or none.

use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use futures::TryStreamExt;
use object_store::aws::{AmazonS3, AmazonS3Builder, AmazonS3ConfigKey};
use object_store::path::Path as Key;
use object_store::{ClientConfigKey, ObjectStore, ObjectStoreExt, RetryConfig};

/// Where a campaign, a log or an output folder lives.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// A local path (also what `file://path` names).
    Local(PathBuf),
    /// `s3://bucket/prefix` (the prefix without its trailing `/`, possibly empty).
    S3 { bucket: String, prefix: String },
}

impl Location {
    /// Parses a path, `file://PATH` or `s3://BUCKET[/PREFIX]`; any other `scheme://` is an
    /// error that says which schemes railgrip reads.
    pub fn parse(text: &str) -> Result<Location, StoreError> {
        if let Some(rest) = text.strip_prefix("file://") {
            return Ok(Location::Local(PathBuf::from(rest)));
        }
        if let Some(rest) = text.strip_prefix("s3://") {
            let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
            if bucket.is_empty() {
                return Err(StoreError::new(
                    text,
                    "no bucket",
                    "write s3://BUCKET/PREFIX, e.g. s3://brake-tests/2026/campaign-a",
                ));
            }
            return Ok(Location::S3 {
                bucket: bucket.to_string(),
                prefix: prefix.trim_matches('/').to_string(),
            });
        }
        if let Some((scheme, _)) = text.split_once("://") {
            if !scheme.is_empty()
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '+')
            {
                return Err(StoreError::new(
                    text,
                    &format!("railgrip does not read {scheme}:// locations"),
                    "give a local path, file://PATH or s3://BUCKET/PREFIX",
                ));
            }
        }
        Ok(Location::Local(PathBuf::from(text)))
    }

    /// The name outputs give a campaign at this location: its path, or `s3://BUCKET/PREFIX`
    /// without a trailing `/`.
    pub fn root(&self) -> PathBuf {
        match self {
            Location::Local(p) => p.clone(),
            Location::S3 { bucket, prefix } => {
                PathBuf::from(format!("s3://{bucket}/{prefix}").trim_end_matches('/'))
            }
        }
    }
}

/// An object-storage error: the URI, what went wrong and what to do.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoreError {
    pub uri: String,
    pub message: String,
    pub hint: String,
}

impl StoreError {
    fn new(uri: &str, message: &str, hint: &str) -> StoreError {
        StoreError {
            uri: uri.to_string(),
            message: message.to_string(),
            hint: hint.to_string(),
        }
    }

    /// An `object_store` error at `uri`, with the hint that fits its kind.
    fn from_store(uri: &str, e: &object_store::Error) -> StoreError {
        let hint = match e {
            object_store::Error::NotFound { .. } => {
                "check the bucket and key (aws s3 ls shows what is there)"
            }
            object_store::Error::PermissionDenied { .. }
            | object_store::Error::Unauthenticated { .. } => {
                "check AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY (and AWS_SESSION_TOKEN) and the bucket's policy"
            }
            _ => "check the endpoint (AWS_ENDPOINT_URL, AWS_ALLOW_HTTP=true for http://), the network, the bucket's name and AWS_REGION",
        };
        // object_store's messages nest their causes; the chain says what the server said.
        let mut message = e.to_string();
        let mut source = std::error::Error::source(e);
        while let Some(s) = source {
            let text = s.to_string();
            if !message.contains(&text) {
                message.push_str(": ");
                message.push_str(&text);
            }
            source = s.source();
        }
        StoreError::new(uri, &message, hint)
    }
}

impl fmt::Display for StoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}. Hint: {}", self.uri, self.message, self.hint)
    }
}

impl std::error::Error for StoreError {}

impl From<StoreError> for std::io::Error {
    fn from(e: StoreError) -> std::io::Error {
        std::io::Error::other(e.to_string())
    }
}

/// One object of a listing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Object {
    /// The key below the bucket.
    pub key: String,
    pub size: u64,
}

/// A bucket, connected (the client built; nothing is sent until the first call).
#[derive(Debug)]
pub struct Bucket {
    name: String,
    store: AmazonS3,
    runtime: tokio::runtime::Runtime,
}

impl Bucket {
    /// A client for `bucket` from the AWS environment variables.
    pub fn connect(bucket: &str) -> Result<Arc<Bucket>, StoreError> {
        let uri = format!("s3://{bucket}");
        let store = AmazonS3Builder::from_env()
            .with_bucket_name(bucket)
            .with_retry(RetryConfig {
                max_retries: 3,
                retry_timeout: Duration::from_secs(30),
                ..RetryConfig::default()
            })
            // Per key, so that the environment's client settings (AWS_ALLOW_HTTP) stay.
            .with_config(
                AmazonS3ConfigKey::Client(ClientConfigKey::ConnectTimeout),
                "5 seconds",
            )
            .with_config(
                AmazonS3ConfigKey::Client(ClientConfigKey::Timeout),
                "300 seconds",
            )
            .build()
            .map_err(|e| StoreError::from_store(&uri, &e))?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| {
                StoreError::new(
                    &uri,
                    &format!("cannot start the I/O runtime: {e}"),
                    "free some threads or memory and run again",
                )
            })?;
        Ok(Arc::new(Bucket {
            name: bucket.to_string(),
            store,
            runtime,
        }))
    }

    /// `s3://bucket/key`.
    pub fn uri(&self, key: &str) -> String {
        format!("s3://{}/{key}", self.name)
    }

    /// Every object below `prefix` (a folder: `prefix/…`; empty: the whole bucket), by key.
    pub fn list(&self, prefix: &str) -> Result<Vec<Object>, StoreError> {
        let uri = self.uri(prefix);
        let p = match prefix.is_empty() {
            true => None,
            false => Some(key(&uri, prefix)?),
        };
        let mut objects: Vec<Object> = self
            .runtime
            .block_on(self.store.list(p.as_ref()).try_collect::<Vec<_>>())
            .map_err(|e| StoreError::from_store(&uri, &e))?
            .into_iter()
            .map(|m| Object {
                key: m.location.as_ref().to_string(),
                size: m.size,
            })
            .collect();
        objects.sort_by(|a, b| a.key.cmp(&b.key));
        Ok(objects)
    }

    /// The bytes of `key`, refused past `limit` bytes (the size the object claims, then the
    /// bytes received).
    pub fn get(&self, k: &str, limit: u64) -> Result<Vec<u8>, StoreError> {
        let uri = self.uri(k);
        let k = key(&uri, k)?;
        let bytes = self
            .runtime
            .block_on(async {
                let r = self.store.get(&k).await?;
                if r.meta.size > limit {
                    return Ok(Err(r.meta.size));
                }
                r.bytes().await.map(Ok)
            })
            .map_err(|e| StoreError::from_store(&uri, &e))?;
        match bytes {
            Ok(b) if b.len() as u64 <= limit => Ok(b.to_vec()),
            Ok(b) => Err(too_large(&uri, b.len() as u64, limit)),
            Err(size) => Err(too_large(&uri, size, limit)),
        }
    }

    /// The size of `key`, or None when there is no such object.
    pub fn head(&self, k: &str) -> Result<Option<u64>, StoreError> {
        let uri = self.uri(k);
        let k = key(&uri, k)?;
        match self.runtime.block_on(self.store.head(&k)) {
            Ok(m) => Ok(Some(m.size)),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(StoreError::from_store(&uri, &e)),
        }
    }

    /// Writes `bytes` to `key` in one PUT (atomic: the whole object or nothing).
    pub fn put(&self, k: &str, bytes: Vec<u8>) -> Result<(), StoreError> {
        let uri = self.uri(k);
        let k = key(&uri, k)?;
        self.runtime
            .block_on(self.store.put(&k, bytes.into()))
            .map(|_| ())
            .map_err(|e| StoreError::from_store(&uri, &e))
    }

    /// Removes `key` (no error when it is not there).
    pub fn delete(&self, k: &str) -> Result<(), StoreError> {
        let uri = self.uri(k);
        let k = key(&uri, k)?;
        match self.runtime.block_on(self.store.delete(&k)) {
            Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(()),
            Err(e) => Err(StoreError::from_store(&uri, &e)),
        }
    }
}

fn too_large(uri: &str, size: u64, limit: u64) -> StoreError {
    StoreError::new(
        uri,
        &format!("{size} bytes, over the {limit}-byte limit for this kind of file"),
        "check that the key names a braking-run log (docs/limits.md)",
    )
}

/// The object_store path of a key as S3 spells it (no percent-encoding of `#`, `%`, `~`, …).
fn key(uri: &str, k: &str) -> Result<Key, StoreError> {
    Key::parse(k).map_err(|e| {
        StoreError::new(
            uri,
            &format!("not a key railgrip can address: {e}"),
            "use keys without empty segments, `.` or `..`",
        )
    })
}

/// `prefix/rest`, or `rest` for an empty prefix.
pub fn join(prefix: &str, rest: &str) -> String {
    if prefix.is_empty() {
        rest.to_string()
    } else {
        format!("{prefix}/{rest}")
    }
}

/// A log (and its sidecar) in a bucket, fetched when read.
#[derive(Debug, Clone)]
pub struct ObjectLog {
    pub bucket: Arc<Bucket>,
    pub key: String,
    pub size: u64,
    /// The `<stem>.meta.toml` beside a CSV log, when the listing has one.
    pub sidecar: Option<String>,
}

impl ObjectLog {
    /// The log at `s3://bucket/key` with the `<stem>.meta.toml` beside a CSV log when the bucket
    /// has one; an error names the URI when there is no such object.
    pub fn at(bucket: &str, key: &str) -> Result<ObjectLog, StoreError> {
        let b = Bucket::connect(bucket)?;
        let size = b.head(key)?.ok_or_else(|| {
            StoreError::new(
                &b.uri(key),
                "no such object",
                "check the bucket and key (aws s3 ls shows what is there)",
            )
        })?;
        let lower = key.to_ascii_lowercase();
        let sidecar = match lower.strip_suffix(".csv") {
            Some(_) => {
                let side = format!("{}.meta.toml", &key[..key.len() - 4]);
                b.head(&side)?.map(|_| side)
            }
            None => None,
        };
        Ok(ObjectLog {
            bucket: b,
            key: key.to_string(),
            size,
            sidecar,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_parse_paths_files_and_buckets() {
        assert_eq!(
            Location::parse("data/camp").unwrap(),
            Location::Local("data/camp".into())
        );
        assert_eq!(
            Location::parse("file:///srv/camp").unwrap(),
            Location::Local("/srv/camp".into())
        );
        assert_eq!(
            Location::parse("s3://b/2026/a/").unwrap(),
            Location::S3 {
                bucket: "b".into(),
                prefix: "2026/a".into()
            }
        );
        assert_eq!(
            Location::parse("s3://b").unwrap(),
            Location::S3 {
                bucket: "b".into(),
                prefix: String::new()
            }
        );
        let e = Location::parse("gs://b/x").unwrap_err();
        assert!(
            e.to_string().contains("gs://") && e.hint.contains("s3://"),
            "{e}"
        );
        assert!(Location::parse("s3:///x").is_err());
        assert_eq!(join("", "a.csv"), "a.csv");
        assert_eq!(join("p/q", "a.csv"), "p/q/a.csv");
    }
}

/// A fresh local folder for staging the outputs bound for `uri`: unique per process and call
/// (two stagings of the same output in one process do not share it), removed first if a
/// crashed process of the same id left it.
pub(crate) fn staging_dir(uri: &str) -> PathBuf {
    static SEQ: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "railgrip-out-{}-{}-{}",
        std::process::id(),
        SEQ.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        crate::hash::sha256_bytes(uri.as_bytes())
            .get(..12)
            .unwrap_or_default()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// An output folder at a location, for the commands that write a few files into one
/// (`estimate`, `ingest`, `train`): a local folder is written in place; for a bucket's prefix
/// the files are written into a local staging folder first and then put one by one, each in
/// one atomic PUT, by [`OutFolder::finish`]. The staging folder is removed when the value is
/// dropped.
#[derive(Debug)]
pub struct OutFolder {
    dir: PathBuf,
    remote: Option<(Arc<Bucket>, String)>,
}

impl OutFolder {
    /// The output folder at `text` (a path, `file://PATH` or `s3://BUCKET/PREFIX`). A bucket is
    /// reached here, so a missing bucket or a dead endpoint is found before any work is done.
    pub fn at(text: &str) -> Result<OutFolder, StoreError> {
        match Location::parse(text)? {
            Location::Local(dir) => Ok(OutFolder { dir, remote: None }),
            Location::S3 { bucket, prefix } => {
                let b = Bucket::connect(&bucket)?;
                // A listing of a key nothing has: an error for a missing bucket or a dead
                // endpoint, without listing what the prefix holds (credentials must allow
                // listing the bucket, as reading a campaign from it does).
                b.list(&join(&prefix, ".railgrip-probe")).map_err(|e| StoreError {
                    uri: b.uri(&prefix),
                    message: e.message,
                    hint: format!("{} (railgrip lists the output prefix before writing: the credentials need s3:ListBucket as well as s3:PutObject)", e.hint),
                })?;
                let dir = staging_dir(&b.uri(&prefix));
                Ok(OutFolder {
                    dir,
                    remote: Some((b, prefix)),
                })
            }
        }
    }

    /// Where to write the files.
    pub fn dir(&self) -> &std::path::Path {
        &self.dir
    }

    /// `text` (an error message) with the staging folder named by the output's URI.
    pub fn explain(&self, text: &str) -> String {
        match &self.remote {
            Some((b, prefix)) => text.replace(&self.dir.display().to_string(), &b.uri(prefix)),
            None => text.to_string(),
        }
    }

    /// The name a user sees for a file written below [`OutFolder::dir`]: its path, or its URI.
    pub fn name_of(&self, file: &std::path::Path) -> String {
        match (&self.remote, file.strip_prefix(&self.dir)) {
            (Some((b, prefix)), Ok(rel)) => {
                b.uri(&join(prefix, &rel.to_string_lossy().replace('\\', "/")))
            }
            _ => file.display().to_string(),
        }
    }

    /// Writes `files` (written below [`OutFolder::dir`]) back to the bucket, one PUT each, in
    /// their order; nothing to do for a local folder.
    pub fn finish(&self, files: &[PathBuf]) -> Result<(), StoreError> {
        let Some((b, prefix)) = &self.remote else {
            return Ok(());
        };
        for f in files {
            let uri = self.name_of(f);
            let rel = f.strip_prefix(&self.dir).map_err(|_| {
                StoreError::new(
                    &uri,
                    "a file outside the output folder",
                    "report this as a railgrip bug",
                )
            })?;
            let bytes = std::fs::read(f).map_err(|e| {
                StoreError::new(
                    &uri,
                    &format!("cannot read the staged file: {e}"),
                    "check the temporary folder's disk space",
                )
            })?;
            b.put(
                &join(prefix, &rel.to_string_lossy().replace('\\', "/")),
                bytes,
            )?;
        }
        Ok(())
    }
}

impl Drop for OutFolder {
    fn drop(&mut self) {
        if self.remote.is_some() {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}
