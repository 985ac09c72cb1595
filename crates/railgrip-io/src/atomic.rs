//! Atomic output files: write to a temporary file beside the target, then rename.
//!
//! Architecture invariant: every output railgrip writes goes through [`write_atomically`], so a
//! crash or an error never leaves a half-written file under the final name.

use std::fs::{self, File};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};

/// Writes `path` through `fill`; on success the complete file appears under `path` at once, on
/// failure nothing is left behind (the temporary file is removed).
pub fn write_atomically<E>(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<File>) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<io::Error>,
{
    let tmp = temp_path(path);
    let result = (|| {
        let mut w = BufWriter::new(File::create(&tmp)?);
        fill(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        fs::rename(&tmp, path)?;
        Ok(())
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Removes the temporary files ([`temp_path`]) below `root`, at most `depth` folders down,
/// that processes no longer running left behind (a killed run: they were never
/// cleaned). Where the operating system has no `/proc`, every temporary file not of this
/// process counts as left behind. Errors are ignored: a file that cannot be removed stays.
pub fn remove_stale_temporaries(root: &Path, depth: usize) {
    let Ok(entries) = fs::read_dir(root) else {
        return;
    };
    let me = std::process::id();
    let proc_fs = Path::new("/proc/self").exists();
    for e in entries.flatten() {
        let path = e.path();
        let Ok(ft) = e.file_type() else { continue };
        if ft.is_dir() {
            if depth > 0 {
                remove_stale_temporaries(&path, depth - 1);
            }
            continue;
        }
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = temp_pid(&name) else { continue };
        let alive = pid == me || (proc_fs && Path::new(&format!("/proc/{pid}")).exists());
        if !alive {
            let _ = fs::remove_file(&path);
        }
    }
}

/// The process id in a temporary file's name `.<name>.tmp-<pid>`.
fn temp_pid(name: &str) -> Option<u32> {
    let (head, pid) = name.rsplit_once(".tmp-")?;
    if !head.starts_with('.') || pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// A scratch file beside an output, `<dir>/.<name>.<tag>.tmp-<pid>`: written and read back
/// while the output is being built (so that what the output gathers need not be held in
/// memory), removed when dropped; one a killed process left behind is removed by the next
/// [`remove_stale_temporaries`] over its folder (`railgrip run` sweeps its output folder).
#[derive(Debug)]
pub struct Scratch {
    path: PathBuf,
    file: File,
}

impl Scratch {
    /// Creates (truncates) the scratch file for the output `beside`, open for reading and
    /// writing.
    pub fn beside(beside: &Path, tag: &str) -> io::Result<Scratch> {
        let name = beside
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = format!(".{name}.{tag}.tmp-{}", std::process::id());
        let path = match beside.parent() {
            Some(dir) => dir.join(tmp),
            None => PathBuf::from(tmp),
        };
        let file = fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)?;
        Ok(Scratch { path, file })
    }

    /// The open file (its position is wherever the last read or write left it).
    pub fn file(&mut self) -> &mut File {
        &mut self.file
    }

    /// Where it is.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_file(&self.path);
    }
}

/// `<dir>/.<name>.tmp-<pid>`: hidden, beside the target (same file system, so rename is atomic).
fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = format!(".{name}.tmp-{}", std::process::id());
    match path.parent() {
        Some(dir) => dir.join(tmp),
        None => PathBuf::from(tmp),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn a_scratch_file_reads_back_what_was_written_and_is_gone_when_dropped() {
        use std::io::{Read, Seek};
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("index.html");
        let mut s = Scratch::beside(&target, "sections").unwrap();
        let path = s.path().to_path_buf();
        assert!(path
            .file_name()
            .unwrap()
            .to_string_lossy()
            .starts_with(".index.html.sections.tmp-"));
        s.file().write_all(b"one two").unwrap();
        s.file().rewind().unwrap();
        let mut back = String::new();
        s.file().read_to_string(&mut back).unwrap();
        assert_eq!(back, "one two");
        drop(s);
        assert!(!path.exists());
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn failure_leaves_no_file_and_success_replaces_whole() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.txt");
        let r: Result<(), io::Error> = write_atomically(&target, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("boom"))
        });
        assert!(r.is_err());
        assert_eq!(
            fs::read_dir(dir.path()).unwrap().count(),
            0,
            "no temp file, no target"
        );

        write_atomically::<io::Error>(&target, |w| w.write_all(b"complete")).unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"complete");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
