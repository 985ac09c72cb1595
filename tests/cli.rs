//! The `railgrip` binary at the process boundary: output, exit codes, files written.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::*;
use railgrip::format::McapCompression;

fn railgrip(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn help_explains_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let o = railgrip(&["--help"], dir.path());
    assert_eq!(o.status.code(), Some(0));
    let s = text(&o.stdout);
    assert!(
        s.contains("ingest") && s.contains("Exit codes: 0 ok, 1 error, 2 usage, 3"),
        "{s}"
    );
    for cmd in [
        "run",
        "report",
        "simulate",
        "estimate",
        "calibrate",
        "train",
        "export",
        "eval",
        "contact",
    ] {
        assert!(s.contains(cmd), "{cmd}: {s}");
        let o = railgrip(&[cmd, "--help"], dir.path());
        assert_eq!(o.status.code(), Some(0), "{cmd} --help");
    }
    let o = railgrip(&["ingest", "--help"], dir.path());
    assert_eq!(o.status.code(), Some(0));
    let s = text(&o.stdout);
    assert!(
        s.contains("--pipeline <FILE>")
            && s.contains("--out <DIR>")
            && s.contains("runlog.parquet"),
        "{s}"
    );
}

#[test]
fn usage_errors_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(railgrip(&["ingest"], dir.path()).status.code(), Some(2));
    assert_eq!(railgrip(&["frobnicate"], dir.path()).status.code(), Some(2));
    assert_eq!(
        railgrip(&["ingest", "x.csv", "--bogus"], dir.path())
            .status
            .code(),
        Some(2)
    );
}

#[test]
fn ingest_prints_a_summary_and_writes_parquet() {
    let dir = tempfile::tempdir().unwrap();
    let table = Table::analytic(4.0, 417.0, 0.2, 1);
    table.write_csv(&dir.path().join("run.csv"));
    std::fs::write(
        dir.path().join("run.meta.toml"),
        soap_metadata().to_sidecar_toml(),
    )
    .unwrap();
    let o = railgrip(&["ingest", "run.csv", "--out", "out"], dir.path());
    let s = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{s}{}", text(&o.stderr));
    assert!(s.contains("file       run.csv (CSV)"), "{s}");
    assert!(
        s.contains("vehicle UIC-Z1 · condition soap · ambient 5 °C · initial speed 120 km/h"),
        "{s}"
    );
    assert!(s.contains("samples at 417 Hz"), "{s}");
    assert!(s.contains("v_radar  m/s"), "{s}");
    assert!(
        s.contains("gaps       none") && s.contains("warnings   none"),
        "{s}"
    );
    assert!(s.contains("wrote      out/run.runlog.parquet"), "{s}");
    assert!(dir.path().join("out/run.runlog.parquet").is_file());
}

