//! `railgrip export --fmu`: FMI 2.0 FMUs of every model kind, checked with FMPy (PyPI `fmpy`;
//! .ci/run installs it): FMPy's validation finds no problem, and co-simulating the FMU (and
//! running it as Model Exchange) on a braking run's inputs gives the μ of `railgrip eval` on
//! the same inputs — networks bit for bit, Polach and residual models within 1e-12 — with
//! co-simulation's one-step output lag accounted for; bad inputs are error statuses. And the
//! command's own errors: a model file that fails its checks, an unwritable path, no compiler.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::*;

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

fn ok(o: &Output) -> String {
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    text(&o.stdout)
}

/// The model files of every kind, trained on the bundled archive's soap runs: the 2-input
/// network (one hidden layer), the 4-input network, the residual network, the Polach model
/// with its temperature and speed laws, and a network with two hidden layers.
fn models(dir: &Path) -> Vec<(&'static str, PathBuf)> {
    // Every soap run of the bundled archive: enough temperatures for the campaign's Polach
    // model to carry a temperature law, and speeds for its speed law.
    let camp = dir.join("camp");
    std::fs::create_dir_all(&camp).unwrap();
    let archive = fixture("soap_120kmh_0c.csv")
        .parent()
        .unwrap()
        .to_path_buf();
    for e in std::fs::read_dir(&archive).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with("soap_") && !name.ends_with(".truth.parquet") {
            std::fs::copy(e.path(), camp.join(&name)).unwrap();
        }
    }
    ok(&railgrip(&["run", "camp", "--out", "out"], dir));
    let polach = dir.join("out/models/mlp.polach.json");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&polach).unwrap()).unwrap();
    assert!(
        v["polach"]["temperature"].is_object() && v["polach"]["speed"].is_object(),
        "the campaign's Polach model has a temperature law and a speed law: {}",
        v["polach"]
    );
    let pipeline = deep_pipeline_text();
    std::fs::write(dir.join("deep.toml"), pipeline).unwrap();
    ok(&railgrip(
        &[
            "train",
            "camp/soap_120kmh_p20.csv",
            "--pipeline",
            "deep.toml",
            "--out",
            "deep",
            "--quiet",
        ],
        dir,
    ));
    vec![
        ("2-input network", dir.join("out/models/mlp.json")),
        ("deep network", dir.join("deep/mlp.json")),
        ("4-input network", dir.join("out/models/mlp.4in.json")),
        ("residual network", dir.join("out/models/mlp.residual.json")),
        ("Polach, temperature and speed laws", polach),
    ]
}

/// A braking run's inputs (axle 2, every 8th valid sample of `soap_160kmh_m20`: Δv, dΔv/dt,
/// v, and an ambient temperature sweeping −25 … +25 °C), as a CSV with a header.
fn braking_inputs(dir: &Path) -> PathBuf {
    ok(&railgrip(
        &[
            "estimate",
            "camp/soap_160kmh_m20.mcap",
            "--out",
            "est",
            "--csv",
        ],
        dir,
    ));
    let csv = std::fs::read_to_string(dir.join("est/soap_160kmh_m20.estimates.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (axle, dv, ddv, v, valid) = (
        col("axle"),
        col("dv_mps"),
        col("ddv_mps2"),
        col("v_mps"),
        col("valid"),
    );
    let mut out = String::from("dv_mps,ddv_mps2,v_mps,ambient_temperature_c\n");
    let mut n = 0;
    let rows = lines
        .map(|l| l.split(',').collect::<Vec<&str>>())
        .filter(|f| f[axle] == "2" && f[valid] == "true");
    for (k, f) in rows.step_by(8).enumerate() {
        // The ambient temperature sweeps −25 … +25 °C over the run (beyond the laws' fitted
        // ranges at both ends), so that the temperature input is exercised too.
        let t_c = -25.0 + (k % 501) as f64 * 0.1;
        out.push_str(&format!("{},{},{},{t_c:?}\n", f[dv], f[ddv], f[v]));
        n += 1;
    }
    assert!(n > 1000, "{n} rows");
    let path = dir.join("inputs.csv");
    std::fs::write(&path, out).unwrap();
    path
}

/// The `mu` column of a CSV.
fn mu_column(path: &Path) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = header.iter().position(|h| *h == "mu").unwrap();
    lines
        .map(|l| l.split(',').nth(k).unwrap().parse::<f64>().unwrap())
        .collect()
}

