//! Ingest of a synthetic 1-hour run at 417 Hz (1.5 M rows), side by side with the bare
//! readers it builds on:
//!
//! - `ingest/csv/1h`: railgrip's CSV ingest (read + validate + convert + resample) against
//!   `ingest/csv_polars_bare/1h`, polars reading the same file with default options;
//! - `ingest/mcap/1h`: railgrip's MCAP ingest (9 JSON channels, zstd chunks, CRCs checked)
//!   against `ingest/mcap_bare/1h`, the mcap crate's message iteration plus serde_json parsing
//!   of every payload into a `serde_json::Value`.
//!
//! - `ingest/mcap_protobuf/1h` and `ingest/mcap_ros2/1h`: the same hour as protobuf messages
//!   (tests/data/mcap's schemas: radar Twist, tachometers as one packed repeated double,
//!   pressures as DoubleValue wrappers) and as ROS 2 CDR (TwistStamped, JointState, Float64),
//!   against `…_bare/1h`: the mcap crate's message iteration plus the full decode of every
//!   payload by the same decoder family — prost-reflect's `DynamicMessage::decode`, and for CDR
//!   railgrip's reader visiting every field (no other Rust crate reads ros2msg schemas).
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

/// The schemas of the committed test logs: (topic, schema name, schema encoding, data).
fn schemas(file: &str) -> Vec<(String, String, String, Vec<u8>)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/mcap")
        .join(file);
    let bytes = std::fs::read(path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let mut out: Vec<_> = summary
        .channels
        .values()
        .map(|c| {
            let s = c.schema.as_ref().unwrap();
            (
                c.topic.clone(),
                s.name.clone(),
                s.encoding.clone(),
                s.data.to_vec(),
            )
        })
        .collect();
    out.sort();
    out
}

/// The default pipeline with the `[ingest.mcap]` mapping of tests/data/mcap/`mapping`.
fn pipeline_with(mapping: &str) -> Pipeline {
    let text = common::pipeline_text_with_mcap(&common::mcap_mapping(mapping));
    Pipeline::from_toml(&text, mapping).unwrap()
}

/// CDR (little endian) with 4-byte header; alignment relative to the body.
struct Cdr(Vec<u8>);
impl Cdr {
    fn new() -> Cdr {
        Cdr(vec![0, 1, 0, 0])
    }
    fn align(&mut self, n: usize) {
        while !(self.0.len() - 4).is_multiple_of(n) {
            self.0.push(0);
        }
    }
    fn u32(&mut self, x: u32) {
        self.align(4);
        self.0.extend(x.to_le_bytes());
    }
    fn f64(&mut self, x: f64) {
        self.align(8);
        self.0.extend(x.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.0.extend(s.as_bytes());
        self.0.push(0);
    }
    fn header(&mut self, t_ns: u64, frame: &str) {
        self.u32((t_ns / 1_000_000_000) as u32);
        self.u32((t_ns % 1_000_000_000) as u32);
        self.string(frame);
    }
}

/// The hour as protobuf (`ros2` false) or ROS 2 CDR messages, written once.
#[allow(clippy::too_many_lines)] // a test or benchmark: one scenario end to end
fn encoded_file(ros2: bool, time: &[f64], cols: &[Vec<f64>; 9]) -> PathBuf {
    use prost_reflect::prost::Message as _;
    use prost_reflect::{DescriptorPool, DynamicMessage, Value};
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
    let path = dir.join(if ros2 {
        "one_hour_v1.ros2.mcap"
    } else {
        "one_hour_v1.protobuf.mcap"
    });
    if path.exists() {
        return path;
    }
    eprintln!("generating {} (once)…", path.display());
    let sch = schemas(if ros2 {
        "soap_160kmh_0c.ros2.mcap"
    } else {
        "soap_160kmh_0c.protobuf.mcap"
    });
    let tmp = path.with_extension("tmp");
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .create(BufWriter::new(File::create(&tmp).unwrap()))
        .unwrap();
    let mut ids = std::collections::BTreeMap::new();
    for (topic, name, enc, data) in &sch {
        let sid = w.add_schema(name, enc, data).unwrap();
        let msg_enc = if ros2 { "cdr" } else { "protobuf" };
        ids.insert(
            topic.clone(),
            w.add_channel(sid, topic, msg_enc, &Default::default())
                .unwrap(),
        );
    }
    w.write_metadata(&mcap::records::Metadata {
        name: "run".into(),
        metadata: common::soap_metadata().to_pairs(),
    })
    .unwrap();
    let pool = (!ros2).then(|| DescriptorPool::decode(sch[0].3.as_slice()).unwrap());
    let desc = |n: &str| pool.as_ref().unwrap().get_message_by_name(n).unwrap();
    let stamp = |m: &mut DynamicMessage, t: u64| {
        let mut ts = DynamicMessage::new(desc("google.protobuf.Timestamp"));
        ts.set_field_by_name("seconds", Value::I64((t / 1_000_000_000) as i64));
        ts.set_field_by_name("nanos", Value::I32((t % 1_000_000_000) as i32));
        m.set_field_by_name("timestamp", Value::Message(ts));
    };
    for (i, &t) in time.iter().enumerate() {
        let t_ns = (t * 1e9).round() as u64;
        let mut put = |topic: &str, payload: &[u8]| {
            w.write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: ids[topic],
                    sequence: i as u32,
                    log_time: t_ns,
                    publish_time: t_ns,
                },
                payload,
            )
            .unwrap()
        };
        let v = |s: usize| cols[s][i];
        if ros2 {
            let mut c = Cdr::new();
            c.header(t_ns, "radar");
            for x in [v(0), 0.0, 0.0, 0.0, 0.0, 0.0] {
                c.f64(x);
            }
            put("/radar/twist", &c.0);
            let mut c = Cdr::new();
            c.header(t_ns, "bogie");
            c.u32(4);
            for name in ["axle1", "axle2", "axle3", "axle4"] {
                c.string(name);
            }
            c.u32(0);
            c.u32(4);
            for a in 1..=4 {
                c.f64(v(a));
            }
            c.u32(0);
            put("/joint_states", &c.0);
            for a in 1..=4 {
                let mut c = Cdr::new();
                c.f64(v(4 + a));
                put(&format!("/axle{a}/pressure"), &c.0);
            }
        } else {
            let mut radar = DynamicMessage::new(desc("railgrip.test.RadarSpeed"));
            stamp(&mut radar, t_ns);
            radar.set_field_by_name("frame_id", Value::String("radar".into()));
            let mut lin = DynamicMessage::new(desc("railgrip.test.Vector3"));
            lin.set_field_by_name("x", Value::F64(v(0)));
            let mut tw = DynamicMessage::new(desc("railgrip.test.Twist"));
            tw.set_field_by_name("linear", Value::Message(lin));
            radar.set_field_by_name("twist", Value::Message(tw));
            put("/radar/speed", &radar.encode_to_vec());
            let mut tacho = DynamicMessage::new(desc("railgrip.test.Tachometers"));
            stamp(&mut tacho, t_ns);
            tacho.set_field_by_name(
                "name",
                Value::List(
                    ["a1", "a2", "a3", "a4"]
                        .iter()
                        .map(|s| Value::String(s.to_string()))
                        .collect(),
                ),
            );
            tacho.set_field_by_name(
                "omega",
                Value::List((1..=4).map(|a| Value::F64(v(a))).collect()),
            );
            put("/tachometers", &tacho.encode_to_vec());
            for a in 1..=4 {
                let mut p = DynamicMessage::new(desc("railgrip.test.Pressure"));
                stamp(&mut p, t_ns);
                let mut bar = DynamicMessage::new(desc("google.protobuf.DoubleValue"));
                bar.set_field_by_name("value", Value::F64(v(4 + a)));
                p.set_field_by_name("bar", Value::Message(bar));
                put(&format!("/axle{a}/pressure"), &p.encode_to_vec());
            }
        }
    }
    w.finish().unwrap();
    drop(w);
    std::fs::rename(&tmp, &path).unwrap();
    path
}

