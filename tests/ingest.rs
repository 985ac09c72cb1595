//! Ingest over every format, unit mapping, resampling rule and bad input.

mod common;

use std::fs;
use std::path::{Path, PathBuf};

use common::*;
use railgrip::format::{McapCompression, RunMetadata, Signal};
use railgrip::ingest::{
    ingest_file, linear_interpolation_bound, write_runlog_parquet, IngestError, RunLog, Warning,
    WarningKind,
};
use railgrip::Pipeline;

fn default() -> Pipeline {
    Pipeline::default_uic_z1()
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    fs::write(&p, bytes).unwrap();
    p
}

fn err(path: &Path, p: &Pipeline) -> String {
    match ingest_file(path, p) {
        Ok(_) => panic!("{} should fail to ingest", path.display()),
        Err(e) => e.to_string(),
    }
}

/// Every resampled value is within the linear-interpolation bound of the analytic signal.
fn assert_matches_analytic(log: &RunLog, max_raw_step: impl Fn(Signal) -> f64) {
    assert!(log.valid.iter().all(|v| *v));
    for s in Signal::ALL {
        let bound = linear_interpolation_bound(max_second_derivative(s), max_raw_step(s)) + 1e-9;
        let worst = log
            .time_s
            .iter()
            .zip(log.signal(s))
            .map(|(t, v)| (v - analytic(s, *t)).abs())
            .fold(0.0, f64::max);
        assert!(worst <= bound, "{s}: worst error {worst} > bound {bound}");
    }
}

fn assert_uniform(log: &RunLog) {
    let h = 1.0 / log.sample_rate_hz;
    for (i, t) in log.time_s.iter().enumerate() {
        assert!(
            (t - (log.time_s[0] + i as f64 * h)).abs() < 1e-9,
            "sample {i} off the grid"
        );
    }
}

#[test]
fn canonical_csv_with_jitter_resamples_within_the_interpolation_bound() {
    let dir = tempfile::tempdir().unwrap();
    let table = Table::analytic(20.0, 417.0, 0.3, 1);
    let path = dir.path().join("run.csv");
    table.write_csv(&path);
    fs::write(
        dir.path().join("run.meta.toml"),
        soap_metadata().to_sidecar_toml(),
    )
    .unwrap();
    let log = ingest_file(&path, &default()).unwrap();
    assert_eq!(log.format.to_string(), "CSV");
    assert_uniform(&log);
    assert!((log.duration_s() - 20.0).abs() < 2.0 / 417.0);
    let max_step = table
        .time_s
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(0.0, f64::max);
    assert_matches_analytic(&log, |_| max_step);
    assert_eq!(log.metadata, soap_metadata());
    assert!(log.warnings.is_empty(), "{:?}", log.warnings);
    assert!(!log.lost_data());
    let radar = &log.channels[0];
    assert!(
        (radar.rate_hz - 417.0).abs() < 5.0,
        "rate found {}",
        radar.rate_hz
    );
    assert_eq!(radar.samples, table.time_s.len());
}

#[test]
fn multi_rate_mcap_with_jitter_in_every_compression() {
    let dir = tempfile::tempdir().unwrap();
    let run = MultiRate::analytic(12.0, 50.0, 417.0, 200.0, 0.2, 7);
    for (name, c) in [
        ("zstd", McapCompression::Zstd),
        ("lz4", McapCompression::Lz4),
        ("none", McapCompression::None),
    ] {
        let path = write(
            dir.path(),
            &format!("{name}.mcap"),
            &run.mcap_bytes(&soap_metadata(), c),
        );
        let log = ingest_file(&path, &default()).unwrap();
        assert_eq!(log.format.to_string(), "MCAP");
        assert_eq!(log.start_log_time_ns, Some(1_700_000_000_000_000_000));
        assert_uniform(&log);
        assert_matches_analytic(&log, |s| {
            run.times[s.index()]
                .windows(2)
                .map(|w| w[1] - w[0])
                .fold(0.0, f64::max)
        });
        assert_eq!(log.metadata, soap_metadata());
        assert!((log.channels[0].rate_hz - 50.0).abs() < 2.0);
        assert!((log.channels[1].rate_hz - 417.0).abs() < 10.0);
        assert!((log.channels[5].rate_hz - 200.0).abs() < 5.0);
        assert!(log.warnings.is_empty(), "{name}: {:?}", log.warnings);
    }
}

#[test]
fn csv_and_mcap_of_the_same_samples_give_identical_run_logs() {
    let dir = tempfile::tempdir().unwrap();
    let table = Table::analytic(5.0, 417.0, 0.0, 3);
    let csv = write(dir.path(), "same.csv", &table.csv_bytes());
    let mcap = write(
        dir.path(),
        "same.mcap",
        &MultiRate::from_table(&table).mcap_bytes(&RunMetadata::default(), McapCompression::Zstd),
    );
    let a = ingest_file(&csv, &default()).unwrap();
    let b = ingest_file(&mcap, &default()).unwrap();
    assert_eq!(a.len(), b.len());
    for s in Signal::ALL {
        for (x, y) in a.signal(s).iter().zip(b.signal(s)) {
            // MCAP log times are whole nanoseconds.
            assert!((x - y).abs() < 1e-6, "{s}: {x} vs {y}");
        }
    }
}

/// Writes the table with custom column names and units; values converted from canonical.
fn mapped_csv(table: &Table, time_unit: (&str, f64), units: [(&str, f64); 3]) -> Vec<u8> {
    let mut s = String::from("zeit,radar,w1,w2,w3,w4,bc1,bc2,bc3,bc4,comment\n");
    for (i, t) in table.time_s.iter().enumerate() {
        s.push_str(&format!("{:?}", t / time_unit.1));
        for sig in Signal::ALL {
            let f = match sig {
                Signal::VRadar => units[0].1,
                Signal::Omega(_) => units[1].1,
                Signal::Pressure(_) => units[2].1,
            };
            s.push_str(&format!(",{:?}", table.column(sig)[i] / f));
        }
        s.push_str(",x\n");
    }
    s.into_bytes()
}

fn mapping_pipeline(time_unit: &str, units: [&str; 3]) -> Pipeline {
    let mut text = railgrip::config::DEFAULT_PIPELINE_TOML
        .split("[ingest.csv]")
        .next()
        .unwrap()
        .to_string();
    text.push_str("[ingest.csv]\n");
    text.push_str(&format!(
        "time = {{ column = \"zeit\", unit = \"{time_unit}\" }}\n"
    ));
    text.push_str(&format!(
        "v_radar = {{ column = \"radar\", unit = \"{}\" }}\n",
        units[0]
    ));
    for a in 1..=4 {
        text.push_str(&format!(
            "omega{a} = {{ column = \"w{a}\", unit = \"{}\" }}\n",
            units[1]
        ));
        text.push_str(&format!(
            "p{a} = {{ column = \"bc{a}\", unit = \"{}\" }}\n",
            units[2]
        ));
    }
    Pipeline::from_toml(&text, "mapping.toml").unwrap()
}

