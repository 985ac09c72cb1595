//! `railgrip run` end to end on the bundled archive (8 runs), stage by stage, and the per-run
//! stage with 1 worker thread against 2 (`--jobs 1` / `--jobs 2`), all through the library's
//! campaign functions (the ones `railgrip run` calls):
//!
//! - `run/calibrate`: the campaign's calibration the default pipeline asks for
//!   (`estimate.calibration = "auto"`: the 8 runs conditioned once more and the force balance
//!   solved) — `campaign::calibration::calibrated_pipeline`; the stages below use the pipeline
//!   carrying it, as `railgrip run` does;
//! - `run/estimate_jobs1`, `run/estimate_jobs2`: ingest, condition, estimate and write the
//!   estimates table of every run (`--force`: nothing reused) — `campaign::estimate_runs`;
//! - `run/estimate_reused`: the same stage when every run is unchanged (hashing and reading
//!   the tables back);
//! - `run/train`: the campaign's models on the pooled estimates with the default
//!   `train.model = "auto"` (every candidate, its held-out folds and the choice), files written
//!   — `campaign::train_models` and `CampaignModels::write`;
//! - `run/train_named_mlp`: the same with `train.model = "mlp"` (the network and the Polach
//!   model, no folds; the leave-one-run-out networks instead) — what the choice costs, side by
//!   side;
//! - the training stage part by part (`run/train` is these with the fits on all runs and the
//!   folds side by side, `rayon::join`, on the two cores):
//!   - `run/train/polach`: Polach's law with the temperature and speed forms BIC chooses and
//!     its profile-likelihood intervals (pooled, per run, per temperature) — first, alone: the
//!     other candidates need it as fallback or base; `run/train/polach_no_intervals` the same
//!     without the intervals;
//!   - `run/train/all_runs/<candidate>`: each other candidate fitted on all runs (the network of
//!     `[train]` with its starts, the networks over the other input sets, the residual
//!     network);
//!   - `run/train/folds`: every candidate on every held-out fold and scored
//!     (`choice::score_candidates`: 7 folds × the Polach law and 4 networks);
//! - `run/report`: the HTML report — `report::write_report`;
//! - `run/all`: `campaign::run` with `--force`, everything above in one call.
//!
//!     cargo bench --bench run

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use railgrip::campaign::{self, Options, OutDir, Quiet};
use railgrip::Pipeline;

fn bench(c: &mut Criterion) {
    let root = campaign::bundled_archive();
    let p = Pipeline::default_uic_z1();
    let logs = campaign::sources(&root, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = OutDir::new(dir.path());
    let opts = |jobs: usize, force: bool| Options {
        jobs: Some(jobs),
        force,
        ..Options::default()
    };
    let mut g = c.benchmark_group("run");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    let calibrate = || {
        campaign::calibration::calibrated_pipeline(
            &logs,
            &p,
            opts(2, true),
            true,
            true,
            &root,
            None,
        )
        .unwrap()
    };
    g.bench_function("calibrate", |b| b.iter(calibrate));
    let p = calibrate().pipeline;
    for (name, o) in [
        ("estimate_jobs1", opts(1, true)),
        ("estimate_jobs2", opts(2, true)),
        ("estimate_reused", opts(2, false)),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| campaign::estimate_runs(&root, &logs, &out, &p, o, &Quiet).unwrap())
        });
    }
    let (_, tables) =
        campaign::estimate_runs(&root, &logs, &out, &p, opts(2, false), &Quiet).unwrap();
    g.bench_function("train", |b| {
        b.iter(|| {
            let m = campaign::train_models(tables.clone(), &p, None).unwrap();
            m.write(&out.models(), true).unwrap()
        })
    });
    train_parts(&mut g, &tables, &p);
    let mut named = p.clone();
    named.train.model = railgrip::config::ModelChoice::Mlp;
    g.bench_function("train_named_mlp", |b| {
        b.iter(|| {
            let m = campaign::train_models(tables.clone(), &named, None).unwrap();
            m.write(&out.models(), true).unwrap()
        })
    });
    campaign::run(&root, &out, &p, opts(2, false), &Quiet).unwrap();
    g.bench_function("report", |b| {
        b.iter(|| railgrip::report::write_report(&out).unwrap())
    });
    g.bench_function("all", |b| {
        b.iter(|| campaign::run(&root, &out, &p, opts(2, true), &Quiet).unwrap())
    });
    g.finish();
}

/// The training stage's parts, each alone (see the module text).
fn train_parts(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    tables: &[railgrip::identify::RunTable],
    p: &Pipeline,
) {
    use railgrip::identify::choice;
    use railgrip::identify::family::PolachWithLaws;
    use railgrip::identify::{select_condition, FitData, ModelFamily};
    use railgrip::model::{Model, Provenance};
    let used = select_condition(tables.to_vec(), None).unwrap().used;
    fn data<'a>(
        tables: &'a [railgrip::identify::RunTable],
        pipeline: &'a Pipeline,
        fallback: Option<&'a Model>,
    ) -> FitData<'a> {
        FitData {
            tables,
            pipeline,
            provenance: Provenance {
                inputs: vec![],
                pipeline: String::new(),
                pipeline_sha256: String::new(),
                seed: pipeline.train.seed,
                crate_version: String::new(),
                created: String::new(),
                generation: None,
                calibration: None,
            },
            fallback,
            epochs: None,
            audit: true,
        }
    }
    let polach = |intervals| PolachWithLaws {
        intervals,
        law_required: false,
        pinned: None,
    };
    g.bench_function("train/polach", |b| {
        b.iter(|| polach(true).fit(&data(&used, p, None)).unwrap())
    });
    g.bench_function("train/polach_no_intervals", |b| {
        b.iter(|| polach(false).fit(&data(&used, p, None)).unwrap())
    });
    let fitted = polach(true).fit(&data(&used, p, None)).unwrap();
    let law = Model::named(fitted.model.unwrap(), "Polach model").unwrap();
    let form = fitted
        .report
        .into_polach()
        .and_then(|r| r.temperature.map(|t| t.form_choice()))
        .unwrap_or_default();
    let cands = choice::candidates(p, &used);
    for c in cands.iter().filter(|c| c.name != "polach") {
        g.bench_function(format!("train/all_runs/{}", c.name), |b| {
            b.iter(|| {
                c.family(None)
                    .fit(&data(&used, &c.pipeline, Some(&law)))
                    .unwrap()
            })
        });
    }
    let t = &p.train;
    g.bench_function("train/folds", |b| {
        b.iter(|| choice::score_candidates(&cands, &used, t.folds, t.decimate, form))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
