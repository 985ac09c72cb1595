//! Ingest of a synthetic 1-hour run at 417 Hz (1.5 M rows), side by side with the bare
//! readers it builds on:
//!
//! - `ingest/csv/1h`: railgrip's CSV ingest (read + validate + convert + resample) against
//!   `ingest/csv_polars_bare/1h`, polars reading the same file with default options;
//! - `ingest/mcap/1h`: railgrip's MCAP ingest (9 JSON channels, zstd chunks, CRCs checked)
//!   against `ingest/mcap_bare/1h`, the mcap crate's message iteration plus serde_json parsing
//!   of every payload into a `serde_json::Value`.
//!
//! After the timings it prints the peak heap of one ingest of each (counting allocator) as a
//! multiple of the RunLog's own size.
//!
//!     cargo bench --bench ingest
//!
//! The generated files are cached in target/bench-data/.

#[path = "../tests/common/mod.rs"]
mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use common::{analytic, Rng};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use railgrip::format::{self, McapCompression, SeriesRef, Signal};
use railgrip::Pipeline;

struct Counting;
static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            let now = CURRENT.fetch_add(l.size(), Ordering::Relaxed) + l.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        CURRENT.fetch_sub(l.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, l, new) };
        if !q.is_null() {
            if new > l.size() {
                let now = CURRENT.fetch_add(new - l.size(), Ordering::Relaxed) + new - l.size();
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                CURRENT.fetch_sub(l.size() - new, Ordering::Relaxed);
            }
        }
        q
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

const SECONDS: f64 = 3600.0;
const RATE: f64 = 417.0;

/// A 1-hour log at logger precision (µs times, 3 decimals), jittered ±10 % of a period.
fn one_hour() -> (Vec<f64>, [Vec<f64>; 9]) {
    let n = (SECONDS * RATE) as usize;
    let mut rng = Rng::new(42);
    let r = |x: f64, inv: f64| (x * inv).round() / inv;
    let time: Vec<f64> = (0..n)
        .map(|k| {
            r(
                k as f64 / RATE
                    + if k == 0 {
                        0.0
                    } else {
                        (rng.uniform() - 0.5) * 0.2 / RATE
                    },
                1e6,
            )
        })
        .collect();
    let cols = std::array::from_fn(|i| {
        time.iter()
            .map(|t| r(analytic(Signal::ALL[i], *t), 1e3))
            .collect()
    });
    (time, cols)
}

fn data_files() -> (PathBuf, PathBuf) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("one_hour_v1.csv");
    let mcap = dir.join("one_hour_v1.mcap");
    if !csv.exists() || !mcap.exists() {
        eprintln!(
            "generating the 1-hour CSV and MCAP in {} (once)…",
            dir.display()
        );
        let (time, cols) = one_hour();
        let c: [&[f64]; 9] = std::array::from_fn(|i| cols[i].as_slice());
        let tmp = csv.with_extension("tmp");
        format::write_canonical_csv(BufWriter::new(File::create(&tmp).unwrap()), &time, c).unwrap();
        std::fs::rename(&tmp, &csv).unwrap();
        let series: Vec<SeriesRef> = Signal::ALL
            .iter()
            .map(|s| SeriesRef {
                signal: *s,
                time_s: &time,
                values: &cols[s.index()],
            })
            .collect();
        let tmp = mcap.with_extension("tmp");
        format::write_mcap(
            BufWriter::new(File::create(&tmp).unwrap()),
            &series,
            &common::soap_metadata(),
            McapCompression::Zstd,
            0,
        )
        .unwrap();
        std::fs::rename(&tmp, &mcap).unwrap();
    }
    (csv, mcap)
}

fn polars_bare(path: &Path) -> usize {
    use polars::prelude::*;
    CsvReadOptions::default()
        .with_has_header(true)
        .try_into_reader_with_file_path(Some(path.to_path_buf()))
        .unwrap()
        .finish()
        .unwrap()
        .height()
}

fn mcap_bare(path: &Path) -> usize {
    let bytes = std::fs::read(path).unwrap();
    let mut n = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        n += v.as_object().map_or(0, |o| o.len());
    }
    n
}

fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = CURRENT.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let out = f();
    (out, PEAK.load(Ordering::Relaxed) - base)
}

fn bench(c: &mut Criterion) {
    let (csv, mcap) = data_files();
    let pipeline = Pipeline::default_uic_z1();
    let rows = (SECONDS * RATE) as u64;
    let mb = |p: &Path| std::fs::metadata(p).unwrap().len() as f64 / 1e6;
    eprintln!(
        "CSV {:.0} MB, MCAP {:.0} MB, {rows} rows",
        mb(&csv),
        mb(&mcap)
    );

    let mut g = c.benchmark_group("ingest");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(20));
    g.throughput(Throughput::Elements(rows));
    g.bench_function("csv/1h", |b| {
        b.iter(|| railgrip::ingest_file(&csv, &pipeline).unwrap().len())
    });
    g.bench_function("csv_polars_bare/1h", |b| b.iter(|| polars_bare(&csv)));
    g.bench_function("mcap/1h", |b| {
        b.iter(|| railgrip::ingest_file(&mcap, &pipeline).unwrap().len())
    });
    g.bench_function("mcap_bare/1h", |b| b.iter(|| mcap_bare(&mcap)));
    g.finish();

    let (log, peak_csv) = peak_of(|| railgrip::ingest_file(&csv, &pipeline).unwrap());
    let runlog_bytes = log.len() * (10 * 8 + 1);
    drop(log);
    let (_, peak_polars) = peak_of(|| polars_bare(&csv));
    let (_, peak_mcap) = peak_of(|| railgrip::ingest_file(&mcap, &pipeline).unwrap());
    let (_, peak_mcap_bare) = peak_of(|| mcap_bare(&mcap));
    let m = |b: usize| b as f64 / 1e6;
    eprintln!("peak heap, RunLog itself {:.0} MB:", m(runlog_bytes));
    eprintln!(
        "  ingest csv   {:>6.0} MB = {:.2} x RunLog",
        m(peak_csv),
        peak_csv as f64 / runlog_bytes as f64
    );
    eprintln!("  polars bare  {:>6.0} MB", m(peak_polars));
    eprintln!(
        "  ingest mcap  {:>6.0} MB = {:.2} x RunLog",
        m(peak_mcap),
        peak_mcap as f64 / runlog_bytes as f64
    );
    eprintln!("  mcap bare    {:>6.0} MB", m(peak_mcap_bare));
}

criterion_group!(benches, bench);
criterion_main!(benches);