#[test]
fn every_unit_of_the_mapping_converts_to_canonical() {
    let dir = tempfile::tempdir().unwrap();
    let table = Table::analytic(3.0, 417.0, 0.1, 5);
    let reference = {
        let p = write(dir.path(), "canonical.csv", &table.csv_bytes());
        ingest_file(&p, &default()).unwrap()
    };
    // (time unit, its factor to s, [(speed, angular, pressure) unit and factor])
    type Case<'a> = (&'a str, f64, [(&'a str, f64); 3]);
    let cases: [Case; 4] = [
        ("s", 1.0, [("m/s", 1.0), ("rad/s", 1.0), ("bar", 1.0)]),
        (
            "ms",
            1e-3,
            [
                ("km/h", 1.0 / 3.6),
                ("rpm", std::f64::consts::TAU / 60.0),
                ("kPa", 1e-2),
            ],
        ),
        (
            "us",
            1e-6,
            [
                ("km/h", 1.0 / 3.6),
                ("rev/s", std::f64::consts::TAU),
                ("Pa", 1e-5),
            ],
        ),
        (
            "ns",
            1e-9,
            [
                ("m/s", 1.0),
                ("rpm", std::f64::consts::TAU / 60.0),
                ("MPa", 10.0),
            ],
        ),
    ];
    for (i, (tu, tf, units)) in cases.iter().enumerate() {
        let path = write(
            dir.path(),
            &format!("mapped{i}.csv"),
            &mapped_csv(&table, (tu, *tf), *units),
        );
        let p = mapping_pipeline(tu, [units[0].0, units[1].0, units[2].0]);
        let log = ingest_file(&path, &p).unwrap_or_else(|e| panic!("{tu}/{units:?}: {e}"));
        assert_eq!(log.len(), reference.len(), "{tu}");
        for s in Signal::ALL {
            for (x, y) in log.signal(s).iter().zip(reference.signal(s)) {
                assert!(
                    (x - y).abs() <= 1e-9 * y.abs().max(1.0),
                    "{tu} {units:?} {s}: {x} vs {y}"
                );
            }
        }
        assert!(log.channels[0].source.contains("radar"));
    }
}

#[test]
fn mcap_topics_and_fields_are_configurable_and_may_share_a_topic() {
    // A logger that puts all four tachometers on one topic, fields w1..w4, in rpm.
    let dir = tempfile::tempdir().unwrap();
    let table = Table::analytic(2.0, 417.0, 0.0, 9);
    let mut cur = std::io::Cursor::new(Vec::new());
    {
        let mut w = mcap::Writer::new(&mut cur).unwrap();
        let sid = w.add_schema("x", "jsonschema", b"{}").unwrap();
        let radar = w
            .add_channel(sid, "/sensors/radar", "json", &Default::default())
            .unwrap();
        let axles = w
            .add_channel(sid, "/sensors/axles", "json", &Default::default())
            .unwrap();
        let brake = w
            .add_channel(sid, "/sensors/brake", "json", &Default::default())
            .unwrap();
        let other = w
            .add_channel(sid, "/diagnostics", "cdr", &Default::default())
            .unwrap();
        let rpm = 60.0 / std::f64::consts::TAU;
        for (i, t) in table.time_s.iter().enumerate() {
            let ns = (t * 1e9).round() as u64;
            let c = |s| table.column(s)[i];
            let msgs = [
                (radar, format!(r#"{{"speed":{}}}"#, c(Signal::VRadar))),
                (
                    axles,
                    format!(
                        r#"{{"w1":{},"w2":{},"w3":{},"w4":{}}}"#,
                        c(Signal::Omega(1)) * rpm,
                        c(Signal::Omega(2)) * rpm,
                        c(Signal::Omega(3)) * rpm,
                        c(Signal::Omega(4)) * rpm
                    ),
                ),
                (
                    brake,
                    format!(
                        r#"{{"p1":{},"p2":{},"p3":{},"p4":{}}}"#,
                        c(Signal::Pressure(1)),
                        c(Signal::Pressure(2)),
                        c(Signal::Pressure(3)),
                        c(Signal::Pressure(4))
                    ),
                ),
                (other, "\u{1}binary".to_string()),
            ];
            for (ch, payload) in msgs {
                let h = mcap::records::MessageHeader {
                    channel_id: ch,
                    sequence: i as u32,
                    log_time: ns,
                    publish_time: ns,
                };
                w.write_to_known_channel(&h, payload.as_bytes()).unwrap();
            }
        }
        w.finish().unwrap();
    }
    let path = write(dir.path(), "shared.mcap", cur.get_ref());
    let mut text = railgrip::config::DEFAULT_PIPELINE_TOML
        .split("[ingest.mcap]")
        .next()
        .unwrap()
        .to_string();
    text.push_str("[ingest.mcap]\nv_radar = { topic = \"/sensors/radar\", field = \"speed\" }\n");
    for a in 1..=4 {
        text.push_str(&format!(
            "omega{a} = {{ topic = \"/sensors/axles\", field = \"w{a}\", unit = \"rpm\" }}\n"
        ));
        text.push_str(&format!(
            "p{a} = {{ topic = \"/sensors/brake\", field = \"p{a}\" }}\n"
        ));
    }
    let p = Pipeline::from_toml(&text, "m.toml").unwrap();
    let log = ingest_file(&path, &p).unwrap();
    for s in Signal::ALL {
        for (t, v) in log.time_s.iter().zip(log.signal(s)) {
            assert!((v - analytic(s, *t)).abs() < 1e-3, "{s} at {t}: {v}");
        }
    }
    // No "run" metadata record: a warning that loses nothing.
    assert_eq!(log.warnings.len(), 1);
    assert_eq!(log.warnings[0].kind, WarningKind::NoMetadata);
    assert!(!log.lost_data());
}

#[test]
fn long_gap_is_masked_medium_gap_bridged_and_short_gap_interpolated() {
    let dir = tempfile::tempdir().unwrap();
    let mut run = MultiRate::analytic(10.0, 417.0, 417.0, 417.0, 0.0, 11);
    // omega2: remove 4.00–4.60 s (600 ms, longer than bridge_gap_ms = 500);
    // omega3: remove 7.00–7.20 s (200 ms: bridged by cubic Hermite);
    // p3: remove 6.00–6.03 s (30 ms, within max_gap_ms: interpolated linearly).
    let cut = |run: &mut MultiRate, s: Signal, a: f64, b: f64| {
        let i = s.index();
        let keep: Vec<bool> = run.times[i].iter().map(|t| !(*t > a && *t < b)).collect();
        let mut k = keep.iter();
        run.times[i].retain(|_| *k.next().unwrap());
        let mut k = keep.iter();
        run.values[i].retain(|_| *k.next().unwrap());
    };
    cut(&mut run, Signal::Omega(2), 4.0, 4.6);
    cut(&mut run, Signal::Omega(3), 7.0, 7.2);
    cut(&mut run, Signal::Pressure(3), 6.0, 6.03);
    let path = write(
        dir.path(),
        "gap.mcap",
        &run.mcap_bytes(&soap_metadata(), McapCompression::Zstd),
    );
    let log = ingest_file(&path, &default()).unwrap();
    assert_eq!(log.gaps.len(), 2);
    let gap = &log.gaps[0];
    assert_eq!(gap.signal, Signal::Omega(2));
    assert!(!gap.bridged);
    assert!(gap.from_s <= 4.0 && gap.to_s >= 4.6 && gap.to_s - gap.from_s < 0.61);
    // The bridged gap: valid samples, close to the signal — far closer than a straight line
    // (whose error bound is M h²/8 = 0.11 rad/s here).
    let bridged = &log.gaps[1];
    assert!(bridged.bridged && bridged.signal == Signal::Omega(3));
    let linear_bound =
        railgrip::ingest::linear_interpolation_bound(max_second_derivative(Signal::Omega(3)), 0.2);
    let mut worst: f64 = 0.0;
    for (i, t) in log.time_s.iter().enumerate() {
        if *t > bridged.from_s && *t < bridged.to_s {
            assert!(log.valid[i]);
            worst = worst.max((log.omega_radps[2][i] - analytic(Signal::Omega(3), *t)).abs());
        }
    }
    eprintln!("bridged 0.2 s: worst error {worst:.2e} rad/s (linear bound {linear_bound:.2e})");
    assert!(worst < linear_bound / 10.0, "{worst} vs {linear_bound}");
    for (i, t) in log.time_s.iter().enumerate() {
        let inside = *t > gap.from_s && *t < gap.to_s;
        assert_eq!(log.valid[i], !inside, "t = {t}");
        assert_eq!(log.omega_radps[1][i].is_nan(), inside, "t = {t}");
        // Other channels keep their real data inside the gap.
        assert!(log.omega_radps[0][i].is_finite() && log.p_bar[2][i].is_finite());
    }
    let invalid = log.invalid_samples();
    assert!(
        (invalid as f64 - 0.6 * 417.0).abs() <= 3.0,
        "{invalid} invalid samples"
    );
    assert_eq!(log.valid_segments().len(), 2);
    assert!(log.lost_data());
    let w: Vec<_> = log
        .warnings
        .iter()
        .filter(|w| w.kind == WarningKind::Gap)
        .collect();
    assert_eq!(w.len(), 2);
    assert!(
        w[0].message
            .starts_with("omega2: 1 gap(s) longer than 500 ms not interpolated"),
        "{}",
        w[0].message
    );
    assert!(
        w[1].message
            .starts_with("omega3: 1 gap(s) longer than 50 ms bridged by cubic Hermite"),
        "{}",
        w[1].message
    );
}

#[test]
fn a_channel_starting_late_trims_the_start_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut run = MultiRate::analytic(5.0, 417.0, 417.0, 417.0, 0.0, 13);
    let i = Signal::VRadar.index();
    let skip = run.times[i].iter().take_while(|t| **t < 1.0).count();
    run.times[i].drain(..skip);
    run.values[i].drain(..skip);
    let path = write(
        dir.path(),
        "late.mcap",
        &run.mcap_bytes(&soap_metadata(), McapCompression::Zstd),
    );
    let log = ingest_file(&path, &default()).unwrap();
    assert!(log.time_s[0] >= 1.0 && log.time_s[0] < 1.01);
    assert!(log.warnings.iter().any(
        |w| w.kind == WarningKind::Trimmed && w.message.contains("v_radar has no data before")
    ));
    assert!(log.lost_data());
}

#[test]
fn implausible_samples_are_dropped_with_a_warning_or_rejected_per_config() {
    let dir = tempfile::tempdir().unwrap();
    let mut table = Table::analytic(3.0, 417.0, 0.0, 17);
    table.columns[Signal::Pressure(1).index()][600] = 25.0; // above 10 bar
    table.columns[Signal::VRadar.index()][700] = -3.0; // negative speed beyond noise
    let path = write(dir.path(), "spiky.csv", &table.csv_bytes());
    let log = ingest_file(&path, &default()).unwrap();
    assert_eq!(log.channels[5].dropped, 1);
    assert_eq!(log.channels[0].dropped, 1);
    assert!(
        log.valid.iter().all(|v| *v),
        "single dropped samples are bridged"
    );
    assert!(log.lost_data());
    let msgs: Vec<_> = log
        .warnings
        .iter()
        .filter(|w| w.kind == WarningKind::Implausible)
        .map(|w| w.message.clone())
        .collect();
    assert_eq!(msgs.len(), 2, "{msgs:?}");
    assert!(
        msgs.iter().any(|m| m.starts_with(
            "p1: 1 sample(s) outside [-0.5, 10] bar dropped, the first 25 bar at line 602"
        )),
        "{msgs:?}"
    );

    let strict = Pipeline::from_toml(
        &railgrip::config::DEFAULT_PIPELINE_TOML
            .replace(r#"action = "warn""#, r#"action = "error""#),
        "strict.toml",
    )
    .unwrap();
    let e = err(&path, &strict);
    // The first signal checked (v_radar, contract order) is the one reported.
    assert!(e.contains("spiky.csv: line 702: v_radar = -3 m/s is outside the plausibility limits [-0.5, 100] m/s"), "{e}");
    assert!(e.contains("Hint:"), "{e}");
}

#[test]
fn runlog_parquet_reads_back_with_nulls_in_gaps() {
    use polars::prelude::*;
    let dir = tempfile::tempdir().unwrap();
    let table = Table::analytic(2.0, 417.0, 0.0, 19);
    let mut run = MultiRate::from_table(&table);
    let i = Signal::Omega(4).index();
    let keep: Vec<bool> = run.times[i]
        .iter()
        .map(|t| !(*t > 1.0 && *t < 1.2))
        .collect();
    let mut k = keep.iter();
    run.times[i].retain(|_| *k.next().unwrap());
    let mut k = keep.iter();
    run.values[i].retain(|_| *k.next().unwrap());
    let path = write(
        dir.path(),
        "r.mcap",
        &run.mcap_bytes(&soap_metadata(), McapCompression::Zstd),
    );
    let log = ingest_file(&path, &default()).unwrap();
    let out = dir.path().join("r.runlog.parquet");
    write_runlog_parquet(&log, &out).unwrap();
    let df = ParquetReader::new(fs::File::open(&out).unwrap())
        .finish()
        .unwrap();
    let names: Vec<String> = df
        .get_column_names()
        .iter()
        .map(|s| s.to_string())
        .collect();
    assert_eq!(
        names,
        [
            "time_s",
            "v_radar_mps",
            "omega1_radps",
            "omega2_radps",
            "omega3_radps",
            "omega4_radps",
            "p1_bar",
            "p2_bar",
            "p3_bar",
            "p4_bar",
            "valid"
        ]
    );
    assert_eq!(df.height(), log.len());
    let w4 = df.column("omega4_radps").unwrap().f64().unwrap();
    assert_eq!(w4.null_count(), log.invalid_samples());
    let v = df.column("v_radar_mps").unwrap().f64().unwrap();
    for (a, b) in v.into_no_null_iter().zip(&log.v_radar_mps) {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    assert_eq!(
        fs::read_dir(dir.path()).unwrap().count(),
        2,
        "no temporary files left"
    );
}

#[test]
fn mcap_messages_out_of_order_are_sorted() {
    let dir = tempfile::tempdir().unwrap();
    let table = Table::analytic(1.0, 417.0, 0.0, 23);
    let mut run = MultiRate::from_table(&table);
    // Write pressures in reverse: MCAP does not promise order within a channel.
    let i = Signal::Pressure(2).index();
    let mut cur = std::io::Cursor::new(Vec::new());
    {
        let mut w = mcap::Writer::new(&mut cur).unwrap();
        let sid = w.add_schema("x", "jsonschema", b"{}").unwrap();
        for s in Signal::ALL {
            let ch = w
                .add_channel(sid, s.mcap_topic(), "json", &Default::default())
                .unwrap();
            let mut order: Vec<usize> = (0..run.times[s.index()].len()).collect();
            if s.index() == i {
                order.reverse();
            }
            for k in order {
                let ns = (run.times[s.index()][k] * 1e9).round() as u64;
                let payload = format!("{{\"{}\":{}}}", s.mcap_field(), run.values[s.index()][k]);
                w.write_to_known_channel(
                    &mcap::records::MessageHeader {
                        channel_id: ch,
                        sequence: k as u32,
                        log_time: ns,
                        publish_time: ns,
                    },
                    payload.as_bytes(),
                )
                .unwrap();
            }
        }
        w.finish().unwrap();
    }
    let path = write(dir.path(), "unordered.mcap", cur.get_ref());
    let log = ingest_file(&path, &default()).unwrap();
    for (t, v) in log.time_s.iter().zip(log.signal(Signal::Pressure(2))) {
        assert!((v - analytic(Signal::Pressure(2), *t)).abs() < 1e-3);
    }
    run.values.clear();
}

// ---------------------------------------------------------------- bad input, one test each

#[test]
fn missing_file() {
    let e = err(Path::new("/no/such/run.csv"), &default());
    assert_eq!(e, "/no/such/run.csv: file not found. Hint: check the path; railgrip reads .csv and .mcap logs");
}

#[test]
fn empty_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "empty.csv", b"");
    assert!(err(&p, &default()).ends_with(
        "empty.csv: the file is empty. Hint: the logger wrote nothing; re-export the run"
    ));
}

#[test]
fn neither_csv_nor_mcap_is_sniffed_not_trusted_by_extension() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "photo.csv",
        &[0xff, 0xd8, 0xff, 0xe0, 0, 0x10, b'J', b'F', b'I', b'F'],
    );
    let e = err(&p, &default());
    assert!(
        e.contains(
            "photo.csv: neither CSV nor MCAP: binary data starting with ff d8 ff e0 00 10 4a 46"
        ),
        "{e}"
    );
    let p = write(
        dir.path(),
        "notes.mcap",
        b"just some notes\nwithout separators\n",
    );
    let e = err(&p, &default());
    assert!(
        e.contains("notes.mcap: neither CSV nor MCAP: text whose first line has no comma"),
        "{e}"
    );
    // A CSV named .mcap is read as CSV.
    let table = Table::analytic(1.0, 417.0, 0.0, 1);
    let p = write(dir.path(), "actually_csv.mcap", &table.csv_bytes());
    assert_eq!(
        ingest_file(&p, &default()).unwrap().format.to_string(),
        "CSV"
    );
}

fn small_csv() -> String {
    String::from_utf8(Table::analytic(0.5, 417.0, 0.0, 2).csv_bytes()).unwrap()
}

#[test]
fn csv_cut_mid_line() {
    let dir = tempfile::tempdir().unwrap();
    let text = small_csv();
    let lines = text.lines().count();
    let last_start = text.trim_end().rfind('\n').unwrap() + 1;
    let cut = &text[..last_start + 30];
    let p = write(dir.path(), "cut.csv", cut.as_bytes());
    let e = err(&p, &default());
    assert!(
        e.contains(&format!("cut.csv: line {lines}: the last line has")),
        "{e}"
    );
    assert!(
        e.contains("looks cut off mid-line")
            && e.contains("Hint: the logger or copy was interrupted"),
        "{e}"
    );
}

/// A last line cut off inside its last mapped column, with only unmapped columns after it:
/// polars reads the mapped columns alone, so the cut value (a number's first digits) was once
/// read as it was, without a word. It is named now — also past the first 64 KiB, with CRLF line
/// ends, where a quoted comma makes the line-by-line rescan miscount, and where one sits in a
/// header's name. Read as before: the
/// same file whole, with its unmapped cells left empty, with a quoted last cell that holds a
/// comma or a line end, with a quoted comma in an unmapped column's name, and with every row
/// short of the unmapped column (an export that drops trailing empty cells).
#[test]
fn csv_cut_before_unmapped_columns() {
    let dir = tempfile::tempdir().unwrap();
    let text = small_csv();
    let lines = text.lines().count();
    let header_fields = text.lines().next().unwrap().split(',').count() + 1;
    let extra = |text: &str, name: &str, cell: &str| -> String {
        text.lines()
            .enumerate()
            .map(|(i, l)| format!("{l},{}\n", if i == 0 { name } else { cell }))
            .collect()
    };
    let reads = |name: &str, body: &str| {
        let p = write(dir.path(), name, body.as_bytes());
        ingest_file(&p, &default()).unwrap_or_else(|e| panic!("{name}: {e}"))
    };
    let run = reads("whole.csv", &extra(&text, "gps_fix", "4"));
    for (name, body) in [
        ("empty.csv", extra(&text, "gps_fix", "")),
        ("quoted.csv", extra(&text, "gps_fix", "\"a, b\"")),
        ("two_lines.csv", {
            let w = extra(&text, "gps_fix", "4");
            w[..w.len() - "4\n".len()].to_string() + "\"first,\nsecond\"\n"
        }),
        ("named.csv", extra(&text, "\"speed, km/h\"", "4")),
        // Without a line end after the last line: its quoted comma counted as one field's.
        (
            "quoted_open.csv",
            extra(&text, "gps_fix", "\"a, b\"").trim_end().to_string(),
        ),
        ("two_lines_open.csv", {
            let w = extra(&text, "gps_fix", "4");
            w[..w.len() - "4\n".len()].to_string() + "\"first,\nsecond\""
        }),
        (
            "ragged.csv",
            text.replacen('\n', ",gps_fix\n", 1).trim_end().to_string(),
        ),
    ] {
        let got = reads(name, &body);
        assert_eq!(
            (&got.time_s, &got.v_radar_mps, &got.p_bar),
            (&run.time_s, &run.v_radar_mps, &run.p_bar),
            "{name}"
        );
    }
    // The last line without its ",4\n" and its last mapped value's last two characters.
    let cut = |whole: &str| -> String {
        let last_value = whole.lines().last().unwrap().rsplit(',').nth(1).unwrap();
        assert!(last_value.len() > 2, "{last_value}");
        let end = whole.trim_end();
        end[..end.len() - ",4".len() - 2].to_string()
    };
    let long = String::from_utf8(Table::analytic(3.0, 417.0, 0.0, 2).csv_bytes()).unwrap();
    assert!(long.len() > 64 * 1024);
    let crlf = extra(&text, "gps_fix", "4").replace('\n', "\r\n");
    // A quoted comma in the cut line (a note), where a rescan that splits at every comma would
    // count it whole; and one in a header's name, where the plain count would find every line
    // short and the cut line not shorter than the one before it.
    let noted = extra(&text, "note,gps_fix", "\"a, b\",4");
    let named = extra(&text, "\"speed, km/h\"", "4");
    let (h, long_lines) = (header_fields, long.lines().count());
    for (name, body, line, fields, of) in [
        (
            "cut.csv",
            cut(&extra(&text, "gps_fix", "4")),
            lines,
            h - 1,
            h,
        ),
        (
            "cut_long.csv",
            cut(&extra(&long, "gps_fix", "4")),
            long_lines,
            h - 1,
            h,
        ),
        ("cut_crlf.csv", cut(&crlf), lines, h - 1, h),
        (
            "cut_noted.csv",
            noted.trim_end().trim_end_matches(",4").to_string(),
            lines,
            h,
            h + 1,
        ),
        ("cut_named.csv", cut(&named), lines, h - 1, h),
    ] {
        let p = write(dir.path(), name, body.as_bytes());
        let e = err(&p, &default());
        assert!(
            e.contains(&format!(
                "{name}: line {line}: the last line has {fields} of {of} fields"
            )) && e.contains("looks cut off mid-line"),
            "{e}"
        );
    }
}

/// A quoted comma inside an unmapped cell belongs to its field: a file with such cells and one
/// empty mapped cell (a missing sample, which starts the line-by-line rescan) reads, with the
/// hole named. The rescan once split at every comma and refused it as a row of too many fields.
#[test]
fn quoted_commas_survive_the_rescan() {
    let dir = tempfile::tempdir().unwrap();
    let noted: String = replace_cell(&small_csv(), 120, 1, "")
        .lines()
        .enumerate()
        .map(|(i, l)| format!("{l},{}\n", if i == 0 { "note" } else { "\"a, b\"" }))
        .collect();
    let p = write(dir.path(), "noted.csv", noted.as_bytes());
    let log = ingest_file(&p, &default()).unwrap_or_else(|e| panic!("{e}"));
    let w = missing_warnings(&log);
    assert_eq!(w.len(), 1, "{:?}", log.warnings);
    assert!(w[0].message.ends_with("line 120"), "{}", w[0].message);
}

/// A quoted cell that holds a line end (a note over two lines, as polars reads it) moves every
/// later row one line down: the missing sample and the bad cell after it are named at the
/// lines a text editor shows, not one line early.
#[test]
fn lines_are_named_past_a_quoted_line_end() {
    let dir = tempfile::tempdir().unwrap();
    let noted = |text: &str| -> String {
        text.lines()
            .enumerate()
            .map(|(i, l)| {
                let note = match i {
                    0 => "note",
                    10 => "\"first,\nsecond\"",
                    _ => "",
                };
                format!("{l},{note}\n")
            })
            .collect()
    };
    // Line 120 of the file without the note's line end is line 121 with it.
    let p = write(
        dir.path(),
        "noted_missing.csv",
        noted(&replace_cell(&small_csv(), 120, 1, "")).as_bytes(),
    );
    let log = ingest_file(&p, &default()).unwrap_or_else(|e| panic!("{e}"));
    let w = missing_warnings(&log);
    assert_eq!(w.len(), 1, "{:?}", log.warnings);
    assert!(w[0].message.ends_with("line 121"), "{}", w[0].message);
    let p = write(
        dir.path(),
        "noted_bad.csv",
        noted(&replace_cell(&small_csv(), 120, 1, "abc")).as_bytes(),
    );
    let e = err(&p, &default());
    assert!(e.contains("noted_bad.csv: line 121"), "{e}");
}

/// A log's warnings of missing samples.
fn missing_warnings(log: &RunLog) -> Vec<&Warning> {
    log.warnings
        .iter()
        .filter(|w| w.kind == WarningKind::Missing)
        .collect()
}

fn replace_cell(text: &str, line: usize, col: usize, with: &str) -> String {
    text.lines()
        .enumerate()
        .map(|(i, l)| {
            if i + 1 == line {
                let mut f: Vec<&str> = l.split(',').collect();
                f[col] = with;
                f.join(",")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

#[test]
fn non_numeric_cell() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "text.csv",
        replace_cell(&small_csv(), 57, 3, "n/a").as_bytes(),
    );
    let e = err(&p, &default());
    assert_eq!(
        e.rsplit_once("text.csv: ").unwrap().1,
        "line 57, column \"omega2\": \"n/a\" is not a number. Hint: numbers use '.' as decimal point and no thousands separator"
    );
    let p = write(
        dir.path(),
        "comma.csv",
        replace_cell(&small_csv(), 9, 6, "2;5").as_bytes(),
    );
    assert!(err(&p, &default()).contains("line 9, column \"p1\": \"2;5\" is not a number"));
}

/// A signal's empty or NaN cell is a missing sample of that channel alone: a warning names
/// the column and lines, the hole follows the gap rules (one missing sample is interpolated),
/// and the other channels keep that row.
#[test]
fn empty_and_nan_cells_are_missing_samples_of_their_channel() {
    let dir = tempfile::tempdir().unwrap();
    let whole = ingest_file(
        &write(dir.path(), "whole.csv", small_csv().as_bytes()),
        &default(),
    )
    .unwrap();
    for (name, cell) in [("hole.csv", ""), ("nan.csv", "NaN")] {
        let p = write(
            dir.path(),
            name,
            replace_cell(&small_csv(), 120, 1, cell).as_bytes(),
        );
        let log = ingest_file(&p, &default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        let w = missing_warnings(&log);
        assert_eq!(w.len(), 1, "{name}: {:?}", log.warnings);
        assert!(
            w[0].message
                .contains("1 cell(s) of column \"v_radar\" without a value")
                && w[0].message.ends_with("line 120"),
            "{}",
            w[0].message
        );
        assert!(w[0].kind.loses_data());
        assert_eq!(log.invalid_samples(), 0);
        assert_eq!(
            log.channels[Signal::VRadar.index()].samples + 1,
            whole.channels[0].samples
        );
        // The row's other channels are read as they are.
        assert_eq!(log.omega_radps, whole.omega_radps);
        assert_eq!(log.p_bar, whole.p_bar);
    }
    // A column without any value is a channel without samples: an error naming it.
    let text: String = small_csv()
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let mut f: Vec<&str> = l.split(',').collect();
            if i > 0 {
                f[5] = "";
            }
            format!("{}\n", f.join(","))
        })
        .collect();
    let e = err(
        &write(dir.path(), "no_omega4.csv", text.as_bytes()),
        &default(),
    );
    assert!(
        e.contains("no_omega4.csv") && e.contains("column \"omega4\" has fewer than two values"),
        "{e}"
    );
}

/// Lines without data — blank, separators only, an extra line end at the end — are left out
/// (polars reads them as rows of empty cells), and the lines named after them stay right.
#[test]
fn lines_without_data_are_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let whole = ingest_file(
        &write(dir.path(), "whole.csv", small_csv().as_bytes()),
        &default(),
    )
    .unwrap();
    let mut lines: Vec<String> = small_csv().lines().map(str::to_string).collect();
    lines.insert(4, String::new());
    lines.insert(9, ",,, ,,,,,,".into());
    lines.insert(20, "  ".into());
    let text = lines.join("\n") + "\n\n";
    let log = ingest_file(&write(dir.path(), "blank.csv", text.as_bytes()), &default()).unwrap();
    assert_eq!(log.omega_radps, whole.omega_radps);
    assert_eq!(log.v_radar_mps, whole.v_radar_mps);
    assert!(log.warnings.iter().all(|w| w.kind != WarningKind::Missing));
    // A missing cell after them is named at its own line.
    let p = write(
        dir.path(),
        "blank_hole.csv",
        replace_cell(&text, 50, 3, "").as_bytes(),
    );
    let log = ingest_file(&p, &default()).unwrap();
    let w: Vec<_> = log
        .warnings
        .iter()
        .filter(|w| w.kind == WarningKind::Missing)
        .collect();
    assert!(
        w.len() == 1
            && w[0].message.ends_with(
                "column \"omega2\" without a value (empty or NaN) read as missing samples, line 50"
            ),
        "{:?}",
        log.warnings
    );
}

/// The time column needs every row; ±inf is no measurement (NaN is a missing value).
#[test]
fn empty_time_and_inf_cells() {
    let dir = tempfile::tempdir().unwrap();
    for (i, (col, bad)) in [(0, ""), (0, "NaN"), (9, "inf"), (9, "-inf")]
        .iter()
        .enumerate()
    {
        let p = write(
            dir.path(),
            &format!("bad{i}.csv"),
            replace_cell(&small_csv(), 33, *col, bad).as_bytes(),
        );
        let e = err(&p, &default());
        let what = if bad.is_empty() {
            "line 33, column \"t\": empty cell. Hint: every row needs its time".to_string()
        } else {
            format!(
                "line 33, column \"{}\": \"{bad}\" is not a finite number",
                if *col == 0 { "t" } else { "p4" }
            )
        };
        assert!(e.contains(&what), "{e}");
    }
}

#[test]
fn timestamps_not_increasing_or_duplicated() {
    let dir = tempfile::tempdir().unwrap();
    let text = small_csv();
    let t10: String = text
        .lines()
        .nth(9)
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .to_string();
    let p = write(
        dir.path(),
        "dup.csv",
        replace_cell(&text, 11, 0, &t10).as_bytes(),
    );
    let e = err(&p, &default());
    assert!(e.contains("dup.csv: line 11: time"), "{e}");
    assert!(
        e.contains("does not increase after") && e.contains("strictly increasing"),
        "{e}"
    );
    let p = write(
        dir.path(),
        "back.csv",
        replace_cell(&text, 40, 0, "0.01").as_bytes(),
    );
    assert!(err(&p, &default()).contains("back.csv: line 40: time 0.01 s does not increase after"));
}

#[test]
fn blank_lines_do_not_shift_reported_line_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let text = small_csv();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    lines.insert(5, String::new());
    let text = lines.join("\n") + "\n";
    let p = write(
        dir.path(),
        "blank.csv",
        replace_cell(&text, 50, 2, "oops").as_bytes(),
    );
    let e = err(&p, &default());
    assert!(
        e.contains("blank.csv: line 50, column \"omega1\": \"oops\" is not a number"),
        "{e}"
    );
}

