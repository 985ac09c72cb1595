//! One input, every reader: the entry points of the cargo-fuzz targets in `fuzz/` and of the
//! bounded no-panic tests (`tests/no_panic.rs`), so both exercise the same code.
//! Each takes raw bytes, runs them through the public API as a user's file would go, and
//! panics only on a broken promise — an error that does not name its file, a model that loads
//! but evaluates to a non-finite μ inside its domain, a pipeline that loads but does not load
//! again from its own text. A panic anywhere else in the library is itself the finding.

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use crate::config::Pipeline;
use crate::ingest::{ingest_source, LogSource};
use crate::model::{c_header, Model, ModelFile};
use crate::sim::Scene;

fn pipeline() -> &'static Pipeline {
    static P: OnceLock<Pipeline> = OnceLock::new();
    P.get_or_init(Pipeline::default_uic_z1)
}

/// A small valid CSV log (0.25 s at 417 Hz, braking with slip) for the sidecar target.
pub fn small_csv() -> &'static [u8] {
    static CSV: OnceLock<Vec<u8>> = OnceLock::new();
    CSV.get_or_init(|| {
        let mut s = String::from("t,v_radar,omega1,omega2,omega3,omega4,p1,p2,p3,p4\n");
        for i in 0..105 {
            let t = i as f64 / 417.0;
            let v = 30.0 - 1.0 * t;
            let w = (v - 0.5) / 0.445;
            s.push_str(&format!(
                "{t:.6},{v:.6},{w:.6},{w:.6},{w:.6},{w:.6},2.0,2.0,2.0,2.0\n"
            ));
        }
        s.into_bytes()
    })
}

/// The field paths the `mcap_message` target reads from the corner-case messages of
/// tests/data/mcap (protobuf `railgrip.test.Corner`, ROS 2 `railgrip_test/msg/Corner`).
pub const MCAP_MESSAGE_PATHS: [(&str, &str, &str, &[&str]); 2] = [
    (
        "protobuf",
        "railgrip.test.Corner",
        "protobuf",
        &[
            "samples[1].value",
            "unpacked[2]",
            "packed[0]",
            "wrapped",
            "zigzag",
            "twist.angular.z",
        ],
    ),
    (
        "cdr",
        "railgrip_test/msg/Corner",
        "ros2msg",
        &["small[2]", "points[1].x", "value", "bounded[1]", "blob[1]"],
    ),
];

/// One protobuf or CDR message with its schema: byte 0 picks the encoding (even: protobuf,
/// odd: CDR), bytes 1–2 the schema's length L (little endian), then L bytes of schema (a
/// FileDescriptorSet or ros2msg text) and the payload. The decoder must build or refuse the
/// schema, and read the payload or refuse it, without a panic; a read gives one value (or
/// default) per path and the header stamp.
pub fn mcap_message_bytes(data: &[u8]) {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let (encoding, name, _, paths) = MCAP_MESSAGE_PATHS[(pick % 2) as usize];
    let len = rest
        .get(..2)
        .map_or(0, |b| u16::from_le_bytes([b[0], b[1]]) as usize);
    let rest = rest.get(2..).unwrap_or(&[]);
    let (schema, payload) = rest.split_at(len.min(rest.len()));
    if let Ok(d) = crate::ingest::MessageDecoder::new(encoding, name, schema, paths, true) {
        if let Ok(v) = d.extract(payload, &[]) {
            assert_eq!(v.len(), paths.len() + 2, "one value per path and the stamp");
        }
        let _ = d.decode_whole(payload);
    }
}

/// A log's bytes named `name` (`.csv` or `.mcap`, with an optional sidecar) through ingest
/// and, when it reads, the estimator.
pub fn log_bytes(data: &[u8], name: &str, sidecar: Option<&[u8]>) {
    let src = LogSource::Memory {
        name: PathBuf::from(name),
        bytes: Arc::from(data),
        sidecar: sidecar.map(Arc::from),
    };
    match ingest_source(&src, pipeline()) {
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains(name), "error does not name {name}: {msg}");
        }
        Ok(log) => {
            let _ = crate::estimate::estimate(&log, pipeline()).map_err(|e| e.to_string());
        }
    }
}

/// A metadata sidecar's bytes beside [`small_csv`]; errors name the log or the sidecar.
pub fn sidecar_bytes(data: &[u8]) {
    log_bytes(small_csv(), "fuzz.csv", Some(data));
}

/// Pipeline TOML: a pipeline that loads loads again from its own text, to the same settings.
pub fn pipeline_bytes(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match Pipeline::from_toml(text, "fuzz.toml") {
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains("fuzz.toml"),
                "error does not name the file: {msg}"
            );
        }
        Ok(p) => {
            let again = Pipeline::from_toml(&p.text, "fuzz.toml").expect("its own text loads");
            assert_eq!(again.text, p.text);
        }
    }
}

/// Scene TOML (paths resolved against no folder; the scene is not run).
pub fn scene_bytes(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(e) = Scene::from_toml(text, "fuzz.toml", None) {
        let _ = e.to_string();
    }
}

/// Model-file JSON: a file that loads gives finite μ at the middle of its domain and exports
/// a C header.
pub fn model_bytes(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let file = match ModelFile::from_json(text, "fuzz.json") {
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains("fuzz.json"),
                "error does not name the file: {msg}"
            );
            return;
        }
        Ok(f) => f,
    };
    let _header = c_header::c_header(&file, "fuzz", "fuzz.json");
    let mid = |name: &str| {
        file.inputs
            .iter()
            .find(|i| i.name == name)
            .map_or(f64::NAN, |i| 0.5 * (i.domain_min + i.domain_max))
    };
    let (dv, ddv, v, t) = (
        mid("dv_mps"),
        mid("ddv_mps2"),
        mid("v_mps"),
        mid("ambient_temperature_c"),
    );
    let model = Model::new(file).expect("a file that reads is a model");
    let mu = model.mu_vt(dv, if ddv.is_nan() { 0.0 } else { ddv }, v, t);
    assert!(mu.is_finite(), "μ = {mu} at the middle of the domain");
}
