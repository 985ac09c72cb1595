//! Shared by tests and benchmarks: synthetic braking logs (smooth analytic signals with known
//! second derivatives, sampled with jitter, written through the crate's own format writers),
//! the bundled runs' estimates, the numpy trainlm peer, and a golden-file comparison that
//! allows rounding in numbers.
#![allow(dead_code)]

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use railgrip::format::{self, McapCompression, RunMetadata, SeriesRef, Signal};

/// Wheel radius used to turn speeds into angular speeds, m.
pub const R: f64 = 0.445;

/// The analytic value of each signal at `t` (canonical units), periodic so any duration works.
pub fn analytic(s: Signal, t: f64) -> f64 {
    let v = 25.0 + 5.0 * (0.0105 * t).sin() + 0.3 * (0.7 * t).sin();
    match s {
        Signal::VRadar => v,
        Signal::Omega(a) => (v - (1.0 + (std::f64::consts::PI * t + a as f64).sin())) / R,
        Signal::Pressure(a) => 2.0 + 0.5 * (std::f64::consts::TAU * t + a as f64).sin(),
    }
}

/// Upper bound of |d²x/dt²| of [`analytic`] per signal.
pub fn max_second_derivative(s: Signal) -> f64 {
    let v2 = 5.0 * 0.0105f64.powi(2) + 0.3 * 0.49;
    match s {
        Signal::VRadar => v2,
        Signal::Omega(_) => (v2 + std::f64::consts::PI.powi(2)) / R,
        Signal::Pressure(_) => 0.5 * std::f64::consts::TAU.powi(2),
    }
}

/// Tiny deterministic generator (xorshift64*), enough for jitter and noise in tests.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Sample times over `[0, duration_s]` at `rate_hz`, each moved by up to ±`jitter` of a period.
pub fn jittered_times(duration_s: f64, rate_hz: f64, jitter: f64, seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let n = (duration_s * rate_hz).floor() as usize + 1;
    let h = 1.0 / rate_hz;
    (0..n)
        .map(|k| {
            let j = if k == 0 {
                0.0
            } else {
                (rng.uniform() * 2.0 - 1.0) * jitter * h
            };
            k as f64 * h + j
        })
        .collect()
}

/// One log with a single time column (CSV shape).
pub struct Table {
    pub time_s: Vec<f64>,
    pub columns: Vec<Vec<f64>>,
}

impl Table {
    pub fn analytic(duration_s: f64, rate_hz: f64, jitter: f64, seed: u64) -> Table {
        let time_s = jittered_times(duration_s, rate_hz, jitter, seed);
        let columns = Signal::ALL
            .iter()
            .map(|s| time_s.iter().map(|t| analytic(*s, *t)).collect())
            .collect();
        Table { time_s, columns }
    }

    pub fn column(&self, s: Signal) -> &[f64] {
        &self.columns[s.index()]
    }

    pub fn write_csv(&self, path: &Path) {
        let cols: [&[f64]; 9] = std::array::from_fn(|i| self.columns[i].as_slice());
        format::write_canonical_csv(
            BufWriter::new(File::create(path).unwrap()),
            &self.time_s,
            cols,
        )
        .unwrap();
    }

    pub fn csv_bytes(&self) -> Vec<u8> {
        let cols: [&[f64]; 9] = std::array::from_fn(|i| self.columns[i].as_slice());
        let mut out = Vec::new();
        format::write_canonical_csv(&mut out, &self.time_s, cols).unwrap();
        out
    }
}

/// One log with a time base per signal (MCAP shape, channels at different rates).
pub struct MultiRate {
    pub times: Vec<Vec<f64>>,
    pub values: Vec<Vec<f64>>,
}

impl MultiRate {
    /// Radar at `radar_hz`, tachometers at `tacho_hz`, pressures at `pressure_hz`, all jittered.
    pub fn analytic(
        duration_s: f64,
        radar_hz: f64,
        tacho_hz: f64,
        pressure_hz: f64,
        jitter: f64,
        seed: u64,
    ) -> Self {
        let mut times = Vec::new();
        let mut values = Vec::new();
        for (i, s) in Signal::ALL.iter().enumerate() {
            let rate = match s {
                Signal::VRadar => radar_hz,
                Signal::Omega(_) => tacho_hz,
                Signal::Pressure(_) => pressure_hz,
            };
            let t = jittered_times(duration_s, rate, jitter, seed + i as u64);
            values.push(t.iter().map(|t| analytic(*s, *t)).collect());
            times.push(t);
        }
        MultiRate { times, values }
    }