#[test]
fn header_only_csv() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "header.csv",
        b"t,v_radar,omega1,omega2,omega3,omega4,p1,p2,p3,p4\n",
    );
    let e = err(&p, &default());
    assert!(
        e.contains("header.csv: line 2: the file has a header but no data rows"),
        "{e}"
    );
    // Followed by lines without data only (polars reads them as rows of empty cells).
    let p = write(
        dir.path(),
        "no_rows.csv",
        b"t,v_radar,omega1,omega2,omega3,omega4,p1,p2,p3,p4\n\n,,,,,,,,,\n\n",
    );
    let e = err(&p, &default());
    assert!(
        e.contains("no_rows.csv: line 2: the file has a header but no data rows"),
        "{e}"
    );
}

#[test]
fn required_column_missing_lists_what_exists_and_suggests_a_mapping() {
    let dir = tempfile::tempdir().unwrap();
    let text = small_csv()
        .replacen("v_radar", "V_Radar_kmh", 1)
        .replacen("omega3", "omega_3", 1);
    let p = write(dir.path(), "names.csv", text.as_bytes());
    let e = err(&p, &default());
    assert!(
        e.contains("names.csv: missing CSV column(s) \"v_radar\" (v_radar), \"omega3\" (omega3)"),
        "{e}"
    );
    assert!(
        e.contains("the header has \"t\", \"V_Radar_kmh\", \"omega1\""),
        "{e}"
    );
    assert!(
        e.contains(r#"v_radar = { column = "V_Radar_kmh", unit = "m/s" }"#),
        "{e}"
    );
    assert!(
        e.contains(r#"omega3 = { column = "omega_3", unit = "rad/s" }"#),
        "{e}"
    );
}

#[test]
fn unknown_unit_in_pipeline() {
    let text = railgrip::config::DEFAULT_PIPELINE_TOML.replace(
        r#"p1 = { column = "p1", unit = "bar" }"#,
        r#"p1 = { column = "p1", unit = "psi" }"#,
    );
    let e = Pipeline::from_toml(&text, "psi.toml")
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        r#"psi.toml: ingest.csv.p1.unit = "psi": unknown pressure unit; use one of "bar", "kPa", "Pa", "MPa" (default "bar")"#
    );
}

fn good_mcap() -> Vec<u8> {
    MultiRate::analytic(1.0, 100.0, 417.0, 200.0, 0.1, 29)
        .mcap_bytes(&soap_metadata(), McapCompression::Zstd)
}

#[test]
fn truncated_mcap() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = good_mcap();
    let p = write(dir.path(), "trunc.mcap", &bytes[..bytes.len() * 2 / 3]);
    let e = err(&p, &default());
    assert!(
        e.contains("trunc.mcap: truncated file after") && e.contains("mcap recover"),
        "{e}"
    );
}