#[test]
fn lossy_input_exits_3_and_bad_input_exits_1_writing_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mut run = MultiRate::analytic(3.0, 417.0, 417.0, 417.0, 0.0, 2);
    let i = railgrip::format::Signal::Omega(2).index();
    let keep: Vec<bool> = run.times[i]
        .iter()
        .map(|t| !(*t > 1.0 && *t < 1.5))
        .collect();
    let mut k = keep.iter();
    run.times[i].retain(|_| *k.next().unwrap());
    let mut k = keep.iter();
    run.values[i].retain(|_| *k.next().unwrap());
    std::fs::write(
        dir.path().join("gap.mcap"),
        run.mcap_bytes(&soap_metadata(), McapCompression::Zstd),
    )
    .unwrap();
    let o = railgrip(&["ingest", "gap.mcap"], dir.path());
    assert_eq!(o.status.code(), Some(3));
    let s = text(&o.stdout);
    assert!(
        s.contains("gaps       1 not interpolated:") && s.contains("omega2"),
        "{s}"
    );

    std::fs::write(dir.path().join("bad.csv"), "t,v_radar\n0,1\n").unwrap();
    let o = railgrip(&["ingest", "bad.csv", "--out", "out"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    let e = text(&o.stderr);
    assert!(
        e.starts_with("error: bad.csv: missing CSV column(s)"),
        "{e}"
    );
    assert!(
        !dir.path().join("out").exists()
            || std::fs::read_dir(dir.path().join("out")).unwrap().count() == 0
    );
}

#[test]
fn pipeline_errors_exit_1_and_name_the_key() {
    let dir = tempfile::tempdir().unwrap();
    Table::analytic(1.0, 417.0, 0.0, 3).write_csv(&dir.path().join("run.csv"));
    let p = railgrip::config::DEFAULT_PIPELINE_TOML
        .replace("sample_rate_hz = 417.0", "sample_rate_hz = 0.0");
    std::fs::write(dir.path().join("p.toml"), p).unwrap();
    let o = railgrip(&["ingest", "run.csv", "--pipeline", "p.toml"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(text(&o.stderr).trim(), "error: p.toml: ingest.sample_rate_hz = 0: must be >= 1 Hz and <= 100000 Hz (default 417 Hz)");
}

/// `railgrip eval MODEL` on the (Δv, dΔv/dt) rows `rows` (CSV lines) in `dir`: the μ column
/// (the command exits 0 and writes the header `dv_mps,ddv_mps2,mu`).
fn eval_grid(dir: &Path, model: &str, rows: &str) -> Vec<f64> {
    std::fs::write(dir.join("grid.csv"), format!("dv_mps,ddv_mps2\n{rows}")).unwrap();
    let o = railgrip(
        &["eval", model, "--input", "grid.csv", "--output", "pred.csv"],
        dir,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let pred = std::fs::read_to_string(dir.join("pred.csv")).unwrap();
    let mut lines = pred.lines();
    assert_eq!(lines.next(), Some("dv_mps,ddv_mps2,mu"));
    lines
        .map(|r| r.split(',').nth(2).unwrap().parse().unwrap())
        .collect()
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn archive(name: &str) -> String {
    format!("{}/fixtures/archive/{name}", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn estimate_writes_the_table_and_prints_per_axle_figures() {
    let dir = tempfile::tempdir().unwrap();
    let run = archive("soap_120kmh_p20.csv");
    let o = railgrip(&["estimate", &run, "--out", "est", "--csv"], dir.path());
    let s = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{s}{}", text(&o.stderr));
    for needle in [
        "zero-phase",
        "despiking",
        "peak μ",
        "utilisation",
        "filter settling",
    ] {
        assert!(s.contains(needle), "{needle}: {s}");
    }
    // Four axle rows.
    for a in 1..=4 {
        assert!(
            s.lines().any(|l| l.starts_with(&format!("{a}     "))),
            "{s}"
        );
    }
    assert!(dir
        .path()
        .join("est/soap_120kmh_p20.estimates.parquet")
        .exists());
    let csv =
        std::fs::read_to_string(dir.path().join("est/soap_120kmh_p20.estimates.csv")).unwrap();
    assert!(csv.starts_with("time_s,axle,v_mps,omega_radps,p_bar,dv_mps,ddv_mps2,slip_ratio,decel_mps2,normal_N,tangential_N,mu,valid\n"));
}

#[test]
fn estimate_errors_name_the_problem_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(
        &bad,
        railgrip::config::DEFAULT_PIPELINE_TOML
            .replace("radar_cutoff_hz = 1.5", "radar_cutoff_hz = 0.0"),
    )
    .unwrap();
    let run = archive("soap_120kmh_p20.csv");
    let o = railgrip(
        &[
            "estimate",
            &run,
            "--out",
            "est",
            "--pipeline",
            bad.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    let e = text(&o.stderr);
    assert!(
        e.contains("filters.radar_cutoff_hz = 0: must be > 0 Hz"),
        "{e}"
    );
    assert!(!dir.path().join("est").exists());
    let o = railgrip(&["estimate", "nope.csv", "--out", "est"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o.stderr).contains("nope.csv"));
}

#[test]
fn calibrate_prints_the_pipeline_line() {
    let dir = tempfile::tempdir().unwrap();
    let run = archive("dry_120kmh_p20.csv");
    let o = railgrip(&["calibrate", &run, "--davis", "1200,30,6"], dir.path());
    let s = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{s}{}", text(&o.stderr));
    let line = s
        .lines()
        .find(|l| l.starts_with("brake_torque_nm_per_bar = ["))
        .unwrap_or_else(|| panic!("{s}"));
    let alpha: f64 = line
        .trim_start_matches("brake_torque_nm_per_bar = [")
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((alpha - 1600.0).abs() < 16.0, "{line}");
    let o = railgrip(&["calibrate", &run, "--per-axle"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o.stderr).contains("use the common fit"));
    let o = railgrip(&["calibrate", &run, "--davis", "1,2"], dir.path());
    assert_eq!(o.status.code(), Some(1));
}

/// A campaign over `train.max_pooled_samples` parks most runs' tables in their estimates files
/// and reads them back thinned: `run` as one job, as estimate shards and then its models part
/// (which recalls the runs from the output folder), and `train` on the runs' estimates tables
/// train the same network as `train` on the logs (estimated on the fly, so never parked).
#[test]
fn a_campaign_over_the_sample_limit_trains_the_same_network_whole_sharded_and_from_tables() {
    let dir = tempfile::tempdir().unwrap();
    // 558 536 pooled valid samples in the bundled archive: a run or two fit, the rest park.
    let pipeline = std::fs::read_to_string(root().join("pipelines/uic_z1.toml"))
        .unwrap()
        .replace("[train]\n", "[train]\nmax_pooled_samples = 100000\n")
        // The pipeline's calibration, so that `train` on the logs estimates as `run` does.
        .replace("[estimate]\n", "[estimate]\ncalibration = \"pipeline\"\n")
        .replace("model = \"auto\" ", "model = \"mlp\" ")
        .replace("leave_one_run_out = true ", "leave_one_run_out = false ")
        .replace("polach_intervals = true ", "polach_intervals = false ");
    for key in [
        "max_pooled_samples = 100000",
        "model = \"mlp\"",
        "calibration = \"pipeline\"",
    ] {
        assert!(pipeline.contains(key), "{key}");
    }
    std::fs::write(dir.path().join("p.toml"), pipeline).unwrap();
    let campaign = archive("");
    let ok = |args: &[&str]| {
        let o = railgrip(args, dir.path());
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", text(&o.stderr));
    };
    ok(&["run", &campaign, "--out", "whole", "--pipeline", "p.toml"]);
    let whole = std::fs::read_to_string(dir.path().join("whole/models/mlp.json")).unwrap();
    let record = std::fs::read_to_string(dir.path().join("whole/campaign.json")).unwrap();
    assert!(
        record.contains("exceed train.max_pooled_samples = 100000"),
        "{record}"
    );
    for stage in [
        &["--stage", "calibrate"][..],
        &["--stage", "estimate", "--shard", "1/2"],
        &["--stage", "estimate", "--shard", "2/2"],
        &["--stage", "models"],
    ] {
        let mut args = vec!["run", &campaign, "--out", "sharded", "--pipeline", "p.toml"];
        args.extend_from_slice(stage);
        ok(&args);
    }
    let sharded = std::fs::read_to_string(dir.path().join("sharded/models/mlp.json")).unwrap();
    assert_eq!(sharded, whole, "the sharded campaign's network");
    // `train` on the whole run's estimates tables, in the campaign's order.
    let mut runs: Vec<String> = files_below(&dir.path().join("whole/runs"))
        .into_iter()
        .filter(|p| p.ends_with("estimates.parquet"))
        .map(|p| p.display().to_string())
        .collect();
    runs.sort();
    assert!(runs.len() >= 7, "{runs:?}");
    let mut args = vec![
        "train",
        "--out",
        "tables",
        "--pipeline",
        "p.toml",
        "--quiet",
    ];
    args.extend(runs.iter().map(String::as_str));
    ok(&args);
    let layers = |text: &str| -> serde_json::Value {
        serde_json::from_str::<serde_json::Value>(text).unwrap()["layers"].clone()
    };
    let from_tables = std::fs::read_to_string(dir.path().join("tables/mlp.json")).unwrap();
    assert_eq!(
        layers(&from_tables),
        layers(&whole),
        "the network from the tables"
    );
    ok(&[
        "train",
        &campaign,
        "--out",
        "logs",
        "--pipeline",
        "p.toml",
        "--quiet",
    ]);
    let from_logs = std::fs::read_to_string(dir.path().join("logs/mlp.json")).unwrap();
    assert_eq!(
        layers(&from_logs),
        layers(&whole),
        "the network from the logs"
    );
}

#[test]
fn train_takes_a_campaign_folder_like_run() {
    // `train` refused a folder ("Is a directory") while `run` took it.
    let dir = tempfile::tempdir().unwrap();
    let campaign = dir.path().join("campaign/day1");
    std::fs::create_dir_all(&campaign).unwrap();
    for f in [
        "soap_120kmh_p20.csv",
        "soap_120kmh_p20.meta.toml",
        "soap_160kmh_0c.mcap",
    ] {
        std::fs::copy(archive(f), campaign.join(f)).unwrap();
    }
    let o = railgrip(
        &["train", "campaign", "--out", "models", "--quiet"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("2 run(s)"), "{}", text(&o.stderr));
    // Provenance names each log with the hash of its bytes.
    let model = std::fs::read_to_string(dir.path().join("models/mlp.json")).unwrap();
    for f in ["soap_120kmh_p20.csv", "soap_160kmh_0c.mcap"] {
        let sha = common::sha256_file(&campaign.join(f)).unwrap();
        assert!(model.contains(&sha) && model.contains(f), "{f}: {model}");
    }
    // An empty folder: an error naming it.
    std::fs::create_dir_all(dir.path().join("empty")).unwrap();
    let o = railgrip(&["train", "empty", "--out", "m2"], dir.path());
    assert_ne!(o.status.code(), Some(0));
    assert!(
        text(&o.stderr).contains("no .csv or .mcap logs found"),
        "{}",
        text(&o.stderr)
    );
}

#[allow(clippy::too_many_lines)] // a test or benchmark: one scenario end to end
#[test]
fn train_eval_export_work_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let a = archive("soap_120kmh_p20.csv");
    let b = archive("soap_160kmh_0c.mcap");
    let o = railgrip(&["train", &a, &b, "--out", "models", "--quiet"], dir.path());
    let s = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{s}{}", text(&o.stderr));
    for needle in [
        "network 2-10-1 (2 inputs",
        "trained",
        "validation",
        "Polach",
        "95 %       mu0 [",
        // Two runs at two temperatures: no temperature law; from 120 and 160 km/h, the level's
        // speed law (the truth's falls with speed).
        "law        μ0(T) constant, k(T) constant, μ0(v) curtius_kniffler chosen by BIC among 16 forms",
        "μ0 × g(v), curtius_kniffler: c = [",
        // Polach truth: Polach's creepage, and why.
        "creepage   Polach's w/v (BIC w/v ",
    ] {
        assert!(s.contains(needle), "{needle}: {s}");
    }
    let model = dir.path().join("models/mlp.json");
    assert!(model.exists() && dir.path().join("models/mlp.history.csv").exists());
    assert!(dir.path().join("models/mlp.polach-fits.json").exists());
    // The campaign's Polach model: a model file of kind polach; two runs at two temperatures
    // do not support a temperature law (BIC), so it has none.
    let polach = std::fs::read_to_string(dir.path().join("models/mlp.polach.json")).unwrap();
    assert!(
        polach.contains("\"kind\": \"polach\"") && !polach.contains("\"temperature\""),
        "{polach}"
    );
    // A Polach model with μ0(T) and k(T): the golden file.
    let golden = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/golden/synthetic_polach.json");
    let golden = golden.to_str().unwrap();
    std::fs::write(
        dir.path().join("pgrid.csv"),
        "dv_mps,v_mps,ambient_temperature_c\n1.0,30,0\n1.0,30,20\n-1.0,30,20\n",
    )
    .unwrap();
    let o = railgrip(
        &[
            "eval",
            golden,
            "--input",
            "pgrid.csv",
            "--output",
            "ppred.csv",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let pred = std::fs::read_to_string(dir.path().join("ppred.csv")).unwrap();
    let rows: Vec<&str> = pred.lines().collect();
    assert_eq!(rows[0], "dv_mps,v_mps,ambient_temperature_c,mu");
    let mu: Vec<f64> = rows[1..]
        .iter()
        .map(|r| r.split(',').nth(3).unwrap().parse().unwrap())
        .collect();
    assert!(
        mu[0] > 0.01 && mu[0] < 0.3 && mu[1] > 0.01 && mu[1] < 0.3,
        "{mu:?}"
    );
    assert_eq!(mu[2], -mu[1]);
    let o = railgrip(&["export", golden, "--c-header", "polach.h"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(text(&o.stdout).contains("Polach with μ0(T), k(T)"));
    let h = std::fs::read_to_string(dir.path().join("polach.h")).unwrap();
    assert!(h.contains("static inline double railgrip_mu_vt(") && h.contains("atan("));

    let mu = eval_grid(dir.path(), "models/mlp.json", "0.5,1.0\n2.0,-1.0\n-0.5,0\n");
    assert_eq!(mu.len(), 3);
    assert!(mu[0] > 0.01 && mu[0] < 0.2, "{mu:?}");

    std::fs::write(
        dir.path().join("bad.csv"),
        "dv_mps,ddv_mps2\n0.5,1.0\n0.7,abc\n",
    )
    .unwrap();
    let o = railgrip(
        &[
            "eval",
            "models/mlp.json",
            "--input",
            "bad.csv",
            "--output",
            "p2.csv",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains("bad.csv: line 3, column \"ddv_mps2\""),
        "{}",
        text(&o.stderr)
    );
    assert!(!dir.path().join("p2.csv").exists());

    let o = railgrip(
        &["export", "models/mlp.json", "--c-header", "mlp.h"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let h = std::fs::read_to_string(dir.path().join("mlp.h")).unwrap();
    assert!(h.contains("static inline double railgrip_mu(double dv_mps, double ddv_mps2)"));
    let o = railgrip(
        &[
            "export",
            "models/mlp.json",
            "--c-header",
            "x.h",
            "--prefix",
            "9bad",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1));

    std::fs::write(dir.path().join("nodv.csv"), "speed,ddv_mps2\n0.5,1.0\n").unwrap();
    let o = railgrip(
        &[
            "eval",
            "models/mlp.json",
            "--input",
            "nodv.csv",
            "--output",
            "p4.csv",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains("nodv.csv: line 1: the header needs a column dv_mps"),
        "{}",
        text(&o.stderr)
    );
    // A Parquet file that is not an estimates table (here a truth table).
    let truth = archive("soap_120kmh_p20.truth.parquet");
    let o = railgrip(&["train", &truth, "--out", "m3"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    let e = text(&o.stderr);
    assert!(
        e.contains("soap_120kmh_p20.truth.parquet")
            && e.contains("no column \"valid\"")
            && e.contains("railgrip estimate"),
        "{e}"
    );
    assert!(!dir.path().join("m3/mlp.json").exists());
    let o = railgrip(&["train", "missing.csv", "--out", "m2"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o.stderr).contains("missing.csv"));
    let o = railgrip(
        &[
            "eval", "grid.csv", "--input", "grid.csv", "--output", "p3.csv",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains("not a model file"),
        "{}",
        text(&o.stderr)
    );
}

#[test]
fn train_reads_estimates_tables_with_their_metadata() {
    let dir = tempfile::tempdir().unwrap();
    for run in ["soap_120kmh_p20.csv", "soap_120kmh_m20.csv"] {
        let o = railgrip(&["estimate", &archive(run), "--out", "est"], dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    }
    let o = railgrip(
        &[
            "train",
            "est/soap_120kmh_p20.estimates.parquet",
            "est/soap_120kmh_m20.estimates.parquet",
            "--out",
            "m",
            "--quiet",
        ],
        dir.path(),
    );
    let s = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{s}{}", text(&o.stderr));
    // The ambient temperatures travelled in the tables' metadata: k(T) over −20 … 20 °C.
    assert!(s.contains("fitted over -20 … 20 °C"), "{s}");
    let model = std::fs::read_to_string(dir.path().join("m/mlp.json")).unwrap();
    assert!(model.contains("soap_120kmh_p20.estimates.parquet"));
    assert!(model.contains("\"sha256\": \""));
}

/// Files below `dir`, recursively.
fn files_below(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(files_below(&p));
        } else {
            out.push(p);
        }
    }
    out
}

#[allow(clippy::too_many_lines)] // a test or benchmark: one scenario end to end
#[test]
fn run_completes_a_campaign_with_broken_files_and_reuses_unchanged_runs() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    two_run_campaign(&camp);
    std::fs::create_dir_all(camp.join("day 2")).unwrap();
    std::fs::copy(
        archive("soap_160kmh_0c.mcap"),
        camp.join("day 2/soap_160kmh_0c.mcap"),
    )
    .unwrap();
    // Two broken logs in the middle of the campaign.
    std::fs::write(camp.join("broken.csv"), "t,v_radar\n0,abc\n").unwrap();
    // A hostile name reaches the report (failed runs table) and campaign.json only escaped.
    std::fs::write(
        camp.join("<img src=x onerror=alert(1)>.csv"),
        "t,v_radar\n0,abc\n",
    )
    .unwrap();
    std::fs::write(camp.join("day 2/truncated.mcap"), b"\x89MCAP0\r\n\x01\x02").unwrap();
    // A well-formed CSV whose last row lies 1e9 s after the others once made the
    // resampler ask for terabytes and abort the whole campaign.
    let mut far = common::Table::analytic(0.5, 417.0, 0.0, 2);
    *far.time_s.last_mut().unwrap() = 1e9;
    std::fs::write(camp.join("far.csv"), far.csv_bytes()).unwrap();
    // A FIFO as a log or a sidecar blocked the campaign forever, and a sidecar
    // pointing at /dev/zero was read to gigabytes. Both fail their own run.
    let fifo = camp.join("fifo.csv");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    std::fs::copy(
        camp.join("soap_120kmh_p20.csv"),
        camp.join("zero_sidecar.csv"),
    )
    .unwrap();
    std::os::unix::fs::symlink("/dev/zero", camp.join("zero_sidecar.meta.toml")).unwrap();
    // Files that are not logs are listed as skipped, with why (they used to be skipped silently).
    std::fs::write(camp.join("random.bin"), [7u8; 64]).unwrap();
    std::fs::write(
        camp.join("orphan.meta.toml"),
        "ambient_temperature_c = 5.0\n",
    )
    .unwrap();
    // A temporary file of a killed earlier run is cleaned up (it used to stay).
    let o_dir = dir.path().join("out");
    std::fs::create_dir_all(o_dir.join("models")).unwrap();
    let stale_tmp = o_dir.join("models/.mlp.json.tmp-999999999");
    std::fs::write(&stale_tmp, "partial").unwrap();

    let o = railgrip(
        &["run", "campaign", "--out", "out", "--jobs", "2"],
        dir.path(),
    );
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    assert_eq!(o.status.code(), Some(3), "{out}{err}");
    assert!(
        out.contains("failed     broken:")
            && out.contains("failed     day_2__truncated:")
            && out.contains("failed     far:")
            && out.contains("failed     fifo:")
            && out.contains("failed     zero_sidecar:"),
        "{out}"
    );
    assert!(out.contains("6 of 9 run(s) failed"), "{out}");
    assert!(
        out.contains("fifo.csv is a FIFO") && out.contains("zero_sidecar.meta.toml is a device"),
        "{out}"
    );
    assert!(
        out.contains("skipped    random.bin: not a .csv or .mcap log")
            && out.contains("skipped    orphan.meta.toml: a metadata sidecar without its log"),
        "{out}"
    );
    assert!(!stale_tmp.exists(), "stale temporary file left");
    assert!(
        out.contains("far.csv") && out.contains("ingest.max_duration_s"),
        "{out}"
    );
    // The errors name the file.
    assert!(
        out.contains("broken.csv") && out.contains("truncated.mcap"),
        "{out}"
    );
    for f in [
        "timings.json",
        "runs/soap_120kmh_p20/estimates.parquet",
        "runs/day_2__soap_160kmh_0c/estimates.parquet",
        "summary.csv",
        "summary.parquet",
        "campaign.json",
        "models/mlp.json",
        "models/mlp.h",
        "models/mlp.polach.json",
        "models/mlp.polach.h",
        "report/index.html",
    ] {
        assert!(o_dir.join(f).exists(), "{f}");
    }
    assert!(!o_dir.join("runs/broken/estimates.parquet").exists());
    // No temporary file left behind.
    for f in files_below(&o_dir) {
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        assert!(!name.starts_with('.'), "left behind: {}", f.display());
    }
    let summary = std::fs::read_to_string(o_dir.join("summary.csv")).unwrap();
    let rows: Vec<&str> = summary.lines().collect();
    assert_eq!(rows.len(), 10, "{summary}");
    assert!(rows[0].starts_with("run,status,error,initial_speed_kmh"));
    assert_eq!(rows.iter().filter(|r| r.contains(",failed,")).count(), 6);
    let html = std::fs::read_to_string(o_dir.join("report/index.html")).unwrap();
    assert!(
        html.contains("<svg") && html.contains("Failed runs") && html.contains("truncated.mcap"),
        "report"
    );
    assert!(html.contains("Fig. 9") && html.contains("k_A(T)") && html.contains("Fig. 11"));
    // The creepage the Polach fits took: Polach's own on this archive of Polach truth.
    assert!(html.contains("Creepage: Polach's w/v"), "report");
    // The campaign's calibration ("auto", three runs estimated): what was fitted with its
    // errors, what it does to each axle's brake force, the pad forms compared (a mixture's
    // weight beside its name) and the one chosen.
    for want in [
        "<h2>Calibration</h2>",
        "<b>campaign</b> calibration fitted on 3 of 9 runs",
        "<th>± 1σ</th>",
        "<th>brake force at ",
        "Pad friction law: ",
        "Radar: scale ",
        "the slip Δv moves by ",
        "Tachometers: delay ",
        "Running resistance: ",
        "<td class=\"l\">linear-quadratic, w = ",
        "<td class=\"l\">quadratic-cubic, w = ",
        ">chosen",
    ] {
        assert!(
            html.contains(want),
            "no {want:?} in the report's calibration"
        );
    }
    assert_eq!(
        html.matches("<td class=\"l\">karwatzki</td>").count(),
        2,
        "each pad form with one and with a constant per run"
    );
    // Every run that was estimated has its own section (drawn as the report loads the run),
    // and Fig. 10 still has the first training run's validation axle.
    let ok_runs = rows.iter().filter(|r| r.contains(",ok,")).count();
    assert!(ok_runs >= 2, "{summary}");
    for title in [
        "Vehicle and wheel peripheral speeds (Fig. 3)",
        "Brake-cylinder pressures (Fig. 4)",
        "per axle (Fig. 7)",
    ] {
        assert_eq!(html.matches(title).count(), ok_runs, "{title}");
    }
    assert!(html.contains("Fig. 10"));
    assert!(
        !html.contains("<img src=x") && html.contains("&lt;img src=x onerror=alert(1)&gt;.csv"),
        "the report must escape names"
    );
    let rec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(o_dir.join("campaign.json")).unwrap()).unwrap();
    assert!(
        rec["runs"].as_array().unwrap().iter().any(|r| r["source"]
            .as_str()
            .unwrap()
            .ends_with("<img src=x onerror=alert(1)>.csv")),
        "campaign.json holds the name exactly"
    );

    // Unchanged inputs: reused; --json on stdout.
    let o = railgrip(&["run", "campaign", "--out", "out", "--json"], dir.path());
    assert_eq!(o.status.code(), Some(3));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["reused"], 3, "{j}");
    assert_eq!(j["failed"], 6);
    assert_eq!(j["skipped"].as_array().unwrap().len(), 2, "{j}");
    // With runs reused, the model files' provenance hashed the estimates tables, not
    // the logs they name.
    let mlp: serde_json::Value =
        serde_json::from_slice(&std::fs::read(o_dir.join("models/mlp.json")).unwrap()).unwrap();
    let inputs = mlp["provenance"]["inputs"].as_array().unwrap();
    assert_eq!(inputs.len(), 3, "{inputs:?}");
    for i in inputs {
        let log = dir.path().join(i["path"].as_str().unwrap());
        let want = common::sha256_file(&log).unwrap();
        assert_eq!(i["sha256"], want.as_str(), "{}", log.display());
    }
    assert_eq!(j["exit_code"], 3);
    assert_eq!(j["condition"], "soap");
    // The chosen model and the candidates' table, as campaign.json and mlp.choice.json hold
    // them.
    let camp_json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(o_dir.join("campaign.json")).unwrap()).unwrap();
    let chosen = camp_json["chosen_model"].as_str().unwrap();
    assert!(
        j["chosen"]["path"].as_str().unwrap().ends_with(chosen),
        "{} against {chosen}",
        j["chosen"]
    );
    let choice: serde_json::Value =
        serde_json::from_slice(&std::fs::read(o_dir.join("models/mlp.choice.json")).unwrap())
            .unwrap();
    assert_eq!(j["choice"], choice);
    // A changed sidecar invalidates its run only.
    let meta = camp.join("soap_120kmh_m20.meta.toml");
    let t = std::fs::read_to_string(&meta).unwrap();
    std::fs::write(&meta, t + "\n# edited\n").unwrap();
    let o = railgrip(&["run", "campaign", "--out", "out", "--json"], dir.path());
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["reused"], 2, "{j}");
    let o = railgrip(
        &["run", "campaign", "--out", "out", "--json", "--force"],
        dir.path(),
    );
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["reused"], 0, "{j}");

    // The report rebuilds from the outputs alone.
    std::fs::remove_file(o_dir.join("report/index.html")).unwrap();
    let o = railgrip(&["report", "out"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(o_dir.join("report/index.html").exists());

    // Each run on a page of its own: index.html links every estimated run's page (its name
    // percent-encoded) and draws none of their charts; each page has its run's three.
    let o = railgrip(&["report", "out", "--run-sections", "pages"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let index = std::fs::read_to_string(o_dir.join("report/index.html")).unwrap();
    assert_eq!(
        index
            .matches("Vehicle and wheel peripheral speeds (Fig. 3)")
            .count(),
        0
    );
    assert!(
        index.contains("Fig. 10") && index.contains("Fig. 11"),
        "the rest stays"
    );
    let decode = |s: &str| -> String {
        let b = s.as_bytes();
        let mut out = Vec::new();
        let mut k = 0;
        while k < b.len() {
            if b[k] == b'%' {
                out.push(u8::from_str_radix(&s[k + 1..k + 3], 16).unwrap());
                k += 3;
            } else {
                out.push(b[k]);
                k += 1;
            }
        }
        String::from_utf8(out).unwrap()
    };
    let mut linked: Vec<String> = index
        .split("href=\"runs/")
        .skip(1)
        .map(|rest| decode(&rest[..rest.find('"').unwrap()]))
        .collect();
    linked.sort();
    linked.dedup();
    assert_eq!(linked.len(), ok_runs, "{linked:?}");
    let mut pages: Vec<String> = std::fs::read_dir(o_dir.join("report/runs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    pages.sort();
    assert_eq!(pages, linked, "every page linked, every link a page");
    for p in &pages {
        let page = std::fs::read_to_string(o_dir.join("report/runs").join(p)).unwrap();
        for title in [
            "Vehicle and wheel peripheral speeds (Fig. 3)",
            "Brake-cylinder pressures (Fig. 4)",
            "per axle (Fig. 7)",
        ] {
            assert_eq!(page.matches(title).count(), 1, "{p}: {title}");
        }
        assert!(page.contains("href=\"../index.html\"") && page.ends_with("</body></html>\n"));
    }
    // Inline again (auto: fewer runs than a page each needs): the pages are gone.
    let o = railgrip(&["report", "out"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(!o_dir.join("report/runs").exists());
    let index = std::fs::read_to_string(o_dir.join("report/index.html")).unwrap();
    assert_eq!(
        index
            .matches("Vehicle and wheel peripheral speeds (Fig. 3)")
            .count(),
        ok_runs
    );

    // `bad` written over an output file: `report` exits 1 (the file restored after); its error.
    let refused = |file: &str, bad: &str| -> String {
        let path = o_dir.join(file);
        let good = std::fs::read(&path).unwrap();
        std::fs::write(&path, bad).unwrap();
        let o = railgrip(&["report", "out"], dir.path());
        std::fs::write(&path, good).unwrap();
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{file}: {err}");
        err
    };

    // A model file of another generation (a killed re-run) is refused by name.
    let good = std::fs::read_to_string(o_dir.join("models/mlp.json")).unwrap();
    let camp_rec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(o_dir.join("campaign.json")).unwrap()).unwrap();
    let g = camp_rec["generation"].as_str().unwrap();
    assert_eq!(g.len(), 16);
    assert!(good.contains(g));
    let err = refused("models/mlp.json", &good.replace(g, "0123456789abcdef"));
    assert!(
        err.contains("mlp.json") && err.contains("generation 0123456789abcdef"),
        "{err}"
    );

    // A corrupt model or fits file is an error naming it, not a report without that section.
    for (file, bad) in [
        ("models/mlp.polach-fits.json", "{\"pooled\": 3}"),
        ("models/mlp.json", "{}"),
    ] {
        let err = refused(file, bad);
        assert!(err.contains(file) && err.contains("Hint:"), "{file}: {err}");
    }
    // A run's table without a column the report reads (a truth table in its place): named,
    // with the column.
    let table = o_dir.join("runs/soap_120kmh_p20/estimates.parquet");
    let good = std::fs::read(&table).unwrap();
    std::fs::copy(archive("soap_120kmh_p20.truth.parquet"), &table).unwrap();
    let o = railgrip(&["report", "out"], dir.path());
    std::fs::write(&table, good).unwrap();
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("soap_120kmh_p20/estimates.parquet") && err.contains("no column valid"),
        "{err}"
    );
    // A creepage the fits cannot have taken: named, with the values it may take.
    let fits = "models/mlp.polach-fits.json";
    let good = std::fs::read_to_string(o_dir.join(fits)).unwrap();
    let chosen = "\"chosen\": \"rolling_speed\"";
    assert!(good.contains(chosen), "{good}");
    let err = refused(fits, &good.replace(chosen, "\"chosen\": \"sideways\""));
    assert!(
        err.contains("mlp.polach-fits.json")
            && err.contains("sideways")
            && err.contains("fixed_speed"),
        "{err}"
    );
}

#[test]
fn run_refuses_what_is_not_a_campaign() {
    let dir = tempfile::tempdir().unwrap();
    let o = railgrip(&["run", "nowhere"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o.stderr).contains("nowhere"), "{}", text(&o.stderr));
    std::fs::create_dir(dir.path().join("empty")).unwrap();
    let o = railgrip(&["run", "empty"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains("no .csv or .mcap logs found"),
        "{}",
        text(&o.stderr)
    );
    let o = railgrip(&["report", "empty"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains("campaign.json"),
        "{}",
        text(&o.stderr)
    );
}

#[test]
fn interrupting_run_leaves_no_complete_looking_partial_file() {
    // SIGINT at several moments of a run on the bundled archive: whatever exists under a final
    // name afterwards is complete (Parquet and JSON parse, CSV has its header); partial files
    // can only be hidden temporaries.
    for delay_ms in [150u64, 400, 900] {
        let dir = tempfile::tempdir().unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_railgrip"))
            .args(["run", "--out", "out"])
            .current_dir(dir.path())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status();
        let _ = child.wait();
        let out = dir.path().join("out");
        if !out.exists() {
            continue;
        }
        for f in files_below(&out) {
            let name = f.file_name().unwrap().to_string_lossy().into_owned();
            if name.starts_with('.') {
                continue;
            }
            if name.ends_with(".parquet") {
                let file = std::fs::File::open(&f).unwrap();
                use polars::prelude::*;
                ParquetReader::new(file)
                    .finish()
                    .unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            } else if name.ends_with(".json") {
                let t = std::fs::read_to_string(&f).unwrap();
                serde_json::from_str::<serde_json::Value>(&t)
                    .unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            } else if name.ends_with(".html") {
                let t = std::fs::read_to_string(&f).unwrap();
                assert!(t.trim_end().ends_with("</html>"), "{}", f.display());
            }
        }
    }
}

/// `eval` and `export` of a four-input network (the golden file): the temperature column is
/// required, used, and the header offers the batch call with temperatures.
#[test]
fn eval_of_a_four_input_network_needs_and_uses_the_temperature() {
    let dir = tempfile::tempdir().unwrap();
    let model =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/golden/synthetic_mlp_4inputs.json");
    let model = model.to_str().unwrap();
    std::fs::write(
        dir.path().join("g.csv"),
        "dv_mps,ddv_mps2,v_mps\n1.5,0.5,25\n",
    )
    .unwrap();
    let o = railgrip(
        &["eval", model, "--input", "g.csv", "--output", "p.csv"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    let e = text(&o.stderr);
    assert!(
        e.contains("g.csv: line 1") && e.contains("ambient_temperature_c"),
        "{e}"
    );
    assert!(!dir.path().join("p.csv").exists());
    std::fs::write(
        dir.path().join("g.csv"),
        "dv_mps,ddv_mps2,v_mps,ambient_temperature_c\n1.5,0.5,25,-10\n1.5,0.5,25,20\n",
    )
    .unwrap();
    let o = railgrip(
        &["eval", model, "--input", "g.csv", "--output", "p.csv"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let pred = std::fs::read_to_string(dir.path().join("p.csv")).unwrap();
    let mu: Vec<f64> = pred
        .lines()
        .skip(1)
        .map(|r| r.split(',').nth(4).unwrap().parse().unwrap())
        .collect();
    // The synthetic law's level is 18 % higher at −10 °C than at +20 °C.
    assert!(mu[0] > 1.1 * mu[1], "{mu:?}");
    let o = railgrip(&["export", model, "--c-header", "m.h"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(text(&o.stdout).contains("(4 inputs, "));
    let h = std::fs::read_to_string(dir.path().join("m.h")).unwrap();
    assert!(h.contains("railgrip_mu_batch_t(") && h.contains("#define RAILGRIP_N_INPUTS 4"));
}

/// The two soap CSV runs of [`two_run_campaign`] and an MCAP run at 160 km/h.
fn three_run_campaign(camp: &Path) {
    two_run_campaign(camp);
    std::fs::copy(
        archive("soap_160kmh_0c.mcap"),
        camp.join("soap_160kmh_0c.mcap"),
    )
    .unwrap();
}

/// Every file below `dir` (relative path → bytes), leaving out `timings.json`.
fn outputs(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    files_below(dir)
        .into_iter()
        .filter(|p| p.file_name().unwrap() != "timings.json")
        .map(|p| {
            (
                p.strip_prefix(dir).unwrap().to_path_buf(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect()
}

#[test]
fn run_outputs_are_the_same_bytes_for_any_jobs_and_on_a_rerun() {
    // run.json, campaign.json, summary, model files and the report once differed between
    // identical runs only in timing and clock fields. Now those are in timings.json alone.
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    three_run_campaign(&camp);
    let run = |out: &str, jobs: &str, force: bool| {
        let mut args = vec!["run", "campaign", "--out", out, "--jobs", jobs];
        if force {
            args.push("--force");
        }
        let o = railgrip(&args, dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
        outputs(&dir.path().join(out))
    };
    let a = run("a", "1", false);
    let b = run("b", "2", false);
    assert!(
        a.contains_key(Path::new("report/index.html")) && a.len() >= 12,
        "{:?}",
        a.keys()
    );
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        assert!(
            b[k] == *v,
            "{} differs between --jobs 1 and --jobs 2",
            k.display()
        );
    }
    // Twice each: a re-run that reuses every run, and one that recomputes them.
    let a2 = run("a", "2", false);
    let b2 = run("b", "1", true);
    for (again, name) in [(&a2, "reused re-run"), (&b2, "forced re-run")] {
        assert_eq!(
            again.keys().collect::<Vec<_>>(),
            a.keys().collect::<Vec<_>>()
        );
        for (k, v) in &a {
            assert!(again[k] == *v, "{} differs after a {name}", k.display());
        }
    }
    let t: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("a/timings.json")).unwrap()).unwrap();
    assert_eq!(t["runs"].as_array().unwrap().len(), 3, "{t}");
    assert!(
        t["runs"]
            .as_array()
            .unwrap()
            .iter()
            .all(|r| r["reused"] == true),
        "{t}"
    );
}

#[test]
fn a_campaign_where_every_run_fails_exits_1_for_no_models() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    std::fs::create_dir_all(&camp).unwrap();
    std::fs::write(camp.join("broken.csv"), "t,v_radar\n0,abc\n").unwrap();
    let o = railgrip(&["run", "campaign", "--out", "out"], dir.path());
    let out = text(&o.stdout);
    assert_eq!(o.status.code(), Some(1), "{out}");
    assert!(
        out.contains("No models were trained") && out.contains("Exit code 1"),
        "{out}"
    );
}

#[test]
fn an_unwritable_output_folder_fails_before_any_run_is_estimated() {
    // A read-only output folder was found only after training. (The tests may run
    // as root, who may write anywhere: a file where the models folder belongs stands in.)
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    two_run_campaign(&camp);
    std::fs::create_dir_all(dir.path().join("out")).unwrap();
    std::fs::write(dir.path().join("out/models"), "not a folder").unwrap();
    let o = railgrip(&["run", "campaign", "--out", "out"], dir.path());
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("out/models: cannot write") && err.contains("exists"),
        "{err}"
    );
    assert!(!dir.path().join("out/runs/soap_120kmh_p20").exists());
}

#[test]
fn write_errors_name_the_file_and_the_operating_systems_cause() {
    let dir = tempfile::tempdir().unwrap();
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/golden/synthetic_mlp.json");
    let o = railgrip(
        &[
            "export",
            model.to_str().unwrap(),
            "--c-header",
            "missing/dir/m.h",
        ],
        dir.path(),
    );
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("missing/dir/m.h: cannot write") && err.contains("No such file or directory"),
        "{err}"
    );
}

#[test]
fn a_csv_that_panics_the_csv_parser_exits_1_with_a_clean_error() {
    // Found by fuzzing: polars panics on this file; railgrip exited 101 with a
    // backtrace. Now: exit 1, the file and line named, no panic text.
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz/polars_panic_builder_141.csv"),
        dir.path().join("found.csv"),
    )
    .unwrap();
    let o = railgrip(&["ingest", "found.csv"], dir.path());
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("found.csv: line 2") && !err.contains("panicked"),
        "{err}"
    );
}

#[test]
fn contact_writes_creep_curves_and_temperatures_and_refuses_bad_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("curves.csv");
    let o = railgrip(
        &[
            "contact",
            "--law",
            "linear,polach,fastsim,fastsim-modified",
            "--steps",
            "21",
            "--creepage-max",
            "0.002",
            "--temperature",
            "--out",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("C33"), "{}", text(&o.stderr));
    let csv = std::fs::read_to_string(&out).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 21);
    let (mu, t, lin) = (
        col("mu_fastsim"),
        col("peak_temperature_c"),
        col("mu_linear"),
    );
    for w in rows.windows(2) {
        // FASTSIM's curve rises towards μ0 = 0.3 and never past it; the contact warms with slip.
        assert!(w[1][mu] >= w[0][mu] && w[1][mu] <= 0.3 + 1e-12);
        assert!(w[1][t] >= w[0][t]);
    }
    assert!(rows[20][t] > rows[0][t] + 1.0);
    // At the first step the linear theory and FASTSIM agree (small creepage) within 5 %.
    assert!(
        (rows[1][mu] / rows[1][lin] - 1.0).abs() < 0.05,
        "{:?}",
        rows[1]
    );
    assert_eq!(rows[0][t], 20.0, "no slip, no heat");
    for (args, says) in [
        (vec!["contact", "--grid", "0"], "1 ..= 1000"),
        (vec!["contact", "--grid", "1001"], "1 ..= 1000"),
        (vec!["contact", "--load-n", "nan"], "normal force"),
        (
            vec![
                "contact",
                "--temperature",
                "--initial-temperature-c",
                "-300",
            ],
            "absolute zero",
        ),
        (
            vec!["contact", "--temperature", "--law", "polach"],
            "needs a FASTSIM law",
        ),
        (vec!["contact", "--poisson", "0.7"], "Poisson"),
    ] {
        let o = railgrip(&args, dir.path());
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        let e = text(&o.stderr);
        assert!(e.contains(says), "{args:?}: {e}");
        assert!(!e.contains("panicked"), "{e}");
    }
}

/// `railgrip train` with `train.layers` and `optimizer = "adam"` trains a deeper
/// network through burn and writes a version-3 model file that `eval` and `export --c-header`
/// take like any other.
#[test]
fn train_a_deeper_network_through_burn_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = deep_pipeline_text();
    std::fs::write(dir.path().join("deep.toml"), pipeline).unwrap();
    let a = archive("soap_120kmh_p20.csv");
    let o = railgrip(
        &[
            "train",
            &a,
            "--pipeline",
            "deep.toml",
            "--out",
            "m",
            "--quiet",
        ],
        dir.path(),
    );
    let s = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{s}{}", text(&o.stderr));
    assert!(s.contains("network 2-6-5-1 (2 inputs"), "{s}");
    let file = std::fs::read_to_string(dir.path().join("m/mlp.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&file).unwrap();
    assert_eq!(v["version"], 3);
    assert_eq!(v["layers"].as_array().unwrap().len(), 3);
    assert!(v["history"].as_array().unwrap().len() <= 8);
    let mu = eval_grid(dir.path(), "m/mlp.json", "0.5,1.0\n-0.5,-1.0\n");
    assert!(mu[0] > 0.0 && mu[0] < 0.3 && mu[1] == -mu[0], "{mu:?}");
    let o = railgrip(
        &["export", "m/mlp.json", "--c-header", "deep.h"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let h = std::fs::read_to_string(dir.path().join("deep.h")).unwrap();
    assert!(h.contains("#define RAILGRIP_N_DEEP 1"), "{h}");
}

/// The model choice writes every candidate, its table and the chosen file's name, the same
/// bytes on one worker thread as on two (folds and candidates run in parallel); a named
/// `train.model` is obeyed and writes no candidates beyond the network and the Polach model.
#[test]
fn the_model_choice_names_its_file_and_is_the_same_on_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    three_run_campaign(&camp);
    let run = |out: &str, threads: &str, pipeline: Option<&str>| {
        let mut args = vec!["run", "campaign", "--out", out, "--mcap"];
        if let Some(p) = pipeline {
            args.extend(["--pipeline", p]);
        }
        let o = Command::new(env!("CARGO_BIN_EXE_railgrip"))
            .args(&args)
            .current_dir(dir.path())
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
        (outputs(&dir.path().join(out)), text(&o.stdout))
    };
    let (one, printed) = run("one", "1", None);
    let (two, _) = run("two", "2", None);
    assert_eq!(
        one.keys().collect::<Vec<_>>(),
        two.keys().collect::<Vec<_>>()
    );
    for (k, v) in &one {
        assert!(
            two[k] == *v,
            "{} differs between 1 and 2 threads",
            k.display()
        );
    }
    let camp_json: serde_json::Value =
        serde_json::from_slice(&one[Path::new("campaign.json")]).unwrap();
    let chosen = camp_json["chosen_model"].as_str().unwrap();
    let choice: serde_json::Value =
        serde_json::from_slice(&one[Path::new("models/mlp.choice.json")]).unwrap();
    let name = choice["chosen"].as_str().unwrap();
    assert_eq!(choice["setting"], "auto");
    assert_eq!(choice["folds"], 3, "{choice}");
    let names: Vec<&str> = choice["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    // Three runs at three temperatures: the 4-input network is a candidate.
    assert_eq!(names, ["polach", "mlp", "mlp_3in", "mlp_4in", "residual"]);
    for c in choice["candidates"].as_array().unwrap() {
        assert!(c["rmse_mu"].as_f64().unwrap() > 0.0, "{c}");
        assert_eq!(c["runs"].as_array().unwrap().len(), 3, "{c}");
        // `run` prints the candidates' table as `train` does, a line each.
        let line = format!("candidate  {:<9}", c["name"].as_str().unwrap());
        let rmse = format!("held-out RMSE {:.5}", c["rmse_mu"].as_f64().unwrap());
        assert!(
            printed
                .lines()
                .any(|l| l.starts_with(&line) && l.contains(&rmse)),
            "{line} … {rmse} not in:\n{printed}"
        );
    }
    let best = choice["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .min_by(|a, b| {
            a["rmse_mu"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["rmse_mu"].as_f64().unwrap())
        })
        .unwrap();
    assert_eq!(best["name"], name);
    // The chosen file and its header exist; the report names it.
    assert!(one.contains_key(Path::new(chosen)), "{chosen}");
    assert!(
        one.contains_key(Path::new(&chosen.replace(".json", ".h"))),
        "{chosen}"
    );
    let report = String::from_utf8_lossy(&one[Path::new("report/index.html")]).into_owned();
    assert!(
        report.contains("Campaign model") && report.contains(chosen),
        "report"
    );
    // The bundled campaign's Polach law has a speed law: the report draws μ0 × g(v).
    let polach: serde_json::Value =
        serde_json::from_slice(&one[Path::new("models/mlp.polach.json")]).unwrap();
    assert!(polach["polach"]["speed"].is_object(), "no speed law");
    assert!(
        report.contains("Speed law of the level"),
        "no speed-law chart"
    );
    // A named model: the Polach model, no other candidates, no scores.
    let pipeline = dir.path().join("polach.toml");
    let text_p =
        railgrip::config::DEFAULT_PIPELINE_TOML.replace("model = \"auto\"", "model = \"polach\"");
    std::fs::write(&pipeline, text_p).unwrap();
    let (named, _) = run("named", "2", Some(pipeline.to_str().unwrap()));
    let camp_json: serde_json::Value =
        serde_json::from_slice(&named[Path::new("campaign.json")]).unwrap();
    assert_eq!(camp_json["chosen_model"], "models/mlp.polach.json");
    let others = ["2in", "3in", "4in", "residual"];
    let other = |k: &Path| {
        let n = k.to_string_lossy();
        others
            .iter()
            .any(|o| n.contains(&format!("mlp.{o}.json")) || n.contains(&format!("mlp.{o}.h")))
    };
    assert!(!named.keys().any(|k| other(k)), "{:?}", named.keys());
    let choice: serde_json::Value =
        serde_json::from_slice(&named[Path::new("models/mlp.choice.json")]).unwrap();
    assert_eq!(choice["candidates"].as_array().unwrap().len(), 0);
    assert_eq!(choice["folds"], 0);
    // The same over the first output folder: the candidates it held are removed.
    assert!(one.keys().any(|k| other(k)));
    let (again, _) = run("one", "2", Some(pipeline.to_str().unwrap()));
    assert!(!again.keys().any(|k| other(k)), "{:?}", again.keys());
}

#[test]
fn estimate_shards_then_the_models_stage_write_the_bytes_of_one_run() {
    // A scheduler's job array: each shard a separate process on the shared output folder,
    // then the models stage. A broken log fails in its shard and stays a failed record.
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    three_run_campaign(&camp);
    std::fs::write(camp.join("broken.csv"), "t,v_radar\n0,abc\n").unwrap();
    let one = railgrip(&["run", "campaign", "--out", "one"], dir.path());
    assert_eq!(one.status.code(), Some(3), "{}", text(&one.stderr));
    // The default pipeline calibrates the campaign: a shard refuses to start without it.
    let early = railgrip(
        &[
            "run", "campaign", "--out", "sh", "--stage", "estimate", "--shard", "1/3",
        ],
        dir.path(),
    );
    assert_eq!(early.status.code(), Some(1), "{}", text(&early.stdout));
    assert!(
        text(&early.stderr).contains("--stage calibrate"),
        "{}",
        text(&early.stderr)
    );
    let c = railgrip(
        &["run", "campaign", "--out", "sh", "--stage", "calibrate"],
        dir.path(),
    );
    assert_eq!(c.status.code(), Some(0), "{}", text(&c.stderr));
    let out = text(&c.stdout);
    assert!(
        out.contains("campaign calibration over") && out.contains("broken"),
        "{out}"
    );
    for k in 1..=3 {
        let shard = format!("{k}/3");
        let o = railgrip(
            &[
                "run", "campaign", "--out", "sh", "--stage", "estimate", "--shard", &shard,
            ],
            dir.path(),
        );
        let out = text(&o.stdout);
        assert!(
            o.status.code() == Some(0) || o.status.code() == Some(3),
            "{out}"
        );
        assert!(out.contains(&format!("estimate shard {k}/3")), "{out}");
        assert!(!dir.path().join("sh/campaign.json").exists());
    }
    let m = railgrip(
        &["run", "campaign", "--out", "sh", "--stage", "models"],
        dir.path(),
    );
    assert_eq!(m.status.code(), Some(3), "{}", text(&m.stdout));
    let (a, b) = (
        outputs(&dir.path().join("one")),
        outputs(&dir.path().join("sh")),
    );
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        assert!(
            b[k] == *v,
            "{} differs between one run and the shards",
            k.display()
        );
    }
    assert!(a.contains_key(Path::new("campaign.json")) && a.len() >= 12);
}

#[test]
fn the_models_stage_refuses_missing_and_stale_runs_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    two_run_campaign(&camp);
    // Only the first of two shards has run.
    let o = railgrip(
        &[
            "run", "campaign", "--out", "sh", "--stage", "estimate", "--shard", "1/2",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let m = railgrip(
        &["run", "campaign", "--out", "sh", "--stage", "models"],
        dir.path(),
    );
    let err = text(&m.stderr);
    assert_eq!(m.status.code(), Some(1), "{err}");
    assert!(
        err.contains("1 of the campaign's 2 runs")
            && err.contains("soap_120kmh_p20 (not estimated)")
            && err.contains("--stage estimate --shard"),
        "{err}"
    );
    assert!(!dir.path().join("sh/models/mlp.json").exists());
    // The second shard, then a log that changes after its shard estimated it: stale.
    let o = railgrip(
        &[
            "run", "campaign", "--out", "sh", "--stage", "estimate", "--shard", "2/2",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let sidecar = camp.join("soap_120kmh_m20.meta.toml");
    let mut side = std::fs::read_to_string(&sidecar).unwrap();
    side.push_str("\n# edited\n");
    std::fs::write(&sidecar, side).unwrap();
    let m = railgrip(
        &["run", "campaign", "--out", "sh", "--stage", "models"],
        dir.path(),
    );
    let err = text(&m.stderr);
    assert_eq!(m.status.code(), Some(1), "{err}");
    assert!(err.contains("soap_120kmh_m20 (stale"), "{err}");
    // Usage: a shard needs the estimate stage, K/N must make sense, models does not force.
    for args in [
        &["run", "campaign", "--shard", "1/2"][..],
        &["run", "campaign", "--stage", "estimate", "--shard", "3/2"],
        &["run", "campaign", "--stage", "estimate", "--shard", "0/2"],
        &["run", "campaign", "--stage", "estimate", "--shard", "x"],
        &["run", "campaign", "--stage", "models", "--force"],
    ] {
        let o = railgrip(args, dir.path());
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", text(&o.stderr));
        assert!(text(&o.stderr).contains("--"), "{args:?}");
    }
}

#[test]
fn the_slurm_script_runs_the_calibration_the_shards_then_the_models_stage() {
    // scripts/slurm-campaign.sh against a stand-in for sbatch that runs each job at once
    // (array tasks one after the other with SLURM_ARRAY_TASK_ID set) and records its options.
    // The script was also run under a real single-node Slurm 22.05 (docs/cluster.md).
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    three_run_campaign(&camp);
    let fake = dir.path().join("sbatch");
    std::fs::write(
        &fake,
        r#"#!/usr/bin/env bash
set -euo pipefail
echo "$*" >> "$(dirname "$0")/submitted.txt"
array="" wrap="" name=""
for a in "$@"; do
    case $a in
        --array=*) array=${a#--array=} ;;
        --wrap=*) wrap=${a#--wrap=} ;;
        --job-name=*) name=${a#--job-name=} ;;
    esac
done
if [ -n "$array" ]; then
    for k in $(seq "${array%-*}" "${array#*-}"); do
        SLURM_ARRAY_TASK_ID=$k bash -c "$wrap" > /dev/null || [ $? -eq 3 ]
    done
    echo 101
elif [ "$name" = railgrip-calibrate ]; then
    bash -c "$wrap" > /dev/null
    echo 100
else
    bash -c "$wrap" > /dev/null
    echo 102
fi
"#,
    )
    .unwrap();
    std::process::Command::new("chmod")
        .args(["+x", fake.to_str().unwrap()])
        .status()
        .unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/slurm-campaign.sh");
    let o = Command::new(&script)
        .args(["campaign", "sh", "2"])
        .current_dir(dir.path())
        .env("SBATCH", &fake)
        .env("RAILGRIP", env!("CARGO_BIN_EXE_railgrip"))
        .env("SBATCH_MODELS_OPTS", "--cpus-per-task=2")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stdout)
        .contains("calibration: job 100; estimate shards: job 101 (array 1-2); models: job 102"));
    let submitted = std::fs::read_to_string(dir.path().join("submitted.txt")).unwrap();
    assert!(
        submitted.contains("--dependency=afterok:100")
            && submitted.contains("--dependency=afterany:101"),
        "{submitted}"
    );
    // The default pipeline ("auto") calibrates the three runs; every part took that calibration.
    assert!(dir.path().join("sh/calibration.json").is_file());
    assert!(
        submitted.contains("--cpus-per-task=2 --job-name=railgrip-models"),
        "{submitted}"
    );
    let one = railgrip(&["run", "campaign", "--out", "one"], dir.path());
    assert_eq!(one.status.code(), Some(0), "{}", text(&one.stderr));
    let (a, b) = (
        outputs(&dir.path().join("one")),
        outputs(&dir.path().join("sh")),
    );
    assert!(a.contains_key(Path::new("campaign.json")));
    for (k, v) in &a {
        assert!(b.get(k) == Some(v), "{} differs", k.display());
    }
    // Usage errors exit 2 before anything is submitted.
    let o = Command::new(&script)
        .args(["campaign", "sh", "0"])
        .current_dir(dir.path())
        .env("SBATCH", &fake)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
}

/// A JSON file, parsed.
fn json_file(path: impl AsRef<Path>) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The bundled pipeline with `estimate.calibration` set, written into `dir`.
fn calibrated_pipeline(dir: &Path, source: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("pipelines/uic_z1.toml")).unwrap();
    let text = text.replacen(
        "[estimate]\n",
        &format!("[estimate]\ncalibration = \"{source}\"\n"),
        1,
    );
    let path = dir.join(format!("{source}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// A campaign calibration's record gives each run's constant of the balance, finite and with
/// a positive error, under the campaign's name for the run; `calibrate` prints them.
fn assert_run_constants(record: &serde_json::Value, stdout: &str) {
    assert!(stdout.contains("constant   "), "{stdout}");
    let constants = record["campaign"]["resistance_constants"]
        .as_array()
        .unwrap();
    let names: Vec<&str> = constants
        .iter()
        .map(|c| c["run"].as_str().unwrap())
        .collect();
    let runs: Vec<&str> = record["calibrated"]["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_str().unwrap())
        .collect();
    assert_eq!(names, runs);
    assert!(constants
        .iter()
        .all(|c| c["constant_n"].as_f64().is_some_and(f64::is_finite)
            && c["se_n"].as_f64().is_some_and(|x| x > 0.0)));
}

#[test]
fn calibrate_a_campaign_and_give_its_calibration_to_every_part() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (camp, pipe, cal) = bundled_calibration(d);
    let (camp, pipe, cal) = (camp.as_str(), pipe.as_str(), cal.as_str());
    // Written only for a pipeline that runs with it: the default ("auto") does.
    let own = calibrated_pipeline(d, "pipeline").display().to_string();
    let o = railgrip(
        &[
            "calibrate",
            "--campaign",
            camp,
            "--out",
            "x",
            "--pipeline",
            &own,
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o.stderr).contains("estimate.calibration is \"pipeline\""));

    let o = railgrip(&["calibrate", "--campaign", camp], d);
    let s = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{s}{}", text(&o.stderr));
    for want in ["α1 ", "α4 ", "pad ", "radar      scale", "tachos     delay"] {
        assert!(s.contains(want), "{want}: {s}");
    }
    // One bundled run's radar is logged at its own rate: its samples do not show its noise,
    // and the residual is held against the other seven runs' (all of it their noise).
    assert!(
        s.contains("noise      the radar's 0.050")
            && s.contains("on the 7 of 8 runs whose radar shows it")
            && s.contains("the residual shows nothing but the radar's noise"),
        "{s}"
    );
    let record = json_file(cal);
    assert_eq!(record["calibrated"]["source"], "campaign");
    assert_eq!(record["calibrated"]["runs"].as_array().unwrap().len(), 8);
    assert_run_constants(&record, &s);

    // A shard of a campaign whose pipeline asks for the calibration needs it given.
    let shard = [
        "run",
        camp,
        "--pipeline",
        pipe,
        "--out",
        "o",
        "--stage",
        "estimate",
        "--shard",
        "1/2",
    ];
    let o = railgrip(&shard, d);
    assert_eq!(o.status.code(), Some(1));
    let e = text(&o.stderr);
    assert!(
        e.contains("--calibration") && e.contains("railgrip calibrate --campaign"),
        "{e}"
    );
    let mut given = shard.to_vec();
    given.extend(["--calibration", cal]);
    let o = railgrip(&given, d);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));

    // A run estimated alone needs it too.
    let o = railgrip(
        &[
            "estimate",
            &archive("soap_120kmh_0c.csv"),
            "--pipeline",
            pipe,
            "--out",
            "one",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stdout));
    assert!(text(&o.stderr).contains("--calibration FILE"));
    let o = railgrip(
        &[
            "estimate",
            &archive("soap_120kmh_0c.csv"),
            "--pipeline",
            pipe,
            "--out",
            "one",
            "--calibration",
            cal,
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let mu = |p: &Path| common::parquet_columns(p, &["mu"]).remove(0);
    let plain = railgrip(
        &["estimate", &archive("soap_120kmh_0c.csv"), "--out", "plain"],
        d,
    );
    assert_eq!(plain.status.code(), Some(0));
    let calibrated = mu(&d.join("one/soap_120kmh_0c.estimates.parquet"));
    assert_ne!(
        calibrated,
        mu(&d.join("plain/soap_120kmh_0c.estimates.parquet"))
    );
    // Shard 1/2 holds the campaign's first run: alone or in its shard, the same μ.
    let o = railgrip(
        &[
            "estimate",
            &archive("dry_120kmh_p20.csv"),
            "--pipeline",
            pipe,
            "--out",
            "one",
            "--calibration",
            cal,
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let (alone, in_shard) = (
        mu(&d.join("one/dry_120kmh_p20.estimates.parquet")),
        mu(&d.join("o/runs/dry_120kmh_p20/estimates.parquet")),
    );
    assert_eq!(alone.len(), in_shard.len());
    let same = alone
        .iter()
        .zip(&in_shard)
        .all(|(a, b)| a == b || (a.is_nan() && b.is_nan()));
    assert!(same);
}

/// The default pipeline ("auto"): `calibrate --campaign --out` writes a "campaign" calibration;
/// a run estimated alone takes the pipeline's values (the same μ as "pipeline") and says why,
/// or the campaign's calibration when it is given.
#[test]
fn auto_estimates_a_run_alone_with_the_pipelines_values_unless_given_the_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let camp = root().join("fixtures/archive").display().to_string();
    let o = railgrip(&["calibrate", "--campaign", &camp, "--out", "x"], d);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let auto = json_file(d.join("x/calibration.json"));
    assert_eq!(auto["calibrated"]["source"], "campaign");
    let own = calibrated_pipeline(d, "pipeline").display().to_string();
    let run = archive("soap_120kmh_0c.csv");
    let estimate = |out: &str, extra: &[&str]| {
        let mut args = vec!["estimate", run.as_str(), "--out", out];
        args.extend(extra);
        let o = railgrip(&args, d);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
        let mu = common::parquet_columns(
            &d.join(out).join("soap_120kmh_0c.estimates.parquet"),
            &["mu"],
        )
        .remove(0);
        (text(&o.stderr), mu)
    };
    let (said, plain) = estimate("plain", &[]);
    assert!(
        said.contains("a run alone cannot calibrate itself"),
        "{said}"
    );
    let (said, mu_own) = estimate("own", &["--pipeline", &own]);
    assert!(!said.contains("cannot calibrate"), "{said}");
    let same = |a: &[f64], b: &[f64]| {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| x == y || (x.is_nan() && y.is_nan()))
    };
    assert!(same(&plain, &mu_own));
    let cal = d.join("x/calibration.json").display().to_string();
    let (said, given) = estimate("given", &["--calibration", &cal]);
    assert!(!said.contains("cannot calibrate"), "{said}");
    assert!(!same(&plain, &given));
}

/// A run's reuse key holds the calibration it was estimated with: the same shard given the same
/// calibration again is reused, given one that differs in one value (the radar's scale) it is
/// estimated again, with other μ.
#[test]
fn a_changed_calibration_estimates_the_runs_again() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (camp, pipe, cal) = bundled_calibration(d);
    let shard = |cal: &str| {
        let args = [
            "run",
            camp.as_str(),
            "--pipeline",
            pipe.as_str(),
            "--out",
            "o",
            "--stage",
            "estimate",
            "--shard",
            "1/4",
            "--calibration",
            cal,
        ];
        let o = railgrip(&args, d);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
        // Each run's line of the summary: its name, then "ok" or "reused".
        let out = text(&o.stdout);
        let reused: Vec<bool> = ["dry_120kmh_p20", "soap_120kmh_p20"]
            .iter()
            .map(|run| {
                let line = out
                    .lines()
                    .find(|l| l.starts_with(run))
                    .unwrap_or_else(|| panic!("no line for {run}: {out}"));
                line.split_whitespace().nth(1) == Some("reused")
            })
            .collect();
        let mu =
            common::parquet_columns(&d.join("o/runs/dry_120kmh_p20/estimates.parquet"), &["mu"])
                .remove(0);
        (reused, mu)
    };
    let (reused, mu) = shard(&cal);
    assert_eq!(reused, [false, false]);
    let (reused, mu_again) = shard(&cal);
    assert_eq!(reused, [true, true], "the same calibration again");
    assert_eq!(mu_again.len(), mu.len());
    let mut other = json_file(&cal);
    let scale = other["calibrated"]["corrections"]["radar_scale"]
        .as_f64()
        .unwrap();
    other["calibrated"]["corrections"]["radar_scale"] = serde_json::json!(scale * 1.002);
    let other_path = d.join("other.json");
    std::fs::write(&other_path, serde_json::to_vec_pretty(&other).unwrap()).unwrap();
    let (reused, mu_other) = shard(other_path.to_str().unwrap());
    assert_eq!(
        reused,
        [false, false],
        "another calibration reused the runs"
    );
    assert_eq!(mu_other.len(), mu.len());
    assert!(
        mu_other
            .iter()
            .zip(&mu)
            .any(|(a, b)| a.is_finite() && b.is_finite() && a != b),
        "the radar's scale moved no μ"
    );
}

/// A campaign calibration, as `railgrip calibrate --campaign` writes it for the bundled archive
/// and a pipeline that runs with it: (archive, pipeline file, calibration file).
fn bundled_calibration(d: &Path) -> (String, String, String) {
    let camp = root().join("fixtures/archive").display().to_string();
    let pipe = calibrated_pipeline(d, "campaign").display().to_string();
    let o = railgrip(
        &[
            "calibrate",
            "--campaign",
            &camp,
            "--pipeline",
            &pipe,
            "--out",
            "cal",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    (
        camp,
        pipe,
        d.join("cal/calibration.json").display().to_string(),
    )
}

#[test]
fn a_calibration_of_another_pipeline_or_campaign_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (camp, pipe, cal) = bundled_calibration(d);
    let (camp, pipe, cal) = (camp.as_str(), pipe.as_str(), cal.as_str());
    // Exit 1, the message saying `why`.
    let refused = |args: &[&str], why: &str| {
        let o = railgrip(args, d);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        assert!(text(&o.stderr).contains(why), "{}", text(&o.stderr));
    };
    fn models<'a>(archive: &'a str, pipeline: Option<&'a str>, cal: &'a str) -> Vec<&'a str> {
        let mut args = vec!["run", archive, "--out", "p", "--stage", "models"];
        args.extend(pipeline.map(|p| ["--pipeline", p]).into_iter().flatten());
        args.extend(["--calibration", cal]);
        args
    }
    // A pipeline that does not ask for a calibration.
    let own = calibrated_pipeline(d, "pipeline").display().to_string();
    refused(
        &models(camp, Some(&own), cal),
        "estimate.calibration is \"pipeline\"",
    );
    // The same settings in another file (one more comment line): another pipeline file.
    let edited = d.join("edited.toml");
    std::fs::write(
        &edited,
        std::fs::read_to_string(pipe).unwrap() + "# edited\n",
    )
    .unwrap();
    let edited = edited.to_str().unwrap();
    refused(
        &models(camp, Some(edited), cal),
        "fitted with another pipeline file",
    );
    // One run estimated alone: the same checks of the pipeline.
    let run = archive("soap_120kmh_0c.csv");
    let alone = ["estimate", run.as_str(), "--out", "e", "--calibration", cal];
    refused(
        &[&alone[..], &["--pipeline", &own]].concat(),
        "estimate.calibration is \"pipeline\"",
    );
    // The default pipeline ("auto") takes a "campaign" calibration, but of its own file.
    refused(&alone, "another pipeline file");
    refused(
        &[&alone[..], &["--pipeline", edited]].concat(),
        "another pipeline file",
    );
    // A file that is not a calibration: named, with what to give instead.
    std::fs::write(d.join("bad.json"), "{\"alpha\": 1}").unwrap();
    refused(
        &[
            "estimate",
            run.as_str(),
            "--out",
            "e",
            "--calibration",
            "bad.json",
        ],
        "bad.json: not a calibration file",
    );
    refused(
        &[
            "run",
            camp,
            "--out",
            "p",
            "--stage",
            "models",
            "--calibration",
            "missing.json",
        ],
        "missing.json: cannot read the file",
    );
    // Another campaign's runs.
    let other = d.join("other");
    std::fs::create_dir_all(&other).unwrap();
    for f in ["soap_120kmh_0c.csv", "soap_120kmh_0c.meta.toml"] {
        std::fs::copy(root().join("fixtures/archive").join(f), other.join(f)).unwrap();
    }
    refused(
        &models(other.to_str().unwrap(), Some(pipe), cal),
        "does not belong to this campaign: it was fitted on other runs (not fitted: none; not in the campaign: dry_120kmh_p20",
    );
}

/// A scheduled campaign's later parts follow what its calibrate part decided: where "auto" can
/// fit no calibration (three runs listed, one of them broken) the calibrate part records that,
/// and the shards and the models part estimate with the pipeline's values — the bytes of one
/// `run`. The models part refuses a calibration fitted before a log changed, and the calibrate
/// part is not given one.
#[test]
fn the_parts_follow_the_calibrate_parts_record() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let camp = d.join("campaign");
    two_run_campaign(&camp);
    std::fs::write(camp.join("broken.csv"), "t,v_radar\n0,abc\n").unwrap();
    let one = railgrip(&["run", "campaign", "--out", "one"], d);
    assert_eq!(one.status.code(), Some(3), "{}", text(&one.stderr));
    let part = |args: &[&str]| {
        let mut all = vec!["run", "campaign", "--out", "sh"];
        all.extend(args);
        let o = railgrip(&all, d);
        assert!(
            matches!(o.status.code(), Some(0 | 3)),
            "{args:?}: {}{}",
            text(&o.stdout),
            text(&o.stderr)
        );
        text(&o.stdout)
    };
    let said = part(&["--stage", "calibrate"]);
    assert!(said.contains("calibration: none (only 2 runs"), "{said}");
    let record = json_file(d.join("sh/calibration.json"));
    assert_eq!(record["calibrated"]["source"], "none");
    for k in ["1/2", "2/2"] {
        part(&["--stage", "estimate", "--shard", k]);
    }
    part(&["--stage", "models"]);
    let (a, b) = (outputs(&d.join("one")), outputs(&d.join("sh")));
    assert!(a.contains_key(Path::new("calibration.json")));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        assert!(b.get(k) == Some(v), "{} differs", k.display());
    }

    // Three good runs: calibrated; a sidecar edited after the calibrate part.
    let camp3 = d.join("three");
    three_run_campaign(&camp3);
    let run3 = |args: &[&str]| {
        let mut all = vec!["run", "three", "--out", "t"];
        all.extend(args);
        railgrip(&all, d)
    };
    let given = run3(&[
        "--stage",
        "calibrate",
        "--calibration",
        "sh/calibration.json",
    ]);
    assert_eq!(given.status.code(), Some(1));
    assert!(text(&given.stderr).contains("--stage calibrate fits it"));
    assert_eq!(run3(&["--stage", "calibrate"]).status.code(), Some(0));
    assert_eq!(run3(&["--stage", "estimate"]).status.code(), Some(0));
    let sidecar = std::fs::read_dir(&camp3)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().ends_with(".meta.toml"))
        .unwrap();
    let text_s = std::fs::read_to_string(&sidecar).unwrap();
    std::fs::write(&sidecar, text_s + "# edited\n").unwrap();
    let m = run3(&["--stage", "models"]);
    assert_eq!(m.status.code(), Some(1), "{}", text(&m.stdout));
    assert!(
        text(&m.stderr).contains("fitted on other inputs"),
        "{}",
        text(&m.stderr)
    );
}

/// A part that takes a damaged `OUT/calibration.json` stops, naming the file and the command
/// that writes it again.
#[test]
fn a_damaged_output_folder_calibration_is_named_with_the_command_to_write_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    three_run_campaign(&d.join("three"));
    std::fs::create_dir_all(d.join("t")).unwrap();
    std::fs::write(d.join("t/calibration.json"), "{\"calibrated\": 1").unwrap();
    for stage in [&["--stage", "estimate"][..], &["--stage", "models"][..]] {
        let mut args = vec!["run", "three", "--out", "t"];
        args.extend(stage);
        let o = railgrip(&args, d);
        assert_eq!(o.status.code(), Some(1), "{stage:?}: {}", text(&o.stdout));
        let e = text(&o.stderr);
        assert!(
            e.contains("calibration.json")
                && e.contains("cannot be used")
                && e.contains("--stage calibrate"),
            "{stage:?}: {e}"
        );
    }
}

/// The default `estimate.calibration = "auto"`: a campaign of three runs is calibrated (its
/// calibration in the output folder, the campaign record and the report), one of two runs is
/// estimated with the pipeline's values, the notes and its calibration.json say why;
/// `"campaign"` refuses two.
#[test]
fn auto_calibrates_a_campaign_of_3_runs_and_says_why_not_for_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    three_run_campaign(&d.join("three"));
    two_run_campaign(&d.join("two"));
    let o = railgrip(&["run", "three", "--out", "o3", "--json"], d);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let campaign = json_file(d.join("o3/campaign.json"));
    assert_eq!(campaign["calibration"]["source"], "campaign");
    assert_eq!(campaign["calibration"]["runs"].as_array().unwrap().len(), 3);
    assert!(d.join("o3/calibration.json").is_file());
    // What was fitted, its uncertainty and its effect on μ: in the campaign record and the
    // model files' provenance.
    let errors = &campaign["calibration"]["errors"];
    assert_eq!(errors["alpha_se"].as_array().unwrap().len(), 4, "{errors}");
    assert!(errors["alpha_se"][0].as_f64().unwrap() > 0.0, "{errors}");
    let model = json_file(d.join("o3/models/mlp.json"));
    let prov = model["provenance"]["calibration"].as_str().unwrap();
    assert!(
        prov.starts_with("campaign calibration over 3 runs: α = [")
            && prov.contains(" ± ")
            && prov.contains("N·m/bar (1σ)")
            && prov.contains("and with it its μ, moved")
            && prov.ends_with("from [vehicle]'s α"),
        "{prov}"
    );

    let o = railgrip(&["run", "two", "--out", "o2", "--json"], d);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let json: serde_json::Value = serde_json::from_str(&text(&o.stdout)).unwrap();
    let notes: Vec<&str> = json["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    assert!(
        notes
            .iter()
            .any(|n| n.starts_with("calibration: none (only 2 runs")
                && n.contains("estimated with [vehicle]'s α")),
        "{notes:?}"
    );
    // Its calibration.json records that none was fitted, and why.
    let none = json_file(d.join("o2/calibration.json"));
    assert_eq!(none["calibrated"]["source"], "none");
    assert!(
        none["notes"][0].as_str().unwrap().contains("only 2 runs"),
        "{none}"
    );
    let campaign = json_file(d.join("o2/campaign.json"));
    assert!(campaign["calibration"].is_null(), "{campaign}");
    // The same two runs with the pipeline's own values: the same estimates.
    let own = calibrated_pipeline(d, "pipeline");
    let o = railgrip(
        &[
            "run",
            "two",
            "--out",
            "own",
            "--pipeline",
            own.to_str().unwrap(),
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert_same_mu(&d.join("o2"), &d.join("own"), 2);
    // "campaign" refuses the two.
    let camp = calibrated_pipeline(d, "campaign");
    let o = railgrip(
        &[
            "run",
            "two",
            "--out",
            "oc",
            "--pipeline",
            camp.to_str().unwrap(),
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stdout));
    assert!(
        text(&o.stderr).contains("a campaign's calibration needs at least 3"),
        "{}",
        text(&o.stderr)
    );
}

/// The μ columns of every `estimates.parquet` below `a` and `b` are the same (NaN where NaN),
/// `runs` of them.
fn assert_same_mu(a: &Path, b: &Path, runs: usize) {
    // Paired by the table's path below its folder (the runs' names).
    let mu = |dir: &Path| {
        let mut v: Vec<(PathBuf, Vec<f64>)> = files_below(dir)
            .into_iter()
            .filter(|p| p.file_name().unwrap() == "estimates.parquet")
            .map(|p| {
                let mu = common::parquet_columns(&p, &["mu"]).remove(0);
                (p.strip_prefix(dir).unwrap().to_path_buf(), mu)
            })
            .collect();
        v.sort_by(|a, b| a.0.cmp(&b.0));
        v
    };
    let (x, y) = (mu(a), mu(b));
    assert_eq!((x.len(), y.len()), (runs, runs));
    for ((pa, a), (pb, b)) in x.iter().zip(&y) {
        assert_eq!(pa, pb);
        assert!(
            a.len() == b.len()
                && a.iter()
                    .zip(b)
                    .all(|(x, y)| x == y || (x.is_nan() && y.is_nan())),
            "{}: μ differs",
            pa.display()
        );
    }
}

/// Three runs cut to their first 3.1 s (1.8 s of braking) are enough runs but too little
/// braking for the balance: its fit cannot place the α (−398.2 ± 501.9 N·m/bar from the
/// balance integrated over time; 26.7 ± 507.7 from the force balance). "auto" then keeps the
/// pipeline's
/// values with the fit's error in a note and a "none" record, for the whole job and for the
/// calibrate part; "campaign" stops with the error, naming the campaign.
#[test]
fn auto_keeps_the_pipelines_values_where_the_campaigns_fit_fails() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let camp = d.join("short");
    std::fs::create_dir(&camp).unwrap();
    for run in ["soap_120kmh_0c", "soap_120kmh_m20", "soap_120kmh_p20"] {
        let log = std::fs::read_to_string(archive(&format!("{run}.csv"))).unwrap();
        let head: Vec<&str> = log.lines().take(1300).collect();
        std::fs::write(camp.join(format!("{run}.csv")), head.join("\n") + "\n").unwrap();
        std::fs::copy(
            archive(&format!("{run}.meta.toml")),
            camp.join(format!("{run}.meta.toml")),
        )
        .unwrap();
    }
    let o = railgrip(&["run", "short", "--out", "auto", "--json"], d);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let json: serde_json::Value = serde_json::from_str(&text(&o.stdout)).unwrap();
    let note = json["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .find(|n| n.starts_with("calibration: none"))
        .unwrap_or_else(|| panic!("{json}"));
    assert!(
        note.contains("could not be fitted")
            && note.contains("cannot place the brake coefficients")
            && note.contains("estimated with [vehicle]'s α"),
        "{note}"
    );
    let none = json_file(d.join("auto/calibration.json"));
    assert_eq!(none["calibrated"]["source"], "none");
    assert!(json_file(d.join("auto/campaign.json"))["calibration"].is_null());
    // The estimates are the pipeline's.
    let own = calibrated_pipeline(d, "pipeline");
    let o = railgrip(
        &[
            "run",
            "short",
            "--out",
            "own",
            "--pipeline",
            own.to_str().unwrap(),
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert_same_mu(&d.join("auto"), &d.join("own"), 3);
    // The calibrate part writes the same record.
    let o = railgrip(
        &["run", "short", "--out", "part", "--stage", "calibrate"],
        d,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert_eq!(
        json_file(d.join("part/calibration.json"))["calibrated"]["source"],
        "none"
    );
    // "campaign" stops with the fit's error.
    let camp = calibrated_pipeline(d, "campaign");
    let o = railgrip(
        &[
            "run",
            "short",
            "--out",
            "oc",
            "--pipeline",
            camp.to_str().unwrap(),
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stdout));
    let err = text(&o.stderr);
    assert!(
        err.contains("short") && err.contains("cannot place the brake coefficients"),
        "{err}"
    );
}

#[test]
fn a_dry_run_calibration_pools_the_full_adhesion_runs_into_the_campaign() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let camp = root().join("fixtures/archive");
    let pipe = calibrated_pipeline(d, "dry-run");
    let o = railgrip(
        &[
            "run",
            camp.to_str().unwrap(),
            "--pipeline",
            pipe.to_str().unwrap(),
            "--out",
            "o",
        ],
        d,
    );
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    let record = json_file(d.join("o/calibration.json"));
    let runs: Vec<&str> = record["dry_run"]["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r[0].as_str().unwrap())
        .collect();
    assert!(runs.contains(&"dry_120kmh_p20"), "{runs:?}");
    let alpha = record["dry_run"]["alpha_nm_per_bar"].as_f64().unwrap();
    assert!((alpha / 1600.0 - 1.0).abs() < 0.02, "{alpha}");
    let campaign = json_file(d.join("o/campaign.json"));
    assert_eq!(campaign["calibration"]["source"], "dry-run");
    let model = json_file(d.join("o/models/mlp.json"));
    let prov = model["provenance"]["calibration"].as_str().unwrap();
    assert!(
        prov.starts_with("dry-run calibration over 8 runs") && prov.contains(" ± "),
        "{prov}"
    );
    let report = std::fs::read_to_string(d.join("o/report/index.html")).unwrap();
    assert!(
        report.contains("<h2>Calibration</h2>")
            && report.contains("<b>dry-run</b> calibration fitted on 8 runs"),
        "no calibration section"
    );
    // A rerun reuses every run (the calibration is the same, so are the runs' keys); the
    // same archive with the pipeline's own α ("pipeline") leaves no calibration file behind.
    let o = railgrip(
        &[
            "run",
            camp.to_str().unwrap(),
            "--pipeline",
            pipe.to_str().unwrap(),
            "--out",
            "o",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(
        text(&o.stderr).matches("unchanged, reused").count(),
        8,
        "{}",
        text(&o.stderr)
    );
    let own = calibrated_pipeline(d, "pipeline");
    let o = railgrip(
        &[
            "run",
            camp.to_str().unwrap(),
            "--out",
            "o",
            "--pipeline",
            own.to_str().unwrap(),
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(0));
    assert!(!d.join("o/calibration.json").exists());
}

/// A whole campaign run again with the same inputs reuses its calibration (`calibration.json`
/// of the output folder, fitted on the same pipeline file, logs and sidecars by hash) instead
/// of fitting it again, as it reuses unchanged runs' estimates: the same files, and
/// `timings.json` says so. A changed input or `--force` fits it again.
#[test]
fn a_rerun_reuses_the_campaigns_calibration_until_an_input_changes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let camp = d.join("camp");
    std::fs::create_dir(&camp).unwrap();
    for run in ["soap_120kmh_0c", "soap_120kmh_p20", "soap_160kmh_p20"] {
        for ext in ["csv", "meta.toml"] {
            let from = root().join(format!("fixtures/archive/{run}.{ext}"));
            std::fs::copy(&from, camp.join(format!("{run}.{ext}"))).unwrap();
        }
    }
    let pipe = calibrated_pipeline(d, "campaign").display().to_string();
    let run = |extra: &[&str]| {
        let mut args = vec!["run", "camp", "--out", "out", "--pipeline", &pipe];
        args.extend(extra);
        let o = railgrip(&args, d);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
        let timings = std::fs::read_to_string(d.join("out/timings.json")).unwrap();
        let cal = std::fs::read(d.join("out/calibration.json")).unwrap();
        let campaign = std::fs::read(d.join("out/campaign.json")).unwrap();
        (
            timings.contains("\"calibration_reused\": true"),
            cal,
            campaign,
        )
    };
    let (reused, cal, campaign) = run(&[]);
    assert!(!reused);
    let (reused, cal2, campaign2) = run(&[]);
    assert!(reused, "the second run fitted the calibration again");
    assert_eq!((cal2, campaign2), (cal.clone(), campaign.clone()));
    let (reused, cal3, _) = run(&["--force"]);
    assert!(!reused);
    assert_eq!(cal3, cal);
    // A changed sidecar (a comment added: other bytes) is another input.
    let side = camp.join("soap_120kmh_0c.meta.toml");
    let text_before = std::fs::read_to_string(&side).unwrap();
    std::fs::write(&side, format!("{text_before}\n# edited\n")).unwrap();
    let (reused, _, _) = run(&[]);
    assert!(!reused, "a changed sidecar reused the calibration");
    assert!(run(&[]).0, "the same inputs again");
    // A damaged calibration.json is not reused: fitted again, and written whole.
    std::fs::write(d.join("out/calibration.json"), "{ not json").unwrap();
    let (reused, cal4, _) = run(&[]);
    assert!(!reused);
    assert!(serde_json::from_slice::<serde_json::Value>(&cal4).is_ok());
    // So is a changed pipeline file, and one run fewer.
    let text_before = std::fs::read_to_string(&pipe).unwrap();
    std::fs::write(&pipe, format!("{text_before}\n# edited\n")).unwrap();
    assert!(
        !run(&[]).0,
        "a changed pipeline file reused the calibration"
    );
    std::fs::remove_file(camp.join("soap_160kmh_p20.csv")).unwrap();
    std::fs::remove_file(camp.join("soap_160kmh_p20.meta.toml")).unwrap();
    let o = railgrip(&["run", "camp", "--out", "out", "--pipeline", &pipe], d);
    // Two runs are too few to calibrate: refused, saying so (not the old calibration reused).
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stdout));
    assert!(
        text(&o.stderr).contains("at least 3"),
        "{}",
        text(&o.stderr)
    );
}
