//! `railgrip run` end to end on the bundled archive (8 runs), stage by stage, and the per-run
//! stage with 1 worker thread against 2 (`--jobs 1` / `--jobs 2`):
//!
//! - `run/estimate_jobs1`, `run/estimate_jobs2`: ingest, condition, estimate and write the
//!   estimates table of every run (`--force`: nothing reused);
//! - `run/estimate_reused`: the same stage when every run is unchanged (hashing and reading
//!   the tables back);
//! - `run/train`: the network and the Polach/k(T) fits on the pooled estimates, files written;
//! - `run/report`: the HTML report.
//!
//!     cargo bench --bench run

use std::path::{Path, PathBuf};
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use railgrip::campaign::{self, CampaignRecord, RunRecord};
use railgrip::identify::campaign::train_models;
use railgrip::identify::RunTable;
use railgrip::Pipeline;
use rayon::prelude::*;

fn estimate_all(
    pool: &rayon::ThreadPool,
    root: &Path,
    logs: &[PathBuf],
    out: &Path,
    p: &Pipeline,
    force: bool,
) -> Vec<(RunRecord, Option<RunTable>)> {
    pool.install(|| {
        logs.par_iter()
            .map(|l| {
                let name = campaign::run_name(root, l);
                let src = railgrip::ingest::LogSource::File(l.clone());
                campaign::process_run(&src, &name, &out.join("runs"), p, force)
            })
            .collect()
    })
}

fn bench(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/archive");
    let p = Pipeline::default_uic_z1();
    let logs = campaign::discover(&root, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    let pools: Vec<rayon::ThreadPool> = [1, 2]
        .iter()
        .map(|n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(*n)
                .build()
                .unwrap()
        })
        .collect();
    let mut g = c.benchmark_group("run");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    g.bench_function("estimate_jobs1", |b| {
        b.iter(|| estimate_all(&pools[0], &root, &logs, out, &p, true))
    });
    g.bench_function("estimate_jobs2", |b| {
        b.iter(|| estimate_all(&pools[1], &root, &logs, out, &p, true))
    });
    g.bench_function("estimate_reused", |b| {
        b.iter(|| estimate_all(&pools[1], &root, &logs, out, &p, false))
    });
    let results = estimate_all(&pools[1], &root, &logs, out, &p, false);
    let (records, tables): (Vec<RunRecord>, Vec<Option<RunTable>>) = results.into_iter().unzip();
    let tables: Vec<RunTable> = tables.into_iter().flatten().collect();
    g.bench_function("train", |b| {
        b.iter(|| {
            let m = train_models(tables.clone(), &p, None).unwrap();
            m.write(&out.join("models"), "mlp", true).unwrap()
        })
    });
    let m = train_models(tables.clone(), &p, None).unwrap();
    campaign::write_summary(out, &records).unwrap();
    CampaignRecord {
        archive: root.display().to_string(),
        runs: records,
        condition: Some(m.condition.clone()),
        model_error: None,
        notes: m.notes.clone(),
        pipeline: p.source.clone(),
        validation_axles: vec![3],
    }
    .write(out)
    .unwrap();
    g.bench_function("report", |b| {
        b.iter(|| railgrip::report::write_report(out).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