#[test]
fn mcap_bad_crc() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = MultiRate::analytic(1.0, 100.0, 417.0, 200.0, 0.1, 29)
        .mcap_bytes(&soap_metadata(), McapCompression::None);
    // Flip one digit inside the first chunk's (uncompressed) message records.
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let chunk = &summary.chunk_indexes[0];
    let at = (chunk.chunk_start_offset + chunk.chunk_length - 20) as usize;
    bytes[at] ^= 0x01;
    let p = write(dir.path(), "crc.mcap", &bytes);
    let e = err(&p, &default());
    assert!(
        e.starts_with(&format!("{}: CRC mismatch after", p.display())),
        "{e}"
    );
    assert!(
        e.contains("Hint: the file is corrupted; copy it again from the logger"),
        "{e}"
    );
}

fn mcap_with(
    encoding: &str,
    topics: &[&str],
    empty_topic: Option<&str>,
    payload: impl Fn(&str) -> String,
) -> Vec<u8> {
    let mut cur = std::io::Cursor::new(Vec::new());
    let mut w = mcap::Writer::new(&mut cur).unwrap();
    let sid = w.add_schema("x", "jsonschema", b"{}").unwrap();
    let mut ids = Vec::new();
    for t in topics {
        ids.push((
            w.add_channel(sid, t, encoding, &Default::default())
                .unwrap(),
            *t,
        ));
    }
    if let Some(t) = empty_topic {
        w.add_channel(sid, t, encoding, &Default::default())
            .unwrap();
    }
    for k in 0..50u64 {
        for (id, t) in &ids {
            let ns = k * 2_400_000;
            w.write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: *id,
                    sequence: k as u32,
                    log_time: ns,
                    publish_time: ns,
                },
                payload(t).as_bytes(),
            )
            .unwrap();
        }
    }
    w.finish().unwrap();
    drop(w);
    cur.into_inner()
}

