//! `railgrip run` end to end on the bundled archive (8 runs), stage by stage, and the per-run
//! stage with 1 worker thread against 2 (`--jobs 1` / `--jobs 2`), all through the library's
//! campaign functions (the ones `railgrip run` calls):
//!
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
        mcap: false,
    };
    let mut g = c.benchmark_group("run");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
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

criterion_group!(benches, bench);
criterion_main!(benches);