    pub fn from_table(t: &Table) -> Self {
        MultiRate {
            times: vec![t.time_s.clone(); 9],
            values: t.columns.clone(),
        }
    }

    pub fn series(&self) -> Vec<SeriesRef<'_>> {
        Signal::ALL
            .iter()
            .map(|s| SeriesRef {
                signal: *s,
                time_s: &self.times[s.index()],
                values: &self.values[s.index()],
            })
            .collect()
    }

    pub fn mcap_bytes(&self, metadata: &RunMetadata, compression: McapCompression) -> Vec<u8> {
        let mut cur = std::io::Cursor::new(Vec::new());
        format::write_mcap(
            &mut cur,
            &self.series(),
            metadata,
            compression,
            1_700_000_000_000_000_000,
        )
        .unwrap();
        cur.into_inner()
    }
}

pub fn soap_metadata() -> RunMetadata {
    RunMetadata {
        ambient_temperature_c: Some(5.0),
        initial_speed_kmh: Some(120.0),
        vehicle: Some("UIC-Z1".into()),
        condition: Some("soap".into()),
        direction: Some("forward".into()),
        other: Default::default(),
    }
}

/// A RunLog built directly from signals on a uniform time base (no file, every sample valid).
pub fn runlog(
    name: &str,
    sample_rate_hz: f64,
    time_s: Vec<f64>,
    v_radar_mps: Vec<f64>,
    omega_radps: [Vec<f64>; 4],
    p_bar: [Vec<f64>; 4],
) -> railgrip::RunLog {
    let n = time_s.len();
    railgrip::RunLog {
        source: std::path::PathBuf::from(name),
        format: railgrip::ingest::LogFormat::Csv,
        sample_rate_hz,
        v_radar_mps,
        omega_radps,
        p_bar,
        valid: vec![true; n],
        metadata: RunMetadata::default(),
        start_log_time_ns: None,
        channels: Vec::new(),
        gaps: Vec::new(),
        warnings: Vec::new(),
        time_s,
    }
}

/// Columns of a Parquet file as f64 (any numeric type).
pub fn parquet_columns(path: &Path, names: &[&str]) -> Vec<Vec<f64>> {
    use polars::prelude::*;
    let df = ParquetReader::new(File::open(path).unwrap())
        .finish()
        .unwrap();
    names
        .iter()
        .map(|name| {
            df.column(name)
                .unwrap()
                .cast(&DataType::Float64)
                .unwrap()
                .f64()
                .unwrap()
                .into_no_null_iter()
                .collect()
        })
        .collect()
}

/// Whether python3 can `import module`; without it a test is skipped with a message — except
/// under CI=true, where it fails (`.ci/run` installs numpy and mcap). `pip` names the package.
pub fn python_has(module: &str, pip: &str) -> bool {
    let there = std::process::Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !there {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "python3 with {module} is required under CI=true (pip install {pip})"
        );
        eprintln!("SKIPPED: python3 with {module} not found (pip install {pip})");
    }
    there
}

/// The text of the default pipeline with its `[ingest.mcap]` section replaced by `mapping`
/// (the mappings of tests/data/mcap are such sections).
pub fn pipeline_text_with_mcap(mapping: &str) -> String {
    let text = railgrip::config::DEFAULT_PIPELINE_TOML;
    let cut = text
        .find("[ingest.mcap]")
        .expect("the default pipeline maps MCAP topics");
    format!("{}{mapping}", &text[..cut])
}

/// A mapping section of tests/data/mcap (`protobuf.toml`, `ros2.toml`).
pub fn mcap_mapping(name: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/mcap")
            .join(name),
    )
    .unwrap()
}

/// A bundled archive file.
pub fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/archive")
        .join(name)
}

/// A small campaign folder at `dir`: two soap CSV runs at 120 km/h with their sidecars.
pub fn two_run_campaign(dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    for f in [
        "soap_120kmh_p20.csv",
        "soap_120kmh_p20.meta.toml",
        "soap_120kmh_m20.csv",
        "soap_120kmh_m20.meta.toml",
    ] {
        std::fs::copy(fixture(f), dir.join(f)).unwrap();
    }
}