fn canonical_payload(topic: &str) -> String {
    let s = Signal::ALL
        .iter()
        .find(|s| s.mcap_topic() == topic)
        .unwrap();
    format!("{{\"{}\":1.5}}", s.mcap_field())
}

#[test]
fn mcap_encoding_other_than_json() {
    let dir = tempfile::tempdir().unwrap();
    let topics: Vec<&str> = Signal::ALL.iter().map(|s| s.mcap_topic()).collect();
    let p = write(
        dir.path(),
        "fb.mcap",
        &mcap_with("flatbuffer", &topics, None, canonical_payload),
    );
    let e = err(&p, &default());
    assert!(e.contains("fb.mcap: topic /radar/speed has message encoding \"flatbuffer\"; railgrip reads \"json\", \"protobuf\" (protobuf schema) and \"cdr\" (ros2msg schema)"), "{e}");
    // CDR messages need a ros2msg schema (tests/mcap_encodings.rs reads real ones).
    let p = write(
        dir.path(),
        "cdr.mcap",
        &mcap_with("cdr", &topics, None, canonical_payload),
    );
    let e = err(&p, &default());
    assert!(e.contains("cdr.mcap: topic /radar/speed: "), "{e}");
    assert!(e.contains("ros2msg"), "{e}");
}

#[test]
fn mcap_missing_topic_lists_what_exists() {
    let dir = tempfile::tempdir().unwrap();
    let mut topics: Vec<&str> = Signal::ALL.iter().map(|s| s.mcap_topic()).collect();
    topics.retain(|t| *t != "/axle3/omega");
    topics.push("/axle3/speed");
    let p = write(
        dir.path(),
        "topics.mcap",
        &mcap_with("json", &topics, None, |t| {
            if t == "/axle3/speed" {
                "{\"omega\":1.0}".into()
            } else {
                canonical_payload(t)
            }
        }),
    );
    let e = err(&p, &default());
    assert!(
        e.contains("topics.mcap: missing MCAP topic(s) /axle3/omega (omega3); the file has"),
        "{e}"
    );
    assert!(
        e.contains("/axle3/speed (50 messages)") && e.contains("[ingest.mcap]"),
        "{e}"
    );
}