#[test]
fn fmus_of_every_model_kind_pass_fmpy_and_give_the_mu_of_eval() {
    if !python_has("fmpy", "fmpy") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let models = models(d);
    let inputs = braking_inputs(d);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fmpy_check.py");
    // Each model's FMU as railgrip builds it, and the 4-input network's as a source FMU that
    // FMPy builds (CMake, Release flags: what an importing tool does).
    let mut cases: Vec<(String, PathBuf, bool)> = models
        .iter()
        .map(|(w, m)| (w.to_string(), m.clone(), false))
        .collect();
    if Command::new("cmake").arg("--version").output().is_ok() {
        cases.push((
            "4-input network, built from sources".into(),
            models[2].1.clone(),
            true,
        ));
    } else {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "cmake is needed under CI=true"
        );
        eprintln!("SKIPPED: the source FMU's build (no cmake)");
    }
    for (k, (what, model, from_sources)) in cases.iter().enumerate() {
        let what = what.as_str();
        let fmu = d.join(format!("m{k}.fmu"));
        let mut args = vec![
            "export",
            model.to_str().unwrap(),
            "--fmu",
            fmu.to_str().unwrap(),
        ];
        if *from_sources {
            args.push("--fmu-sources-only");
        }
        let s = ok(&railgrip(&args, d));
        assert!(
            *from_sources || s.contains("binaries/linux64") || !cfg!(target_os = "linux"),
            "{s}"
        );
        let want_out = d.join(format!("eval{k}.csv"));
        ok(&railgrip(
            &[
                "eval",
                model.to_str().unwrap(),
                "--input",
                inputs.to_str().unwrap(),
                "--output",
                want_out.to_str().unwrap(),
            ],
            d,
        ));
        let want = mu_column(&want_out);
        let prefix = d.join(format!("fmpy{k}"));
        let o = Command::new("python3")
            .arg(&script)
            .args([&fmu, &inputs, &prefix])
            .args(from_sources.then_some("--build"))
            .output()
            .unwrap();
        let report = text(&o.stdout);
        assert!(o.status.success(), "{what}: {report}{}", text(&o.stderr));
        assert!(!report.contains("problem:"), "{what}: FMPy: {report}");
        let cs = mu_column(&prefix.with_extension("cs.csv"));
        let me = mu_column(&prefix.with_extension("me.csv"));
        assert_eq!(cs.len(), want.len(), "{what}");
        assert_eq!(me.len(), want.len(), "{what}");
        // Co-simulation: the output at communication point k comes from the inputs set at
        // k − 1 (set, fmi2DoStep, read); at the start, from the first row. Model Exchange: no lag.
        let lagged: Vec<f64> = std::iter::once(want[0])
            .chain(want[..want.len() - 1].iter().copied())
            .collect();
        // The signals move from step to step: a missing or extra lag would show.
        assert!(
            lagged.iter().zip(&want).filter(|(a, b)| a != b).count() > want.len() / 2,
            "{what}: the inputs hardly change"
        );
        let tol = if what.contains("network") && !what.contains("residual") {
            0.0
        } else {
            1e-12
        };
        for (name, got, want) in [("CS", &cs, &lagged), ("ME", &me, &want)] {
            let worst = got
                .iter()
                .zip(want.iter())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            eprintln!("{what}: {name} vs railgrip eval, max |Δμ| = {worst:.1e}");
            assert!(
                worst <= tol && got.iter().all(|m| m.is_finite()),
                "{what} {name}: {worst}"
            );
        }
        check_statuses(what, &report, model, tol);
    }
}

/// What tests/fmpy_check.py found about bad inputs, NaN speed and temperature and FMU states,
/// checked: error statuses, the Rust evaluator's μ (within `tol`), states that restore μ.
fn check_statuses(what: &str, report: &str, model: &Path, tol: f64) {
    // A NaN or infinite slip or slip rate: an error status, not a crash; NaN speed or
    // temperature: the file's reference (or base) values, as the Rust evaluator has them.
    assert!(report.contains("nan_dv: doStep error"), "{what}: {report}");
    assert!(report.contains("nan_dv: getReal error"), "{what}: {report}");
    if what.contains("network") {
        assert!(report.contains("inf_ddv: doStep error"), "{what}: {report}");
    }
    // FMU states: restoring one (directly, or from its bytes) restores mu.
    let line = report.lines().find(|l| l.starts_with("state: ")).unwrap();
    let st: Vec<f64> = line[7..]
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    assert!(
        st[0] != st[1] && st[2] == st[0] && st[3] == st[0],
        "{what}: {line}"
    );
    let rust = railgrip::model::Model::load(model).unwrap();
    for (label, v, t) in [("nan_v", f64::NAN, 20.0), ("nan_t", 30.0, f64::NAN)] {
        let line = report
            .lines()
            .find(|l| l.starts_with(&format!("{label}: ")))
            .unwrap();
        let got: f64 = line[label.len() + 2..].trim().parse().unwrap();
        let want = rust.mu_vt(0.5, 0.3, v, t);
        assert!(
            (got - want).abs() <= tol && got.is_finite(),
            "{what} {label}: FMU {got} against the Rust evaluator {want}"
        );
    }
}