/// The mcap crate's message iteration plus the full decode of every payload by the decoder
/// family of its channel's encoding (see the module comment).
fn mcap_bare_decoded(path: &Path) -> usize {
    let bytes = std::fs::read(path).unwrap();
    let mut decoders: std::collections::HashMap<u16, railgrip::ingest::MessageDecoder> =
        Default::default();
    let mut n = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let d = decoders.entry(m.channel.id).or_insert_with(|| {
            let s = m.channel.schema.as_ref().unwrap();
            railgrip::ingest::MessageDecoder::new(
                &m.channel.message_encoding,
                &s.name,
                &s.data,
                &[],
                false,
            )
            .unwrap()
        });
        n += d.decode_whole(&m.data).unwrap();
    }
    n
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
    let (protobuf, ros2) = {
        let (time, cols) = one_hour();
        (
            encoded_file(false, &time, &cols),
            encoded_file(true, &time, &cols),
        )
    };
    let pb_pipeline = pipeline_with("protobuf.toml");
    let ros2_pipeline = pipeline_with("ros2.toml");
    let pipeline = Pipeline::default_uic_z1();
    let rows = (SECONDS * RATE) as u64;
    let mb = |p: &Path| std::fs::metadata(p).unwrap().len() as f64 / 1e6;
    eprintln!(
        "CSV {:.0} MB, MCAP {:.0} MB (JSON), {:.0} MB (protobuf), {:.0} MB (ROS 2), {rows} rows",
        mb(&csv),
        mb(&mcap),
        mb(&protobuf),
        mb(&ros2)
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
    g.bench_function("mcap_protobuf/1h", |b| {
        b.iter(|| {
            railgrip::ingest_file(&protobuf, &pb_pipeline)
                .unwrap()
                .len()
        })
    });
    g.bench_function("mcap_protobuf_bare/1h", |b| {
        b.iter(|| mcap_bare_decoded(&protobuf))
    });
    g.bench_function("mcap_ros2/1h", |b| {
        b.iter(|| railgrip::ingest_file(&ros2, &ros2_pipeline).unwrap().len())
    });
    g.bench_function("mcap_ros2_bare/1h", |b| b.iter(|| mcap_bare_decoded(&ros2)));
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
