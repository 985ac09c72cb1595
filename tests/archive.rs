//! Campaign archives read in place: .zip, .tar, .tar.gz and .tar.zst give the same runs and
//! estimates as the unpacked folder; decompression bombs and damaged archives fail cleanly.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use railgrip::archive::{read_archive, Limits};

fn archive(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/archive")
        .join(name)
}

/// (member path, bytes) of a small campaign: a CSV run with its sidecar and an MCAP run in a
/// subfolder, and a file railgrip ignores.
fn members() -> Vec<(String, Vec<u8>)> {
    let mut m = Vec::new();
    for f in ["soap_120kmh_p20.csv", "soap_120kmh_p20.meta.toml"] {
        m.push((format!("campaign/{f}"), std::fs::read(archive(f)).unwrap()));
    }
    m.push((
        "campaign/day 2/soap_160kmh_0c.mcap".into(),
        std::fs::read(archive("soap_160kmh_0c.mcap")).unwrap(),
    ));
    m.push((
        "campaign/notes.txt".into(),
        b"weather: dry until 10:00".to_vec(),
    ));
    m
}

fn tar_bytes(m: &[(String, Vec<u8>)]) -> Vec<u8> {
    let mut b = tar::Builder::new(Vec::new());
    for (name, bytes) in m {
        let mut h = tar::Header::new_gnu();
        h.set_size(bytes.len() as u64);
        h.set_mode(0o644);
        h.set_cksum();
        b.append_data(&mut h, name, bytes.as_slice()).unwrap();
    }
    b.into_inner().unwrap()
}

fn write_all(dir: &Path) -> Vec<PathBuf> {
    let m = members();
    let zip_path = dir.join("c.zip");
    let mut z = zip::ZipWriter::new(std::fs::File::create(&zip_path).unwrap());
    for (i, (name, bytes)) in m.iter().enumerate() {
        let method = if i % 2 == 0 {
            zip::CompressionMethod::Deflated
        } else {
            zip::CompressionMethod::Stored
        };
        let o = zip::write::SimpleFileOptions::default().compression_method(method);
        z.start_file(name.as_str(), o).unwrap();
        z.write_all(bytes).unwrap();
    }
    z.finish().unwrap();
    let tar = tar_bytes(&m);
    std::fs::write(dir.join("c.tar"), &tar).unwrap();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(&tar).unwrap();
    std::fs::write(dir.join("c.tar.gz"), gz.finish().unwrap()).unwrap();
    std::fs::write(
        dir.join("c.tar.zst"),
        zstd::encode_all(tar.as_slice(), 3).unwrap(),
    )
    .unwrap();
    ["c.zip", "c.tar", "c.tar.gz", "c.tar.zst"]
        .iter()
        .map(|f| dir.join(f))
        .collect()
}

fn summary(dir: &Path, out: &str) -> Vec<String> {
    // summary.csv without its error column (which names the log's path).
    std::fs::read_to_string(dir.join(out).join("summary.csv"))
        .unwrap()
        .lines()
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            [&c[..2], &c[3..]].concat().join(",")
        })
        .collect()
}