/// Splits `s` into text and numbers: a number starts at a digit, or at `-`/`.` before a digit,
/// that does not continue a word (`v1`, `mlp_2` stay text).
fn tokens(s: &str) -> Vec<Result<f64, String>> {
    let b = s.as_bytes();
    let mut out: Vec<Result<f64, String>> = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let word_before = i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_');
        let digit_at = |j: usize| j < b.len() && b[j].is_ascii_digit();
        let starts =
            !word_before && (digit_at(i) || ((b[i] == b'-' || b[i] == b'.') && digit_at(i + 1)));
        if starts {
            let mut j = i + 1;
            while j < b.len()
                && (b[j].is_ascii_digit()
                    || b[j] == b'.'
                    || b[j] == b'e'
                    || b[j] == b'E'
                    || ((b[j] == b'-' || b[j] == b'+') && matches!(b[j - 1], b'e' | b'E')))
            {
                j += 1;
            }
            // A sentence's full stop or a range's dash may follow the number: back off.
            while j > i {
                if let Ok(v) = s[i..j].parse::<f64>() {
                    out.push(Ok(v));
                    break;
                }
                j -= 1;
            }
            if j > i {
                i = j;
                continue;
            }
        }
        let c = s[i..].chars().next().unwrap();
        match out.last_mut() {
            Some(Err(t)) => t.push(c),
            _ => out.push(Err(c.to_string())),
        }
        i += c.len_utf8();
    }
    out
}

/// `got` equals `want` but for numbers, which may differ by `rel` relative or 1e-15 absolute:
/// for files holding trained weights, whose last bits follow the CPU's matrix kernels, and
/// fitted residuals that are rounding noise around zero (a k(T) through two temperatures
/// leaves ±7e-18).
pub fn assert_same_up_to_rounding(name: &str, got: &str, want: &str, rel: f64) {
    let (g, w) = (tokens(got), tokens(want));
    assert_eq!(g.len(), w.len(), "{name}: a different number of tokens");
    for (k, (a, b)) in g.iter().zip(&w).enumerate() {
        let same = match (a, b) {
            // x == y first: hex such as a generation id "6e898…" reads as ∞ on both sides.
            (Ok(x), Ok(y)) => x == y || (x - y).abs() <= rel * x.abs().max(y.abs()) + 1e-15,
            (Err(x), Err(y)) => x == y,
            _ => false,
        };
        assert!(same, "{name}: token {k} differs: got {a:?}, want {b:?}");
    }
}

/// Estimates of the bundled runs whose file name `keep` accepts, sorted by file name, as
/// `railgrip run` makes them (default UIC-Z1 pipeline).
pub fn bundled_tables(keep: impl Fn(&str) -> bool) -> Vec<railgrip::identify::RunTable> {
    let p = railgrip::Pipeline::default_uic_z1();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/archive");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| (n.ends_with(".csv") || n.ends_with(".mcap")) && keep(n))
        .collect();
    names.sort();
    names
        .iter()
        .map(|name| {
            let log = railgrip::ingest_file(&dir.join(name), &p).unwrap();
            let e = railgrip::estimate::estimate(&log, &p).unwrap();
            railgrip::identify::RunTable::from_estimates(name, name, "", &e)
        })
        .collect()
}

/// Writes the problem file `benches/peers/trainlm_numpy.py` reads: normalised data
/// (row-major inputs), initial weights, the network shape and trainlm's settings.
#[allow(clippy::too_many_arguments)]
pub fn write_trainlm_problem(
    path: &Path,
    inputs: usize,
    hidden: usize,
    (x, y, vx, vy): (&[f64], &[f64], &[f64], &[f64]),
    scale: f64,
    theta0: &[f64],
    s: &railgrip::identify::lm::LmSettings,
) {
    let problem = serde_json::json!({
        "inputs": inputs, "hidden": hidden, "train_x": x, "train_y": y, "val_x": vx,
        "val_y": vy, "theta0": theta0, "scale": scale,
        "settings": { "epochs": s.epochs, "goal": s.goal, "min_grad": s.min_grad, "mu": s.mu,
            "mu_dec": s.mu_dec, "mu_inc": s.mu_inc, "mu_max": s.mu_max, "max_fail": s.max_fail,
            "bayesian": s.bayesian },
    });
    std::fs::write(path, problem.to_string()).unwrap();
}

/// Runs `benches/peers/trainlm_numpy.py` on a problem file and returns its JSON line.
/// `threads`: BLAS threads (None: all); `probe`: the script's rounding probe ("" for none).
fn run_numpy_peer(
    problem: &Path,
    repeats: usize,
    threads: Option<usize>,
    probe: &str,
) -> Result<serde_json::Value, String> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/trainlm_numpy.py");
    let mut cmd = std::process::Command::new("python3");
    cmd.arg(&script)
        .arg(problem)
        .arg(repeats.to_string())
        .env("TRAINLM_PROBE", probe);
    if let Some(t) = threads {
        for var in ["OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"] {
            cmd.env(var, t.to_string());
        }
    }
    let out = cmd.output().map_err(|e| format!("no python3 ({e})"))?;
    if !out.status.success() {
        return Err(format!(
            "python3 {} failed: {} (needs numpy: pip install numpy)",
            script.display(),
            String::from_utf8_lossy(&out.stderr)
                .lines()
                .last()
                .unwrap_or("")
        ));
    }
    serde_json::from_slice(&out.stdout).map_err(|e| e.to_string())
}

