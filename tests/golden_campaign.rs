//! `railgrip run` on the bundled archive gives the committed bytes: `summary.csv` (exactly:
//! wall-clock fields are in `timings.json`), the C headers of both models
//! and the Polach fits.
//! A refactoring that changes any of them fails here; `UPDATE_GOLDEN=1 cargo test --test
//! golden_campaign` refreshes the files after an intended change (say why in the commit).
//! The model files hold trained weights, whose last bits follow the CPU's matrix kernels (see
//! ARCHITECTURE.md, determinism): their numbers are compared to 1e-7 relative, the rest exactly.

mod common;

use std::path::Path;
use std::process::Command;

const GOLDEN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/golden_campaign");

fn check(name: &str, got: &str, rel: f64) {
    let path = Path::new(GOLDEN).join(name);
    if std::env::var("UPDATE_GOLDEN").as_deref() == Ok("1") {
        std::fs::create_dir_all(GOLDEN).unwrap();
        std::fs::write(&path, got).unwrap();
        return;
    }
    let want = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (UPDATE_GOLDEN=1 writes it)", path.display()));
    if rel > 0.0 {
        common::assert_same_up_to_rounding(name, got, &want, rel);
        return;
    }
    if got != want {
        let line = got
            .lines()
            .zip(want.lines())
            .position(|(a, b)| a != b)
            .unwrap_or(got.lines().count().min(want.lines().count()));
        panic!(
            "{name} differs from {} at line {}:\n got: {:?}\nwant: {:?}",
            path.display(),
            line + 1,
            got.lines().nth(line),
            want.lines().nth(line)
        );
    }
}

#[test]
fn run_on_the_bundled_archive_gives_the_golden_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(["run", "--out", "out", "--jobs", "2"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let out = dir.path().join("out");
    let read = |p: &str| std::fs::read_to_string(out.join(p)).unwrap();
    check("summary.csv", &read("summary.csv"), 0.0);
    for f in ["mlp.h", "mlp.polach.h", "mlp.polach-fits.json"] {
        check(f, &read(&format!("models/{f}")), 1e-7);
    }
}
