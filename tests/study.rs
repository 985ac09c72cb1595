//! `railgrip study`: plans, refusals, cells measured against truth from a law
//! family none of the cells contains, resumption and determinism.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use railgrip::study::{Plan, StudyError, DEFAULT_PLAN_TOML};

fn railgrip(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn parse(plan: &str) -> Result<Plan, StudyError> {
    Plan::parse(plan, "plan.toml", None, None)
}

fn plan_error(plan: &str) -> String {
    parse(plan)
        .expect_err("the plan should be refused")
        .to_string()
}

#[test]
fn the_default_plan_covers_the_whole_grid() {
    let p = Plan::load(None, None).unwrap();
    assert_eq!(p.text, DEFAULT_PLAN_TOML);
    let has = |f: &dyn Fn(&railgrip::study::CellSpec) -> bool| p.cells.iter().any(f);
    assert!(has(&|c| c.family.name() == "polach_pooled"));
    assert!(has(&|c| c.family.name() == "polach_kt"));
    for inputs in [2, 3, 4] {
        for width in [3, 5, 10, 20, 40] {
            assert!(
                has(&|c| c.family.name() == "mlp"
                    && c.pipeline.train.inputs.count() == inputs
                    && c.pipeline.train.layers == vec![width]
                    && c.pipeline.train.trainer == railgrip::config::Trainer::Lm),
                "{inputs}-input LM net with {width} neurons"
            );
        }
    }
    for opt in [
        railgrip::config::Optimizer::Adam,
        railgrip::config::Optimizer::AdamW,
    ] {
        assert!(has(&|c| c.pipeline.train.trainer
            == railgrip::config::Trainer::Burn(opt)
            && c.pipeline.train.layers.len() == 2));
    }
    assert!(has(&|c| c.pipeline.train.ensemble > 1));
    assert!(has(&|c| c.pipeline.train.starts > 1));
    assert!(has(&|c| c.pipeline.train.bayesian));
    assert!(has(&|c| c.pipeline.train.decimate != 4));
    assert!(has(&|c| c.pipeline.train.epochs < 1000));
    for hz in [3.0, 8.0] {
        for mode in [
            railgrip::config::FilterMode::Causal,
            railgrip::config::FilterMode::ZeroPhase,
        ] {
            assert!(has(&|c| c.conditioning.filters.tacho_cutoff_hz == hz
                && c.conditioning.filters.mode == mode));
        }
    }
    // Training keys do not reach the conditioning: cells differing in [train] share estimates.
    let conditionings: std::collections::BTreeSet<&str> = p
        .cells
        .iter()
        .map(|c| c.conditioning.text.as_str())
        .collect();
    assert_eq!(
        conditionings.len(),
        10,
        "4 tachometer cut-offs × 2 modes, 2 pressure cut-offs"
    );
    for hz in [3.0, 8.0] {
        assert!(has(&|c| c.conditioning.filters.pressure_cutoff_hz == hz));
    }
    // The other bundled plan parses too.
    let lm_adam = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/study_lm_vs_adam.toml");
    let q = Plan::load(Some(&lm_adam), None).unwrap();
    assert_eq!(q.cells.len(), 23);
    // Duplicates are dropped: every cell's pipeline differs.
    let mut seen = std::collections::HashSet::new();
    assert!(p
        .cells
        .iter()
        .all(|c| seen.insert((c.family.name(), c.pipeline.text.clone()))));
}

#[test]
fn bad_plans_are_refused_with_the_key_and_the_allowed_values() {
    let e = plan_error("[study]\nmax_cell = 3\n[[grid]]\ntrain.model = \"mlp\"\n");
    assert!(
        e.contains("study.max_cell") && e.contains("max_cells, max_minutes"),
        "{e}"
    );
    let e = plan_error("[[grid]]\ntrain.layerz = [[3]]\n");
    assert!(
        e.contains("grid[0]: unknown key train.layerz") && e.contains("train.layers"),
        "{e}"
    );
    let e = plan_error("[[grid]]\nvehicle.mass_kg = [1.0]\n");
    assert!(
        e.contains("unknown key vehicle") && e.contains("filters, estimate, contact, train"),
        "{e}"
    );
    let e = plan_error("[[grid]]\ntrain.model = [\"gbm\"]\n");
    assert!(
        e.contains("grid[0].train.model: unknown model") && e.contains("polach_kt"),
        "{e}"
    );
    // A cell fits the one model it names; the campaign's choice among models is no cell.
    let e = plan_error("[[grid]]\ntrain.model = [\"mlp\", \"auto\"]\n");
    assert!(
        e.contains("grid[0].train.model = \"auto\"") && e.contains("\"residual\""),
        "{e}"
    );
    let e = plan_error("[[grid]]\ntrain.folds = [4, 8]\n");
    assert!(e.contains("grid[0]: train.folds"), "{e}");
    // The key of earlier releases names the new one.
    let e = plan_error("[[grid]]\nfamily = \"polach\"\n");
    assert!(
        e.contains("family is now train.model") && e.contains("polach_pooled"),
        "{e}"
    );
    let e = plan_error("[study]\nmax_cells = 5\n");
    assert!(e.contains("no [[grid]]"), "{e}");
    let e = plan_error("[[grid]]\ntrain.decimate = []\n");
    assert!(e.contains("empty list makes no cells"), "{e}");
    let e = plan_error("[[grid]]\ntrain.layers = [10, 20]\n");
    assert!(
        e.contains("list of lists") && e.contains("[[10], [20]]"),
        "{e}"
    );
    let e = plan_error("[[grid]]\ntrain.optimizer = [\"sgd\"]\n");
    assert!(e.contains("train.optimizer") && e.contains("sgd"), "{e}");
    let e = plan_error("[[grid]]\ntrain.layers = [[3, 3, 3]]\n");
    assert!(e.contains("adam"), "LM takes two layers at most: {e}");
    let e = plan_error("[grid]\ntrain.model = \"mlp\"\n");
    assert!(e.contains("[[grid]]"), "{e}");
    let e = plan_error("[study]\nheld_out = \"run1\"\n[[grid]]\n");
    assert!(e.contains("study.held_out") && e.contains("list"), "{e}");
    let e = plan_error("[study]\nmax_minutes = -1\n[[grid]]\n");
    assert!(e.contains("study.max_minutes"), "{e}");
    let e = plan_error("[[grid]]\ntrain.model = \"mlp\"\n[extra]\n");
    assert!(e.contains("unknown top-level key `extra`"), "{e}");
    let e = plan_error("[[grid]\n");
    assert!(e.contains("plan.toml") && e.contains("TOML"), "{e}");
    let e = Plan::load(Some(Path::new("/nonexistent/plan.toml")), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("/nonexistent/plan.toml") && e.contains("--plan"),
        "{e}"
    );
    let e = Plan::parse(
        "[study]\npipeline = \"missing.toml\"\n[[grid]]\n",
        "plan.toml",
        Some(Path::new("/tmp")),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("missing.toml") && e.contains("relative to the plan"),
        "{e}"
    );
    // A plain value is one cell; `hidden` in the base gives way to `layers`.
    let p = parse("[[grid]]\ntrain.layers = [[4, 4]]\ntrain.decimate = 8\n").unwrap();
    assert_eq!(p.cells.len(), 1);
    assert_eq!(p.cells[0].pipeline.train.layers, vec![4, 4]);
    assert_eq!(p.cells[0].pipeline.train.decimate, 8);
}

/// Simulated runs of the tabulated foreign law (not Polach, not a network) at several
/// speeds and temperatures, with their truth tables, noise from `seed`.
fn foreign_campaign(dir: &Path, seed: u64) {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/scenes/foreign");
    for s in [
        "table_80kmh_p10",
        "table_120kmh_m20",
        "table_120kmh_m5",
        "table_120kmh_p10",
        "table_120kmh_p30",
        "table_160kmh_p10",
    ] {
        let scene = scenes.join(format!("{s}.toml"));
        let o = railgrip(
            dir,
            &[
                "simulate",
                scene.to_str().unwrap(),
                "--out",
                "campaign",
                "--format",
                "csv",
                "--seed",
                &seed.to_string(),
            ],
        );
        assert!(o.status.success(), "{}", text(&o));
    }
}

const SMALL_PLAN: &str = r#"
[[grid]]
label = "Polach"
train.model = "polach_pooled"

[[grid]]
label = "LM"
train.inputs = [["dv_mps", "ddv_mps2"], ["dv_mps", "ddv_mps2", "v_mps"]]
train.layers = [[3], [10]]
"#;

/// Writes `plan` and runs a study that must be refused (exit 1): its output.
fn refused(dir: &Path, plan: &str) -> String {
    std::fs::write(dir.join("plan.toml"), plan).unwrap();
    let o = railgrip(
        dir,
        &["study", "campaign", "--plan", "plan.toml", "--out", "st"],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    text(&o)
}

fn study_json(dir: &Path, out: &str, extra: &[&str]) -> (serde_json::Value, String) {
    let mut args = vec![
        "study",
        "campaign",
        "--plan",
        "plan.toml",
        "--out",
        out,
        "--json",
    ];
    args.extend_from_slice(extra);
    let o = railgrip(dir, &args);
    assert!(o.status.success(), "{}", text(&o));
    (
        serde_json::from_slice(&o.stdout).unwrap(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn cells_are_scored_against_a_foreign_law_resume_and_repeat_bit_for_bit() {
    for seed in [3u64, 11] {
        let dir = tempfile::tempdir().unwrap();
        foreign_campaign(dir.path(), seed);
        std::fs::write(dir.path().join("plan.toml"), SMALL_PLAN).unwrap();
        let (o, log) = study_json(dir.path(), "st", &[]);
        assert!(log.contains("5 cell(s), 0 reused"), "{log}");
        assert_eq!(o["by_truth"], true, "every held-out run has its truth");
        assert_eq!(
            o["held_out"],
            serde_json::json!(["table_120kmh_p10", "table_80kmh_p10"]),
            "every third run by name"
        );
        let cells = o["cells"].as_array().unwrap();
        assert_eq!(cells.len(), 5);
        // The default pipeline calibrates the campaign per conditioning, as `railgrip run` does.
        let calibrations: Vec<PathBuf> = std::fs::read_dir(dir.path().join("st/conditioning"))
            .unwrap()
            .map(|e| e.unwrap().path().join("calibration.json"))
            .collect();
        assert!(!calibrations.is_empty());
        assert!(calibrations.iter().all(|c| c.is_file()), "{calibrations:?}");
        let mut best_net = f64::INFINITY;
        for c in cells {
            assert!(c["error"].is_null(), "{c}");
            let truth = c["truth_rmse"].as_f64().unwrap();
            let held = c["held_out_rmse"].as_f64().unwrap();
            assert!(truth > 0.0 && truth < 0.05, "seed {seed}: {c}");
            assert!(held > 0.0 && held < 0.05, "seed {seed}: {c}");
            assert!(c["truth_cells"].as_u64().unwrap() >= 20, "{c}");
            let e = &c["eval"];
            assert!(e["single_ns"].as_f64().unwrap() > 0.0, "{c}");
            assert!(e["batch_ns"].as_f64().unwrap() > 0.0, "{c}");
            if c["model"] == "mlp" {
                best_net = best_net.min(truth);
                assert_eq!(c["truth_negative_cells"], 0, "μ̂ < 0 on data: {c}");
                // The fast tanh changes μ by rounding only.
                assert!(e["libm_max_diff"].as_f64().unwrap() < 1e-12, "{c}");
                assert!(e["plain_libm_ns"].as_f64().unwrap() > 0.0, "{c}");
            } else {
                assert!(e["plain_libm_ns"].is_null(), "{c}");
            }
            assert!(dir
                .path()
                .join(format!(
                    "st/cells/{}.model.json",
                    c["key"].as_str().unwrap()
                ))
                .is_file());
        }
        // Polach's law cannot have the table's sharp peak; the best network is nearer the truth.
        let polach = cells
            .iter()
            .find(|c| c["model"] == "polach_pooled")
            .unwrap();
        assert!(
            best_net < polach["truth_rmse"].as_f64().unwrap(),
            "seed {seed}: best network {best_net} vs Polach {}",
            polach["truth_rmse"]
        );
        // The recommendation without budgets is the most accurate cell; fronts are not empty.
        let rec = o["recommended"].as_str().unwrap();
        let best = cells
            .iter()
            .min_by(|a, b| {
                a["truth_rmse"]
                    .as_f64()
                    .unwrap()
                    .total_cmp(&b["truth_rmse"].as_f64().unwrap())
            })
            .unwrap();
        assert_eq!(rec, best["key"].as_str().unwrap());
        assert!(!o["pareto_train"].as_array().unwrap().is_empty());
        assert!(o["pareto_eval"].as_array().unwrap().contains(&best["key"]));
        for f in ["study.html", "study.csv", "study.json"] {
            assert!(dir.path().join("st").join(f).is_file(), "{f}");
        }
        let csv = std::fs::read_to_string(dir.path().join("st/study.csv")).unwrap();
        assert_eq!(csv.lines().count(), 6, "{csv}");

        if seed == 3 {
            // Resumed: nothing retrained, the same results.
            let (again, log) = study_json(dir.path(), "st", &[]);
            assert!(log.contains("5 cell(s), 5 reused"), "{log}");
            assert_eq!(again["cells"], o["cells"]);
            // A fresh folder, one job: the same models and errors, bit for bit.
            let (fresh, _) = study_json(dir.path(), "st2", &["--jobs", "1"]);
            for (a, b) in cells.iter().zip(fresh["cells"].as_array().unwrap()) {
                for k in [
                    "key",
                    "held_out_rmse",
                    "truth_rmse",
                    "truth_cells",
                    "file_bytes",
                ] {
                    assert_eq!(a[k], b[k], "{k}");
                }
                let key = a["key"].as_str().unwrap();
                let read =
                    |d: &str| std::fs::read(dir.path().join(format!("{d}/cells/{key}.model.json")));
                assert_eq!(read("st").unwrap(), read("st2").unwrap());
            }
            // Budgets: nothing evaluates in 0.001 ns; a generous budget recommends again.
            let (none, _) = study_json(dir.path(), "st", &["--budget-ns", "0.001"]);
            assert!(none["recommended"].is_null());
            assert!(none["notes"]
                .to_string()
                .contains("no cell meets the budgets"));
            let (cheap, _) = study_json(
                dir.path(),
                "st",
                &["--budget-ns", "1e6", "--budget-train-s", "1e6"],
            );
            assert_eq!(cheap["recommended"], o["recommended"]);
        }
    }
}

#[test]
fn too_large_plans_are_refused_with_their_estimate_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    common::two_run_campaign(&dir.path().join("campaign"));
    // Cell count.
    let t = refused(
        dir.path(),
        "[study]\nmax_cells = 1\n[[grid]]\ntrain.layers = [[2], [3]]\n",
    );
    assert!(
        t.contains("2 cells, more than study.max_cells = 1") && t.contains("--force"),
        "{t}"
    );
    // Estimated time: refused with the estimate; nothing trained.
    let t = refused(dir.path(), "[study]\nmax_minutes = 0.0001\nheld_out = [\"soap_120kmh_p20\"]\n[[grid]]\ntrain.layers = [[20]]\ntrain.epochs = 20\n");
    assert!(
        t.contains("estimated at") && t.contains("min") && t.contains("max_minutes = 0.0001"),
        "{t}"
    );
    assert!(!dir.path().join("st/study.json").exists());
    // --force runs it (two runs: one trains, one is held out; no truth beside these logs).
    let o = railgrip(
        dir.path(),
        &[
            "study",
            "campaign",
            "--plan",
            "plan.toml",
            "--out",
            "st",
            "--force",
            "--json",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["by_truth"], false);
    assert!(j["cells"][0]["truth_rmse"].is_null());
    assert!(j["cells"][0]["held_out_rmse"].as_f64().unwrap() > 0.0);
}

#[test]
fn inputs_the_campaign_lacks_and_unknown_runs_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    common::two_run_campaign(&camp);
    // No ambient temperature in one run's metadata.
    let meta = camp.join("soap_120kmh_m20.meta.toml");
    let text_meta = std::fs::read_to_string(&meta).unwrap();
    let stripped: String = text_meta
        .lines()
        .filter(|l| !l.starts_with("ambient_temperature_c"))
        .map(|l| format!("{l}\n"))
        .collect();
    assert_ne!(stripped, text_meta, "the fixture names its temperature");
    std::fs::write(&meta, stripped).unwrap();
    let t = refused(dir.path(), "[[grid]]\ntrain.inputs = [[\"dv_mps\", \"ddv_mps2\", \"v_mps\", \"ambient_temperature_c\"]]\n");
    assert!(
        t.contains("ambient temperature") && t.contains("soap_120kmh_m20"),
        "{t}"
    );
    let t = refused(
        dir.path(),
        "[study]\nheld_out = [\"nope\"]\n[[grid]]\ntrain.model = \"polach_pooled\"\n",
    );
    assert!(
        t.contains("held_out names nope") && t.contains("soap_120kmh_p20"),
        "{t}"
    );
}

#[test]
fn simulator_and_contact_rows_measure_step_and_grid() {
    let dir = tempfile::tempdir().unwrap();
    common::two_run_campaign(&dir.path().join("campaign"));
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/scenes/soap_120kmh_p20.toml");
    std::fs::write(
        dir.path().join("plan.toml"),
        format!(
            r#"[[grid]]
train.model = "polach_pooled"

[[simulator]]
scene = "{}"
step_ms = [0.05, 0.4]
reference_step_ms = 0.05

[[contact]]
law = ["linear", "saturated", "polach", "fastsim"]
grid = [5, 20, 50]
reference_grid = 200
"#,
            scene.display()
        ),
    )
    .unwrap();
    let (o, _) = study_json(dir.path(), "st", &[]);
    let sim = o["simulator"].as_array().unwrap();
    assert_eq!(sim.len(), 2);
    // The reference step against itself: the simulator is deterministic.
    assert_eq!(sim[0]["rms_mu_error"], 0.0);
    assert_eq!(sim[0]["max_v_error_mps"], 0.0);
    assert!(sim[1]["rms_mu_error"].as_f64().unwrap() > 0.0);
    assert!(sim[1]["real_time_factor"].as_f64().unwrap() > 0.0);
    let contact = o["contact"].as_array().unwrap();
    let err = |law: &str| -> f64 {
        contact
            .iter()
            .find(|r| r["law"] == law)
            .unwrap_or_else(|| panic!("{law}: {contact:?}"))["rms_error"]
            .as_f64()
            .unwrap()
    };
    // FASTSIM converges to its fine grid; the linear law does not saturate at μN.
    let (e5, e20, e50) = (
        err("fastsim 5×5 elliptic"),
        err("fastsim 20×20 elliptic"),
        err("fastsim 50×50 elliptic"),
    );
    assert!(e5 > e20 && e20 > e50 && e50 > 0.0, "{e5} {e20} {e50}");
    assert!(err("linear") > err("saturated"), "{contact:?}");
    assert!(err("polach (k_A = k_S = 1)") < 0.2, "{contact:?}");
    for r in contact {
        assert!(r["ns_per_call"].as_f64().unwrap() > 0.0);
    }
    // Bad rows are named.
    for (plan, want) in [
        (
            "[[grid]]\n[[simulator]]\nstep_ms = [0.1]\n",
            "simulator[0].scene is missing",
        ),
        ("[[grid]]\n[[contact]]\ngrid = [0]\n", "contact[0].grid = 0"),
        (
            "[[grid]]\n[[contact]]\nlaw = [\"magic\"]\n",
            "contact[0].law: unknown value",
        ),
        (
            "[[grid]]\n[[contact]]\nsize = 3\n",
            "contact[0]: unknown key size",
        ),
    ] {
        let e = plan_error(plan);
        assert!(e.contains(want), "{e}");
    }
    let e = plan_error(&format!(
        "[[grid]]\n[[simulator]]\nscene = \"{}\"\nstep_ms = [5.0]\n",
        scene.display()
    ));
    assert!(e.contains("simulator[0]") && e.contains("step_ms"), "{e}");
}

#[test]
fn a_cell_trained_but_not_timed_is_timed_on_resume_not_retrained() {
    let dir = tempfile::tempdir().unwrap();
    common::two_run_campaign(&dir.path().join("campaign"));
    std::fs::write(
        dir.path().join("plan.toml"),
        "[[grid]]\ntrain.layers = [[4]]\ntrain.epochs = 20\n",
    )
    .unwrap();
    let (o, _) = study_json(dir.path(), "st", &[]);
    let key = o["cells"][0]["key"].as_str().unwrap().to_string();
    // As if killed between training and timing: the result without its timings.
    let cell = dir.path().join(format!("st/cells/{key}.json"));
    let mut r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cell).unwrap()).unwrap();
    r["eval"] = serde_json::Value::Null;
    r["train_s"] = serde_json::json!(123.0);
    std::fs::write(&cell, r.to_string()).unwrap();
    let (again, log) = study_json(dir.path(), "st", &[]);
    assert!(log.contains("1 cell(s), 1 reused"), "{log}");
    assert!(!log.contains("trained"), "{log}");
    let c = &again["cells"][0];
    assert_eq!(c["train_s"], 123.0, "kept, not retrained");
    assert!(c["eval"]["single_ns"].as_f64().unwrap() > 0.0);
    // Cells on different rail conditions cannot share held-out runs.
    let t = refused(
        dir.path(),
        "[[grid]]\ntrain.condition = [\"soap\", \"dry\"]\n",
    );
    assert!(t.contains("one rail condition"), "{t}");
}

#[test]
fn a_broken_truth_table_or_base_pipeline_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    common::two_run_campaign(&camp);
    std::fs::write(camp.join("soap_120kmh_p20.truth.parquet"), b"not parquet").unwrap();
    let t = refused(
        dir.path(),
        "[study]\nheld_out = [\"soap_120kmh_p20\"]\n[[grid]]\ntrain.model = \"polach_pooled\"\n",
    );
    assert!(
        t.contains("soap_120kmh_p20.truth.parquet") && t.contains("railgrip simulate"),
        "{t}"
    );
    std::fs::write(dir.path().join("bad.toml"), "[train]\nlayerz = [3]\n").unwrap();
    let e = Plan::load(None, Some(&dir.path().join("bad.toml")))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("base pipeline") && e.contains("bad.toml") && e.contains("layerz"),
        "{e}"
    );
}