#[test]
fn mcap_channel_with_no_messages() {
    let dir = tempfile::tempdir().unwrap();
    let mut topics: Vec<&str> = Signal::ALL.iter().map(|s| s.mcap_topic()).collect();
    topics.retain(|t| *t != "/axle4/brake_pressure");
    let p = write(
        dir.path(),
        "silent.mcap",
        &mcap_with(
            "json",
            &topics,
            Some("/axle4/brake_pressure"),
            canonical_payload,
        ),
    );
    let e = err(&p, &default());
    assert!(
        e.contains("silent.mcap: topic /axle4/brake_pressure (p4) has no messages"),
        "{e}"
    );
}

#[test]
fn mcap_message_without_the_field_or_not_json() {
    let dir = tempfile::tempdir().unwrap();
    let topics: Vec<&str> = Signal::ALL.iter().map(|s| s.mcap_topic()).collect();
    let p = write(
        dir.path(),
        "field.mcap",
        &mcap_with("json", &topics, None, |t| {
            if t == "/radar/speed" {
                "{\"speed\":3.0}".into()
            } else {
                canonical_payload(t)
            }
        }),
    );
    let e = err(&p, &default());
    assert!(
        e.contains(
            "field.mcap: topic /radar/speed, message #0 (log_time 0 ns): no number field \"v\""
        ),
        "{e}"
    );
    let p = write(
        dir.path(),
        "garbage.mcap",
        &mcap_with("json", &topics, None, |t| {
            if t == "/axle1/omega" {
                "omega=3".into()
            } else {
                canonical_payload(t)
            }
        }),
    );
    let e = err(&p, &default());
    assert!(
        e.contains("topic /axle1/omega, message #0") && e.contains("not a JSON object of numbers"),
        "{e}"
    );
}

#[test]
fn mcap_duplicated_timestamps() {
    let dir = tempfile::tempdir().unwrap();
    let mut run = MultiRate::analytic(0.5, 417.0, 417.0, 417.0, 0.0, 31);
    let i = Signal::Omega(1).index();
    run.times[i][20] = run.times[i][19];
    let p = write(
        dir.path(),
        "dupt.mcap",
        &run.mcap_bytes(&soap_metadata(), McapCompression::None),
    );
    let e = err(&p, &default());
    assert!(
        e.contains("dupt.mcap: topic /axle1/omega, message #20") && e.contains("does not increase"),
        "{e}"
    );
}

#[test]
fn mcap_bad_metadata_value() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = soap_metadata();
    m.ambient_temperature_c = None;
    m.other
        .insert("ambient_temperature_c".into(), "cold".into());
    let bytes = MultiRate::analytic(0.5, 417.0, 417.0, 417.0, 0.0, 37)
        .mcap_bytes(&m, McapCompression::Zstd);
    let p = write(dir.path(), "meta.mcap", &bytes);
    let e = err(&p, &default());
    assert!(e.contains("meta.mcap: bad run metadata in metadata record \"run\": ambient_temperature_c = \"cold\" is not a number in °C"), "{e}");
}