#[test]
fn every_archive_kind_gives_the_runs_of_the_folder() {
    let dir = tempfile::tempdir().unwrap();
    let paths = write_all(dir.path());
    for p in &paths {
        let logs = read_archive(p, Limits::default()).unwrap();
        let names: Vec<String> = logs
            .iter()
            .map(|s| s.name().display().to_string())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
        assert!(
            names[0].ends_with("campaign/day 2/soap_160kmh_0c.mcap"),
            "{names:?}"
        );
        assert!(
            names[1].ends_with("campaign/soap_120kmh_p20.csv"),
            "{names:?}"
        );
    }
    // The folder, unpacked by hand, as the reference.
    for (name, bytes) in members() {
        let p = dir.path().join("folder").join(&name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, bytes).unwrap();
    }
    let run = |input: &str, out: &str| {
        let o = Command::new(env!("CARGO_BIN_EXE_railgrip"))
            .args(["run", input, "--out", out])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert_eq!(
            o.status.code(),
            Some(0),
            "{input}: {}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    };
    run("folder/campaign", "o_folder");
    let want = summary(dir.path(), "o_folder");
    assert_eq!(want.len(), 3, "{want:?}");
    for (k, p) in paths.iter().enumerate() {
        let out = format!("o_{k}");
        run(&p.file_name().unwrap().to_string_lossy(), &out);
        let got: Vec<String> = summary(dir.path(), &out)
            .into_iter()
            .map(|l| l.replacen("campaign__", "", 1))
            .collect();
        assert_eq!(got, want, "{}", p.display());
    }
}

#[test]
fn decompression_bombs_and_damaged_archives_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    // A 64 MiB member of zeros compresses to a few kB.
    let zeros = vec![0u8; 64 << 20];
    let bomb = tar_bytes(&[("big.csv".into(), zeros.clone())]);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(&bomb).unwrap();
    let p = dir.path().join("bomb.tar.gz");
    std::fs::write(&p, gz.finish().unwrap()).unwrap();
    assert!(std::fs::metadata(&p).unwrap().len() < 1 << 20);
    let limits = Limits {
        max_member_bytes: 8 << 20,
        max_total_bytes: 1 << 40,
        max_members: 1000,
    };
    let e = read_archive(&p, limits).unwrap_err().to_string();
    assert!(
        e.contains("bomb.tar.gz/big.csv") && e.contains("decompresses to more than 8388608 bytes"),
        "{e}"
    );
    // Skipped members count towards the total too.
    let junk = tar_bytes(&[("junk.bin".into(), zeros)]);
    let p = dir.path().join("junk.tar.zst");
    std::fs::write(&p, zstd::encode_all(junk.as_slice(), 19).unwrap()).unwrap();
    let limits = Limits {
        max_member_bytes: 1 << 40,
        max_total_bytes: 16 << 20,
        max_members: 1000,
    };
    let e = read_archive(&p, limits).unwrap_err().to_string();
    assert!(
        e.contains("junk.tar.zst") && e.contains("more than 16777216 bytes in all"),
        "{e}"
    );
    // Damaged: a zip header and then garbage; through the CLI, exit 1 and the file named.
    let p = dir.path().join("damaged.zip");
    std::fs::write(&p, b"PK\x03\x04garbage that is not a zip archive").unwrap();
    assert!(read_archive(&p, Limits::default()).is_err());
    let o = Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(["run", "damaged.zip", "--out", "o"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("damaged.zip") && err.contains("Hint"), "{err}");
    // A truncated tar.gz names the archive.
    let tar = tar_bytes(&members());
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(&tar).unwrap();
    let bytes = gz.finish().unwrap();
    let p = dir.path().join("cut.tar.gz");
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let e = read_archive(&p, Limits::default()).unwrap_err().to_string();
    assert!(e.contains("cut.tar.gz"), "{e}");
}

/// "run-name collision": `x.csv` and `x.mcap` in one campaign once shared
/// `runs/x/`, the last writer winning and re-runs alternating between sources. Colliding names
/// now carry their log's format, and names that sanitise alike a counter — the same on every
/// run, for a folder and for the same campaign as an archive.
#[test]
fn logs_with_the_same_stem_get_their_own_runs() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("camp");
    std::fs::create_dir_all(&camp).unwrap();
    for (from, to) in [
        ("soap_120kmh_p20.csv", "x.csv"),
        ("soap_160kmh_0c.mcap", "x.mcap"),
        ("soap_120kmh_p20.csv", "a b.csv"),
        ("soap_120kmh_p20.csv", "a_b.csv"),
        ("soap_120kmh_m20.csv", "solo.csv"),
    ] {
        std::fs::copy(archive(from), camp.join(to)).unwrap();
    }
    let names = |root: &Path| -> Vec<(String, String)> {
        railgrip::campaign::sources(root, None)
            .unwrap()
            .into_iter()
            .map(|(n, s)| {
                (
                    n,
                    s.name().file_name().unwrap().to_string_lossy().into_owned(),
                )
            })
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect()
    };
    let want: Vec<(String, String)> = [
        ("a_b_csv", "a b.csv"),
        ("a_b_csv_2", "a_b.csv"),
        ("solo", "solo.csv"),
        ("x_csv", "x.csv"),
        ("x_mcap", "x.mcap"),
    ]
    .iter()
    .map(|(a, b)| (a.to_string(), b.to_string()))
    .collect();
    assert_eq!(names(&camp), want);
    assert_eq!(names(&camp), want, "the same names on a second look");
    // The same campaign as an archive (members in another order: the names follow the paths).
    let tar = tar_bytes(
        &["x.mcap", "solo.csv", "a_b.csv", "x.csv", "a b.csv"]
            .iter()
            .map(|f| (f.to_string(), std::fs::read(camp.join(f)).unwrap()))
            .collect::<Vec<_>>(),
    );
    let tar_path = dir.path().join("camp.tar");
    std::fs::write(&tar_path, tar).unwrap();
    assert_eq!(names(&tar_path), want);
}
