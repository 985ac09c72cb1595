//! Campaign archives read in place: `.zip` (stored, deflate, zstd members), `.tar`, `.tar.gz`
//! and `.tar.zst`, recognised by their first bytes (not the extension). Nothing is unpacked
//! to disk: the log members (`.csv`, `.mcap`) and the CSV sidecars (`.meta.toml`) are read
//! into memory as [`LogSource::Memory`]; every other member is skipped unread (zip) or
//! streamed past (tar).
//!
//! Decompression is bounded ([`Limits`]): a member that inflates past `max_member_bytes`, a
//! stream that inflates past `max_total_bytes` in all, or more than `max_members` entries is
//! an error naming the archive and the member — a decompression bomb fails cleanly instead of
//! filling memory.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::format::SIDECAR_SUFFIX;
use crate::ingest::LogSource;

/// Bounds on what an archive may decompress to.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Largest member (log or sidecar) after decompression, bytes.
    pub max_member_bytes: u64,
    /// Largest total after decompression (every member, also the skipped ones of a tar
    /// stream), bytes.
    pub max_total_bytes: u64,
    /// Most entries.
    pub max_members: usize,
}

impl Default for Limits {
    /// 2 GiB per member, 16 GiB in all, 100 000 entries.
    fn default() -> Limits {
        Limits {
            max_member_bytes: 2 << 30,
            max_total_bytes: 16 << 30,
            max_members: 100_000,
        }
    }
}

/// Why an archive could not be read.
#[derive(Debug, thiserror::Error)]
#[error("{archive}{member}: {message}. Hint: {hint}")]
pub struct ArchiveError {
    pub archive: PathBuf,
    /// `/<member>` when one member is at fault, else empty.
    pub member: String,
    pub message: String,
    pub hint: String,
}

/// Archive formats railgrip reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Zip,
    Tar,
    TarGz,
    TarZst,
}

/// The archive kind of `path` from its first bytes; None for anything else (a folder, a log).
pub fn kind_of(path: &Path) -> Option<Kind> {
    let mut head = [0u8; 512];
    let mut f = crate::input::open_regular(path).ok()?;
    let mut n = 0;
    while n < head.len() {
        match f.read(&mut head[n..]) {
            Ok(0) | Err(_) => break,
            Ok(k) => n += k,
        }
    }
    let h = &head[..n];
    if h.starts_with(b"PK\x03\x04") || h.starts_with(b"PK\x05\x06") {
        Some(Kind::Zip)
    } else if h.starts_with(&[0x1f, 0x8b]) {
        Some(Kind::TarGz)
    } else if h.starts_with(&[0x28, 0xb5, 0x2f, 0xfd]) {
        Some(Kind::TarZst)
    } else if n >= 262 && &h[257..262] == b"ustar" {
        Some(Kind::Tar)
    } else {
        None
    }
}

/// What a member is to railgrip.
fn hidden(name: &str) -> bool {
    name.split('/')
        .any(|c| c.starts_with('.') || c == "__MACOSX")
}

fn wanted(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    !hidden(name)
        && (lower.ends_with(".csv")
            || lower.ends_with(".mcap")
            || lower.ends_with(&SIDECAR_SUFFIX.to_ascii_lowercase()))
}

/// Counts the bytes read through it and fails past a limit.
struct Counted<R> {
    inner: R,
    read: u64,
    limit: u64,
}

impl<R: Read> Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read += n as u64;
        if self.read > self.limit {
            return Err(std::io::Error::other(format!(
                "decompresses to more than {} bytes in all",
                self.limit
            )));
        }
        Ok(n)
    }
}

/// The log sources of an archive (`.csv` with their sidecars, `.mcap`), in member-path order,
/// each named `<archive>/<member path>`.
pub fn read_archive(path: &Path, limits: Limits) -> Result<Vec<LogSource>, ArchiveError> {
    Ok(read_archive_all(path, limits)?.0)
}

/// An archive's logs and its other members with why they are not logs.
pub type Listing = (Vec<LogSource>, Vec<(String, String)>);

/// [`read_archive`], and the members that are not logs with why (member path, reason);
/// hidden members (`.name`, `__MACOSX`) and folders are left out silently.
pub fn read_archive_all(path: &Path, limits: Limits) -> Result<Listing, ArchiveError> {
    let mut u = Unpack {
        path,
        limits,
        members: BTreeMap::new(),
        skipped: Vec::new(),
    };
    let kind = kind_of(path).ok_or_else(|| {
        u.err(
            "",
            "not a .zip, .tar, .tar.gz or .tar.zst archive".into(),
            "give a campaign folder or one of these archives",
        )
    })?;
    let file =
        crate::input::open_regular(path).map_err(|e| u.err("", e.to_string(), "check the path"))?;
    match kind {
        Kind::Zip => u.zip(file)?,
        Kind::Tar | Kind::TarGz | Kind::TarZst => u.tar(kind, file)?,
    }
    Ok(u.finish())
}

/// Hint for an archive that cannot be read.
const DAMAGED: &str = "the archive is damaged or truncated; copy it again or unpack it with the tool that made it and give the folder";
/// Hint for an archive past the [`Limits`].
const BOMB: &str = "the member is larger than railgrip reads from an archive (a decompression bomb or a wrong file); unpack the campaign and give the folder";

/// An archive being read: the wanted members' bytes by member path, and the members skipped
/// with why.
struct Unpack<'a> {
    path: &'a Path,
    limits: Limits,
    members: BTreeMap<String, Vec<u8>>,
    skipped: Vec<(String, String)>,
}