#[test]
fn csv_bad_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "side.csv", small_csv().as_bytes());
    fs::write(
        dir.path().join("side.meta.toml"),
        "ambient_temperature_c = \"warm\"\n",
    )
    .unwrap();
    let e = err(&p, &default());
    assert!(
        e.contains("side.meta.toml: ambient_temperature_c = \"warm\" is not a number in °C"),
        "{e}"
    );
    fs::write(
        dir.path().join("side.meta.toml"),
        "ambient_temperature_c = \n",
    )
    .unwrap();
    let e = err(&p, &default());
    assert!(
        e.contains("bad run metadata in") && e.contains("side.meta.toml"),
        "{e}"
    );
}

#[test]
fn channels_that_do_not_overlap() {
    let dir = tempfile::tempdir().unwrap();
    let mut run = MultiRate::analytic(2.0, 417.0, 417.0, 417.0, 0.0, 41);
    let i = Signal::Pressure(4).index();
    for t in run.times[i].iter_mut() {
        *t += 5.0;
    }
    let p = write(
        dir.path(),
        "apart.mcap",
        &run.mcap_bytes(&soap_metadata(), McapCompression::Zstd),
    );
    let e = err(&p, &default());
    assert!(
        e.contains("apart.mcap: the channels do not overlap long enough to resample: p4 starts at"),
        "{e}"
    );
}

#[test]
fn errors_name_the_file_for_every_case_and_never_panic_on_mutations() {
    // Deterministic mutation sweep (the proptest in tests/no_panic.rs covers random inputs).
    let dir = tempfile::tempdir().unwrap();
    let csv = small_csv().into_bytes();
    let mcap = good_mcap();
    for (name, base) in [("m.csv", &csv), ("m.mcap", &mcap)] {
        for k in (0..base.len()).step_by(base.len() / 40 + 1) {
            let mut b = base.clone();
            b[k] ^= 0xA5;
            let p = write(dir.path(), name, &b);
            if let Err(e) = ingest_file(&p, &default()) {
                let text = e.to_string();
                assert!(text.contains(name), "{text}");
                let _: &IngestError = &e;
            }
        }
    }
}

#[test]
fn corrupt_record_length_is_an_error_not_an_allocation_abort() {
    // Regression: a mutated length field once made the streaming reader try to allocate 4e18
    // bytes and abort the process.
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = good_mcap();
    // After the 8-byte magic: the header record's opcode, then its u64 little-endian length.
    bytes[9..17].copy_from_slice(&0x3FFF_FFFF_FFFF_FFFFu64.to_le_bytes());
    let p = write(dir.path(), "huge.mcap", &bytes);
    let e = err(&p, &default());
    assert!(
        e.contains("huge.mcap: record larger than the file allows after 0 message(s)"),
        "{e}"
    );
}

/// A 206-byte CSV must not take down the whole campaign: two rows 1e9 s apart made the
/// resampler ask for 3.3 TB and abort; t = 1e300 overflowed the grid to 0 samples and passed
/// as a run; a time column in ms read as s used 1.4 GB. Each is now an error before the grid is
/// allocated, naming the file, the span and the limit, with a hint at the time unit where the
/// rows' spacing suggests one.
#[test]
fn time_spans_beyond_the_limit_are_errors_before_any_allocation() {
    let dir = tempfile::tempdir().unwrap();
    for (name, last_t) in [
        ("far.csv", 1e9),
        ("overflow.csv", 1e300),
        ("hours.csv", 5.0 * 3600.0),
    ] {
        let mut table = Table::analytic(0.5, 417.0, 0.0, 2);
        *table.time_s.last_mut().unwrap() = last_t;
        let p = write(dir.path(), name, &table.csv_bytes());
        let e = err(&p, &default());
        assert!(
            e.contains(name) && e.contains("ingest.max_duration_s = 14400 s") && e.contains("span"),
            "{e}"
        );
        // One stray row: named as such, whatever its value.
        assert!(e.contains("a time stamp far from the others"), "{e}");
    }
    // A 60 s run logged in ms under a pipeline that says s: 60 000 "s", rows 2.4 "s" apart.
    let mut table = Table::analytic(60.0, 417.0, 0.0, 3);
    table.time_s.iter_mut().for_each(|t| *t *= 1000.0);
    let p = write(dir.path(), "in_ms.csv", &table.csv_bytes());
    let e = err(&p, &default());
    assert!(
        e.contains("in_ms.csv") && e.contains("milliseconds") && e.contains("unit = \"ms\""),
        "{e}"
    );
    // The limit is the pipeline's: a 200 s log passes the default and fails a 100 s limit.
    let mut table = Table::analytic(0.5, 417.0, 0.0, 2);
    *table.time_s.last_mut().unwrap() = 200.0;
    let path = write(dir.path(), "long.csv", &table.csv_bytes());
    let log = ingest_file(&path, &default()).unwrap();
    assert_eq!(log.time_s.len(), 200 * 417 + 1);
    let mut short = default();
    short.ingest.max_duration_s = 100.0;
    let e = err(&path, &short);
    assert!(
        e.contains("long.csv") && e.contains("ingest.max_duration_s = 100 s"),
        "{e}"
    );
}

#[test]
fn duplicate_column_names_and_overlong_headers_are_named() {
    // A column named twice silently took the first; a header over 1 MiB was
    // reported as "missing columns".
    let dir = tempfile::tempdir().unwrap();
    let text = small_csv().replacen("p4", "omega2", 1);
    let p = write(dir.path(), "dup.csv", text.as_bytes());
    let e = err(&p, &default());
    assert!(
        e.contains("dup.csv: line 1: column \"omega2\" (omega2) appears 2 times in the header, at positions 4, 10"),
        "{e}"
    );
    let mut long = "t,v_radar,".to_string();
    long.push_str(&"x".repeat(1 << 20));
    long.push_str("\n0,1\n");
    let p = write(dir.path(), "long_header.csv", long.as_bytes());
    let e = err(&p, &default());
    assert!(
        e.contains("long_header.csv: line 1: the header line is longer than 1048576 bytes"),
        "{e}"
    );
}

#[cfg(unix)]
#[test]
fn fifos_and_devices_are_refused_without_blocking() {
    // A FIFO log or sidecar blocked ingest forever; a sidecar linked to /dev/zero
    // was read to 4.2 GB.
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.csv");
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let e = err(&fifo, &default());
    assert!(e.contains("pipe.csv is a FIFO (named pipe)"), "{e}");
    let p = write(dir.path(), "z.csv", small_csv().as_bytes());
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("z.meta.toml")).unwrap();
    let e = err(&p, &default());
    assert!(e.contains("z.meta.toml is a device"), "{e}");
    let p = write(dir.path(), "big.csv", small_csv().as_bytes());
    let big = format!("# {}\n", "x".repeat(1 << 20));
    std::fs::write(dir.path().join("big.meta.toml"), big).unwrap();
    let e = err(&p, &default());
    assert!(
        e.contains("over the 1048576-byte limit for a metadata sidecar"),
        "{e}"
    );
}

/// `text` (a log with a header) with two columns more, `note` and `gps_fix` (4 on every row):
/// each row's note is `fill`, or the one `notes` gives for its 0-based line.
fn with_notes(text: &str, fill: &str, notes: &[(usize, &str)]) -> String {
    text.lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                return format!("{l},note,gps_fix\n");
            }
            let note = notes
                .iter()
                .find(|(r, _)| *r == i)
                .map_or(fill, |(_, n)| *n);
            format!("{l},{note},4\n")
        })
        .collect()
}

