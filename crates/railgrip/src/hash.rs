//! SHA-256 as lowercase hex: what provenance and the campaign's reuse check record.

use std::io::Read;
use std::path::Path;

use sha2::{Digest, Sha256};

/// Lowercase hex of a digest.
pub fn hex(digest: &[u8]) -> String {
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of bytes, lowercase hex.
pub fn sha256_bytes(b: &[u8]) -> String {
    hex(&Sha256::digest(b))
}

/// SHA-256 of everything `r` yields, streamed (no copy in memory), fed to every hasher in
/// `into` as well; lowercase hex of the stream alone.
pub fn sha256_stream(mut r: impl Read, into: &mut [&mut Sha256]) -> std::io::Result<String> {
    let mut own = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = match r.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        own.update(&buf[..n]);
        for h in into.iter_mut() {
            h.update(&buf[..n]);
        }
    }
    Ok(hex(&own.finalize()))
}

/// SHA-256 of a file, streamed; lowercase hex.
pub fn sha256_file(path: &Path) -> std::io::Result<String> {
    sha256_stream(crate::input::open_regular(path)?, &mut [])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_digests() {
        assert_eq!(
            sha256_bytes(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let mut extra = Sha256::new();
        let s = sha256_stream(&b"abc"[..], &mut [&mut extra]).unwrap();
        assert_eq!(s, sha256_bytes(b"abc"));
        assert_eq!(hex(&extra.finalize()), s);
    }
}