/// A list of numbers from the peer's output.
fn numbers(v: &serde_json::Value, key: &str) -> Result<Vec<f64>, String> {
    Ok(v[key]
        .as_array()
        .ok_or(format!("no {key} in the peer's output"))?
        .iter()
        .filter_map(|x| x.as_f64())
        .collect())
}

/// What sets the numpy peer's speed on this machine, as its script reports it: numpy's
/// version, its BLAS (and the kernel OpenBLAS picked at run time), numpy's SIMD extensions and
/// np.tanh's ns per element; one line.
pub fn numpy_environment(problem: &Path) -> Result<String, String> {
    // Zero repeats: the script reports its environment without training.
    let v = run_numpy_peer(problem, 0, Some(1), "")?;
    let e = &v["environment"];
    let simd: Vec<&str> = e["simd"]
        .as_array()
        .map(|a| a.iter().filter_map(|x| x.as_str()).collect())
        .unwrap_or_default();
    Ok(format!(
        "numpy {}, BLAS {} (kernel {}), numpy SIMD [{}], np.tanh {:.1} ns per element",
        e["numpy"].as_str().unwrap_or("?"),
        e["blas"].as_str().unwrap_or("?"),
        e["blas_core"].as_str().unwrap_or("unknown"),
        simd.join(", "),
        e["tanh_ns_per_element"].as_f64().unwrap_or(f64::NAN)
    ))
}

/// This CPU: its model name and the widest vector path railgrip's kernels take on it (from
/// /proc/cpuinfo where there is one), and the logical CPUs this process may use.
pub fn cpu_line() -> String {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let field = |key: &str| {
        info.lines()
            .find(|l| l.starts_with(key))
            .and_then(|l| l.split(':').nth(1))
            .map(|s| s.trim().to_string())
    };
    let model = field("model name").unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let flags = field("flags").unwrap_or_default();
    let has = |f: &str| flags.split_whitespace().any(|x| x == f);
    // railgrip's kernels take their AVX-512 path with AVX-512F and VL, AVX2 and FMA, and their
    // AVX2 path with AVX2 and FMA.
    let width = if ["avx512f", "avx512vl", "avx2", "fma"]
        .iter()
        .all(|f| has(f))
    {
        "AVX-512"
    } else if has("avx2") && has("fma") {
        "AVX2"
    } else {
        "no AVX2"
    };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{model}, {width}, {threads} logical CPUs")
}

/// Runs the numpy trainlm peer on a problem file: the seconds per epoch of the fastest of
/// `repeats` trainings and the training MSE after each epoch. `threads`: BLAS threads (None:
/// all); `probe`: the script's rounding probe ("" for none).
pub fn trainlm_numpy(
    problem: &Path,
    repeats: usize,
    threads: Option<usize>,
    probe: &str,
) -> Result<(f64, Vec<f64>), String> {
    let v = run_numpy_peer(problem, repeats, threads, probe)?;
    let secs = v["seconds_per_epoch"]
        .as_f64()
        .ok_or("no seconds_per_epoch in the peer's output")?;
    Ok((secs, numbers(&v, "train_mse")?))
}

/// The weights numpy trainlm returns on a problem file (those of its best validation error),
/// one training, one BLAS thread.
pub fn trainlm_numpy_theta(problem: &Path) -> Result<Vec<f64>, String> {
    numbers(&run_numpy_peer(problem, 1, Some(1), "")?, "theta")
}

/// The numpy peer in trainbr mode (the problem's settings say `bayesian`), one BLAS thread:
/// training MSE and γ after each epoch.
pub fn trainbr_numpy(problem: &Path, probe: &str) -> Result<(Vec<f64>, Vec<f64>), String> {
    let v = run_numpy_peer(problem, 1, Some(1), probe)?;
    Ok((numbers(&v, "train_mse")?, numbers(&v, "gamma")?))
}