/// A row over two lines (a quoted note holding a line end) that the file's end cuts off — after
/// its note or inside it — is named at the file's last line, as a row of two lines with the
/// fields it has; one cut right after the note's first line end, as a line ending inside it.
/// Past the first 64 KiB, where only the file's tail is looked at, a tail that begins
/// inside a note over many lines (each with more fields than the header) is read right: the
/// whole file reads, with and without a line end, and its last row cut before an unmapped
/// column is named.
#[test]
fn a_record_over_two_lines_cut_off_at_the_end_is_named_at_its_last_line() {
    let dir = tempfile::tempdir().unwrap();
    let text = small_csv();
    let lines = text.lines().count();
    let h = text.lines().next().unwrap().split(',').count();
    let noted = with_notes(&text, "\"\"", &[(lines - 1, "\"first,\nsecond\"")]);
    let p = write(dir.path(), "whole.csv", noted.as_bytes());
    ingest_file(&p, &default()).unwrap_or_else(|e| panic!("whole.csv: {e}"));
    let row = |how: &str| {
        format!(
            "line {}: the last row (lines {lines}–{}) has {} of {} fields and {how}",
            lines + 1,
            lines + 1,
            h + 1,
            h + 2
        )
    };
    for (name, body, what) in [
        (
            "after_note.csv",
            noted.trim_end().trim_end_matches(",4").to_string(),
            row("no line end"),
        ),
        (
            "inside_note.csv",
            noted.trim_end().trim_end_matches("ond\",4").to_string(),
            row("ends inside a quoted field, with no line end"),
        ),
    ] {
        let p = write(dir.path(), name, body.as_bytes());
        let e = err(&p, &default());
        assert!(
            e.contains(&format!("{name}: {what}"))
                && e.contains("looks cut off mid-row")
                && e.contains("delete the incomplete last row"),
            "{e}"
        );
    }
    // Cut right after the note's line end: a line that ends inside its open note.
    let name = "inside_note_line_end.csv";
    let p = write(
        dir.path(),
        name,
        noted.trim_end().trim_end_matches("second\",4").as_bytes(),
    );
    let e = err(&p, &default());
    assert!(
        e.contains(&format!(
            "{name}: line {lines}: the last line has {} of {} fields and ends inside a quoted field: the file looks cut off mid-line",
            h + 1,
            h + 2
        )),
        "{e}"
    );
    // A note of ~90 KiB over 2 500 lines, five rows before the end: the last 64 KiB begin inside it.
    let long = String::from_utf8(Table::analytic(3.0, 417.0, 0.0, 2).csv_bytes()).unwrap();
    let long_lines = long.lines().count();
    let big = format!(
        "\"{}\"",
        "a, b, c, d, e, f, g, h, i, j, k, l, m\n".repeat(2500)
    );
    let body = with_notes(&long, "\"\"", &[(long_lines - 6, &big)]);
    assert!(body.len() > 64 * 1024 && big.len() > 64 * 1024);
    let last_line = long_lines + 2500;
    for (name, whole) in [
        ("long_whole.csv", body.trim_end()),
        ("long_whole_line_end.csv", body.as_str()),
    ] {
        let p = write(dir.path(), name, whole.as_bytes());
        ingest_file(&p, &default()).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    let p = write(
        dir.path(),
        "long_cut.csv",
        body.trim_end().trim_end_matches(",4").as_bytes(),
    );
    let e = err(&p, &default());
    assert!(
        e.contains(&format!(
            "long_cut.csv: line {last_line}: the last line has {} of {} fields and no line end",
            h + 1,
            h + 2
        )),
        "{e}"
    );
}

/// Quotes polars reads two ways: its row splitting toggles at every quote, its cell reading
/// opens a quoted cell only at a cell's first character. A quote inside a cell's text
/// (`5" wheel`), or after a space, is named at its line — polars drops the rows after it
/// without a word where the cell lies past the columns it reads — in the last row too, whole or
/// cut. Two such quotes in one cell keep the two readings in step: the file reads, every row.
/// A doubled quote inside a quoted note is an escaped quote: the file reads, and a last row cut
/// inside such a note is named as open.
#[test]
fn quotes_inside_a_cells_text_are_named_and_escaped_ones_read() {
    let dir = tempfile::tempdir().unwrap();
    let text = small_csv();
    let lines = text.lines().count();
    let h = text.lines().next().unwrap().split(',').count();
    let with_notes = |notes: &[(usize, &str)]| with_notes(&text, "n", notes);
    let p = write(dir.path(), "plain.csv", with_notes(&[]).as_bytes());
    let plain = ingest_file(&p, &default()).unwrap();
    let escaped = with_notes(&[(lines - 1, "\"say \"\"hi\"\" twice\"")]);
    for (name, body) in [
        (
            "two_strays.csv",
            with_notes(&[(lines - 20, "5\" and 6\" wheels")]),
        ),
        ("escaped.csv", escaped.clone()),
        ("escaped_open.csv", escaped.trim_end().to_string()),
    ] {
        let p = write(dir.path(), name, body.as_bytes());
        let got = ingest_file(&p, &default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            (&got.time_s, &got.v_radar_mps),
            (&plain.time_s, &plain.v_radar_mps),
            "{name}"
        );
    }
    let stray_last = with_notes(&[(lines - 1, "5\" wheel")]);
    for (name, body, line) in [
        (
            "stray_before.csv",
            with_notes(&[(lines - 20, "5\" wheel")]),
            lines - 19,
        ),
        (
            "spaced.csv",
            with_notes(&[(lines - 20, " \"x")]),
            lines - 19,
        ),
        ("stray_last.csv", stray_last.clone(), lines),
        (
            "stray_last_open.csv",
            stray_last.trim_end().to_string(),
            lines,
        ),
        (
            "stray_last_cut.csv",
            stray_last.trim_end().trim_end_matches(",4").to_string(),
            lines,
        ),
    ] {
        let p = write(dir.path(), name, body.as_bytes());
        let e = err(&p, &default());
        assert!(
            e.contains(&format!(
                "{name}: line {line}: a double quote inside a cell's text"
            )) && e.contains("quote doubled"),
            "{e}"
        );
    }
    let p = write(
        dir.path(),
        "escaped_cut.csv",
        escaped
            .trim_end()
            .trim_end_matches("\"\" twice\",4")
            .as_bytes(),
    );
    let e = err(&p, &default());
    assert!(
        e.contains(&format!(
            "escaped_cut.csv: line {lines}: the last line has {} of {} fields and ends inside a quoted field, with no line end: the file looks cut off mid-line",
            h + 1,
            h + 2
        )),
        "{e}"
    );
}

/// Quotes that take rows with them further back than the file's end: two quotes inside the text
/// of two cells of one row, which pair up across the commas between them (polars then fails to
/// read the file), are named as such at their line, not as a row of too few fields; a quoted
/// cell that opens and never closes, further back than the file's last 64 KiB, is named where
/// it opens.
#[test]
fn quotes_that_pair_across_cells_or_never_close_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let text = small_csv();
    let h = text.lines().next().unwrap().split(',').count();
    // Two quotes in two cells, one before the last mapped column and one after: polars fails,
    // and the rescan names the line as a quote inside a cell's text (not as a short row).
    let straddle: String = with_notes(&text, "n", &[(100, "5\" wheel")])
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
            if i == 100 {
                f[h - 2].push('"');
            }
            f.join(",") + "\n"
        })
        .collect();
    let p = write(dir.path(), "straddle.csv", straddle.as_bytes());
    let e = err(&p, &default());
    assert!(
        e.contains("straddle.csv: line 101: a double quote inside a cell's text"),
        "{e}"
    );
    // A quoted cell that opens 100 rows in and never closes, in a log over 64 KiB: named where
    // it opens (polars would read every row after it as that cell).
    let long = String::from_utf8(Table::analytic(3.0, 417.0, 0.0, 2).csv_bytes()).unwrap();
    let unclosed = with_notes(&long, "n", &[(100, "\"12 wheel")]);
    assert!(unclosed.len() > 64 * 1024);
    let p = write(dir.path(), "unclosed.csv", unclosed.as_bytes());
    let e = err(&p, &default());
    assert!(
        e.contains("unclosed.csv: line 101: a quoted cell opens here and the file ends inside it"),
        "{e}"
    );
}
