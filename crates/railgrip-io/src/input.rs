//! Opening input files safely: only regular files, and never more bytes than a limit.
//!
//! A sidecar that was a FIFO blocked `ingest` and `run` forever (opening a FIFO for
//! reading waits for a writer), and one that pointed at /dev/zero was read to 4.2 GB. Every
//! file railgrip reads because a user or a log named it goes through here: logs, sidecars,
//! pipeline and scene files, model files, archives.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// Largest metadata sidecar (`<stem>.meta.toml`) read, bytes. Real ones are under 1 KiB.
pub const MAX_SIDECAR_BYTES: u64 = 1 << 20;
/// Largest pipeline or scene file read, bytes.
pub const MAX_CONFIG_BYTES: u64 = 4 << 20;
/// Largest model file read, bytes. A 256-neuron 4-input network with a full support grid of
/// 2²⁰ cells is about 25 MB of JSON.
pub const MAX_MODEL_BYTES: u64 = 64 << 20;

/// What kind of non-regular file `path` is, for the error message.
fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

/// Fails unless `path` (after following symbolic links) is a regular file. The error says
/// what it is instead and what to do.
pub fn check_regular(path: &Path) -> io::Result<std::fs::Metadata> {
    let meta = std::fs::metadata(path)?;
    if meta.is_file() {
        Ok(meta)
    } else {
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{} is {}; railgrip reads only regular files (copy the data into a file)",
                path.display(),
                kind_of(&meta)
            ),
        ))
    }
}

/// Opens a regular file for reading. FIFOs, devices, sockets and directories are refused
/// before `open` (which would block on a FIFO).
pub fn open_regular(path: &Path) -> io::Result<File> {
    check_regular(path)?;
    File::open(path)
}

/// Reads a whole regular file of at most `limit` bytes; `what` names it in the error
/// ("sidecar", "pipeline file").
pub fn read_limited(path: &Path, limit: u64, what: &str) -> io::Result<Vec<u8>> {
    let meta = check_regular(path)?;
    let too_big = |n: u64| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "{} is {n} bytes, over the {limit}-byte limit for a {what}; is it the right file?",
                path.display()
            ),
        )
    };
    if meta.len() > limit {
        return Err(too_big(meta.len()));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    // The file may grow between stat and read: read one byte more than the limit to tell.
    File::open(path)?.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_big(bytes.len() as u64));
    }
    Ok(bytes)
}

/// [`read_limited`] for UTF-8 text.
pub fn read_text_limited(path: &Path, limit: u64, what: &str) -> io::Result<String> {
    String::from_utf8(read_limited(path, limit, what)?).map_err(|_| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{} is not UTF-8 text; a {what} is text", path.display()),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directories_and_oversized_files_are_refused_with_what_they_are() {
        let dir = tempfile::tempdir().unwrap();
        let e = open_regular(dir.path()).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        let f = dir.path().join("big.toml");
        std::fs::write(&f, vec![b'#'; 101]).unwrap();
        let e = read_limited(&f, 100, "sidecar").unwrap_err();
        assert!(e.to_string().contains("101 bytes"), "{e}");
        assert_eq!(read_limited(&f, 101, "sidecar").unwrap().len(), 101);
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_refused_before_reading() {
        let e = read_limited(Path::new("/dev/zero"), 100, "sidecar").unwrap_err();
        assert!(e.to_string().contains("a device"), "{e}");
    }
}