/// Times an exported C header (`c_header::c_header(…, "rg", …)`) by a small C program compiled
/// with the system `cc` at `-O2` and at `-O3 -march=native`: ns per single call and ns per
/// sample of the batch function over 1 024 inputs (slip 0…4 m/s, slip rates ±5 m/s², speeds
/// 10…39 m/s), best of 20 × 200 rounds. `single` is the C call on input `i` (e.g.
/// `rg_mu(dv[i], ddv[i])`), `batch` the batch call into `out` (e.g.
/// `rg_mu_batch(dv, ddv, 0, out, 1024)`). One line per level: (flags, ns single, ns batch),
/// or why it could not run (no cc, a compile error).
pub fn time_c_header(
    header: &str,
    single: &str,
    batch: &str,
) -> Vec<Result<(String, f64, f64), String>> {
    let dir = match tempfile::tempdir() {
        Ok(d) => d,
        Err(e) => return vec![Err(format!("no temporary folder: {e}"))],
    };
    let prog = format!(
        r#"#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#include "model.h"
int main(void) {{
    double dv[1024], ddv[1024], v[1024], out[1024], s = 0.0, best = 1e30, best_b = 1e30;
    int i, r, k;
    for (i = 0; i < 1024; ++i) {{
        dv[i] = 0.004 * i; ddv[i] = ((i * 7919) % 1000) / 100.0 - 5.0; v[i] = 10.0 + (i % 30);
    }}
    for (r = 0; r < 20; ++r) {{
        struct timespec a, b;
        clock_gettime(CLOCK_MONOTONIC, &a);
        for (k = 0; k < 200; ++k) for (i = 0; i < 1024; ++i) s += {single};
        clock_gettime(CLOCK_MONOTONIC, &b);
        double ns = ((b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec)) / (200.0 * 1024.0);
        if (ns < best) best = ns;
    }}
    for (r = 0; r < 20; ++r) {{
        struct timespec a, b;
        clock_gettime(CLOCK_MONOTONIC, &a);
        for (k = 0; k < 200; ++k) {{ {batch}; s += out[k]; }}
        clock_gettime(CLOCK_MONOTONIC, &b);
        double ns = ((b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec)) / (200.0 * 1024.0);
        if (ns < best_b) best_b = ns;
    }}
    printf("%.2f %.2f %g\n", best, best_b, s);
    return 0;
}}
"#
    );
    let written = std::fs::write(dir.path().join("model.h"), header)
        .and_then(|_| std::fs::write(dir.path().join("bench.c"), prog));
    if let Err(e) = written {
        return vec![Err(format!("cannot write the C program: {e}"))];
    }
    let exe = dir.path().join("bench");
    ["-O2", "-O3 -march=native"]
        .into_iter()
        .map(|opt| {
            let o = std::process::Command::new("cc")
                .arg("-std=c99")
                .args(opt.split(' '))
                .arg("-o")
                .arg(&exe)
                .arg(dir.path().join("bench.c"))
                .arg("-lm")
                .output()
                .map_err(|e| format!("no cc ({e})"))?;
            if !o.status.success() {
                return Err(format!("cc failed: {}", String::from_utf8_lossy(&o.stderr)));
            }
            let run = std::process::Command::new(&exe)
                .output()
                .map_err(|e| format!("cannot run the C program: {e}"))?;
            let text = String::from_utf8_lossy(&run.stdout);
            let mut it = text.split_whitespace().map(str::parse::<f64>);
            match (it.next(), it.next()) {
                (Some(Ok(ns)), Some(Ok(nb))) => Ok((opt.to_string(), ns, nb)),
                _ => Err(format!("unexpected output {text:?}")),
            }
        })
        .collect()
}

/// SHA-256 of `bytes` as lowercase hex (what railgrip writes into provenance and run records).
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest as _;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// SHA-256 of the file at `path`, lowercase hex.
pub fn sha256_file(path: &Path) -> std::io::Result<String> {
    Ok(sha256_hex(&std::fs::read(path)?))
}

/// The default pipeline with a quick deeper network: two hidden layers (6, 5) trained by AdamW
/// for 8 epochs, without Polach intervals or leave-one-run-out (tests that need a deep model
/// file, not a good one).
pub fn deep_pipeline_text() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/uic_z1.toml"))
        .unwrap()
        .replace(
            "hidden = 10",
            "layers = [6, 5]\noptimizer = \"adamw\"\nlearning_rate = 0.005\nbatch = 128",
        )
        .replace("epochs = 1000", "epochs = 8")
        .replace("polach_intervals = true", "polach_intervals = false")
        .replace("leave_one_run_out = true", "leave_one_run_out = false")
}