impl Unpack<'_> {
    /// An error about the archive, or about its member `member` when not empty.
    fn err(&self, member: &str, message: String, hint: &str) -> ArchiveError {
        ArchiveError {
            archive: self.path.to_path_buf(),
            member: if member.is_empty() {
                String::new()
            } else {
                format!("/{member}")
            },
            message,
            hint: hint.into(),
        }
    }

    /// Lists a member that is not read: a regular file that is not hidden is skipped with
    /// its reason, folders and hidden members silently.
    fn skip(&mut self, name: &str, regular: bool) {
        if regular && !hidden(name) {
            self.skipped
                .push((name.to_string(), "not a .csv or .mcap log".to_string()));
        }
    }

    /// The bytes of member `name`, at most `max_member_bytes` of them.
    fn read_member(&self, name: &str, r: &mut dyn Read) -> Result<Vec<u8>, ArchiveError> {
        let limits = self.limits;
        let mut buf = Vec::new();
        r.take(limits.max_member_bytes + 1)
            .read_to_end(&mut buf)
            .map_err(|e| self.err(name, e.to_string(), DAMAGED))?;
        if buf.len() as u64 > limits.max_member_bytes {
            return Err(self.err(
                name,
                format!(
                    "decompresses to more than {} bytes",
                    limits.max_member_bytes
                ),
                BOMB,
            ));
        }
        Ok(buf)
    }

    /// Reads the wanted members of a zip archive, entry by entry; the entry count and the
    /// total of the members read are bounded.
    fn zip(&mut self, file: std::fs::File) -> Result<(), ArchiveError> {
        let limits = self.limits;
        let mut z = zip::ZipArchive::new(file).map_err(|e| self.err("", e.to_string(), DAMAGED))?;
        if z.len() > limits.max_members {
            return Err(self.err(
                "",
                format!("{} entries (at most {})", z.len(), limits.max_members),
                BOMB,
            ));
        }
        let mut total: u64 = 0;
        for i in 0..z.len() {
            let mut f = z
                .by_index(i)
                .map_err(|e| self.err("", format!("entry {i}: {e}"), DAMAGED))?;
            let name = f
                .name()
                .map_err(|e| self.err("", format!("entry {i}: {e}"), DAMAGED))?
                .to_string();
            if f.is_dir() || !wanted(&name) {
                self.skip(&name, !f.is_dir());
                continue;
            }
            let bytes = self.read_member(&name, &mut f)?;
            total += bytes.len() as u64;
            if total > limits.max_total_bytes {
                return Err(self.err(
                    &name,
                    format!(
                        "the archive decompresses to more than {} bytes in all",
                        limits.max_total_bytes
                    ),
                    BOMB,
                ));
            }
            self.members.insert(name, bytes);
        }
        Ok(())
    }

    /// Reads the wanted members of a tar stream (plain, gzip or zstd), streaming past the
    /// others; the entry count and everything decompressed are bounded.
    fn tar(&mut self, kind: Kind, file: std::fs::File) -> Result<(), ArchiveError> {
        let limits = self.limits;
        let stream: Box<dyn Read> = match kind {
            Kind::Tar => Box::new(file),
            Kind::TarGz => Box::new(flate2::read::MultiGzDecoder::new(file)),
            _ => Box::new(
                zstd::stream::read::Decoder::new(file)
                    .map_err(|e| self.err("", e.to_string(), DAMAGED))?,
            ),
        };
        let counted = Counted {
            inner: stream,
            read: 0,
            limit: limits.max_total_bytes,
        };
        let mut ar = tar::Archive::new(counted);
        let entries = ar
            .entries()
            .map_err(|e| self.err("", e.to_string(), DAMAGED))?;
        for (count, entry) in entries.enumerate() {
            if count >= limits.max_members {
                return Err(self.err(
                    "",
                    format!("more than {} entries", limits.max_members),
                    BOMB,
                ));
            }
            let mut e = entry.map_err(|e| self.err("", e.to_string(), DAMAGED))?;
            let name = e
                .path()
                .map_err(|x| self.err("", x.to_string(), DAMAGED))?
                .to_string_lossy()
                .trim_start_matches("./")
                .to_string();
            if !e.header().entry_type().is_file() || !wanted(&name) {
                self.skip(&name, e.header().entry_type().is_file());
                continue;
            }
            let bytes = self.read_member(&name, &mut e)?;
            self.members.insert(name, bytes);
        }
        Ok(())
    }

    /// The logs in member-path order, each CSV log with its sidecar; the skipped members
    /// sorted, then the sidecars without their log.
    fn finish(self) -> Listing {
        let Unpack {
            path,
            members,
            mut skipped,
            ..
        } = self;
        let mut sidecars: BTreeMap<String, Arc<[u8]>> = BTreeMap::new();
        skipped.sort();
        let mut logs = Vec::new();
        for (name, bytes) in members {
            if name.to_ascii_lowercase().ends_with(SIDECAR_SUFFIX) {
                let stem = &name[..name.len() - SIDECAR_SUFFIX.len()];
                sidecars.insert(stem.to_string(), bytes.into());
            } else {
                logs.push((name, bytes));
            }
        }
        for stem in sidecars.keys() {
            if !logs.iter().any(|(n, _)| {
                n.to_ascii_lowercase().ends_with(".csv")
                    && Path::new(n).with_extension("") == Path::new(stem)
            }) {
                skipped.push((
                    format!("{stem}{SIDECAR_SUFFIX}"),
                    format!("a metadata sidecar without its log ({stem}.csv is not beside it)"),
                ));
            }
        }
        let logs = logs
            .into_iter()
            .map(|(name, bytes)| {
                let stem = Path::new(&name).with_extension("");
                let sidecar = sidecars.get(&*stem.to_string_lossy()).cloned();
                LogSource::Memory {
                    name: path.join(&name),
                    bytes: bytes.into(),
                    sidecar,
                }
            })
            .collect();
        (logs, skipped)
    }
}