#[test]
fn an_fmu_says_what_it_holds_and_is_the_same_for_the_same_model() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/golden/synthetic_mlp_4inputs.json");
    let m = model.to_str().unwrap();
    ok(&railgrip(
        &["export", m, "--fmu", "a.fmu", "--fmu-sources-only"],
        d,
    ));
    ok(&railgrip(
        &["export", m, "--fmu", "b.fmu", "--fmu-sources-only"],
        d,
    ));
    // The same model: the same bytes (but the identifier, which is the file's name).
    let read = |p: &str| {
        let mut z = zip::ZipArchive::new(std::fs::File::open(d.join(p)).unwrap()).unwrap();
        let names: Vec<String> = z.file_names().map(|n| n.unwrap().into_owned()).collect();
        let mut xml = String::new();
        std::io::Read::read_to_string(&mut z.by_name("modelDescription.xml").unwrap(), &mut xml)
            .unwrap();
        (names, xml)
    };
    let (names, xml) = read("a.fmu");
    let (_, xml_b) = read("b.fmu");
    assert_eq!(
        names,
        [
            "modelDescription.xml",
            "sources/fmu.c",
            "sources/model.h",
            "resources/model.json"
        ]
    );
    assert_eq!(xml.replace("\"a\"", "\"b\""), xml_b);
    for needle in [
        "fmiVersion=\"2.0\"",
        "name=\"dv_mps\"",
        "name=\"ddv_mps2\"",
        "name=\"v_mps\"",
        "name=\"ambient_temperature_c\"",
        "unit=\"degC\"",
        "name=\"mu\"",
        "causality=\"output\"",
        "training domain",
        "generation",
        "<CoSimulation modelIdentifier=\"a\"",
        "<ModelExchange modelIdentifier=\"a\"",
    ] {
        assert!(xml.contains(needle), "{needle} missing:\n{xml}");
    }
    // No min/max an importer would enforce.
    assert!(!xml.contains(" min=") && !xml.contains(" max="), "{xml}");
}

#[test]
fn export_errors_name_the_file_and_say_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/golden/synthetic_mlp.json");
    let g = good.to_str().unwrap();
    // A model file that reads but fails its checks (a layer's biases one short of its weights).
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&good).unwrap()).unwrap();
    v["layers"][0]["biases"].as_array_mut().unwrap().pop();
    std::fs::write(d.join("bad.json"), v.to_string()).unwrap();
    let o = railgrip(&["export", "bad.json", "--fmu", "bad.fmu"], d);
    let e = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("bad.json: ") && e.contains("Hint: "), "{e}");
    assert!(
        !e.contains("not a model file"),
        "a check, not the parser: {e}"
    );
    assert!(!d.join("bad.fmu").exists());
    // An unwritable path.
    let o = railgrip(
        &[
            "export",
            g,
            "--fmu",
            "no/such/folder/m.fmu",
            "--fmu-sources-only",
        ],
        d,
    );
    let e = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("no/such/folder/m.fmu: cannot write"), "{e}");
    // No compiler: a clear error, and a source FMU still works.
    let o = Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(["export", g, "--fmu", "m.fmu"])
        .current_dir(d)
        .env("CC", "/nonexistent/cc")
        .output()
        .unwrap();
    let e = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("m.fmu: /nonexistent/cc: no C compiler found")
            && e.contains("--fmu-sources-only"),
        "{e}"
    );
    assert!(!d.join("m.fmu").exists());
    // Not an .fmu name; neither output asked for.
    let o = railgrip(&["export", g, "--fmu", "m.zip"], d);
    assert!(
        text(&o.stderr).contains("ends in .fmu"),
        "{}",
        text(&o.stderr)
    );
    let o = railgrip(&["export", g], d);
    assert_eq!(o.status.code(), Some(2));
}
